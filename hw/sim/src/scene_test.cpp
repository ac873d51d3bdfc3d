// SPDX-License-Identifier: MIT
// Scene JSON parsing: values, defaults, and errors that name file and field.
#include "procam/hw/sim/scene.hpp"

#include <gtest/gtest.h>

#include "test_util.hpp"

namespace procam::sim {
namespace {

using test::temp_dir;
using test::write_text;

// Parses `objects_json` (the objects array text) from a fresh file; returns the status.
Status parse_objects(const std::string& objects_json, std::string* path_out = nullptr) {
  const std::string dir = temp_dir("scene");
  const std::string path = write_text(dir, "x.json", "{\"name\":\"x\",\"objects\":" + objects_json + "}");
  if (path_out) *path_out = path;
  return load_scene_file(path).status();
}

TEST(SceneParse, NegativeRadiusNamesFileAndField) {
  std::string path;
  Status st = parse_objects(R"([
    {"type":"plane","point_mm":[0,0,900],"normal":[0,0,-1]},
    {"type":"sphere","center_mm":[0,0,700],"radius_mm":50},
    {"type":"sphere","center_mm":[0,0,700],"radius_mm":-5}])", &path);
  ASSERT_FALSE(st.ok());
  EXPECT_EQ(st.code(), Code::invalid_argument);
  EXPECT_EQ(st.message(), path + ": objects[2].radius_mm: must be > 0, got -5.0");
}

TEST(SceneParse, MissingFieldNamesIt) {
  std::string path;
  Status st = parse_objects(R"([{"type":"sphere","center_mm":[0,0,700]}])", &path);
  ASSERT_FALSE(st.ok());
  EXPECT_NE(st.message().find(path + ": objects[0].radius_mm: missing"), std::string::npos) << st.message();
}

TEST(SceneParse, WrongTypeNamesFieldAndType) {
  Status st = parse_objects(R"([{"type":"box","center_mm":[0,0,700],"size_mm":"big"}])");
  ASSERT_FALSE(st.ok());
  EXPECT_NE(st.message().find("objects[0].size_mm: must be an array of 3 numbers"), std::string::npos) << st.message();
  st = parse_objects(R"([{"type":"sphere","center_mm":[0,0,700],"radius_mm":"50"}])");
  EXPECT_NE(st.message().find("objects[0].radius_mm: must be a number, got string"), std::string::npos) << st.message();
}

TEST(SceneParse, UnknownObjectTypeListsKnownOnes) {
  Status st = parse_objects(R"([{"type":"cone","center_mm":[0,0,700]}])");
  ASSERT_FALSE(st.ok());
  EXPECT_NE(st.message().find("objects[0].type: unknown object type 'cone'"), std::string::npos) << st.message();
  EXPECT_NE(st.hint().find("plane, box, sphere"), std::string::npos);
}

TEST(SceneParse, UnknownFieldIsRejected) {
  Status st = parse_objects(R"([{"type":"sphere","center_mm":[0,0,700],"radius":50}])");
  ASSERT_FALSE(st.ok());
  EXPECT_NE(st.message().find("objects[0].radius: unknown field"), std::string::npos) << st.message();
}

TEST(SceneParse, MaterialFieldsAreChecked) {
  Status st = parse_objects(R"([{"type":"sphere","center_mm":[0,0,700],"radius_mm":5,"material":{"albedo":1.5}}])");
  ASSERT_FALSE(st.ok());
  EXPECT_NE(st.message().find("objects[0].material.albedo: must be in [0.0, 1.0], got 1.5"), std::string::npos)
      << st.message();
}

TEST(SceneParse, ZeroNormalAndBoxSize) {
  Status st = parse_objects(R"([{"type":"plane","point_mm":[0,0,700],"normal":[0,0,0]}])");
  EXPECT_NE(st.message().find("objects[0].normal: must be a non-zero vector"), std::string::npos) << st.message();
  st = parse_objects(R"([{"type":"box","center_mm":[0,0,700],"size_mm":[10,0,10]}])");
  EXPECT_NE(st.message().find("objects[0].size_mm: all three edge lengths must be > 0"), std::string::npos)
      << st.message();
}

TEST(SceneParse, MissingFileIsNotFoundAndNamesPath) {
  auto r = load_scene_file("/nonexistent/dir/none.json");
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.status().code(), Code::not_found);
  EXPECT_NE(r.status().message().find("/nonexistent/dir/none.json"), std::string::npos);
}

TEST(SceneParse, BadJsonNamesFile) {
  const std::string dir = temp_dir("scene");
  const std::string path = write_text(dir, "bad.json", "{\"objects\": [ }");
  auto r = load_scene_file(path);
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.status().code(), Code::invalid_argument);
  EXPECT_EQ(r.status().message().rfind(path + ": not valid JSON", 0), 0u) << r.status().message();
}

TEST(SceneParse, RootFieldsChecked) {
  const std::string dir = temp_dir("scene");
  const std::string path = write_text(dir, "a.json", R"({"objects":[],"ambient":-1})");
  auto r = load_scene_file(path);
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.status().message().find(path + ": ambient: must be in [0.0, inf], got -1.0"), std::string::npos)
      << r.status().message();
  const std::string p2 = write_text(dir, "b.json", R"({"name":"b"})");
  EXPECT_NE(load_scene_file(p2).status().message().find(p2 + ": objects: missing"), std::string::npos);
}

TEST(SceneParse, ValuesAndDefaults) {
  const std::string dir = temp_dir("scene");
  const std::string path = write_text(dir, "v.json", R"({
    "description": "d", "ambient": 0.25,
    "objects": [
      {"type":"plane","point_mm":[1,2,900],"normal":[0,0,-2],"size_mm":[300,200],"u_axis":[1,0,0.5],
       "material":{"albedo":0.3}},
      {"type":"box","name":"b","center_mm":[0,0,700],"size_mm":[10,20,30],"euler_deg":[10,20,30]},
      {"type":"sphere","center_mm":[5,6,7],"radius_mm":8},
      {"type":"bowl","center_mm":[0,0,800],"radius_mm":50},
      {"type":"bowl","center_mm":[0,0,800],"radius_mm":50,"depth_mm":70}]})");
  auto r = load_scene_file(path);
  ASSERT_TRUE(r.ok()) << r.status().to_string();
  const Scene& s = *r;
  EXPECT_EQ(s.name, "v");  // file stem when "name" is absent
  EXPECT_EQ(s.description, "d");
  EXPECT_DOUBLE_EQ(s.ambient, 0.25);
  ASSERT_EQ(s.objects.size(), 5u);
  const Plane& p = std::get<Plane>(s.objects[0].shape);
  EXPECT_NEAR(p.normal.z, -1.0, 1e-15);
  EXPECT_TRUE(p.finite);
  EXPECT_DOUBLE_EQ(p.width_mm, 300);
  // u axis = (1,0,0.5) with its normal component removed → (1,0,0).
  EXPECT_NEAR(p.u_axis.x, 1.0, 1e-12);
  EXPECT_NEAR(p.u_axis.z, 0.0, 1e-12);
  EXPECT_NEAR(dot(p.v_axis, p.normal), 0.0, 1e-12);
  EXPECT_NEAR(norm(p.v_axis), 1.0, 1e-12);
  EXPECT_DOUBLE_EQ(s.objects[0].material.albedo, 0.3);
  const Box& b = std::get<Box>(s.objects[1].shape);
  EXPECT_EQ(s.objects[1].name, "b");
  EXPECT_DOUBLE_EQ(s.objects[1].material.albedo, 0.5);  // default material
  // R = Rz(30) Ry(20) Rx(10): compare one column with the closed form.
  const double d = M_PI / 180;
  const double cy = std::cos(20 * d), cz = std::cos(30 * d), sz = std::sin(30 * d), sy = std::sin(20 * d);
  EXPECT_NEAR(b.rotation(0, 0), cz * cy, 1e-12);
  EXPECT_NEAR(b.rotation(1, 0), sz * cy, 1e-12);
  EXPECT_NEAR(b.rotation(2, 0), -sy, 1e-12);
  EXPECT_DOUBLE_EQ(std::get<Sphere>(s.objects[2].shape).radius_mm, 8);
  EXPECT_DOUBLE_EQ(std::get<Bowl>(s.objects[3].shape).depth_mm, 50);  // default: hemisphere
  EXPECT_DOUBLE_EQ(std::get<Bowl>(s.objects[4].shape).depth_mm, 70);
}

TEST(SceneLookup, ByNameAndNotFoundListsScenes) {
  const std::string dir = temp_dir("scenes");
  write_text(dir, "alpha.json", R"({"objects":[]})");
  write_text(dir, "beta.json", R"({"name":"B","objects":[]})");
  auto r = load_scene("beta", {"/nonexistent", dir});
  ASSERT_TRUE(r.ok()) << r.status().to_string();
  EXPECT_EQ(r->name, "B");
  auto missing = load_scene("gamma", {dir});
  ASSERT_FALSE(missing.ok());
  EXPECT_EQ(missing.status().code(), Code::not_found);
  EXPECT_NE(missing.status().message().find("'gamma'"), std::string::npos);
  EXPECT_EQ(missing.status().hint(), "available scenes: alpha, beta");
  // A path (contains '/') is loaded directly; relative paths try base_dir first.
  auto by_path = load_scene("./alpha.json", {}, dir);
  EXPECT_TRUE(by_path.ok()) << by_path.status().to_string();
}

TEST(SceneLookup, ShippedScenesParse) {
  const std::string dir = test::configs_dir() + "/scenes";
  for (const char* name : {"plane", "tilted-box", "sphere"}) {
    auto r = load_scene(name, {dir});
    ASSERT_TRUE(r.ok()) << r.status().to_string();
    EXPECT_EQ(r->name, name);
    EXPECT_FALSE(r->objects.empty());
  }
}

}  // namespace
}  // namespace procam::sim
