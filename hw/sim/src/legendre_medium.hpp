// SPDX-License-Identifier: MIT
// Internal: the scene's dynamic Legendre medium (Scene::legendre_medium,
// SCENES.md, docs/legendre.md) as a volume TransportComponent.
//
// The medium's density evolves in procam::legendre::LegendreFluid (thesis
// ch. 6 §6.4); set_time_s() advances it to a frame's time (re-simulating
// from t = 0 when asked for an earlier time, so every camera and every
// repeat of a frame sees the same medium). Per frame, for each camera pixel
// the density is marched along the camera ray inside the box:
//  - attenuation (Eq. 6.4 along both legs): the surface light already in the
//    radiance buffer is multiplied by exp(-sigma (tau_cam + tau_proj)), the
//    optical depths of the camera ray up to the surface and of the projector
//    ray to that surface point (ambient light gets the same factor);
//  - air-light (Eq. 6.5, single scattering): the Stokes vector
//      S = sum over the ray of beta r M(theta) S_in I e(x_p(Y)) / d_LY^2
//          exp(-sigma (tau_cam(Y) + tau_proj(Y))) ds,
//    e the sharp emitted pattern at the projector pixel that lights the
//    sample Y (nearest pixel, pinhole projector; 0 outside its image and
//    where the projector ray to Y is blocked by a surface: shadow map of the
//    scene's objects), tau_proj(Y) the projector leg's optical depth
//    (trilinear in a per-frame (kGrid+1)^3 lattice of marched depths), and
//    beta = sigma_s_per_mm, or omega(Y) sigma_t_per_mm with the advected
//    single-scattering albedo omega (LegendreFluid::passive[0]), and
//    M the homogeneous medium's Mueller matrix (scattering_mueller,
//    Eq. 5.35-5.36, LegendreMediumSpec::dop_model) acting on the Stokes
//    vector S_in = (1, cos2chi, sin2chi) of the projector polariser's light
//    ((1, 0, 0) without one). One Stokes frame per pixel: the scattering
//    plane holds the camera ray and the projector centre, so it is the same
//    for every Y on the ray. An analyser at phi passes
//    (I + Q cos2phi + U sin2phi)/2 (Malus); surface light stays depolarized
//    (the renderer's 1/2).
//    Device angle -> Stokes angle: the polariser's (analyser's) axis in its
//    own image plane, as a 3D direction, projected perpendicular to the ray
//    it acts on and measured from the scattering plane's in-plane axis
//    towards its normal (exact for every ray direction).
// Rendering marches a per-frame density grid (kGrid^3 samples of the
// Legendre field, trilinear), not the Legendre image equations of
// procam::legendre::LegendreRenderer, because the sim's camera is
// perspective and its rays are not box axes.
//
// This component multiplies the buffer it adds to (a volume component runs
// after the surface light has been summed and scaled, renderer.cpp): it is
// still linear in the pattern. It is not part of the ground truth images.
// Threads: set_time_s/begin_frame on the rendering thread; apply() reads
// only per-frame state and is safe on disjoint rows.
#pragma once

#include <memory>
#include <vector>

#include "procam/hw/sim/renderer.hpp"
#include "procam/hw/sim/scene.hpp"
#include "procam/legendre/fluid.hpp"

namespace procam::sim {

class LegendreMediumComponent final : public TransportComponent {
 public:
  // `scene` must hold a legendre_medium (std::invalid_argument otherwise);
  // its objects give the projector's shadow map, ray-cast here on `threads`
  // threads (once per renderer). Throws std::invalid_argument for a spec the
  // parser should have refused.
  LegendreMediumComponent(const Scene& scene, const ProjectorModel& projector, const Rigid3& world_from_cam,
                          const Rigid3& world_from_proj, int threads);

  std::string name() const override { return "legendre_medium"; }
  bool is_volume() const override { return true; }
  void begin_frame(const FrameContext& frame, int threads) override;
  void apply(const FrameContext& frame, uint32_t row_begin, uint32_t row_end, float* radiance) const override;

  // Advance (or rewind) the medium to time t >= 0 (s). Returns the number of
  // fluid sub-steps taken (CFL, fluid.hpp).
  int set_time_s(double t);
  double time_s() const { return time_s_; }
  const legendre::LegendreFluid& fluid() const { return *fluid_; }

  static constexpr size_t kGrid = 16;   // density samples per box axis per frame (n <= 8: degree <= 7)
  static constexpr int kSteps = 48;     // at most this many march samples along a ray in the box

 private:
  void reset();
  void build_shadow_map(const Scene& scene, int threads);
  double density_at(const Vec3& world_mm) const { return grid_at(grid_, world_mm); }
  // Trilinear in a kGrid^3 cell-centre grid of the frame; 0 outside the box.
  double grid_at(const std::vector<float>& grid, const Vec3& world_mm) const;
  double optical_depth(const Vec3& a, const Vec3& b, int steps) const;  // sigma-free int r ds
  double proj_depth_at(const Vec3& world_mm) const;  // tau_proj (sigma-free), trilinear in the lattice; box points
  int march_steps(double length_mm) const;  // ~one sample per grid cell, 4..kSteps

  LegendreMediumSpec spec_;
  Medium mueller_;    // g and dop_model of spec_, for scattering_mueller()
  double intensity_;  // projector iu*mm^2 per unit emitted
  Intrinsics projector_k_;
  Rigid3 world_from_cam_, world_from_proj_;
  std::unique_ptr<legendre::LegendreFluid> fluid_;
  double time_s_ = 0.0;
  bool grid_stale_ = true;
  std::vector<float> grid_;      // kGrid^3 density samples (cell centres)
  std::vector<float> albedo_;    // kGrid^3 samples of the advected albedo in [0, 1] (spec_.has_albedo())
  std::vector<float> tau_proj_;  // (kGrid+1)^3 lattice nodes (box corners included): projector -> node
  std::vector<float> shadow_;    // per projector pixel: first-hit distance from its centre (mm; inf: none)
};

}  // namespace procam::sim
