// SPDX-License-Identifier: MIT
// Method `concentration` end to end (thesis §4.2.4, Fig. 4.7; M3): one HDR
// bracket per volume of the bulb's direct image, synthesised from Eq. 4.3
// in radiance, E(s) = W exp(-sigma_hat(V) l(s)), l(s) = B - sqrt(R^2 - s^2)
// (s: lateral offset from the bulb centre), quantised to 12 bits. The true
// sigma_hat(V) is chosen per case: linear (a Merlot-like absorber), bending
// below the line (milk-like multiple scattering), or crossing the 0.04 /mm
// bound.
#include "medium_session.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <functional>
#include <random>

namespace procam::medium {
namespace {

constexpr uint32_t kW = 120, kH = 100, kBits = 12;
constexpr double kMmPerPx = 1.5, kR = 15, kB = 150, kW0 = 0.05 * 4095 / 255;  // W in DN/us

struct Result {
  sdk::Outputs out;
  nlohmann::json report;
  double best = std::nan("");
};

void run(const std::vector<double>& volumes, const std::function<double(double)>& sigma_hat, Result& res) {
  std::string csv;
  for (double v : volumes) csv += (csv.empty() ? "" : ",") + std::to_string(v);
  const nlohmann::json params = {{"volumes_ml", csv}, {"bulb_x_px", 0}, {"bulb_y_px", 50}, {"bulb_radius_mm", kR},
                                 {"mm_per_px", kMmPerPx}, {"tank_depth_mm", 2 * kB}};
  const nlohmann::json rig = {{"projector", {{"width", 32}, {"height", 24}}},
                              {"cameras", {{{"width", kW}, {"height", kH}, {"bit_depth", kBits}}}},
                              {"threads", 2}};
  std::unique_ptr<sdk::Session> s;
  sdk::Error e = create_session({"concentration", params, rig}, s);
  ASSERT_TRUE(e.ok()) << e.message;
  std::mt19937 rng(5);
  std::normal_distribution<double> read(0, 0.5 * 16);
  for (double v : volumes) {
    sdk::Plan plan;
    bool has = false;
    ASSERT_TRUE(s->next_plan(plan, has).ok());
    ASSERT_TRUE(has);
    ASSERT_EQ(plan.size(), 25u);
    for (uint32_t i = 0; i < plan.size(); ++i) {
      const double t = plan.settings(i).exposure_us;
      std::vector<uint16_t> f(size_t{kW} * kH);
      for (uint32_t y = 0; y < kH; ++y)
        for (uint32_t x = 0; x < kW; ++x) {
          const double smm = std::hypot(double(x), double(y) - 50.0) * kMmPerPx;
          const double l = smm < kR ? kW0 * std::exp(-sigma_hat(v) * (kB - std::sqrt(kR * kR - smm * smm))) : 0.0;
          f[size_t{y} * kW + x] = static_cast<uint16_t>(std::clamp(std::round(l * t + 40 + read(rng)), 0.0, 4095.0));
        }
      ASSERT_TRUE(s->add_frame(i, sdk::gray_view(f.data(), kW, kH, kBits)).ok());
    }
    ASSERT_TRUE(s->end_round().ok());
  }
  bool has = false;  // as the SDK's wrapper passes it: the session sets it only for a round
  sdk::Plan done;
  ASSERT_TRUE(s->next_plan(done, has).ok());
  ASSERT_FALSE(has);
  ASSERT_TRUE(s->outputs(res.out).ok());
  for (size_t i = 0; i < res.out.size(); ++i) {
    const procam_output& o = res.out.view()[i];
    if (std::strcmp(o.name, "report") == 0) res.report = nlohmann::json::parse(o.json);
    if (std::strcmp(o.name, "best_volume_ml") == 0) res.best = o.scalar;
    if (std::strcmp(o.name, "sigma_hat_plot") == 0) {
      EXPECT_EQ(o.image.pixel_type, PROCAM_PIXEL_U8);
    }
  }
}

// sigma-hat per volume within 2 % (+ 2e-5 /mm) of the truth.
void expect_sigma_hat(const Result& r, const std::function<double(double)>& truth) {
  for (const auto& p : r.report["dilutions"]["points"]) {
    const double v = p["volume_ml"], s = p["sigma_hat_per_mm"];
    EXPECT_NEAR(s, truth(v), 0.02 * truth(v) + 2e-5) << v << " ml";
  }
}

std::string warnings(const Result& r) { return r.report["dilutions"]["warnings"].dump(); }

TEST(Concentration, AbsorberStaysLinearAndTheLargestVolumeIsBest) {
  const auto merlot = [](double v) { return 0.0005 * v; };  // linear at every volume (Fig. 4.7, MERLOT)
  Result r;
  run({0, 2, 4, 8, 16, 32, 64}, merlot, r);
  expect_sigma_hat(r, merlot);
  EXPECT_EQ(r.best, 64.0);
  EXPECT_FALSE(r.report["dilutions"].contains("stop_volume_ml")) << warnings(r);
  EXPECT_NEAR(r.report["dilutions"]["slope_per_mm_per_ml"].get<double>(), 0.0005, 1e-5);
  EXPECT_EQ(r.report["method"], "concentration");
}

TEST(Concentration, ScatteringMediumDepartsFromTheLineAndIsStopped) {
  // Multiple scattering: sigma-hat bends below sigma = c V (Fig. 4.7, milk).
  const auto milk = [](double v) { return 0.0011 * v / (1 + v / 16); };
  Result r;
  run({0, 2, 4, 8, 16, 32}, milk, r);
  expect_sigma_hat(r, milk);
  EXPECT_EQ(r.best, 8.0);
  EXPECT_EQ(r.report["dilutions"]["first_nonlinear_volume_ml"], 16.0);
  EXPECT_EQ(r.report["dilutions"]["stop_volume_ml"], 16.0);
  EXPECT_NE(warnings(r).find("STOP at volume 16 ml"), std::string::npos) << warnings(r);
}

TEST(Concentration, BeyondTheSingleScatteringBoundIsStopped) {
  const auto dense = [](double v) { return 0.003 * v; };  // linear, but 0.048 /mm at 16 ml > 0.04
  Result r;
  run({0, 2, 4, 8, 16}, dense, r);
  expect_sigma_hat(r, dense);
  EXPECT_EQ(r.best, 8.0);
  EXPECT_EQ(r.report["dilutions"]["first_over_bound_volume_ml"], 16.0);
  EXPECT_NE(warnings(r).find("exceeds max_sigma_per_mm"), std::string::npos) << warnings(r);
}

}  // namespace
}  // namespace procam::medium
