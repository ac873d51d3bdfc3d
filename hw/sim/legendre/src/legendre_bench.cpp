// SPDX-License-Identifier: MIT
// Claims of thesis Figs. 6.10/6.11: one simulation step plus one rendered
// image, Legendre domain vs the Stable Fluids grid baseline, side by side.
//   2D: grids 200^2..500^2 vs 16..144 coefficients (n = 4, 6, 8, 12)
//   3D: grids 20^3..40^3  vs 64..216 coefficients (n = 4, 5, 6)
// Scenario: a smooth swirl (~1 m/s on a 2 m box) advecting a density blob,
// dt = 0.01 s, light from below, camera on the +x face; grid: Stam's 20
// Gauss-Seidel sweeps per solve. The Legendre step includes its CFL
// sub-steps (counter "substeps"). BM_Error* (run with --benchmark_filter)
// simulate T = 0.25 s and report the relative L2 density difference against
// the Legendre n = 12 (2D) / n = 6 (3D) solution.
// Render plot/table: hw/sim/legendre/tools/bench_report.cpp.
#include <benchmark/benchmark.h>

#include <cmath>

#include "procam/legendre/fluid.hpp"
#include "procam/legendre/grid_fluid.hpp"
#include "procam/legendre/render.hpp"

namespace procam::legendre {
namespace {

constexpr double kDt = 0.01;

Box scene_box(size_t dims) {
  Box b;
  b.lo = {-1, -1, dims == 3 ? -1.0 : 0.0};
  b.hi = {1, 1, 1};
  return b;
}

// psi = A (1-x^2)^2 (1-y^2)^2 g(z): u = psi_y, v = -psi_x, w = 0 (divergence
// free, no flow through the walls).
double swirl(size_t comp, double x, double y, double z, size_t dims) {
  const double g = dims == 3 ? 1.0 - 0.5 * z * z : 1.0;
  if (comp == 0) return 0.8 * g * (1 - x * x) * (1 - x * x) * 2 * (1 - y * y) * (-2 * y);
  if (comp == 1) return -0.8 * g * (1 - y * y) * (1 - y * y) * 2 * (1 - x * x) * (-2 * x);
  return 0.0;
}
double blob(double x, double y, double z) {
  return 0.5 * std::exp(-3.0 * ((x - 0.3) * (x - 0.3) + (y + 0.1) * (y + 0.1) + z * z));
}

Lighting scene_light() {
  Lighting l;
  l.light_axis = 1;
  l.view_axis = 0;
  l.sigma = 1.0;
  l.beta = 0.8;
  return l;
}

LegendreFluid make_legendre(size_t dims, size_t n) {
  const Box b = scene_box(dims);
  LegendreFluid f(dims, n, b, {});
  for (size_t a = 0; a < dims; ++a)
    f.velocity[a] = project([&](double x, double y, double z) { return swirl(a, x, y, z, dims); }, f.velocity[a].n, b, 16);
  f.density = project(blob, f.density.n, b, 24);
  f.project();
  return f;
}

GridFluid make_grid(size_t dims, size_t cells) {
  const Box b = scene_box(dims);
  const LegendreFluid init = make_legendre(dims, dims == 2 ? 12 : 6);
  GridFluid g(dims, cube_shape(dims, cells), b, {});
  g.set_from(init.velocity, init.density);
  return g;
}

void BM_Legendre(benchmark::State& state, size_t dims) {
  const size_t n = static_cast<size_t>(state.range(0));
  LegendreFluid f = make_legendre(dims, n);
  const LegendreRenderer render(dims, n, f.box(), scene_light());
  const Shape image = cube_shape(dims, dims == 2 ? 500 : 40);
  int substeps = 0;
  for (auto _ : state) {
    const StepReport r = f.step(kDt);
    substeps = r.substeps;
    RenderResult img = render.render(f.density, image);
    benchmark::DoNotOptimize(img.airlight.data());
  }
  state.counters["coefficients"] = static_cast<double>(f.density.size());
  state.counters["substeps"] = substeps;
}

void BM_Grid(benchmark::State& state, size_t dims) {
  const size_t cells = static_cast<size_t>(state.range(0));
  GridFluid g = make_grid(dims, cells);
  const Lighting light = scene_light();
  for (auto _ : state) {
    g.step(kDt);
    RenderResult img = render_grid(g.density, dims, g.cells(), g.box(), light);
    benchmark::DoNotOptimize(img.airlight.data());
  }
  state.counters["cells"] = static_cast<double>(g.size());
}

// Relative L2 difference of the density at T = 0.25 s against the largest
// Legendre solution, sampled on `cells` per axis.
double rel_l2(const std::vector<double>& a, const std::vector<double>& b) {
  double num = 0, den = 0;
  for (size_t i = 0; i < a.size(); ++i) num += (a[i] - b[i]) * (a[i] - b[i]), den += b[i] * b[i];
  return std::sqrt(num / den);
}
std::vector<double> reference_density(size_t dims, const Shape& g) {
  LegendreFluid ref = make_legendre(dims, dims == 2 ? 12 : 6);
  for (int s = 0; s < 25; ++s) ref.step(kDt);
  return evaluate_grid(ref.density, g);
}

void BM_ErrorGrid(benchmark::State& state, size_t dims) {
  const size_t cells = static_cast<size_t>(state.range(0));
  double err = 0;
  for (auto _ : state) {
    GridFluid g = make_grid(dims, cells);
    for (int s = 0; s < 25; ++s) g.step(kDt);
    err = rel_l2(g.density, reference_density(dims, g.cells()));
  }
  state.counters["rel_l2_density"] = err;
}

void BM_ErrorLegendre(benchmark::State& state, size_t dims) {
  const size_t n = static_cast<size_t>(state.range(0));
  const Shape g = cube_shape(dims, dims == 2 ? 200 : 40);
  double err = 0;
  for (auto _ : state) {
    LegendreFluid f = make_legendre(dims, n);
    for (int s = 0; s < 25; ++s) f.step(kDt);
    err = rel_l2(evaluate_grid(f.density, g), reference_density(dims, g));
  }
  state.counters["rel_l2_density"] = err;
}

BENCHMARK_CAPTURE(BM_Legendre, 2d, 2)->Arg(4)->Arg(6)->Arg(8)->Arg(12)->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_Grid, 2d, 2)->Arg(200)->Arg(300)->Arg(400)->Arg(500)->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_Legendre, 3d, 3)->Arg(4)->Arg(5)->Arg(6)->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_Grid, 3d, 3)->Arg(20)->Arg(30)->Arg(40)->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_ErrorGrid, 2d, 2)->Arg(200)->Arg(300)->Arg(400)->Arg(500)->Iterations(1)->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_ErrorLegendre, 2d, 2)->Arg(4)->Arg(6)->Arg(8)->Iterations(1)->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_ErrorGrid, 3d, 3)->Arg(20)->Arg(30)->Arg(40)->Iterations(1)->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_ErrorLegendre, 3d, 3)->Arg(4)->Arg(5)->Iterations(1)->Unit(benchmark::kMillisecond);

}  // namespace
}  // namespace procam::legendre

BENCHMARK_MAIN();
