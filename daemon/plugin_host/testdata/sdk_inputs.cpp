// SPDX-License-Identifier: MIT
// Test fixture "inputs-fixture": an ABI 2 plugin built with the C++ SDK whose
// methods take an earlier scan's depth map (plugin_abi.h "Scan inputs"). Used
// by the plugin host's tests and by the daemon/CLI integration tests
// (tests/integration/inputs_test.cpp); never installed.
//
// Methods (each plans one white projector frame and checks the camera frame):
//   stats      input depth_mm (required, camera-sized): outputs
//              input_mean_mm (mean of the finite values), input_valid_count
//              (how many) and shifted_depth_mm = depth_mm + 10 (NaN stays NaN)
//   calibrate  input depth_mm (required): outputs JSON calibration_table, a
//              table in the procam-calibration-table v1 format whose samples
//              are the depth quantiles: x = q in {0, 0.1, ..., 1} ("quantile",
//              unit "fraction"), y = the valid depth at nearest rank
//              round(q * (n - 1)) of the sorted values (mm); a q whose depth
//              equals the previous one is dropped (y strictly increasing)
//   plain      no inputs: outputs frame_mean_dn
#include <algorithm>
#include <cmath>
#include <vector>

#include "procam/plugin_sdk.hpp"
#include "procam/sdk/calibration_table.hpp"

namespace {

namespace sdk = procam::sdk;

class FixtureSession final : public sdk::Session {
 public:
  FixtureSession(std::string method, sdk::Rig rig, std::vector<float> depth)
      : method_(std::move(method)), rig_(std::move(rig)), depth_(std::move(depth)) {}

  sdk::Error next_plan(sdk::Plan& plan, bool& has_round) override {
    if (decoded_) return sdk::ok();
    const uint32_t i = plan.add_frame("white", rig_.projector_width, rig_.projector_height);
    std::ranges::fill(plan.pattern_u8(i), uint8_t{255});
    has_round = true;
    return sdk::ok();
  }
  sdk::Error add_frame(uint32_t index, const procam_image& frame) override {
    const sdk::RigCamera& cam = rig_.cameras.at(0);
    if (sdk::Error e = sdk::check_frame(&frame, cam.width, cam.height, 1, "frame " + std::to_string(index));
        !e.ok())
      return e;
    std::vector<float> row(cam.width);
    double sum = 0;
    for (uint32_t y = 0; y < cam.height; ++y) {
      sdk::read_row(frame, y, row.data());
      for (float v : row) sum += double(v);
    }
    frame_mean_ = sum / (double(cam.width) * cam.height);
    return sdk::ok();
  }
  sdk::Error end_round() override {
    decoded_ = true;
    return sdk::ok();
  }
  sdk::Error outputs(sdk::Outputs& out) override {
    const sdk::RigCamera& cam = rig_.cameras.at(0);
    if (method_ == "plain") {
      out.add_scalar("frame_mean_dn", "DN", "mean of the captured frame", frame_mean_);
      return sdk::ok();
    }
    std::vector<float> valid;
    for (float v : depth_)
      if (std::isfinite(v)) valid.push_back(v);
    if (method_ == "stats") {
      double sum = 0;
      for (float v : valid) sum += double(v);
      out.add_scalar("input_mean_mm", "mm", "mean of the input's valid depths",
                     valid.empty() ? std::nan("") : sum / double(valid.size()));
      out.add_scalar("input_valid_count", "", "valid pixels of the input", double(valid.size()));
      std::vector<float> shifted(depth_);
      for (float& v : shifted) v += 10.f;  // NaN + 10 = NaN
      out.add_image("shifted_depth_mm", "mm", "the input depth + 10 mm", cam.width, cam.height,
                    std::move(shifted));
      return sdk::ok();
    }
    // calibrate: quantiles of the input as a table.
    if (valid.size() < 2) return sdk::invalid_argument("calibrate: the input depth map has < 2 valid pixels");
    std::sort(valid.begin(), valid.end());
    sdk::CalibrationTable table;
    table.name = "inputs-fixture.calibrate";
    table.x_name = "quantile";
    table.x_unit = "fraction";
    double last = -INFINITY;
    for (int k = 0; k <= 10; ++k) {
      const double q = k / 10.0;
      const double y = double(valid[static_cast<size_t>(std::lround(q * double(valid.size() - 1)))]);
      if (!(y > last)) continue;
      table.samples.emplace_back(q, y);
      last = y;
    }
    if (table.samples.size() < 2)
      return sdk::invalid_argument("calibrate: the input depth is constant; scan an inclined plane");
    table.extra = {{"valid_pixels", valid.size()}};
    table.made = {{"plugin", "inputs-fixture"}, {"method", "calibrate"}};
    out.add_json("calibration_table", "depth quantiles of the input as a calibration table",
                 sdk::to_json(table).dump());
    return sdk::ok();
  }

 private:
  std::string method_;
  sdk::Rig rig_;
  std::vector<float> depth_;  // copy of the input (camera-sized), empty for "plain"
  bool decoded_ = false;
  double frame_mean_ = 0;
};

std::string describe() {
  const sdk::InputSpec depth{"depth_mm", "image_f32", "mm", true, "a depth map of camera 0 (e.g. a gray scan's depth_mm)"};
  auto method = [](const char* name, const char* summary) {
    sdk::MethodDescription d;
    d.name = name;
    d.summary = summary;
    d.patterns = 1;
    return d;
  };
  sdk::MethodDescription stats = method("stats", "statistics of an input depth map");
  stats.outputs = {"input_mean_mm", "input_valid_count", "shifted_depth_mm"};
  stats.inputs = {depth};
  sdk::MethodDescription cal = method("calibrate", "depth quantiles as a calibration table");
  cal.outputs = {"calibration_table"};
  cal.inputs = {depth};
  sdk::MethodDescription plain = method("plain", "no inputs: mean of the frame");
  plain.outputs = {"frame_mean_dn"};
  return sdk::describe_methods({stats, cal, plain});
}

sdk::Error create(const sdk::CreateArgs& args, std::unique_ptr<sdk::Session>& out) {
  sdk::Params params;
  if (sdk::Error e = sdk::parse_params(args.params, {}, params, args.method); !e.ok()) return e;
  sdk::Rig rig;
  if (sdk::Error e = sdk::parse_rig(args.rig, rig); !e.ok()) return e;
  std::vector<float> depth;
  if (args.method != "plain")
    if (sdk::Error e = args.inputs.image_f32("depth_mm", rig.cameras[0].width, rig.cameras[0].height, depth);
        !e.ok())
      return e;
  out = std::make_unique<FixtureSession>(args.method, std::move(rig), std::move(depth));
  return sdk::ok();
}

}  // namespace

PROCAM_DEFINE_PLUGIN("inputs-fixture", "0.0.1", "stats,calibrate,plain", describe, create);
