// SPDX-License-Identifier: MIT
// Test-only (the through-the-rig tests): a `medium` scan's medium_image as
// the scan input of that name, and stereo params made deliberately wrong
// (clear water) so a test sees the fit replace them.
#pragma once

#include <cstdint>
#include <vector>

#include <nlohmann/json.hpp>

#include "procam/host/plugin_host.hpp"

namespace procam::media_stereo::test {

// A view of `image` (width x height F32, full scale): it must outlive the input.
inline host::InputImage medium_image_input(const std::vector<float>& image, uint32_t width, uint32_t height) {
  host::InputImage in;
  in.name = "medium_image";
  in.description = "medium_image of the medium scan";
  in.image = procam_image{.width = width, .height = height, .channels = 1, .pixel_type = PROCAM_PIXEL_F32,
                          .bit_depth = 32, .reserved = 0, .stride_bytes = size_t{width} * sizeof(float),
                          .data = image.data()};
  return in;
}

inline nlohmann::json with_clear_water(nlohmann::json p) {
  p["sigma_per_mm"] = 0.0;  // wrong on purpose: the fit must replace them
  p["beta_per_mm"] = 0.0;
  p["g"] = 0.0;
  return p;
}

}  // namespace procam::media_stereo::test
