// SPDX-License-Identifier: MIT
// What the media-stereo sessions (binocular, helmholtz, medium) share: the
// params of a depth search in a medium, their checks, and the medium taken
// either from the params or fitted from an input image of the medium alone
// (thesis §5.4.1).
//
// Units: sigma/beta in 1/mm, depths in mm, images in full-scale fractions,
// light_intensity in full-scale units x mm^2 (as the sessions' params say).
// Errors: sdk::Error values, never exceptions.
// Threads: pure functions.
#pragma once

#include <optional>
#include <string>
#include <vector>

#include "medium_fit.hpp"
#include "procam/plugin_sdk.hpp"
#include "scatter_model.hpp"
#include "stereo_common.hpp"
#include "synthetic.hpp"

namespace procam::media_stereo {

// A rig camera as a PinholeCamera placed by world_from_cam (mm).
PinholeCamera pinhole_of(const Intrinsics& k, const Rigid3& world_from_cam);

// `frame` (U8, U16 or F32, 1 channel, already size-checked) as full-scale
// fractions into `img` (resized to the frame): integer frames divided by
// 2^bits − 1, where bits is the frame's bit_depth or, when the frame claims
// more, the rig camera's `rig_bits` (a 12-bit frame read back from 16-bit PNG).
void frame_to_full_scale(const procam_image& frame, uint32_t rig_bits, std::vector<float>& img);

// Pixel stride of the §5.4.1 medium fit: every 4th pixel in x and y (432
// samples on a 96 x 72 camera), coarser on larger cameras so the fit sees
// about 500 samples at most (its cost grows with the count; every 7th pixel
// at 160 x 120, every 68th at 1920 x 1200).
uint32_t medium_fit_stride(uint32_t width, uint32_t height);

// Params of a depth search in a medium: constraint, sigma/beta/g,
// light_intensity, z range and step, window (default `window`), min_signal,
// saturation, medium_wall_mm. `constraint_doc` and `light_doc` describe the
// method's constraint and light.
std::vector<sdk::ParamSpec> stereo_params(int window, const std::string& constraint_doc, const std::string& light_doc);

// beta <= sigma, three depth hypotheses at least, an odd window.
sdk::Error check_stereo_params(const sdk::Params& p);

// The DepthSearch the params describe.
DepthSearch search_from(const sdk::Params& p);

// The field of a pinhole light (the projector, or a rig light's "field")
// placed by light_from_world.
LightCone cone_of(const Rigid3& light_from_world, uint32_t width, uint32_t height, double fx, double fy, double cx,
                  double cy);

// Where a session's medium comes from: the light that lit the image of the
// medium alone, seen by camera `cam`.
struct MediumShot {
  PinholeCamera cam;
  Vec3 light;          // light centre, world (camera 0's frame), mm
  LightCone cone;      // its field
  std::string light_name;  // for the report: "the projector's flood" or "unit 1's light"
};

// Camera 0 lit by the projector's flood (a rig whose projector is the
// light: binocular's, or `medium` on a rig without camera+light units).
// The rig must be calibrated (can_triangulate(0)); world = camera 0's frame.
MediumShot projector_shot(const sdk::Rig& rig);

// §5.4.1: sigma, beta, g from `image` (full scale) of the medium alone, rays
// ending at a black wall at z = wall_mm (camera 0's frame).
MediumFit fit_medium_shot(const MediumShot& shot, const std::vector<float>& image, double i0, double wall_mm,
                          double saturation);

// The optional input `medium_image` of a stereo method: its spec, and the fit
// when the host passed one (`fit` stays empty without it). INVALID_ARGUMENT
// when it has the wrong size or no usable backscatter.
sdk::InputSpec medium_image_input();
sdk::Error medium_from_input(const sdk::CreateArgs& args, const sdk::Params& p, const MediumShot& shot,
                             std::optional<MediumFit>& fit);

// The medium a session uses: the fit's when there is one, else the params'.
MediumParams medium_of(const sdk::Params& p, const std::optional<MediumFit>& fit);

// report.medium: the values, which were fitted or given, and from where.
nlohmann::json medium_report(const MediumParams& m, const std::optional<MediumFit>& fit,
                             const std::string& fit_source);

// The scalar outputs medium_extinction_per_mm, medium_scattering_per_mm,
// medium_hg_g, each described with `how`.
void add_medium_scalars(sdk::Outputs& out, const MediumParams& m, const std::string& how);

}  // namespace procam::media_stereo
