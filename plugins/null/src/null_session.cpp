// SPDX-License-Identifier: MIT
// The null plugin's sessions (see null_session.hpp).
#include "null_session.hpp"

#include <vector>

namespace procam::null_plugin {
namespace {

// One round of one frame: full white on the projector, the rig's default
// camera settings. The frame is checked against camera 0's size.
class NullSession final : public sdk::Session {
 public:
  NullSession(bool echo, const sdk::Rig& rig) : echo_(echo), rig_(rig) {}

  sdk::Error next_plan(sdk::Plan& plan, bool& has_round) override {
    if (planned_) return sdk::ok();  // one round only
    const uint32_t i = plan.add_frame("white", rig_.projector_width, rig_.projector_height);
    for (uint8_t& v : plan.pattern_u8(i)) v = 255;
    plan.set_note(echo_ ? "echo: one white frame, returned as it was captured"
                        : "null: one white frame, its mean value");
    planned_ = true;
    has_round = true;
    return sdk::ok();
  }

  sdk::Error add_frame(uint32_t index, const procam_image& frame) override {
    const sdk::RigCamera& cam = rig_.cameras[0];
    if (sdk::Error e = sdk::check_frame(&frame, cam.width, cam.height, 1, "frame " + std::to_string(index) + " (white)");
        !e.ok())
      return e;
    mean_ = mean_value(frame);
    if (echo_) {
      pixels_.resize(size_t{cam.width} * cam.height);
      for (uint32_t y = 0; y < cam.height; ++y) sdk::read_row(frame, y, pixels_.data() + size_t{y} * cam.width);
    }
    return sdk::ok();
  }

  sdk::Error end_round() override { return sdk::ok(); }

  sdk::Error outputs(sdk::Outputs& out) override {
    out.add_scalar("mean_dn", "DN", "mean camera value over the white frame (digital numbers)", mean_);
    if (echo_) {
      const sdk::RigCamera& cam = rig_.cameras[0];
      out.add_image("frame_dn", "DN", "the white frame as captured, as float digital numbers", cam.width, cam.height,
                    pixels_);
    }
    return sdk::ok();
  }

 private:
  bool echo_;
  sdk::Rig rig_;
  bool planned_ = false;
  double mean_ = 0;
  std::vector<float> pixels_;
};

}  // namespace

double mean_value(const procam_image& frame) {
  std::vector<float> row(frame.width);
  double sum = 0;
  for (uint32_t y = 0; y < frame.height; ++y) {
    sdk::read_row(frame, y, row.data());
    double row_sum = 0;  // per row first: keeps float rounding small on large frames
    for (float v : row) row_sum += double(v);
    sum += row_sum;
  }
  return sum / (double(frame.width) * double(frame.height));
}

nlohmann::json describe_methods() {
  const nlohmann::json outputs_null = {"mean_dn"};
  const nlohmann::json outputs_echo = {"mean_dn", "frame_dn"};
  return nlohmann::json::array(
      {{{"name", "null"},
        {"description", "One white frame; outputs its mean camera value (mean_dn). Decodes nothing: a check of "
                        "the capture machinery."},
        {"patterns", 1},
        {"rounds", 1},
        {"outputs", outputs_null},
        {"params", nlohmann::json::array()}},
       {{"name", "echo"},
        {"description", "One white frame; outputs it unchanged as an F32 map (frame_dn) and its mean (mean_dn)."},
        {"patterns", 1},
        {"rounds", 1},
        {"outputs", outputs_echo},
        {"params", nlohmann::json::array()}}});
}

sdk::Error create_session(const sdk::CreateArgs& args, std::unique_ptr<sdk::Session>& out) {
  sdk::Params params;
  if (sdk::Error e = sdk::parse_params(args.params, {}, params, args.method); !e.ok()) return e;
  sdk::Rig rig;
  if (sdk::Error e = sdk::parse_rig(args.rig, rig); !e.ok()) return e;
  out = std::make_unique<NullSession>(args.method == "echo", rig);
  return sdk::ok();
}

}  // namespace procam::null_plugin
