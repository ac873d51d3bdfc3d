// SPDX-License-Identifier: MIT
// The `binocular` method through the plugin ABI (thesis §5.4.1, Eq. 5.20-5.23)
// on a rig with two calibrated cameras and a calibrated projector that floods
// the scene as the light source.
//
// Plan: one round of two frames, both a full-white flood from the projector:
// frame 0 taken by camera 0 (settings.camera_index 0), frame 1 by camera 1.
// Decoding: binocular_depth() (binocular.hpp) with camera 0 as the reference,
// the light at the projector's centre, its emission clipped to the projector
// image (LightCone), and the medium taken from the params (not fitted: in a
// scan every pixel may see an object, while the §5.4.1 fit needs an image of
// the medium alone; fit_medium() serves that separate calibration shot).
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
// devices or distortion; BAD_FRAME on a frame of the wrong size.
// Threads: a Session is thread-bound (SDK); decoding is single-threaded.
#pragma once

#include <memory>
#include <vector>

#include "procam/plugin_sdk.hpp"
#include "synthetic.hpp"

namespace procam::media_stereo {

// A rig camera as a PinholeCamera placed by world_from_cam (mm).
PinholeCamera pinhole_of(const Intrinsics& k, const Rigid3& world_from_cam);

// `frame` (U8, U16 or F32, 1 channel, already size-checked) as full-scale
// fractions into `img` (resized to the frame): integer frames divided by
// 2^bits − 1, where bits is the frame's bit_depth or, when the frame claims
// more, the rig camera's `rig_bits` (a 12-bit frame read back from 16-bit PNG).
void frame_to_full_scale(const procam_image& frame, uint32_t rig_bits, std::vector<float>& img);

sdk::MethodDescription binocular_description();
sdk::Error create_binocular_session(const sdk::CreateArgs& args, std::unique_ptr<sdk::Session>& out);

}  // namespace procam::media_stereo
