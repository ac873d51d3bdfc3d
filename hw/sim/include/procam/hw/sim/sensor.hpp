// SPDX-License-Identifier: MIT
// Camera sensor simulation: radiance (ru) → electrons → noise → DN frame
// (model and units in models.hpp SensorModel).
//
// Noise is deterministic in `noise_seed`: the same radiance, settings and seed
// give the same frame on any thread count (each row draws from its own stream
// derived from the seed and the row). Shot noise uses the Gaussian
// approximation of Poisson (variance = mean electrons, clamped at 0 e⁻), read
// noise is Gaussian; both are drawn as one normal of variance
// shot + read². Normals come from a 16384-quantile table rescaled to unit
// variance (tails truncated at ~4σ), which is fast and exact in mean/variance.
// Threads: reentrant.
#pragma once

#include <cstdint>

#include "procam/core/image.hpp"
#include "procam/hw/sim/models.hpp"

namespace procam::sim {

// Noise-free DN before rounding and clamping: exposure_us · sensitivity ·
// radiance · dn_per_e(gain_db).
double expected_dn(const SensorModel& sensor, double radiance_ru, double exposure_us, double gain_db);

// Frame of `width`×`height` from `radiance_ru` (row-major). U8 when
// bit_depth ≤ 8, else U16 with bit_depth significant right-aligned bits.
// Electrons clamp to [0, full_well_e], DN to [0, 2^bit_depth − 1].
Image expose(const float* radiance_ru, uint32_t width, uint32_t height, const SensorModel& sensor,
             double exposure_us, double gain_db, uint64_t noise_seed, int threads = 1);

// Seed of one frame's noise: mixes the rig seed, camera index and frame id so
// successive frames and different cameras draw independent noise.
uint64_t frame_noise_seed(uint64_t rig_seed, uint32_t camera_index, uint64_t frame_id);

}  // namespace procam::sim
