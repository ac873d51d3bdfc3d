// SPDX-License-Identifier: MIT
// The dilution tank rig: bulb light in the medium (tank.hpp, docs/media.md "Tank rig").
#include "tank.hpp"

#include <algorithm>
#include <cmath>

#include "medium.hpp"
#include "parallel.hpp"

namespace procam::sim {
namespace {

constexpr double kPi = 3.14159265358979323846;
// Beyond this many bulb radii the visible cap (half-angle < 3.6°) is
// sampled with at most kFarSamples² directions instead of `samples`². Not
// by its centre alone: the phase function's curvature across the cap is a
// second-order but systematic error, p̄/p(centre) − 1 ≈ (α²/8)·p''/p, about
// +0.2 % at 90° for g = 0.93 and 160 mm (issue 14: the centre alone made
// the tank image 0.1–0.26 % dark at 90–200 mm from the bulb and biased the
// fitted σ by +0.7 %, κ = σ − β by +170 %).
constexpr double kFarRadii = 16.0;
constexpr int kFarSamples = 4;
constexpr int kZSteps = 768;       // midpoints in the angle about the bulb per line of sight
constexpr int kInnerEntries = 96;  // table entries for ρ in [0, r)
constexpr int kOuterEntries = 1024;  // table entries for ρ in [r, ρ_max], quadratic spacing

// Light single-scattered towards the camera (−z) at Y per unit β (§4.3.3):
//   ∫_cap L e^{−σ l(ω)} p(g, ω·ẑ) dω
// over the cone of directions ω from Y to the bulb (half-angle asin(r/d)),
// l the distance to the bulb's surface along ω. The cone is sampled
// samples × samples (midpoints in cos θ and φ: each sample is one patch of
// the visible cap, weighted by the solid angle it subtends, so Σ dω is the
// cap's exact solid angle 2π(1 − cos θ_max)).
double bulb_in_scatter(const Medium& m, const Medium::Bulb& b, const Vec3& y) {
  const Vec3 a_vec = y - b.center_mm;  // bulb centre → Y
  const double d = norm(a_vec);
  const double r = b.radius_mm;
  const double sigma = m.sigma_t_per_mm;
  const double L = b.radiance();
  const double sin_max = std::min(1.0, r / d);
  const double cos_max = std::sqrt(std::max(0.0, 1 - sin_max * sin_max));
  // az[] below holds 64; a far, small cap needs few (midpoints: second order).
  const int n = std::clamp(d >= kFarRadii * r ? std::min(b.samples, kFarSamples) : b.samples, 1, 64);
  const Vec3 a = a_vec * (1.0 / d);
  const Vec3 helper = std::abs(a.x) < 0.9 ? Vec3{1, 0, 0} : Vec3{0, 1, 0};
  const Vec3 e1 = normalized(cross(a, helper));
  const Vec3 e2 = cross(a, e1);
  const double dcos = (1 - cos_max) / n, dphi = 2 * kPi / n;
  // z components of the in-cone directions' azimuthal parts, per φ sample.
  double az[64];
  for (int j = 0; j < n; ++j) az[j] = e1.z * std::cos((j + 0.5) * dphi) + e2.z * std::sin((j + 0.5) * dphi);
  double sum = 0;
  for (int i = 0; i < n; ++i) {
    const double ct = 1 - (i + 0.5) * dcos, st = std::sqrt(std::max(0.0, 1 - ct * ct));
    // Distance from Y to the sphere along a direction θ off the axis.
    const double l = d * ct - std::sqrt(std::max(0.0, r * r - d * d * st * st));
    const double att = L * std::exp(-sigma * l);
    // u: from Y towards the bulb; light propagates along −u, so the
    // scattering angle towards −z has cos = (−u)·(−ẑ) = u.z.
    double ring = 0;
    for (int j = 0; j < n; ++j) ring += hg_phase(m.g, -a.z * ct + st * az[j]);
    sum += att * ring;
  }
  return sum * dcos * dphi;
}

// One table: ρ → profile, with its own grid.
struct RadialTable {
  double rho0 = 0, rho1 = 0;  // range
  bool quadratic = false;     // ρ = ρ0 + (ρ1 − ρ0)(k/K)²
  std::vector<double> scatter, source;
  double lookup(const std::vector<double>& t, double rho) const {
    const double k_max = static_cast<double>(t.size() - 1);
    double f = (rho - rho0) / (rho1 - rho0);
    f = std::clamp(f, 0.0, 1.0);
    const double k = (quadratic ? std::sqrt(f) : f) * k_max;
    const size_t k0 = std::min(static_cast<size_t>(k), t.size() - 2);
    const double w = k - static_cast<double>(k0);
    return t[k0] * (1 - w) + t[k0 + 1] * w;
  }
  double rho_at(size_t k) const {
    const double f = static_cast<double>(k) / static_cast<double>(scatter.size() - 1);
    return rho0 + (rho1 - rho0) * (quadratic ? f * f : f);
  }
};

}  // namespace

nlohmann::json TankGeometry::to_json() const {
  return {{"depth_mm", depth_mm},
          {"bulb_depth_mm", bulb_depth_mm},
          {"bulb_radius_mm", bulb_radius_mm},
          {"bulb_u_px", bulb_u_px},
          {"bulb_v_px", bulb_v_px},
          {"mm_per_px_x", mm_per_px_x},
          {"mm_per_px_y", mm_per_px_y},
          {"face_px", {face_u_min, face_v_min, face_u_max, face_v_max}},
          {"bulb_intensity_iu_mm2", bulb_intensity},
          {"bulb_radiance_ru", bulb_radiance},
          {"extinction_per_mm", sigma_t_per_mm},
          {"scattering_per_mm", sigma_s_per_mm},
          {"hg_g", g}};
}

Result<TankGeometry> tank_geometry(const Medium& m, const Rigid3& world_from_cam, const Intrinsics& camera) {
  if (m.whole_scene || !m.bulb)
    return Error(Code::invalid_argument, "tank rig: the medium needs a box (the tank) and a bulb",
                 "add medium.box_min_mm, box_max_mm and medium.bulb (hw/sim/SCENES.md)");
  const Vec3 axis = world_from_cam.rotation * Vec3{0, 0, 1};
  if (!(axis.z > std::cos(10.0 * kPi / 180.0)))
    return Error(Code::invalid_argument, "tank rig: the camera must look at the tank's front face along +z (within 10 deg)",
                 "use camera 0 of a rig facing the tank (configs/rigs/sim-tank.json)");
  const Vec3 c = world_from_cam.translation_mm;
  const double z0 = m.box_min_mm.z;
  if (!(c.z < z0))
    return Error(Code::invalid_argument, "tank rig: the camera must be in front of the tank (z < box_min_mm.z)");
  const Medium::Bulb& b = *m.bulb;
  TankGeometry g;
  g.depth_mm = m.box_max_mm.z - z0;
  g.bulb_depth_mm = b.center_mm.z - z0;
  g.bulb_radius_mm = b.radius_mm;
  g.bulb_intensity = b.intensity();
  g.bulb_radiance = b.radiance();
  g.sigma_t_per_mm = m.sigma_t_per_mm;
  g.sigma_s_per_mm = m.sigma_s_per_mm;
  g.g = m.g;
  // Image of a face point: project it with the camera (exact for any pose).
  const Rigid3 cam_from_world = world_from_cam.inverse();
  auto image_of = [&](double x, double y, double& u, double& v) {
    camera.project(cam_from_world * Vec3{x, y, z0}, u, v);
  };
  image_of(b.center_mm.x, b.center_mm.y, g.bulb_u_px, g.bulb_v_px);
  double u1 = 0, v1 = 0, u2 = 0, v2 = 0;
  image_of(b.center_mm.x + 1.0, b.center_mm.y, u1, v1);
  image_of(b.center_mm.x, b.center_mm.y + 1.0, u2, v2);
  g.mm_per_px_x = 1.0 / std::hypot(u1 - g.bulb_u_px, v1 - g.bulb_v_px);
  g.mm_per_px_y = 1.0 / std::hypot(u2 - g.bulb_u_px, v2 - g.bulb_v_px);
  image_of(m.box_min_mm.x, m.box_min_mm.y, g.face_u_min, g.face_v_min);
  image_of(m.box_max_mm.x, m.box_max_mm.y, g.face_u_max, g.face_v_max);
  return g;
}

TankProfile tank_profile(const Medium& m, double rho_mm, int z_steps) {
  TankProfile out;
  if (!m.bulb || z_steps < 1) return out;
  const Medium::Bulb& b = *m.bulb;
  const double r = b.radius_mm, zb = b.center_mm.z, z0 = m.box_min_mm.z, z1 = m.box_max_mm.z;
  double z_end = z1;
  if (rho_mm < r) {
    z_end = zb - std::sqrt(r * r - rho_mm * rho_mm);  // the line of sight stops on the bulb
    out.source = b.radiance() * std::exp(-m.sigma_t_per_mm * (z_end - z0));
  }
  if (!(m.sigma_s_per_mm > 0)) return out;
  // z = zb + h tan t: uniform steps in the angle t about the bulb (the phase
  // function's argument) resolve the forward peak; dz = h / cos²t dt.
  const double h = std::max(rho_mm, r);
  const double t0 = std::atan((z0 - zb) / h), t1 = std::atan((z_end - zb) / h);
  const double dt = (t1 - t0) / z_steps;
  // Points on the line of sight: (bulb.x + ρ, bulb.y, z); the profile is radial.
  double sum = 0;
  for (int k = 0; k < z_steps; ++k) {
    const double t = t0 + (k + 0.5) * dt;
    const double ct = std::cos(t);
    const double z = zb + h * std::tan(t);
    const Vec3 y{b.center_mm.x + rho_mm, b.center_mm.y, z};
    sum += bulb_in_scatter(m, b, y) * std::exp(-m.sigma_t_per_mm * (z - z0)) * h / (ct * ct) * dt;
  }
  out.scatter = m.sigma_s_per_mm * sum;  // Eq. 4.2: β × the integral
  return out;
}

Result<std::shared_ptr<const TankTaps>> prepare_tank(const Medium& m, const Rigid3& world_from_cam,
                                                     const PreparedView& v, int threads) {
  Result<TankGeometry> geo = tank_geometry(m, world_from_cam, v.camera.intrinsics);
  if (!geo.ok()) return geo.status();
  auto taps = std::make_shared<TankTaps>();
  taps->width = v.width;
  taps->height = v.height;
  taps->geometry = *geo;
  const Medium::Bulb& b = *m.bulb;
  const double r = b.radius_mm;
  const Vec3 c = world_from_cam.translation_mm;
  const double z0 = m.box_min_mm.z;
  const Intrinsics& K = v.camera.intrinsics;
  // ρ of a (sub-)pixel: where its ray meets the front face, inside the face or NaN.
  auto rho_of = [&](double u, double vv) {
    const Vec3 d = world_from_cam.rotation * K.ray(u, vv);
    const double t = (z0 - c.z) / d.z;
    const Vec3 p = c + d * t;
    if (p.x < m.box_min_mm.x || p.x > m.box_max_mm.x || p.y < m.box_min_mm.y || p.y > m.box_max_mm.y)
      return std::numeric_limits<double>::quiet_NaN();
    return std::hypot(p.x - b.center_mm.x, p.y - b.center_mm.y);
  };
  const double rho_max =
      std::hypot(std::max(b.center_mm.x - m.box_min_mm.x, m.box_max_mm.x - b.center_mm.x),
                 std::max(b.center_mm.y - m.box_min_mm.y, m.box_max_mm.y - b.center_mm.y)) + 1.0;
  RadialTable inner{0.0, r, false, std::vector<double>(kInnerEntries + 1), std::vector<double>(kInnerEntries + 1)};
  RadialTable outer{r, rho_max, true, std::vector<double>(kOuterEntries + 1), std::vector<double>(kOuterEntries + 1)};
  for (RadialTable* tab : {&inner, &outer}) {
    const uint32_t n = static_cast<uint32_t>(tab->scatter.size());
    detail::parallel_rows(n, threads, [&](uint32_t lo, uint32_t hi) {
      for (uint32_t k = lo; k < hi; ++k) {
        // The inner table's last entry sits just inside the rim.
        const double rho = tab == &inner ? std::min(tab->rho_at(k), r * (1 - 1e-9)) : tab->rho_at(k);
        const TankProfile p = tank_profile(m, rho, kZSteps);
        tab->scatter[k] = p.scatter;
        tab->source[k] = p.source;
      }
    });
  }
  auto profile_at = [&](double rho, double& s, double& src) {
    const RadialTable& t = rho < r ? inner : outer;
    s = t.lookup(t.scatter, rho);
    src = t.lookup(t.source, rho);
  };
  const size_t n = v.pixel_count();
  taps->scatter.assign(n, 0.f);
  taps->source.assign(n, 0.f);
  const double px_mm = std::max(geo->mm_per_px_x, geo->mm_per_px_y);
  detail::parallel_rows(v.height, threads, [&](uint32_t lo, uint32_t hi) {
    for (uint32_t row = lo; row < hi; ++row)
      for (uint32_t col = 0; col < v.width; ++col) {
        const size_t i = size_t{row} * v.width + col;
        const double rho = rho_of(col, row);
        if (!std::isfinite(rho)) continue;
        double s = 0, src = 0;
        if (std::abs(rho - r) < 2.0 * px_mm) {
          // Near the rim both parts jump: box-filter the pixel with 4×4 samples.
          for (int a = 0; a < 4; ++a)
            for (int bb = 0; bb < 4; ++bb) {
              const double rr = rho_of(col - 0.375 + 0.25 * a, row - 0.375 + 0.25 * bb);
              if (!std::isfinite(rr)) continue;
              double s1 = 0, src1 = 0;
              profile_at(rr, s1, src1);
              s += s1 / 16;
              src += src1 / 16;
            }
        } else {
          profile_at(rho, s, src);
        }
        taps->scatter[i] = static_cast<float>(s);
        taps->source[i] = static_cast<float>(src);
      }
  });
  return std::shared_ptr<const TankTaps>(std::move(taps));
}

double mean_emitted(const PreparedPattern& pattern) {
  const float* l0 = pattern.level(0);
  if (l0 == nullptr || pattern.width() == 0 || pattern.height() == 0) return 0;
  double sum = 0;
  for (uint32_t r = 0; r < pattern.height(); ++r) {
    const float* p = l0 + (size_t{r} + 1) * pattern.stride() + 1;
    float row = 0;  // float per row (≤ a few thousand terms), double across rows
    for (uint32_t c = 0; c < pattern.width(); ++c) row += p[c];
    sum += static_cast<double>(row);
  }
  return sum / (double(pattern.width()) * pattern.height());
}

void TankComponent::begin_frame(const FrameContext& frame, int threads) {
  (void)threads;
  level_ = mean_emitted(frame.pattern);
  if (std::isfinite(frame.analyser_deg)) level_ *= 0.5;  // unpolarized bulb light through an analyser
}

void TankComponent::apply(const FrameContext& frame, uint32_t row_begin, uint32_t row_end, float* radiance) const {
  const std::vector<float>& gain = part_ == Part::scatter ? taps_->scatter : taps_->source;
  const size_t b = size_t{row_begin} * frame.view.width, e = size_t{row_end} * frame.view.width;
  const float k = static_cast<float>(level_);
  for (size_t i = b; i < e; ++i) radiance[i] += k * gain[i];
}

}  // namespace procam::sim
