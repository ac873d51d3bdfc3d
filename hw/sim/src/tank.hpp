// SPDX-License-Identifier: MIT
// Internal: the dilution tank rig (thesis §4.2.1-4.2.2, §4.3.3; docs/media.md
// "Tank rig"). A homogeneous medium in an axis-aligned tank (Scene::medium
// with box and bulb), a spherical diffuse bulb inside it, black walls, and a
// camera looking at the front face z = box_min.z along +z from far away.
//
// Model (orthographic inside the tank, as the thesis assumes for its camera
// 5 m away): camera pixel (u, v) sees the point P where its ray meets the
// front face; inside the tank its line of sight runs from P straight along +z
// to the back wall (or to the bulb, if it hits it). Along it, Eq. 4.1-4.2 with
// the area bulb of §4.3.3:
//
//   E(u, v) = ∫ β e^{−σ (z − z_front)} ∫_cap L e^{−σ l(ω)} p_HG(g, ω·ẑ) dω dz
//
// over the cone of directions ω from Y to the bulb (the bulb's visible cap),
// sampled samples × samples (midpoints in cos θ and φ about the axis to the
// bulb's centre), l(ω) the distance to the bulb's surface, L = I0/(π r²) the
// bulb's radiance (ru per unit emitted light). Far from the bulb
// (|Y − c| ≥ 16 r) one direction, to the centre, with the cap's exact solid
// angle 2π(1 − √(1 − r²/d²)) ≈ π r²/d² and the cone's mean path d − 2r/3
// (so I0/d² · e^{−σ(d − 2r/3)}: Eq. 4.1).
// Pixels whose line of sight hits the bulb also see its surface:
// L · e^{−σ (z_hit − z_front)} (Eq. 4.3's regime), and no light from behind it.
//
// Both parts depend only on ρ, the distance of P from the bulb's centre
// projected on the face, so they are tabulated over ρ once and looked up per
// pixel (pixels within 2 px of the bulb's rim: 4×4 sub-samples).
//
// Threads: TankTaps is immutable plain data once built; the components are
// TransportComponents (apply() safe on disjoint rows).
#pragma once

#include <memory>
#include <vector>

#include <nlohmann/json.hpp>

#include "procam/base/calibration.hpp"
#include "procam/base/geometry.hpp"
#include "procam/hw/sim/renderer.hpp"
#include "procam/hw/sim/scene.hpp"

namespace procam::sim {

// What a `medium` plugin needs to model the frames (docs/media.md "Tank rig"),
// in the thesis's frame: x, y across the front face, z the depth from it.
struct TankGeometry {
  double depth_mm = 0;         // 2B: front face to back wall
  double bulb_depth_mm = 0;    // B: front face to the bulb's centre
  double bulb_radius_mm = 0;
  double bulb_u_px = 0, bulb_v_px = 0;  // image of the bulb's centre (orthographic: its footprint on the face)
  double mm_per_px_x = 0, mm_per_px_y = 0;  // at the front face; x_mm = (u − bulb_u_px)·mm_per_px_x
  double face_u_min = 0, face_u_max = 0, face_v_min = 0, face_v_max = 0;  // front face in pixels
  double bulb_intensity = 0;  // I0, iu·mm² per unit emitted light
  double bulb_radiance = 0;   // L = I0/(π r²), ru per unit emitted light
  double sigma_t_per_mm = 0, sigma_s_per_mm = 0, g = 0;  // the medium (truth)
  nlohmann::json to_json() const;
};

// Per-pixel gains of the tank rig (ru per unit mean emitted light) and the
// radial tables they came from.
struct TankTaps {
  uint32_t width = 0, height = 0;
  std::vector<float> scatter;  // single-scattered bulb light (Eq. 4.1-4.2, area bulb)
  std::vector<float> source;   // the directly seen, attenuated bulb (0 off the bulb)
  TankGeometry geometry;
};

// Tank geometry for a camera at `world_from_cam` with `camera` intrinsics.
// invalid_argument without a medium box and bulb, or if the camera does not
// look at the front face (its axis must point along +z within 10°).
Result<TankGeometry> tank_geometry(const Medium& medium, const Rigid3& world_from_cam, const Intrinsics& camera);

// Single-scattered bulb light (ru per unit emitted light) on the line of
// sight at distance rho_mm from the bulb's axis (the tabulated integrand
// above, evaluated directly with `z_steps` midpoints in the angle about the
// bulb), and the directly seen bulb there. Used to build the tables.
struct TankProfile {
  double scatter = 0;
  double source = 0;
};
TankProfile tank_profile(const Medium& medium, double rho_mm, int z_steps);

// Builds the taps for prepared view `v` (camera 0 or any camera whose axis
// looks along +z). Errors as tank_geometry().
Result<std::shared_ptr<const TankTaps>> prepare_tank(const Medium& medium, const Rigid3& world_from_cam,
                                                     const PreparedView& v, int threads);

// The bulb's light as transport components. The bulb emits in proportion to
// the frame's mean emitted light (white frame: full, black: off); it is
// unpolarized, so an analyser passes half. Both are volume components
// (attenuation is already in the gains).
class TankComponent final : public TransportComponent {
public:
  enum class Part { scatter, source };
  TankComponent(std::shared_ptr<const TankTaps> taps, Part part) : taps_(std::move(taps)), part_(part) {}
  std::string name() const override { return part_ == Part::scatter ? "tank-bulb-scatter" : "tank-bulb-source"; }
  bool is_volume() const override { return true; }
  void begin_frame(const FrameContext& frame, int threads) override;
  void apply(const FrameContext& frame, uint32_t row_begin, uint32_t row_end, float* radiance) const override;

private:
  std::shared_ptr<const TankTaps> taps_;
  Part part_;
  double level_ = 0;  // this frame's bulb level (begin_frame)
};

// Mean emitted light of a pattern's sharp level (the bulb's level for it).
double mean_emitted(const PreparedPattern& pattern);

// ---- Monte Carlo reference with multiple scattering (tank_mc.cpp) ----------

// Light scattered towards the camera on the line of sight through face point
// (x_mm, y_mm) (world frame) in ru per unit emitted light, by backward path
// tracing: free flights with pdf σe^{−σs} from the face along +z, ending at
// the walls (black) or the bulb; at each vertex the weight takes the albedo
// β/σ, the bulb is connected by one direction drawn uniformly in its visible
// cone (L e^{−σl} p Ω, as the renderer's cap samples), and the next direction
// is drawn from the H-G phase function. `single` is the first vertex's
// connection alone — an unbiased estimate of the renderer's `scatter`;
// `total` adds every order up to `max_vertices`. *_se: standard errors of the
// means (1/sqrt(paths)). The seen bulb (`source`) is not included.
// Deterministic for a seed; reentrant; slow (tests and tools).
struct TankMonteCarlo {
  double single = 0, single_se = 0;
  double total = 0, total_se = 0;
  double excess_se = 0;  // standard error of total − single (same paths)
};
TankMonteCarlo tank_monte_carlo(const Medium& medium, double x_mm, double y_mm, size_t paths, uint64_t seed,
                                int max_vertices);

// Variance reduction for the same estimator (docs/media.md "Monte Carlo
// reference"); every option keeps it unbiased:
//  - connections: each vertex's bulb connection is split over k x k
//    directions stratified in (cos θ, φ) over the bulb's cone (one jittered
//    sample per stratum, mean of the k² estimates). Near the bulb the cone is
//    wide and the forward lobe of H-G varies across it: one uniform direction
//    gives the heavy tail of the original estimator.
//  - forced: every flight is forced to collide before it leaves the tank
//    (distance drawn from the exponential truncated at the exit, weight ×
//    (1 − e^{−σ s_exit}), the probability of colliding at all); paths then end
//    only by Russian roulette. In a dilute tank (σ·D ≲ 1) most unforced paths
//    leave without a vertex and contribute 0.
//  - exact_single: a control variate. The first vertex's connection is an
//    unbiased estimate of the renderer's single scattering S (tank_profile,
//    Eq. 4.1-4.2, deterministic); total is returned as S + (T̂ − Ŝ) from the
//    same paths and single as S, so total_se = excess_se: only the multiply
//    scattered part is noisy. Where single scattering dominates (the fit
//    volume of Fig. 4.11) that removes most of the variance. (Bias: the
//    renderer's far-field cap path d − 2r/3, < 0.5 % of S: tank_mc_test.)
//  - common_random_numbers: path k draws from its own generator, seeded from
//    (seed, k), instead of one stream for all paths. Two runs with the same
//    seed on two media (say a fitted one and the truth) then use the same
//    random numbers path for path, however long each path is in either
//    medium, so their difference is far less noisy than either (tank_mc_test).
//    Different numbers from the shared stream, the same distribution.
//  - sampling_*: trace the paths as in a reference medium (its extinction for
//    the free flights, its H-G g for the new directions) and weight them to
//    `medium` (importance sampling: × β e^{−σs} / pdf_ref(s) per flight,
//    × p(g, ·) / p(g_ref, ·) per turn; unbiased for any reference with
//    σ_ref > 0 and |g_ref| < 1, low-variance only near `medium`). With common
//    random numbers and the same reference, renders of two nearby media
//    follow the very same paths and differ only in their weights: without
//    it a 1 % change of σ or a 0.002 change of g moves the paths' late
//    vertices across H-G's narrow forward lobe (g 0.93) towards the bulb,
//    and the difference of two renders at 50-150 ml of chocolate milk is as
//    noisy as either (medium_mc_claims_test, Fig. 4.11). A reference g
//    outside (−1, 1) gives the zero result, as other bad input does.
// tank_monte_carlo(…) above is {connections = 1, forced = false, exact_single = false}.
struct TankMcOptions {
  int connections = 1;  // k: k x k stratified bulb directions per vertex
  bool forced = false;
  bool exact_single = false;
  bool common_random_numbers = false;
  double sampling_sigma_t_per_mm = 0;  // the reference's σ; 0: sample `medium` itself
  double sampling_g = 0;               // the reference's g, in (−1, 1); used when σ above > 0
};
TankMonteCarlo tank_monte_carlo(const Medium& medium, double x_mm, double y_mm, size_t paths, uint64_t seed,
                                int max_vertices, const TankMcOptions& options);

// The image of the tank's face by tank_monte_carlo() on an nx × ny grid of
// face points (cell centres), leaving out points within r + 2 mm of the
// bulb's axis (the seen bulb), compared with single scattering (thesis
// §4.2.3, Fig. 4.5) two ways:
//  - relative_excess = Σ(total − single)/Σ total: the share of the image's
//    energy that single scattering misses (with its standard error);
//  - relative_rms = √Σ(total − single)² / √Σ total²: the RMS difference
//    relative to the image's RMS, which weights the bright pixels near the
//    bulb as a least-squares fit does (Monte Carlo variance subtracted from
//    the squares; noisier: compare two seeds).
struct TankEnergy {
  double single = 0, total = 0;  // mean over the grid points, ru
  double relative_excess = 0, relative_excess_se = 0;
  double relative_rms = 0;
};
TankEnergy tank_energy_monte_carlo(const Medium& medium, int nx, int ny, size_t paths_per_point, uint64_t seed,
                                   int threads);

}  // namespace procam::sim
