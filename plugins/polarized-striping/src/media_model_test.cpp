// SPDX-License-Identifier: MIT
// The estimators of media_model.hpp against closed forms: Eq. 5.4–5.6 with
// known S, B, p (and their guards at p -> 0 and p -> 1), the DOP estimate on
// maps built from Eq. 5.4–5.5, and Eq. 5.8–5.10 evaluated by hand.
#include "media_model.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

namespace procam::polarized_striping {
namespace {

// Eq. 5.4–5.5 written out here, independently of the code under test.
float best_of(double s, double b, double p) { return float(s / 2 + b * (1 - p) / 2); }
float worst_of(double s, double b, double p) { return float(s / 2 + b * (1 + p) / 2); }

TEST(SignalFromPolarized, RecoversSignalAndBackscatterExactly) {
  for (double p : {0.1, 0.5, 0.8, 1.0})
    for (double s : {0.0, 10.0, 200.0})
      for (double b : {0.0, 30.0, 500.0}) {
        const SignalBackscatter r = signal_from_polarized(best_of(s, b, p), worst_of(s, b, p), p);
        EXPECT_NEAR(r.signal, s, 1e-3 * (1 + s + b)) << p << " " << s << " " << b;
        EXPECT_NEAR(r.backscatter, b, 1e-3 * (1 + s + b)) << p << " " << s << " " << b;
      }
}

// p -> 1: Eq. 5.6 is regular, S^ = 2 E_b. p -> 0: the caller does not apply
// it (p_min), but even a tiny p must give finite values within [0, E_b + E_w].
TEST(SignalFromPolarized, GuardsAtBothEndsOfP) {
  const SignalBackscatter one = signal_from_polarized(50.0f, 90.0f, 1.0);
  EXPECT_FLOAT_EQ(one.signal, 100.0f);
  EXPECT_FLOAT_EQ(one.backscatter, 40.0f);
  for (double p : {1e-9, 1e-3}) {
    const SignalBackscatter r = signal_from_polarized(50.0f, 51.0f, p);  // noise: E_w - E_b = 1
    EXPECT_TRUE(std::isfinite(r.signal) && std::isfinite(r.backscatter));
    EXPECT_GE(r.signal, 0.0f);
    EXPECT_LE(r.backscatter, 101.0f);
    EXPECT_FLOAT_EQ(r.signal + r.backscatter, 101.0f);
  }
  // Noise can put E_w below E_b: B^ clamps to 0, S^ to the total.
  const SignalBackscatter neg = signal_from_polarized(60.0f, 58.0f, 0.5);
  EXPECT_FLOAT_EQ(neg.backscatter, 0.0f);
  EXPECT_FLOAT_EQ(neg.signal, 118.0f);
}

// A quarter of the pixels see medium only (S = 0): the 0.9 quantile of
// (E_w - E_b) / (E_w + E_b) is p within the noise; object pixels alone would
// give less (r = B p / (S + B)).
TEST(EstimateDop, FromMediumOnlyPixelsWithNoise) {
  std::mt19937 rng(7);
  std::normal_distribution<double> noise(0.0, 0.5);  // DN
  for (double p : {0.3, 0.8, 0.98}) {
    std::vector<float> eb, ew;
    for (int i = 0; i < 4000; ++i) {
      const double b = 60 + 0.01 * i, s = i % 4 == 0 ? 0.0 : 40 + (i % 7) * 10;
      eb.push_back(best_of(s, b, p) + float(noise(rng)));
      ew.push_back(worst_of(s, b, p) + float(noise(rng)));
    }
    const double est = estimate_dop(eb, ew, 20.0, 0.9);
    EXPECT_NEAR(est, p, 0.02) << p;  // r noise ~ sqrt(2) 0.5 / 60 = 0.012
  }
  // Nothing bright enough: NaN, the caller says why.
  std::vector<float> dark(100, 1.0f);
  EXPECT_TRUE(std::isnan(estimate_dop(dark, dark, 20.0, 0.9)));
}

TEST(Quantile, InterpolatesAndSkipsNaN) {
  EXPECT_DOUBLE_EQ(quantile({4, 1, 3, 2, kNaN}, 0.5), 2.5);
  EXPECT_DOUBLE_EQ(quantile({4, 1, 3, 2}, 0.0), 1.0);
  EXPECT_DOUBLE_EQ(quantile({4, 1, 3, 2}, 1.0), 4.0);
  EXPECT_TRUE(std::isnan(quantile({kNaN}, 0.5)));
}

// Large inputs take the radix selection: same values as a full sort (truth:
// std::sort, independent of the code under test), with negatives, ties,
// signed zeros, NaN to skip.
TEST(Quantile, LargeInputsMatchASortedCopy) {
  std::mt19937 rng(3);
  for (int trial = 0; trial < 4; ++trial) {
    std::vector<float> v(20000 + size_t(trial) * 7777);
    for (float& x : v) {
      const auto r = static_cast<uint32_t>(rng() % 10);
      x = r == 0 ? 0.0f : r == 1 ? -0.0f : r == 2 ? kNaN : r < 5 ? float(int(rng() % 9) - 4) : float(rng() % 100000) * 1e-3f - 50.0f;
    }
    std::vector<float> sorted;
    for (float x : v)
      if (std::isfinite(x)) sorted.push_back(x);
    std::sort(sorted.begin(), sorted.end());
    for (double q : {0.0, 0.02, 0.5, 0.9, 0.9999, 1.0}) {
      const double pos = q * double(sorted.size() - 1);
      const auto lo = static_cast<size_t>(std::floor(pos));
      const double hi = lo + 1 < sorted.size() ? double(sorted[lo + 1]) : double(sorted[lo]);
      const double truth = double(sorted[lo]) + (pos - double(lo)) * (hi - double(sorted[lo]));
      EXPECT_EQ(quantile(v, q), truth) << "trial " << trial << " q " << q;
    }
  }
}

TEST(QualityMeasures, Eq5_8To5_10ByHand) {
  // CQM = S / (S + B (1 - p)): S = 30, B = 60, p = 0.5 -> 30 / 60.
  EXPECT_DOUBLE_EQ(cqm(30, 60, 0.5), 0.5);
  EXPECT_DOUBLE_EQ(cqm(30, 60, 0.0), 30.0 / 90.0);
  EXPECT_DOUBLE_EQ(cqm(0, 0, 0.0), 0.0);  // zero denominator: no contrast, not NaN
  // GQM = (D + B (1 - p)) / (D + A + B (1 - p)): D = 10, A = 5, B = 40, p = 0.75 -> 20 / 25.
  EXPECT_DOUBLE_EQ(gqm(10, 5, 40, 0.75), 0.8);
  EXPECT_DOUBLE_EQ(gqm(0, 0, 0, 0.0), 0.0);
  // W = 1 / (1 + exp(-(S - mu) / z)).
  EXPECT_DOUBLE_EQ(snr_weight(3, 3, 1), 0.5);
  EXPECT_NEAR(snr_weight(5, 3, 1), 1.0 / (1.0 + std::exp(-2.0)), 1e-15);
  EXPECT_DOUBLE_EQ(snr_weight(5, 3, 0), 1.0);
  EXPECT_DOUBLE_EQ(snr_weight(1, 3, 0), 0.0);
}

TEST(Summarize, MeanAndRmsContrastOverFinitePixels) {
  const std::vector<float> m = {10, 30, kNaN, 10, 30};
  const Summary s = summarize(m);
  EXPECT_EQ(s.pixels, 4u);
  EXPECT_DOUBLE_EQ(s.mean, 20.0);
  EXPECT_DOUBLE_EQ(s.rms_contrast, 0.5);  // std 10 / mean 20
  EXPECT_EQ(summarize(std::vector<float>{kNaN}).pixels, 0u);
}

}  // namespace
}  // namespace procam::polarized_striping
