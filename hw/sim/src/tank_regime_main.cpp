// SPDX-License-Identifier: MIT
// procam_medium_regime: where single scattering holds in the dilution tank
// (thesis §4.2.3, Fig. 4.5). For a grid of extinction σ and absorption
// κ = σ − β it renders the tank's face by Monte Carlo with all orders of
// scattering and records the share of the image's energy that single
// scattering misses, (E_all − E_single)/E_all, as CSV and a PNG heat map.
//
//   procam_medium_regime [--scene NAME|PATH] [--g G] [--paths N] [--grid NX NY]
//                        [--sigma a,b,...|--beta a,b,...] [--kappa a,b,...] [--out DIR] [--threads T] [--rms]
//
// --beta gives the columns as scattering β (σ = β + κ) instead of σ.
// Defaults: the tank-lowfat-milk scene's tank and bulb, g 0.9, 400 paths at
// each of 8 × 6 face points, σ 0.0025–0.04 /mm, κ 0–0.008 /mm, out ".".
// Writes DIR/medium_regime.csv (sigma_per_mm, kappa_per_mm, g, single_ru,
// total_ru, relative_excess, relative_excess_se, relative_rms; tank.hpp
// TankEnergy) and DIR/medium_regime.png (columns σ, rows κ growing
// downwards; colour: relative_excess, or relative_rms with --rms, blue 0 →
// red ≥ 0.5; dark grey for κ > σ; a white frame marks cells under 5 %).
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "procam/core/image_io.hpp"
#include "procam/hw/sim/scene.hpp"
#include "tank.hpp"

namespace {

std::vector<double> parse_list(const std::string& s) {
  std::vector<double> v;
  std::stringstream ss(s);
  std::string tok;
  while (std::getline(ss, tok, ',')) v.push_back(std::strtod(tok.c_str(), nullptr));
  return v;
}

int usage(const char* why) {
  std::fprintf(stderr,
               "procam_medium_regime: %s\nusage: procam_medium_regime [--scene NAME|PATH] [--g G] [--paths N] "
               "[--grid NX NY] [--sigma a,b,..|--beta a,b,..] [--kappa a,b,..] [--out DIR] [--threads T] [--rms]\n",
               why);
  return 2;
}

// Heat colour for an excess e in [0, 0.5]: blue (0) → yellow → red (0.5+).
void heat(double e, uint8_t* rgb) {
  const double t = std::clamp(e / 0.5, 0.0, 1.0);
  rgb[0] = static_cast<uint8_t>(255 * std::min(1.0, 2 * t));
  rgb[1] = static_cast<uint8_t>(255 * (t < 0.5 ? 2 * t : 2 - 2 * t));
  rgb[2] = static_cast<uint8_t>(255 * (1 - t));
}

}  // namespace

int main(int argc, char** argv) {
  using namespace procam;
  using namespace procam::sim;
  std::string scene_name = "tank-lowfat-milk", out = ".";
  double g = 0.9;
  size_t paths = 400;
  int nx = 8, ny = 6, threads = 2;
  bool rms = false;      // colour the PNG by relative_rms instead of relative_excess
  bool by_beta = false;  // columns are β = σ − κ (--beta) instead of σ
  std::vector<double> sigmas{0.0025, 0.005, 0.01, 0.02, 0.03, 0.04}, kappas{0, 0.001, 0.002, 0.004, 0.008};
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    auto next = [&]() -> const char* { return i + 1 < argc ? argv[++i] : nullptr; };
    const char* v = nullptr;
    if (a == "--scene" && (v = next())) scene_name = v;
    else if (a == "--g" && (v = next())) g = std::strtod(v, nullptr);
    else if (a == "--paths" && (v = next())) paths = std::strtoull(v, nullptr, 10);
    else if (a == "--grid" && i + 2 < argc) { nx = std::atoi(argv[++i]); ny = std::atoi(argv[++i]); }
    else if (a == "--sigma" && (v = next())) sigmas = parse_list(v);
    else if (a == "--kappa" && (v = next())) kappas = parse_list(v);
    else if (a == "--out" && (v = next())) out = v;
    else if (a == "--threads" && (v = next())) threads = std::atoi(v);
    else if (a == "--rms") rms = true;
    else if (a == "--beta" && (v = next())) { sigmas = parse_list(v); by_beta = true; }
    else return usage(("unknown or incomplete argument " + a).c_str());
  }
  if (!(std::abs(g) < 1) || paths == 0 || nx < 1 || ny < 1 || sigmas.empty() || kappas.empty())
    return usage("need |g| < 1, paths > 0, a grid of at least 1x1 and non-empty sigma and kappa lists");
  const std::vector<std::string> dirs{PROCAM_SOURCE_DIR "/configs/scenes", "configs/scenes"};
  const Result<Scene> scene = load_scene(scene_name, dirs);
  if (!scene.ok() || !scene->medium || !scene->medium->bulb) {
    std::fprintf(stderr, "procam_medium_regime: scene '%s' %s\n", scene_name.c_str(),
                 scene.ok() ? "has no tank with a bulb" : scene.status().message().c_str());
    return 1;
  }
  std::filesystem::create_directories(out);
  std::ofstream csv(out + "/medium_regime.csv");
  csv << "sigma_per_mm,kappa_per_mm,g,single_ru,total_ru,relative_excess,relative_excess_se,relative_rms\n";
  constexpr uint32_t kCell = 48;
  Image png(static_cast<uint32_t>(sigmas.size()) * kCell, static_cast<uint32_t>(kappas.size()) * kCell,
            PixelType::u8, 3);
  for (size_t ki = 0; ki < kappas.size(); ++ki)
    for (size_t si = 0; si < sigmas.size(); ++si) {
      const double kappa = kappas[ki], sigma = by_beta ? sigmas[si] + kappa : sigmas[si];
      uint8_t rgb[3] = {40, 40, 40};
      bool valid = false;
      if (kappa <= sigma) {
        Medium m = *scene->medium;
        m.sigma_t_per_mm = sigma;
        m.sigma_s_per_mm = sigma - kappa;
        m.g = g;
        const TankEnergy e = tank_energy_monte_carlo(m, nx, ny, paths, 1000 * ki + si + 1, threads);
        csv << sigma << ',' << kappa << ',' << g << ',' << e.single << ',' << e.total << ',' << e.relative_excess
            << ',' << e.relative_excess_se << ',' << e.relative_rms << '\n';
        std::fprintf(stderr, "sigma %.4f kappa %.4f: excess %.4f ± %.4f, rms %.4f\n", sigma, kappa, e.relative_excess,
                     e.relative_excess_se, e.relative_rms);
        const double metric = rms ? e.relative_rms : e.relative_excess;
        heat(metric, rgb);
        valid = metric < 0.05;
      }
      for (uint32_t y = 0; y < kCell; ++y)
        for (uint32_t x = 0; x < kCell; ++x) {
          const bool edge = x < 3 || y < 3 || x >= kCell - 3 || y >= kCell - 3;
          uint8_t* p = png.data() + 3 * ((ki * kCell + y) * png.width() + si * kCell + x);
          for (int c = 0; c < 3; ++c) p[c] = edge ? (valid ? 255 : 0) : rgb[c];
        }
    }
  const Status st = write_image(out + "/medium_regime.png", png);
  if (!st.ok()) {
    std::fprintf(stderr, "procam_medium_regime: %s\n", st.message().c_str());
    return 1;
  }
  return 0;
}
