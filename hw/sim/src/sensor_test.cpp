// SPDX-License-Identifier: MIT
// Sensor model: output types and ranges, saturation, noise statistics against
// sqrt(shot + read²), determinism.
#include "procam/hw/sim/sensor.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <vector>

namespace procam::sim {
namespace {

constexpr uint32_t W = 64, H = 48;

std::vector<float> flat(float radiance) { return std::vector<float>(size_t{W} * H, radiance); }

double pixel(const Image& im, size_t i) {
  return im.type() == PixelType::u8 ? im.ptr<uint8_t>()[i] : im.ptr<uint16_t>()[i];
}

TEST(Sensor, OutputTypesAndRanges) {
  for (uint32_t bits : {8u, 10u, 12u, 16u}) {
    SensorModel s;
    s.bit_depth = bits;
    const auto rad = flat(0.2f);
    const Image im = expose(rad.data(), W, H, s, 10000, 0, 1);
    EXPECT_EQ(im.type(), bits == 8 ? PixelType::u8 : PixelType::u16) << bits;
    EXPECT_EQ(im.bit_depth(), bits);
    EXPECT_EQ(im.width(), W);
    const double max_dn = std::pow(2.0, bits) - 1;
    // Mean DN = exposure · sensitivity · L · max / full_well (independent formula).
    const double expected = 10000 * 2.0 * 0.2 * max_dn / 10000;
    double sum = 0;
    for (size_t i = 0; i < im.pixel_count(); ++i) {
      ASSERT_LE(pixel(im, i), max_dn);
      sum += pixel(im, i);
    }
    EXPECT_NEAR(sum / static_cast<double>(im.pixel_count()), expected, 0.01 * expected) << bits;
  }
}

TEST(Sensor, SaturatesAtFullWellAndMaxDn) {
  for (uint32_t bits : {8u, 12u}) {
    SensorModel s;
    s.bit_depth = bits;
    const auto rad = flat(5.0f);  // 100 000 e⁻ ≫ full well
    const double max_dn = std::pow(2.0, bits) - 1;
    for (double gain : {0.0, 12.0}) {
      const Image im = expose(rad.data(), W, H, s, 10000, gain, 3);
      for (size_t i = 0; i < im.pixel_count(); ++i) ASSERT_EQ(pixel(im, i), max_dn);
    }
    // With gain, DN clips before the well is full: 0.6 full well × 2 (6 dB) → max.
    const auto half = flat(0.3f);  // 6000 e⁻
    const Image g = expose(half.data(), W, H, s, 10000, 20 * std::log10(2.0), 3);
    size_t at_max = 0;
    for (size_t i = 0; i < g.pixel_count(); ++i) at_max += pixel(g, i) == max_dn ? 1u : 0u;
    EXPECT_EQ(at_max, g.pixel_count());
  }
}

TEST(Sensor, NoiseMatchesShotPlusRead) {
  struct Case { uint32_t bits; double electrons; double read; double gain_db; };
  for (const Case c : {Case{12, 4000, 10, 0}, Case{8, 6000, 10, 0}, Case{12, 50, 20, 12}, Case{16, 9000, 5, 0}}) {
    SensorModel s;
    s.bit_depth = c.bits;
    s.read_noise_e = c.read;
    const double exposure = 10000;
    const auto rad = flat(static_cast<float>(c.electrons / (exposure * s.sensitivity)));
    const size_t n = size_t{W} * H;
    const int frames = 24;
    std::vector<double> sum(n, 0), sum2(n, 0);
    for (int f = 0; f < frames; ++f) {
      const Image im = expose(rad.data(), W, H, s, exposure, c.gain_db, frame_noise_seed(42, 0, static_cast<uint64_t>(f)));
      for (size_t i = 0; i < n; ++i) {
        const double v = pixel(im, i);
        sum[i] += v;
        sum2[i] += v * v;
      }
    }
    double var = 0, mean = 0;
    for (size_t i = 0; i < n; ++i) {
      const double m = sum[i] / frames;
      var += (sum2[i] - frames * m * m) / (frames - 1);
      mean += m;
    }
    var /= static_cast<double>(n);
    mean /= static_cast<double>(n);
    const double dn_per_e = (std::pow(2.0, c.bits) - 1) / s.full_well_e * std::pow(10.0, c.gain_db / 20);
    const double expected_std = dn_per_e * std::sqrt(c.electrons + c.read * c.read);
    EXPECT_NEAR(std::sqrt(var) / expected_std, 1.0, 0.15) << "bits " << c.bits << " e " << c.electrons;
    EXPECT_NEAR(mean, c.electrons * dn_per_e, 0.02 * c.electrons * dn_per_e + 0.05);
  }
}

TEST(Sensor, DeterministicPerSeedAndFramesDiffer) {
  SensorModel s;
  s.bit_depth = 12;
  const auto rad = flat(0.2f);
  const Image a = expose(rad.data(), W, H, s, 10000, 0, frame_noise_seed(9, 0, 5), 1);
  const Image b = expose(rad.data(), W, H, s, 10000, 0, frame_noise_seed(9, 0, 5), 3);  // thread count irrelevant
  const Image c = expose(rad.data(), W, H, s, 10000, 0, frame_noise_seed(9, 0, 6));
  const Image d = expose(rad.data(), W, H, s, 10000, 0, frame_noise_seed(9, 1, 5));
  ASSERT_EQ(a.size_bytes(), b.size_bytes());
  EXPECT_EQ(0, std::memcmp(a.data(), b.data(), a.size_bytes()));
  size_t diff_c = 0, diff_d = 0;
  for (size_t i = 0; i < a.pixel_count(); ++i) {
    diff_c += pixel(a, i) != pixel(c, i) ? 1u : 0u;
    diff_d += pixel(a, i) != pixel(d, i) ? 1u : 0u;
  }
  EXPECT_GT(diff_c, a.pixel_count() / 2);
  EXPECT_GT(diff_d, a.pixel_count() / 2);
}

TEST(Sensor, NoiseFreeIsExactRounding) {
  SensorModel s;
  s.bit_depth = 10;
  s.shot_noise = false;
  s.read_noise_e = 0;
  std::vector<float> rad(size_t{W} * H);
  for (size_t i = 0; i < rad.size(); ++i) rad[i] = static_cast<float>(i) * 1e-4f;
  const Image im = expose(rad.data(), W, H, s, 7000, 3, 1);
  for (size_t i = 0; i < rad.size(); ++i) {
    const double dn = 7000 * 2.0 * static_cast<double>(rad[i]) * 1023.0 / 10000 * std::pow(10.0, 3.0 / 20);
    ASSERT_EQ(pixel(im, i), std::min(1023.0, std::floor(dn + 0.5))) << i;
    EXPECT_NEAR(expected_dn(s, static_cast<double>(rad[i]), 7000, 3), dn, 1e-9);
  }
}

}  // namespace
}  // namespace procam::sim
