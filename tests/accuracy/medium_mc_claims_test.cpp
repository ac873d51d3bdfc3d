// SPDX-License-Identifier: MIT
// Thesis ch. 4 claims (issue 14) on multiple-scattering data: the sim's Monte
// Carlo reference of the dilution tank (hw/sim tank_mc.cpp, all orders of
// scattering) as the "photograph", the `medium` plugin's analysis on it;
// and Fig. 4.11 (fit at 8 ml, Eq. 4.8, Monte Carlo at 50-150 ml) as stated.
//
// Fig. 4.7: sigma-hat from the bulb's attenuation (Eq. 4.3) stays linear in
// the volume for an absorber (Merlot) and departs from the line for milk,
// where forward-scattered light adds to the bulb's direct image. The bulb's
// central pixels are synthesised as the Monte Carlo gives them: the direct,
// attenuated bulb L e^{-sigma l} (exact) plus the light scattered into the
// line of sight in front of the bulb (Monte Carlo, every order); then the
// plugin's own sigma_from_attenuation() (Eq. 4.3) and analyse_dilutions()
// (linearity test, stop rule), as the `concentration` method runs them.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <functional>
#include <map>
#include <string>
#include <vector>

#include "concentration.hpp"
#include "fit.hpp"
#include "procam/hw/sim/medium_library.hpp"
#include "tank.hpp"

namespace procam {
namespace {

// The shipped tank (configs/scenes/tank-*.json): 300 x 250 x 300 mm, a 10 mm
// bulb 20 mm from the left wall at mid height and mid depth.
sim::Medium tank_medium(const std::string& material, double volume_ml, sim::ColorChannel channel) {
  auto m = sim::material_medium(material, volume_ml, 23.0, channel);
  EXPECT_TRUE(m.ok()) << m.status().to_string();
  sim::Medium out = m.ok() ? *m : sim::Medium{};
  out.whole_scene = false;
  out.box_min_mm = {-150, -125, 5000};
  out.box_max_mm = {150, 125, 5300};
  sim::Medium::Bulb b;
  b.center_mm = {-130, 0, 5150};
  b.radius_mm = 10;
  b.irradiance_at_1m = 5e-4;
  out.bulb = b;
  return out;
}

// The bulb's central pixels (1.25 mm per pixel, bulb centre at pixel (8, 8))
// by the Monte Carlo: direct L e^{-sigma l(s)} plus scattered light at
// lateral offset s, every order (one Monte Carlo run per distinct offset).
struct BulbImage {
  std::vector<float> radiance;
  medium::FitSettings settings;
};
constexpr uint32_t kSide = 17;
BulbImage bulb_image(const sim::Medium& m, size_t paths, uint64_t seed) {
  BulbImage im;
  medium::FitSettings& s = im.settings;
  s.tank = {300, 150, 10};
  s.bulb_x_px = 8;
  s.bulb_y_px = 8;
  s.mm_per_px = 1.25;
  s.bulb_radius_mm = 10;
  im.radiance.assign(size_t{kSide} * kSide, 0.0f);
  std::map<int, double> scattered;  // by squared pixel offset
  const double radiance = m.bulb->radiance(), b = 150, r = 10;
  for (uint32_t y = 0; y < kSide; ++y)
    for (uint32_t x = 0; x < kSide; ++x) {
      const int dx = int(x) - 8, dy = int(y) - 8, r2 = dx * dx + dy * dy;
      const double smm = std::sqrt(double(r2)) * s.mm_per_px;
      if (smm > 0.5 * r) continue;  // the plugin reads the pixels within R/2
      auto it = scattered.find(r2);
      if (it == scattered.end()) {
        const sim::TankMonteCarlo mc =
            sim::tank_monte_carlo(m, m.bulb->center_mm.x + smm, m.bulb->center_mm.y, paths, seed + uint64_t(r2),
                                  1 << 20, sim::TankMcOptions{4, true});
        it = scattered.emplace(r2, mc.total).first;
      }
      const double l = b - std::sqrt(r * r - smm * smm);  // front face to the bulb's surface
      im.radiance[size_t{y} * kSide + x] = float(radiance * std::exp(-m.sigma_t_per_mm * l) + it->second);
    }
  return im;
}

medium::ConcentrationResult dilution_series(const std::string& material, sim::ColorChannel channel,
                                            const std::vector<double>& volumes, size_t paths) {
  std::vector<medium::DilutionPoint> points;
  const double water = tank_medium(material, 1.0, channel).bulb->radiance();  // W: the bulb through pure water
  for (double v : volumes) {
    medium::DilutionPoint p;
    p.volume_ml = v;
    const sim::Medium m = tank_medium(material, v, channel);
    const BulbImage im = bulb_image(m, paths, 1000 + uint64_t(v * 10));
    std::string why;
    const medium::Estimate e = medium::sigma_from_attenuation(im.settings, water, im.radiance, kSide, kSide, why);
    EXPECT_TRUE(why.empty()) << why;
    p.sigma_hat = e.value;
    p.sigma_hat_ci95 = e.ci95;
    p.bulb_radiance = medium::bulb_radiance(im.settings, im.radiance, kSide, kSide);
    std::printf("%-12s %7.1f ml: sigma %.5f /mm  sigma-hat %.5f /mm (%.0f %% of sigma), bulb %.3g of W\n",
                material.c_str(), v, m.sigma_t_per_mm, p.sigma_hat, 100 * p.sigma_hat / m.sigma_t_per_mm,
                p.bulb_radiance / water);
    points.push_back(p);
  }
  medium::ConcentrationSettings cs;  // the method's defaults: 3 points, 10 %, 0.04 /mm
  return medium::analyse_dilutions(points, cs);
}

// Fig. 4.7 on multiple-scattering data.
TEST(MediumMonteCarloClaims, SigmaHatLinearForMerlotDepartsForMilk) {
  // Merlot (red: the channel where Table 4.1 gives it a trace of scattering,
  // beta / sigma = 0.007) over the thesis's 1.5 l and beyond.
  const medium::ConcentrationResult merlot =
      dilution_series("Merlot", sim::ColorChannel::red, {250, 500, 1000, 1500, 2000, 3000}, 400);
  for (const std::string& w : merlot.warnings) std::printf("Merlot: %s\n", w.c_str());
  EXPECT_EQ(merlot.first_nonlinear, -1) << "Merlot stays linear at every volume";
  EXPECT_EQ(merlot.first_over_bound, -1);
  EXPECT_EQ(merlot.best, int(merlot.points.size()) - 1) << "any volume may be used: the largest";
  for (const medium::DilutionPoint& p : merlot.points) {
    const double truth = tank_medium("Merlot", p.volume_ml, sim::ColorChannel::red).sigma_t_per_mm;
    // sigma-hat is sigma for an absorber: the scattered light (0.7 % albedo)
    // lifts the bulb by < 1 % at these paths (ln: < 0.01 / 140 mm).
    EXPECT_NEAR(p.sigma_hat, truth, 0.02 * truth) << p.volume_ml << " ml";
  }
  // Lowfat milk (green), doubling steps as the recipe: forward-scattered
  // light (g = 0.9) adds to the bulb's image, sigma-hat falls below the line
  // and the method stops the user.
  const medium::ConcentrationResult milk =
      dilution_series("Lowfat Milk", sim::ColorChannel::green, {1, 2, 4, 8, 16, 32, 64}, 400);
  for (const std::string& w : milk.warnings) std::printf("milk: %s\n", w.c_str());
  ASSERT_GE(milk.first_nonlinear, 0) << "milk departs from the line";
  EXPECT_LE(milk.points[size_t(milk.first_nonlinear)].volume_ml, 64.0);  // measured: 64 ml (15 % below)
  EXPECT_FALSE(milk.warnings.empty());
  EXPECT_LT(milk.best, milk.first_nonlinear);
  // sigma-hat is below the true sigma at every volume: with g = 0.9 the light
  // scattered forward in front of the bulb looks like the bulb (measured 57 %
  // of sigma at 1-8 ml, 48 % at 64 ml), and the share grows with the volume:
  // the bend of Fig. 4.7.
  double low_ratio = 0;
  for (size_t i = 0; i < milk.points.size(); ++i) {
    const double truth = tank_medium("Lowfat Milk", milk.points[i].volume_ml, sim::ColorChannel::green).sigma_t_per_mm;
    EXPECT_LT(milk.points[i].sigma_hat, 0.7 * truth) << milk.points[i].volume_ml << " ml";
    if (i == 0) low_ratio = milk.points[i].sigma_hat / truth;
    if (i + 1 == milk.points.size()) {
      EXPECT_LT(milk.points[i].sigma_hat / truth, 0.9 * low_ratio);
    }
  }
}

// ---- Fig. 4.11: fit at a dilution, scale by Eq. 4.8, compare at 50-150 ml ----

// Face points on the bulb's row, to the right of its axis (the bulb is 20 mm
// from the left wall): lateral distances rho (mm).
const std::vector<double> kFitRho = {25, 30, 36, 43, 52, 62, 75, 90, 108, 130, 156, 187, 225, 265};

struct Profile {
  std::vector<double> rho, value, se;
};

// The plugin's fit (sigma, g, beta by Eq. 4.6-4.7 with the sphere bulb) on a
// Monte Carlo profile: each point is one radial bin. Noise weights with the
// points' relative standard error (Weights::noise).
medium::FitResult fit_mc_profile(const Profile& p, const sim::Medium& m) {
  medium::RadialProfile rp;
  double rel_se = 0;
  for (size_t i = 0; i < p.rho.size(); ++i) {
    medium::Bin b;
    b.rho_mm = b.rho_px = p.rho[i];  // 1 mm per "pixel"
    b.mean = p.value[i];
    b.n = 100;
    rp.bins.push_back(b);
    rp.pixels += b.n;
    rel_se = std::max(rel_se, p.se[i] / p.value[i]);
  }
  medium::FitSettings s;
  s.tank = {300, 150, m.bulb->radius_mm};
  s.bulb_radius_mm = m.bulb->radius_mm;
  s.mask_radius_px = 20;
  s.source_intensity = m.bulb->intensity();
  s.weights = medium::Weights::noise;
  s.noise_relative = std::max(rel_se, 1e-3);
  return medium::fit_profile(rp, s, {}, 0, 0);
}

// ---- Fig. 4.11 as the issue states it ---------------------------------------

// Eq. 4.8 in one tank: sigma and beta scale with the volume (c2 / c1 = V2 /
// V1), g does not. A fit with beta > sigma (albedo > 1: the all-orders fit
// below) is not a medium; it is clamped to beta = sigma before rendering (a
// Monte Carlo's path weights would grow without bound), and `clamped` says so.
sim::Medium scaled_fit(const medium::FitResult& f, const sim::Medium& truth_at_v, double fit_ml, double v_ml,
                       bool& clamped) {
  sim::Medium m = truth_at_v;  // tank, bulb
  m.sigma_t_per_mm = f.sigma.value * v_ml / fit_ml;
  m.sigma_s_per_mm = f.beta.value * v_ml / fit_ml;
  m.g = f.g.value;
  clamped = m.sigma_s_per_mm > m.sigma_t_per_mm;
  m.sigma_s_per_mm = std::min(m.sigma_s_per_mm, m.sigma_t_per_mm);
  return m;
}

struct FacePoint {
  double x_mm, y_mm;
};

// The compared points: the fit's 14 row points (25-265 mm right of the
// bulb's axis) and a coarse 6 x 5 image of the whole face (cell centres,
// 50 mm apart), leaving out the bulb's own image (r + 2 mm) as
// tank_energy_monte_carlo() does: 43 points.
std::vector<FacePoint> fig411_points(const sim::Medium& m) {
  std::vector<FacePoint> pts;
  for (double r : kFitRho) pts.push_back({m.bulb->center_mm.x + r, m.bulb->center_mm.y});
  constexpr int nx = 6, ny = 5;
  for (int j = 0; j < ny; ++j)
    for (int i = 0; i < nx; ++i) {
      const double x = m.box_min_mm.x + (i + 0.5) * (m.box_max_mm.x - m.box_min_mm.x) / nx;
      const double y = m.box_min_mm.y + (j + 0.5) * (m.box_max_mm.y - m.box_min_mm.y) / ny;
      if (std::hypot(x - m.bulb->center_mm.x, y - m.bulb->center_mm.y) < m.bulb->radius_mm + 2) continue;
      pts.push_back({x, y});
    }
  return pts;
}

// The Monte Carlo reference (every order) at the points, each point in two
// halves of `paths` with seeds seed + 2i and seed + 2i + 1: the mean is the
// render, the halves' disagreement its noise. Common random numbers: two
// renders with the same seed draw the same numbers path for path
// (TankMcOptions::common_random_numbers), so noise cancels in a difference.
// Unforced flights (at 50-150 ml the tank is 11-23 mean free paths deep and
// paths leave by themselves; forced ones would roulette for ~1000 vertices),
// 2 x 2 split bulb connection, exact single scattering as control variate.
struct McRender {
  std::vector<double> half[2];
};
McRender mc_render(const sim::Medium& m, const std::vector<FacePoint>& pts, size_t paths, uint64_t seed,
                  const sim::Medium& sampling) {
  const sim::TankMcOptions opt{2, false, true, true, sampling.sigma_t_per_mm, sampling.g};
  McRender out;
  for (const FacePoint& p : pts)
    for (int h = 0; h < 2; ++h)
      out.half[h].push_back(
          sim::tank_monte_carlo(m, p.x_mm, p.y_mm, paths / 2, seed + 2 * out.half[0].size() + uint64_t(h), 1 << 20, opt)
              .total);
  return out;
}

double quantile(std::vector<double> v, double q) {
  std::sort(v.begin(), v.end());
  return v.empty() ? std::nan("") : v[size_t(std::lround(q * double(v.size() - 1)))];
}

// Per point r = a / b - 1 (b: the truth's render); its noise |r_1 - r_2| / 2
// from the halves (the standard error of their mean, one degree of freedom
// per point: read the median). Summaries over the points: median and 90th
// percentile of |r|, median of the noise, and the mean signed r.
struct Comparison {
  double median = 0, p90 = 0, noise_median = 0, mean_signed = 0;
};
Comparison compare(const McRender& a, const McRender& b) {
  std::vector<double> r, noise;
  Comparison c;
  for (size_t i = 0; i < b.half[0].size(); ++i) {
    const double ra = 0.5 * (a.half[0][i] + a.half[1][i]), rb = 0.5 * (b.half[0][i] + b.half[1][i]);
    const double r1 = a.half[0][i] / b.half[0][i] - 1, r2 = a.half[1][i] / b.half[1][i] - 1;
    r.push_back(std::abs(ra / rb - 1));
    c.mean_signed += (ra / rb - 1) / double(b.half[0].size());
    noise.push_back(0.5 * std::abs(r1 - r2));
  }
  c.median = quantile(r, 0.5);
  c.p90 = quantile(r, 0.9);
  c.noise_median = quantile(noise, 0.5);
  return c;
}

constexpr double kFig411FitMl = 8;
const std::vector<double> kFig411Volumes = {50, 100, 150};
constexpr size_t kFig411Paths = 2000;  // per point, both halves

// The renderer's single-scattering profile at the fit's points (tank_profile:
// the function the sim's renderer tabulates for the tank image claim 1 fits).
Profile single_scattering_profile(const sim::Medium& m) {
  Profile p;
  for (double r : kFitRho) {
    p.rho.push_back(r);
    p.value.push_back(sim::tank_profile(m, r, 768).scatter);
    p.se.push_back(0);
  }
  return p;
}

// Sensitivity of the 50-150 ml renders to the medium (what the tolerance
// below rests on): common-random-number renders of the truth with sigma and
// beta both +1 % (the albedo kept), with kappa = sigma - beta +10 % (sigma
// kept), and with g +0.002, each against the truth as the sampling medium.
// Exploration, not a claim: run by hand with --gtest_also_run_disabled_tests.
// Measured 2026-11-24 at 1000 paths per point (per-point |r| median / p90;
// the Monte Carlo noise is in them, so they are upper bounds):
//   volume  sigma,beta +1 %   kappa +10 %    g +0.002
//   50 ml   0.63 / 1.9 %      0.22 / 0.37 %  2.6 / 7.2 %
//   100 ml  1.17 / 3.7 %      0.42 / 0.65 %  4.0 / 10.0 %
//   150 ml  1.31 / 5.1 %      0.60 / 0.94 %  3.3 / 9.7 %
TEST(MediumMonteCarloClaims, DISABLED_Fig411Sensitivity) {
  for (double v : kFig411Volumes) {
    const sim::Medium truth = tank_medium("Lowfat Chocolate Milk", v, sim::ColorChannel::green);
    const std::vector<FacePoint> pts = fig411_points(truth);
    const McRender b = mc_render(truth, pts, 1000, 4111, truth);
    sim::Medium scale = truth, kappa = truth, g = truth;
    scale.sigma_t_per_mm *= 1.01;
    scale.sigma_s_per_mm *= 1.01;
    kappa.sigma_s_per_mm = truth.sigma_t_per_mm - 1.1 * (truth.sigma_t_per_mm - truth.sigma_s_per_mm);
    g.g += 0.002;
    for (const auto& [name, m] : {std::pair{"sigma,beta +1 %", scale}, {"kappa +10 %", kappa}, {"g +0.002", g}}) {
      const Comparison c = compare(mc_render(m, pts, 1000, 4111, truth), b);
      std::printf("%3.0f ml %-16s |r| median %.3f %% p90 %.3f %% (noise median %.3f %%) mean r %+.3f %%\n", v, name,
                  100 * c.median, 100 * c.p90, 100 * c.noise_median, 100 * c.mean_signed);
    }
  }
}

// Fig. 4.11 read as the issue states it, consistently with its first claim:
// the 8 ml image of lowfat chocolate milk (green) as the sim's
// single-scattering renderer makes it (the renderer's profile, claim 1's
// images) fitted by the plugin's fit; sigma and beta scaled by Eq. 4.8 to
// 50, 100 and 150 ml; the tank rendered there by the Monte Carlo reference
// (every order) (a) with the scaled fit and (b) with Table 4.1's own
// parameters at that volume, and the two renders compared at 43 face points
// (the fit's row and a coarse 6 x 5 image). (a) and (b) use common random
// numbers (the same seed, the same numbers path for path), so most of the
// Monte Carlo noise cancels in the difference; the halves of each render
// measure what is left.
//
// TOLERANCE, per volume: the per-point |a / b - 1| has median <= 1.5 % and
// 90th percentile <= 4.5 % (stated before (a) was first rendered). Why:
// Eq. 4.8 is exact in the sim (the library scales Table 4.1 the same way),
// so the fit's relative errors at 8 ml carry unchanged to every volume and
// (a) differs from (b) only through them. The fit's accuracy on the
// renderer's 8 ml image, asserted below as this test's premise: sigma and
// beta within 0.4 % (measured -0.27 % each before issue 14's fix of the
// bulb cap's phase curvature, -0.07 / -0.06 % after), kappa = sigma - beta
// within 5 % (measured +1.6 %, then -3.1 %: the absorption is 0.3 % of
// sigma, a difference of two fitted numbers), g within 0.0003 (measured
// -0.0001, then 0.0000). Through the
// sensitivities of the renders (DISABLED_Fig411Sensitivity above: per point,
// per 1 % of sigma and beta, per 10 % of kappa, per 0.002 of g), at those
// bounds, with the signs aligned and the worst volume for each term:
// median 0.4 x 1.31 + 0.54 x 0.60 + 0.15 x 3.95 = 1.4 %, 90th percentile
// 0.4 x 5.1 + 0.54 x 0.94 + 0.15 x 10.0 = 4.1 %. The remaining Monte Carlo
// noise of the difference is in those sensitivities already (measured at
// half this test's paths); for a medium 0.3 % from the sampling one it is
// a few tenths of a percent (the halves measure it, printed). Cost: 6
// renders of 43 points x 2000 paths, ~4 s CPU; fewer paths raise the noise
// as 1 / sqrt(paths), not the tolerance's deterministic part.
constexpr double kFig411TolMedian = 0.015, kFig411TolP90 = 0.045;
TEST(MediumMonteCarloClaims, Fig411FitAt8mlScaledByEq48MatchesMonteCarloAt50To150ml) {
  const std::string material = "Lowfat Chocolate Milk";
  const sim::Medium truth8 = tank_medium(material, kFig411FitMl, sim::ColorChannel::green);
  const medium::FitResult f = fit_mc_profile(single_scattering_profile(truth8), truth8);
  ASSERT_TRUE(f.error.empty()) << f.error;
  const double kappa8 = truth8.sigma_t_per_mm - truth8.sigma_s_per_mm;
  const double e_sigma = f.sigma.value / truth8.sigma_t_per_mm - 1, e_beta = f.beta.value / truth8.sigma_s_per_mm - 1;
  const double e_kappa = (f.sigma.value - f.beta.value) / kappa8 - 1, e_g = f.g.value - truth8.g;
  std::printf("8 ml fit of the single-scattered image: sigma %+.2f %%  beta %+.2f %%  kappa = sigma - beta %+.1f %%  "
              "g %+.4f  rms %.2f %%\n",
              100 * e_sigma, 100 * e_beta, 100 * e_kappa, e_g, f.rms_percent);
  // The tolerance's premise: the fit's accuracy at 8 ml.
  ASSERT_LT(std::abs(e_sigma), 0.004);
  ASSERT_LT(std::abs(e_beta), 0.004);
  ASSERT_LT(std::abs(e_kappa), 0.05);
  ASSERT_LT(std::abs(e_g), 0.0003);
  for (double v : kFig411Volumes) {
    const sim::Medium truth = tank_medium(material, v, sim::ColorChannel::green);
    bool clamped = false;
    const sim::Medium fitted = scaled_fit(f, truth, kFig411FitMl, v, clamped);
    EXPECT_FALSE(clamped);
    const std::vector<FacePoint> pts = fig411_points(truth);
    // Both traced in the true medium and weighted (common random numbers).
    const uint64_t seed = 4111 + uint64_t(v);
    const Comparison c = compare(mc_render(fitted, pts, kFig411Paths, seed, truth),
                                 mc_render(truth, pts, kFig411Paths, seed, truth));
    std::printf("%3.0f ml: sigma %.5f /mm (true %.5f)  %zu points: |a/b - 1| median %.2f %% (tolerance %.1f %%), p90 "
                "%.2f %% (%.1f %%); noise median %.2f %%; mean a/b - 1 %+.2f %%\n",
                v, fitted.sigma_t_per_mm, truth.sigma_t_per_mm, pts.size(), 100 * c.median, 100 * kFig411TolMedian,
                100 * c.p90, 100 * kFig411TolP90, 100 * c.noise_median, 100 * c.mean_signed);
    EXPECT_LE(c.median, kFig411TolMedian) << v << " ml";
    EXPECT_LE(c.p90, kFig411TolP90) << v << " ml";
  }
}

// Fig. 4.11's premise: a fit at a dilution "where single scattering is
// dominant" gives sigma and beta that Eq. 4.8 can scale. On the Monte Carlo
// photograph (all orders) of lowfat chocolate milk it does not: sigma comes
// out far too low at every dilution, because forward-scattered light (g =
// 0.93) still travels with the bulb's and the profile falls as if the medium
// were thinner. The attenuation that carries sigma (~ sigma d) and the light
// forward scattering adds (~ beta g d) both grow linearly with the volume,
// so diluting does not remove the bias. The control, the same fit on the same
// face points with one scattering event only (the Monte Carlo's first vertex
// = the renderer's single scattering), recovers the medium: the bias is the
// physics, not the fit. The 8 ml all-orders fit, scaled by Eq. 4.8 to
// 50-150 ml as Fig411FitAt8ml… does with the single-scattering one, has a
// third of the true sigma; its renders' difference from the truth is
// printed, not asserted: the two media cannot share paths, so the per-point
// noise (20-47 % at these paths) is of the order of the difference
// (medians 47-59 %, 2026-11-24; docs/medium.md "Limits").
TEST(MediumMonteCarloClaims, Fig411PremiseSingleScatteringFitIsBiasedByForwardScattering) {
  const std::string material = "Lowfat Chocolate Milk";  // Fig. 4.11 (green channel)
  const sim::TankMcOptions low_var{4, true, true};
  medium::FitResult all_orders_fit;
  for (double fit_volume : {1.0, 8.0}) {  // 1 ml: 5 % of the energy missed (docs/media.md); 8 ml: the thesis's
    const sim::Medium truth = tank_medium(material, fit_volume, sim::ColorChannel::green);
    const double reduced = truth.sigma_t_per_mm * (1 - truth.g * truth.sigma_s_per_mm / truth.sigma_t_per_mm);
    for (int vertices : {1, 1 << 20}) {
      Profile photo;
      for (double r : kFitRho) {
        const sim::TankMonteCarlo mc = sim::tank_monte_carlo(truth, truth.bulb->center_mm.x + r, truth.bulb->center_mm.y,
                                                             2000, 11 + uint64_t(r), vertices, low_var);
        photo.rho.push_back(r);
        photo.value.push_back(mc.total);
        photo.se.push_back(mc.total_se);
      }
      const medium::FitResult f = fit_mc_profile(photo, truth);
      ASSERT_TRUE(f.error.empty()) << f.error;
      std::printf("%.0f ml, %s: sigma %+.1f %% (sigma (1 - g beta / sigma) would be %+.1f %%)  beta %+.1f %%  g %.3f "
                  "(true %.3f)  rms %.2f %%\n",
                  fit_volume, vertices == 1 ? "single scattering" : "all orders",
                  100 * (f.sigma.value / truth.sigma_t_per_mm - 1), 100 * (reduced / truth.sigma_t_per_mm - 1),
                  100 * (f.beta.value / truth.sigma_s_per_mm - 1), f.g.value, truth.g, f.rms_percent);
      if (vertices == 1) {
        // The control: the sphere model against the sim's renderer (two
        // implementations of Eq. 4.1-4.2; the claims test measures < 1 %) on 14
        // noiseless points; sigma is weakly constrained at 1 ml (sigma D = 0.15).
        EXPECT_LT(std::abs(f.sigma.value / truth.sigma_t_per_mm - 1), 0.05) << fit_volume;
        EXPECT_LT(std::abs(f.beta.value / truth.sigma_s_per_mm - 1), 0.03) << fit_volume;
        EXPECT_NEAR(f.g.value, truth.g, 0.01) << fit_volume;
      } else {
        EXPECT_LT(f.sigma.value, 0.5 * truth.sigma_t_per_mm) << fit_volume << " ml: sigma far too low";
        EXPECT_LT(f.g.value, truth.g) << fit_volume;
        if (fit_volume == kFig411FitMl) all_orders_fit = f;
      }
    }
  }
  // The same pipeline as Fig411FitAt8ml… below on this all-orders fit:
  // scaled by Eq. 4.8 (beta clamped to sigma: the fit's albedo is > 1) and
  // rendered at 50-150 ml against the truth, same points and paths (each
  // medium traced as itself: weighting across a factor 3 in sigma would
  // not converge).
  ASSERT_TRUE(std::isfinite(all_orders_fit.sigma.value));
  for (double v : kFig411Volumes) {
    const sim::Medium truth = tank_medium(material, v, sim::ColorChannel::green);
    bool clamped = false;
    const sim::Medium fitted = scaled_fit(all_orders_fit, truth, kFig411FitMl, v, clamped);
    const std::vector<FacePoint> pts = fig411_points(truth);
    const uint64_t seed = 4111 + uint64_t(v);
    const Comparison c = compare(mc_render(fitted, pts, kFig411Paths, seed, fitted),
                                 mc_render(truth, pts, kFig411Paths, seed, truth));
    std::printf("all-orders fit scaled to %3.0f ml%s: sigma %.5f /mm (true %.5f)  |a/b - 1| median %.1f %%, p90 "
                "%.1f %%; noise median %.1f %%; mean a/b - 1 %+.1f %%\n",
                v, clamped ? " (beta clamped to sigma)" : "", fitted.sigma_t_per_mm, truth.sigma_t_per_mm,
                100 * c.median, 100 * c.p90, 100 * c.noise_median, 100 * c.mean_signed);
  }
}

// What the camera pipeline's 8 ml fit would give at 50-150 ml: the errors
// `measure` makes on the shipped 8 ml scene (medium_claims_test,
// Fig411FitStepOnTheShipped8mlScene, 2026-11-24, before the fix of the
// cap's phase curvature: sigma +0.32 %, beta +0.19 %, g exact; kappa +41 %;
// after it the noise-free image gives -0.05 / -0.05 % and kappa +0.5 %,
// and the camera's noise alone moves sigma by ~0.5 % and kappa by ~100-400 %
// per seed: medium_claims_test DISABLED_Fig411CameraBiasBreakdown) applied
// to the truth and compared as the
// claim test does. Exploration (--gtest_also_run_disabled_tests).
TEST(MediumMonteCarloClaims, DISABLED_Fig411WithTheCameraPipelinesFitErrors) {
  for (double v : kFig411Volumes) {
    const sim::Medium truth = tank_medium("Lowfat Chocolate Milk", v, sim::ColorChannel::green);
    sim::Medium fitted = truth;
    fitted.sigma_t_per_mm *= 1.0032;
    fitted.sigma_s_per_mm *= 1.0019;
    const std::vector<FacePoint> pts = fig411_points(truth);
    const uint64_t seed = 4111 + uint64_t(v);
    const Comparison c = compare(mc_render(fitted, pts, kFig411Paths, seed, truth),
                                 mc_render(truth, pts, kFig411Paths, seed, truth));
    std::printf("%3.0f ml: |a/b - 1| median %.2f %%, p90 %.2f %%; noise median %.2f %%; mean %+.2f %%\n", v,
                100 * c.median, 100 * c.p90, 100 * c.noise_median, 100 * c.mean_signed);
  }
}

// ---- Stretch: a Monte Carlo-refined fit of the all-orders photograph ----------

// Nelder-Mead (standard coefficients) on f from x0 with initial steps.
std::vector<double> nelder_mead(const std::function<double(const std::vector<double>&)>& f, std::vector<double> x0,
                                const std::vector<double>& step, int max_evals, int& evals) {
  const size_t n = x0.size();
  std::vector<std::vector<double>> x(n + 1, x0);
  std::vector<double> fx(n + 1);
  for (size_t i = 0; i < n; ++i) x[i + 1][i] += step[i];
  for (size_t i = 0; i <= n; ++i) fx[i] = f(x[i]);
  evals = int(n + 1);
  while (evals < max_evals) {
    std::vector<size_t> o(n + 1);
    for (size_t i = 0; i <= n; ++i) o[i] = i;
    std::sort(o.begin(), o.end(), [&](size_t a, size_t b) { return fx[a] < fx[b]; });
    const size_t best = o[0], worst = o[n], second = o[n - 1];
    std::vector<double> c(n, 0.0);
    for (size_t i = 0; i < n; ++i)
      for (size_t k = 0; k < n; ++k) c[k] += x[o[i]][k] / double(n);
    auto along = [&](double t) {
      std::vector<double> y(n);
      for (size_t k = 0; k < n; ++k) y[k] = c[k] + t * (x[worst][k] - c[k]);
      return y;
    };
    const std::vector<double> r = along(-1);
    const double fr = f(r);
    ++evals;
    if (fr < fx[best]) {
      const std::vector<double> e = along(-2);
      const double fe = f(e);
      ++evals;
      if (fe < fr) x[worst] = e, fx[worst] = fe;
      else x[worst] = r, fx[worst] = fr;
    } else if (fr < fx[second]) {
      x[worst] = r, fx[worst] = fr;
    } else {
      const std::vector<double> k = along(fr < fx[worst] ? -0.5 : 0.5);
      const double fk = f(k);
      ++evals;
      if (fk < std::min(fr, fx[worst])) {
        x[worst] = k, fx[worst] = fk;
      } else {  // shrink towards the best
        for (size_t i = 0; i <= n; ++i) {
          if (i == best) continue;
          for (size_t j = 0; j < n; ++j) x[i][j] = x[best][j] + 0.5 * (x[i][j] - x[best][j]);
          fx[i] = f(x[i]);
          ++evals;
        }
      }
    }
  }
  size_t best = 0;
  for (size_t i = 1; i <= n; ++i)
    if (fx[i] < fx[best]) best = i;
  return x[best];
}

// Starting from the single-scattering fit of the all-orders 8 ml photograph
// (the premise test's), adjust beta, kappa = sigma - beta and g so that Monte
// Carlo renders (every order) match the photograph at its 14 points:
// Nelder-Mead on the noise-weighted squared log ratio, in (ln beta, ln kappa,
// atanh g). Every evaluation renders the 14 points with the same seeds and
// common random numbers, traced in a fixed reference medium and weighted,
// so the objective is smooth in the parameters (noise weights: both
// renders' standard errors, at least 1 %). PROCAM_FIG411_REFINE_ROUNDS > 1
// moves the reference to the result and searches again; _SEED, _PATHS and
// _EVALS set the model's seeds, paths per point and evaluations.
// Exploration, not a claim (run with --gtest_also_run_disabled_tests).
// Measured 2026-11-24 (load ~8; single-scattering start: sigma -66 %, beta
// -18 %, g 0.892):
//   seed 500, 1000 paths, 61 evals (8 s CPU):  sigma -3.8 %  beta -3.6 %  g 0.917
//   seed 900, 1000 paths, 60 evals:            sigma -15 %   beta -15 %   g 0.908
//   seed 900, 4000 paths, 121 evals (35 s):    sigma +15 %   beta +14 %   g 0.937
// and scaled to 50 / 100 / 150 ml, per-point |a/b - 1| medians 10-30 %
// (p90 32-80 %). sigma's bias is gone to within ~15 %, but g scatters by
// ~0.01 between seeds (the 8 ml photograph's own noise: 2000 paths) and the
// 50-150 ml images move ~3.5 % per 0.002 of g, so the extrapolation still
// misses the claim's tolerance. Moving the reference (3 rounds) wandered
// off (kappa x80 at round 3, where the 8 ml image hardly constrains it).
TEST(MediumMonteCarloClaims, DISABLED_Fig411MonteCarloRefinedFit) {
  const std::string material = "Lowfat Chocolate Milk";
  const sim::Medium truth = tank_medium(material, kFig411FitMl, sim::ColorChannel::green);
  const sim::TankMcOptions low_var{4, true, true};
  Profile photo;
  for (double r : kFitRho) {
    const sim::TankMonteCarlo mc = sim::tank_monte_carlo(truth, truth.bulb->center_mm.x + r, truth.bulb->center_mm.y,
                                                         2000, 11 + uint64_t(r), 1 << 20, low_var);
    photo.rho.push_back(r);
    photo.value.push_back(mc.total);
    photo.se.push_back(mc.total_se);
  }
  const medium::FitResult ss = fit_mc_profile(photo, truth);
  ASSERT_TRUE(ss.error.empty()) << ss.error;
  sim::Medium ref = truth;  // tank, bulb; parameters from the fit
  ref.sigma_s_per_mm = ss.beta.value;
  ref.sigma_t_per_mm = std::max(ss.sigma.value, ss.beta.value * 1.003);  // albedo <= 1 (the fit's is 2.4)
  ref.g = ss.g.value;
  const char* paths_env = std::getenv("PROCAM_FIG411_REFINE_PATHS");
  const size_t paths = paths_env ? std::strtoull(paths_env, nullptr, 10) : 1000;
  const char* evals_env = std::getenv("PROCAM_FIG411_REFINE_EVALS");
  const int max_evals = evals_env ? std::atoi(evals_env) : 60;
  const char* seed_env = std::getenv("PROCAM_FIG411_REFINE_SEED");
  const uint64_t model_seed = seed_env ? std::strtoull(seed_env, nullptr, 10) : 500;
  const char* rounds_env = std::getenv("PROCAM_FIG411_REFINE_ROUNDS");
  const int rounds = rounds_env ? std::atoi(rounds_env) : 1;
  auto render = [&](const sim::Medium& m, const sim::Medium& sampling) {
    std::vector<sim::TankMonteCarlo> out;
    sim::TankMcOptions opt{2, true, true, true, sampling.sigma_t_per_mm, sampling.g};
    for (double r : kFitRho)
      out.push_back(sim::tank_monte_carlo(m, m.bulb->center_mm.x + r, m.bulb->center_mm.y, paths,
                                          model_seed + uint64_t(r), 1 << 20, opt));
    return out;
  };
  auto medium_of = [&](const std::vector<double>& x) {
    sim::Medium m = truth;
    m.sigma_s_per_mm = std::exp(x[0]);
    m.sigma_t_per_mm = m.sigma_s_per_mm + std::exp(x[1]);
    m.g = std::tanh(x[2]);
    return m;
  };
  std::vector<double> x = {std::log(ref.sigma_s_per_mm), std::log(ref.sigma_t_per_mm - ref.sigma_s_per_mm),
                           std::atanh(ref.g)};
  int total_evals = 0;
  for (int round = 0; round < rounds; ++round) {
    const sim::Medium sampling = medium_of(x);
    auto objective = [&](const std::vector<double>& y) {
      const sim::Medium m = medium_of(y);
      if (!(m.g > -0.99 && m.g < 0.99) || !(m.sigma_t_per_mm < 1.0)) return 1e30;
      const std::vector<sim::TankMonteCarlo> model = render(m, sampling);
      double sum = 0;
      for (size_t i = 0; i < model.size(); ++i) {
        if (!(model[i].total > 0)) return 1e30;
        // Both renders' noise (relative), at least 1 % (the model's bias).
        const double rel_se = std::max(std::hypot(photo.se[i] / photo.value[i], model[i].total_se / model[i].total), 0.01);
        const double d = std::log(model[i].total / photo.value[i]) / rel_se;
        sum += d * d;
      }
      return sum;
    };
    int evals = 0;
    x = nelder_mead(objective, x, {0.3, 1.0, 0.2}, max_evals, evals);
    total_evals += evals;
    const sim::Medium m = medium_of(x);
    std::printf("round %d: sigma %+.1f %%  beta %+.1f %%  kappa %+.0f %%  g %.4f (true %.4f)  objective %.1f  (%d evals)\n",
                round, 100 * (m.sigma_t_per_mm / truth.sigma_t_per_mm - 1),
                100 * (m.sigma_s_per_mm / truth.sigma_s_per_mm - 1),
                100 * ((m.sigma_t_per_mm - m.sigma_s_per_mm) / (truth.sigma_t_per_mm - truth.sigma_s_per_mm) - 1), m.g,
                truth.g, objective(x), evals);
  }
  const sim::Medium refined = medium_of(x);
  medium::FitResult f;
  f.sigma.value = refined.sigma_t_per_mm;
  f.beta.value = refined.sigma_s_per_mm;
  f.g.value = refined.g;
  for (double v : kFig411Volumes) {
    const sim::Medium tv = tank_medium(material, v, sim::ColorChannel::green);
    bool clamped = false;
    const sim::Medium fitted = scaled_fit(f, tv, kFig411FitMl, v, clamped);
    const std::vector<FacePoint> pts = fig411_points(tv);
    const uint64_t seed = 4111 + uint64_t(v);
    const Comparison c = compare(mc_render(fitted, pts, kFig411Paths, seed, tv), mc_render(tv, pts, kFig411Paths, seed, tv));
    std::printf("refined fit scaled to %3.0f ml: |a/b - 1| median %.2f %%, p90 %.2f %%; noise median %.2f %%; mean "
                "%+.2f %%\n",
                v, 100 * c.median, 100 * c.p90, 100 * c.noise_median, 100 * c.mean_signed);
  }
  std::printf("%d Monte Carlo evaluations of 14 points x %zu paths\n", total_evals, paths);
}

}  // namespace
}  // namespace procam
