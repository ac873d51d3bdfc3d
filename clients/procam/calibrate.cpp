// SPDX-License-Identifier: MIT
// `procam calibrate-geometry`: camera + projector intrinsics with distortion
// and cam_from_proj from chessboard or ChArUco captures under Gray codes
// (daemon/calibration; docs/calibration.md "Geometric calibration").
#include <chrono>
#include <cstdio>
#include <thread>
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
// Board spec from --board COLSxROWS --square-mm S (chessboard) or --board
// charuco:SXxSY:SQUARE_MM:MARKER_MM:DICT (calibration::parse_board); false
// (after a usage message saying what to give) when malformed.
bool board_args(const Args& a, calibration::BoardSpec& board, int& rc) {
  const std::string text = a.get("board");
  const bool charuco = text.rfind("charuco:", 0) == 0;
  double square_mm = 0;
  if (!charuco) {
    try {
      square_mm = std::stod(a.get("square-mm"));
    } catch (...) {
      square_mm = 0;
    }
    if (!(square_mm > 0)) {
      rc = usage_error("--square-mm must be the square size in mm, e.g. 75 (a ChArUco --board carries its own)");
      return false;
    }
  }
  auto b = calibration::parse_board(text, square_mm);
  if (!b) {
    rc = usage_error("--board: " + b.status().message() + "\n" + b.status().hint());
    return false;
  }
  board = *b;
  return true;
}

// Through procamd (request calibrate_geometry, PROTOCOL.md 5.12): the pose
// scans were taken by the daemon (gray rows=true, save_frames); the daemon
// calibrates, this waits for the record and downloads rig-calibration.json.
int calibrate_through_daemon(const Args& a) {
  for (const char* k : {"board", "out"})
    if (!a.has(k)) return usage_error(std::string("calibrate-geometry --scans needs --") + k);
  calibration::BoardSpec board;
  int rc = 0;
  if (!board_args(a, board, rc)) return rc;
  const std::string out = a.get("out");
  if (fs::exists(out) && a.get("force") != "1") return usage_error(out + " exists; pass --force 1 to replace it");
  proto::CalibrateGeometry req;
  for (const std::string& v : a.list("scans")) {  // repeated and/or comma-separated ids
    size_t at = 0;
    while (at <= v.size()) {
      const size_t comma = std::min(v.find(',', at), v.size());
      if (comma > at) req.scans.push_back(v.substr(at, comma - at));
      at = comma + 1;
    }
  }
  req.board_cols = board.cols;
  req.board_rows = board.rows;
  req.square_mm = board.square_mm;
  if (board.type == calibration::BoardType::charuco) {
    req.board_type = "charuco";
    req.marker_mm = board.marker_mm;
    req.dictionary = board.dictionary;
  }
  req.label = a.has("label") ? a.get("label") : "";
  client::Client c = a.connect();
  auto r = c.call(req);
  if (!r) return report(r.status());
  const std::string id = r->value("scan_id", "");
  std::fprintf(stderr, "calibration %s queued on %s: decoding %zu pose scans\n", id.c_str(), c.endpoint().c_str(),
               req.scans.size());
  std::string state;
  for (int i = 0; i < 30 * 60 * 2; ++i) {  // poll status, at most 30 minutes
    auto st = c.call(proto::StatusQuery{id});
    if (!st) return report(st.status());
    state = (*st)["scan"].value("state", "");
    if (state == "done" || state == "failed") break;
    std::this_thread::sleep_for(std::chrono::milliseconds(500));
  }
  auto m = c.call(proto::ResultQuery{id});
  if (!m) return report(m.status());
  const nlohmann::json& man = (*m)["manifest"];
  if (state != "done") {
    const nlohmann::json& e = man.value("error", nlohmann::json::object());
    std::fprintf(stderr, "calibration %s %s: %s\n", id.c_str(), state.c_str(),
                 e.is_object() ? e.value("message", "").c_str() : "");
    if (e.is_object() && !e.value("hint", "").empty()) std::fprintf(stderr, "hint: %s\n", e.value("hint", "").c_str());
    return 1;
  }
  const nlohmann::json& cal = man["calibration"];
  if (Status fs_ = c.fetch_file(id, cal.value("result_file", "rig-calibration.json"), out); !fs_) return report(fs_);
  if (a.json) {
    std::printf("%s\n", cal.dump(2).c_str());
    return 0;
  }
  for (const auto& v : cal["views"])
    std::printf("%-24s %-4s corners %2d (projector %2d)  RMS camera %.3f px projector %.3f px  %s\n",
                v.value("name", "").c_str(), v.value("used", false) ? "used" : "no", v.value("corners", 0),
                v.value("projector_corners", 0), v.value("camera_rms_px", 0.0), v.value("projector_rms_px", 0.0),
                v.value("rejected_because", "").c_str());
  std::printf("joint RMS %.3f px; squares triangulated: mean %.2f mm\n", cal.value("stereo_rms_px", 0.0),
              cal.value("square_check", nlohmann::json::object()).value("mean_mm", 0.0));
  std::printf("wrote %s (calibration %s): copy its \"projector\" and \"cameras\" calibration into your rig config\n",
              out.c_str(), id.c_str());
  return 0;
}
}  // namespace

int cmd_calibrate_geometry(const Args& a) {
  if (a.has("scans")) return calibrate_through_daemon(a);
  for (const char* k : {"captures", "projector", "board", "out"})
    if (!a.has(k)) return usage_error(std::string("calibrate-geometry needs --") + k);
  calibration::DecodeOptions dec;
  if (!parse_pair(a.get("projector"), dec.projector_width, dec.projector_height))
    return usage_error("--projector must be WIDTHxHEIGHT in projector pixels, e.g. 1024x768");
  calibration::BoardSpec board;
  if (int rc = 0; !board_args(a, board, rc)) return rc;
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
