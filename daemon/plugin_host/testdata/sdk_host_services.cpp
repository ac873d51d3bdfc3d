// SPDX-License-Identifier: MIT
// Test fixture: a plugin built with the C++ SDK whose session uses
// sdk::Session::log/progress from the calling thread AND from a worker
// thread; the SDK must deliver the worker's messages on the calling thread
// before end_round returns (checked in host_services_test.cpp).
#include <thread>

#include "procam/plugin_sdk.hpp"

namespace {

namespace sdk = procam::sdk;

class LoggingSession final : public sdk::Session {
 public:
  sdk::Error next_plan(sdk::Plan& plan, bool& has_round) override {
    if (decoded_) return sdk::ok();
    plan.add_frame("flat", 4, 3);
    has_round = true;
    return sdk::ok();
  }
  sdk::Error add_frame(uint32_t, const procam_image&) override {
    log(PROCAM_LOG_INFO, "frame added");
    return sdk::ok();
  }
  sdk::Error end_round() override {
    progress(0.25, "calling thread");
    std::thread worker([this] {
      log(PROCAM_LOG_WARN, "from the worker");
      progress(0.75, "worker");
    });
    worker.join();
    log(PROCAM_LOG_INFO, "round decoded");
    decoded_ = true;
    return sdk::ok();
  }
  sdk::Error outputs(sdk::Outputs& out) override {
    out.add_scalar("decoded", "", "1 once decoded", decoded_ ? 1.0 : 0.0);
    return sdk::ok();
  }

 private:
  bool decoded_ = false;
};

std::string describe() { return R"([{"name":"null"}])"; }
sdk::Error create(const sdk::CreateArgs&, std::unique_ptr<sdk::Session>& out) {
  out = std::make_unique<LoggingSession>();
  return sdk::ok();
}

}  // namespace

PROCAM_DEFINE_PLUGIN("sdk_host_services", "0.0.1", "null", describe, create);
