// SPDX-License-Identifier: MIT
// The `helmholtz` method through the plugin ABI (thesis §5.4.2, Eq. 5.30-5.34)
// on a rig of camera+light units: every camera used carries a light at its
// centre (rig description "lights", plugin ABI 3; docs/media-stereo.md
// "Helmholtz through the rig").
//
// Pairs: unit 0 (camera 0 and its light) is the reference and one member of
// every pair; each other camera j with a light forms pair j with it. Needs
// >= 3 pairs. Plan: one round of 2 frames per pair: camera 0 lit by light j
// ("pair-j-a", settings.light_index = j's light), then camera j lit by
// camera 0's light ("pair-j-b"); the projector is dark (black patterns).
// Decoding: helmholtz_stereo() (helmholtz.hpp) on camera 0's pixel grid, the
// backscatter of each (camera, light) pair integrated inside that light's
// field (its LightCone), then integrate_normals() (normal_integration.hpp)
// seeded with the rank-minimum depth.
//
// Medium: params (sigma_per_mm, beta_per_mm, g), or, when the scan passes
// the optional input `medium_image` (ABI 2 scan inputs), fitted by
// fit_medium() (medium_fit.hpp, §5.4.1) from it: camera 0's image of the
// medium alone lit by unit 1's light, made by the `medium` method below in a
// scan with the scene removed (a black far wall at `medium_wall_mm`). The
// report says which parameters were fitted and which given; a fit adds the
// scalars medium_extinction_per_mm, medium_scattering_per_mm, medium_hg_g.
//
// `medium` (thesis §5.4.1 "Recovering the medium parameters"): one frame,
// camera 0 lit by unit 1's light (side by side: a co-located light sees the
// same scattering angle everywhere, so g would not be observable), the tank
// emptied of objects. On a rig without units (binocular's: the projector is
// the light) the projector floods instead. Outputs medium_image (full scale)
// and the fit; pass it to helmholtz or binocular on the same rig.
//
// Frames: U8/U16/F32 normalised to full scale (frame_to_full_scale); light
// intensity (`light_intensity`, full scale · mm²) is the same for every light
// (the rig's lights must have equal irradiance_at_1m).
// Outputs: depth_mm (rank minimum, camera 0's z), depth_integrated_mm,
// normal_x/normal_y/normal_z (unit normal in camera 0's frame, facing it),
// rank_ratio (s3/s2 at the minimum), the standard outputs and a report.
// Errors: FAILED_PRECONDITION when the rig has no light on camera 0, fewer
// than three other cameras with lights, a light off its camera's centre
// (> 1 mm), unequal light intensities or lens distortion; INVALID_ARGUMENT for
// bad params; BAD_FRAME for a frame of the wrong size.
// Threads: a Session is thread-bound (SDK); decoding is single-threaded.
#pragma once

#include <memory>

#include "procam/plugin_sdk.hpp"

namespace procam::media_stereo {

sdk::MethodDescription helmholtz_description();
sdk::Error create_helmholtz_session(const sdk::CreateArgs& args, std::unique_ptr<sdk::Session>& out);
sdk::MethodDescription medium_description();
sdk::Error create_medium_session(const sdk::CreateArgs& args, std::unique_ptr<sdk::Session>& out);

}  // namespace procam::media_stereo
