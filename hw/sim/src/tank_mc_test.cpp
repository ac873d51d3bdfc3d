// SPDX-License-Identifier: MIT
// The tank rig's Monte Carlo reference (tank.hpp, tank_mc.cpp): with one
// scattering event it must reproduce the single-scattering renderer's
// profile within its noise; multiple scattering must add light, little in a
// thin tank and much in a thick one (thesis §4.2.3, Fig. 4.11); the exported
// regime table (medium_regime.hpp) must hold up against a fresh run.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>

#include "procam/hw/sim/medium_regime.hpp"
#include "tank.hpp"
#include "tank_test_util.hpp"

namespace procam::sim {
namespace {

using namespace tank_test;

TEST(TankMonteCarlo, OneVertexMatchesTheSingleScatteringProfile) {
  for (const char* medium : {R"("material": "Lowfat Milk", "volume_ml": 16)",
                             R"("material": "Espresso", "volume_ml": 8)",
                             R"("sigma_t_per_mm": 0.02, "sigma_s_per_mm": 0.015, "g": -0.3)"}) {
    const Scene s = tank_scene(medium, 10.0);
    const Medium& m = *s.medium;
    for (double rho : {25.0, 80.0, 160.0}) {
      const TankProfile p = tank_profile(m, rho, 768);
      const TankMonteCarlo mc =
          tank_monte_carlo(m, m.bulb->center_mm.x + rho, m.bulb->center_mm.y, 60000, 17 + static_cast<uint64_t>(rho), 1);
      EXPECT_GT(mc.single_se, 0.0);
      EXPECT_LT(mc.single_se, 0.05 * mc.single) << medium << " rho " << rho;  // the comparison means something
      EXPECT_NEAR(mc.single, p.scatter, 4 * mc.single_se + 5e-3 * p.scatter) << medium << " rho " << rho;
      EXPECT_DOUBLE_EQ(mc.total, mc.single);  // one vertex: nothing else
    }
  }
}

TEST(TankMonteCarlo, MultipleScatteringAddsLightWithConcentration) {
  // Lowfat chocolate milk (g 0.927) at 0.5 ml, 8 ml (Fig. 4.11a's fit
  // concentration) and 150 ml (Fig. 4.11d), 60 mm from the bulb's axis.
  // Forward scattering keeps scattered light travelling with the bulb's, so
  // the share single scattering misses grows like 1 − e^{−β g d}: small for
  // a trace, most of the light at the thesis's dilutions, nearly all at 150 ml.
  double excess[3] = {};
  const double volumes[3] = {0.5, 8, 150};
  for (int k = 0; k < 3; ++k) {
    const Scene s = tank_scene(R"("material": "Lowfat Chocolate Milk", "volume_ml": )" + std::to_string(volumes[k]));
    const TankMonteCarlo mc = tank_monte_carlo(*s.medium, s.medium->bulb->center_mm.x + 60, 0, 20000, 5, 1 << 20);
    ASSERT_GT(mc.total, 0.0);
    EXPECT_GE(mc.total, mc.single);
    excess[k] = (mc.total - mc.single) / mc.total;
  }
  EXPECT_LT(excess[0], 0.15);
  EXPECT_GT(excess[1], 2 * excess[0]);
  EXPECT_GT(excess[2], 0.95);
}

// The variance reductions (TankMcOptions: stratified split connection,
// forced collisions, exact single scattering as a control variate) keep the
// estimate (agreement with the plain estimator within 4 combined standard
// errors + 0.5 %, the renderer's far-field path bias) and cut its standard
// error at the same number of paths (per path they cost ~19x: the
// time-for-time comparison is in tank_bench and docs/media.md): lowfat chocolate milk at 1 ml (single
// scattering dominant), 8 ml and 150 ml (Fig. 4.11's fit and far volumes).
TEST(TankMonteCarlo, VarianceReductionKeepsTheMeanAndCutsTheError) {
  const struct {
    double volume, rho, min_gain;  // min_gain: required se(plain) / se(reduced) at equal paths; 0 = none
  } cases[] = {{1, 25, 5}, {1, 100, 1.5}, {8, 25, 1.5}, {8, 100, 0}, {150, 40, 1.5}};
  for (const auto& c : cases) {
    const Scene s = tank_scene(R"("material": "Lowfat Chocolate Milk", "volume_ml": )" + std::to_string(c.volume));
    const Medium& m = *s.medium;
    const double x = m.bulb->center_mm.x + c.rho;
    const TankMonteCarlo plain = tank_monte_carlo(m, x, 0, 20000, 41, 1 << 20);
    const TankMonteCarlo low = tank_monte_carlo(m, x, 0, 20000, 43, 1 << 20, TankMcOptions{4, true, true});
    std::printf("%5.0f ml rho %3.0f: plain %.4g ± %.2f %%, reduced %.4g ± %.2f %%: se ratio %.1f\n", c.volume, c.rho,
                plain.total, 100 * plain.total_se / plain.total, low.total, 100 * low.total_se / low.total,
                plain.total_se / low.total_se);
    EXPECT_NEAR(low.total, plain.total, 4 * std::hypot(plain.total_se, low.total_se) + 5e-3 * plain.total)
        << c.volume << " ml rho " << c.rho;
    // Far from the bulb at 8 ml the error is the higher orders' heavy tail
    // (a later vertex close to the bulb, its connection in the forward lobe):
    // the gain there depends on the seed (measured 0.8-1.9): not asserted.
    if (c.min_gain > 0) {
      EXPECT_GT(plain.total_se / low.total_se, c.min_gain) << c.volume << " ml rho " << c.rho;
    }
  }
}

// Common random numbers with a shared sampling medium
// (TankMcOptions::common_random_numbers, sampling): two nearby media (sigma
// and beta +1 %, g +0.002; lowfat chocolate milk at 100 ml, Fig. 4.11c),
// both traced as the first and weighted, give a relative difference that
// scatters over seeds far less than with independent streams; and the
// reweighted render is unbiased (agrees with the plain estimator within 4
// standard errors).
TEST(TankMonteCarlo, CommonRandomNumbersCutTheNoiseOfADifference) {
  const Scene s = tank_scene(R"("material": "Lowfat Chocolate Milk", "volume_ml": 100)");
  const Medium& a = *s.medium;
  Medium b = a;
  b.sigma_t_per_mm *= 1.01;
  b.sigma_s_per_mm *= 1.01;
  b.g += 0.002;
  const double x = a.bulb->center_mm.x + 60;
  TankMcOptions crn{2, false, true, true, a.sigma_t_per_mm, a.g}, shared{2, false, true, false, 0, 0};
  constexpr int kSeeds = 6;
  double d_crn[kSeeds], d_ind[kSeeds];
  for (int i = 0; i < kSeeds; ++i) {
    const TankMonteCarlo ca = tank_monte_carlo(a, x, 0, 1000, 100 + uint64_t(i), 1 << 20, crn);
    const TankMonteCarlo cb = tank_monte_carlo(b, x, 0, 1000, 100 + uint64_t(i), 1 << 20, crn);
    const TankMonteCarlo ia = tank_monte_carlo(a, x, 0, 1000, 200 + uint64_t(i), 1 << 20, shared);
    const TankMonteCarlo ib = tank_monte_carlo(b, x, 0, 1000, 300 + uint64_t(i), 1 << 20, shared);
    d_crn[i] = cb.total / ca.total - 1;
    d_ind[i] = ib.total / ia.total - 1;
    EXPECT_NEAR(ca.total, ia.total, 4 * std::hypot(ca.total_se, ia.total_se)) << "seed " << i;
    EXPECT_NEAR(cb.total, ib.total, 4 * std::hypot(cb.total_se, ib.total_se)) << "seed " << i << " (reweighted)";
  }
  auto spread = [](const double* d) {
    double m = 0, q = 0;
    for (int i = 0; i < kSeeds; ++i) m += d[i] / kSeeds;
    for (int i = 0; i < kSeeds; ++i) q += (d[i] - m) * (d[i] - m) / (kSeeds - 1);
    return std::sqrt(q);
  };
  std::printf("relative difference over %d seeds: sd %.3f %% with common random numbers, %.3f %% independent\n",
              kSeeds, 100 * spread(d_crn), 100 * spread(d_ind));
  EXPECT_LT(spread(d_crn), spread(d_ind) / 3);
}

TEST(TankMonteCarlo, PureAbsorberAndBadInputGiveZeroNotNaN) {
  const Scene s = tank_scene(R"("material": "Merlot", "volume_ml": 1500, "channel": "green")");
  const TankMonteCarlo mc = tank_monte_carlo(*s.medium, 0, 0, 100, 1, 10);
  EXPECT_EQ(mc.total, 0.0);
  EXPECT_EQ(mc.single, 0.0);
  const Scene milk = tank_scene(R"("material": "milk", "volume_ml": 16)");
  EXPECT_EQ(tank_monte_carlo(*milk.medium, 0, 0, 0, 1, 10).total, 0.0);
  // A sampling medium with |g| >= 1 (no H-G) gives zero, not NaN.
  const TankMonteCarlo bad_g =
      tank_monte_carlo(*milk.medium, 0, 0, 100, 1, 10, TankMcOptions{1, false, false, true, 0.01, 1.0});
  EXPECT_EQ(bad_g.total, 0.0);
  const TankEnergy e = tank_energy_monte_carlo(*milk.medium, 4, 3, 200, 3, 2);
  EXPECT_TRUE(std::isfinite(e.relative_excess));
  EXPECT_GT(e.total, 0.0);
}

}  // namespace
}  // namespace procam::sim

// ---- the exported regime table (medium_regime.hpp) -------------------------------------


namespace procam::sim {
namespace {

TEST(MediumRegime, TableInterpolatesAndBoundsAsDocumented) {
  for (size_t i = 0; i < kRegimeBetaPerMm.size(); ++i)
    EXPECT_DOUBLE_EQ(single_scattering_error(kRegimeBetaPerMm[i]), kRegimeMissedEnergy[i]);
  for (size_t i = 1; i < kRegimeMissedEnergy.size(); ++i) EXPECT_GT(kRegimeMissedEnergy[i], kRegimeMissedEnergy[i - 1]);
  EXPECT_EQ(single_scattering_error(0.0), 0.0);  // no scattering: nothing to miss
  EXPECT_EQ(single_scattering_error(1.0), 1.0);
  EXPECT_EQ(single_scattering_error(std::nan("")), 1.0);
  // The documented 5 % bound: β < 0.00048 /mm in the 300 mm tank.
  EXPECT_TRUE(single_scattering_valid(0.01, 0.0096));   // β 0.0004
  EXPECT_FALSE(single_scattering_valid(0.01, 0.0094));  // β 0.0006
  EXPECT_TRUE(single_scattering_valid(0.0107, 0.0107));  // pure absorber
  EXPECT_FALSE(single_scattering_valid(0.0107, 0.02));   // κ > σ is not a medium
  // A half-depth tank tolerates twice the β.
  EXPECT_NEAR(single_scattering_error(0.002, 150), single_scattering_error(0.001), 1e-12);
  // Lowfat milk at the thesis's 16 ml is far outside (see docs/media.md).
  EXPECT_GT(single_scattering_error(0.010744), 0.6);
}

// A fresh Monte Carlo run (other seeds, another face grid) reproduces two
// measured entries (their own κ column) within its noise: the table is data.
TEST(MediumRegime, FreshMonteCarloAgreesWithTheTable) {
  const struct {
    double beta, kappa, measured, measured_se;
  } cases[] = {{0.0005, 0.0, 0.0503, 0.0062}, {0.002, 0.004, 0.1966, 0.0084}};
  for (const auto& c : cases) {
    Scene s = tank_scene(R"("sigma_t_per_mm": 0.01, "sigma_s_per_mm": 0.01, "g": 0.9)");
    s.medium->sigma_t_per_mm = c.beta + c.kappa;
    s.medium->sigma_s_per_mm = c.beta;
    const TankEnergy e = tank_energy_monte_carlo(*s.medium, 30, 25, 2000, 99, 2);
    EXPECT_NEAR(e.relative_excess, c.measured, 4 * std::hypot(e.relative_excess_se, c.measured_se))
        << "beta " << c.beta << " kappa " << c.kappa << " se " << e.relative_excess_se;
    EXPECT_LE(e.relative_excess, single_scattering_error(c.beta) + 4 * e.relative_excess_se);
  }
}

}  // namespace
}  // namespace procam::sim
