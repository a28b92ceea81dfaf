// The one list of reconstruction methods (reconstruction_method.h): what
// the worker runs, what the server accepts at Submit and lists through
// Jobs.ListMethods. A method is registered by one line in registry.cc.
#pragma once

#include <string>
#include <vector>

#include "common/methods/method_spec.h"
#include "server/recon/reconstruction_method.h"

namespace reenact::recon {

// Every method, in the order `reenact jobs methods` lists them.
const std::vector<const ReconstructionMethod*>& Methods();

// The method named `name`, or null.
const ReconstructionMethod* FindMethod(const std::string& name);

// Their specs, each with the options every method shares (loading) after
// its own.
std::vector<methods::MethodSpec> MethodSpecs();

// Names of the methods RunMethod accepts, in registry order.
std::vector<std::string> MethodNames();

}  // namespace reenact::recon
