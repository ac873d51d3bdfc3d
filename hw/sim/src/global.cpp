// SPDX-License-Identifier: MIT
// Scene-renderer assembly: prepares the view and adds the global transport components the options enable.
//
// The models live one per file: global_radiosity.cpp (inter-reflection),
// global_glossy.cpp (glossy transport), global_mirror.cpp (ideal planar
// mirrors), global_diffusion.cpp (sub-surface
// scattering, thin sheets); shared helpers in global_internal.hpp.
#include "procam/hw/sim/global.hpp"

#include <chrono>

#include "legendre_medium.hpp"

namespace procam::sim {
namespace {

double ms_since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
}

}  // namespace

// ---- Assembly ------------------------------------------------------------------

Result<std::unique_ptr<Renderer>> make_scene_renderer(const Scene& scene, const ProjectorModel& projector,
                                                      const CameraCalibration& camera,
                                                      const Rigid3& world_from_proj,
                                                      const GlobalOptions& options, int threads,
                                                      PrepStats* stats) {
  PrepStats st;
  auto t0 = std::chrono::steady_clock::now();
  auto view = prepare_view(scene, projector, camera, world_from_proj, threads);
  if (!view.ok()) return view.status();
  st.view_ms = ms_since(t0);
  const Rigid3 world_from_cam = world_from_proj * camera.cam_from_proj.inverse();
  std::unique_ptr<InterreflectionComponent> inter;
  if (options.interreflection) {
    t0 = std::chrono::steady_clock::now();
    auto model = build_radiosity(scene, *view, world_from_cam, options.patch_px, threads);
    if (!model.ok()) return model.status();
    st.radiosity_ms = ms_since(t0);
    st.patches = model->size();
    if (options.glossy) {
      t0 = std::chrono::steady_clock::now();
      add_glossy_transport(scene, *view, projector, world_from_cam, world_from_proj, options, *model);
      st.glossy_ms = ms_since(t0);
      st.glossy_entries = model->glossy.size();
    }
    inter = std::make_unique<InterreflectionComponent>(std::move(model).value());
  }
  std::unique_ptr<GlossyViewComponent> glossy_view;
  if (options.glossy) {
    t0 = std::chrono::steady_clock::now();
    GlossyViewModel gv = build_glossy_view(scene, *view, projector, world_from_cam, world_from_proj, options);
    st.glossy_ms += ms_since(t0);
    st.glossy_entries += gv.pixel.size();
    if (!gv.pixel.empty()) glossy_view = std::make_unique<GlossyViewComponent>(std::move(gv));
  }
  std::unique_ptr<MirrorComponent> mirror;
  if (options.glossy) {
    MirrorModel mm = build_mirror_paths(scene, *view, projector, world_from_cam, world_from_proj);
    if (!mm.pixel.empty()) mirror = std::make_unique<MirrorComponent>(std::move(mm), projector);
  }
  std::unique_ptr<DiffusionComponent> diff;
  if (options.diffusion) {
    t0 = std::chrono::steady_clock::now();
    auto models = build_diffusion(scene, *view, world_from_cam);
    st.diffusion_ms = ms_since(t0);
    st.diffusion_objects = models.size();
    if (!models.empty()) diff = std::make_unique<DiffusionComponent>(std::move(models));
  }
  auto r = std::make_unique<Renderer>(std::move(view).value(), projector, threads);
  if (inter) r->add_component(std::move(inter));
  if (glossy_view) r->add_component(std::move(glossy_view));
  if (diff) r->add_component(std::move(diff));
  if (mirror) r->add_component(std::move(mirror));
  if (scene.legendre_medium)  // dynamic medium (docs/legendre.md); the rig sets its time per frame
    r->add_component(
        std::make_unique<LegendreMediumComponent>(scene, projector, world_from_cam, world_from_proj, threads));
  if (stats) *stats = st;
  return r;
}

}  // namespace procam::sim
