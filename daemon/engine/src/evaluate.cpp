// SPDX-License-Identifier: MIT
// Accuracy against ground truth (see evaluate.hpp for the definitions).
#include "procam/engine/evaluate.hpp"

#include <algorithm>
#include <cmath>
#include <vector>

namespace procam::engine {

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

}  // namespace procam::engine
