// SPDX-License-Identifier: MIT
// libFuzzer harness over the procamd config parser (daemon/procamd/config.cpp):
// any JSON document (comments allowed, as in config files) must give a Config
// or an error naming the problem, never a throw or crash. Rig paths are not
// opened: read_json_file is stubbed here so the harness touches no files.
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <string>

#include "../../daemon/procamd/config.hpp"
#include "procam/engine/rig_json.hpp"

namespace procam::engine {
Result<nlohmann::json> read_json_file(const std::string& path) {
  if (path.find("rig-object") != std::string::npos) return nlohmann::json{{"name", "fuzz"}};
  return Error(Code::not_found, "cannot open '" + path + "' (fuzzing: no files)");
}
}  // namespace procam::engine

// PROCAM_FUZZ_ENTRY renames the entry point for the regression test, which
// links both harnesses into one gtest binary.
#ifndef PROCAM_FUZZ_ENTRY
#define PROCAM_FUZZ_ENTRY LLVMFuzzerTestOneInput
#endif

extern "C" int PROCAM_FUZZ_ENTRY(const uint8_t* data, size_t size);
extern "C" int PROCAM_FUZZ_ENTRY(const uint8_t* data, size_t size) {
  const std::string text(reinterpret_cast<const char*>(data), size);
  nlohmann::json j = nlohmann::json::parse(text, nullptr, /*allow_exceptions=*/false, /*ignore_comments=*/true);
  if (j.is_discarded()) return 0;
  auto c = procam::daemon::parse_config(j, "/fuzz/base");
  if (c.ok()) {
    if (c->threads == 0 || c->max_queue == 0 || c->endpoint.empty()) std::abort();  // validated limits
    (void)procam::daemon::is_local_endpoint(c->endpoint);
  } else if (c.status().message().empty()) {
    std::abort();  // every refusal says why
  }
  return 0;
}
