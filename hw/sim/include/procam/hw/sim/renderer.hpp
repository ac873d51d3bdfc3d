// SPDX-License-Identifier: MIT
// Pattern renderer of the simulated rig, linear in the projected light:
//   radiance = T · emitted(pattern) + ambient
// where T is a sum of light-transport components (TransportComponent): the
// direct component here, the global ones (inter-reflection, glossy, sub-surface,
// thin sheets) in global.hpp, added without changing callers.
//
// Pipeline: prepare_view() once per scene + rig + camera (ray casting,
// shadows, Lambertian gains) → PreparedView; per focus setting
// compute_defocus() (cheap, per pixel); per pattern a PreparedPattern (emitted
// light + stack of blurred copies); Renderer::render_radiance() per frame.
// The camera sensor (sensor.hpp) turns radiance into a frame.
//
// Defocus (thesis §2.2): thin lens, blur-circle diameter
// b = aperture·fx_p·|1/focus − 1/z_p| projector pixels, modelled as a Gaussian
// of σ = b/4. The pattern is blurred at fixed σ levels (kBlurLevelSigmaPx) and
// each camera pixel blends the two levels around its σ with weights that match
// the variance σ² (w = (σ² − σ_k²)/(σ_{k+1}² − σ_k²)).
// Level 0 is the sharp projector image of box pixels: a camera pixel whose
// projector coordinate falls inside projector pixel i sees pattern[i] fully.
// Level k > 0 is the box image convolved with a Gaussian (kernel = Gaussian
// integrated over each pixel box), sampled bilinearly.
//
// Coordinates: pixel centres at integers; lengths in mm; radiance in ru
// (models.hpp). Threads: PreparedView/DefocusMap are plain data. A Renderer is
// thread-bound (docs/threading.md) (one frame at a time); it may use `threads` worker threads
// internally. Errors are returned, never thrown.
#pragma once

#include <array>
#include <cmath>
#include <cstdint>
#include <functional>
#include <limits>
#include <memory>
#include <string>
#include <vector>

#include "procam/base/calibration.hpp"
#include "procam/core/image.hpp"
#include "procam/core/status.hpp"
#include "procam/hw/sim/models.hpp"
#include "procam/hw/sim/scene.hpp"
#include "procam/pixel.h"

namespace procam::sim {

struct MediumTaps;  // medium.hpp: per-pixel backscatter taps of a participating medium
struct TankTaps;    // tank.hpp: per-pixel bulb light of the dilution tank rig

// σ of the blur-stack levels in projector pixels; level 0 is the sharp image.
// σ above the last level is clamped to it.
inline constexpr std::array<float, 7> kBlurLevelSigmaPx = {0.f, 0.5f, 1.f, 2.f, 4.f, 8.f, 16.f};

// What one camera sees of the scene and how the projector reaches it; one
// entry per camera pixel, row-major (index = v * width + u).
struct PreparedView {
  uint32_t width = 0, height = 0;            // camera pixels
  uint32_t proj_width = 0, proj_height = 0;  // projector pixels
  CameraCalibration camera;                  // intrinsics + cam_from_proj used
  Intrinsics projector;

  std::vector<float> depth_mm;    // camera-frame z of the first surface; NaN if none
  std::vector<float> point_mm;    // 3 per pixel: x, y, z in the camera frame; NaN if none
  std::vector<float> normal;      // 3 per pixel: unit normal facing the camera; 0 if none
  std::vector<int32_t> object;    // Scene::objects index; −1 if none
  std::vector<float> albedo;      // 0 if none
  std::vector<float> proj_x;      // continuous projector column of the point; NaN if none / behind
  std::vector<float> proj_y;      // continuous projector row
  std::vector<float> proj_z_mm;   // depth of the point along the projector axis; NaN if none
  std::vector<uint8_t> lit;       // 1: inside the projector image, facing it, unoccluded
  std::vector<float> direct_gain; // ru per unit emitted: direct_albedo/π · I · cosθ_p / d_p²; 0 if not lit
                                  // (direct_albedo = albedo for opaque surfaces, Material::direct_albedo())
  std::vector<float> irradiance_gain; // iu per unit emitted: I · cosθ_p / d_p² (Eq. 2.1's incident light); 0 if not lit
  std::vector<float> ambient;     // ru: albedo/π · scene ambient; 0 if no surface

  // Sampling into a projector image stored with a 1-pixel zero border
  // (padded index = (y + 1) * (proj_width + 2) + (x + 1)).
  std::vector<int32_t> nearest;   // padded index of the projector pixel holding the point; −1 if not lit
  std::vector<int32_t> bilinear;  // padded index of the top-left of its 2×2 bilinear cell; −1 if not lit
  std::vector<float> frac_x;      // bilinear weights of the right / lower neighbours
  std::vector<float> frac_y;

  // Participating medium (Scene::medium; medium.hpp, docs/media.md). Without
  // one both stay empty. With one, prepare_view() has already multiplied
  // direct_gain and irradiance_gain by the projector leg's transmittance
  // exp(−σ·ℓ_proj) (Eq. 5.11); the renderer multiplies the surface light
  // (components that are not is_volume(), and ambient) by camera_transmittance
  // exp(−σ·ℓ_cam) (1 where no surface); `medium` holds the backscatter taps.
  std::vector<float> camera_transmittance;
  std::shared_ptr<const MediumTaps> medium;
  // Tank rig (Medium::bulb; tank.hpp): the bulb's light per pixel. With a
  // bulb the projector does not light the medium (`medium` stays empty).
  std::shared_ptr<const TankTaps> tank;

  size_t pixel_count() const { return size_t{width} * height; }
};

// Ray-cast `scene` through `camera` (intrinsics + cam_from_proj) lit by
// `projector`. A point is lit iff it lies inside the projector image
// (x_p, y_p in [−0.5, W−0.5) × [−0.5, H−0.5)), its camera-facing normal faces
// the projector, and the first surface on the projector ray is the point itself.
// Fails with invalid_argument on invalid intrinsics. `threads` ≥ 1 row workers.
//
// The scene's world frame is camera 0's frame: `world_from_proj` is camera 0's
// cam_from_proj. The overload without it treats `camera` as camera 0.
// Outputs (depth, points, normals) are in `camera`'s own frame.
Result<PreparedView> prepare_view(const Scene& scene, const ProjectorModel& projector,
                                  const CameraCalibration& camera, const Rigid3& world_from_proj,
                                  int threads = 1);
Result<PreparedView> prepare_view(const Scene& scene, const ProjectorModel& projector,
                                  const CameraCalibration& camera, int threads = 1);

// Per-pixel blur for one focus setting.
struct DefocusMap {
  double focus_mm = 0;
  std::vector<float> sigma_px;  // Gaussian σ in projector pixels (0 where not lit)
  std::vector<uint8_t> level;   // lower stack level k (σ_k ≤ σ)
  std::vector<float> weight;    // weight of level k + 1 (0..1)
  size_t levels_needed = 1;     // stack levels any pixel reads
};
DefocusMap compute_defocus(const PreparedView& view, const ProjectorModel& projector, double focus_mm);

// A projector frame as linear emitted light plus its blur stack.
// Not thread-safe for concurrent build_levels(); const access is.
class PreparedPattern {
public:
  PreparedPattern() = default;
  // From a pattern (1 channel; U8 /255, U16 /(2^bit_depth − 1), F32 clamped to
  // [0, 1]) through the projector's black level and gamma. invalid_argument if
  // the size differs from the projector's or the view is malformed. Rows are
  // converted on up to `threads` threads.
  static Result<PreparedPattern> from_pattern(const procam_image& pattern, const ProjectorModel& projector,
                                              int threads = 1);
  // The same into this object, reusing its storage when the size matches
  // (the per-frame path of the sim projector). On error nothing changes.
  Status assign(const procam_image& pattern, const ProjectorModel& projector, int threads = 1);
  // From linear emitted light (F32, 1 channel, any finite values: the renderer
  // is linear in it). Used for light-transport work and linearity tests.
  static Result<PreparedPattern> from_emitted(const Image& emitted);

  uint32_t width() const { return width_; }
  uint32_t height() const { return height_; }
  size_t stride() const { return size_t{width_} + 2; }
  bool empty() const { return levels_.empty(); }
  size_t levels_built() const;
  // Padded level k (see PreparedView); nullptr if not built.
  const float* level(size_t k) const;
  // Builds levels 1..count−1 that are missing (each from level 0). O(W·H·σ).
  void build_levels(size_t count, int threads = 1);

private:
  uint32_t width_ = 0, height_ = 0;
  std::vector<std::vector<float>> levels_;  // [0] sharp; levels_[k] valid for k < built_
  size_t built_ = 0;
  std::vector<float> tmp_;                  // build_levels scratch
};

// Everything a component sees for one frame.
struct FrameContext {
  const PreparedView& view;
  const DefocusMap& defocus;
  const PreparedPattern& pattern;  // levels up to defocus.levels_needed are built
  // Projector irradiance per camera pixel (iu): irradiance_gain · blurred
  // emitted light, for the whole image; nullptr unless a component asked for
  // it (TransportComponent::needs_irradiance()).
  const float* irradiance = nullptr;
  // direct_gain / irradiance_gain per pixel (direct_albedo/π; 0 where not
  // lit), set together with `irradiance`: the direct component then reads
  // the irradiance instead of sampling the pattern a second time.
  const float* direct_per_irradiance = nullptr;
  // Polarisation of this frame (degrees; NaN = none): the projector's
  // polariser and the camera's analyser, both measured in their own image
  // plane from the +x (column) axis towards +y (row). Surface light is
  // depolarized (an analyser passes half of it, applied by the renderer);
  // volume components use them (medium.hpp).
  double projector_polarizer_deg = std::numeric_limits<double>::quiet_NaN();
  double analyser_deg = std::numeric_limits<double>::quiet_NaN();
};

// One light-transport path from projector to camera. Implementations must be
// linear in the pattern's emitted light, and apply() must be safe to call
// concurrently for disjoint row ranges.
class TransportComponent {
public:
  virtual ~TransportComponent() = default;
  virtual std::string name() const = 0;
  // Global components (everything but the direct path) form the global-only
  // image of the ground truth.
  virtual bool is_global() const { return true; }
  // Light scattered inside a participating medium rather than leaving a
  // surface: not multiplied by the camera leg's transmittance nor by the
  // analyser's 1/2 for depolarized light (it handles both itself).
  virtual bool is_volume() const { return false; }
  // Whether begin_frame/apply read FrameContext::irradiance.
  virtual bool needs_irradiance() const { return false; }
  // Blur-stack levels (kBlurLevelSigmaPx) this component samples at focus
  // `focus_mm`, beyond those the camera pixels' own defocus needs (e.g. light
  // reaching a point by a mirror is defocused over its unfolded path).
  virtual size_t levels_needed(double focus_mm) const { (void)focus_mm; return 1; }
  // Once per frame, before any apply(), on the rendering thread: whole-image
  // work (e.g. patch irradiance, blurs). May use `threads` workers.
  virtual void begin_frame(const FrameContext& frame, int threads) { (void)frame; (void)threads; }
  // Add this component's radiance (ru) for camera rows [row_begin, row_end) to
  // `radiance` (the whole camera image, row-major).
  virtual void apply(const FrameContext& frame, uint32_t row_begin, uint32_t row_end,
                     float* radiance) const = 0;
};

// Direct illumination: direct_gain · blurred emitted light at (x_p, y_p).
class DirectComponent final : public TransportComponent {
public:
  std::string name() const override { return "direct"; }
  bool is_global() const override { return false; }
  void apply(const FrameContext& frame, uint32_t row_begin, uint32_t row_end,
             float* radiance) const override;
};

// Camera lens (thin lens). aperture_mm 0 = pinhole: no camera defocus (the
// default). Blur circle b = aperture_mm · fx · |1/focus_mm − 1/z| camera
// pixels at depth z (mm), Gaussian σ = b/4 — the projector's model.
struct CameraLens {
  double aperture_mm = 0;
  double focus_mm = 800;
  double blur_sigma_px(double fx, double z_mm) const {
    return 0.25 * aperture_mm * fx * std::abs(1.0 / focus_mm - (std::isfinite(z_mm) && z_mm > 0 ? 1.0 / z_mm : 0.0));
  }
};

class Renderer {
public:
  // Installs the direct component; focus at the projector's default.
  Renderer(PreparedView view, ProjectorModel projector, int threads = 1);

  const PreparedView& view() const { return view_; }
  const ProjectorModel& projector() const { return projector_; }
  uint32_t width() const { return view_.width; }
  uint32_t height() const { return view_.height; }

  void set_threads(int threads) { threads_ = threads < 1 ? 1 : threads; }
  // Focal plane for the following renders (mm along the projector axis);
  // <= 0 or NaN: the projector's default. O(pixels) when it changes.
  void set_focus_mm(double focus_mm);
  double focus_mm() const { return defocus_.focus_mm; }
  const DefocusMap& defocus() const { return defocus_; }

  // Camera defocus for the following renders: the radiance (all parts,
  // ambient included) is blurred per pixel with σ = lens.blur_sigma_px(fx,
  // depth) — pixels without a surface use z = ∞ — as a blend of a blur stack
  // (kBlurLevelSigmaPx, clamped at the image border), like the projector's
  // defocus. A gather approximation: each pixel takes its own σ, so depth
  // edges do not bleed as a true scatter would. Linear in the pattern.
  void set_camera_lens(const CameraLens& lens);
  const CameraLens& camera_lens() const { return lens_; }

  void add_component(std::unique_ptr<TransportComponent> component);
  void clear_components() { components_.clear(); }
  const std::vector<std::unique_ptr<TransportComponent>>& components() const { return components_; }

  // radiance[v * width + u] = Σ components + (include_ambient ? ambient : 0),
  // in ru. `radiance` must hold width()*height() floats. Builds the blur
  // levels the current focus needs into `pattern`. invalid_argument if the
  // pattern is not projector-sized.
  Status render_radiance(PreparedPattern& pattern, float* radiance, bool include_ambient = true) const;

  // Polariser (projector) and analyser (camera) angles in degrees for the
  // following renders; NaN = none (the default). See FrameContext.
  void set_polarization(double projector_polarizer_deg, double analyser_deg) {
    projector_polarizer_deg_ = projector_polarizer_deg;
    analyser_deg_ = analyser_deg;
  }
  double projector_polarizer_deg() const { return projector_polarizer_deg_; }
  double analyser_deg() const { return analyser_deg_; }

  // Which components render_radiance_parts() sums. volume_only: the
  // components with is_volume() (a medium's backscatter B), no ambient.
  enum class Parts { all, direct_only, global_only, volume_only };
  // As render_radiance, restricted to the direct component (is_global() false)
  // or to the global ones; the ground truth's direct-only / global-only images.
  Status render_radiance_parts(PreparedPattern& pattern, float* radiance, bool include_ambient, Parts parts) const;
  // One component by name (TransportComponent::name()), no ambient, with the
  // same camera-leg / analyser scaling as in a full render; all zeros if no
  // component has that name. Ground truth of single paths (e.g. a medium's A).
  Status render_component(PreparedPattern& pattern, float* radiance, const std::string& name) const;

private:
  Status render_selected(PreparedPattern& pattern, float* radiance, bool include_ambient,
                         const std::function<bool(const TransportComponent&)>& wanted) const;
  PreparedView view_;
  ProjectorModel projector_;
  DefocusMap defocus_;
  std::vector<std::unique_ptr<TransportComponent>> components_;
  int threads_ = 1;
  mutable std::vector<float> irradiance_;  // per-frame scratch (thread-bound renderer)
  std::vector<float> direct_per_irradiance_;  // FrameContext::direct_per_irradiance
  void blur_camera(float* radiance) const;
  CameraLens lens_;
  std::vector<uint8_t> cam_level_;   // per pixel: lower stack level
  std::vector<float> cam_weight_;    // weight of the level above
  size_t cam_levels_ = 1;            // 1: no camera blur
  mutable std::vector<std::vector<float>> cam_stack_;
  mutable std::vector<float> cam_tmp_;
  double projector_polarizer_deg_ = std::numeric_limits<double>::quiet_NaN();
  double analyser_deg_ = std::numeric_limits<double>::quiet_NaN();
};

}  // namespace procam::sim
