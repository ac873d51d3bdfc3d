// SPDX-License-Identifier: MIT
// `procam bench`: the speed-vs-error report (issue 4). Runs every method of
// every loaded plugin (plus listed variants) on every sim scene, in process:
// sim rig library (hw::create_rig) -> plugin host session -> engine::run_scan
// (plan -> sim capture -> streaming decode, all rounds) -> outputs ->
// engine::evaluate_outputs against the sim ground truth. No procamd.
// Writes bench.md (table), bench.json (all numbers) and bench.png (plot of
// gross-error rate vs capture time) to --out; with other families also
// bench-depth.png and bench-direct.png (their error vs capture time). Methods without a projector
// column map (defocus, separation, ...) get a second table with what their
// outputs are evaluated on: depth against the true depth, direct/global
// against the sim's light-transport split. Calibration methods (calibrate-*)
// make tables rather than decode a scene and are left out unless named with
// --method (--keep then holds the table in outputs.json); a required input
// "depth_mm" (e.g. separation/one-focal-depth) is fed the sim's true depth,
// which the report says. The rig's calibration_tables are passed to plugins
// as procamd does.
#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <functional>
#include <iostream>
#include <map>
#include <set>
#include <sstream>
#include <thread>

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "cli.hpp"
#include "procam/engine/calibration_tables.hpp"
#include "procam/engine/evaluate.hpp"
#include "procam/engine/results.hpp"
#include "procam/engine/rig_json.hpp"
#include "procam/engine/scan_runner.hpp"
#include "procam/host/plugin_host.hpp"
#include "procam/hw/rig.hpp"

#ifndef PROCAM_DEFAULT_PLUGIN_DIRS
#define PROCAM_DEFAULT_PLUGIN_DIRS ""
#endif
#ifndef PROCAM_DEFAULT_RIG
#define PROCAM_DEFAULT_RIG ""
#endif

namespace procam::cli {
namespace fs = std::filesystem;

namespace {

struct Variant {
  std::string plugin, method, label;
  nlohmann::json params = nlohmann::json::object();
};

struct Row {
  std::string scene, label;
  bool ok = false;
  bool correspondence = false;  // has proj_col_px: first table and the plot
  std::string inputs_note;      // inputs fed from ground truth
  std::string error;
  size_t patterns = 0, rounds = 0;
  double decode_ms = 0;
  nlohmann::json eval;
};

// Extra variants worth a row of their own (the same method, other settings).
// Labels: structured-light methods by name (the report's columns since issue
// 4), every other plugin's as plugin/method (defocus and separation both
// have a multi-focal).
std::vector<Variant> variants_for(const std::string& plugin, const std::string& method) {
  const std::string label = plugin == "structured-light" ? method : plugin + "/" + method;
  std::vector<Variant> v{{plugin, method, label, nlohmann::json::object()}};
  if (plugin == "structured-light" && method == "ensemble")
    v.insert(v.begin(), Variant{plugin, method, "ensemble-nocorr", {{"correction_rounds", 0}}});
  return v;
}

std::string fmt(double v, int prec) {
  if (!std::isfinite(v)) return "–";
  char b[64];
  std::snprintf(b, sizeof b, "%.*f", prec, v);
  return b;
}

double num(const nlohmann::json& j, const char* k) {
  return j.contains(k) && j[k].is_number() ? j[k].get<double>() : std::nan("");
}

// Plot: x = capture time at 60 Hz (log scale), y = gross errors (% of decoded
// lit pixels), one colour per method, one point per scene, the method's
// median over scenes joined and labelled.
// What a plot shows: its y value per row (NaN: row not plotted) and title.
struct PlotSpec {
  std::function<double(const Row&)> y;  // percent
  std::string title;
};

void plot(const std::vector<Row>& rows, const std::vector<std::string>& labels, const std::string& path,
          const PlotSpec& spec) {
  const int W = 1100, H = 700, L = 90, R = 250, T = 50, B = 70;
  cv::Mat img(H, W, CV_8UC3, cv::Scalar(255, 255, 255));
  double xmin = 1e9, xmax = 0, ymax = 1.0;
  for (const Row& r : rows) {
    if (!r.ok || !std::isfinite(spec.y(r))) continue;
    const double x = static_cast<double>(r.patterns) / 60.0;
    xmin = std::min(xmin, x);
    xmax = std::max(xmax, x);
    ymax = std::max(ymax, spec.y(r));
  }
  if (xmax <= 0) return;
  xmin = std::max(0.05, xmin / 1.5);
  xmax *= 1.5;
  ymax = std::ceil(std::min(ymax * 1.1, 100.0));
  auto X = [&](double x) { return L + static_cast<int>((std::log10(x) - std::log10(xmin)) / (std::log10(xmax) - std::log10(xmin)) * (W - L - R)); };
  auto Y = [&](double y) { return H - B - static_cast<int>(y / ymax * (H - T - B)); };
  const cv::Scalar black(0, 0, 0), grid(220, 220, 220);
  for (double t : {0.1, 0.2, 0.5, 1.0, 2.0, 5.0, 10.0}) {
    if (t < xmin || t > xmax) continue;
    cv::line(img, {X(t), T}, {X(t), H - B}, grid);
    cv::putText(img, fmt(t, 1) + " s", {X(t) - 18, H - B + 20}, cv::FONT_HERSHEY_SIMPLEX, 0.45, black);
  }
  for (int k = 0; k <= 5; ++k) {
    const double y = ymax * k / 5;
    cv::line(img, {L, Y(y)}, {W - R, Y(y)}, grid);
    cv::putText(img, fmt(y, 1), {L - 45, Y(y) + 5}, cv::FONT_HERSHEY_SIMPLEX, 0.45, black);
  }
  cv::rectangle(img, {L, T}, {W - R, H - B}, black);
  cv::putText(img, "capture time at 60 Hz (patterns / 60), log scale", {L + 150, H - 25}, cv::FONT_HERSHEY_SIMPLEX, 0.55, black);
  cv::putText(img, spec.title, {L, T - 20}, cv::FONT_HERSHEY_SIMPLEX, 0.55, black);
  const cv::Scalar palette[] = {{200, 0, 0}, {0, 140, 0}, {0, 0, 220}, {180, 0, 180}, {0, 150, 200},
                                {120, 80, 0}, {80, 80, 80}, {0, 90, 255}, {150, 150, 0}, {255, 100, 100}};
  int legend_y = T + 10;
  for (size_t m = 0; m < labels.size(); ++m) {
    const cv::Scalar c = palette[m % std::size(palette)];
    std::vector<double> ys;
    double x = 0;
    for (const Row& r : rows) {
      if (!r.ok || r.label != labels[m]) continue;
      const double y = spec.y(r);
      if (!std::isfinite(y)) continue;
      x = static_cast<double>(r.patterns) / 60.0;
      ys.push_back(y);
      cv::circle(img, {X(x), Y(y)}, 4, c, 1, cv::LINE_AA);
    }
    if (ys.empty()) continue;
    std::sort(ys.begin(), ys.end());
    const double med = ys[ys.size() / 2];
    cv::drawMarker(img, {X(x), Y(med)}, c, cv::MARKER_DIAMOND, 14, 2);
    cv::putText(img, labels[m], {W - R + 15, legend_y + 4}, cv::FONT_HERSHEY_SIMPLEX, 0.5, c, 1, cv::LINE_AA);
    cv::drawMarker(img, {W - R + 8, legend_y}, c, cv::MARKER_DIAMOND, 10, 2);
    legend_y += 22;
  }
  cv::putText(img, "o: one scene", {W - R + 8, legend_y + 15}, cv::FONT_HERSHEY_SIMPLEX, 0.42, black);
  cv::putText(img, "<>: median over scenes", {W - R + 8, legend_y + 33}, cv::FONT_HERSHEY_SIMPLEX, 0.42, black);
  cv::imwrite(path, img);
}

// Gross errors (|col - truth| > 1 on lit pixels) per light-transport class of
// the ensemble: which vote outcome the wrong pixels came from.
nlohmann::json gross_by_class(const Image& col, const Image& cls, const hw::GroundTruth& t) {
  const char* names[] = {"unlit", "all_agree", "interreflection", "subsurface", "partial", "error"};
  size_t gross[6] = {}, decoded[6] = {};
  for (uint32_t y = 0; y < col.height(); ++y)
    for (uint32_t x = 0; x < col.width(); ++x) {
      const float c = col.at<float>(x, y), tc = t.proj_col.at<float>(x, y);
      if (t.lit.at<uint8_t>(x, y) == 0 || !std::isfinite(c) || !std::isfinite(tc)) continue;
      const size_t k = std::min<size_t>(cls.at<uint8_t>(x, y), 5);
      ++decoded[k];
      if (std::fabs(c - tc) > 1.0f) ++gross[k];
    }
  nlohmann::json j;
  for (size_t k = 0; k < 6; ++k) j[names[k]] = {{"decoded", decoded[k]}, {"gross", gross[k]}};
  return j;
}

// Required inputs of a method from the sim's truth: "depth_mm" only (the
// depth a structured-light scan would give). `storage` owns the pixels.
Result<std::vector<host::InputImage>> truth_inputs(const nlohmann::json& describe, const hw::GroundTruth& truth,
                                                   std::vector<std::vector<float>>& storage, std::string& note) {
  std::vector<host::InputImage> inputs;
  if (!describe.contains("inputs") || !describe["inputs"].is_array()) return inputs;
  const uint32_t w = truth.depth_mm.width(), h = truth.depth_mm.height();
  storage.reserve(describe["inputs"].size());
  for (const auto& in : describe["inputs"]) {
    if (!in.value("required", false)) continue;
    const std::string name = in.value("name", "");
    if (name != "depth_mm" || truth.depth_mm.empty())
      return Error(Code::failed_precondition, "needs input '" + name + "', which the bench cannot make");
    const float* src = truth.depth_mm.ptr<float>();
    storage.emplace_back(src, src + size_t{w} * h);
    host::InputImage img;
    img.name = name;
    img.unit = in.value("unit", "mm");
    img.description = "procam bench: the sim's true depth";
    img.image = procam_image{.width = w, .height = h, .channels = 1, .pixel_type = PROCAM_PIXEL_F32,
                             .bit_depth = 32, .reserved = 0, .stride_bytes = size_t{w} * sizeof(float),
                             .data = storage.back().data()};
    inputs.push_back(img);
    note += (note.empty() ? "" : ", ") + name + " = true depth";
  }
  return inputs;
}

}  // namespace

int cmd_bench(const Args& a) {
  if (!a.has("out")) return usage_error("bench needs --out DIR");
  const std::string rig_path = a.has("rig") ? a.get("rig") : PROCAM_DEFAULT_RIG;
  auto rig_cfg = engine::read_json_file(rig_path);
  if (!rig_cfg) return report(rig_cfg.status().with_context("--rig"));
  const fs::path scenes_dir = a.has("scenes")
      ? fs::path(a.get("scenes"))
      : (fs::path(rig_path).parent_path() / ".." / "scenes").lexically_normal();
  std::vector<std::string> scenes;  // names in scenes_dir, then files given with --scene
  if (!a.has("only-listed") && fs::is_directory(scenes_dir))
    for (const auto& e : fs::directory_iterator(scenes_dir))
      if (e.path().extension() == ".json") scenes.push_back(e.path().stem().string());
  std::sort(scenes.begin(), scenes.end());
  // Scan options take scene names only (a rig never opens a path a client
  // names); a --scene FILE adds its folder to the rig's scene folders and is
  // run by its name.
  std::vector<std::string> scene_dirs{scenes_dir.string()};
  // The rig config's own scene folder last: its default scene must load even
  // when --scenes names a folder without it (e.g. configs/scenes/validation).
  const fs::path rig_scenes = (fs::path(rig_path).parent_path() / ".." / "scenes").lexically_normal();
  if (fs::is_directory(rig_scenes) && fs::weakly_canonical(rig_scenes) != fs::weakly_canonical(scenes_dir))
    scene_dirs.push_back(rig_scenes.string());
  for (const auto& s : a.list("scene")) {
    const fs::path p(s);
    if (p.extension() == ".json" || s.find('/') != std::string::npos) {
      scene_dirs.push_back(fs::absolute(p).parent_path().string());
      scenes.push_back(p.stem().string());
    } else {
      scenes.push_back(s);
    }
  }
  if (scenes.empty()) return usage_error("bench: no scenes in " + scenes_dir.string() + " and none given with --scene");

  unsigned threads = 2;
  if (a.has("threads")) threads = static_cast<unsigned>(std::max(1, std::atoi(a.get("threads").c_str())));
  hw::RigContext ctx{fs::path(rig_path).parent_path().string(), scene_dirs};
  auto rig = hw::create_rig(engine::without_calibration_tables(*rig_cfg), ctx);  // tables: not a device key
  if (!rig) return report(rig.status());
  nlohmann::json rig_json = engine::plugin_rig_json(**rig, threads);
  {
    // The rig config's calibration tables (defocus, separation), as procamd passes them.
    auto tables = engine::load_calibration_tables(*rig_cfg, fs::path(rig_path).parent_path().string(), rig_path);
    if (!tables) return report(tables.status().with_context("--rig"));
    if (tables->is_object() && !tables->empty()) rig_json["calibration_tables"] = *tables;
  }

  const std::vector<std::string> dirs = plugin_search_dirs(a);
  host::PluginHost host;
  host.load_directories(dirs);
  std::vector<Variant> variants;
  const std::vector<std::string> only = a.list("method");
  std::map<std::string, nlohmann::json> describe;  // "plugin/method" -> describe()
  for (const auto& p : host.plugins())
    for (const auto& m : p.methods) {
      // Calibration methods make a table and decode no scene: only when named
      // with --method (their table is then in --keep's outputs.json).
      if (m.name.rfind("calibrate-", 0) == 0 && std::find(only.begin(), only.end(), m.name) == only.end()) continue;
      describe[p.name + "/" + m.name] = m.describe;
      for (Variant v : variants_for(p.name, m.name)) {
        for (const auto& kv : a.list("param")) {  // --param method.key=value
          const auto dot = kv.find('.'), eq = kv.find('=');
          if (dot == std::string::npos || eq == std::string::npos || dot > eq) continue;
          if (kv.substr(0, dot) != v.label) continue;
          const std::string val = kv.substr(eq + 1);
          const nlohmann::json parsed = nlohmann::json::parse(val, nullptr, false);
          v.params[kv.substr(dot + 1, eq - dot - 1)] = parsed.is_discarded() ? nlohmann::json(val) : parsed;
        }
        if (!only.empty() && std::find(only.begin(), only.end(), v.label) == only.end() &&
            std::find(only.begin(), only.end(), v.method) == only.end())
          continue;
        variants.push_back(std::move(v));
      }
    }
  if (variants.empty()) return usage_error("bench: no plugin methods found (or none match --method)");

  std::vector<Row> rows;
  std::atomic<bool> cancel{false};
  for (const std::string& scene : scenes) {
    if (auto s = (*rig)->apply_scan_options({{"scene", scene}}); !s) {
      Row r;
      r.scene = scene;
      r.label = "*";
      r.error = s.message();
      rows.push_back(r);
      std::fprintf(stderr, "scene %s: %s\n", scene.c_str(), r.error.c_str());
      continue;
    }
    auto truth = (*rig)->ground_truth(0);
    for (const Variant& v : variants) {
      // Re-applying the scene (loaded already: cheap) restarts the rig's
      // frame sequence, so every method sees the same sensor noise on the
      // frames it shares with another: paired comparisons.
      (void)(*rig)->apply_scan_options({{"scene", scene}});
      Row r;
      r.scene = fs::path(scene).stem().string();
      r.label = v.label;
      std::fprintf(stderr, "  %-16s %-18s ", r.scene.c_str(), v.label.c_str());
      std::vector<std::vector<float>> storage;
      Result<std::vector<host::InputImage>> inputs = std::vector<host::InputImage>{};
      if (truth) inputs = truth_inputs(describe[v.plugin + "/" + v.method], *truth, storage, r.inputs_note);
      auto session = inputs ? host.create_session(v.plugin, v.method, v.params.dump(), rig_json.dump(), *inputs)
                            : Result<host::Session>(inputs.status());
      if (!session) {
        r.error = session.status().message();
      } else {
        auto outcome = engine::run_scan(**rig, *session, engine::CaptureOptions{}, nullptr, cancel);
        if (!outcome) {
          r.error = outcome.status().message();
        } else {
          r.patterns = outcome->patterns;
          r.rounds = outcome->rounds.size();
          r.decode_ms = outcome->decode_ms;
          auto outs = session->outputs();
          if (!outs) {
            r.error = outs.status().message();
          } else {
            std::optional<Image> col;
            for (const auto& o : *outs) {
              if (o.kind == PROCAM_OUTPUT_IMAGE && o.name == "proj_col_px") col = Image::copy_of(o.image);
              if (o.kind == PROCAM_OUTPUT_SCALAR && o.name == "decode_ms") r.decode_ms = o.scalar;
            }
            if (a.has("keep")) {  // every run's outputs, for inspection
              const fs::path keep = fs::path(a.get("keep")) / r.scene / v.label;
              auto w = engine::write_outputs(keep.string(), *outs);
              if (!w) {
                std::fprintf(stderr, "(keep: %s) ", w.status().message().c_str());
              } else {  // scalars and the method's report (rounds, classes, why) beside the maps
                std::ofstream(keep / "outputs.json") << w->outputs.dump(2) << "\n";
              }
            }
            if (!truth) {
              r.error = "no ground truth: " + truth.status().message();
            } else {
              // correspondence (+ per-code maps, sub-pixel), depth, components: the evaluators the outputs select
              r.eval = engine::evaluate_outputs(*outs, *truth);
              r.correspondence = col.has_value();
              r.ok = true;  // a method without a map to evaluate (e.g. a report only) is a row of dashes
              for (const auto& o : *outs)  // this report's own breakdown by light-transport class
                if (col && o.kind == PROCAM_OUTPUT_IMAGE && o.name == "transport_class")
                  r.eval["gross_by_class"] = gross_by_class(*col, Image::copy_of(o.image), *truth);
            }
          }
        }
      }
      if (r.ok && r.correspondence)
        std::fprintf(stderr, "%3zu patterns  %7.1f ms  decoded %5.1f%%  gross %6.2f%%\n", r.patterns, r.decode_ms,
                     100 * num(r.eval, "decoded_fraction"), 100 * num(r.eval, "gross_error_fraction"));
      else if (r.ok)
        std::fprintf(stderr, "%3zu patterns  %7.1f ms  evaluated: %s\n", r.patterns, r.decode_ms,
                     r.eval["evaluators"].dump().c_str());
      else
        std::fprintf(stderr, "error: %s\n", r.error.c_str());
      rows.push_back(std::move(r));
    }
  }

  const fs::path out(a.get("out"));
  std::error_code ec;
  fs::create_directories(out, ec);
  std::vector<std::string> labels;
  for (const Variant& v : variants) labels.push_back(v.label);
  std::ostringstream md, other;
  md << "| scene | method | patterns | capture @60 Hz (s) | rounds | decode (ms) | lit decoded (%) | gross errors (%) | within 1 col (%) | RMS col err (px) | RMS sub-px refined (px) | depth RMS (mm) |\n"
     << "|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|\n";
  // Other families: depth relative to the true depth, direct/global median
  // relative error against the sim's light-transport split.
  other << "| scene | method | patterns | decode (ms) | depth: lit decoded (%) | depth median rel err (%) | depth rel RMS (%) "
           "| direct median rel err (%) | global median rel err (%) | inputs from truth |\n"
        << "|---|---|---:|---:|---:|---:|---:|---:|---:|---|\n";
  size_t other_rows = 0;
  nlohmann::json all = nlohmann::json::array();
  for (const Row& r : rows) {
    if (!r.ok && r.error.empty()) continue;
    if (!r.ok) {
      md << "| " << r.scene << " | " << r.label << " | error: " << r.error << " ||||||||||\n";
    } else if (r.correspondence) {
      md << "| " << r.scene << " | " << r.label << " | " << r.patterns << " | "
         << fmt(static_cast<double>(r.patterns) / 60.0, 2) << " | " << r.rounds << " | " << fmt(r.decode_ms, 1) << " | "
         << fmt(100 * num(r.eval, "decoded_fraction"), 1) << " | " << fmt(100 * num(r.eval, "gross_error_fraction"), 2)
         << " | " << fmt(100 * num(r.eval, "within_1col_fraction"), 1) << " | " << fmt(num(r.eval, "col_rms_px"), 3)
         << " | " << (r.eval.contains("subpx") ? fmt(num(r.eval["subpx"], "col_rms_px"), 3) : std::string("–"))
         << " | " << fmt(num(r.eval, "depth_rms_mm"), 2) << " |\n";
    } else {
      ++other_rows;
      const nlohmann::json d = r.eval.value("depth", nlohmann::json::object());
      const nlohmann::json c = r.eval.value("components", nlohmann::json::object());
      const nlohmann::json cd = c.value("direct", nlohmann::json::object()), cg = c.value("global", nlohmann::json::object());
      other << "| " << r.scene << " | " << r.label << " | " << r.patterns << " | " << fmt(r.decode_ms, 1) << " | "
            << (d.empty() ? "–" : fmt(100 * num(d, "decoded_fraction"), 1)) << " | "
            << fmt(100 * num(d, "median_rel_error"), 2) << " | " << fmt(100 * num(d, "rel_rms"), 2) << " | " << fmt(100 * num(cd, "median_rel_error"), 1) << " | "
            << fmt(100 * num(cg, "median_rel_error"), 1) << " | " << (r.inputs_note.empty() ? "–" : r.inputs_note)
            << (r.eval["evaluators"].empty() ? " (no map to evaluate: see the method's report)" : "") << " |\n";
    }
    all.push_back({{"scene", r.scene}, {"method", r.label}, {"ok", r.ok}, {"error", r.error},
                   {"patterns", r.patterns}, {"capture_s_at_60hz", static_cast<double>(r.patterns) / 60.0},
                   {"rounds", r.rounds}, {"decode_ms", r.decode_ms}, {"evaluation", r.eval},
                   {"inputs_from_truth", r.inputs_note}});
  }
  if (other_rows > 0) md << "\n" << other.str();
  const nlohmann::json doc = {{"rig", rig_path}, {"threads", threads},
                              {"hardware_concurrency", std::thread::hardware_concurrency()},
                              {"runs", all}};
  std::ofstream(out / "bench.md") << md.str();
  std::ofstream(out / "bench.json") << doc.dump(2) << "\n";
  // Column codes: gross errors; other families: depth and direct-light error
  // (bench-depth.png, bench-direct.png), each only when some row has it.
  plot(rows, labels, (out / "bench.png").string(),
       {[](const Row& r) { return r.correspondence ? 100.0 * num(r.eval, "gross_error_fraction") : std::nan(""); },
        "gross errors, % of decoded lit pixels (|col err| > 1)"});
  auto section = [](const Row& r, const char* name) {
    return r.eval.contains(name) && r.eval[name].is_object() ? r.eval[name] : nlohmann::json::object();
  };
  const PlotSpec depth{[&](const Row& r) {
                         return r.correspondence ? std::nan("") : 100.0 * num(section(r, "depth"), "median_rel_error");
                       },
                       "depth error, median % of the true depth"};
  const PlotSpec direct{[&](const Row& r) {
                          const auto c = section(r, "components");
                          const auto d = c.contains("direct") ? c["direct"] : nlohmann::json::object();
                          return r.correspondence ? std::nan("") : 100.0 * num(d, "median_rel_error");
                        },
                        "direct light (white) error, median % of the truth"};
  for (const auto& [spec, file] : {std::pair{depth, "bench-depth.png"}, std::pair{direct, "bench-direct.png"}})
    if (std::any_of(rows.begin(), rows.end(), [&](const Row& r) { return r.ok && std::isfinite(spec.y(r)); }))
      plot(rows, labels, (out / file).string(), spec);
  if (a.json)
    std::cout << doc.dump(2) << "\n";
  else
    std::cout << md.str();
  return 0;
}

}  // namespace procam::cli
