// SPDX-License-Identifier: MIT
// Source–camera placement by single scattering (thesis §5.3; see placement.hpp).
#include "placement.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <numbers>

#include "media_model.hpp"

namespace procam::polarized_striping {
namespace {

constexpr double kPi = std::numbers::pi;
// Scatterers closer than this to the camera/source plane z = 0 are left out:
// B diverges as 1/t^2 at a co-located source (a real rig's housing and the
// tank's front glass keep the medium this far away).
constexpr double kNearMm = 10.0;

struct V3 {
  double x, y, z;
};
V3 operator-(V3 a, V3 b) { return {a.x - b.x, a.y - b.y, a.z - b.z}; }
V3 operator+(V3 a, V3 b) { return {a.x + b.x, a.y + b.y, a.z + b.z}; }
V3 operator*(double s, V3 a) { return {s * a.x, s * a.y, s * a.z}; }
double dot(V3 a, V3 b) { return a.x * b.x + a.y * b.y + a.z * b.z; }
double norm(V3 a) { return std::sqrt(dot(a, a)); }

// Henyey–Greenstein phase function (per steradian) of the angle whose cosine is c.
double hg(double g, double c) { return (1 - g * g) / (4 * kPi * std::pow(1 + g * g - 2 * g * c, 1.5)); }

struct Components {
  double d = 0, a = 0, b = 0;
};

// Eq. 5.11–5.13 for the source at L (flood) and, restricted to the light
// sheet through L, O and the y axis, for one sheet. Units: I0 = 1.
void components(const PlacementParams& pp, double s, Components& flood, Components& sheet) {
  const double d = pp.distance_mm, sg = pp.sigma_per_mm, bt = pp.beta_per_mm, g = pp.g;
  const double rho = pp.albedo / kPi;  // Lambertian BRDF
  const V3 L{s, 0, 0}, O{0, 0, d};
  const double d_lo = norm(O - L);
  // Eq. 5.11: cos(phi) = d / d_LO (plane normal -z, source direction (s, 0, -d)).
  flood.d = sheet.d = std::exp(-sg * (d_lo + d)) / (d_lo * d_lo) * rho * (d / d_lo);
  // Light-sheet plane: normal n = (O - L) x y, unit.
  const V3 n0{-d, 0, -s};
  const V3 n = (1.0 / norm(n0)) * n0;
  const double half = 0.5 * pp.sheet_mm;

  // Eq. 5.13 along the camera ray Y = (0, 0, t): scattering angle between the
  // incident direction (Y - L) and the direction to the camera (0, 0, -1).
  const int nb = 2000 * pp.quality;
  const double dt = (d - kNearMm) / nb;
  flood.b = sheet.b = 0;
  for (int i = 0; i < nb; ++i) {
    const double t = kNearMm + (i + 0.5) * dt;
    const V3 Y{0, 0, t};
    const V3 ly = Y - L;
    const double d_ly = norm(ly);
    const double v = std::exp(-sg * (d_ly + t)) / (d_ly * d_ly) * bt * hg(g, -ly.z / d_ly) * dt;
    flood.b += v;
    if (std::abs(dot(n, Y - O)) <= half) sheet.b += v;
  }

  // Eq. 5.12, flood. The integrand has 1/d_LX^2 and 1/d_XO^2 peaks; the
  // volume is split by the plane equidistant from O and L, and each half is
  // integrated in spherical coordinates about its own peak (dV = r^2 dr dw
  // cancels it). X = c + r w about c = O (w towards the camera, -z) or c = L
  // (w into the medium, +z); alpha between (X - L) and (O - X); cos(gamma) =
  // (d - X_z) / d_XO. Midpoint rule in (theta, phi, r).
  const int nth = 16 * pp.quality, nph = 32 * pp.quality, nr = 48 * pp.quality;
  double acc = 0;
  for (int centre = 0; centre < 2; ++centre) {
    const bool about_o = centre == 0;
    const V3 c = about_o ? O : L;
    for (int it = 0; it < nth; ++it) {
      const double th = (it + 0.5) * (0.5 * kPi / nth), ct = std::cos(th), st = std::sin(th);
      // Medium slab kNearMm <= z <= d along w: r in [r0, r1].
      const double r0 = about_o ? 0.0 : kNearMm / ct;
      const double r1 = std::min(about_o ? (d - kNearMm) / ct : d / ct, 3 * d);
      if (r1 <= r0) continue;
      const double dr = (r1 - r0) / nr;
      for (int ip = 0; ip < nph; ++ip) {
        const double ph = (ip + 0.5) * (2 * kPi / nph);
        const V3 w{st * std::cos(ph), st * std::sin(ph), about_o ? -ct : ct};
        for (int ir = 0; ir < nr; ++ir) {
          const double r = r0 + (ir + 0.5) * dr;
          const V3 X = c + r * w, lx = X - L, xo = O - X;
          const double d_lx = norm(lx), d_xo = norm(xo);
          if ((d_xo <= d_lx) != about_o) continue;  // the other half's sample
          const double cos_alpha = dot(lx, xo) / (d_lx * d_xo), cos_gamma = (d - X.z) / d_xo;
          // 1/d^2 of the centre cancels with r^2; the other one stays.
          const double other = about_o ? d_lx * d_lx : d_xo * d_xo;
          acc += std::exp(-sg * (d_lx + d_xo)) / other * bt * hg(g, cos_alpha) * cos_gamma * dr * st;
        }
      }
    }
  }
  flood.a = rho * std::exp(-sg * d) * acc * (0.5 * kPi / nth) * (2 * kPi / nph);

  // Eq. 5.12, light sheet: X = O + r (cos ps e1 + sin ps e2) in the sheet's
  // plane (e1 = y, e2 = (L - O) / d_LO), dV = sheet_mm r dr dps; the part
  // within half a thickness of O (where the slab is not thin) is left out.
  const V3 e1{0, 1, 0}, e2 = (1.0 / d_lo) * (L - O);
  const int nps = 32 * pp.quality, nr2 = 96 * pp.quality;
  double acc2 = 0;
  for (int ip = 0; ip < nps; ++ip) {
    const double ps = (ip + 0.5) * (kPi / nps);  // sin ps > 0: the camera side of the plane
    const V3 w = std::cos(ps) * e1 + std::sin(ps) * e2;
    const double cos_gamma = -w.z;
    if (cos_gamma <= 0) continue;
    const double r_max = std::min((d - kNearMm) / cos_gamma, 3 * d);
    if (r_max <= half) continue;
    const double dr = (r_max - half) / nr2;
    for (int ir = 0; ir < nr2; ++ir) {
      const double r = half + (ir + 0.5) * dr;
      const V3 lx = (O + r * w) - L;
      const double d_lx = norm(lx);
      const double cos_alpha = -dot(lx, w) / d_lx;
      acc2 += std::exp(-sg * (d_lx + r)) / (d_lx * d_lx) * bt * hg(g, cos_alpha) * cos_gamma / r * dr;
    }
  }
  sheet.a = rho * std::exp(-sg * d) * acc2 * pp.sheet_mm * (kPi / nps);
}

// Index of the largest value and its parabolic refinement in separation units.
// Samples below `from_mm` are not candidates.
std::pair<size_t, double> arg_max(const std::vector<PlacementSample>& c, double PlacementSample::*f,
                                  double from_mm = -1) {
  size_t k = 0;
  while (k + 1 < c.size() && c[k].separation_mm < from_mm) ++k;
  for (size_t i = k + 1; i < c.size(); ++i)
    if (c[i].*f > c[k].*f) k = i;
  double x = c[k].separation_mm;
  if (k > 0 && k + 1 < c.size()) {
    const double y0 = c[k - 1].*f, y1 = c[k].*f, y2 = c[k + 1].*f, den = y0 - 2 * y1 + y2;
    const double h = c[k + 1].separation_mm - c[k].separation_mm;
    if (den < 0) x += std::clamp(0.5 * (y0 - y2) / den, -0.5, 0.5) * h;
  }
  return {k, x};
}

}  // namespace

std::string check(const PlacementParams& p) {
  if (!(p.distance_mm > 2 * kNearMm)) return "distance_mm must exceed " + std::to_string(2 * kNearMm) + " mm";
  if (!(p.sigma_per_mm >= 0) || !(p.beta_per_mm >= 0) || p.beta_per_mm > p.sigma_per_mm)
    return "need 0 <= beta <= sigma (scattering cannot exceed extinction)";
  if (!(std::abs(p.g) < 1)) return "the Henyey-Greenstein g must lie in (-1, 1)";
  if (!(p.albedo > 0 && p.albedo <= 1)) return "albedo must lie in (0, 1]";
  if (!(p.p >= 0 && p.p <= 1)) return "the DOP p must lie in [0, 1]";
  if (!(p.noise >= 0)) return "noise must be >= 0";
  if (!(p.sheet_mm > 0)) return "sheet_mm must be > 0";
  if (!(p.min_separation_mm >= 0 && p.max_separation_mm > p.min_separation_mm))
    return "need 0 <= min_separation_mm < max_separation_mm";
  if (p.steps < 3 || p.steps > 10000) return "steps must lie in 3..10000";
  if (p.quality < 1 || p.quality > 8) return "quality must lie in 1..8";
  return "";
}

PlacementResult evaluate_placement(const PlacementParams& pp) {
  PlacementResult r;
  const double d_clear = pp.albedo / kPi / (pp.distance_mm * pp.distance_mm);
  const double mu = 3 * pp.noise, z = pp.noise;  // Eq. 5.10 in units of D_clear
  for (int i = 0; i < pp.steps; ++i) {
    PlacementSample s;
    s.separation_mm = pp.min_separation_mm + (pp.max_separation_mm - pp.min_separation_mm) * i / (pp.steps - 1);
    Components f, sh;
    components(pp, s.separation_mm, f, sh);
    s.d = f.d / d_clear;
    s.a = f.a / d_clear;
    s.b = f.b / d_clear;
    s.sheet_a = sh.a / d_clear;
    s.sheet_b = sh.b / d_clear;
    s.cqm = cqm(s.d + s.a, s.b, pp.p);                 // Eq. 5.8
    s.w = snr_weight(s.d + s.a, mu, z);                 // Eq. 5.10
    s.cqm_w = s.cqm * s.w;
    s.gqm = gqm(s.d, s.sheet_a, s.sheet_b, pp.p);       // Eq. 5.9
    s.sheet_w = snr_weight(s.d + s.sheet_a, mu, z);
    s.gqm_w = s.gqm * s.sheet_w;
    r.curve.push_back(s);
  }
  std::tie(r.best_flood_index, r.best_flood_mm) = arg_max(r.curve, &PlacementSample::cqm_w);
  // A sheet seen from within its own plane (separation < its thickness)
  // cannot be delineated or triangulated: not a candidate.
  std::tie(r.best_sheet_index, r.best_sheet_mm) = arg_max(r.curve, &PlacementSample::gqm_w, pp.sheet_mm);
  return r;
}

std::string placement_csv(const PlacementResult& r) {
  std::string out = "separation_mm,d,a,b,cqm,w,cqm_w,sheet_a,sheet_b,gqm,sheet_w,gqm_w\n";
  char buf[400];
  for (const PlacementSample& s : r.curve) {
    std::snprintf(buf, sizeof buf, "%.3f,%.6g,%.6g,%.6g,%.6g,%.6g,%.6g,%.6g,%.6g,%.6g,%.6g,%.6g\n", s.separation_mm,
                  s.d, s.a, s.b, s.cqm, s.w, s.cqm_w, s.sheet_a, s.sheet_b, s.gqm, s.sheet_w, s.gqm_w);
    out += buf;
  }
  return out;
}

}  // namespace procam::polarized_striping
