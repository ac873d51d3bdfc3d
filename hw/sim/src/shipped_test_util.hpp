// SPDX-License-Identifier: MIT
// Test helpers for tests that link procam_sim: the shipped rig and scenes.
#pragma once

#include <gtest/gtest.h>

#include <string>

#include "procam/hw/sim/scene.hpp"
#include "procam/hw/sim/sim_rig.hpp"
#include "test_util.hpp"

namespace procam::sim::test {

// The shipped default rig and scenes (test failure if they do not load).
inline SimRigConfig default_rig() {
  auto c = parse_sim_rig_config(read_json(configs_dir() + "/rigs/sim.json"));
  EXPECT_TRUE(c.ok()) << c.status().to_string();
  return c.ok() ? *c : SimRigConfig{};
}
inline Scene shipped_scene(const std::string& name) {
  auto s = load_scene(name, {configs_dir() + "/scenes"});
  EXPECT_TRUE(s.ok()) << s.status().to_string();
  return s.ok() ? *s : Scene{};
}

}  // namespace procam::sim::test
