// SPDX-License-Identifier: MIT
// Linearity, best volume and the single-scattering stop (see concentration.hpp).
#include "concentration.hpp"

#include <cmath>
#include <cstdio>

namespace procam::medium {
namespace {

std::string fmt(double v) {
  char b[32];
  std::snprintf(b, sizeof b, "%.4g", v);
  return b;
}

bool usable(const DilutionPoint& p) { return p.volume_ml > 0 && std::isfinite(p.sigma_hat); }

}  // namespace

ConcentrationResult analyse_dilutions(std::vector<DilutionPoint> points, const ConcentrationSettings& s) {
  ConcentrationResult r;
  r.points = std::move(points);
  double num = 0, den = 0;
  unsigned used = 0;
  for (const DilutionPoint& p : r.points) {
    if (!usable(p) || used >= s.linear_points) continue;
    num += p.volume_ml * p.sigma_hat;
    den += p.volume_ml * p.volume_ml;
    ++used;
  }
  r.slope_per_ml = den > 0 ? num / den : 0.0;
  for (size_t i = 0; i < r.points.size(); ++i) {
    const DilutionPoint& p = r.points[i];
    if (!std::isfinite(p.sigma_hat)) {
      r.warnings.push_back("volume " + fmt(p.volume_ml) + " ml: no sigma-hat (" + p.note + ")");
      continue;
    }
    if (r.first_over_bound < 0 && p.sigma_hat > s.max_sigma_per_mm) {
      r.first_over_bound = int(i);
      r.warnings.push_back("STOP at volume " + fmt(p.volume_ml) + " ml: sigma-hat = " + fmt(p.sigma_hat) +
                           " /mm exceeds max_sigma_per_mm = " + fmt(s.max_sigma_per_mm) +
                           " /mm, beyond single scattering (thesis §4.2.3): do not measure at this or a higher volume");
    }
    const double line = r.slope_per_ml * p.volume_ml;
    if (r.first_nonlinear < 0 && usable(p) && line > 0 && p.sigma_hat < (1.0 - s.tolerance) * line) {
      r.first_nonlinear = int(i);
      r.warnings.push_back("STOP at volume " + fmt(p.volume_ml) + " ml: sigma-hat = " + fmt(p.sigma_hat) + " /mm is " +
                           fmt(100.0 * (1.0 - p.sigma_hat / line)) + " % below the line through the low volumes (" +
                           fmt(line) + " /mm): multiple scattering (thesis §4.2.4, Fig. 4.7); measure at a lower volume");
    }
  }
  size_t end = r.points.size();
  if (r.first_nonlinear >= 0) end = std::min(end, size_t(r.first_nonlinear));
  if (r.first_over_bound >= 0) end = std::min(end, size_t(r.first_over_bound));
  for (size_t i = 0; i < end; ++i)
    if (usable(r.points[i]) && r.points[i].bulb_radiance >= s.min_bulb_radiance) r.best = int(i);
  if (r.best < 0)
    r.warnings.push_back("no usable volume: every non-zero volume is nonlinear, beyond the bound, too dark (bulb "
                         "radiance below min_bulb_radiance) or unmeasured; dilute further and repeat");
  return r;
}

nlohmann::json ConcentrationResult::to_json() const {
  nlohmann::json pts = nlohmann::json::array();
  for (size_t i = 0; i < points.size(); ++i) {
    const DilutionPoint& p = points[i];
    pts.push_back({{"volume_ml", p.volume_ml},
                   {"sigma_hat_per_mm", p.sigma_hat},
                   {"sigma_hat_ci95", p.sigma_hat_ci95},
                   {"bulb_radiance", p.bulb_radiance},
                   {"line_per_mm", slope_per_ml * p.volume_ml},
                   {"linear", (first_nonlinear < 0 || int(i) < first_nonlinear)},
                   {"within_bound", (first_over_bound < 0 || int(i) < first_over_bound)}});
    if (!p.note.empty()) pts.back()["note"] = p.note;
  }
  nlohmann::json j = {{"points", pts},
                      {"slope_per_mm_per_ml", slope_per_ml},
                      {"warnings", warnings},
                      {"best_volume_ml", best >= 0 ? nlohmann::json(points[size_t(best)].volume_ml) : nlohmann::json()}};
  if (first_nonlinear >= 0) j["first_nonlinear_volume_ml"] = points[size_t(first_nonlinear)].volume_ml;
  if (first_over_bound >= 0) j["first_over_bound_volume_ml"] = points[size_t(first_over_bound)].volume_ml;
  const int stop = first_nonlinear < 0 ? first_over_bound
                   : first_over_bound < 0 ? first_nonlinear
                                          : std::min(first_nonlinear, first_over_bound);
  if (stop >= 0) j["stop_volume_ml"] = points[size_t(stop)].volume_ml;
  return j;
}

}  // namespace procam::medium
