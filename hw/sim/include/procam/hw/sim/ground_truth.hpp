// SPDX-License-Identifier: MIT
// Ground truth of a prepared view (depth, projector coordinates, lit mask) and
// writing it to files.
//
// Threads: reentrant. Errors are returned, never thrown.
#pragma once

#include <map>
#include <string>

#include "procam/core/status.hpp"
#include "procam/hw/rig.hpp"
#include "procam/hw/sim/models.hpp"
#include "procam/hw/sim/renderer.hpp"

namespace procam::sim {

// depth_mm: camera-frame z (NaN where no surface); proj_col/proj_row: the
// visible point projected through the projector intrinsics (continuous, pixel
// centres at integers; NaN where not lit); lit: U8 255/0.
hw::GroundTruth ground_truth_from_view(const PreparedView& view);

// Writes <folder>/depth_mm.exr, proj_col.exr, proj_row.exr (F32, NaN where
// undefined) and lit.png (8-bit 0/255), creating the folder. `attributes` are
// stored as EXR string attributes (e.g. {"scene": "plane"}). io_error naming
// the file on failure.
// Direct / global split of one pattern (sim only; thesis §2.5): F32 ru images
// without ambient, direct + global = the full radiance minus ambient, and the
// per-pixel global/direct ratio under full illumination (pattern value 1
// everywhere; NaN where there is no direct light).
struct ComponentTruth {
  Image direct;
  Image global;
  Image global_direct_ratio_white;
};
// Renders `pattern` twice (direct only, global only) and the white pattern
// twice. invalid_argument as Renderer::render_radiance.
Result<ComponentTruth> component_truth(const Renderer& renderer, PreparedPattern& pattern,
                                       const ProjectorModel& projector);

// Fills truth.direct / truth.global (see hw::GroundTruth) for the camera of
// `renderer` at its current focus: the white pattern rendered direct-only and
// global-only (no ambient), each converted to DN with expected_dn() at
// `exposure_us` / `gain_db`. invalid_argument as Renderer::render_radiance.
Status add_white_components(hw::GroundTruth& truth, const Renderer& renderer, const ProjectorModel& projector,
                            const SensorModel& sensor, double exposure_us, double gain_db);

// Fills the participating-medium maps of `truth` (hw::GroundTruth::medium_*:
// D, A (approximate, docs/media.md), B in DN like add_white_components,
// and the DOP of B for projector polariser `projector_polarizer_deg`, NaN =
// unpolarized) and truth.medium = {"extinction_per_mm", "scattering_per_mm",
// "hg_g"} from `medium`. Renders with the renderer's current polarization
// settings, so call it with none set (SimRig::ground_truth does). No-op when
// the view has no medium. invalid_argument as Renderer::render_radiance.
Status add_medium_components(hw::GroundTruth& truth, const Renderer& renderer, const Medium* medium,
                             const ProjectorModel& projector, const SensorModel& sensor, double exposure_us,
                             double gain_db, double projector_polarizer_deg);

// Also writes the medium maps (medium_direct.exr, medium_indirect.exr,
// medium_backscatter.exr in DN, medium_backscatter_dop.exr) when present.
Status write_ground_truth(const hw::GroundTruth& truth, const std::string& folder,
                          const std::map<std::string, std::string>& attributes = {});

}  // namespace procam::sim
