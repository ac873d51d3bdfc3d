// SPDX-License-Identifier: MIT
// Thesis ch. 4 claims (issue 14) on multiple-scattering data: the sim's Monte
// Carlo reference of the dilution tank (hw/sim tank_mc.cpp, all orders of
// scattering) as the "photograph", the `medium` plugin's analysis on it.
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

#include <cmath>
#include <cstdio>
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
// physics, not the fit. So the extrapolation to 50-150 ml is not tested
// (docs/medium.md "Limits"): the scaled medium would have a third or less of
// the true sigma.
TEST(MediumMonteCarloClaims, Fig411PremiseSingleScatteringFitIsBiasedByForwardScattering) {
  const std::string material = "Lowfat Chocolate Milk";  // Fig. 4.11 (green channel)
  const sim::TankMcOptions low_var{4, true, true};
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
      }
    }
  }
}

}  // namespace
}  // namespace procam
