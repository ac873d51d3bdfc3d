// SPDX-License-Identifier: MIT
// Readable previews (colour bar with unit, class key) and the one-page scan report.
#include "procam/engine/previews.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <map>
#include <sstream>

#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include "procam/core/image_io.hpp"
#include "procam/engine/results.hpp"
#include "procam/engine/rig_json.hpp"

namespace procam::engine {
namespace fs = std::filesystem;

namespace {

// Text is drawn with OpenCV's built-in Hershey font: no font files needed on
// a headless scan station. Scale grows with the image so labels stay legible.
double text_scale(uint32_t width) { return std::clamp(static_cast<double>(width) / 1600.0, 0.45, 1.2); }

void put_text(cv::Mat& m, const std::string& s, int x, int y, double scale, const cv::Scalar& color) {
  cv::putText(m, s, {x, y}, cv::FONT_HERSHEY_SIMPLEX, scale, color, std::max(1, static_cast<int>(scale * 2)),
              cv::LINE_AA);
}

int text_width(const std::string& s, double scale) {
  int base = 0;
  return cv::getTextSize(s, cv::FONT_HERSHEY_SIMPLEX, scale, std::max(1, static_cast<int>(scale * 2)), &base).width;
}

std::string number(double v) {
  char buf[32];
  const double a = std::fabs(v);
  std::snprintf(buf, sizeof buf, (a != 0 && (a < 1e-3 || a >= 1e6)) ? "%.3g" : "%.4g", v);
  return buf;
}

Image from_mat(const cv::Mat& rgb) {
  Image out(static_cast<uint32_t>(rgb.cols), static_cast<uint32_t>(rgb.rows), PixelType::u8, 3);
  for (int y = 0; y < rgb.rows; ++y)
    std::copy_n(rgb.ptr<uint8_t>(y), static_cast<size_t>(rgb.cols) * 3, out.row<uint8_t>(static_cast<uint32_t>(y)));
  return out;
}

cv::Mat to_mat(const Image& rgb) {
  cv::Mat m(static_cast<int>(rgb.height()), static_cast<int>(rgb.width()), CV_8UC3);
  for (uint32_t y = 0; y < rgb.height(); ++y)
    std::copy_n(rgb.row<uint8_t>(y), size_t{rgb.width()} * 3, m.ptr<uint8_t>(static_cast<int>(y)));
  return m;
}

// 1st and 99th percentile of the finite values (the range the colours span).
bool finite_range(const Image& f, double& lo, double& hi) {
  std::vector<float> v;
  v.reserve(f.pixel_count());
  for (size_t i = 0; i < f.pixel_count(); ++i)
    if (std::isfinite(f.ptr<float>()[i])) v.push_back(f.ptr<float>()[i]);
  if (v.empty()) return false;
  auto pct = [&](double q) {
    const auto k = static_cast<std::ptrdiff_t>(q * static_cast<double>(v.size() - 1));
    std::nth_element(v.begin(), v.begin() + k, v.end());
    return static_cast<double>(v[static_cast<size_t>(k)]);
  };
  lo = pct(0.01);
  hi = pct(0.99);
  return true;
}

std::string html_escape(const std::string& s) {
  std::string o;
  for (char c : s) {
    switch (c) {
      case '&': o += "&amp;"; break;
      case '<': o += "&lt;"; break;
      case '>': o += "&gt;"; break;
      case '"': o += "&quot;"; break;
      default: o += c;
    }
  }
  return o;
}

std::string json_text(const nlohmann::json& j) {
  if (j.is_string()) return j.get<std::string>();
  if (j.is_number_float()) return number(j.get<double>());
  if (j.is_null()) return "—";
  return j.dump();
}

}  // namespace

void class_color(int v, uint8_t rgb[3]) {
  // A fixed, high-contrast palette (Tableau 10 order); 0 = black so "unlit"
  // or "none" recedes; values past the palette cycle with a shade shift.
  static constexpr uint8_t kPalette[10][3] = {{31, 119, 180}, {255, 127, 14}, {44, 160, 44},  {214, 39, 40},
                                              {148, 103, 189}, {140, 86, 75}, {227, 119, 194}, {127, 127, 127},
                                              {188, 189, 34},  {23, 190, 207}};
  if (v <= 0) {
    rgb[0] = rgb[1] = rgb[2] = 0;
    return;
  }
  const int k = (v - 1) % 10, shade = (v - 1) / 10;
  for (int c = 0; c < 3; ++c) rgb[c] = static_cast<uint8_t>(std::max(0, kPalette[k][c] - 40 * (shade % 3)));
}

std::vector<ClassLabel> parse_class_legend(const nlohmann::json& legend) {
  std::vector<ClassLabel> out;
  if (!legend.is_object() || !legend.contains("classes") || !legend["classes"].is_array()) return out;
  for (const auto& c : legend["classes"]) {
    if (!c.is_object() || !c.contains("value") || !c["value"].is_number_integer()) continue;
    const int v = c["value"].get<int>();
    if (v < 0 || v > 255) continue;
    ClassLabel l;
    l.value = v;
    l.name = c.value("name", "class " + std::to_string(v));
    l.meaning = c.value("meaning", "");
    out.push_back(std::move(l));
  }
  return out;
}

Image scalar_map_preview(const Image& f32, const std::string& unit, const std::string& title) {
  const Image body = colormap_preview(f32);
  const int w = static_cast<int>(body.width());
  const double s = text_scale(body.width());
  const int line = static_cast<int>(std::lround(30 * s)) + 6;
  const int bar_h = std::max(10, line / 2);
  cv::Mat m(static_cast<int>(body.height()) + 3 * line + bar_h, w, CV_8UC3, cv::Scalar(255, 255, 255));
  to_mat(body).copyTo(m(cv::Rect(0, 0, w, static_cast<int>(body.height()))));
  const int y0 = static_cast<int>(body.height());
  double lo = 0, hi = 0;
  const bool any = f32.type() == PixelType::f32 && f32.channels() == 1 && finite_range(f32, lo, hi);
  const cv::Scalar ink(20, 20, 20);
  put_text(m, title, 6, y0 + line - 8, s, ink);
  if (!any) {
    put_text(m, "no valid pixels", 6, y0 + 2 * line - 8, s, ink);
    return from_mat(m);
  }
  const int margin = 6, bx0 = margin, bx1 = w - margin;
  for (int x = bx0; x < bx1; ++x) {
    uint8_t rgb[3];
    turbo(static_cast<double>(x - bx0) / std::max(1, bx1 - bx0 - 1), rgb);
    cv::line(m, {x, y0 + line}, {x, y0 + line + bar_h}, cv::Scalar(rgb[0], rgb[1], rgb[2]));
  }
  const std::string u = unit.empty() ? "" : " " + unit;
  const std::string l0 = number(lo) + u, l1 = number((lo + hi) / 2) + u, l2 = number(hi) + u;
  const int ty = y0 + line + bar_h + line - 8;
  put_text(m, l0, bx0, ty, s, ink);
  put_text(m, l1, (w - text_width(l1, s)) / 2, ty, s, ink);
  put_text(m, l2, bx1 - text_width(l2, s), ty, s, ink);
  put_text(m, "1st..99th percentile; black = no value", bx0, ty + line - 4, s * 0.8, cv::Scalar(90, 90, 90));
  return from_mat(m);
}

Image class_map_preview(const Image& u8, const std::vector<ClassLabel>& classes, const std::string& title) {
  const uint32_t w = u8.width(), h = u8.height();
  std::map<int, size_t> counts;
  const bool ok = u8.type() == PixelType::u8 && u8.channels() == 1;
  if (ok)
    for (size_t i = 0; i < u8.pixel_count(); ++i) ++counts[u8.ptr<uint8_t>()[i]];
  std::map<int, ClassLabel> named;
  for (const auto& c : classes) named[c.value] = c;
  std::vector<int> shown;
  for (const auto& [v, c] : named) shown.push_back(v);
  for (const auto& [v, n] : counts)
    if (!named.count(v)) shown.push_back(v);
  std::sort(shown.begin(), shown.end());

  const double s = text_scale(w);
  const int line = static_cast<int>(std::lround(30 * s)) + 8;
  int key_w = 0;
  std::vector<std::string> texts;
  const double total = static_cast<double>(std::max<size_t>(1, u8.pixel_count()));
  for (int v : shown) {
    const auto it = named.find(v);
    std::string t = std::to_string(v) + "  " + (it != named.end() ? it->second.name : "class " + std::to_string(v));
    char pct[32];
    std::snprintf(pct, sizeof pct, "  %.1f %%", 100.0 * static_cast<double>(counts[v]) / total);
    t += pct;
    texts.push_back(t);
    key_w = std::max(key_w, text_width(t, s));
  }
  key_w += line + 24;
  const int rows = std::max(static_cast<int>(h), static_cast<int>(shown.size() + 2) * line);
  cv::Mat m(rows, static_cast<int>(w) + key_w, CV_8UC3, cv::Scalar(255, 255, 255));
  if (ok)
    for (uint32_t y = 0; y < h; ++y)
      for (uint32_t x = 0; x < w; ++x) {
        uint8_t rgb[3];
        class_color(u8.row<uint8_t>(y)[x], rgb);
        m.at<cv::Vec3b>(static_cast<int>(y), static_cast<int>(x)) = {rgb[0], rgb[1], rgb[2]};
      }
  const int kx = static_cast<int>(w) + 12;
  const cv::Scalar ink(20, 20, 20);
  put_text(m, title, kx, line - 8, s, ink);
  for (size_t k = 0; k < shown.size(); ++k) {
    const int y = static_cast<int>(k + 1) * line + 4;
    uint8_t rgb[3];
    class_color(shown[k], rgb);
    cv::rectangle(m, cv::Rect(kx, y, line - 8, line - 8), cv::Scalar(rgb[0], rgb[1], rgb[2]), cv::FILLED);
    cv::rectangle(m, cv::Rect(kx, y, line - 8, line - 8), cv::Scalar(120, 120, 120), 1);
    put_text(m, texts[k], kx + line, y + line - 12, s, ink);
  }
  return from_mat(m);
}

Status write_scan_report(const std::string& dir, const nlohmann::json& manifest) {
  auto str = [&](const char* k) { return manifest.contains(k) && manifest[k].is_string() ? manifest[k].get<std::string>() : ""; };
  std::ostringstream h;
  h << "<!DOCTYPE html>\n<html><head><meta charset=\"utf-8\"><title>procam scan " << html_escape(str("scan_id"))
    << "</title>\n<style>body{font-family:sans-serif;max-width:1100px;margin:1em auto;color:#222}"
       "table{border-collapse:collapse;margin:.5em 0}td,th{border:1px solid #ccc;padding:3px 8px;text-align:left}"
       "th{background:#f3f3f3}img{max-width:100%;border:1px solid #ddd}figure{margin:1em 0}"
       "figcaption{color:#555;font-size:90%}pre{background:#f6f6f6;padding:.5em;overflow:auto;font-size:85%}"
       ".bad{color:#a00}</style></head><body>\n";
  h << "<h1>Scan " << html_escape(str("scan_id")) << "</h1>\n";
  const std::string state = str("state");
  h << "<p>State: <b" << (state == "done" ? "" : " class=\"bad\"") << ">" << html_escape(state) << "</b>";
  if (manifest.contains("error") && manifest["error"].is_object())
    h << " — " << html_escape(manifest["error"].value("message", "")) << " <i>"
      << html_escape(manifest["error"].value("hint", "")) << "</i>";
  h << "</p>\n<table>\n";
  auto row = [&](const std::string& k, const std::string& v) {
    h << "<tr><th>" << html_escape(k) << "</th><td>" << html_escape(v) << "</td></tr>\n";
  };
  row("plugin / method", str("plugin") + " / " + str("method"));
  if (!str("label").empty()) row("label", str("label"));
  if (manifest.contains("params")) row("parameters", manifest["params"].dump());
  if (manifest.contains("rig") && manifest["rig"].is_object()) {
    std::string rig = manifest["rig"].value("name", "");
    if (manifest["rig"].contains("state") && !manifest["rig"]["state"].empty())
      rig += " " + manifest["rig"]["state"].dump();
    row("rig", rig);
  }
  if (manifest.contains("plan") && manifest["plan"].is_object()) {
    const auto& plan = manifest["plan"];
    const size_t rounds = plan.contains("rounds") && plan["rounds"].is_array() ? plan["rounds"].size() : 0;
    row("patterns", json_text(plan.value("patterns", nlohmann::json(0))) + " in " + std::to_string(rounds) +
                        " round(s)");
    if (rounds > 0)
      for (size_t r = 0; r < rounds; ++r)
        row("round " + std::to_string(r + 1),
            json_text(plan["rounds"][r].value("frames", nlohmann::json(0))) + " frames — " +
                plan["rounds"][r].value("note", std::string()));
  }
  if (manifest.contains("timing_ms") && manifest["timing_ms"].is_object())
    for (const auto& [k, v] : manifest["timing_ms"].items()) row("time: " + k, json_text(v) + " ms");
  h << "</table>\n";

  if (manifest.contains("evaluation") && manifest["evaluation"].is_object()) {
    h << "<h2>Accuracy against ground truth</h2>\n<table>\n";
    for (const auto& [k, v] : manifest["evaluation"].items())
      if (!v.is_object() && !v.is_array()) row(k, json_text(v));
    h << "</table>\n";
  }

  // Calibration records (calibrate_geometry, PROTOCOL.md 5.12): the per-view table.
  if (manifest.contains("calibration") && manifest["calibration"].is_object()) {
    const auto& c = manifest["calibration"];
    h << "<h2>Geometric calibration</h2>\n<table><tr><th>view (scan)</th><th>used</th><th>corners</th>"
         "<th>with projector position</th><th>camera RMS (px)</th><th>projector RMS (px)</th><th>why rejected</th></tr>\n";
    for (const auto& v : c.value("views", nlohmann::json::array()))
      h << "<tr><td>" << html_escape(v.value("name", "")) << "</td><td>" << (v.value("used", false) ? "yes" : "no")
        << "</td><td>" << json_text(v.value("corners", nlohmann::json(0))) << "</td><td>"
        << json_text(v.value("projector_corners", nlohmann::json(0))) << "</td><td>"
        << json_text(v.value("camera_rms_px", nlohmann::json(0))) << "</td><td>"
        << json_text(v.value("projector_rms_px", nlohmann::json(0))) << "</td><td>"
        << html_escape(v.value("rejected_because", "")) << "</td></tr>\n";
    h << "</table>\n<table>\n";
    for (const char* k : {"camera_rms_px", "projector_rms_px", "stereo_rms_px"})
      if (c.contains(k)) row(k, json_text(c[k]));
    if (c.contains("square_check")) row("squares triangulated", c["square_check"].dump());
    row("result file", c.value("result_file", ""));
    h << "</table>\n";
  }

  std::map<std::string, std::string> descriptions;
  if (manifest.contains("outputs") && manifest["outputs"].is_array()) {
    bool any = false;
    for (const auto& o : manifest["outputs"]) {
      descriptions[o.value("name", "")] = o.value("description", "");
      if (o.value("kind", "") != "scalar") continue;
      if (!any) h << "<h2>Numbers</h2>\n<table><tr><th>name</th><th>value</th><th>unit</th><th>meaning</th></tr>\n";
      any = true;
      h << "<tr><td>" << html_escape(o.value("name", "")) << "</td><td>" << json_text(o.value("value", nlohmann::json()))
        << "</td><td>" << html_escape(o.value("unit", "")) << "</td><td>" << html_escape(o.value("description", ""))
        << "</td></tr>\n";
    }
    if (any) h << "</table>\n";
  }
  if (manifest.contains("previews") && manifest["previews"].is_array() && !manifest["previews"].empty()) {
    h << "<h2>Maps</h2>\n";
    for (const auto& p : manifest["previews"]) {
      const std::string of = p.value("of", ""), file = p.value("file", "");
      h << "<figure><img src=\"" << html_escape(file) << "\" alt=\"" << html_escape(of) << "\"><figcaption><b>"
        << html_escape(of) << "</b> — " << html_escape(descriptions[of]) << "</figcaption></figure>\n";
    }
  }
  if (manifest.contains("outputs") && manifest["outputs"].is_array())
    for (const auto& o : manifest["outputs"])
      if (o.value("kind", "") == "json" && o.value("name", "") == "report")
        h << "<h2>Decoder report</h2>\n<pre>" << html_escape(o.value("value", nlohmann::json()).dump(2)) << "</pre>\n";
  h << "<p><small>manifest.json holds every number above; files are listed there.</small></p>\n</body></html>\n";
  return write_file_atomic((fs::path(dir) / "report.html").string(), h.str());
}

}  // namespace procam::engine
