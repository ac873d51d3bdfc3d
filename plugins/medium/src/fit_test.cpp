// SPDX-License-Identifier: MIT
// The fast Eq. 4.2 profile and the fit against the independent brute-force
// reference (reference.hpp): recovery of sigma, beta, g within the thesis's
// §4.4 tolerances with noise at 0.03 of the mean (§5.4.1), a unique minimum
// from 20 random starts (§4.3.2), g -> 1 (§4.3.3), and beta = 0 (M5).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <random>
#include <vector>

#include "fit.hpp"
#include "reference.hpp"

namespace procam::medium {
namespace {

namespace ref = reference;

// Parameters in the range of the thesis's Table 4.1 (1/mm).
const ref::Medium kMilk = {0.010748, 0.010744, 0.902};      // lowfat milk, 16 ml, G
const ref::Medium kEspresso = {0.005115, 0.002828, 0.896};  // espresso, 8 ml, G: low-scattering
const ref::Medium kMocha = {0.0026, 0.001081, 0.907};       // mint mocha, 6 ml, G: low-scattering

FitSettings settings_for(const ref::Scene& sc) {
  FitSettings s;
  s.tank = {sc.depth_mm, sc.bulb_depth_mm};
  s.bulb_x_px = sc.bulb_x;
  s.bulb_y_px = sc.bulb_y;
  s.mm_per_px = sc.mm_per_px;
  s.mask_radius_px = 8;
  s.source_intensity = sc.i0;
  return s;
}

std::vector<float> to_float(const std::vector<double>& v) { return {v.begin(), v.end()}; }

FitResult fit_image(const ref::Medium& m, const ref::Scene& sc, const FitSettings& s, double noise, uint32_t seed = 1) {
  std::vector<double> e = ref::image(m, sc);
  if (noise > 0) ref::add_noise(e, sc, noise, s.mask_radius_px, seed);
  const std::vector<float> f = to_float(e);
  const RadialProfile p = radial_profile(f, sc.width, sc.height, s);
  return fit_profile(p, s, f, sc.width, sc.height);
}

double rel(double a, double b) { return std::abs(a - b) / std::abs(b); }

TEST(ProfileModel, MatchesBruteForceEq42) {
  const double rhos[] = {2.0, 12.0, 40.0, 120.0, 290.0};
  for (const ref::Medium& m : {kMilk, kEspresso, ref::Medium{0.02, 0.015, 0.3}, ref::Medium{0.01, 0.01, -0.4},
                               ref::Medium{0.008, 0.006, 0.97}, ref::Medium{0.008, 0.006, 0.99}}) {
    ProfileModel model({300, 150}, {std::begin(rhos), std::end(rhos)});
    std::vector<double> k;
    model.evaluate(m.sigma, m.g, Phase::henyey_greenstein, 99, k);
    for (size_t i = 0; i < k.size(); ++i) {
      const double want = ref::eq_4_2(m, rhos[i], 300, 150, 20000) / m.beta;
      EXPECT_LT(rel(k[i], want), m.g > 0.95 ? 2e-4 : 2e-5) << "g " << m.g << " rho " << rhos[i];
    }
  }
  // The truncated Legendre series (M5) on the finer panels the fit uses for
  // it (<= 0.02 rad: the series oscillates with period ~0.06 rad).
  const ref::Medium lg{0.008, 0.006, 0.97, 99};
  ProfileModel fine({300, 150}, {std::begin(rhos), std::end(rhos)}, 0.02);
  std::vector<double> kl;
  fine.evaluate(lg.sigma, lg.g, Phase::truncated_legendre, 99, kl);
  for (size_t i = 0; i < kl.size(); ++i)
    EXPECT_LT(rel(kl[i], ref::eq_4_2(lg, rhos[i], 300, 150, 20000) / lg.beta), 2e-3) << "Legendre rho " << rhos[i];
  // Off-centre bulb (B != D / 2) too.
  ProfileModel model({250, 60}, {30.0});
  std::vector<double> k;
  model.evaluate(kMilk.sigma, kMilk.g, Phase::henyey_greenstein, 99, k);
  EXPECT_LT(rel(k[0], ref::eq_4_2(kMilk, 30, 250, 60, 20000) / kMilk.beta), 2e-5);
}

// The bulb as a 10 mm Lambertian sphere (thesis §4.3.3) against the brute
// force over its surface: within 0.5 % from 2 radii out (H-G, g up to 0.97),
// and the point model is clearly different near the forward lobe (why the
// sphere matters: a point model fits g too high on the sim's tank).
TEST(ProfileModel, SphereBulbMatchesBruteForceOverItsSurface) {
  const double rhos[] = {20.0, 35.0, 80.0, 200.0};
  for (const ref::Medium& m : {kMilk, kEspresso, ref::Medium{0.008, 0.006, 0.97}, ref::Medium{0.02, 0.015, 0.3}}) {
    ProfileModel sphere({300, 150, 10.0}, {std::begin(rhos), std::end(rhos)});
    ProfileModel point({300, 150, 0.0}, {std::begin(rhos), std::end(rhos)});
    std::vector<double> ks, kp;
    sphere.evaluate(m.sigma, m.g, Phase::henyey_greenstein, 99, ks);
    point.evaluate(m.sigma, m.g, Phase::henyey_greenstein, 99, kp);
    for (size_t i = 0; i < ks.size(); ++i) {
      const double want = ref::eq_4_2_sphere(m, rhos[i], 300, 150, 10.0) / m.beta;
      EXPECT_LT(rel(ks[i], want), 5e-3) << "g " << m.g << " rho " << rhos[i];
      std::printf("g %.2f rho %5.0f: sphere model %+.3f %%, point model %+.3f %% vs the brute-force sphere\n", m.g,
                  rhos[i], 100 * (ks[i] / want - 1), 100 * (kp[i] / want - 1));
    }
  }
  // A tiny sphere (r = 0.01 mm) is the point source.
  ProfileModel tiny({300, 150, 0.01}, {30.0, 120.0});
  ProfileModel point({300, 150, 0.0}, {30.0, 120.0});
  std::vector<double> kt, kp;
  tiny.evaluate(kMilk.sigma, kMilk.g, Phase::henyey_greenstein, 99, kt);
  point.evaluate(kMilk.sigma, kMilk.g, Phase::henyey_greenstein, 99, kp);
  for (size_t i = 0; i < kt.size(); ++i) EXPECT_LT(rel(kt[i], kp[i]), 1e-4);  // paths differ by ~r: sigma r ~ 1e-4
}

// Beyond 4 radii and 1.2 rad the model takes one direction per node; the
// phase function's curvature over the cap (p + <sin^2 psi>/4 Lap p) must
// stay in: without it the model was ~0.1 % low at 50-250 mm for lowfat
// chocolate milk (g = 0.927), and the fitted kappa = sigma - beta (0.3 % of
// sigma) came out 170 % off on the sim's noise-free tank image (issue 14).
TEST(ProfileModel, SphereBulbKeepsThePhaseCurvatureFarFromTheBulb) {
  const ref::Medium choc{0.005371, 0.005354, 0.927};
  const double rhos[] = {50.0, 100.0, 170.0, 250.0};
  for (const ref::Medium& m : {choc, ref::Medium{0.008, 0.006, 0.97}}) {
    ProfileModel sphere({300, 150, 10.0}, {std::begin(rhos), std::end(rhos)});
    std::vector<double> ks;
    sphere.evaluate(m.sigma, m.g, Phase::henyey_greenstein, 99, ks);
    for (size_t i = 0; i < ks.size(); ++i) {
      const double want = ref::eq_4_2_sphere(m, rhos[i], 300, 150, 10.0, 800, 60) / m.beta;
      EXPECT_LT(rel(ks[i], want), 3e-4) << "g " << m.g << " rho " << rhos[i] << ": " << 100 * (ks[i] / want - 1) << " %";
    }
  }
}

TEST(Phase, LegendreTendsToHgAndIsNormalised) {
  // sum_i (2i+1) g^i P_i(x) / 4pi converges to H-G for |g| < 1 (thesis §4.3.3).
  for (double x : {-0.9, -0.2, 0.3, 0.8})
    EXPECT_LT(rel(legendre_phase(0.6, x, 99), hg_phase(0.6, x)), 1e-12) << x;
  // Normalisation over the sphere: 2 pi ∫ P d(cos) = 1 for both, any g.
  for (double g : {0.5, 0.97}) {
    double hg = 0, lg = 0;
    const int n = 200000;
    for (int i = 0; i < n; ++i) {
      const double x = -1 + (i + 0.5) * 2.0 / n;
      hg += hg_phase(g, x) * 2.0 / n;
      lg += legendre_phase(g, x, 99) * 2.0 / n;
    }
    EXPECT_NEAR(2 * std::numbers::pi * hg, 1.0, 1e-3) << g;
    EXPECT_NEAR(2 * std::numbers::pi * lg, 1.0, 2e-5) << g;  // exactly 1 (only P_0 integrates); midpoint error
  }
}

TEST(Fit, NoiselessRecoversParametersExactly) {
  const ref::Scene sc;
  const FitSettings s = settings_for(sc);
  const FitResult r = fit_image(kMilk, sc, s, 0.0);
  ASSERT_TRUE(r.error.empty()) << r.error;
  EXPECT_EQ(r.model, "henyey_greenstein");
  EXPECT_LT(rel(r.sigma.value, kMilk.sigma), 2e-3);
  EXPECT_LT(rel(r.beta.value, kMilk.beta), 2e-3);
  EXPECT_NEAR(r.g.value, kMilk.g, 2e-3);
  EXPECT_LT(r.rms_percent, 0.2);
}

// §4.4: within 3 % (sigma, beta) for highly scattering media, 6 % for
// low-scattering ones, fit RMS < 3 % / < 6 %, with noise at 0.03 of the mean.
TEST(Fit, RecoversTable41MediaWithNoise) {
  struct Case {
    const char* name;
    ref::Medium m;
    double tol;
  };
  const ref::Scene sc;
  for (const Case& c : {Case{"lowfat milk", kMilk, 0.03}, Case{"espresso", kEspresso, 0.06}, Case{"mint mocha", kMocha, 0.06}}) {
    for (Objective obj : {Objective::normalized, Objective::profiled}) {
      FitSettings s = settings_for(sc);
      s.objective = obj;
      const FitResult r = fit_image(c.m, sc, s, 0.03, 7);
      ASSERT_TRUE(r.error.empty()) << r.error;
      SCOPED_TRACE(std::string(c.name) + (obj == Objective::normalized ? " normalized" : " profiled"));
      std::printf("%-11s %-10s sigma %+.2f %%  beta %+.2f %%  g %.4f (true %.3f)  rms %.2f %%  ci95(sigma) %.2f %%\n", c.name,
                  obj == Objective::normalized ? "normalized" : "profiled", 100 * (r.sigma.value / c.m.sigma - 1),
                  100 * (r.beta.value / c.m.beta - 1), r.g.value, c.m.g, r.rms_percent, 100 * r.sigma.ci95 / c.m.sigma);
      EXPECT_EQ(r.model, "henyey_greenstein");
      EXPECT_LT(rel(r.sigma.value, c.m.sigma), c.tol) << r.sigma.value;
      EXPECT_LT(rel(r.beta.value, c.m.beta), c.tol) << r.beta.value;
      EXPECT_NEAR(r.g.value, c.m.g, 0.03);
      EXPECT_LT(r.rms_percent, c.tol * 100);
      // The 95 % intervals are finite, informative and cover the truth (with
      // some slack for the model's own discretisation bias).
      EXPECT_TRUE(std::isfinite(r.sigma.ci95) && r.sigma.ci95 > 0);
      EXPECT_LT(r.sigma.ci95, 0.02 * c.m.sigma);
      EXPECT_LT(std::abs(r.beta.value - c.m.beta), 3 * r.beta.ci95 + 0.002 * c.m.beta);
      EXPECT_LT(std::abs(r.sigma.value - c.m.sigma), 3 * r.sigma.ci95 + 0.002 * c.m.sigma);
      EXPECT_TRUE(r.g_defined);
    }
  }
}

// §4.3.2: random starts. The thesis finds one minimum. Here: 20 random
// starts over the forward-scattering range (g in [0.3, 0.98]; every medium
// of Table 4.1 has g >= 0.5) all reach the same minimum. Over the whole range
// (g in [-0.5, 0.98]) the tank with the bulb at mid-depth is nearly
// symmetric front to back, and starts at large sigma or negative g can stop
// in one of two backscattering valleys (g < 0) whose objective is > 100x
// worse: every start either reaches THE minimum or ends there, and the fit's
// grid start never picks them.
TEST(Fit, TwentyRandomStartsFindOneMinimum) {
  const ref::Scene sc;
  const FitSettings s = settings_for(sc);
  std::vector<double> e = ref::image(kEspresso, sc);
  ref::add_noise(e, sc, 0.03, s.mask_radius_px, 3);
  const std::vector<float> f = to_float(e);
  const RadialProfile p = radial_profile(f, sc.width, sc.height, s);
  const FitResult fit = fit_profile(p, s, f, sc.width, sc.height);
  EXPECT_LT(rel(fit.sigma.value, kEspresso.sigma), 0.06);
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> ls(std::log(5e-4), std::log(0.05)), forward(0.3, 0.98), any(-0.5, 0.98);
  for (int i = 0; i < 20; ++i) {
    const double s0 = std::exp(ls(rng)), g0 = forward(rng);
    const Minimum m = minimise_from(p, s, Phase::henyey_greenstein, s0, g0);
    EXPECT_LT(rel(m.sigma, fit.sigma.value), 1e-3) << "start " << s0 << ", " << g0;
    EXPECT_NEAR(m.g, fit.g.value, 1e-3) << "start " << s0 << ", " << g0;
    EXPECT_LT(m.evaluations, 500);
  }
  int same = 0;
  for (int i = 0; i < 20; ++i) {
    const double s0 = std::exp(ls(rng)), g0 = any(rng);
    const Minimum m = minimise_from(p, s, Phase::henyey_greenstein, s0, g0);
    if (rel(m.sigma, fit.sigma.value) < 1e-3 && std::abs(m.g - fit.g.value) < 1e-3) {
      ++same;
      continue;
    }
    EXPECT_LT(m.g, 0.0) << "start " << s0 << ", " << g0 << " -> " << m.sigma << ", " << m.g;
    EXPECT_GT(m.objective, 100 * fit.objective) << "start " << s0 << ", " << g0;
  }
  std::printf("starts with g in [-0.5, 0.98] reaching the minimum: %d of 20\n", same);
  EXPECT_GE(same, 10);
}

// M5, §4.3.3: g -> 1. On an H-G medium the truncated Legendre refit is tried
// and rejected (its tail rings); on a medium whose phase function is the
// truncated series it is chosen. Either way sigma and beta come back.
TEST(Fit, ForwardScatteringTriesTruncatedLegendre) {
  const ref::Scene sc;
  for (double g : {0.97, 0.99}) {
    for (int terms : {0, 99}) {
      if (g > 0.98 && terms > 0) continue;  // that series is negative over wide angles: no physical medium
      const ref::Medium m{0.008, 0.006, g, terms};
      const FitResult r = fit_image(m, sc, settings_for(sc), 0.03, 5);
      ASSERT_TRUE(r.error.empty()) << r.error;
      SCOPED_TRACE("g " + std::to_string(g) + " terms " + std::to_string(terms));
      std::printf("g %.2f %-11s -> %-18s sigma %+.2f %%  beta %+.2f %%  g %.4f  rms %.2f %%\n", g,
                  terms == 0 ? "H-G" : "Legendre-99", r.model.c_str(), 100 * (r.sigma.value / m.sigma - 1),
                  100 * (r.beta.value / m.beta - 1), r.g.value, r.rms_percent);
      EXPECT_EQ(r.model, terms == 0 ? "henyey_greenstein" : "truncated_legendre") << r.model_reason;
      EXPECT_TRUE(std::isfinite(r.legendre_objective));
      EXPECT_GT(r.g.value, 0.95);
      EXPECT_LT(rel(r.sigma.value, m.sigma), 0.06) << r.sigma.value;
      EXPECT_LT(rel(r.beta.value, m.beta), 0.06) << r.beta.value;
      EXPECT_LT(r.rms_percent, 6.0);
    }
  }
}

// M5: beta = 0. The image is the bulb alone (its direct radiance W e^{-sigma l})
// plus noise; sigma = kappa by attenuation, g undefined.
TEST(Fit, PureAbsorberSigmaFromAttenuation) {
  ref::Scene sc;
  FitSettings s = settings_for(sc);
  s.bulb_radius_mm = 15;
  s.water_radiance = 40.0;
  s.source_intensity = 0;
  const double sigma = 0.0076;  // Merlot-like (Table 4.1, R)
  std::vector<double> e(size_t{sc.width} * sc.height, 0.0);
  for (uint32_t y = 0; y < sc.height; ++y)
    for (uint32_t x = 0; x < sc.width; ++x) {
      const double smm = std::hypot(double(x) - sc.bulb_x, double(y) - sc.bulb_y) * sc.mm_per_px;
      if (smm < s.bulb_radius_mm)  // the bulb's front surface at depth B - sqrt(R^2 - s^2)
        e[size_t{y} * sc.width + x] =
            s.water_radiance * std::exp(-sigma * (sc.bulb_depth_mm - std::sqrt(225.0 - smm * smm)));
    }
  ref::add_noise(e, sc, 0.0, s.mask_radius_px, 1);
  std::mt19937 rng(2);
  std::normal_distribution<double> n(0, 1e-4);
  for (double& v : e) v += n(rng);
  const std::vector<float> f = to_float(e);
  const FitResult r = fit_profile(radial_profile(f, sc.width, sc.height, s), s, f, sc.width, sc.height);
  ASSERT_TRUE(r.error.empty()) << r.error;
  EXPECT_EQ(r.model, "pure_absorber") << r.model_reason;
  EXPECT_FALSE(r.g_defined);
  EXPECT_TRUE(std::isnan(r.g.value));
  EXPECT_EQ(r.beta.value, 0.0);
  EXPECT_LT(rel(r.sigma.value, sigma), 0.03) << r.sigma.value;
  EXPECT_EQ(r.kappa.value, r.sigma.value);
  const std::vector<float> model = model_image(r, s, sc.width, sc.height);
  for (size_t i = 0; i < model.size(); ++i) {
    if (std::hypot(double(i % sc.width) - sc.bulb_x, double(i / sc.width) - sc.bulb_y) >= s.mask_radius_px) {
      ASSERT_EQ(model[i], 0.0f) << i;
    }
  }
}

// Noise weighting (Weights::noise). Multiplicative noise of 0.03 per pixel
// (what an HDR merge of a geometric bracket gives where the long exposures
// saturate) and a 6 mm mask (4 px): with uniform weights the few bright,
// absolutely noisiest pixels next to the bulb dominate the fit. Weighting by
// the stated noise model (noise_relative = 0.03) must lower the sigma and beta
// errors of both objectives, averaged over seeds (one seed could be lucky
// either way). With the profiled objective the weighted fit is inside the
// thesis's 3 % for this highly scattering medium at every seed; the
// normalized one (Eq. 4.6-4.7) divides by max E, the mean of one small bin
// next to the mask, whose noise (~0.6 % here) the weights cannot remove: it
// stays a few percent biased (measured -1 ... -4.5 %), so 6 % there.
TEST(Fit, NoiseWeightsBeatUniformUnderMultiplicativeNoise) {
  const ref::Scene sc;
  const std::vector<double> clean = ref::image(kMilk, sc);
  const int seeds = 3;
  for (Objective obj : {Objective::profiled, Objective::normalized}) {
    const char* name = obj == Objective::profiled ? "profiled" : "normalized";
    const double tol = obj == Objective::profiled ? 0.03 : 0.06;
    double err[2][2] = {{0, 0}, {0, 0}};  // [uniform, noise][sigma, beta]: mean |relative error|
    for (int seed = 1; seed <= seeds; ++seed) {
      std::vector<double> e = clean;
      std::mt19937 rng(static_cast<uint32_t>(100 + seed));
      std::normal_distribution<double> n01(0.0, 1.0);
      for (double& v : e) v *= 1.0 + 0.03 * n01(rng);
      const std::vector<float> f = to_float(e);
      for (int wi = 0; wi < 2; ++wi) {
        FitSettings s = settings_for(sc);
        s.mask_radius_px = 4;  // 6 mm at 1.5 mm/px
        s.objective = obj;
        s.weights = wi == 0 ? Weights::uniform : Weights::noise;
        s.noise_relative = 0.03;
        const FitResult r = fit_profile(radial_profile(f, sc.width, sc.height, s), s, f, sc.width, sc.height);
        ASSERT_TRUE(r.error.empty()) << r.error;
        std::printf("%-10s seed %d %-7s sigma %+.2f %%  beta %+.2f %%  g %.4f  rms(Eq. 4.6) %.2f %%\n", name, seed,
                    wi == 0 ? "uniform" : "noise", 100 * (r.sigma.value / kMilk.sigma - 1),
                    100 * (r.beta.value / kMilk.beta - 1), r.g.value, r.rms_normalized_percent);
        err[wi][0] += rel(r.sigma.value, kMilk.sigma) / seeds;
        err[wi][1] += rel(r.beta.value, kMilk.beta) / seeds;
        if (wi == 1) {
          EXPECT_LT(rel(r.sigma.value, kMilk.sigma), tol) << name << " seed " << seed;
          EXPECT_LT(rel(r.beta.value, kMilk.beta), tol) << name << " seed " << seed;
          EXPECT_NEAR(r.g.value, kMilk.g, 0.01) << name << " seed " << seed;
        }
      }
    }
    std::printf("%s: mean |error| uniform: sigma %.2f %% beta %.2f %%; noise-weighted: sigma %.2f %% beta %.2f %%\n",
                name, 100 * err[0][0], 100 * err[0][1], 100 * err[1][0], 100 * err[1][1]);
    EXPECT_LT(err[1][0], 0.5 * err[0][0]) << name;  // at least halved (measured: 5-10x)
    EXPECT_LT(err[1][1], 0.5 * err[0][1]) << name;
  }
}

// Issue 14, Deliver 2 (`measure`: "the parameters per channel with
// confidence intervals"): the reported 95 % intervals must cover the truth
// at the stated rate under camera-like noise, for the default objective
// (Eq. 4.6-4.7: E / max E, max E the mean of the small ring next to the
// mask, itself noisy) as for the others. Noise per pixel: 3 % multiplicative
// (an HDR merge near full well, fit.hpp Weights) plus a floor of 1e-3 of the
// image's peak; on the brute-force reference image of lowfat milk, 30
// seeds for the default fit and 15 for profiled + noise weights (~0.13 s CPU a
// fit). Stated before running: each of sigma and beta covered in >= 25 of
// 30 (>= 12 of 15) seeds (honest 95 % intervals miss more often with
// probability 0.33 % (0.55 %); the intervals before this test covered ~1 in
// 5 on the camera, brief k14), and the intervals
// are not wide for nothing: the median half-width lies within 1.2 ... 3.2
// times the seeds' own standard deviation of the estimate (1.96 if exact).
TEST(Fit, IntervalsCoverTheTruthUnderCameraNoise) {
  const ref::Scene sc;
  const std::vector<double> clean = ref::image(kMilk, sc);
  double peak = 0;
  for (size_t i = 0; i < clean.size(); ++i)
    if (std::hypot(double(i % sc.width) - sc.bulb_x, double(i / sc.width) - sc.bulb_y) >= 8) peak = std::max(peak, clean[i]);
  struct Variant {
    const char* name;
    Objective obj;
    Weights wts;
    int seeds, min_covered;
  };
  for (const Variant& v : {Variant{"normalized, uniform (default)", Objective::normalized, Weights::uniform, 30, 25},
                           Variant{"profiled, noise weights", Objective::profiled, Weights::noise, 15, 12}}) {
    const int kSeeds = v.seeds, kMinCovered = v.min_covered;
    SCOPED_TRACE(v.name);
    FitSettings s = settings_for(sc);
    s.objective = v.obj;
    s.weights = v.wts;
    int covered[2] = {0, 0};
    std::vector<double> est[2], half[2];
    for (int seed = 1; seed <= kSeeds; ++seed) {
      std::vector<double> e = clean;
      std::mt19937 rng(static_cast<uint32_t>(1400 + seed));
      std::normal_distribution<double> n01(0.0, 1.0);
      for (double& x : e) x = x * (1.0 + 0.03 * n01(rng)) + 1e-3 * peak * n01(rng);
      const std::vector<float> f = to_float(e);
      const FitResult r = fit_profile(radial_profile(f, sc.width, sc.height, s), s, f, sc.width, sc.height);
      ASSERT_TRUE(r.error.empty()) << r.error;
      ASSERT_EQ(r.model, "henyey_greenstein") << "seed " << seed;
      const Estimate* q[2] = {&r.sigma, &r.beta};
      const double truth[2] = {kMilk.sigma, kMilk.beta};
      for (int k = 0; k < 2; ++k) {
        ASSERT_TRUE(std::isfinite(q[k]->ci95) && q[k]->ci95 > 0) << "seed " << seed;
        covered[k] += std::abs(q[k]->value - truth[k]) <= q[k]->ci95;
        est[k].push_back(q[k]->value);
        half[k].push_back(q[k]->ci95);
      }
    }
    for (int k = 0; k < 2; ++k) {
      double m = 0, v2 = 0;
      for (double x : est[k]) m += x / kSeeds;
      for (double x : est[k]) v2 += (x - m) * (x - m) / (kSeeds - 1);
      const double sd = std::sqrt(v2), truth = k == 0 ? kMilk.sigma : kMilk.beta;
      std::sort(half[k].begin(), half[k].end());
      const size_t hm = half[k].size() / 2;
      const double med = half[k].size() % 2 == 1 ? half[k][hm] : 0.5 * (half[k][hm - 1] + half[k][hm]);
      std::printf("%-30s %-5s covered %d / %d  mean error %+.3f %% (SD %.3f %%)  median ci95 %.3f %% = %.2f SD\n", v.name,
                  k == 0 ? "sigma" : "beta", covered[k], kSeeds, 100 * (m / truth - 1), 100 * sd / truth,
                  100 * med / truth, med / sd);
      EXPECT_GE(covered[k], kMinCovered) << (k == 0 ? "sigma" : "beta");
      EXPECT_GT(med, 1.2 * sd) << (k == 0 ? "sigma" : "beta");
      EXPECT_LT(med, 3.2 * sd) << (k == 0 ? "sigma" : "beta");
    }
  }
}

TEST(Fit, ReportsWhatIsMissing) {
  const ref::Scene sc;
  FitSettings s = settings_for(sc);
  s.mask_radius_px = 1000;  // masks everything
  const std::vector<float> f(size_t{sc.width} * sc.height, 1.0f);
  const FitResult r = fit_profile(radial_profile(f, sc.width, sc.height, s), s, f, sc.width, sc.height);
  EXPECT_NE(r.error.find("usable pixels"), std::string::npos) << r.error;
}

}  // namespace
}  // namespace procam::medium
