// SPDX-License-Identifier: MIT
// The tank rig's Monte Carlo reference (tank.hpp, tank_mc.cpp): with one
// scattering event it must reproduce the single-scattering renderer's
// profile within its noise; multiple scattering must add light, little in a
// thin tank and much in a thick one (thesis §4.2.3, Fig. 4.11).
#include <gtest/gtest.h>

#include <cmath>

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
    const TankGeometry geo = geometry_of(s);
    for (double rho : {25.0, 80.0, 160.0}) {
      const TankProfile p = tank_profile(m, geo, rho, 768);
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

TEST(TankMonteCarlo, PureAbsorberAndBadInputGiveZeroNotNaN) {
  const Scene s = tank_scene(R"("material": "Merlot", "volume_ml": 1500, "channel": "green")");
  const TankMonteCarlo mc = tank_monte_carlo(*s.medium, 0, 0, 100, 1, 10);
  EXPECT_EQ(mc.total, 0.0);
  EXPECT_EQ(mc.single, 0.0);
  const Scene milk = tank_scene(R"("material": "milk", "volume_ml": 16)");
  EXPECT_EQ(tank_monte_carlo(*milk.medium, 0, 0, 0, 1, 10).total, 0.0);
  const TankEnergy e = tank_energy_monte_carlo(*milk.medium, 4, 3, 200, 3, 2);
  EXPECT_TRUE(std::isfinite(e.relative_excess));
  EXPECT_GT(e.total, 0.0);
}

}  // namespace
}  // namespace procam::sim
