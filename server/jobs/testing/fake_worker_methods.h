// The methods the tests that run fake-reenact-worker give the job
// scheduler: the registry's (so that Submit checks names, types and bounds
// as reenact-server does), each with the fake worker's own options
// (fake_worker_main.cc) added.
#pragma once

#include <vector>

#include "common/methods/method_spec.h"
#include "server/recon/registry.h"

namespace reenact::server {

inline std::vector<methods::MethodSpec> FakeWorkerMethods() {
  std::vector<methods::MethodSpec> specs = recon::MethodSpecs();
  for (methods::MethodSpec& spec : specs) {
    for (const char* name : {"fake_steps", "fake_step_ms", "fake_end", "fake_hang_first",
                             "fake_ignore_term", "fake_trace"}) {
      methods::OptionSpec option;
      option.name = name;
      option.doc = "fake-reenact-worker";
      spec.options.push_back(option);
    }
  }
  return specs;
}

}  // namespace reenact::server
