// SPDX-License-Identifier: MIT
// Chessboard albedo textures and lens distortion in the sim (issue 16 item 1):
// strict parsing, the anti-aliased pixel footprint against a closed-form box
// filter, that a texture or zero distortion leaves the renderer exactly as
// before, and that a distorted camera's and projector's ground truth follows
// OpenCV's forward model (written out here, independently of
// procam/base/calibration.hpp).
#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <string>
#include <vector>

#include "procam/hw/sim/renderer.hpp"
#include "procam/hw/sim/scene.hpp"
#include "procam/hw/sim/sim_rig.hpp"
#include "procam/hw/sim/texture.hpp"
#include "test_util.hpp"

namespace procam::sim {
namespace {

using test::temp_dir;
using test::write_text;

Result<Scene> parse_text(const std::string& objects_json) {
  return parse_scene(nlohmann::json::parse("{\"name\":\"t\",\"objects\":" + objects_json + "}"), "t.json");
}

std::string board_plane(const std::string& texture, const std::string& extra = "") {
  return R"([{"type":"plane","point_mm":[0,0,800],"normal":[0,0,-1],"size_mm":[360,300])" + extra +
         R"(,"texture":)" + texture + "}]";
}

TEST(TextureParse, ChessboardFieldsAndDefaults) {
  auto s = parse_text(board_plane(R"({"type":"chessboard","inner_corners":[9,7],"square_mm":30})"));
  ASSERT_TRUE(s.ok()) << s.status().to_string();
  ASSERT_TRUE(s->objects[0].texture.has_value());
  const ChessboardTexture& t = *s->objects[0].texture;
  EXPECT_EQ(t.cols, 9);
  EXPECT_EQ(t.rows, 7);
  EXPECT_DOUBLE_EQ(t.square_mm, 30);
  EXPECT_DOUBLE_EQ(t.dark, 0.05);
  EXPECT_DOUBLE_EQ(t.light, 0.9);
  EXPECT_EQ(t.border_squares, 1);
}

TEST(TextureParse, ErrorsNameTheField) {
  struct Case {
    std::string objects, needle;
  };
  const std::vector<Case> cases = {
      {board_plane(R"({"type":"checker","inner_corners":[9,7],"square_mm":30})"),
       "objects[0].texture.type: unknown texture type 'checker'"},
      {board_plane(R"({"type":"chessboard","inner_corners":[9.5,7],"square_mm":30})"),
       "objects[0].texture.inner_corners: both counts must be integers"},
      {board_plane(R"({"type":"chessboard","inner_corners":[9,7]})"), "objects[0].texture.square_mm: missing"},
      {board_plane(R"({"type":"chessboard","inner_corners":[9,7],"square_mm":30,"dark":1.5})"),
       "objects[0].texture.dark: must be in [0.0, 1.0]"},
      {board_plane(R"({"type":"chessboard","inner_corners":[9,7],"square_mm":30,"shade":1})"),
       "objects[0].texture.shade: unknown field"},
      {board_plane(R"({"type":"chessboard","inner_corners":[9,7],"square_mm":40})"),
       "objects[0].size_mm: the plane (360.0 x 300.0 mm) must hold the board"},
      {board_plane(R"({"type":"chessboard","inner_corners":[9,7],"square_mm":30})",
                   R"(,"material":{"albedo":0.5,"transmittance":0.3})"),
       "objects[0].texture: a texture needs an opaque material"},
      {board_plane(R"({"type":"chessboard","inner_corners":[9,7],"square_mm":30})",
                   R"(,"material":{"albedo":0.5,"specular":0.3})"),
       "objects[0].texture.light: max(dark, light) + material.specular must be <= 1"},
      {R"([{"type":"sphere","center_mm":[0,0,800],"radius_mm":50,
            "texture":{"type":"chessboard","inner_corners":[9,7],"square_mm":30}}])",
       "objects[0].texture: only planes take a texture"},
  };
  for (const Case& c : cases) {
    auto s = parse_text(c.objects);
    ASSERT_FALSE(s.ok()) << c.needle;
    EXPECT_EQ(s.status().code(), Code::invalid_argument);
    EXPECT_NE(s.status().message().find(c.needle), std::string::npos)
        << "want '" << c.needle << "' in: " << s.status().message();
  }
}

TEST(Texture, AlbedoPattern) {
  ChessboardTexture t;  // 9x7 inner corners: 10x8 squares of 30 mm, 1 border square
  // Square (0, 0) at a in [-150, -120), b in [-120, -90): dark; its neighbours light.
  EXPECT_EQ(t.albedo_at(-140, -110, 0.3), t.dark);
  EXPECT_EQ(t.albedo_at(-110, -110, 0.3), t.light);
  EXPECT_EQ(t.albedo_at(-140, -80, 0.3), t.light);
  EXPECT_EQ(t.albedo_at(1, 1, 0.3), t.light);  // square (5, 4): 5 + 4 odd -> light
  EXPECT_EQ(t.albedo_at(-1, 1, 0.3), t.dark);  // square (4, 4)
  EXPECT_EQ(t.albedo_at(-160, 0, 0.3), t.light);  // border
  EXPECT_EQ(t.albedo_at(-181, 0, 0.3), 0.3);      // beyond the border: the material
  double a = 0, b = 0;
  t.board_corner(0, 0, a, b);
  EXPECT_DOUBLE_EQ(a, -120);
  EXPECT_DOUBLE_EQ(b, -90);
}

// An image texture: a 4 x 2 PGM printed 40 x 20 mm, relative to the scene
// file's folder. Column 0 at -a, row 0 at +b (unmirrored from the front); albedo dark + (light - dark)
// value / 255, nearest pixel; the material beyond.
TEST(TextureParse, ImageTextureFromAPgm) {
  const std::string dir = temp_dir("imgtex");
  const std::string pgm = std::string("P5\n# comment\n4 2\n255\n") + std::string("\x00\xff\x00\xff\xff\x00\xff\x33", 8);
  write_text(dir, "b.pgm", pgm);
  const auto j = nlohmann::json::parse(
      "{\"name\":\"t\",\"objects\":" +
      board_plane(R"({"type":"image","file":"b.pgm","size_mm":[40,20],"dark":0.1,"light":0.7})") + "}");
  auto s = parse_scene(j, dir + "/t.json");
  ASSERT_TRUE(s.ok()) << s.status().to_string();
  const ChessboardTexture& t = *s->objects[0].texture;
  ASSERT_TRUE(t.image);
  EXPECT_DOUBLE_EQ(t.half_width_mm(), 20);
  EXPECT_DOUBLE_EQ(t.half_height_mm(), 10);
  EXPECT_DOUBLE_EQ(t.albedo_at(-15, 5, 0.3), 0.1);    // pixel (0, 0) = 0
  EXPECT_DOUBLE_EQ(t.albedo_at(-5, 5, 0.3), 0.7);     // pixel (1, 0) = 255
  EXPECT_DOUBLE_EQ(t.albedo_at(-15, -5, 0.3), 0.7);   // pixel (0, 1) = 255
  EXPECT_NEAR(t.albedo_at(15, -5, 0.3), 0.1 + 0.6 * 0x33 / 255.0, 1e-12);  // pixel (3, 1)
  EXPECT_DOUBLE_EQ(t.albedo_at(21, 0, 0.3), 0.3);     // beyond the bitmap
  EXPECT_DOUBLE_EQ(t.albedo_at(0, -10.5, 0.3), 0.3);
  EXPECT_DOUBLE_EQ(t.albedo_at(std::nan(""), 0, 0.3), 0.3);

  write_text(dir, "bad.pgm", "P2\n4 2\n255\n0 0 0 0 0 0 0 0\n");
  write_text(dir, "short.pgm", "P5\n4 2\n255\n\x01\x02");
  const std::vector<std::pair<std::string, std::string>> cases = {
      {R"({"type":"image","file":"none.pgm","size_mm":[40,20]})", "cannot be opened"},
      {R"({"type":"image","file":"bad.pgm","size_mm":[40,20]})", "is not a binary PGM"},
      {R"({"type":"image","file":"short.pgm","size_mm":[40,20]})", "is truncated"},
      {R"({"type":"image","file":"b.pgm","size_mm":[400,20]})", "must hold the board"},
      {R"({"type":"image","file":"b.pgm","size_mm":[0,20]})", "both extents must be > 0"},
      {R"({"type":"image","file":"b.pgm","size_mm":[40,20],"square_mm":3})", "square_mm: unknown field"},
  };
  for (const auto& [tex, needle] : cases) {
    auto bad = parse_scene(nlohmann::json::parse("{\"name\":\"t\",\"objects\":" + board_plane(tex) + "}"),
                           dir + "/t.json");
    ASSERT_FALSE(bad.ok()) << needle;
    EXPECT_NE(bad.status().message().find(needle), std::string::npos)
        << "want '" << needle << "' in: " << bad.status().message();
  }
}

// Fronto-parallel board, pinhole camera: a pixel's footprint is the square
// [(u - 0.5 - cx) z / fx, (u + 0.5 - cx) z / fx] x (the same in v), so the
// box-filtered albedo over a vertical edge at a = 0 is the area fraction.
TEST(Texture, FootprintIsTheBoxFilterOfTheEdge) {
  ChessboardTexture t;
  t.dark = 0.1;
  t.light = 0.7;
  Plane p;
  p.point_mm = {0, 0, 1000};
  p.normal = {0, 0, -1};
  p.u_axis = {1, 0, 0};
  p.v_axis = {0, -1, 0};  // normal x u_axis
  Intrinsics K;
  K.width = 640;
  K.height = 480;
  K.fx = K.fy = 1000;  // 1 px = 1 mm at 1000 mm
  K.cx = 319.5;
  K.cy = 239.5;
  const Rigid3 world_from_cam;  // identity
  // The edge between squares (4, j) and (5, j) lies at a = 0 (x = 0), i.e.
  // u = cx = 319.5. Row v = 249.5 -> y = 10 mm -> b = -10: square row j = 3.
  const double v = 239.5 + 10;
  for (double shift : {-0.4, -0.25, 0.0, 0.1, 0.37}) {
    const double u = 319.5 + shift;  // pixel covers x in [shift - 0.5, shift + 0.5] mm
    const double frac_right = std::clamp(shift + 0.5, 0.0, 1.0);
    // Square i = 4 left of x = 0, 5 right; j = 3: (4 + 3) odd -> light left, dark right.
    const double want = t.light * (1 - frac_right) + t.dark * frac_right;
    const double got = footprint_albedo(t, p, 0.5, K, world_from_cam, u, v);
    EXPECT_NEAR(got, want, (t.light - t.dark) / 377.0 + 1e-12) << "shift " << shift;
  }
  // An oblique edge (the board turned 30 degrees in its plane): against a
  // 512 x 512 brute-force average over the same square footprint.
  const double c30 = std::cos(M_PI / 6), s30 = std::sin(M_PI / 6);
  p.u_axis = {c30, s30, 0};
  p.v_axis = {s30, -c30, 0};  // normal x u_axis for normal (0, 0, -1)
  double worst = 0;
  for (double u = 300; u < 340; u += 0.7)
    for (double vv = 230; vv < 250; vv += 0.9) {
      const double x0 = u - K.cx, y0 = vv - K.cy;  // mm at 1000 mm
      double ref = 0;
      constexpr int M = 512;
      for (int j = 0; j < M; ++j)
        for (int i = 0; i < M; ++i) {
          const double x = x0 - 0.5 + (i + 0.5) / M, y = y0 - 0.5 + (j + 0.5) / M;
          ref += t.albedo_at(x * p.u_axis.x + y * p.u_axis.y, x * p.v_axis.x + y * p.v_axis.y, 0.5);
        }
      ref /= M * M;
      worst = std::max(worst, std::abs(footprint_albedo(t, p, 0.5, K, world_from_cam, u, vv) - ref));
      if (u > 310) break;  // a few columns are enough; keep the test fast
    }
  std::printf("oblique edge: worst footprint error %.5f of contrast %.2f\n", worst, t.light - t.dark);
  EXPECT_LT(worst, 0.005 * (t.light - t.dark)) << "oblique edges: area fraction within 0.5 % of the contrast";
  // A pixel well inside a square is exact.
  EXPECT_EQ(footprint_albedo(t, p, 0.5, K, world_from_cam, 319.5 + 10, v), t.dark);
}

// A texture whose squares have the material's albedo renders the very same
// view as no texture: the texture path changes nothing else.
TEST(Texture, UniformTextureRendersBitIdentical) {
  auto plain = parse_text(R"([{"type":"plane","point_mm":[0,0,800],"normal":[0.1,0.05,-1],"size_mm":[360,300],
                               "material":{"albedo":0.6}}])");
  auto tex = parse_text(board_plane(R"({"type":"chessboard","inner_corners":[9,7],"square_mm":30,
                                        "dark":0.6,"light":0.6,"border_squares":1})",
                                    R"(,"material":{"albedo":0.6})"));
  ASSERT_TRUE(plain.ok() && tex.ok());
  tex->objects[0].shape = plain->objects[0].shape;
  auto cfg = parse_sim_rig_config(test::read_json(test::configs_dir() + "/rigs/sim-distorted.json"));
  ASSERT_TRUE(cfg.ok()) << cfg.status().to_string();
  auto a = prepare_view(*plain, cfg->projector, cfg->cameras[0].calibration, 2);
  auto b = prepare_view(*tex, cfg->projector, cfg->cameras[0].calibration, 2);
  ASSERT_TRUE(a.ok() && b.ok());
  EXPECT_EQ(a->albedo, b->albedo);
  EXPECT_EQ(a->direct_gain, b->direct_gain);
  EXPECT_EQ(a->ambient, b->ambient);
}

// Explicit zero distortion is the pinhole renderer, bit for bit (frames and
// ground truth), on a shipped scene.
TEST(Distortion, ZeroCoefficientsRenderBitIdentical) {
  auto base = test::read_json(test::configs_dir() + "/rigs/sim.json");
  base["projector"]["intrinsics"]["width"] = 320;
  base["projector"]["intrinsics"]["height"] = 200;
  base["projector"]["intrinsics"]["cx"] = 159.5;
  base["projector"]["intrinsics"]["cy"] = 99.5;
  base["projector"]["intrinsics"]["fx"] = base["projector"]["intrinsics"]["fy"] = 400.0;
  base["cameras"][0]["intrinsics"] = {{"width", 320}, {"height", 200}, {"fx", 450.0}, {"fy", 450.0},
                                      {"cx", 159.5}, {"cy", 99.5}};
  base["scene"] = "tilted-box";
  auto zero = base;
  zero["projector"]["intrinsics"]["distortion"] = {0, 0, 0, 0, 0};
  zero["cameras"][0]["intrinsics"]["distortion"] = {0, 0, 0, 0, 0};
  const hw::RigContext ctx{test::configs_dir() + "/rigs", {test::configs_dir() + "/scenes"}};
  std::vector<std::vector<uint8_t>> frames;
  std::vector<std::vector<float>> depth;
  for (const auto& j : {base, zero}) {
    auto cfg = parse_sim_rig_config(j);
    ASSERT_TRUE(cfg.ok()) << cfg.status().to_string();
    auto rig = SimRig::create(*cfg, ctx);
    ASSERT_TRUE(rig.ok()) << rig.status().to_string();
    Image pat(320, 200, PixelType::u8);
    for (uint32_t y = 0; y < 200; ++y)
      for (uint32_t x = 0; x < 320; ++x) pat.row<uint8_t>(y)[x] = static_cast<uint8_t>((x / 7 + y / 5) % 2 ? 255 : 30);
    ASSERT_TRUE((*rig)->projector().show(pat.view(), 1).ok());
    auto f = (*rig)->camera(0).capture(std::chrono::milliseconds(1000));
    ASSERT_TRUE(f.ok()) << f.status().to_string();
    frames.emplace_back(f->image.data(), f->image.data() + f->image.size_bytes());
    auto gt = (*rig)->ground_truth(0);
    ASSERT_TRUE(gt.ok());
    depth.emplace_back(gt->depth_mm.ptr<float>(), gt->depth_mm.ptr<float>() + 320 * 200);
  }
  EXPECT_EQ(frames[0], frames[1]);
  ASSERT_EQ(depth[0].size(), depth[1].size());
  EXPECT_EQ(0, std::memcmp(depth[0].data(), depth[1].data(), depth[0].size() * sizeof(float)));
}

// OpenCV's forward model, written out here: normalised (x, y) -> pixel.
void forward(const nlohmann::json& k, double x, double y, double& u, double& v) {
  const auto d = k.at("distortion").get<std::vector<double>>();
  const double r2 = x * x + y * y;
  const double rad = 1 + d[0] * r2 + d[1] * r2 * r2 + d[4] * r2 * r2 * r2;
  const double xd = x * rad + 2 * d[2] * x * y + d[3] * (r2 + 2 * x * x);
  const double yd = y * rad + d[2] * (r2 + 2 * y * y) + 2 * d[3] * x * y;
  u = k.at("fx").get<double>() * xd + k.at("cx").get<double>();
  v = k.at("fy").get<double>() * yd + k.at("cy").get<double>();
}

// With the distorted rig, every camera pixel's 3-D point projects back onto
// that pixel through the camera's forward model, and onto the ground truth's
// projector (col, row) through the projector's: the truth follows the lenses.
TEST(Distortion, GroundTruthFollowsBothLenses) {
  const auto j = test::read_json(test::configs_dir() + "/rigs/sim-distorted.json");
  auto cfg = parse_sim_rig_config(j);
  ASSERT_TRUE(cfg.ok()) << cfg.status().to_string();
  ASSERT_TRUE(cfg->cameras[0].calibration.intrinsics.distorted());
  ASSERT_TRUE(cfg->projector.intrinsics.distorted());
  auto scene = load_scene(test::configs_dir() + "/scenes/calib/board-4.json", {});
  ASSERT_TRUE(scene.ok()) << scene.status().to_string();
  auto view = prepare_view(*scene, cfg->projector, cfg->cameras[0].calibration, 2);
  ASSERT_TRUE(view.ok());
  const auto& kc = j["cameras"][0]["intrinsics"];
  const auto& kp = j["projector"]["intrinsics"];
  const Rigid3 proj_from_cam = cfg->cameras[0].calibration.cam_from_proj.inverse();
  size_t checked = 0;
  double worst_cam = 0, worst_proj = 0, max_shift = 0;
  for (uint32_t row = 0; row < view->height; row += 7)
    for (uint32_t col = 0; col < view->width; col += 7) {
      const size_t i = size_t{row} * view->width + col;
      if (!view->lit[i]) continue;
      const Vec3 x{view->point_mm[3 * i], view->point_mm[3 * i + 1], view->point_mm[3 * i + 2]};
      double u = 0, v = 0;
      forward(kc, x.x / x.z, x.y / x.z, u, v);
      worst_cam = std::max(worst_cam, std::hypot(u - col, v - row));
      const Vec3 xp = proj_from_cam * x;
      forward(kp, xp.x / xp.z, xp.y / xp.z, u, v);
      worst_proj = std::max(worst_proj, std::hypot(u - static_cast<double>(view->proj_x[i]), v - static_cast<double>(view->proj_y[i])));
      // How far the lens moves this point: the test must see real distortion.
      max_shift = std::max(max_shift, std::hypot(u - (kp["fx"].get<double>() * xp.x / xp.z + kp["cx"].get<double>()),
                                                 v - (kp["fy"].get<double>() * xp.y / xp.z + kp["cy"].get<double>())));
      ++checked;
    }
  EXPECT_GT(checked, 1000u);
  EXPECT_LT(worst_cam, 0.01) << "camera pixel -> point -> forward model must return to the pixel (float points)";
  EXPECT_LT(worst_proj, 0.01) << "ground-truth projector coordinates must be the distorted projection";
  EXPECT_GT(max_shift, 1.0) << "the projector's distortion should move some points by > 1 px";
}

}  // namespace
}  // namespace procam::sim
