// SPDX-License-Identifier: MIT
// Speed of the medium plugin at 1280 x 800 (issue 14's goals on 2 cores):
//   BM_HdrMergeFrame  one frame folded into the HDR sums (goal <= 1 ms),
//                     8-bit and 12-bit (U16) frames, 1 and 2 threads;
//   BM_Fit            everything after the last frame of `measure`: radial
//                     profile, sigma/g search, beta, intervals, the model
//                     image for fit_residual (goal <= 2 s);
//   BM_FitProfileOnly the search on a ready profile.
//   BM_FitForwardG097 the same for g = 0.97, where the Legendre refit runs.
// The image is Eq. 4.2 for lowfat milk (Table 4.1, G) from the plugin's own
// model (speed only; accuracy is in fit_test.cpp against the brute force).
// Run: build/plugins/medium/procam_medium_bench
#include <benchmark/benchmark.h>

#include <cmath>
#include <random>
#include <vector>

#include "fit.hpp"
#include "hdr_merge.hpp"

namespace procam::medium {
namespace {

constexpr uint32_t kW = 1280, kH = 800;

FitSettings settings() {
  FitSettings s;
  s.tank = {300, 150};
  s.bulb_x_px = 0;
  s.bulb_y_px = 399.5;
  s.mm_per_px = 0.3;
  s.mask_radius_px = 20;
  s.source_intensity = 5e4;
  return s;
}

// Eq. 4.2 (beta = sigma, I0 = 5e4) with Gaussian noise at 0.03 of the mean (thesis §5.4.1's level).
std::vector<float> make_image(double sigma, double g) {
  const FitSettings s = settings();
  std::vector<double> rho;
  for (int i = 0; i < 4096; ++i) rho.push_back(std::exp(std::log(0.5) + i * (std::log(1600.0) - std::log(0.5)) / 4095) * s.mm_per_px);
  std::vector<double> k;
  ProfileModel(s.tank, rho).evaluate(sigma, g, Phase::henyey_greenstein, 99, k);
  std::vector<double> clean(size_t{kW} * kH);
  for (uint32_t y = 0; y < kH; ++y)
    for (uint32_t x = 0; x < kW; ++x) {
      const double d = std::max(0.5, std::hypot(double(x) - s.bulb_x_px, double(y) - s.bulb_y_px));
      const double t = (std::log(d) - std::log(0.5)) / (std::log(1600.0) - std::log(0.5)) * 4095;
      const auto i = std::min<size_t>(size_t(t), 4094);
      const double v = 5e4 * sigma * (k[i] + (t - double(i)) * (k[i + 1] - k[i]));
      clean[size_t{y} * kW + x] = v;
    }
  double mean = 0;
  for (double v : clean) mean += v;
  mean /= double(clean.size());
  std::mt19937 rng(1);
  std::normal_distribution<double> n(0, 0.03 * mean);
  std::vector<float> out(clean.size());
  for (size_t i = 0; i < out.size(); ++i) out[i] = static_cast<float>(clean[i] + n(rng));
  return out;
}

const std::vector<float>& milk_image() {
  static const std::vector<float> img = make_image(0.010748, 0.902);
  return img;
}

template <class T>
void merge_frame(benchmark::State& state, uint32_t bits) {
  std::vector<T> frame(size_t{kW} * kH);
  std::mt19937 rng(3);
  for (T& v : frame) v = static_cast<T>(rng() % (1u << bits));
  const procam_image view = sdk::gray_view(frame.data(), kW, kH, bits);
  HdrMerge merge(kW, kH, HdrSettings{});
  const auto threads = static_cast<uint32_t>(state.range(0));
  double t = 500;
  for (auto _ : state) {
    benchmark::DoNotOptimize(merge.add(view, t, threads));
    t *= 1.0001;
  }
  state.SetLabel(std::to_string(bits) + "-bit, " + std::to_string(threads) + " thread(s)");
}

void BM_HdrMergeFrame8(benchmark::State& state) { merge_frame<uint8_t>(state, 8); }
void BM_HdrMergeFrame12(benchmark::State& state) { merge_frame<uint16_t>(state, 12); }
BENCHMARK(BM_HdrMergeFrame8)->Arg(1)->Arg(2)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_HdrMergeFrame12)->Arg(1)->Arg(2)->Unit(benchmark::kMillisecond)->UseRealTime();

// Arg: the bulb radius in the fit's model (0 = point; 10 mm = the sphere of
// §4.3.3, its cap sampled near the forward lobe), mask 40 px = 12 mm. The
// image is the point model's, so the sphere's sigma is off: timing only.
FitSettings settings_with_bulb(int64_t radius_mm) {
  FitSettings s = settings();
  s.tank.bulb_radius_mm = s.bulb_radius_mm = double(radius_mm);
  if (radius_mm > 0) s.mask_radius_px = 40;
  return s;
}

void BM_Fit(benchmark::State& state) {
  const std::vector<float>& img = milk_image();
  const FitSettings s = settings_with_bulb(state.range(0));
  for (auto _ : state) {
    const RadialProfile p = radial_profile(img, kW, kH, s);
    const FitResult r = fit_profile(p, s, img, kW, kH);
    benchmark::DoNotOptimize(model_image(r, s, kW, kH));
    state.counters["sigma"] = r.sigma.value;
    state.counters["evals"] = r.evaluations;
  }
}
BENCHMARK(BM_Fit)->Arg(0)->Arg(10)->Unit(benchmark::kMillisecond)->UseRealTime();

// g = 0.97: the H-G fit, then the truncated Legendre refit (M5) is tried.
void BM_FitForwardG097(benchmark::State& state) {
  static const std::vector<float> img = make_image(0.008, 0.97);
  const FitSettings s = settings_with_bulb(state.range(0));
  for (auto _ : state) {
    const FitResult r = fit_profile(radial_profile(img, kW, kH, s), s, img, kW, kH);
    benchmark::DoNotOptimize(model_image(r, s, kW, kH));
    state.counters["evals"] = r.evaluations;
    state.counters["legendre_tried"] = std::isfinite(r.legendre_objective) ? 1 : 0;
  }
}
BENCHMARK(BM_FitForwardG097)->Arg(0)->Arg(10)->Unit(benchmark::kMillisecond)->UseRealTime();

void BM_FitProfileOnly(benchmark::State& state) {
  const std::vector<float>& img = milk_image();
  const FitSettings s = settings();
  const RadialProfile p = radial_profile(img, kW, kH, s);
  for (auto _ : state) benchmark::DoNotOptimize(fit_profile(p, s, img, kW, kH));
  state.counters["bins"] = double(p.bins.size());
}
BENCHMARK(BM_FitProfileOnly)->Unit(benchmark::kMillisecond)->UseRealTime();

}  // namespace
}  // namespace procam::medium

BENCHMARK_MAIN();
