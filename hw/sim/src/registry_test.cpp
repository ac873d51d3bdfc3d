// SPDX-License-Identifier: MIT
// Backend registry: selection by name, errors that name the backend and list
// the available ones.
#include <gtest/gtest.h>

#include "procam/hw/rig.hpp"
#include "test_util.hpp"

namespace procam::hw {
namespace {

nlohmann::json rig_json() { return sim::test::read_json(sim::test::configs_dir() + "/rigs/sim.json"); }
RigContext context() { return {sim::test::configs_dir() + "/rigs", {sim::test::configs_dir() + "/scenes"}}; }

TEST(Registry, ListsSim) {
  // The sim backend comes first; hardware backends (issue 5) follow it.
  const auto b = available_backends();
  ASSERT_GE(b.size(), 1u);
  EXPECT_EQ(b[0], "sim");
}

TEST(Registry, UnknownBackendNamedWithAvailableList) {
  nlohmann::json j = rig_json();
  j["projector"]["backend"] = "holodeck";
  auto r = create_rig(j, context());
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.status().code(), Code::invalid_argument);
  EXPECT_NE(r.status().message().find("projector.backend: unknown backend 'holodeck'"), std::string::npos)
      << r.status().message();
  EXPECT_EQ(r.status().hint().rfind("available backends: sim", 0), 0u) << r.status().hint();

  j = rig_json();
  j["cameras"][0]["backend"] = "aravis-x";
  r = create_rig(j, context());
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.status().to_string().find("cameras[0].backend: unknown backend 'aravis-x'"), std::string::npos);
  EXPECT_NE(r.status().to_string().find("sim"), std::string::npos);

  j = rig_json();
  j["projector"].erase("backend");
  r = create_rig(j, context());
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.status().message().find("projector.backend: missing"), std::string::npos);
}

TEST(Registry, CreatesSimRigAndRejectsUnknownScanOption) {
  auto r = create_rig(rig_json(), context());
  ASSERT_TRUE(r.ok()) << r.status().to_string();
  Rig& rig = **r;
  EXPECT_EQ(rig.camera_count(), 1u);
  EXPECT_EQ(rig.projector().info().backend, "sim");
  EXPECT_EQ(rig.projector_intrinsics().width, 1280u);
  Status st = rig.apply_scan_options({{"exposure", 5}});
  EXPECT_EQ(st.code(), Code::invalid_argument);
  EXPECT_NE(st.message().find("'exposure'"), std::string::npos);
  EXPECT_TRUE(rig.apply_scan_options({{"scene", "tilted-box"}}).ok());
  EXPECT_EQ(rig.describe()["state"]["scene"], "tilted-box");
}

TEST(Registry, SimConfigErrorsPassThrough) {
  nlohmann::json j = rig_json();
  j["cameras"][0]["exposure_us"] = "long";
  auto r = create_rig(j, context());
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.status().message(), "rig config: cameras[0].exposure_us: must be a number, got string");
}

}  // namespace
}  // namespace procam::hw
