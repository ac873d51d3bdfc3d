// SPDX-License-Identifier: MIT
// The `binocular` method through the plugin ABI (thesis §5.4.1, Eq. 5.20-5.23)
// on a rig with two calibrated cameras and a calibrated projector that floods
// the scene as the light source.
//
// Plan: one round of two frames, both a full-white flood from the projector:
// frame 0 taken by camera 0 (settings.camera_index 0), frame 1 by camera 1.
// Decoding: binocular_depth() (binocular.hpp) with camera 0 as the reference,
// the light at the projector's centre, its emission clipped to the projector
// image (LightCone), and the medium taken from the params or, when the scan
// passes the optional input `medium_image`, fitted from it (§5.4.1; in a scan
// every pixel may see an object, so the fit needs a separate shot of the
// medium alone: the `medium` method on this rig, camera 0 lit by the
// projector's flood, scene removed, a black wall at `medium_wall_mm`). A fit
// adds the scalars medium_extinction_per_mm, medium_scattering_per_mm,
// medium_hg_g, and the report says which parameters were fitted.
//
// Frames: U8, U16 (any bit depth) or F32, normalised by the frame's full scale
// (sdk::full_scale) so light_intensity and min_signal are in full-scale units
// for every bit depth; an integer frame that claims more bits than the rig's
// camera (rig "bit_depth") is scaled by the camera's (a 12-bit frame recorded
// to 16-bit PNG comes back as bit_depth 16). A sample at/above `saturation`
// (of full scale) drops out.
// World frame: camera 0's (rig cam_from_proj of camera 0 places the
// projector); lens distortion is refused (undistort the frames first).
// Outputs: depth_mm (F32, camera 0's z, NaN invalid), the standard outputs and
// a report naming the constraint, the medium and the light used.
// Errors: FAILED_PRECONDITION when the rig has < 2 cameras, uncalibrated
// devices or distortion; INVALID_ARGUMENT for bad params or a medium_image of
// the wrong size or without usable backscatter; BAD_FRAME on a frame of the
// wrong size.
// Threads: a Session is thread-bound (SDK); decoding is single-threaded.
#pragma once

#include <memory>
#include <vector>

#include "procam/plugin_sdk.hpp"
#include "stereo_session.hpp"
#include "synthetic.hpp"

namespace procam::media_stereo {

sdk::MethodDescription binocular_description();
sdk::Error create_binocular_session(const sdk::CreateArgs& args, std::unique_ptr<sdk::Session>& out);

}  // namespace procam::media_stereo
