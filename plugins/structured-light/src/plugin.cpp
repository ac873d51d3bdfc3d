// SPDX-License-Identifier: MIT
// ABI glue of the structured-light plugin: exported info, describe(), and the
// factory that dispatches a method name to its session. To add a method:
// write its session (like gray_session.cpp), add its name to the METHODS_CSV
// below, a describe entry and a branch in create().
#include <memory>
#include <string>
#include <vector>

#include "codes_session.hpp"
#include "gray_session.hpp"
#include "phase_session.hpp"
#include "procam/plugin_sdk.hpp"

namespace {

std::string describe() {
  std::vector<procam::sdk::MethodDescription> methods;
  methods.push_back(procam::sl::describe_gray());
  for (const char* m : procam::sl::kCodeMethods)
    methods.push_back(procam::sl::describe_codes_method(m));
  for (const char* m : procam::sl::kPhaseMethods)
    methods.push_back(procam::sl::describe_phase_method(m));
  return procam::sdk::describe_methods(methods);
}

procam::sdk::Error create(const procam::sdk::CreateArgs& args,
                          std::unique_ptr<procam::sdk::Session>& out) {
  if (args.method == "gray") return procam::sl::create_gray_session(args, out);
  for (const char* m : procam::sl::kCodeMethods)
    if (args.method == m) return procam::sl::create_codes_session(args, out);
  for (const char* m : procam::sl::kPhaseMethods)
    if (args.method == m) return procam::sl::create_phase_session(args, out);
  // The SDK only passes names listed in the METHODS_CSV below.
  return procam::sdk::internal_error("method '" + args.method + "' is listed but not built");
}

}  // namespace

PROCAM_DEFINE_PLUGIN("structured-light", "0.2.0", "gray,xor02,xor04,minsw,ensemble,auto,phase-shift,modulated-phase-shift", describe,
                     create);
