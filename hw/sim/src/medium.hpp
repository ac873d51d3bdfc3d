// SPDX-License-Identifier: MIT
// Internal: a homogeneous participating medium in the sim (thesis ch. 5,
// Eq. 5.11-5.13; ch. 4, Eq. 4.1-4.2; appendix Eq. 5.35-5.36). Model and limits:
// docs/media.md.
//
//  - Attenuation (Eq. 5.11): surface light is multiplied by exp(−σ ℓ) on both
//    legs, ℓ the path length inside the medium (prepare_medium()).
//  - Backscatter B (Eq. 5.13 / 4.2), single scattering along the camera ray up
//    to the first surface (or the tank's far wall):
//      B = ∫ β p_HG(θ) · I·e(x_p(Y)) / d_LY² · exp(−σ(ℓ_L(Y) + ℓ_C(Y))) dY
//    I the projector intensity (irradiance_at_1m · 10⁶ iu·mm², the same as the
//    direct component's), e the SHARP emitted pattern (blur level 0, box
//    pixels; projector defocus is not applied to B), Y skipped where the
//    projector ray to it is occluded or outside the projector image.
//  - Indirect signal A (Eq. 5.12), approximated: forward single scattering
//    on both legs (light in, and surface light out to the camera), so A is
//    reciprocal: forward_scatter() and MediumIndirectComponent
//    (medium_indirect.cpp).
//  - Polarization: per-pixel Stokes-weighted sums and the Mueller matrix of
//    Medium::DopModel; surface light is depolarized (renderer.cpp).
//
// Threads: MediumTaps is immutable plain data once built; MediumComponent is
// a TransportComponent (thread-bound, apply() safe on disjoint rows).
#pragma once

#include <cstdint>
#include <memory>
#include <random>
#include <vector>

#include "procam/base/geometry.hpp"
#include "procam/core/status.hpp"
#include "procam/hw/sim/models.hpp"
#include "procam/hw/sim/renderer.hpp"
#include "procam/hw/sim/scene.hpp"

namespace procam::sim {

// Henyey-Greenstein phase function, 1/sr (∫ over the sphere = 1):
// p(θ) = (1 − g²) / (4π (1 + g² − 2g cosθ)^{3/2}), θ between the incident
// and the scattered propagation directions (θ = π: straight back).
double hg_phase(double g, double cos_theta);

// Mueller matrix on (I, Q, U) of linearly polarized light (Eq. 5.35 extended
// by U), in the scattering plane's frame: Q = I_par − I_perp, U at 45°, the
// angle counted from the in-plane axis (n × k) towards the plane's normal n.
// Normalised so m[0][0] = p_HG(θ); the off-diagonal ratios follow the model.
struct Mueller3 {
  double m[3][3] = {};
};
Mueller3 scattering_mueller(const Medium& medium, double cos_theta);

// Eq. 5.36: DOP of the scattered light for incident light of DOP `dop_in`
// polarized along the scattering plane's Q axis: (m21 + m22·dop)/(m11 + m12·dop).
// NaN where no light is scattered (e.g. Rayleigh at θ = 90° for dop = 1).
double scattered_dop(const Mueller3& m, double dop_in);

// Ray / medium: [t0, t1] of origin + t·dir (t >= 0) inside the medium; false
// if the ray misses it. Whole-scene media give [0, +inf).
bool medium_interval(const Medium& medium, const Vec3& origin, const Vec3& dir, double& t0, double& t1);
// Length (mm) of the segment a → b inside the medium.
double medium_length(const Medium& medium, const Vec3& a, const Vec3& b);

// One piece of a camera ray's backscatter integral: its Y lie in projector
// row `row` over columns [x_lo, x_hi] (continuous, pixel centres at integers).
// Its share of B for emitted light e(x) along that row is
//   ∫ (a + b·(x − x_c)) e(x) dx,   x_c = (x_lo + x_hi)/2,
// the linear weight whose zeroth and first moments equal those of the true
// weight G(x) = g(s(x))·|ds/dx| (moment matching). 20 bytes: a frame streams
// every chunk once, so their size sets the frame time.
struct MediumChunk {
  int32_t row;
  float x_lo, x_hi;
  float a, b;
};

// Backscatter taps of one prepared view.
struct MediumTaps {
  uint32_t width = 0, height = 0;            // camera pixels
  uint32_t proj_width = 0, proj_height = 0;  // projector pixels
  bool polarizing = false;                   // DopModel::rayleigh
  double m22 = 0;                            // normalised m22 (1 rayleigh, 0 none)
  std::vector<uint32_t> offset;              // pixel i's chunks: [offset[i], offset[i + 1])
  std::vector<MediumChunk> chunks;
  // Per pixel: incident Stokes angle χ = δ_L ± α of the projector polariser α
  // as cos2χ = pc[0]·cos2α + pc[1]·sin2α, sin2χ = pc[2]·cos2α + pc[3]·sin2α;
  // the same for the analyser (ac) in the scattered light's frame.
  std::vector<float> pol_proj;  // 4 per pixel
  std::vector<float> pol_cam;   // 4 per pixel
  // Per pixel: the normalised Mueller entries m12/m11 and m33/m11 averaged
  // over the ray with the flood-lit backscatter as weight. The scattering
  // angle changes little along a ray (e.g. 150°–170° in the chart scenes), so
  // one value per pixel stands in for the whole ray: exact for flood light,
  // and otherwise off by at most the spread of m12, m33 along the ray.
  std::vector<float> m12, m33;
  // Indirect signal A (medium_indirect.cpp, forward scattering on both legs):
  // per pixel the in-leg gain direct_albedo/π · R(ℓ_L) (R = F_A/exp(−σℓ),
  // forward_scatter()), direct_albedo/π alone (indirect_reflect: surface
  // radiance per irradiance), the camera leg's R(ℓ_C), and the normalisers
  // Ê/(G ∗ Ê) of the two normalised blurs (indirect_norm: in-leg,
  // indirect_cam_norm: out-leg); each blur's σ in camera pixels (one per view
  // and leg). Empty: no A.
  std::vector<float> indirect_gain, indirect_reflect, indirect_cam_ratio, indirect_norm, indirect_cam_norm;
  double indirect_sigma_px = 0, indirect_cam_sigma_px = 0;
  // Multiple scattering (Medium::MultipleScattering::diffuse; medium_multiple.cpp,
  // docs/media.md "Multiple scattering"): B_ms(i) = ms_gain[i] · (G ∗ S)(i),
  // S the frame's single-scattered intensity per pixel (the chunk sums, no
  // polariser terms), G a Gaussian of ms_sigma_px camera pixels.
  // ms_ratio ± ms_ratio_se: the Monte Carlo's multiple/single ratio under
  // flood light at the sample pixels (ms_gain is ms_ratio where the pixel's
  // ray crosses the medium, else 0). Empty ms_gain: single scattering only.
  // ms_keep: the share of B_ms from Monte Carlo paths that only turned by
  // small angles before scattering back (BackscatterOrders::multiple_small_turns):
  // it keeps the pixel's single-scattering polarization; the rest is depolarized.
  std::vector<float> ms_gain;
  double ms_sigma_px = 0;
  double ms_ratio = 0, ms_ratio_se = 0, ms_keep = 0;
  size_t pixel_count() const { return size_t{width} * height; }
};

// Medium pass of prepare_view(): camera/projector-leg transmittances and the
// backscatter taps (when β > 0). invalid_argument if the scene has no medium.
Status prepare_medium(const Scene& scene, const ProjectorModel& projector, const Rigid3& world_from_cam,
                      const Rigid3& world_from_proj, PreparedView& view, int threads);

// Forward single scattering onto a surface behind ℓ mm of medium, in the
// plane-parallel (slab) approximation of Eq. 5.12: a collimated beam crosses
// the slab; light scattered at depth t by angle α (cos α = μ > 0) reaches the
// surface after (ℓ − t)/μ more. `ratio` = F_A/exp(−σℓ), the forward-scattered
// flux per unit unscattered flux,
//   F_A = ∫₀^ℓ β e^{−σt} ∫₀¹ 2π p(μ) e^{−σ(ℓ−t)/μ} dμ dt,
// and `sigma_lat_mm` the per-axis RMS of its landing offset (ℓ − t)·tan α.
struct ForwardScatter {
  double ratio = 0;
  double sigma_lat_mm = 0;
};
ForwardScatter forward_scatter(const Medium& medium, double length_mm);

// Fills taps.indirect_* for a prepared view (medium_indirect.cpp); the
// projector (or light) gives the flood irradiance without cast shadows.
void prepare_indirect(const Medium& medium, const ProjectorModel& projector, const Rigid3& world_from_proj,
                      const PreparedView& view, MediumTaps& taps, int threads);

// Fills taps.ms_* for a prepared view whose medium asks for multiple
// scattering (medium_multiple.cpp): the ratio from backscatter_monte_carlo_orders
// under flood light at up to 9 pixels (a 3×3 grid), the kernel from the
// forward-scatter spread of forward_scatter(). Deterministic (fixed seeds).
void prepare_multiple(const Scene& scene, const ProjectorModel& projector, const Rigid3& world_from_cam,
                      const Rigid3& world_from_proj, const PreparedView& view, MediumTaps& taps, int threads);

// Reference B for one camera pixel by brute force: midpoint rule with `steps`
// samples along the ray, each sampling the sharp emitted pattern at its own
// projector pixel, shadow-tested one by one. Independent of the taps (tests).
// `emitted` is projector-sized, row-major, linear emitted light.
double backscatter_reference(const Scene& scene, const ProjectorModel& projector, const Rigid3& world_from_cam,
                             const Rigid3& world_from_proj, const Intrinsics& camera, double col, double row,
                             const std::vector<float>& emitted, size_t steps);

// Slow Monte Carlo reference for B with multiple scattering (medium_mc.cpp):
// `paths` backward paths from the camera pixel centre, up to `max_vertices`
// scattering events each (1: single scattering only), each vertex connected
// to the projector. Unbiased for the sharp pattern `emitted`; the standard
// error falls as 1/sqrt(paths). Tests only.
double backscatter_monte_carlo(const Scene& scene, const ProjectorModel& projector, const Rigid3& world_from_cam,
                               const Rigid3& world_from_proj, const Intrinsics& camera, double col, double row,
                               const std::vector<float>& emitted, size_t paths, uint64_t seed, int max_vertices);

// The same paths split by order: `single` the first vertex's estimate
// (unbiased for Eq. 5.13), `multiple` the sum over vertices 2..max_vertices,
// each with its standard error over the paths. Scalar: no polarization.
// multiple_small_turns: the part of `multiple` from paths whose sampled
// deflections before the connecting vertex were all below 30° (light that
// was scattered forward only, then once back towards the camera: the paths
// that keep most of single scattering's polarization; docs/media.md).
struct BackscatterOrders {
  double single = 0, multiple = 0, multiple_small_turns = 0;
  double se_single = 0, se_multiple = 0;
};
BackscatterOrders backscatter_monte_carlo_orders(const Scene& scene, const ProjectorModel& projector,
                                                const Rigid3& world_from_cam, const Rigid3& world_from_proj,
                                                const Intrinsics& camera, double col, double row,
                                                const std::vector<float>& emitted, size_t paths, uint64_t seed,
                                                int max_vertices);

// The Stokes vector (I, Q, U) of B at each camera pixel for emitted light
// from `pattern` level 0, polariser `projector_deg` (NaN: unpolarized), in the
// pixel's scattering-plane frame; I in ru. DOP = sqrt(Q² + U²)/I.
// i includes the depolarized multiple-scattered part, also given alone in
// i_multiple (zeros without multiple scattering).
struct BackscatterStokes {
  std::vector<float> i, q, u;
  std::vector<float> i_multiple;
};
BackscatterStokes backscatter_stokes(const MediumTaps& taps, const PreparedPattern& pattern, double projector_deg,
                                     int threads);

namespace detail {
// Direction whose cosine to the unit vector w is drawn from HG(g), uniform
// azimuth (the phase function's exact importance sample; medium_mc.cpp).
Vec3 sample_hg(const Vec3& w, double g, std::mt19937_64& rng);

// Row prefix sums of the emitted light for the chunk integrals (per frame).
struct RowPrefix {
  uint32_t width = 0, height = 0;
  std::vector<double> c;  // (width + 1) per row: Σ_{k<j} e_k
  std::vector<double> m;  // (width + 1) per row: Σ_{k<j} k·e_k
  const float* level0 = nullptr;  // padded sharp level (PreparedPattern::level(0))
  size_t stride = 0;
  void build(const PreparedPattern& pattern, int threads);
  // Σ over pixel i's chunks of their share of B (ru) for this pattern.
  double sum(const MediumTaps& taps, size_t i) const;
};

// The multiple-scattered intensity of every pixel (ru, taps.ms_*) for the
// pattern of `prefix`, into ms (taps-sized); `single` receives the chunk sums
// S; `tmp` is scratch. Zeros when taps.ms_gain is empty.
void multiple_scattering(const MediumTaps& taps, const RowPrefix& prefix, std::vector<float>& single,
                         std::vector<float>& ms, std::vector<float>& tmp, int threads);

// In place: a Gaussian blur of σ = sigma_px of a W×H image, three box passes
// per axis, clamped at the borders (medium_indirect.cpp). `tmp` is scratch.
void gaussian_blur3(std::vector<float>& data, std::vector<float>& tmp, uint32_t W, uint32_t H, double sigma_px,
                    int threads);
}  // namespace detail

// The indirect signal A (Eq. 5.12), approximated on both legs
// (medium_indirect.cpp): the surface irradiance blurred by the in-leg
// forward-scatter spread (a normalised Gaussian of taps.indirect_sigma_px
// camera pixels, three box passes) times the in-leg gain, plus the surface
// radiance (direct and in-leg A) blurred by the camera leg's spread times
// R(ℓ_C). Surface light: attenuated on the camera leg and depolarized like D.
class MediumIndirectComponent final : public TransportComponent {
public:
  explicit MediumIndirectComponent(std::shared_ptr<const MediumTaps> taps) : taps_(std::move(taps)) {}
  std::string name() const override { return "medium-indirect"; }
  bool needs_irradiance() const override { return true; }
  void begin_frame(const FrameContext& frame, int threads) override;
  void apply(const FrameContext& frame, uint32_t row_begin, uint32_t row_end, float* radiance) const override;

private:
  std::shared_ptr<const MediumTaps> taps_;
  // This frame's blurred irradiance and blurred surface radiance (begin_frame).
  std::vector<float> blurred_, blurred_cam_, tmp_;
};

// The backscatter B as a volume transport component.
class MediumComponent final : public TransportComponent {
public:
  explicit MediumComponent(std::shared_ptr<const MediumTaps> taps) : taps_(std::move(taps)) {}
  std::string name() const override { return "medium-backscatter"; }
  bool is_volume() const override { return true; }
  void begin_frame(const FrameContext& frame, int threads) override;
  void apply(const FrameContext& frame, uint32_t row_begin, uint32_t row_end, float* radiance) const override;

private:
  std::shared_ptr<const MediumTaps> taps_;
  detail::RowPrefix prefix_;  // this frame's row prefix sums (begin_frame)
  // With multiple scattering: this frame's chunk sums and B_ms (begin_frame).
  std::vector<float> single_, ms_, tmp_;
};

}  // namespace procam::sim
