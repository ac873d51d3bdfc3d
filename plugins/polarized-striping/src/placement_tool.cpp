// SPDX-License-Identifier: MIT
// procam-placement: the source–camera separation that maximises CQM·W (flood)
// and GQM·W (light sheet) in a medium (thesis §5.3; placement.hpp).
//   procam_polarized_striping_placement [--sigma 0.005] [--beta 0.004] [--g 0.8]
//       [--distance 500] [--albedo 0.6] [--p 0.8] [--noise 5e-4] [--sheet 5]
//       [--min 0] [--max 800] [--steps 41] [--quality 1] [--csv curve.csv] [--png curve.png]
// Prints a JSON summary on stdout; exit 2 on bad arguments (saying which).
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <map>
#include <string>

#include <nlohmann/json.hpp>

#include "placement.hpp"

using procam::polarized_striping::PlacementParams;

int main(int argc, char** argv) {
  PlacementParams p;
  std::string csv, png;
  const std::map<std::string, double*> numbers = {
      {"--sigma", &p.sigma_per_mm}, {"--beta", &p.beta_per_mm}, {"--g", &p.g}, {"--distance", &p.distance_mm},
      {"--albedo", &p.albedo}, {"--p", &p.p}, {"--noise", &p.noise}, {"--sheet", &p.sheet_mm},
      {"--min", &p.min_separation_mm}, {"--max", &p.max_separation_mm}};
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (i + 1 >= argc) {
      std::fprintf(stderr, "option %s needs a value\n", a.c_str());
      return 2;
    }
    const std::string v = argv[++i];
    char* end = nullptr;
    const double x = std::strtod(v.c_str(), &end);
    const bool numeric = end != v.c_str() && *end == '\0';
    if (a == "--csv") csv = v;
    else if (a == "--png") png = v;
    else if (numbers.count(a) && numeric) *numbers.at(a) = x;
    else if (a == "--steps" && numeric) p.steps = int(x);
    else if (a == "--quality" && numeric) p.quality = int(x);
    else {
      std::fprintf(stderr, "unknown option or non-numeric value: %s %s (see the file comment for options)\n",
                   a.c_str(), v.c_str());
      return 2;
    }
  }
  if (const std::string err = procam::polarized_striping::check(p); !err.empty()) {
    std::fprintf(stderr, "bad parameters: %s\n", err.c_str());
    return 2;
  }
  const auto r = procam::polarized_striping::evaluate_placement(p);
  if (!csv.empty()) std::ofstream(csv) << procam::polarized_striping::placement_csv(r);
  if (!png.empty()) {
    const auto bytes = procam::polarized_striping::placement_png(r);
    std::ofstream(png, std::ios::binary).write(reinterpret_cast<const char*>(bytes.data()), std::streamsize(bytes.size()));
  }
  const nlohmann::json j = {{"best_flood_separation_mm", r.best_flood_mm},
                            {"best_sheet_separation_mm", r.best_sheet_mm},
                            {"best_flood_cqm_w", r.curve[r.best_flood_index].cqm_w},
                            {"best_sheet_gqm_w", r.curve[r.best_sheet_index].gqm_w},
                            {"samples", r.curve.size()}};
  std::printf("%s\n", j.dump(2).c_str());
  return 0;
}
