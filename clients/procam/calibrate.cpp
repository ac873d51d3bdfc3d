// SPDX-License-Identifier: MIT
// `procam calibrate-geometry`: camera + projector intrinsics with distortion
// and cam_from_proj from chessboard captures under Gray codes, offline
// (daemon/calibration; docs/calibration.md "Geometric calibration").
#include <cstdio>
#include <filesystem>
#include <string>
#include <vector>

#include "cli.hpp"
#include "procam/calibration/captures.hpp"
#include "procam/calibration/geometric.hpp"
#include "procam/engine/rig_json.hpp"
#include "procam/engine/scan_runner.hpp"

namespace procam::cli {
namespace fs = std::filesystem;

namespace {
// "AxB" -> (A, B), both > 0.
bool parse_pair(const std::string& s, uint32_t& a, uint32_t& b) {
  unsigned x = 0, y = 0;
  char sep = 0;
  if (std::sscanf(s.c_str(), "%u%c%u", &x, &sep, &y) != 3 || (sep != 'x' && sep != 'X') || x == 0 || y == 0)
    return false;
  a = x;
  b = y;
  return true;
}
}  // namespace

int cmd_calibrate_geometry(const Args& a) {
  for (const char* k : {"captures", "projector", "board", "square-mm", "out"})
    if (!a.has(k)) return usage_error(std::string("calibrate-geometry needs --") + k);
  calibration::DecodeOptions dec;
  if (!parse_pair(a.get("projector"), dec.projector_width, dec.projector_height))
    return usage_error("--projector must be WIDTHxHEIGHT in projector pixels, e.g. 1024x768");
  uint32_t cols = 0, rows = 0;
  if (!parse_pair(a.get("board"), cols, rows))
    return usage_error("--board must be COLSxROWS inner corners, e.g. 9x7");
  calibration::BoardSpec board{static_cast<int>(cols), static_cast<int>(rows), 0.0};
  try {
    board.square_mm = std::stod(a.get("square-mm"));
  } catch (...) {
    board.square_mm = 0;
  }
  if (!(board.square_mm > 0)) return usage_error("--square-mm must be the square size in mm, e.g. 75");
  if (a.has("layout")) dec.layout = a.get("layout");
  const std::string out = a.get("out");
  if (fs::exists(out) && a.get("force") != "1")
    return usage_error(out + " exists; pass --force 1 to replace it");
  // Capture folders: each --captures DIR is one pose, or, when it holds no
  // images, a folder of pose folders.
  std::vector<std::string> dirs;
  for (const std::string& d : a.list("captures")) {
    if (!fs::is_directory(d)) return usage_error("--captures " + d + " is not a folder");
    if (!engine::list_image_files(d).empty()) {
      dirs.push_back(d);
      continue;
    }
    std::vector<std::string> sub;
    for (const auto& e : fs::directory_iterator(d))
      if (e.is_directory() && !engine::list_image_files(e.path().string()).empty()) sub.push_back(e.path().string());
    std::sort(sub.begin(), sub.end());
    if (sub.empty()) return usage_error("--captures " + d + " holds no images and no capture folders");
    dirs.insert(dirs.end(), sub.begin(), sub.end());
  }
  host::PluginHost host;
  host.load_directories(plugin_search_dirs(a));
  std::vector<calibration::View> views;
  for (size_t i = 0; i < dirs.size(); ++i) {
    std::fprintf(stderr, "\r  decoding capture %zu/%zu %-40.40s", i + 1, dirs.size(), dirs[i].c_str());
    auto v = calibration::decode_capture(host, dirs[i], dec);
    if (!v) {
      std::fprintf(stderr, "\n");
      return report(v.status().with_context(dirs[i]));
    }
    if (!views.empty() && (v->width != views[0].width || v->height != views[0].height)) {
      // e.g. the folder of projector patterns next to the captures
      std::fprintf(stderr, "\n  skipped %s: %ux%u images, not the %ux%u camera images of %s\n", dirs[i].c_str(),
                   v->width, v->height, views[0].width, views[0].height, views[0].name.c_str());
      continue;
    }
    views.push_back(std::move(*v));
  }
  std::fprintf(stderr, "\n  calibrating %zu views\n", views.size());
  auto r = calibration::calibrate(views, board, dec.projector_width, dec.projector_height);
  if (!r) return report(r.status());
  nlohmann::json j = calibration::to_rig_json(*r);
  if (auto s = engine::write_file_atomic(out, j.dump(2) + "\n"); !s) return report(s);
  if (a.json) {
    std::printf("%s\n", j.dump(2).c_str());
    return 0;
  }
  std::printf("%s\n", calibration::report_markdown(*r).c_str());
  std::printf("camera    %ux%u fx %.2f fy %.2f cx %.2f cy %.2f  k1 %.4f k2 %.4f p1 %.5f p2 %.5f k3 %.4f\n",
              r->camera.width, r->camera.height, r->camera.fx, r->camera.fy, r->camera.cx, r->camera.cy,
              r->camera.distortion[0], r->camera.distortion[1], r->camera.distortion[2], r->camera.distortion[3],
              r->camera.distortion[4]);
  std::printf("projector %ux%u fx %.2f fy %.2f cx %.2f cy %.2f  k1 %.4f k2 %.4f p1 %.5f p2 %.5f k3 %.4f\n",
              r->projector.width, r->projector.height, r->projector.fx, r->projector.fy, r->projector.cx,
              r->projector.cy, r->projector.distortion[0], r->projector.distortion[1], r->projector.distortion[2],
              r->projector.distortion[3], r->projector.distortion[4]);
  const auto& t = r->cam_from_proj_translation_mm;
  std::printf("cam_from_proj translation (%.2f, %.2f, %.2f) mm\n", t[0], t[1], t[2]);
  std::printf("\nwrote %s: copy its \"projector\" and \"cameras\" calibration into your rig config\n", out.c_str());
  return 0;
}

}  // namespace procam::cli
