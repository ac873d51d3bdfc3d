// SPDX-License-Identifier: MIT
// Thesis ch. 4 claims (issue 14) end to end: the `medium` plugin's `measure`
// bracket captured by the sim's dilution-tank rig (hw/sim tank.*, an
// independent implementation of Eq. 4.1-4.2 with the area bulb of §4.3.3),
// merged to HDR, fitted, and compared with the material library's truth.
//
// Rig: configs/rigs/sim-tank.json at half its resolution (640x400, 0.8 mm
// per pixel at the tank's face) to keep the test short. The plugin gets the
// geometry a user measures on a real rig (bulb centre's pixel, mm per pixel,
// tank and bulb depth, bulb radius, the face rectangle as ROI) from the
// sim's tank truth, and I0 in DN (Eq. 4.5's scale) and the bulb's radiance
// through pure water W (for pure absorbers, Eq. 4.3) from the same record.
// Scenes: configs/scenes/tank-lowfat-milk.json with the material, volume and
// colour channel replaced (written into a temporary scene folder).
//
// Tolerances (thesis §4.4): sigma and beta within 3 % for highly scattering
// media (beta/sigma >= 0.5) and 6 % for low-scattering ones, fit RMS below
// 3 % and 6 %. Pure absorbers (beta/sigma < 0.01): sigma within 3 %, g
// reported undefined.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <functional>
#include <string>
#include <tuple>
#include <unistd.h>
#include <vector>

#include "procam/hw/sim/medium_library.hpp"
#include "fit.hpp"
#include "params.hpp"
#include "sim_scan.hpp"

namespace procam {
namespace {

namespace fs = std::filesystem;
using testing::ScanRun;

struct Case {
  std::string material;
  double volume_ml;   // in the 23 l tank
  std::string channel;
};

// A scratch scene folder for this process.
const fs::path& scene_dir() {
  static const fs::path dir = [] {
    fs::path d = fs::temp_directory_path() / ("procam-medium-claims-" + std::to_string(::getpid()));
    fs::create_directories(d);
    return d;
  }();
  return dir;
}

// Writes the tank scene for `c` and returns its name.
std::string write_scene(const Case& c, size_t index) {
  auto base = engine::read_json_file(testing::source_path("configs/scenes/tank-lowfat-milk.json"));
  EXPECT_TRUE(base.ok()) << base.status().message();
  nlohmann::json s = base.ok() ? *base : nlohmann::json::object();
  const std::string name = "claims-" + std::to_string(index);
  s["name"] = name;
  s["medium"]["material"] = c.material;
  s["medium"]["volume_ml"] = c.volume_ml;
  s["medium"]["channel"] = c.channel;
  std::ofstream(scene_dir() / (name + ".json")) << s.dump(1);
  return name;
}

struct Measured {
  double sigma = std::nan(""), beta = std::nan(""), g = std::nan(""), rms = std::nan("");
  double true_sigma = std::nan(""), true_beta = std::nan(""), true_g = std::nan("");
  double sigma_ci = std::nan(""), beta_ci = std::nan(""), kappa_ci = std::nan("");  // reported 95 % half-widths
  bool g_defined = true;
  std::string model;
};

// Plugin parameters from the sim's tank record (what a user measures on a
// real rig: docs/medium.md "Real-rig recipe").
nlohmann::json params_from_tank(const nlohmann::json& t, double mask_mm) {
  const double mm_px = t.at("mm_per_px_x").get<double>();
  const auto face = t.at("face_px");
  // I0 in (DN/us) mm^2: the record's dn_per_ru is at its exposure.
  const double dn_per_us = t.at("dn_per_ru").get<double>() / t.at("exposure_us").get<double>();
  const double i0 = t.at("bulb_intensity_iu_mm2").get<double>() * dn_per_us;
  // W: the bulb's radiance through pure water (recipe step 4), DN/us.
  const double water = t.at("bulb_radiance_ru").get<double>() * dn_per_us;
  return {{"tank_depth_mm", t.at("depth_mm")},
          {"bulb_depth_mm", t.at("bulb_depth_mm")},
          {"bulb_radius_mm", t.at("bulb_radius_mm")},
          {"bulb_x_px", t.at("bulb_u_px")},
          {"bulb_y_px", t.at("bulb_v_px")},
          {"mm_per_px", mm_px},
          {"mask_radius_px", mask_mm / mm_px},
          {"roi_x0", static_cast<int>(std::ceil(face[0].get<double>())) + 1},
          {"roi_y0", static_cast<int>(std::ceil(face[1].get<double>())) + 1},
          {"roi_x1", static_cast<int>(std::floor(face[2].get<double>())) - 1},
          {"roi_y1", static_cast<int>(std::floor(face[3].get<double>())) - 1},
          {"source_intensity", i0},
          {"water_radiance", water},
          // The shortest exposure leaves the bulb's own image at half of full
          // scale (12-bit camera), as the recipe asks for pure absorbers.
          {"exposure_min_us", std::min(2000.0, 0.5 * 4095.0 / water)}};
}

// A number from a report object; NaN when absent or null (NaN is written as null).
double num(const nlohmann::json& j, const char* key) {
  return j.is_object() && j.contains(key) && j[key].is_number() ? j[key].get<double>() : std::nan("");
}

double rel(double est, double truth) { return (est - truth) / truth; }

// `measure` on the sim tank with scene `scene` (a shipped one or one written
// by write_scene()).
// `edit` changes the rig config (camera noise, bit depth, seed), `extra`
// adds or overrides plugin params, `keep` receives the scan (images, truth).
bool measure_scene(const std::string& scene, Measured& m, const std::string& source_model = "",
                   const std::function<void(nlohmann::json&)>& edit = {}, const nlohmann::json& extra = {},
                   ScanRun* keep = nullptr, int scale = 2) {
  const std::string label = scene;
  testing::RigChoice choice;
  choice.rig_file = "sim-tank.json";
  choice.scale = scale;
  choice.scene_dirs = {scene_dir().string()};
  choice.edit = edit;
  ScanRun local;
  ScanRun& r = keep != nullptr ? *keep : local;
  r.rig = testing::scaled_rig(scene, choice);
  if (!r.rig) return false;
  auto truth = r.rig->ground_truth(0);
  EXPECT_TRUE(truth.ok()) << truth.status().to_string();
  if (!truth.ok() || !truth->medium.contains("tank")) return false;
  const nlohmann::json& t = truth->medium["tank"];
  m.true_sigma = t.at("extinction_per_mm").get<double>();
  m.true_beta = t.at("scattering_per_mm").get<double>();
  m.true_g = t.at("hg_g").is_number() ? t.at("hg_g").get<double>() : std::nan("");
  // Mask 2.5 bulb radii: the plugin models a point source (docs/medium.md
  // "Limits"); the sim's bulb is a 10 mm sphere.
  nlohmann::json params = params_from_tank(t, 2.5 * t.at("bulb_radius_mm").get<double>());
  if (!source_model.empty()) params["source_model"] = source_model;
  if (extra.is_object())
    for (const auto& [k, v] : extra.items()) params[k] = v;
  if (!testing::run_on_rig("medium", "measure", params, r)) return false;
  const nlohmann::json rep = testing::output_report(r);
  EXPECT_TRUE(rep.is_object() && rep.contains("fit")) << label;
  if (!rep.is_object() || !rep.contains("fit")) return false;
  const nlohmann::json& f = rep["fit"];
  EXPECT_FALSE(f.contains("error")) << label << ": " << f.value("error", "");
  if (f.contains("error")) return false;
  m.sigma = num(f["sigma_per_mm"], "value");
  m.beta = num(f["beta_per_mm"], "value");
  m.sigma_ci = num(f["sigma_per_mm"], "ci95");
  m.beta_ci = num(f["beta_per_mm"], "ci95");
  m.kappa_ci = num(f["kappa_per_mm"], "ci95");
  m.g = num(f["g"], "value");
  m.g_defined = f.value("g_defined", true);
  m.rms = num(f, "rms_percent");
  m.model = f.value("model", "");
  if (!std::isfinite(m.sigma)) ADD_FAILURE() << label << ": no sigma; the fit said " << f.dump();
  return true;
}

bool measure(const Case& c, size_t index, Measured& m, const std::string& source_model = "",
             const nlohmann::json& extra = {}) {
  return measure_scene(write_scene(c, index), m, source_model, {}, extra);
}

// Rows measured with their own settings, not the defaults (docs/medium.md
// "Limits"). Pepsi (beta/sigma = 0.014, g = 0.979): beta's share of the
// image is tiny and, with g this close to 1, beta is fixed only through g
// (d ln beta / dg ~ -40 near the mask), so the default fit's beta scatters
// by ~6 % (SD over seeds) at half resolution and misses 6 % on half of the
// seeds (brief pepsi14: -7.3 / +7.6 / +1.9 / -3.2 %). Weighted by the
// stated noise model, profiled, and fitting only bins above 10 % of full
// scale at 10 s it stays within 6 % on seeds 1-4.
nlohmann::json own_settings(const std::string& material) {
  if (material == "Pepsi") return {{"objective", "profiled"}, {"weights", "noise"}, {"min_signal", 0.1}};
  return nlohmann::json::object();
}

// Thesis §4.4: parameters rendered from Table 4.1 at the thesis's dilutions
// are fitted back within 3 % (sigma, beta) for highly scattering media and
// 6 % for low-scattering ones, with fit RMS < 3 % and < 6 %.
TEST(MediumClaims, Table41MaterialsFitBackThroughTheSimTank) {
  // Chosen to span the table: strongly scattering milks and a juice, weakly
  // scattering coffee and juice, and a pure absorber; green channel (the sim
  // is mono), red for one material to cover a second channel.
  // At each material's own table dilution (a natural-concentration entry
  // fills the tank). PROCAM_MEDIUM_CLAIMS_ALL=1 runs every row of the table
  // (about 40 scans; for the report).
  std::vector<Case> cases;
  // PROCAM_MEDIUM_CLAIMS_ONLY=<material> runs that one row (green).
  const char* all = std::getenv("PROCAM_MEDIUM_CLAIMS_ALL");
  const char* only = std::getenv("PROCAM_MEDIUM_CLAIMS_ONLY");
  const std::vector<std::string> names =
      only != nullptr ? std::vector<std::string>{only}
      : all && std::string(all) == "1"
          ? std::vector<std::string>{}
          : std::vector<std::string>{"Lowfat Milk", "Regular Chocolate Milk", "White Grapefruit Juice", "Espresso",
                                     "Mint Mocha Coffee", "Apple Juice", "Merlot"};
  for (const sim::LibraryMaterial& lm : sim::material_library()) {
    if (!names.empty() && std::find(names.begin(), names.end(), lm.name) == names.end()) continue;
    cases.push_back({lm.name, lm.volume_ml > 0 ? lm.volume_ml : 23000.0, "green"});
  }
  if (only == nullptr) cases.push_back({"Lowfat Milk", 16, "red"});
  std::printf("| material | channel | V (ml) | beta/sigma | sigma err | beta err | g (truth) | fit RMS | model |\n");
  std::printf("|---|---|---:|---:|---:|---:|---|---:|---|\n");
  for (size_t i = 0; i < cases.size(); ++i) {
    const Case& c = cases[i];
    const sim::LibraryMaterial* lm = sim::find_material(c.material);
    ASSERT_NE(lm, nullptr) << c.material << " is not in the library";
    Measured m;
    const nlohmann::json own = own_settings(c.material);
    ASSERT_TRUE(measure(c, i, m, "", own)) << c.material;
    const double albedo = m.true_beta / m.true_sigma;
    std::printf("| %s | %s | %g | %.3f | %+.2f %% | %+.2f %% | %.3f (%.3f) | %.2f %% | %s |\n", c.material.c_str(),
                c.channel.c_str(), c.volume_ml, albedo, 100 * rel(m.sigma, m.true_sigma),
                m.beta > 0 ? 100 * rel(m.beta, m.true_beta) : std::nan(""), m.g, m.true_g, m.rms,
                (m.model + (own.empty() ? "" : " (own settings: " + own.dump() + ")")).c_str());
    if (albedo < 0.01) {  // pure absorber (M5): kappa = sigma by attenuation, g undefined
      EXPECT_LT(std::abs(rel(m.sigma, m.true_sigma)), 0.03) << c.material;
      EXPECT_FALSE(m.g_defined) << c.material;
      continue;
    }
    const bool high = albedo >= 0.5;
    const double tol = high ? 0.03 : 0.06;
    EXPECT_LT(std::abs(rel(m.sigma, m.true_sigma)), tol) << c.material << " sigma";
    EXPECT_LT(std::abs(rel(m.beta, m.true_beta)), tol) << c.material << " beta";
    EXPECT_LT(std::abs(m.g - m.true_g), 0.02) << c.material << " g";
    EXPECT_LT(m.rms, high ? 3.0 : 6.0) << c.material << " fit RMS %";
  }
}

// The model choice is visible and matters: the same lowfat milk fitted with
// the bulb as a point source (source_model = point) gets g and beta wrong,
// because the 10 mm bulb 150 mm away is as wide as H-G's forward lobe.
TEST(MediumClaims, PointSourceModelBiasesGOnTheSimsAreaBulb) {
  Measured sphere, point;
  ASSERT_TRUE(measure({"Lowfat Milk", 16, "green"}, 100, sphere));
  ASSERT_TRUE(measure({"Lowfat Milk", 16, "green"}, 101, point, "point"));
  std::printf("lowfat milk, sphere model: g %.3f beta %+.2f %%; point model: g %.3f beta %+.2f %% (truth g %.3f)\n",
              sphere.g, 100 * rel(sphere.beta, sphere.true_beta), point.g, 100 * rel(point.beta, point.true_beta),
              point.true_g);
  EXPECT_LT(std::abs(sphere.g - sphere.true_g), 0.01);
  EXPECT_GT(std::abs(point.g - point.true_g), 0.015);
  EXPECT_GT(std::abs(rel(point.beta, point.true_beta)), 0.2);
}

// Fig. 4.11's fit step end to end: `measure` on the shipped 8 ml lowfat
// chocolate milk scene (configs/scenes/tank-chocolate-milk-8ml.json, the
// camera's HDR image of the renderer's single scattering). The Monte Carlo
// comparison at 50-150 ml (medium_mc_claims_test,
// Fig411FitAt8mlScaledByEq48…) fits the renderer's profile directly and
// derives its tolerance from that fit's accuracy: sigma and beta within
// 0.4 %, g within 0.0003, kappa = sigma - beta within 5 %. This checks how
// much of that accuracy the camera pipeline keeps. Measured, not assumed:
// the bounds asserted here are claim 1's (3 %, g 0.02) and the numbers are
// printed for the report.
TEST(MediumClaims, Fig411FitStepOnTheShipped8mlScene) {
  Measured m;
  ASSERT_TRUE(measure_scene("tank-chocolate-milk-8ml", m));
  const double kappa = m.true_sigma - m.true_beta;
  std::printf("tank-chocolate-milk-8ml: sigma %+.2f %%  beta %+.2f %%  kappa = sigma - beta %+.0f %%  g %.4f (%.4f)  "
              "rms %.2f %%\n",
              100 * rel(m.sigma, m.true_sigma), 100 * rel(m.beta, m.true_beta),
              100 * rel(m.sigma - m.beta, kappa), m.g, m.true_g, m.rms);
  EXPECT_LT(std::abs(rel(m.sigma, m.true_sigma)), 0.03);
  EXPECT_LT(std::abs(rel(m.beta, m.true_beta)), 0.03);
  EXPECT_LT(std::abs(m.g - m.true_g), 0.02);
}

// Issue 14, Deliver 2: `measure` reports "the parameters per channel with
// confidence intervals"; they must be honest through the camera (sensor
// noise, 12 bit, HDR merge) with the default fit (Eq. 4.6-4.7, uniform
// weights), where brief k14 found sigma outside them in 4 of 5 seeds. The
// shipped 8 ml chocolate milk scene at quarter resolution (320 x 200) with
// 9 exposures instead of 25; seeds 101-124. A scan costs ~2 s CPU whatever
// the resolution (rig and plugin set-up), so the 24 take ~60 s CPU: run by hand
// with --gtest_also_run_disabled_tests; the suite's coverage test is
// Fit.IntervalsCoverTheTruthUnderCameraNoise (plugins/medium, ~6 s CPU).
// Stated before running: sigma and beta each inside their 95 % interval in
// >= 20 of 24 seeds (honest intervals miss more than 4 with probability
// 0.6 %), and the median half-width < 3.2 x the seeds' standard deviation
// of the estimate (1.96 if exact) so that coverage is not bought by width.
TEST(MediumClaims, DISABLED_IntervalsCoverTheTruthThroughTheCamera) {
  constexpr int kSeeds = 24, kMinCovered = 20, kScale = 4;
  int covered[2] = {0, 0};
  std::vector<double> err[2], half[2];
  for (int seed = 101; seed < 101 + kSeeds; ++seed) {
    Measured m;
    const auto edit = [&](nlohmann::json& rig) { rig["seed"] = seed; };
    ASSERT_TRUE(measure_scene("tank-chocolate-milk-8ml", m, "", edit, {{"exposures", 9}}, nullptr, kScale)) << seed;
    const double est[2] = {m.sigma, m.beta}, ci[2] = {m.sigma_ci, m.beta_ci}, truth[2] = {m.true_sigma, m.true_beta};
    for (int k = 0; k < 2; ++k) {
      ASSERT_TRUE(std::isfinite(ci[k]) && ci[k] > 0) << "seed " << seed;
      covered[k] += std::abs(est[k] - truth[k]) <= ci[k];
      err[k].push_back(rel(est[k], truth[k]));
      half[k].push_back(ci[k] / truth[k]);
    }
  }
  for (int k = 0; k < 2; ++k) {
    double mean = 0, v2 = 0;
    for (double e : err[k]) mean += e / kSeeds;
    for (double e : err[k]) v2 += (e - mean) * (e - mean) / (kSeeds - 1);
    std::sort(half[k].begin(), half[k].end());
    const size_t hm = half[k].size() / 2;
    const double med = 0.5 * (half[k][hm - 1] + half[k][hm]), sd = std::sqrt(v2);
    std::printf("camera, defaults: %-5s covered %d / %d  mean error %+.3f %% (SD %.3f %%)  median ci95 %.3f %% = %.2f SD\n",
                k == 0 ? "sigma" : "beta", covered[k], kSeeds, 100 * mean, 100 * sd, 100 * med, med / sd);
    EXPECT_GE(covered[k], kMinCovered) << (k == 0 ? "sigma" : "beta");
    EXPECT_LT(med, 3.2 * sd) << (k == 0 ? "sigma" : "beta");
  }
}

// Why `measure` on the 8 ml scene is biased differently in sigma and beta
// (issue 14 brief k14): the same scene through variants of the camera and
// the fit, each printed with three views of the same run:
//  - `measure`: the plugin end to end (errors and its reported 95 % CIs);
//  - oracle: the plugin's own binning and fit (same params) on the sim's
//    noise-free radiance of the scattered light (ground truth B / exposure),
//    i.e. the pipeline without the camera and the HDR merge;
//  - HDR/truth: the merged radiance over that truth per pixel, averaged in
//    bands of rho (what the camera and the merge add to the profile).
// Exploration, not a claim: run by hand with --gtest_also_run_disabled_tests.
struct CameraVariant {
  std::string label;
  uint64_t seed = 1;
  bool noise = true;
  int bits = 12;
  nlohmann::json extra = nlohmann::json::object();
  std::string scene = "tank-chocolate-milk-8ml";
};

void run_variant(const CameraVariant& v) {
  Measured m;
  ScanRun r;
  const auto edit = [&](nlohmann::json& rig) {
    rig["seed"] = v.seed;
    for (auto& c : rig["cameras"]) {
      c["bit_depth"] = v.bits;
      if (!v.noise) {
        c["shot_noise"] = false;
        c["read_noise_e"] = 0.0;
      }
    }
  };
  ASSERT_TRUE(measure_scene(v.scene, m, "", edit, v.extra, &r)) << v.label;
  const double kappa = m.true_sigma - m.true_beta;
  std::printf("%-34s measure: sigma %+.3f %% (CI %.3f %%)  beta %+.3f %% (CI %.3f %%)  kappa %+5.1f %% (CI %.0f %%)  "
              "g %+.5f\n",
              v.label.c_str(), 100 * rel(m.sigma, m.true_sigma), 100 * m.sigma_ci / m.true_sigma,
              100 * rel(m.beta, m.true_beta), 100 * m.beta_ci / m.true_beta, 100 * rel(m.sigma - m.beta, kappa),
              100 * m.kappa_ci / kappa, m.g - m.true_g);
  const nlohmann::json& t = r.truth.medium["tank"];
  const double t0 = t.at("exposure_us").get<double>();
  const auto& b = r.truth.medium_backscatter;
  ASSERT_FALSE(b.empty());
  const uint32_t w = b.width(), h = b.height();
  std::vector<float> truth(b.pixel_count());
  for (size_t i = 0; i < truth.size(); ++i) truth[i] = static_cast<float>(double(b.ptr<float>()[i]) / t0);
  nlohmann::json params = params_from_tank(t, 2.5 * t.at("bulb_radius_mm").get<double>());
  for (const auto& [k, val] : v.extra.items()) params[k] = val;
  medium::Config cfg;
  ASSERT_TRUE(medium::parse_config("measure", params, w, h, cfg).ok());
  const medium::FitResult o = medium::fit_profile(medium::radial_profile(truth, w, h, cfg.fit), cfg.fit, truth, w, h);
  std::printf("%-34s oracle:  sigma %+.3f %%  beta %+.3f %%  kappa %+5.1f %%  g %+.5f\n", "", 100 * rel(o.sigma.value, m.true_sigma),
              100 * rel(o.beta.value, m.true_beta), 100 * rel(o.sigma.value - o.beta.value, kappa), o.g.value - m.true_g);
  // The same noise-free image, other objectives and weights.
  for (const auto& [name, obj, wts] : {std::tuple{"profiled", medium::Objective::profiled, medium::Weights::uniform},
                                       {"normalized, noise weights", medium::Objective::normalized, medium::Weights::noise},
                                       {"profiled, noise weights", medium::Objective::profiled, medium::Weights::noise}}) {
    medium::FitSettings fs = cfg.fit;
    fs.objective = obj;
    fs.weights = wts;
    const medium::FitResult q = medium::fit_profile(medium::radial_profile(truth, w, h, fs), fs, truth, w, h);
    std::printf("%-34s oracle %s: sigma %+.3f %%  beta %+.3f %%  kappa %+5.1f %%  g %+.5f\n", "", name,
                100 * rel(q.sigma.value, m.true_sigma), 100 * rel(q.beta.value, m.true_beta),
                100 * rel(q.sigma.value - q.beta.value, kappa), q.g.value - m.true_g);
  }
  // The image against the plugin's model at the true medium, per bin.
  {
    const medium::RadialProfile prof = medium::radial_profile(truth, w, h, cfg.fit);
    std::vector<double> rr;
    for (const medium::Bin& bn : prof.bins) rr.push_back(bn.rho_mm);
    std::vector<double> k;
    medium::ProfileModel(cfg.fit.tank, rr).evaluate(m.true_sigma, m.true_g, medium::Phase::henyey_greenstein, 99, k);
    const double i0 = cfg.fit.source_intensity;
    std::printf("%-34s image / model(truth) - 1 at rho (mm):", "");
    double next = 0;
    for (size_t i = 0; i < prof.bins.size(); ++i)
      if (prof.bins[i].rho_mm >= next) {
        std::printf("  %.0f: %+.3f %%", prof.bins[i].rho_mm, 100 * (prof.bins[i].mean / (m.true_beta * i0 * k[i]) - 1));
        next = prof.bins[i].rho_mm < 40 ? prof.bins[i].rho_mm + 5 : prof.bins[i].rho_mm * 1.3;
      }
    std::printf("\n");
  }
  const float* hdr = testing::output_image(r, "radiance");
  ASSERT_NE(hdr, nullptr);
  const double bands[] = {0, 50, 100, 150, 200, 400};
  double sum[5] = {}, cnt[5] = {};
  for (uint32_t y = uint32_t(cfg.fit.roi_y0); y <= uint32_t(cfg.fit.roi_y1); ++y)
    for (uint32_t x = uint32_t(cfg.fit.roi_x0); x <= uint32_t(cfg.fit.roi_x1); ++x) {
      const double rho_px = std::hypot(x - cfg.fit.bulb_x_px, y - cfg.fit.bulb_y_px);
      if (rho_px < cfg.fit.mask_radius_px) continue;
      const size_t i = size_t{y} * w + x;
      if (!(truth[i] > 0) || !std::isfinite(hdr[i])) continue;
      const double rho = rho_px * cfg.fit.mm_per_px;
      for (int k = 0; k < 5; ++k)
        if (rho >= bands[k] && rho < bands[k + 1]) sum[k] += double(hdr[i]) / double(truth[i]) - 1, cnt[k] += 1;
    }
  std::printf("%-34s HDR/truth - 1 by rho band (mm):", "");
  for (int k = 0; k < 5; ++k) std::printf("  %g-%g: %+.4f %%", bands[k], bands[k + 1], cnt[k] > 0 ? 100 * sum[k] / cnt[k] : std::nan(""));
  std::printf("\n");
  // The same by the truth's signal in the longest exposure (DN): the merge's
  // bias depends on it (the camera's clip at black, the floor at 2 % of full scale).
  const double t_max = params.value("exposure_max_us", 1e7);
  const double levels[] = {0, 20, 82, 205, 410, 1000, 4000, 1e12};
  double ls[7] = {}, lc[7] = {};
  for (uint32_t y = uint32_t(cfg.fit.roi_y0); y <= uint32_t(cfg.fit.roi_y1); ++y)
    for (uint32_t x = uint32_t(cfg.fit.roi_x0); x <= uint32_t(cfg.fit.roi_x1); ++x) {
      if (std::hypot(x - cfg.fit.bulb_x_px, y - cfg.fit.bulb_y_px) < cfg.fit.mask_radius_px) continue;
      const size_t i = size_t{y} * w + x;
      if (!(truth[i] > 0) || !std::isfinite(hdr[i])) continue;
      const double dn = double(truth[i]) * t_max;
      for (int k = 0; k < 7; ++k)
        if (dn >= levels[k] && dn < levels[k + 1]) ls[k] += double(hdr[i]) / double(truth[i]) - 1, lc[k] += 1;
    }
  std::printf("%-34s HDR/truth - 1 by DN at the longest exposure:", "");
  for (int k = 0; k < 7; ++k)
    std::printf("  %g-%g: %+.3f %% (%.0f px)", levels[k], levels[k + 1], lc[k] > 0 ? 100 * ls[k] / lc[k] : std::nan(""), lc[k]);
  std::printf("\n");
}

TEST(MediumClaims, DISABLED_Fig411CameraBiasBreakdown) {
  std::vector<CameraVariant> vs = {
      {"noise off, 12 bit", 1, false, 12},
      {"noise off, 16 bit", 1, false, 16},
      {"noise on, 12 bit, seed 1 (shipped)", 1, true, 12},
  };
  for (uint64_t seed = 2; seed <= 5; ++seed) vs.push_back({"noise on, 12 bit, seed " + std::to_string(seed), seed, true, 12});
  vs.push_back({"noise on, 16 bit, seed 1", 1, true, 16});
  vs.push_back({"noise on, 12 bit, 49 exposures", 1, true, 12, {{"exposures", 49}}});
  for (uint64_t seed = 1; seed <= 5; ++seed) {
    const std::string sd = ", seed " + std::to_string(seed);
    vs.push_back({"noise on, profiled" + sd, seed, true, 12, {{"objective", "profiled"}}});
    vs.push_back({"noise on, noise weights" + sd, seed, true, 12, {{"weights", "noise"}}});
    vs.push_back({"noise on, profiled, noise weights" + sd, seed, true, 12, {{"objective", "profiled"}, {"weights", "noise"}}});
  }
  const char* only = std::getenv("PROCAM_K14_ONLY");
  for (size_t i = 0; i < vs.size(); ++i)
    if (only == nullptr || std::to_string(i) == only || std::string(only).find("," + std::to_string(i) + ",") != std::string::npos)
      run_variant(vs[i]);
}


// Issue 14 brief pepsi14: why sigma is low on weak scatterers (Pepsi's beta
// misses 6 % on some noise seeds). The same breakdown as above on a Table
// 4.1 row at its table dilution (PROCAM_K14_MATERIAL, default Pepsi):
// noise-free first (a model mismatch between the renderer and the fit),
// then noise seeds. Exploration: run by hand.
TEST(MediumClaims, DISABLED_WeakScattererBiasBreakdown) {
  const char* env = std::getenv("PROCAM_K14_MATERIAL");
  const std::string material = env != nullptr ? env : "Pepsi";
  const sim::LibraryMaterial* lm = sim::find_material(material);
  ASSERT_NE(lm, nullptr) << material;
  const std::string scene = write_scene({material, lm->volume_ml > 0 ? lm->volume_ml : 23000.0, "green"}, 200);
  std::vector<CameraVariant> vs = {
      {material + ": noise off, 16 bit", 1, false, 16},
      {material + ": noise off, 12 bit", 1, false, 12},
  };
  for (uint64_t seed = 1; seed <= 8; ++seed)
    vs.push_back({material + ": noise on, 12 bit, seed " + std::to_string(seed), seed, true, 12});
  const char* only = std::getenv("PROCAM_K14_ONLY");
  const char* extra = std::getenv("PROCAM_K14_EXTRA");  // plugin params as JSON, e.g. {"min_signal":0}
  for (size_t i = 0; i < vs.size(); ++i) {
    vs[i].scene = scene;
    if (extra != nullptr) vs[i].extra = nlohmann::json::parse(extra);
    if (only == nullptr || std::to_string(i) == only || std::string(only).find("," + std::to_string(i) + ",") != std::string::npos)
      run_variant(vs[i]);
  }
}

}  // namespace
}  // namespace procam
