// SPDX-License-Identifier: MIT
// Sensor model: electrons, Gaussian shot + read noise, gain, saturation, quantisation.
#include "procam/hw/sim/sensor.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <vector>

#include "parallel.hpp"

namespace procam::sim {
namespace {

uint64_t splitmix64(uint64_t& state) {
  uint64_t z = (state += 0x9E3779B97F4A7C15ull);
  z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
  z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
  return z ^ (z >> 31);
}

constexpr uint32_t kTableBits = 14;
constexpr size_t kTableSize = size_t{1} << kTableBits;

// Inverse standard-normal CDF by bisection on erfc (table build only).
double inverse_phi(double p) {
  double lo = -10, hi = 10;
  for (int it = 0; it < 100; ++it) {
    const double mid = 0.5 * (lo + hi);
    if (0.5 * std::erfc(-mid / std::sqrt(2.0)) < p) lo = mid;
    else hi = mid;
  }
  return 0.5 * (lo + hi);
}

// Quantiles at (i + 0.5) / N, rescaled so the table has unit variance.
const std::vector<float>& normal_table() {
  static const std::vector<float> table = [] {
    std::vector<double> q(kTableSize);
    double var = 0;
    for (size_t i = 0; i < kTableSize / 2; ++i) {
      const double z = inverse_phi((static_cast<double>(i) + 0.5) / static_cast<double>(kTableSize));
      q[i] = z;
      q[kTableSize - 1 - i] = -z;  // exact symmetry → zero mean
      var += 2 * z * z;
    }
    const double scale = 1.0 / std::sqrt(var / static_cast<double>(kTableSize));
    std::vector<float> t(kTableSize);
    for (size_t i = 0; i < kTableSize; ++i) t[i] = static_cast<float>(q[i] * scale);
    return t;
  }();
  return table;
}

template <typename T>
void expose_rows(const float* radiance, uint32_t width, const SensorModel& s, double exposure_us,
                 double gain_db, uint64_t seed, Image& out, uint32_t b, uint32_t e) {
  const std::vector<float>& table = normal_table();
  const double e_per_ru = exposure_us * s.sensitivity;
  const double dn_per_e = s.dn_per_e(gain_db);
  const double max_dn = s.max_dn();
  const double read_var = s.read_noise_e * s.read_noise_e;
  const bool noisy = s.shot_noise || s.read_noise_e > 0;
  const double shot = s.shot_noise ? 1.0 : 0.0, full_well = s.full_well_e;
  std::vector<double> z(width, 0.0);
  for (uint32_t y = b; y < e; ++y) {
    uint64_t state = seed ^ (0xD1B54A32D192ED03ull * (uint64_t{y} + 1));
    (void)splitmix64(state);
    // The row's standard normals first (4 table draws per 64 random bits),
    // then a branch-free loop the compiler vectorises. Same values as one
    // draw per pixel in order.
    if (noisy)
      for (uint32_t x = 0; x < width; x += 4) {
        uint64_t bits = splitmix64(state);
        for (uint32_t k = 0; k < 4 && x + k < width; ++k, bits <<= 16)
          z[x + k] = static_cast<double>(table[static_cast<size_t>(bits >> (64 - kTableBits))]);
      }
    T* dst = out.row<T>(y);
    const float* src = radiance + size_t{y} * width;
    for (uint32_t x = 0; x < width; ++x) {
      double electrons = std::max(0.0, static_cast<double>(src[x]) * e_per_ru);
      electrons += std::sqrt(shot * electrons + read_var) * z[x];  // z = 0 when noise-free
      electrons = std::min(std::max(electrons, 0.0), full_well);
      // floor(v + 0.5) for v ≥ 0, capped at max_dn before the conversion.
      const double dn = std::min(electrons * dn_per_e + 0.5, max_dn + 0.5);
      dst[x] = static_cast<T>(static_cast<int32_t>(dn));
    }
  }
}

}  // namespace

double expected_dn(const SensorModel& sensor, double radiance_ru, double exposure_us, double gain_db) {
  return exposure_us * sensor.sensitivity * radiance_ru * sensor.dn_per_e(gain_db);
}

uint64_t frame_noise_seed(uint64_t rig_seed, uint32_t camera_index, uint64_t frame_id) {
  uint64_t state = rig_seed;
  uint64_t h = splitmix64(state);
  state = h ^ (uint64_t{camera_index} * 0x9E3779B97F4A7C15ull);
  h = splitmix64(state);
  state = h ^ frame_id;
  return splitmix64(state);
}

Image expose(const float* radiance_ru, uint32_t width, uint32_t height, const SensorModel& sensor,
             double exposure_us, double gain_db, uint64_t noise_seed, int threads) {
  const bool u8 = sensor.bit_depth <= 8;
  Image out(width, height, u8 ? PixelType::u8 : PixelType::u16, 1, sensor.bit_depth);
  (void)normal_table();  // build once before threads start
  detail::parallel_rows(height, threads, [&](uint32_t b, uint32_t e) {
    if (u8) expose_rows<uint8_t>(radiance_ru, width, sensor, exposure_us, gain_db, noise_seed, out, b, e);
    else expose_rows<uint16_t>(radiance_ru, width, sensor, exposure_us, gain_db, noise_seed, out, b, e);
  });
  return out;
}

}  // namespace procam::sim
