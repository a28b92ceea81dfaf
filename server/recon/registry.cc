#include "server/recon/registry.h"

#include "server/recon/body/body_method.h"
#include "server/recon/carving/rigid_carved.h"
#include "server/recon/cylinders/cylinders.h"
#include "server/recon/methods.h"

namespace reenact::recon {

const std::vector<const ReconstructionMethod*>& Methods() {
  // One line per method.
  static const std::vector<const ReconstructionMethod*> methods = {
      &RigidCylindersMethod(),
      &RigidCarvedMethod(),
      &BodyMethod(),
  };
  return methods;
}

const ReconstructionMethod* FindMethod(const std::string& name) {
  for (const ReconstructionMethod* method : Methods()) {
    if (method->spec().name == name) return method;
  }
  return nullptr;
}

std::vector<methods::MethodSpec> MethodSpecs() {
  std::vector<methods::OptionSpec> common = methods::DescribeOptions<LoadOptions>();
  for (methods::OptionSpec& option : common) option.common = true;
  std::vector<methods::MethodSpec> specs;
  for (const ReconstructionMethod* method : Methods()) {
    methods::MethodSpec spec = method->spec();
    spec.options.insert(spec.options.end(), common.begin(), common.end());
    specs.push_back(std::move(spec));
  }
  return specs;
}

std::vector<std::string> MethodNames() {
  std::vector<std::string> names;
  for (const ReconstructionMethod* method : Methods()) names.push_back(method->spec().name);
  return names;
}

}  // namespace reenact::recon
