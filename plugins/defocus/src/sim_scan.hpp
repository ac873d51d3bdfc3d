// SPDX-License-Identifier: MIT
// Test helper: a defocus sweep captured on the simulated co-located rig
// (configs/rigs/sim-colocated.json) through the real sim projector and camera
// (per-frame focus, noise, global light), at a reduced camera resolution, fed
// to the E3Accumulator exactly as the session does. Plus the scene's truth
// (depth and object id per pixel) from the sim's prepared view.
#pragma once

#include <gtest/gtest.h>

#include <algorithm>
#include <fstream>
#include <map>
#include <memory>
#include <sstream>
#include <string>

#include "e3_accumulator.hpp"
#include "procam/hw/sim/sim_rig.hpp"
#include "sweep_plan.hpp"

namespace procam::defocus::test {

struct SimSweep {
  std::unique_ptr<E3Accumulator> acc;
  std::vector<float> depth_mm;  // truth: camera z, NaN where no surface
  std::vector<int32_t> object;  // truth: scene object index, -1 none
  uint32_t width = 0, height = 0;
};

// `rig`: a co-located rig config in configs/rigs/ (sim-colocated, or
// sim-colocated-deep with its HDR camera for 0.3-2 m scenes).
inline nlohmann::json colocated_rig_json(uint32_t width, uint32_t height, const std::string& rig = "sim-colocated") {
  std::ifstream in(std::string(PROCAM_SOURCE_DIR) + "/configs/rigs/" + rig + ".json");
  std::stringstream ss;
  ss << in.rdbuf();
  nlohmann::json j = nlohmann::json::parse(ss.str());
  // Same field of view at a lower resolution: fx scales with the width.
  auto& k = j["cameras"][0]["intrinsics"];
  const double s = double(width) / k["width"].get<double>();
  k = {{"width", width}, {"height", height}, {"fx", 1800.0 * s}, {"fy", 1800.0 * s},
       {"cx", (width - 1) / 2.0}, {"cy", (height - 1) / 2.0}};
  j["threads"] = 2;
  return j;
}

// Captures the sweep `focus_mm` (24 shifted stripe frames per setting) of
// `scene` at width x height on rig config `rig_name`; bit depth 8 unless given
// (0: the rig config's); noiseless = no shot or read noise (light-transport
// claims, not noise ones).
inline SimSweep capture_sweep(const std::string& scene, const std::vector<double>& focus_mm, uint32_t width,
                              uint32_t height, uint32_t bit_depth = 8, bool noiseless = false,
                              const std::string& rig_name = "sim-colocated") {
  SimSweep out;
  nlohmann::json j = colocated_rig_json(width, height, rig_name);
  if (bit_depth == 0) bit_depth = j["cameras"][0]["bit_depth"].get<uint32_t>();
  j["cameras"][0]["bit_depth"] = bit_depth;
  if (noiseless) {
    j["cameras"][0]["shot_noise"] = false;
    j["cameras"][0]["read_noise_e"] = 0;
  }
  auto cfg = sim::parse_sim_rig_config(j);
  EXPECT_TRUE(cfg.ok()) << cfg.status().to_string();
  if (!cfg.ok()) return out;
  hw::RigContext ctx;
  ctx.scene_dirs = {std::string(PROCAM_SOURCE_DIR) + "/configs/scenes"};
  auto rig = sim::SimRig::create(*cfg, ctx);
  EXPECT_TRUE(rig.ok()) << rig.status().to_string();
  if (!rig.ok()) return out;
  sim::SimRig& r = **rig;
  const Status st = r.set_scene(scene);
  EXPECT_TRUE(st.ok()) << st.to_string();
  if (!st.ok()) return out;
  SweepConfig sweep;
  sweep.focus_mm = focus_mm;
  sdk::Plan plan;
  add_sweep_frames(plan, r.projector_intrinsics().width, r.projector_intrinsics().height, sweep);
  const double full = std::ldexp(1.0, int(bit_depth)) - 1.0;
  out.acc = std::make_unique<E3Accumulator>(width, height, uint32_t(focus_mm.size()),
                                            bit_depth > 8 ? PROCAM_PIXEL_U16 : PROCAM_PIXEL_U8, full, 2);
  const procam_plan* pv = plan.view();  // the C view the host sees
  for (uint32_t i = 0; i < pv->frame_count; ++i) {
    EXPECT_TRUE(r.projector().set_focus_mm(pv->frames[i].settings.projector_focus_mm).ok());
    const Status shown = r.projector().show(pv->frames[i].pattern, i + 1);
    EXPECT_TRUE(shown.ok()) << shown.to_string();
    if (!shown.ok()) return out;
    auto frame = r.camera(0).capture(std::chrono::milliseconds(1000));
    EXPECT_TRUE(frame.ok()) << frame.status().to_string();
    if (!frame.ok()) return out;
    const sdk::Error e = out.acc->add(i / kPeriodPx, i % kPeriodPx, frame->image.view());
    EXPECT_TRUE(e.ok()) << e.message;
  }
  const sim::PreparedView& v = r.renderer(0).view();
  out.depth_mm = v.depth_mm;
  out.object = v.object;
  out.width = width;
  out.height = height;
  return out;
}

// Writes `table` as configs/rigs/tables/<rig>-<name with '-' for '.'>.json
// into `dir` (PROCAM_DEFOCUS_WRITE_TABLES), with its provenance.
inline void write_table_file(const std::string& dir, const std::string& rig, const std::string& scene,
                             const std::string& made_by, sdk::CalibrationTable table) {
  table.made = {{"plugin", "defocus"}, {"method", table.extra.value("method", "")}, {"rig", rig},
                {"scene", scene}, {"depth_from", "sim ground truth"}, {"made_by", made_by}};
  std::string name = table.name;
  std::replace(name.begin(), name.end(), '.', '-');
  std::ofstream(dir + "/" + rig + "-" + name + ".json") << sdk::to_json(table).dump(1) << "\n";
}

// The committed table file of `rig` named like write_table_file's.
inline sdk::Error read_table_file(const std::string& rig, const std::string& table_name, sdk::CalibrationTable& out) {
  std::string name = table_name;
  std::replace(name.begin(), name.end(), '.', '-');
  std::ifstream in(std::string(PROCAM_SOURCE_DIR) + "/configs/rigs/tables/" + rig + "-" + name + ".json");
  if (!in.good()) return sdk::invalid_argument("missing table file for " + rig + " " + table_name);
  return sdk::parse_table(nlohmann::json::parse(in), out);
}

// EXPECTs `fresh` within rel_tol x depth of every sample of `committed` where
// fresh is defined; returns how many samples were compared.
inline size_t expect_tables_agree(const sdk::CalibrationTable& committed, const sdk::CalibrationTable& fresh,
                                  double rel_tol) {
  size_t compared = 0;
  for (const auto& [x, y] : committed.samples) {
    const float now = fresh.lookup(x);
    if (std::isnan(now)) continue;
    EXPECT_NEAR(now, y, rel_tol * y) << fresh.name << " at x " << x;
    ++compared;
  }
  return compared;
}

}  // namespace procam::defocus::test
