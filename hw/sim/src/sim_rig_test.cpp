// SPDX-License-Identifier: MIT
// Sim rig adapters on the shipped configs: shadows in tilted-box against an
// independent shadow test, capture semantics, focus, scan options, ground
// truth files, multi-camera frames.
#include "procam/hw/sim/sim_rig.hpp"

#include <gtest/gtest.h>
#include <time.h>

#include <cmath>
#include <cstring>

#include "procam/core/image_io.hpp"
#include "procam/hw/sim/ground_truth.hpp"
#include "test_util.hpp"

namespace procam::sim {
namespace {

using namespace std::chrono_literals;

nlohmann::json rig_json() { return test::read_json(test::configs_dir() + "/rigs/sim.json"); }
hw::RigContext context() {
  return {test::configs_dir() + "/rigs", {test::configs_dir() + "/scenes"}};
}
std::unique_ptr<SimRig> make_rig(const nlohmann::json& j) {
  auto cfg = parse_sim_rig_config(j);
  EXPECT_TRUE(cfg.ok()) << cfg.status().to_string();
  if (!cfg.ok()) return nullptr;
  auto rig = SimRig::create(*cfg, context());
  EXPECT_TRUE(rig.ok()) << rig.status().to_string();
  return rig.ok() ? std::move(rig).value() : nullptr;
}
int64_t now_ns() {
  timespec ts{};
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return ts.tv_sec * 1000000000LL + ts.tv_nsec;
}
Image constant_pattern(const hw::Rig& rig, uint8_t value) {
  const Intrinsics& k = const_cast<hw::Rig&>(rig).projector_intrinsics();
  Image im(k.width, k.height, PixelType::u8);
  std::fill(im.data(), im.data() + im.size_bytes(), value);
  return im;
}
double mean_where(const Image& im, const hw::GroundTruth& gt, bool lit) {
  double sum = 0;
  size_t n = 0;
  for (size_t i = 0; i < im.pixel_count(); ++i) {
    if ((gt.lit.ptr<uint8_t>()[i] != 0) != lit) continue;
    sum += im.type() == PixelType::u8 ? im.ptr<uint8_t>()[i] : im.ptr<uint16_t>()[i];
    ++n;
  }
  return n ? sum / static_cast<double>(n) : std::nan("");
}

TEST(SimRig, TiltedBoxShadowsMatchIndependentTest) {
  auto rig = make_rig(rig_json());
  ASSERT_TRUE(rig);
  ASSERT_TRUE(rig->apply_scan_options({{"scene", "tilted-box"}}).ok());
  const Scene& scene = rig->scene();
  const Plane& bg = std::get<Plane>(scene.objects[0].shape);
  const Box& box = std::get<Box>(scene.objects[1].shape);
  auto gt = rig->ground_truth(0);
  ASSERT_TRUE(gt.ok());
  const CameraCalibration& cal = rig->camera_calibrations()[0];
  const Intrinsics& K = cal.intrinsics;
  const Intrinsics& Kp = rig->projector_intrinsics();
  const Rigid3 proj_from_cam = cal.cam_from_proj.inverse();
  const Vec3 c_p = cal.cam_from_proj.translation_mm;
  const Vec3 half = box.size_mm * 0.5;
  size_t shadow = 0, plane_lit = 0, box_lit = 0, box_away = 0;
  for (uint32_t y = 0; y < K.height; y += 2) {
    for (uint32_t x = 0; x < K.width; x += 2) {
      const double z = gt->depth_mm.at<float>(x, y);
      const Vec3 X{(x - K.cx) / K.fx * z, (y - K.cy) / K.fy * z, z};
      const bool lit = gt->lit.at<uint8_t>(x, y) == 255;
      const Vec3 xp = proj_from_cam * X;
      double u = 0, v = 0;
      Kp.project(xp, u, v);
      const bool inside = u >= -0.5 && u < Kp.width - 0.5 && v >= -0.5 && v < Kp.height - 0.5;
      if (std::abs(dot(normalized(bg.normal), X - bg.point_mm)) < 0.05) {
        // On the background plane: lit iff the segment to the projector misses the box.
        auto s = test::ref_ray_box(c_p, X - c_p, box.center_mm, box.rotation, half);
        const bool blocked = s && *s < 1.0 - 1e-6;
        if (std::abs(u - Kp.width / 2.0) > Kp.width / 2.0 - 2) continue;  // skip projector border ±2 px
        ASSERT_TRUE(inside);
        if (blocked) {
          ASSERT_FALSE(lit) << "shadowed plane pixel " << x << "," << y;
          ++shadow;
        } else {
          // Skip the shadow boundary where float depth can flip the test.
          auto s2 = test::ref_ray_box(c_p, (X - c_p) * 1.0, box.center_mm, box.rotation, half * 1.002);
          if (s2 && *s2 < 1.0) continue;
          ASSERT_TRUE(lit) << "unshadowed plane pixel " << x << "," << y;
          ++plane_lit;
        }
      } else {
        // On the box: find the face (outward normal) and compare with facing.
        const Vec3 local = box.rotation.transposed() * (X - box.center_mm);
        const double hs[3] = {half.x, half.y, half.z};
        // Face = the axis whose |local| is closest to its half size; skip
        // pixels within 0.5 mm of an edge (two faces nearly tie).
        double gap[3];
        for (int a = 0; a < 3; ++a) gap[a] = std::abs(std::abs(local[a]) - hs[a]);
        int face = 0;
        for (int a = 1; a < 3; ++a)
          if (gap[a] < gap[face]) face = a;
        ASSERT_LT(gap[face], 0.05) << "pixel " << x << "," << y << " is on neither plane nor box";
        bool edge = false;
        for (int a = 0; a < 3; ++a) edge = edge || (a != face && gap[a] < 0.5);
        if (edge) continue;
        const double sign = local[face] > 0 ? 1.0 : -1.0;
        const Vec3 n = box.rotation * Vec3{face == 0 ? sign : 0, face == 1 ? sign : 0, face == 2 ? sign : 0};
        const double facing = dot(n, normalized(c_p - X));
        if (std::abs(facing) < 1e-3) continue;
        if (facing > 0) {
          // A convex box face that faces the projector is never shadowed (nothing else is in front).
          ASSERT_TRUE(lit) << "box pixel facing the projector " << x << "," << y;
          ++box_lit;
        } else {
          ASSERT_FALSE(lit) << "box pixel facing away " << x << "," << y << " local " << local.x << " "
                            << local.y << " " << local.z << " face " << face << " facing " << facing;
          ++box_away;
        }
      }
    }
  }
  EXPECT_GT(shadow, 2000u);
  EXPECT_GT(plane_lit, 50000u);
  EXPECT_GT(box_lit, 20000u);
  // In this scene every face the camera sees also faces the projector (the
  // top face only at grazing incidence), so box_away stays 0; the branch
  // above still checks any that do.
  EXPECT_EQ(box_away, 0u);
}

TEST(SimRig, CaptureShowsPatternWithIncreasingIdsAndMonotonicTime) {
  auto rig = make_rig(rig_json());
  ASSERT_TRUE(rig);
  hw::Projector& proj = rig->projector();
  hw::Camera& cam = rig->camera(0);
  EXPECT_EQ(cam.info().backend, "sim");
  EXPECT_EQ(cam.info().width, 1280u);
  EXPECT_EQ(proj.info().width, 1280u);
  auto gt = rig->ground_truth(0);
  ASSERT_TRUE(gt.ok());

  // Left half white, right half black.
  Image half(1280, 800, PixelType::u8);
  for (uint32_t y = 0; y < 800; ++y)
    for (uint32_t x = 0; x < 640; ++x) half.at<uint8_t>(x, y) = 255;
  ASSERT_TRUE(proj.show(half.view(), 7).ok());
  const int64_t t0 = now_ns();
  auto pres = proj.wait_presented(7, 100ms);
  ASSERT_TRUE(pres.ok());
  EXPECT_EQ(pres->pattern_id, 7u);
  EXPECT_GE(pres->shown_ns, t0);
  EXPECT_LE(pres->shown_ns, now_ns());
  auto bad = proj.wait_presented(8, 100ms);
  ASSERT_FALSE(bad.ok());
  EXPECT_EQ(bad.status().code(), Code::failed_precondition);

  auto f1 = cam.capture(100ms);
  auto f2 = cam.capture(100ms);
  ASSERT_TRUE(f1.ok() && f2.ok());
  EXPECT_EQ(f2->frame_id, f1->frame_id + 1);
  EXPECT_GE(f2->timestamp_ns, f1->timestamp_ns);
  EXPECT_GE(f1->timestamp_ns, t0);
  EXPECT_EQ(f1->image.type(), PixelType::u8);
  // Pixels whose projector column is well inside the white half are bright.
  size_t bright = 0, dark = 0;
  for (size_t i = 0; i < f1->image.pixel_count(); ++i) {
    const float col = gt->proj_col.ptr<float>()[i];
    if (std::isnan(col)) continue;
    const uint8_t dn = f1->image.ptr<uint8_t>()[i];
    if (col < 630) { ASSERT_GT(dn, 100) << i; ++bright; }
    if (col > 650) { ASSERT_LT(dn, 12) << i; ++dark; }
  }
  EXPECT_GT(bright, 100000u);
  EXPECT_GT(dark, 100000u);
  // Successive frames of the same pattern differ only by noise.
  size_t differ = 0;
  for (size_t i = 0; i < f1->image.pixel_count(); ++i)
    differ += f1->image.ptr<uint8_t>()[i] != f2->image.ptr<uint8_t>()[i] ? 1u : 0u;
  EXPECT_GT(differ, f1->image.pixel_count() / 4);
  // A malformed pattern is refused with both sizes named.
  Image small(640, 400, PixelType::u8);
  Status st = proj.show(small.view(), 9);
  EXPECT_EQ(st.code(), Code::invalid_argument);
  EXPECT_NE(st.message().find("640x400"), std::string::npos);
}

TEST(SimRig, DefaultExposureReadsSeventyToEightyPercentOnWhitePlane) {
  auto rig = make_rig(rig_json());
  ASSERT_TRUE(rig);
  const Image white = constant_pattern(*rig, 255);
  ASSERT_TRUE(rig->projector().show(white.view(), 1).ok());
  auto f = rig->camera(0).capture(100ms);
  ASSERT_TRUE(f.ok());
  auto gt = rig->ground_truth(0);
  const double mean = mean_where(f->image, *gt, true);
  EXPECT_GT(mean / 255.0, 0.70);
  EXPECT_LT(mean / 255.0, 0.80);
}

TEST(SimRig, ExposureGainAndFocusSettings) {
  nlohmann::json j = rig_json();
  j["cameras"][0]["shot_noise"] = false;
  j["cameras"][0]["read_noise_e"] = 0;
  j["cameras"][0]["bit_depth"] = 12;
  j["projector"]["aperture_mm"] = 20;
  auto rig = make_rig(j);
  ASSERT_TRUE(rig);
  auto gt = rig->ground_truth(0);
  const Image grey = constant_pattern(*rig, 128);
  ASSERT_TRUE(rig->projector().show(grey.view(), 1).ok());
  hw::Camera& cam = rig->camera(0);
  auto base = cam.capture(100ms);
  ASSERT_TRUE(cam.configure({6000, -1, NAN}).ok());
  auto half_exposure = cam.capture(100ms);
  ASSERT_TRUE(cam.configure({6000, 20 * std::log10(2.0), 33.0}).ok());
  auto gained = cam.capture(100ms);
  ASSERT_TRUE(cam.configure({}).ok());  // back to defaults
  auto again = cam.capture(100ms);
  const double m0 = mean_where(base->image, *gt, true), m1 = mean_where(half_exposure->image, *gt, true);
  EXPECT_EQ(base->image.type(), PixelType::u16);
  EXPECT_NEAR(m1 / m0, 0.5, 0.002);
  // Half exposure × 2 gain, through an analyser at 33°: surface light is
  // depolarized, so the analyser passes half of it (docs/media.md).
  EXPECT_NEAR(mean_where(gained->image, *gt, true) / m0, 0.5, 0.002);
  EXPECT_EQ(0, std::memcmp(base->image.data(), again->image.data(), base->image.size_bytes()));
  EXPECT_EQ(cam.configure({2e7, -1, NAN}).code(), Code::invalid_argument);

  // Focus: a fine stripe pattern loses contrast when the projector focuses at 400 mm.
  Image stripes(1280, 800, PixelType::u8);
  for (uint32_t y = 0; y < 800; ++y)
    for (uint32_t x = 0; x < 1280; ++x) stripes.at<uint8_t>(x, y) = (x / 4) % 2 ? 255 : 0;
  ASSERT_TRUE(rig->projector().show(stripes.view(), 2).ok());
  auto contrast = [&] {
    auto f = cam.capture(100ms);
    double lo = 1e9, hi = 0;
    for (uint32_t x = 500; x < 700; ++x) {
      const double v = f->image.at<uint16_t>(x, 400);
      lo = std::min(lo, v);
      hi = std::max(hi, v);
    }
    return (hi - lo) / (hi + lo);
  };
  const double sharp = contrast();
  ASSERT_TRUE(rig->projector().set_focus_mm(400).ok());
  EXPECT_DOUBLE_EQ(rig->current_focus_mm(), 400);
  const double blurred = contrast();
  ASSERT_TRUE(rig->projector().set_focus_mm(0).ok());
  const double restored = contrast();
  EXPECT_GT(sharp, 0.8);
  EXPECT_LT(blurred, 0.1);  // σ ≈ 20·1600·(1/400 − 1/800)/4 = 10 px ≫ stripe width 4 px
  EXPECT_DOUBLE_EQ(restored, sharp);
  EXPECT_EQ(rig->describe()["state"]["projector_focus_mm"].get<double>(), 800.0);
}

// The projector polariser angle (procam_frame_settings.projector_polarizer_deg)
// is accepted and recorded, not dropped; without a medium it does not change
// the image (surface reflection depolarizes; medium_test covers the medium).
TEST(SimRig, ProjectorPolarizerIsRecordedNotYetModelled) {
  nlohmann::json j = rig_json();
  j["cameras"][0]["shot_noise"] = false;  // noise-free: two captures of one pattern are equal
  j["cameras"][0]["read_noise_e"] = 0;
  auto rig = make_rig(j);
  ASSERT_TRUE(rig);
  auto& proj = dynamic_cast<SimProjector&>(rig->projector());
  EXPECT_TRUE(std::isnan(proj.polarizer_deg()));
  Image pattern = constant_pattern(*rig, 180);
  ASSERT_TRUE(rig->projector().show(pattern.view(), 1).ok());
  auto without = rig->camera(0).capture(100ms);
  ASSERT_TRUE(without.ok());

  ASSERT_TRUE(rig->projector().set_polarizer_deg(37.5).ok());
  EXPECT_DOUBLE_EQ(proj.polarizer_deg(), 37.5);
  auto with = rig->camera(0).capture(100ms);
  ASSERT_TRUE(with.ok());
  ASSERT_EQ(with->image.size_bytes(), without->image.size_bytes());
  EXPECT_EQ(std::memcmp(with->image.data(), without->image.data(), with->image.size_bytes()), 0);

  Status st = rig->projector().set_polarizer_deg(-INFINITY);
  EXPECT_EQ(st.code(), Code::invalid_argument) << st.to_string();
  EXPECT_DOUBLE_EQ(proj.polarizer_deg(), 37.5) << "a refused value leaves the angle unchanged";
  ASSERT_TRUE(rig->projector().set_polarizer_deg(std::nan("")).ok());
  EXPECT_TRUE(std::isnan(proj.polarizer_deg()));
}

TEST(SimRig, DeterministicForSeed) {
  auto a = make_rig(rig_json()), b = make_rig(rig_json());
  nlohmann::json j = rig_json();
  j["seed"] = 2;
  auto c = make_rig(j);
  ASSERT_TRUE(a && b && c);
  const Image grey = constant_pattern(*a, 200);
  for (SimRig* r : {a.get(), b.get(), c.get()}) ASSERT_TRUE(r->projector().show(grey.view(), 1).ok());
  auto fa = a->camera(0).capture(100ms), fb = b->camera(0).capture(100ms), fc = c->camera(0).capture(100ms);
  EXPECT_EQ(0, std::memcmp(fa->image.data(), fb->image.data(), fa->image.size_bytes()));
  EXPECT_NE(0, std::memcmp(fa->image.data(), fc->image.data(), fa->image.size_bytes()));
}

// Every scan (apply_scan_options) restarts the frame sequence: the same
// frame index of two scans carries the same noise, while frames within a
// scan differ (bench compares methods on the frames they share).
TEST(SimRig, EachScanRestartsTheFrameSequence) {
  auto rig = make_rig(rig_json());
  ASSERT_TRUE(rig);
  const Image grey = constant_pattern(*rig, 200);
  std::vector<hw::Frame> first, second;
  for (std::vector<hw::Frame>* scan : {&first, &second}) {
    ASSERT_TRUE(rig->apply_scan_options(nlohmann::json::object()).ok());
    for (int k = 0; k < 2; ++k) {
      ASSERT_TRUE(rig->projector().show(grey.view(), uint64_t(k + 1)).ok());
      auto f = rig->camera(0).capture(100ms);
      ASSERT_TRUE(f.ok());
      scan->push_back(std::move(*f));
    }
  }
  EXPECT_EQ(first[0].frame_id, 1u);
  EXPECT_EQ(second[0].frame_id, 1u);
  EXPECT_EQ(second[1].frame_id, 2u);
  EXPECT_EQ(0, std::memcmp(first[0].image.data(), second[0].image.data(), first[0].image.size_bytes()));
  EXPECT_EQ(0, std::memcmp(first[1].image.data(), second[1].image.data(), first[1].image.size_bytes()));
  EXPECT_NE(0, std::memcmp(first[0].image.data(), first[1].image.data(), first[0].image.size_bytes()));
}

TEST(SimRig, DescribeScanOptionsAndErrors) {
  auto rig = make_rig(rig_json());
  ASSERT_TRUE(rig);
  nlohmann::json d = rig->describe();
  EXPECT_EQ(d["name"], "sim");
  EXPECT_EQ(d["state"]["scene"], "plane");
  EXPECT_EQ(d["backends"]["projector"], "sim");
  EXPECT_EQ(d["projector"]["width"], 1280);
  ASSERT_EQ(d["cameras"].size(), 1u);
  const CameraCalibration cal = d["cameras"][0]["calibration"].get<CameraCalibration>();
  const CameraCalibration& truth = rig->camera_calibrations()[0];
  EXPECT_DOUBLE_EQ(cal.intrinsics.fx, truth.intrinsics.fx);
  for (int k = 0; k < 9; ++k) EXPECT_DOUBLE_EQ(cal.cam_from_proj.rotation.m[static_cast<size_t>(k)],
                                               truth.cam_from_proj.rotation.m[static_cast<size_t>(k)]);
  EXPECT_DOUBLE_EQ(cal.cam_from_proj.translation_mm.x, 175.0);

  ASSERT_TRUE(rig->apply_scan_options({{"scene", "sphere"}}).ok());
  EXPECT_EQ(rig->describe()["state"]["scene"], "sphere");
  Status st = rig->apply_scan_options({{"scene", "sphere"}, {"bogus", 1}});
  EXPECT_EQ(st.code(), Code::invalid_argument);
  EXPECT_NE(st.message().find("'bogus'"), std::string::npos);
  st = rig->apply_scan_options({{"scene", 3}});
  EXPECT_EQ(st.code(), Code::invalid_argument);
  EXPECT_NE(st.message().find("rig_options.scene"), std::string::npos);
  st = rig->apply_scan_options({{"scene", "no-such-scene"}});
  EXPECT_EQ(st.code(), Code::invalid_argument);  // the client named something that is not a scene
  EXPECT_NE(st.hint().find("tilted-box"), std::string::npos);
  // Names only: rig_options come from remote clients and never name host files.
  for (const char* bad : {"/etc/passwd", "../scenes/plane", "plane.json", "a/../b", "", "sp ace"}) {
    st = rig->check_scan_options({{"scene", bad}});
    EXPECT_EQ(st.code(), Code::invalid_argument) << bad;
    EXPECT_NE(st.message().find("not a scene name"), std::string::npos) << bad << ": " << st.message();
  }
  EXPECT_TRUE(rig->check_scan_options({{"scene", "sphere"}}).ok());
  EXPECT_EQ(rig->check_scan_options({{"scene", "nope"}}).code(), Code::invalid_argument);
  EXPECT_EQ(rig->check_scan_options(nlohmann::json::array()).code(), Code::invalid_argument);
  EXPECT_EQ(rig->describe()["state"]["scene"], "sphere");  // a failed switch keeps the scene
  ASSERT_TRUE(rig->apply_scan_options(nlohmann::json::object()).ok());
  EXPECT_EQ(rig->describe()["state"]["scene"], "plane");  // no "scene": the configured default
  // A path is not a scene name, even to a real scene file (local tools load
  // files with set_scene or add the folder to the rig's scene folders).
  st = rig->apply_scan_options({{"scene", test::configs_dir() + "/scenes/tilted-box.json"}});
  EXPECT_EQ(st.code(), Code::invalid_argument);
  ASSERT_TRUE(rig->set_scene(test::configs_dir() + "/scenes/tilted-box.json").ok());
  EXPECT_EQ(rig->scene().name, "tilted-box");

  auto gt = rig->ground_truth(3);
  EXPECT_EQ(gt.status().code(), Code::not_found);
}

TEST(SimRig, ConfigErrorsNameTheField) {
  nlohmann::json j = rig_json();
  j["cameras"][0]["bit_depth"] = 4;
  auto r = parse_sim_rig_config(j);
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.status().message(), "rig config: cameras[0].bit_depth: must be in [8, 16], got 4");
  j = rig_json();
  j["projector"]["intrinsics"].erase("fx");
  EXPECT_NE(parse_sim_rig_config(j).status().message().find("projector.intrinsics.fx: missing"), std::string::npos);
  j = rig_json();
  j["cameras"][0]["cam_from_proj"]["rotation"] = {1, 0, 0, 0, 1, 0, 0, 0, 2};
  EXPECT_NE(parse_sim_rig_config(j).status().message().find("give either rotation or euler_deg"), std::string::npos);
  j["cameras"][0]["cam_from_proj"].erase("euler_deg");
  EXPECT_NE(parse_sim_rig_config(j).status().message().find("cameras[0].cam_from_proj.rotation: must be a proper rotation"),
            std::string::npos);
  j = rig_json();
  j["exposure"] = 1;
  EXPECT_NE(parse_sim_rig_config(j).status().message().find("exposure: unknown field"), std::string::npos);
  // Camera lens (defocus): parsed, range-checked, unknown keys named.
  j = rig_json();
  j["cameras"][0]["lens"] = {{"aperture_mm", 8}, {"focus_mm", 600}};
  auto lens = parse_sim_rig_config(j);
  ASSERT_TRUE(lens.ok()) << lens.status().message();
  EXPECT_EQ(lens->cameras[0].lens.aperture_mm, 8.0);
  EXPECT_EQ(lens->cameras[0].lens.focus_mm, 600.0);
  EXPECT_EQ(parse_sim_rig_config(rig_json())->cameras[0].lens.aperture_mm, 0.0);  // default: pinhole
  j["cameras"][0]["lens"]["f_number"] = 2;
  EXPECT_NE(parse_sim_rig_config(j).status().message().find("cameras[0].lens.f_number: unknown field"),
            std::string::npos);
  j["cameras"][0]["lens"] = {{"aperture_mm", -1}};
  EXPECT_NE(parse_sim_rig_config(j).status().message().find("cameras[0].lens.aperture_mm"), std::string::npos);
  j = rig_json();
  j["scene"] = "missing-scene";
  auto cfg = parse_sim_rig_config(j);
  ASSERT_TRUE(cfg.ok());
  auto rig = SimRig::create(*cfg, context());
  ASSERT_FALSE(rig.ok());
  EXPECT_NE(rig.status().message().find("\"scene\""), std::string::npos);
}

TEST(SimRig, GroundTruthFilesRoundTrip) {
  auto rig = make_rig(rig_json());
  ASSERT_TRUE(rig);
  ASSERT_TRUE(rig->apply_scan_options({{"scene", "tilted-box"}}).ok());
  auto gt = rig->ground_truth(0);
  ASSERT_TRUE(gt.ok());
  const std::string dir = test::temp_dir("gt") + "/nested";
  ASSERT_TRUE(write_ground_truth(*gt, dir, {{"scene", "tilted-box"}}).ok());
  auto depth = read_image(dir + "/depth_mm.exr");
  auto col = read_image(dir + "/proj_col.exr");
  auto lit = read_image(dir + "/lit.png");
  ASSERT_TRUE(depth.ok() && col.ok() && lit.ok());
  ASSERT_EQ(depth->type(), PixelType::f32);
  ASSERT_EQ(lit->type(), PixelType::u8);
  for (size_t i = 0; i < gt->depth_mm.pixel_count(); i += 97) {
    EXPECT_EQ(depth->ptr<float>()[i], gt->depth_mm.ptr<float>()[i]);
    const float c = gt->proj_col.ptr<float>()[i];
    if (std::isnan(c)) {
      EXPECT_TRUE(std::isnan(col->ptr<float>()[i]));
    } else {
      EXPECT_EQ(col->ptr<float>()[i], c);
    }
    EXPECT_EQ(lit->ptr<uint8_t>()[i], gt->lit.ptr<uint8_t>()[i]);
  }
}

TEST(SimRig, SecondCameraSeesTheSameWorld) {
  nlohmann::json j = rig_json();
  nlohmann::json cam1 = j["cameras"][0];
  cam1["id"] = "sim1";
  cam1["intrinsics"] = {{"width", 640}, {"height", 400}, {"fx", 900.0}, {"fy", 900.0}, {"cx", 319.5}, {"cy", 199.5}};
  // Camera 1 sits 175 mm to the projector's right, verged the other way.
  cam1["cam_from_proj"] = {{"euler_deg", {0.0, 12.0, 0.0}}, {"translation_mm", {-175.0, 10.0, 5.0}}};
  cam1["bit_depth"] = 12;
  j["cameras"].push_back(cam1);
  auto rig = make_rig(j);
  ASSERT_TRUE(rig);
  ASSERT_EQ(rig->camera_count(), 2u);
  EXPECT_EQ(rig->describe()["cameras"][1]["id"], "sim1");
  auto gt1 = rig->ground_truth(1);
  ASSERT_TRUE(gt1.ok());
  EXPECT_EQ(gt1->depth_mm.width(), 640u);
  // Points from camera 1's depth map, moved into camera 0's frame
  // (cam0_from_cam1 = cam0_from_proj · proj_from_cam1), lie on the scene plane.
  const auto& cals = rig->camera_calibrations();
  const Rigid3 cam0_from_cam1 = cals[0].cam_from_proj * cals[1].cam_from_proj.inverse();
  const Plane& pl = std::get<Plane>(rig->scene().objects[0].shape);
  const Intrinsics& K = cals[1].intrinsics;
  size_t checked = 0;
  for (uint32_t y = 0; y < K.height; y += 7) {
    for (uint32_t x = 0; x < K.width; x += 7) {
      const double z = gt1->depth_mm.at<float>(x, y);
      ASSERT_TRUE(std::isfinite(z));
      const Vec3 X1{(x - K.cx) / K.fx * z, (y - K.cy) / K.fy * z, z};
      ASSERT_NEAR(dot(pl.normal, cam0_from_cam1 * X1 - pl.point_mm), 0.0, 1e-2);
      ++checked;
    }
  }
  EXPECT_GT(checked, 4000u);
  const Image white = constant_pattern(*rig, 255);
  ASSERT_TRUE(rig->projector().show(white.view(), 1).ok());
  auto f1 = rig->camera(1).capture(100ms);
  ASSERT_TRUE(f1.ok());
  EXPECT_EQ(f1->camera_index, 1u);
  EXPECT_EQ(f1->image.type(), PixelType::u16);
  EXPECT_GT(mean_where(f1->image, *gt1, true), 0.5 * 4095);
}

}  // namespace
}  // namespace procam::sim

namespace procam::sim {
namespace {

// The defaults must keep defocus and noise modest enough for the Gray-code
// accuracy test (≥ 99 % of lit pixels within one column). Decode here is the
// textbook one (bit = pattern > inverse), independent of the plugin.
TEST(SimRig, DefaultsSupportGrayCodeDecoding) {
  for (const char* scene : {"plane", "tilted-box"}) {
    auto rig = make_rig(rig_json());
    ASSERT_TRUE(rig);
    ASSERT_TRUE(rig->apply_scan_options({{"scene", scene}}).ok());
    auto gt = rig->ground_truth(0);
    ASSERT_TRUE(gt.ok());
    const uint32_t W = rig->projector_intrinsics().width, H = rig->projector_intrinsics().height;
    const int bits = 11;  // 2048 ≥ 1280 columns
    std::vector<uint32_t> gray(gt->lit.pixel_count(), 0);
    Image pattern(W, H, PixelType::u8), inverse(W, H, PixelType::u8);
    uint64_t id = 0;
    for (int b = bits - 1; b >= 0; --b) {
      for (uint32_t y = 0; y < H; ++y) {
        for (uint32_t x = 0; x < W; ++x) {
          const uint8_t on = ((x ^ (x >> 1)) >> b) & 1u ? 255 : 0;
          pattern.at<uint8_t>(x, y) = on;
          inverse.at<uint8_t>(x, y) = static_cast<uint8_t>(255 - on);
        }
      }
      ASSERT_TRUE(rig->projector().show(pattern.view(), ++id).ok());
      auto f1 = rig->camera(0).capture(100ms);
      ASSERT_TRUE(rig->projector().show(inverse.view(), ++id).ok());
      auto f2 = rig->camera(0).capture(100ms);
      ASSERT_TRUE(f1.ok() && f2.ok());
      for (size_t i = 0; i < gray.size(); ++i)
        gray[i] = (gray[i] << 1) | (f1->image.ptr<uint8_t>()[i] > f2->image.ptr<uint8_t>()[i] ? 1u : 0u);
    }
    size_t lit = 0, within1 = 0;
    for (size_t i = 0; i < gray.size(); ++i) {
      if (gt->lit.ptr<uint8_t>()[i] == 0) continue;
      ++lit;
      uint32_t col = 0;
      for (uint32_t g = gray[i]; g != 0; g >>= 1) col ^= g;  // Gray → binary
      within1 += std::abs(static_cast<double>(col) - static_cast<double>(gt->proj_col.ptr<float>()[i])) <= 1.0 ? 1u : 0u;
    }
    EXPECT_GT(lit, 900000u) << scene;
    EXPECT_GE(static_cast<double>(within1), 0.99 * static_cast<double>(lit)) << scene;
  }
}

}  // namespace
}  // namespace procam::sim
