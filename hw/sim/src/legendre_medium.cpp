// SPDX-License-Identifier: MIT
#include "legendre_medium.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>

#include "medium.hpp"
#include "parallel.hpp"
#include "procam/hw/sim/global.hpp"
#include "procam/hw/sim/raycast.hpp"

namespace procam::sim {
namespace {

constexpr double kMinDistSq = 1.0;  // mm^2: no 1/d^2 blow-up at the projector centre

legendre::Box box_of(const LegendreMediumSpec& s) {
  legendre::Box b;
  b.lo = {s.box_min_mm.x, s.box_min_mm.y, s.box_min_mm.z};
  b.hi = {s.box_max_mm.x, s.box_max_mm.y, s.box_max_mm.z};
  return b;
}

Medium box_medium(const LegendreMediumSpec& s) {  // for medium_interval()
  Medium m;
  m.whole_scene = false;
  m.box_min_mm = s.box_min_mm;
  m.box_max_mm = s.box_max_mm;
  return m;
}

// Sum of peak * exp(-|x - c|^2 / radius^2) over the blobs (SCENES.md).
double blob_sum(const std::vector<LegendreMediumSpec::Blob>& blobs, double x, double y, double z) {
  double s = 0.0;
  for (const auto& b : blobs) {
    const double dx = x - b.center_mm.x, dy = y - b.center_mm.y, dz = z - b.center_mm.z;
    s += b.peak * std::exp(-(dx * dx + dy * dy + dz * dz) / (b.radius_mm * b.radius_mm));
  }
  return s;
}

LegendreMediumSpec spec_of(const Scene& scene) {
  if (!scene.legendre_medium)
    throw std::invalid_argument("LegendreMediumComponent: scene '" + scene.name + "' has no legendre_medium");
  return *scene.legendre_medium;
}

}  // namespace

LegendreMediumComponent::LegendreMediumComponent(const Scene& scene, const ProjectorModel& projector,
                                                 const Rigid3& world_from_cam, const Rigid3& world_from_proj,
                                                 int threads)
    : spec_(spec_of(scene)),
      intensity_(projector.irradiance_at_1m * 1e6),
      projector_k_(projector.intrinsics),
      world_from_cam_(world_from_cam),
      world_from_proj_(world_from_proj) {
  mueller_.g = spec_.g;
  mueller_.dop_model = spec_.dop_model;
  build_shadow_map(scene, threads);
  reset();
}

void LegendreMediumComponent::build_shadow_map(const Scene& scene, int threads) {
  // First-hit distance through each projector pixel centre (the same shadow
  // test as the homogeneous medium's backscatter, medium.cpp).
  const Intrinsics& kp = projector_k_;
  shadow_.assign(size_t{kp.width} * kp.height, std::numeric_limits<float>::infinity());
  if (scene.objects.empty()) return;
  const SceneTracer tracer(scene);
  const Vec3 pc = world_from_proj_.translation_mm;
  detail::parallel_rows(kp.height, threads, [&](uint32_t b, uint32_t e) {
    for (uint32_t r = b; r < e; ++r)
      for (uint32_t col = 0; col < kp.width; ++col) {
        const Vec3 d =
            world_from_proj_.rotation * normalized(kp.ray(static_cast<double>(col), static_cast<double>(r)));
        Hit h;
        if (tracer.first_hit(pc, d, 1e-9, h)) shadow_[size_t{r} * kp.width + col] = static_cast<float>(h.t);
      }
  });
}

void LegendreMediumComponent::reset() {
  const legendre::Box box = box_of(spec_);
  legendre::FluidParams p;
  p.viscosity = spec_.viscosity_mm2_s;
  p.dissipation = spec_.dissipation_per_s;
  const size_t n = static_cast<size_t>(spec_.n);
  fluid_ = std::make_unique<legendre::LegendreFluid>(3, n, box, p);
  const size_t nodes = 2 * n + 4;
  fluid_->density = legendre::project(
      [&](double x, double y, double z) { return spec_.density_uniform + blob_sum(spec_.blobs, x, y, z); },
      fluid_->density.n, box, nodes);
  // Swirl about z: psi = (1-x'^2)^2 (1-y'^2)^2 in unit coordinates,
  // u = (psi_y'/hy, -psi_x'/hx, 0): divergence-free, no flow through the walls.
  const double hx = box.half_width(0), hy = box.half_width(1);
  auto ux = [&](double xu, double yu) { return (1 - xu * xu) * (1 - xu * xu) * 2 * (1 - yu * yu) * (-2 * yu) / hy; };
  auto uy = [&](double xu, double yu) { return -(1 - yu * yu) * (1 - yu * yu) * 2 * (1 - xu * xu) * (-2 * xu) / hx; };
  double peak = 0.0;
  for (int i = 0; i <= 32; ++i)
    for (int j = 0; j <= 32; ++j) {
      const double xu = -1 + i / 16.0, yu = -1 + j / 16.0;
      peak = std::max(peak, std::hypot(ux(xu, yu), uy(xu, yu)));
    }
  const double s = peak > 0 ? spec_.swirl_mm_s / peak : 0.0;
  fluid_->velocity[0] = legendre::project(
      [&](double x, double y, double) { return s * ux(box.unit_from_box(0, x), box.unit_from_box(1, y)); },
      fluid_->velocity[0].n, box, nodes);
  fluid_->velocity[1] = legendre::project(
      [&](double x, double y, double) { return s * uy(box.unit_from_box(0, x), box.unit_from_box(1, y)); },
      fluid_->velocity[1].n, box, nodes);
  fluid_->passive.clear();
  if (spec_.has_albedo()) {  // omega = beta / sigma, advected with the density
    const double base = std::isfinite(spec_.albedo_uniform) ? spec_.albedo_uniform
                        : spec_.sigma_t_per_mm > 0       ? spec_.sigma_s_per_mm / spec_.sigma_t_per_mm
                                                         : 0.0;
    fluid_->passive.push_back(legendre::project(
        [&](double x, double y, double z) { return std::clamp(base + blob_sum(spec_.albedo_blobs, x, y, z), 0.0, 1.0); },
        fluid_->density.n, box, nodes));
  }
  fluid_->project();
  time_s_ = 0.0;
  grid_stale_ = true;
}

int LegendreMediumComponent::set_time_s(double t) {
  if (!(t >= 0.0) || !std::isfinite(t)) return 0;
  if (t < time_s_) reset();  // frames asked out of order: re-simulate (deterministic)
  if (t == time_s_) return 0;
  const legendre::StepReport r = fluid_->step(t - time_s_);
  time_s_ = t;
  grid_stale_ = true;
  return r.substeps;
}

void LegendreMediumComponent::begin_frame(const FrameContext& frame, int threads) {
  (void)threads;
  (void)frame;
  if (grid_stale_) {
    const std::vector<double> g = legendre::evaluate_grid(fluid_->density, {kGrid, kGrid, kGrid});
    grid_.resize(g.size());
    // Truncation ringing can dip a smooth density slightly below zero
    // between lobes; a negative density is unphysical, so it is clamped.
    for (size_t i = 0; i < g.size(); ++i) grid_[i] = static_cast<float>(std::max(0.0, g[i]));
    albedo_.clear();
    if (!fluid_->passive.empty()) {  // an albedo outside [0, 1] (ringing) is unphysical: clamped
      const std::vector<double> a = legendre::evaluate_grid(fluid_->passive[0], {kGrid, kGrid, kGrid});
      albedo_.resize(a.size());
      for (size_t i = 0; i < a.size(); ++i) albedo_[i] = static_cast<float>(std::clamp(a[i], 0.0, 1.0));
    }
    // The projector leg's optical depth at the lattice nodes (box corners
    // included, so no extrapolation at the faces): ~17^3 marches per frame.
    const size_t m = kGrid + 1;
    tau_proj_.resize(m * m * m);
    const Vec3 proj = world_from_proj_.translation_mm;
    const Vec3 lo = spec_.box_min_mm, ext = spec_.box_max_mm - spec_.box_min_mm;
    const double step = 1.0 / static_cast<double>(kGrid);
    for (size_t z = 0; z < m; ++z)
      for (size_t y = 0; y < m; ++y)
        for (size_t x = 0; x < m; ++x) {
          const Vec3 node{lo.x + ext.x * static_cast<double>(x) * step, lo.y + ext.y * static_cast<double>(y) * step,
                          lo.z + ext.z * static_cast<double>(z) * step};
          tau_proj_[(z * m + y) * m + x] = static_cast<float>(optical_depth(proj, node, kSteps));
        }
    grid_stale_ = false;
  }
}

double LegendreMediumComponent::proj_depth_at(const Vec3& q) const {
  const size_t m = kGrid + 1;
  size_t i0[3];
  double t[3];
  const double lo[3] = {spec_.box_min_mm.x, spec_.box_min_mm.y, spec_.box_min_mm.z};
  const double hi[3] = {spec_.box_max_mm.x, spec_.box_max_mm.y, spec_.box_max_mm.z};
  for (int a = 0; a < 3; ++a) {
    const double f = std::clamp((q[a] - lo[a]) / (hi[a] - lo[a]), 0.0, 1.0) * static_cast<double>(kGrid);
    i0[a] = std::min(static_cast<size_t>(f), kGrid - 1);
    t[a] = f - static_cast<double>(i0[a]);
  }
  auto at = [&](size_t dx, size_t dy, size_t dz) {
    return static_cast<double>(tau_proj_[((i0[2] + dz) * m + i0[1] + dy) * m + i0[0] + dx]);
  };
  const double c00 = at(0, 0, 0) * (1 - t[0]) + at(1, 0, 0) * t[0];
  const double c10 = at(0, 1, 0) * (1 - t[0]) + at(1, 1, 0) * t[0];
  const double c01 = at(0, 0, 1) * (1 - t[0]) + at(1, 0, 1) * t[0];
  const double c11 = at(0, 1, 1) * (1 - t[0]) + at(1, 1, 1) * t[0];
  return (c00 * (1 - t[1]) + c10 * t[1]) * (1 - t[2]) + (c01 * (1 - t[1]) + c11 * t[1]) * t[2];
}

double LegendreMediumComponent::grid_at(const std::vector<float>& grid, const Vec3& q) const {
  double f[3];
  size_t i0[3], i1[3];
  double t[3];
  const double lo[3] = {spec_.box_min_mm.x, spec_.box_min_mm.y, spec_.box_min_mm.z};
  const double hi[3] = {spec_.box_max_mm.x, spec_.box_max_mm.y, spec_.box_max_mm.z};
  for (int a = 0; a < 3; ++a) {
    const double u = (q[a] - lo[a]) / (hi[a] - lo[a]);
    if (u < 0.0 || u > 1.0) return 0.0;
    f[a] = std::clamp(u * static_cast<double>(kGrid) - 0.5, 0.0, static_cast<double>(kGrid - 1));
    const double fl = std::floor(f[a]);
    i0[a] = static_cast<size_t>(fl);
    i1[a] = std::min(i0[a] + 1, kGrid - 1);
    t[a] = f[a] - fl;
  }
  auto at = [&](size_t x, size_t y, size_t z) { return static_cast<double>(grid[(z * kGrid + y) * kGrid + x]); };
  const double c00 = at(i0[0], i0[1], i0[2]) * (1 - t[0]) + at(i1[0], i0[1], i0[2]) * t[0];
  const double c10 = at(i0[0], i1[1], i0[2]) * (1 - t[0]) + at(i1[0], i1[1], i0[2]) * t[0];
  const double c01 = at(i0[0], i0[1], i1[2]) * (1 - t[0]) + at(i1[0], i0[1], i1[2]) * t[0];
  const double c11 = at(i0[0], i1[1], i1[2]) * (1 - t[0]) + at(i1[0], i1[1], i1[2]) * t[0];
  return (c00 * (1 - t[1]) + c10 * t[1]) * (1 - t[2]) + (c01 * (1 - t[1]) + c11 * t[1]) * t[2];
}

int LegendreMediumComponent::march_steps(double length_mm) const {
  // About one sample per density-grid cell: finer sampling of a trilinear
  // grid adds cost, not accuracy.
  const double cell = std::min({spec_.box_max_mm.x - spec_.box_min_mm.x, spec_.box_max_mm.y - spec_.box_min_mm.y,
                                spec_.box_max_mm.z - spec_.box_min_mm.z}) / static_cast<double>(kGrid);
  return std::clamp(static_cast<int>(std::ceil(length_mm / cell)), 4, kSteps);
}

double LegendreMediumComponent::optical_depth(const Vec3& a, const Vec3& b, int steps) const {
  const Vec3 d = b - a;
  const double len = norm(d);
  if (!(len > 0.0)) return 0.0;
  const Vec3 u = d / len;
  double t0 = 0, t1 = 0;
  if (!medium_interval(box_medium(spec_), a, u, t0, t1)) return 0.0;
  t1 = std::min(t1, len);
  if (!(t1 > t0)) return 0.0;
  steps = std::min(steps, march_steps(t1 - t0));
  const double ds = (t1 - t0) / steps;
  double tau = 0.0;
  for (int k = 0; k < steps; ++k) tau += density_at(a + u * (t0 + (k + 0.5) * ds)) * ds;
  return tau;
}

void LegendreMediumComponent::apply(const FrameContext& frame, uint32_t row_begin, uint32_t row_end,
                                    float* radiance) const {
  const PreparedView& view = frame.view;
  const Intrinsics& k = view.camera.intrinsics;
  const Medium box = box_medium(spec_);
  const Vec3 cam = world_from_cam_.translation_mm, proj = world_from_proj_.translation_mm;
  const double sigma = spec_.sigma_t_per_mm, beta = spec_.sigma_s_per_mm;
  // Emitted light of the projector pixel that lights a point at distance
  // d_mm from the projector centre (sharp pattern, nearest pixel; 0 outside
  // the projector image, behind it, or in a surface's shadow).
  const Rigid3 proj_from_world = world_from_proj_.inverse();
  const Intrinsics& kp = projector_k_;
  const float* pattern = frame.pattern.level(0);
  const size_t pstride = frame.pattern.stride();
  auto emitted = [&](const Vec3& y, double d_mm) {
    const Vec3 q = proj_from_world * y;
    if (!(q.z > 1e-3) || pattern == nullptr) return 0.0;
    const double xp = kp.fx * q.x / q.z + kp.cx, yp = kp.fy * q.y / q.z + kp.cy;
    if (!(xp >= -0.5 && xp < kp.width - 0.5 && yp >= -0.5 && yp < kp.height - 0.5)) return 0.0;
    const size_t ix = std::min(static_cast<size_t>(xp + 0.5), size_t{kp.width} - 1);
    const size_t iy = std::min(static_cast<size_t>(yp + 0.5), size_t{kp.height} - 1);
    const double hit = static_cast<double>(shadow_[iy * kp.width + ix]);
    if (d_mm > hit * (1 + 1e-3) + 1.0) return 0.0;  // occluded (1 mm + 0.1 % slack, as medium.cpp)
    return static_cast<double>(pattern[(iy + 1) * pstride + ix + 1]);
  };
  // Polarization (Eq. 5.35-5.36): device axes as world directions.
  const bool pol_in = mueller_.dop_model != Medium::DopModel::none && std::isfinite(frame.projector_polarizer_deg);
  const bool analyser = std::isfinite(frame.analyser_deg);
  const double alpha = pol_in ? frame.projector_polarizer_deg * M_PI / 180.0 : 0.0;
  const double psi = analyser ? frame.analyser_deg * M_PI / 180.0 : 0.0;
  const Vec3 pol_axis = world_from_proj_.rotation * Vec3{std::cos(alpha), std::sin(alpha), 0.0};
  const Vec3 ana_axis = world_from_cam_.rotation * Vec3{std::cos(psi), std::sin(psi), 0.0};
  // cos 2chi, sin 2chi of an axis `a` in the frame (par, n) of a ray
  // (par, n perpendicular to it): the angle of a's projection onto the
  // plane perpendicular to the ray. An axis along the ray (no projection):
  // unpolarized (0, 0).
  auto double_angle = [](const Vec3& a, const Vec3& par, const Vec3& n, double& c2, double& s2) {
    const double c = dot(a, par), s = dot(a, n), q = c * c + s * s;
    if (!(q > 1e-12)) {
      c2 = s2 = 0.0;
      return;
    }
    c2 = (c * c - s * s) / q;
    s2 = 2 * c * s / q;
  };
  for (uint32_t v = row_begin; v < row_end; ++v)
    for (uint32_t u = 0; u < view.width; ++u) {
      const size_t i = size_t{v} * view.width + u;
      const Vec3 dir = world_from_cam_.rotation * normalized(k.ray(u, v));
      double t0 = 0, t1 = 0;
      if (!medium_interval(box, cam, dir, t0, t1)) continue;
      const float* pt = &view.point_mm[3 * i];
      const bool surface = std::isfinite(pt[0]);
      const Vec3 pc{static_cast<double>(pt[0]), static_cast<double>(pt[1]), static_cast<double>(pt[2])};
      if (surface) t1 = std::min(t1, norm(pc));
      if (!(t1 > t0)) continue;
      // The pixel's Stokes frame: scattering plane normal n = (Y - L) x o is
      // the same for every Y = C + t dir on the ray ((C - L) x o); a ray
      // through L (or a camera at L) has no plane: any n perpendicular to o.
      const Vec3 o = -dir;
      Vec3 n = cross(cam - proj, o);
      if (!(norm(n) > 1e-9 * (1.0 + norm(cam - proj))))
        n = cross(o, std::abs(o.x) < 0.9 ? Vec3{1, 0, 0} : Vec3{0, 1, 0});
      n = normalized(n);
      const Vec3 par_out = cross(n, o);
      // Eq. 6.5 marched: the air-light's Stokes sums (I, Q, U) and the
      // camera leg's optical depth.
      const int steps = march_steps(t1 - t0);
      const double ds = (t1 - t0) / steps;
      double tau = 0.0, si = 0.0, sq = 0.0, su = 0.0;
      for (int s = 0; s < steps; ++s) {
        const Vec3 y = cam + dir * (t0 + (s + 0.5) * ds);
        const double r = density_at(y);
        if (r <= 0.0) continue;
        const double tau_mid = tau + 0.5 * r * ds;
        tau += r * ds;
        const Vec3 ly = y - proj;
        const double d = norm(ly);
        if (!(d > 0.0)) continue;
        const double e = emitted(y, d);
        if (e == 0.0) continue;
        const Vec3 l = ly / d;
        const Mueller3 mm = scattering_mueller(mueller_, dot(l, o));
        double c2 = 0.0, s2 = 0.0;
        if (pol_in) double_angle(pol_axis, cross(n, l), n, c2, s2);
        const double b = albedo_.empty() ? beta : sigma * grid_at(albedo_, y);
        const double w = b * r * intensity_ * e / std::max(d * d, kMinDistSq) *
                         std::exp(-sigma * (tau_mid + proj_depth_at(y))) * ds;
        si += w * (mm.m[0][0] + mm.m[0][1] * c2);
        sq += w * (mm.m[1][0] + mm.m[1][1] * c2);
        su += w * mm.m[2][2] * s2;
      }
      double air = si;
      if (analyser) {
        double c2 = 0.0, s2 = 0.0;
        double_angle(ana_axis, par_out, n, c2, s2);
        air = 0.5 * (si + sq * c2 + su * s2);
      }
      // Eq. 6.4 on both legs of the surface light. The projector leg ends
      // at the surface point or, beyond the box, at the leg's exit from the
      // box (no medium after it): a point of the lattice's domain.
      double tau_proj = 0.0;
      if (surface) {
        const Vec3 ps = world_from_cam_ * pc, leg = ps - proj;
        const double len = norm(leg);
        double a0 = 0, a1 = 0;
        if (len > 0.0 && medium_interval(box, proj, leg / len, a0, a1) && a0 < len)
          tau_proj = proj_depth_at(proj + leg * (std::min(a1, len) / len));
      }
      radiance[i] = static_cast<float>(static_cast<double>(radiance[i]) * std::exp(-sigma * (tau + tau_proj)) + air);
    }
}

int set_legendre_time(Renderer& renderer, double t_s) {
  for (const auto& c : renderer.components())
    if (auto* m = dynamic_cast<LegendreMediumComponent*>(c.get())) return m->set_time_s(t_s);
  return -1;
}

}  // namespace procam::sim
