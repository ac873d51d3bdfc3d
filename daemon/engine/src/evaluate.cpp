// SPDX-License-Identifier: MIT
// Evaluators of plugin outputs against ground truth and their registry
// (see evaluate.hpp for the definitions).
#include "procam/engine/evaluate.hpp"

#include <algorithm>
#include <cmath>
#include <optional>
#include <string>
#include <vector>

namespace procam::engine {

namespace {

// Value at fraction p of the sorted values (nearest rank); a is reordered.
double percentile(std::vector<double>& a, double p) {
  const size_t k = static_cast<size_t>(p * double(a.size() - 1));
  std::nth_element(a.begin(), a.begin() + static_cast<std::ptrdiff_t>(k), a.end());
  return a[k];
}

bool same_size(const Image& a, const Image& b) { return a.width() == b.width() && a.height() == b.height(); }

const host::Output* find_output(const std::vector<host::Output>& outputs, const std::string& name,
                                procam_output_kind kind) {
  for (const auto& o : outputs)
    if (o.name == name && o.kind == kind) return &o;
  return nullptr;
}

// A copy of an F32 image output, or nullopt for another pixel type.
std::optional<Image> f32_image(const host::Output& o) {
  if (o.image.pixel_type != PROCAM_PIXEL_F32 || o.image.channels != 1) return std::nullopt;
  return Image::copy_of(o.image);
}

nlohmann::json error(const std::string& what) { return {{"error", what}}; }

}  // namespace

nlohmann::json evaluate_correspondence(const Image& col, const Image* depth,
                                       const hw::GroundTruth& truth) {
  nlohmann::json j;
  if (col.type() != PixelType::f32 || col.width() != truth.proj_col.width() ||
      col.height() != truth.proj_col.height()) {
    j["error"] = "decoded column map does not match the ground-truth size";
    return j;
  }
  const bool have_depth = depth != nullptr && depth->type() == PixelType::f32 &&
                          depth->width() == col.width() && depth->height() == col.height();
  const size_t n = col.pixel_count();
  const float* c = col.ptr<float>();
  const float* tc = truth.proj_col.ptr<float>();
  const float* td = truth.depth_mm.ptr<float>();
  const uint8_t* lit = truth.lit.ptr<uint8_t>();
  const float* d = have_depth ? depth->ptr<float>() : nullptr;

  size_t lit_n = 0, decoded_lit = 0, within1 = 0, gross = 0, decoded_all = 0, spurious = 0;
  double col_sq = 0;
  size_t col_n = 0;
  std::vector<double> depth_err;
  for (size_t i = 0; i < n; ++i) {
    const bool dec = std::isfinite(c[i]);
    decoded_all += dec;
    if (!lit[i]) {
      spurious += dec;
      continue;
    }
    ++lit_n;
    if (!dec) continue;
    ++decoded_lit;
    const double err = double(c[i]) - double(tc[i]);
    if (std::abs(err) <= 1.0) {
      ++within1;
      col_sq += err * err;
      ++col_n;
      if (d && std::isfinite(d[i]) && std::isfinite(td[i])) depth_err.push_back(double(d[i]) - double(td[i]));
    } else {
      ++gross;
    }
  }
  auto frac = [](size_t a, size_t b) { return b ? double(a) / double(b) : 0.0; };
  j["lit_pixels"] = lit_n;
  j["decoded_fraction"] = frac(decoded_lit, lit_n);
  j["within_1col_fraction"] = frac(within1, lit_n);
  j["gross_error_fraction"] = frac(gross, decoded_lit);
  j["col_rms_px"] = col_n ? std::sqrt(col_sq / double(col_n)) : 0.0;
  j["spurious_fraction"] = frac(spurious, decoded_all);
  if (have_depth && !depth_err.empty()) {
    double sq = 0;
    std::vector<double> a;
    a.reserve(depth_err.size());
    for (double e : depth_err) {
      sq += e * e;
      a.push_back(std::abs(e));
    }
    auto pct = [&](double p) {
      size_t k = static_cast<size_t>(p * double(a.size() - 1));
      std::nth_element(a.begin(), a.begin() + static_cast<std::ptrdiff_t>(k), a.end());
      return a[k];
    };
    j["depth_rms_mm"] = std::sqrt(sq / double(depth_err.size()));
    j["depth_median_abs_mm"] = pct(0.5);
    j["depth_p99_abs_mm"] = pct(0.99);
    j["depth_pixels"] = depth_err.size();
  }
  return j;
}

nlohmann::json evaluate_depth(const Image& depth, const hw::GroundTruth& truth) {
  if (depth.type() != PixelType::f32 || !same_size(depth, truth.depth_mm))
    return error("depth map is not F32 of the ground-truth size");
  const float* d = depth.ptr<float>();
  const float* td = truth.depth_mm.ptr<float>();
  const uint8_t* lit = truth.lit.ptr<uint8_t>();
  size_t lit_n = 0;
  double sum = 0, sq = 0, rel_sq = 0;
  std::vector<double> a, rel;
  for (size_t i = 0; i < depth.pixel_count(); ++i) {
    if (!lit[i]) continue;
    ++lit_n;
    if (!std::isfinite(d[i]) || !std::isfinite(td[i])) continue;
    const double e = double(d[i]) - double(td[i]);
    sum += e;
    sq += e * e;
    a.push_back(std::abs(e));
    if (td[i] > 0) {  // relative to the true depth (thesis Fig. 2.7 reports depth error this way)
      const double r = std::abs(e) / double(td[i]);
      rel.push_back(r);
      rel_sq += r * r;
    }
  }
  nlohmann::json j = {{"pixels", a.size()}, {"decoded_fraction", lit_n ? double(a.size()) / double(lit_n) : 0.0}};
  if (a.empty()) return j;
  const double n = double(a.size());
  j["bias_mm"] = sum / n;
  j["rms_mm"] = std::sqrt(sq / n);
  j["median_abs_mm"] = percentile(a, 0.5);
  j["p99_abs_mm"] = percentile(a, 0.99);
  if (!rel.empty()) {
    j["median_rel_error"] = percentile(rel, 0.5);
    j["rel_rms"] = std::sqrt(rel_sq / double(rel.size()));
  }
  return j;
}

nlohmann::json evaluate_component(const Image& est, const Image& truth_dn, const hw::GroundTruth& truth) {
  if (est.type() != PixelType::f32 || !same_size(est, truth_dn) || !same_size(est, truth.lit))
    return error("component map is not F32 of the ground-truth size");
  const float* e = est.ptr<float>();
  const float* t = truth_dn.ptr<float>();
  const uint8_t* lit = truth.lit.ptr<uint8_t>();
  std::vector<double> abs_err, rel_err;
  double est_sum = 0, truth_sum = 0;
  for (size_t i = 0; i < est.pixel_count(); ++i) {
    if (!lit[i] || !std::isfinite(e[i]) || !std::isfinite(t[i])) continue;
    const double err = std::abs(double(e[i]) - double(t[i]));
    abs_err.push_back(err);
    est_sum += double(e[i]);
    truth_sum += double(t[i]);
    if (double(t[i]) >= kMinTruthDn) rel_err.push_back(err / double(t[i]));
  }
  nlohmann::json j = {{"pixels", abs_err.size()}, {"rel_pixels", rel_err.size()}};
  if (abs_err.empty()) return j;
  j["median_abs_error_dn"] = percentile(abs_err, 0.5);
  j["estimate_mean_dn"] = est_sum / double(abs_err.size());
  j["truth_mean_dn"] = truth_sum / double(abs_err.size());
  j["median_rel_error"] = rel_err.empty() ? nlohmann::json() : nlohmann::json(percentile(rel_err, 0.5));
  return j;
}

namespace {

// ---- the registry's entries ------------------------------------------------

bool has_image(const std::vector<host::Output>& o, const char* name) {
  return find_output(o, name, PROCAM_OUTPUT_IMAGE) != nullptr;
}

nlohmann::json correspondence(const std::vector<host::Output>& outputs, const hw::GroundTruth& truth) {
  const host::Output* col = find_output(outputs, "proj_col_px", PROCAM_OUTPUT_IMAGE);
  auto c = f32_image(*col);
  if (!c) return error("proj_col_px is not an F32 map");
  std::optional<Image> d;
  if (const host::Output* depth = find_output(outputs, "depth_mm", PROCAM_OUTPUT_IMAGE)) d = f32_image(*depth);
  nlohmann::json j = evaluate_correspondence(*c, d ? &*d : nullptr, truth);
  for (const auto& o : outputs) {
    if (o.kind != PROCAM_OUTPUT_IMAGE) continue;
    const bool code = o.name.rfind("proj_col_px_", 0) == 0;  // per-code maps of an ensemble
    if (!code && o.name != "proj_col_subpx") continue;        // sub-pixel refinement
    auto m = f32_image(o);
    nlohmann::json e = m ? evaluate_correspondence(*m, nullptr, truth) : error(o.name + " is not an F32 map");
    if (code)
      j["codes"][o.name.substr(12)] = std::move(e);
    else
      j["subpx"] = std::move(e);
  }
  return j;
}

nlohmann::json depth(const std::vector<host::Output>& outputs, const hw::GroundTruth& truth) {
  auto d = f32_image(*find_output(outputs, "depth_mm", PROCAM_OUTPUT_IMAGE));
  if (!d) return error("depth_mm is not an F32 map");
  return evaluate_depth(*d, truth);
}

bool has_component(const std::vector<host::Output>& o) { return has_image(o, "direct_dn") || has_image(o, "global_dn"); }

nlohmann::json components(const std::vector<host::Output>& outputs, const hw::GroundTruth& truth) {
  nlohmann::json j = nlohmann::json::object();
  for (const char* name : {"direct", "global"}) {
    const std::string out_name = std::string(name) + "_dn";
    const host::Output* o = find_output(outputs, out_name, PROCAM_OUTPUT_IMAGE);
    if (o == nullptr) continue;
    const Image& t = std::string(name) == "direct" ? truth.direct : truth.global;
    if (t.empty()) {
      j[name] = error("no truth for " + out_name + ": the rig's ground truth has no " + name + " map");
      continue;
    }
    auto m = f32_image(*o);
    j[name] = m ? evaluate_component(*m, t, truth) : error(out_name + " is not an F32 map");
  }
  return j;
}

bool has_medium(const std::vector<host::Output>& outputs) {
  for (const auto& o : outputs)
    if (o.kind == PROCAM_OUTPUT_SCALAR && o.name.rfind("medium_", 0) == 0) return true;
  return false;
}

nlohmann::json medium(const std::vector<host::Output>& outputs, const hw::GroundTruth& truth) {
  nlohmann::json j = nlohmann::json::object();
  for (const auto& o : outputs) {
    if (o.kind != PROCAM_OUTPUT_SCALAR || o.name.rfind("medium_", 0) != 0) continue;
    const std::string param = o.name.substr(7);
    const bool known = truth.medium.is_object() && truth.medium.contains(param) && truth.medium[param].is_number();
    if (!known) {
      j[o.name] = error("no truth for " + o.name);
      continue;
    }
    const double t = truth.medium[param].get<double>();
    nlohmann::json e = {{"estimate", o.scalar}, {"truth", t}, {"abs_error", std::abs(o.scalar - t)}};
    e["rel_error"] = t != 0 ? nlohmann::json(std::abs(o.scalar - t) / std::abs(t)) : nlohmann::json();
    j[o.name] = std::move(e);
  }
  return j;
}

}  // namespace

const std::vector<Evaluator>& evaluators() {
  static const std::vector<Evaluator> registry = {
      {"correspondence", "proj_col_px (+ depth_mm, proj_col_px_<code>, proj_col_subpx)",
       [](const std::vector<host::Output>& o) { return has_image(o, "proj_col_px"); }, &correspondence},
      {"depth", "depth_mm", [](const std::vector<host::Output>& o) { return has_image(o, "depth_mm"); }, &depth},
      {"components", "direct_dn, global_dn", &has_component, &components},
      {"medium", "scalars medium_<param>", &has_medium, &medium},
  };
  return registry;
}

nlohmann::json evaluate_outputs(const std::vector<host::Output>& outputs, const hw::GroundTruth& truth) {
  nlohmann::json result = nlohmann::json::object();
  nlohmann::json ran = nlohmann::json::array();
  for (const Evaluator& e : evaluators()) {
    if (!e.applies(outputs)) continue;
    nlohmann::json section;
    try {
      section = e.evaluate(outputs, truth);
    } catch (const std::exception& ex) {  // bad_alloc, json: keep the other sections
      section = error(std::string("evaluation failed: ") + ex.what());
    }
    if (std::string(e.name) == "correspondence")
      for (auto it = section.begin(); it != section.end(); ++it) result[it.key()] = it.value();
    else
      result[e.name] = std::move(section);
    ran.push_back(e.name);
  }
  result["evaluators"] = std::move(ran);
  return result;
}

}  // namespace procam::engine
