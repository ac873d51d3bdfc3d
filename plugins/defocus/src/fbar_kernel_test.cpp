// SPDX-License-Identifier: MIT
// The multi-focal hot path (fbar_kernel.hpp) against its oracles:
//   - FloatTable against CalibrationTable::lookup (double): the same validity
//     at every sample and either side of it, values within float rounding;
//   - the AVX2 row kernel against the scalar one, bit for bit;
//   - fbar_depth_map on 8- and 16-bit sweeps through the accumulator against
//     the per-pixel reference fbar_from_e3 + usable() + CalibrationTable::lookup,
//     on random curves and the hard cases (ties, flat, black, saturated,
//     all-zero, peak at an end).
// Tolerances: fbar 2e-5 index (the fast logarithm, |error| < 3e-8, divided
// by the smallest curvature the random curves reach); depth 2e-6 relative
// against the table at the kernel's own fbar (float rounding of y0 + t dy),
// and 0.05 % of depth against the table at the reference fbar (the fbar
// tolerance times the table's largest slope, 2e-5 x 140 mm/index at ~600 mm).
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <limits>
#include <vector>

#include "fbar_kernel.hpp"
#include "focus_measures.hpp"
#include "procam/sdk/simd.hpp"

namespace procam::defocus {
namespace {

struct Lcg {
  uint32_t s = 12345;
  double operator()() { return double((s = s * 1103515245u + 12345u) >> 8) / double(1u << 24); }
};

std::vector<sdk::CalibrationTable> tables() {
  std::vector<sdk::CalibrationTable> t(5);
  for (int k = 0; k <= 50; ++k) t[0].samples.emplace_back(0.1 * k, 600 + 10.0 * k);  // uniform (the bench's)
  for (int k = 0; k <= 12; ++k) t[1].samples.emplace_back(0.4 + 0.35 * k + 0.05 * (k % 3), 600 + 37.0 * k * k);
  t[2].samples = {{0.7, 1090.0}, {4.3, 650.0}};  // two samples, decreasing depth
  Lcg rnd;
  double x = 0.55, y = 1100;
  for (int k = 0; k < 40; ++k) {  // scattered gaps from 1e-3 to 0.3, as a fit can give
    t[3].samples.emplace_back(x, y);
    x += k % 7 == 3 ? 1e-3 : 0.3 * rnd() + 2e-3;
    y -= 1 + 20 * rnd();
  }
  t[4].samples = {{1.0, 700.0}, {1.0 + 1e-9, 701.0}, {3.0, 900.0}};  // no 2^16 grid separates these
  return t;
}

TEST(FloatTable, SameValidityAndValueAsTheDoubleLookup) {
  const auto all = tables();
  for (size_t t = 0; t < all.size(); ++t) {
    const auto& table = all[t];
    const detail::FloatTable ft(&table);
    if (t == 4) {
      EXPECT_FALSE(ft.usable);  // fbar_depth_map falls back to the double lookup
      continue;
    }
    ASSERT_TRUE(ft.usable) << t;
    std::vector<float> xs = {std::numeric_limits<float>::quiet_NaN(), -1.f, 100.f};
    for (const auto& s : table.samples) {
      const auto f = static_cast<float>(s.first);
      xs.insert(xs.end(), {f, std::nextafter(f, -1.f), std::nextafter(f, 100.f)});
    }
    Lcg rnd;
    for (int i = 0; i < 20000; ++i)
      xs.push_back(static_cast<float>(table.x_min() - 0.1 + (table.x_max() - table.x_min() + 0.2) * rnd()));
    for (float x : xs) {
      const float ref = table.lookup(double(x)), got = ft.lookup(x);
      ASSERT_EQ(std::isnan(ref), std::isnan(got)) << x;
      if (!std::isnan(ref)) {
        ASSERT_NEAR(got, ref, 2e-6 * std::abs(double(ref))) << x;
      }
    }
  }
}

// Random rows with every hard case, for the row kernels.
struct Rows {
  uint32_t w = 1003, F = 6;  // not a multiple of 8: the scalar tail runs too
  std::vector<std::vector<float>> e;
  std::vector<float> mean;
  std::vector<uint8_t> sat;
  explicit Rows(uint32_t F_) : F(F_), e(F_, std::vector<float>(w)), mean(w), sat((w + 7) / 8) {
    Lcg rnd;
    for (uint32_t x = 0; x < w; ++x) {
      const double centre = -1 + (F + 1) * rnd(), width = 0.4 + 1.5 * rnd(), height = 300 * rnd();
      mean[x] = static_cast<float>(x % 41 == 0 ? 2 : 100 + 100 * rnd());
      for (uint32_t f = 0; f < F; ++f)
        e[f][x] = static_cast<float>(height * std::exp(-0.5 * std::pow((f - centre) / width, 2)));
      if (x % 13 == 0) e[F / 2 - 1][x] = e[F / 2][x];  // exact tie between two settings
      if (x % 17 == 0) for (auto& m : e) m[x] = 30;   // flat
      if (x % 19 == 0) for (auto& m : e) m[x] = 0;    // all black
      if (x % 23 == 0) sat[x / 8] |= uint8_t(1u << (x % 8));
      if (x >= 64 && x < 80) for (auto& m : e) m[x] = 0;  // two AVX2 groups without a valid lane (no lookup)
    }
  }
  detail::RowArgs args(std::vector<const float*>& ptr, const detail::FloatTable* t, float* fbar, float* depth,
                       float* peak, uint8_t* valid = nullptr, size_t* valid_count = nullptr) const {
    ptr.clear();
    for (const auto& m : e) ptr.push_back(m.data());
    return {ptr.data(), F, mean.data(), sat.data(), 5.f, 0.02f, t, fbar, depth, peak, valid, valid_count,
            nullptr, 0, 0};
  }
};

// Random int16 buckets D_0..D_3 (|D| <= 6 x 255, as 8-bit frames give) for a
// deferred fold of `w` pixels, stride w.
std::vector<int16_t> random_buckets(uint32_t w) {
  Lcg rnd;
  std::vector<int16_t> d(4 * size_t{w});
  for (auto& v : d) v = static_cast<int16_t>(std::lround(-1530 + 3060 * rnd()));
  for (uint32_t x = 0; x < w; x += 7) d[x] = d[w + x] = d[2 * w + x] = d[3 * w + x] = 0;  // E = 0
  return d;
}

TEST(FbarRow, Avx2TwinIsBitIdenticalToScalar) {
  if (!sdk::cpu_has_avx2()) GTEST_SKIP() << "no AVX2 on this CPU";
  // Every table with a float grid: the lookup's gathers fetch (y, slope)
  // pairs per lane, so lanes of different bins check their order.
  const auto all = tables();
  for (size_t t = 0; t < 4; ++t)
  for (uint32_t F : {3u, 6u, 9u}) {
    const Rows rows(F);
    const auto& table = all[t];
    const detail::FloatTable ft(&table);
    ASSERT_TRUE(ft.usable) << t;
    std::vector<float> f1(rows.w), d1(rows.w), p1(rows.w), f2(rows.w), d2(rows.w), p2(rows.w);
    std::vector<const float*> ptr;
    const size_t c1 = detail::fbar_row_scalar(rows.args(ptr, &ft, f1.data(), d1.data(), p1.data()), 0, rows.w);
    const size_t c2 = detail::fbar_row_avx2(rows.args(ptr, &ft, f2.data(), d2.data(), p2.data()), 0, rows.w);
    EXPECT_EQ(c1, c2);
    EXPECT_GT(c1, rows.w / 10);  // the random curves give valid pixels
    EXPECT_EQ(std::memcmp(f1.data(), f2.data(), rows.w * 4), 0) << F;
    EXPECT_EQ(std::memcmp(d1.data(), d2.data(), rows.w * 4), 0) << F << " table " << t;
    EXPECT_EQ(std::memcmp(p1.data(), p2.data(), rows.w * 4), 0) << F;
    size_t finite_depth = 0;
    for (float d : d1) finite_depth += std::isfinite(d) ? 1u : 0u;
    EXPECT_GT(finite_depth, 0u) << t;  // the lookup ran on some lanes
  }
}

// The deferred fold and the valid map, row kernels: AVX2 and scalar give the
// same bits, the fold gives e3_from_buckets' value (the peak output shows it
// where that setting is the largest), and valid is 255 exactly where depth is
// finite (valid_where_finite's rule) with the count of those.
TEST(FbarRow, DeferredFoldAndValidMapAreTwinsAndMatchTheirDefinitions) {
  for (uint32_t F : {3u, 6u}) {
    const Rows rows(F);
    const auto table = tables()[1];
    const detail::FloatTable ft(&table);
    const std::vector<int16_t> buckets = random_buckets(rows.w);
    for (uint32_t fold_f : {0u, F - 1}) {
      std::vector<float> f1(rows.w), d1(rows.w), p1(rows.w), f2(rows.w), d2(rows.w), p2(rows.w);
      std::vector<uint8_t> v1(rows.w, 7), v2(rows.w, 7);
      size_t n1 = 0, n2 = 0;
      std::vector<const float*> ptr;
      auto a1 = rows.args(ptr, &ft, f1.data(), d1.data(), p1.data(), v1.data(), &n1);
      a1.fold = buckets.data(), a1.fold_stride = rows.w, a1.fold_f = fold_f;
      const size_t c1 = detail::fbar_row_scalar(a1, 0, rows.w);
      size_t finite = 0, fold_is_peak = 0;
      for (uint32_t x = 0; x < rows.w; ++x) {
        const bool ok = std::isfinite(d1[x]);
        ASSERT_EQ(v1[x], ok ? 255 : 0) << x;
        finite += ok;
        float top = 0;
        for (uint32_t f = 0; f < F; ++f)
          top = std::max(top, f == fold_f ? e3_from_buckets(buckets[x], buckets[rows.w + x], buckets[2 * rows.w + x],
                                                            buckets[3 * rows.w + x])
                                          : rows.e[f][x]);
        ASSERT_EQ(p1[x], top) << x;
        fold_is_peak += top > rows.e[fold_f == 0 ? 1 : 0][x];
      }
      EXPECT_EQ(n1, finite);
      EXPECT_GT(finite, 0u);
      EXPECT_GT(fold_is_peak, rows.w / 4);  // the folded values take part in the argmax
      EXPECT_GT(c1, 0u);
      if (!sdk::cpu_has_avx2()) continue;  // the scalar half above still ran
      auto a2 = rows.args(ptr, &ft, f2.data(), d2.data(), p2.data(), v2.data(), &n2);
      a2.fold = buckets.data(), a2.fold_stride = rows.w, a2.fold_f = fold_f;
      EXPECT_EQ(detail::fbar_row_avx2(a2, 0, rows.w), c1);
      EXPECT_EQ(n1, n2);
      EXPECT_EQ(std::memcmp(f1.data(), f2.data(), rows.w * 4), 0) << F;
      EXPECT_EQ(std::memcmp(d1.data(), d2.data(), rows.w * 4), 0) << F;
      EXPECT_EQ(std::memcmp(p1.data(), p2.data(), rows.w * 4), 0) << F;
      EXPECT_EQ(v1, v2) << F;
    }
  }
}

// A sweep through the accumulator in `pixel_type` (8 or 16 bit): random
// Gaussian E(f) curves on a mean, and the hard cases, quantised to DN.
// `defer`: E3Accumulator::defer_final_fold (the multi-focal session's mode).
E3Accumulator make_sweep(uint32_t pixel_type, uint32_t w, uint32_t h, uint32_t F, bool defer = false) {
  const double full = pixel_type == PROCAM_PIXEL_U8 ? 255 : 65535;
  const size_t n = size_t{w} * h;
  std::vector<double> mean(n);
  std::vector<std::vector<double>> amp(F, std::vector<double>(n));
  Lcg rnd;
  for (size_t i = 0; i < n; ++i) {
    const double centre = -1 + (F + 1) * rnd(), width = 0.4 + 1.5 * rnd();
    mean[i] = full * (0.2 + 0.3 * rnd());
    const double height = mean[i] * rnd();
    for (uint32_t f = 0; f < F; ++f) amp[f][i] = height * std::exp(-0.5 * std::pow((f - centre) / width, 2));
    if (i % 11 == 0) amp[3][i] = amp[2][i];              // tie between two settings
    if (i % 17 == 0) for (auto& a : amp) a[i] = 0.1 * mean[i];  // flat
    if (i % 19 == 0) mean[i] = 0;                       // black: all-zero frames
    if (i % 29 == 0) mean[i] = full;                    // saturated in every frame
  }
  E3Accumulator acc(w, h, F, pixel_type, full, 2);
  acc.defer_final_fold(defer);
  std::vector<uint8_t> f8(n);
  std::vector<uint16_t> f16(n);
  for (uint32_t f = 0; f < F; ++f)
    for (uint32_t t = 0; t < kPeriodPx; ++t) {
      const double c = std::cos(2 * M_PI * kHarmonic * t / kPeriodPx);
      for (size_t i = 0; i < n; ++i) {
        const double v = std::clamp(std::round(mean[i] + (mean[i] > 0 ? amp[f][i] * c : 0)), 0.0, full);
        f8[i] = static_cast<uint8_t>(v);
        f16[i] = static_cast<uint16_t>(v);
      }
      const procam_image img = pixel_type == PROCAM_PIXEL_U8 ? sdk::gray_view(f8.data(), w, h, 8)
                                                             : sdk::gray_view(f16.data(), w, h, 16);
      EXPECT_TRUE(acc.add(f, t, img).ok());
    }
  return acc;
}

TEST(FbarDepthMap, AgreesWithThePerPixelReferenceOn8And16BitSweeps) {
  const auto table = tables()[1];  // x 0.4 .. 4.65, depth 600 .. 5928 mm, up to ~850 mm/index
  for (uint32_t type : {PROCAM_PIXEL_U8, PROCAM_PIXEL_U16}) {
    const uint32_t w = 203, h = 5, F = 6;
    const auto acc = make_sweep(type, w, h, F);
    Validity rule;
    rule.black_dn = 5;
    std::vector<float> fbar, depth, peak;
    const size_t valid = fbar_depth_map(acc, rule, &table, 2, fbar, &depth, &peak);
    size_t expect = 0, with_depth = 0;
    for (uint32_t y = 0; y < h; ++y)
      for (uint32_t x = 0; x < w; ++x) {
        const size_t i = size_t{y} * w + x;
        float e[F], top = 0;
        for (uint32_t f = 0; f < F; ++f) top = std::max(top, e[f] = acc.e3(f)[i]);
        EXPECT_EQ(peak[i], top) << i;
        const float ref = usable(acc, x, y, rule)
                              ? fbar_from_e3(e, F, static_cast<float>(rule.min_modulation) * acc.mean()[i])
                              : std::numeric_limits<float>::quiet_NaN();
        ASSERT_EQ(std::isnan(ref), std::isnan(fbar[i])) << i << " type " << type;
        if (std::isnan(ref)) {
          EXPECT_TRUE(std::isnan(depth[i])) << i;
          continue;
        }
        ++expect;
        EXPECT_NEAR(fbar[i], ref, 2e-5) << i;
        const float at_own = table.lookup(double(fbar[i])), at_ref = table.lookup(double(ref));
        ASSERT_EQ(std::isnan(at_own), std::isnan(depth[i])) << i;
        if (std::isnan(at_own)) continue;
        ++with_depth;
        EXPECT_NEAR(depth[i], at_own, 2e-6 * double(at_own)) << i;
        if (!std::isnan(at_ref)) {
          EXPECT_NEAR(depth[i], at_ref, 5e-4 * double(at_ref)) << i;  // 0.05 % of depth
        }
      }
    EXPECT_EQ(valid, expect);
    EXPECT_GT(expect, size_t{w} * h / 5);
    EXPECT_GT(with_depth, expect / 2);
    // The hard cases are invalid: black (i % 19) and saturated (i % 29) pixels.
    for (size_t i = 0; i < size_t{w} * h; i += 19) EXPECT_TRUE(std::isnan(fbar[i])) << i;
    for (size_t i = 0; i < size_t{w} * h; i += 29) EXPECT_TRUE(std::isnan(fbar[i])) << i;
  }
}

// The multi-focal session's mode: the last setting's fold deferred into the
// fbar pass gives bit for bit the maps of the ordinary fold (fbar, depth,
// peak, valid), and fold_pending() then gives the same E map. 16-bit frames
// do not defer (the fused fold reads int16 buckets only).
TEST(FbarDepthMap, DeferredLastFoldGivesTheSameBitsAsTheFold) {
  const auto table = tables()[1];
  const uint32_t w = 203, h = 5, F = 6;
  const size_t n = size_t{w} * h;
  auto plain = make_sweep(PROCAM_PIXEL_U8, w, h, F);
  auto deferred = make_sweep(PROCAM_PIXEL_U8, w, h, F, true);
  ASSERT_EQ(plain.pending_buckets().d, nullptr);
  ASSERT_NE(deferred.pending_buckets().d, nullptr);
  EXPECT_EQ(deferred.pending_buckets().focus, F - 1);
  Validity rule;
  std::vector<float> fb1, d1, p1, fb2, d2, p2;
  std::vector<uint8_t> v1, v2;
  size_t n1 = 0, n2 = 0;
  for (uint32_t threads : {1u, 2u}) {
    const size_t c1 = fbar_depth_map(plain, rule, &table, threads, fb1, &d1, &p1, &v1, &n1);
    const size_t c2 = fbar_depth_map(deferred, rule, &table, threads, fb2, &d2, &p2, &v2, &n2);
    EXPECT_EQ(c1, c2);
    EXPECT_GT(c1, n / 5);
    EXPECT_EQ(std::memcmp(fb1.data(), fb2.data(), n * 4), 0);
    EXPECT_EQ(std::memcmp(d1.data(), d2.data(), n * 4), 0);
    EXPECT_EQ(std::memcmp(p1.data(), p2.data(), n * 4), 0);
    EXPECT_EQ(v1, v2);
    EXPECT_EQ(n1, n2);
    // valid is valid_where_finite of depth.
    std::vector<uint8_t> ref;
    EXPECT_EQ(valid_where_finite(d1, nullptr, h, 1, ref), n1);
    EXPECT_EQ(ref, v1);
  }
  ASSERT_NE(deferred.pending_buckets().d, nullptr);  // the pass leaves it pending
  deferred.fold_pending();
  EXPECT_EQ(deferred.pending_buckets().d, nullptr);
  for (uint32_t f = 0; f < F; ++f) EXPECT_EQ(std::memcmp(plain.e3(f).data(), deferred.e3(f).data(), n * 4), 0) << f;
  const auto wide = make_sweep(PROCAM_PIXEL_U16, 16, 2, F, true);
  EXPECT_EQ(wide.pending_buckets().d, nullptr);
}

TEST(FbarDepthMap, TableWithoutAFloatGridFallsBackToTheDoubleLookup) {
  const auto table = tables()[4];
  const auto acc = make_sweep(PROCAM_PIXEL_U16, 64, 2, 6);
  Validity rule;
  std::vector<float> fbar, depth;
  std::vector<uint8_t> valid;
  size_t valid_count = 0;
  fbar_depth_map(acc, rule, &table, 1, fbar, &depth, nullptr, &valid, &valid_count);
  size_t checked = 0;
  for (size_t i = 0; i < fbar.size(); ++i) {
    const float ref = std::isnan(fbar[i]) ? fbar[i] : table.lookup(double(fbar[i]));
    ASSERT_EQ(std::isnan(ref), std::isnan(depth[i])) << i;
    ASSERT_EQ(valid[i], std::isnan(ref) ? 0 : 255) << i;
    if (!std::isnan(ref)) {
      EXPECT_NEAR(depth[i], ref, 1e-4) << i;
      ++checked;
    }
  }
  EXPECT_GT(checked, 0u);
  EXPECT_EQ(valid_count, checked);
}

}  // namespace
}  // namespace procam::defocus
