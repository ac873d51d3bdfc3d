// SPDX-License-Identifier: MIT
// Global light transport of the simulated rig (thesis §2.2 Eq. 2.1–2.4, §3.2
// Eq. 3.1–3.4): inter-reflections (diffuse radiosity with visibility, fed also
// by glossy reflections off metal) and screen-space diffusion (sub-surface
// scattering in translucent bodies, light through thin sheets onto what lies
// behind them). Models, parameters and units: docs/sim.md.
//
// Every component is linear in the projector's emitted light: all the
// expensive work (form factors, the radiosity solve, glossy ray tracing, blur
// masks) happens once in make_scene_renderer(); a frame costs a few passes
// over the image and one N×N matrix–vector product.
//
// Frames: patches are stored in the world (camera 0) frame, mm. Irradiance in
// iu, radiance in ru (models.hpp). Threads: the components follow
// TransportComponent's contract (begin_frame on the rendering thread, apply
// on disjoint row ranges concurrently). Errors are returned, never thrown.
#pragma once

#include <cstdint>
#include <memory>
#include <utility>
#include <vector>

#include "procam/base/calibration.hpp"
#include "procam/base/geometry.hpp"
#include "procam/core/status.hpp"
#include "procam/hw/sim/models.hpp"
#include "procam/hw/sim/renderer.hpp"
#include "procam/hw/sim/scene.hpp"

namespace procam::sim {

struct GlobalOptions {
  uint32_t patch_px = 32;          // radiosity patch = the pixels of one object in a patch_px² camera block
  uint32_t glossy_block_px = 4;    // projector pixels per side of a glossy-transport block
  uint32_t glossy_samples = 16;    // lobe samples per glossy block
  bool interreflection = true;     // diffuse radiosity (and the glossy light it receives)
  bool glossy = true;              // glossy reflections off metal (specular > 0)
  bool diffusion = true;           // sub-surface scattering and thin sheets
};

// Preparation cost per part, wall-clock ms, and model sizes.
struct PrepStats {
  double view_ms = 0, radiosity_ms = 0, glossy_ms = 0, diffusion_ms = 0;
  size_t patches = 0, glossy_entries = 0, diffusion_objects = 0;
};

// One radiosity patch: the surface seen by the pixels of one object inside
// one camera block.
struct Patch {
  Vec3 point_mm;       // world frame: the patch pixel's surface point nearest the area centroid
  Vec3 normal;         // unit, area-weighted mean normal, facing the camera
  double area_mm2 = 0; // Σ pixel footprints z²/(fx·fy·cosθ_c)
  double albedo = 0;   // area-weighted diffuse albedo (Material::albedo)
  int32_t object = -1;
};

// Discretised diffuse inter-reflection (radiosity, thesis Eq. 2.3 with a
// Lambertian BRDF): B = D·(E + F·B), D = diag(albedo). The global irradiance
// is E_g = F·B = H·E with H = (I − F·D)⁻¹·F·D.
struct RadiosityModel {
  std::vector<Patch> patches;
  size_t size() const { return patches.size(); }
  // F_ij (row-major, N×N): form factor from patch i to patch j, the fraction
  // of light leaving i diffusely that arrives at j; point-to-patch estimate
  // V_ij·cosθ_i·cosθ_j·A_j / (π r² + (A_i + A_j)/2) (symmetric regulariser
  // keeps reciprocity A_i F_ij = A_j F_ji exact), summed over 4×4 sub-patches
  // of both when r < 3 patch sizes; V_ij by one visibility ray.
  std::vector<float> form_factor;
  std::vector<float> transport;       // H (row-major N×N)
  std::vector<int32_t> pixel_patch;   // per camera pixel: its patch, −1 if no surface
  std::vector<float> pixel_area_mm2;  // per camera pixel footprint
  // Gather: per pixel 4 patch ids (−1 unused) and weights (a tent of one
  // block width around each patch's pixel centroid, normalised) over the
  // neighbouring blocks' patches of the same object.
  std::vector<int32_t> gather_patch;
  std::vector<float> gather_weight;
  // Glossy transport: irradiance at patch `patch` per unit mean emitted light
  // of projector block `block` (index into glossy_blocks).
  struct GlossyEntry {
    uint32_t patch;
    uint32_t block;
    float irradiance;  // iu per unit emitted
  };
  std::vector<GlossyEntry> glossy;
  std::vector<uint32_t> glossy_blocks;  // projector top-left pixel index (y·W + x) of each block
  uint32_t glossy_block_px = 4;
};

// Inter-reflection component: per frame E_patch = area-mean of the projector
// irradiance over each patch, E_gl = glossy transport of the block means,
// E_g = E_gl + H·(E_patch + E_gl); a pixel adds albedo/π · (E_g gathered).
class InterreflectionComponent final : public TransportComponent {
public:
  explicit InterreflectionComponent(RadiosityModel model) : model_(std::move(model)) {}
  std::string name() const override { return "interreflection"; }
  bool needs_irradiance() const override { return true; }
  void begin_frame(const FrameContext& frame, int threads) override;
  void apply(const FrameContext& frame, uint32_t row_begin, uint32_t row_end, float* radiance) const override;
  const RadiosityModel& model() const { return model_; }
  // Patch irradiances of the last frame, iu: direct (projector) and global.
  const std::vector<float>& last_direct_patch_irradiance() const { return e_direct_; }
  const std::vector<float>& last_global_patch_irradiance() const { return e_global_; }

private:
  RadiosityModel model_;
  std::vector<double> sum_;
  std::vector<float> e_direct_, e_global_, e_total_, block_mean_;
  // The gather in the form apply() streams (built on the first frame, when
  // the view's albedo is at hand): 4 patch indices (uint16; empty pixels and
  // unused slots point at patch 0 with weight 0) and weights premultiplied
  // by albedo/π, so a pixel costs 24 bytes and no branches.
  std::vector<uint16_t> gather_p16_;
  std::vector<float> gather_w_;
  bool compact_ = false;
};

// Screen-space diffusion of one object's irradiance E (iu) over the object's
// pixels m, as a normalised convolution with a radial kernel K:
//   radiance += gain · (K ∗ (E·m)) / (K ∗ m)      (light stays in the object)
// K is a weighted sum of Gaussians, K = Σ_t w_t·G_{σ_t} (Σ w_t = 1; σ = 0 is
// a delta, the light leaving where it entered):
//  - sub-surface (translucent body): K = the radial profile R_d(r) of the
//    dipole diffusion model (Jensen et al. 2001, Eq. 4–5; transport mean free
//    path ℓ, single-scattering albedo α', refractive index n), fitted by
//    non-negative least squares to a sum of Gaussians of σ = 0, ½, 1, 2, 4 …
//    camera pixels (d'Eon & Luebke 2007) at the object's median depth; gain =
//    (albedo − F0)/π — the scene's albedo sets the energy, the dipole the
//    shape (its sharp peak of width ~ℓ and its tail out to ℓ_d = 1/σ_tr);
//  - thin sheet: one Gaussian of σ = 0.77·d (the Lambertian sheet→background→
//    sheet kernel's half-width fit, d = distance to the surface behind), gain =
//    τ²·ρ_bg/π.
// Evaluation: a pyramid over the object's bounding box. Level l has cells of
// 2^l pixels (sums of 2×2 cells of level l−1). A Gaussian term lives on the
// coarsest level with 2^l ≤ σ and is blurred there with σ_c, chosen so that
// σ_c²·4^l + box variance (4^l − 1)/12 + the variance of the bilinear
// 2× upsamplings back to level 0, Σ_{k=1..l} 4^k/6, equals σ² (px²). Per
// frame: fill level 0, sum up the pyramid, blur each term and divide by its
// blurred mask, add the levels back down with 2× bilinear upsampling.
struct DiffusionTerm {
  double weight = 0;             // w_t, Σ = 1
  double sigma_px = 0;           // σ_t, camera pixels (0: delta)
  std::vector<float> kernel;     // separable, on its level's grid (odd length; {1} for none)
  std::vector<float> inv_mask;   // 1 / (kernel ∗ mask) per cell of its level (0 where the mask is ~0)
};
struct DiffusionLevel {
  uint32_t factor = 1;           // cell size in pixels (2^l)
  uint32_t cw = 0, ch = 0;       // grid size
  std::vector<float> mask;       // object pixels per cell
  std::vector<DiffusionTerm> terms;
};
struct DiffusionModel {
  int32_t object = -1;
  bool sheet = false;
  double sigma_px = 0;   // characteristic width in camera pixels: ℓ_d (translucent) or the sheet's σ
  double sigma_mm = 0;   // the same on the surface, mm
  double px_per_mm = 0;  // camera pixels per mm at the object's median depth
  double gain = 0;       // ru per iu
  double behind_mm = 0;  // sheets: distance to the background, mm
  double behind_albedo = 0;
  uint32_t x0 = 0, y0 = 0, x1 = 0, y1 = 0;  // pixel bbox [x0, x1) × [y0, y1)
  std::vector<DiffusionLevel> levels;       // levels[0]: one cell per pixel of the bbox
};

// Dipole diffusion profile (Jensen et al. 2001): R_d(r) in 1/mm² for a
// translucent material (r in mm), and its Gaussian-sum fit in camera pixels
// (px_per_mm) as (σ_px, weight) pairs with σ = 0 for the delta; weights ≥ 0,
// Σ = 1. Exposed for tests and docs.
double dipole_profile(const Material& m, double r_mm);
std::vector<std::pair<double, double>> fit_dipole_gaussians(const Material& m, double px_per_mm);

class DiffusionComponent final : public TransportComponent {
public:
  explicit DiffusionComponent(std::vector<DiffusionModel> models) : models_(std::move(models)) {}
  std::string name() const override { return "diffusion"; }
  bool needs_irradiance() const override { return true; }
  void begin_frame(const FrameContext& frame, int threads) override;
  void apply(const FrameContext& frame, uint32_t row_begin, uint32_t row_end, float* radiance) const override;
  const std::vector<DiffusionModel>& models() const { return models_; }

private:
  std::vector<DiffusionModel> models_;
  // Per model, per level: the summed irradiance (d_) and the result (s_).
  std::vector<std::vector<std::vector<float>>> d_, s_;
  std::vector<float> blurred_, tmp_;
};

// Glossy reflection toward the camera (camera side of the glossy transport):
// a camera pixel on a glossy surface sees, around the mirror direction of its
// view ray (lobe σ = roughness_rad, glossy_samples rays), the points y that the
// projector lights directly; radiance += specular/S · albedo_y/π · E_y with E_y
// = I·cosθ/d² times the sharp emitted light at y's projector pixel. Keeps the
// projector's full resolution: the high-frequency inter-reflection of metal.
struct GlossyViewModel {
  std::vector<uint32_t> pixel;    // camera pixel index, sorted ascending
  std::vector<int32_t> source;    // padded projector index of y (PreparedView "nearest" layout)
  std::vector<float> weight;      // ru per unit emitted
};

class GlossyViewComponent final : public TransportComponent {
public:
  explicit GlossyViewComponent(GlossyViewModel model) : model_(std::move(model)) {}
  std::string name() const override { return "glossy-view"; }
  void apply(const FrameContext& frame, uint32_t row_begin, uint32_t row_end, float* radiance) const override;
  const GlossyViewModel& model() const { return model_; }

private:
  GlossyViewModel model_;
};

GlossyViewModel build_glossy_view(const Scene& scene, const PreparedView& view, const ProjectorModel& projector,
                                  const Rigid3& world_from_cam, const Rigid3& world_from_proj,
                                  const GlobalOptions& options);

// ---- Planar mirrors (global_mirror.cpp) ----------------------------------------
// A finite plane whose material is specular with roughness_rad <= 0.002
// (lobe under ~0.1 deg) is an ideal mirror: it forms a virtual projector (the
// real one reflected in the mirror plane), and a point X that this virtual
// projector reaches through the mirror rectangle, unoccluded on both legs,
// receives the pattern as the real projector shows it at the mirror point,
// defocused over the unfolded path: sigma from X's depth z' along the
// reflected projector axis (thesis Fig. 2.13: a distant mirror's light is
// blurred unlike the point's own). The glossy models skip mirrors.
bool is_planar_mirror(const Object& object);

struct MirrorModel {
  std::vector<uint32_t> pixel;  // camera pixel index, ascending
  std::vector<float> gain;      // ru per unit emitted: specular · albedo/π · I · cos / d'^2
  std::vector<float> proj_x;    // projector pixel seen through the mirror (continuous)
  std::vector<float> proj_y;
  std::vector<float> z_virtual_mm;  // depth of X along the reflected projector axis
};
MirrorModel build_mirror_paths(const Scene& scene, const PreparedView& view, const ProjectorModel& projector,
                               const Rigid3& world_from_cam, const Rigid3& world_from_proj);

class MirrorComponent final : public TransportComponent {
public:
  MirrorComponent(MirrorModel model, ProjectorModel projector);
  std::string name() const override { return "mirror"; }
  size_t levels_needed(double focus_mm) const override;
  void apply(const FrameContext& frame, uint32_t row_begin, uint32_t row_end, float* radiance) const override;
  const MirrorModel& model() const { return model_; }

private:
  MirrorModel model_;
  ProjectorModel projector_;
};

// A scene's dynamic Legendre medium (Scene::legendre_medium, added by
// make_scene_renderer) at time t_s >= 0 for the following renders (earlier
// times re-simulate from 0). Returns the fluid sub-steps taken, or -1 when
// the renderer has no such medium. Rendering thread only.
int set_legendre_time(Renderer& renderer, double t_s);

// Prepares `scene` for one camera and returns a renderer with the direct
// component plus the global components `options` enables (those that have
// anything to do in the scene). `world_from_proj` is camera 0's cam_from_proj.
Result<std::unique_ptr<Renderer>> make_scene_renderer(const Scene& scene, const ProjectorModel& projector,
                                                      const CameraCalibration& camera,
                                                      const Rigid3& world_from_proj,
                                                      const GlobalOptions& options, int threads,
                                                      PrepStats* stats = nullptr);

// Building blocks, exposed for tests and tools.
Result<RadiosityModel> build_radiosity(const Scene& scene, const PreparedView& view,
                                       const Rigid3& world_from_cam, uint32_t patch_px, int threads);
void add_glossy_transport(const Scene& scene, const PreparedView& view, const ProjectorModel& projector,
                          const Rigid3& world_from_cam, const Rigid3& world_from_proj,
                          const GlobalOptions& options, RadiosityModel& model);
std::vector<DiffusionModel> build_diffusion(const Scene& scene, const PreparedView& view,
                                            const Rigid3& world_from_cam);

}  // namespace procam::sim
