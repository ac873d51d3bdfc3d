// SPDX-License-Identifier: MIT
// The indirect signal A of a participating medium (thesis Eq. 5.12): light
// scattered forward out of the projector's beam that still reaches a surface
// and is reflected. Approximation (docs/media.md):
//  - amount: the slab model of forward_scatter() along the pixel's projector
//    leg (single scattering, beam normal to the slab, wide flood);
//  - where it lands: spread around the direct irradiance by a Gaussian whose
//    σ is the median landing offset of the view's surface points, applied to
//    the surface irradiance in camera-image space (so it leaks across depth
//    edges, and a shadowed point receives its lit neighbours' scattered light).
#include <algorithm>
#include <cmath>

#include "medium.hpp"
#include "parallel.hpp"

namespace procam::sim {

ForwardScatter forward_scatter(const Medium& m, double len) {
  ForwardScatter f;
  if (!(len > 0) || !(m.sigma_s_per_mm > 0)) return f;
  // t: midpoint rule (the integrand is smooth in t); μ = 1 − (1 − μ₀)u², u
  // midpoint, to resolve the forward peak of p near μ = 1. μ₀ = 0.02: grazing
  // light (α > 88.9°) is dropped.
  constexpr int kT = 48, kU = 400;
  constexpr double kMu0 = 0.02;
  const double sigma = m.sigma_t_per_mm, beta = m.sigma_s_per_mm;
  double flux = 0, rho2 = 0;
  for (int it = 0; it < kT; ++it) {
    const double t = (it + 0.5) * len / kT, r = len - t;
    const double w_t = beta * std::exp(-sigma * t) * len / kT;
    for (int iu = 0; iu < kU; ++iu) {
      const double u = (iu + 0.5) / kU;
      const double mu = 1.0 - (1.0 - kMu0) * u * u;
      const double dmu = 2.0 * (1.0 - kMu0) * u / kU;
      const double w = w_t * 2.0 * M_PI * hg_phase(m.g, mu) * std::exp(-sigma * r / mu) * dmu;
      flux += w;
      const double tan_a = std::sqrt(1.0 - mu * mu) / mu;
      rho2 += w * r * r * tan_a * tan_a;
    }
  }
  f.ratio = flux / std::exp(-sigma * len);
  f.sigma_lat_mm = flux > 0 ? std::sqrt(rho2 / flux / 2.0) : 0.0;
  return f;
}

void prepare_indirect(const Medium& m, const Rigid3& world_from_proj, const PreparedView& v, MediumTaps& taps) {
  const size_t n = v.pixel_count();
  const Rigid3 world_from_cam = world_from_proj * v.camera.cam_from_proj.inverse();
  const Vec3 proj_c = world_from_proj.translation_mm;
  // forward_scatter() tabulated over the projector leg's length (64 steps, linear interpolation).
  double max_len = 0;
  std::vector<double> len(n, 0.0);
  for (size_t i = 0; i < n; ++i) {
    if (!std::isfinite(v.depth_mm[i])) continue;
    const Vec3 x = world_from_cam * Vec3{static_cast<double>(v.point_mm[3 * i]), static_cast<double>(v.point_mm[3 * i + 1]),
                                         static_cast<double>(v.point_mm[3 * i + 2])};
    len[i] = medium_length(m, proj_c, x);
    max_len = std::max(max_len, len[i]);
  }
  if (!(max_len > 0)) return;
  constexpr int kSteps = 64;
  std::vector<ForwardScatter> table(kSteps + 1);
  for (int k = 0; k <= kSteps; ++k) table[static_cast<size_t>(k)] = forward_scatter(m, max_len * k / kSteps);
  auto lookup = [&](double l) {
    const double f = std::clamp(l / max_len * kSteps, 0.0, static_cast<double>(kSteps));
    const auto k = std::min(static_cast<size_t>(f), static_cast<size_t>(kSteps - 1));
    const double w = f - static_cast<double>(k);
    return ForwardScatter{table[k].ratio + w * (table[k + 1].ratio - table[k].ratio),
                          table[k].sigma_lat_mm + w * (table[k + 1].sigma_lat_mm - table[k].sigma_lat_mm)};
  };
  taps.indirect_gain.assign(n, 0.f);
  std::vector<double> spread_px;
  for (size_t i = 0; i < n; ++i) {
    if (!(len[i] > 0)) continue;
    const ForwardScatter fs = lookup(len[i]);
    // direct_albedo/π: the direct gain per irradiance where lit, else albedo/π.
    const double k = v.irradiance_gain[i] > 0.f
                         ? static_cast<double>(v.direct_gain[i]) / static_cast<double>(v.irradiance_gain[i])
                         : static_cast<double>(v.albedo[i]) / M_PI;
    taps.indirect_gain[i] = static_cast<float>(k * fs.ratio);
    spread_px.push_back(fs.sigma_lat_mm * v.camera.intrinsics.fx / static_cast<double>(v.depth_mm[i]));
  }
  if (spread_px.empty()) {
    taps.indirect_gain.clear();
    return;
  }
  std::nth_element(spread_px.begin(), spread_px.begin() + static_cast<ptrdiff_t>(spread_px.size() / 2), spread_px.end());
  taps.indirect_sigma_px = spread_px[spread_px.size() / 2];
}

namespace detail {
namespace {

// Box filter of radius r along each row of `data` (W wide), rows [b, e),
// clamped at the ends (no darkening at the image border). `line` is scratch.
void box_rows(float* data, uint32_t W, uint32_t b, uint32_t e, int r, std::vector<float>& line) {
  const auto n = static_cast<int64_t>(W);
  const double inv = 1.0 / (2 * r + 1);
  line.resize(W);
  for (uint32_t y = b; y < e; ++y) {
    float* row = data + size_t{y} * W;
    std::copy(row, row + W, line.begin());
    auto at = [&](int64_t k) { return static_cast<double>(line[static_cast<size_t>(std::clamp<int64_t>(k, 0, n - 1))]); };
    double sum = 0;
    for (int64_t k = -r; k <= r; ++k) sum += at(k);
    for (int64_t k = 0; k < n; ++k) {
      row[k] = static_cast<float>(sum * inv);
      sum += at(k + r + 1) - at(k - r);
    }
  }
}

// The same down the columns [b, e) of `src` (W×H) into `dst`, row by row with
// a running sum per column (contiguous access).
void box_cols(const float* src, float* dst, uint32_t W, uint32_t H, uint32_t b, uint32_t e, int r,
              std::vector<double>& acc) {
  const auto h = static_cast<int64_t>(H);
  auto row = [&](int64_t y) { return src + static_cast<size_t>(std::clamp<int64_t>(y, 0, h - 1)) * W; };
  acc.assign(e - b, 0.0);
  for (int64_t y = -r; y <= r; ++y)
    for (uint32_t x = b; x < e; ++x) acc[x - b] += static_cast<double>(row(y)[x]);
  const double inv = 1.0 / (2 * r + 1);
  for (int64_t y = 0; y < h; ++y) {
    float* out = dst + static_cast<size_t>(y) * W;
    const float* add = row(y + r + 1);
    const float* sub = row(y - r);
    for (uint32_t x = b; x < e; ++x) {
      out[x] = static_cast<float>(acc[x - b] * inv);
      acc[x - b] += static_cast<double>(add[x]) - static_cast<double>(sub[x]);
    }
  }
}

}  // namespace

void gaussian_blur3(std::vector<float>& data, std::vector<float>& tmp, uint32_t W, uint32_t H, double sigma_px,
                    int threads) {
  // Three box passes of radius r approximate a Gaussian of σ² = 3·((2r+1)² − 1)/12.
  const int r = static_cast<int>(std::lround((std::sqrt(4.0 * sigma_px * sigma_px + 1.0) - 1.0) / 2.0));
  if (r < 1 || data.size() != size_t{W} * H) return;
  tmp.resize(data.size());
  for (int pass = 0; pass < 3; ++pass) {
    parallel_rows(H, threads, [&](uint32_t b, uint32_t e) {
      std::vector<float> line;
      box_rows(data.data(), W, b, e, r, line);
    });
    tmp.swap(data);
    parallel_rows(W, threads, [&](uint32_t b, uint32_t e) {
      std::vector<double> acc;
      box_cols(tmp.data(), data.data(), W, H, b, e, r, acc);
    });
  }
}

}  // namespace detail

void MediumIndirectComponent::begin_frame(const FrameContext& frame, int threads) {
  const MediumTaps& t = *taps_;
  blurred_.assign(frame.irradiance, frame.irradiance + frame.view.pixel_count());
  detail::gaussian_blur3(blurred_, tmp_, frame.view.width, frame.view.height, t.indirect_sigma_px, threads);
}

void MediumIndirectComponent::apply(const FrameContext& frame, uint32_t row_begin, uint32_t row_end,
                                    float* radiance) const {
  const std::vector<float>& k = taps_->indirect_gain;
  if (k.size() != frame.view.pixel_count() || blurred_.size() != k.size()) return;
  const size_t b = size_t{row_begin} * frame.view.width, e = size_t{row_end} * frame.view.width;
  for (size_t i = b; i < e; ++i) radiance[i] += k[i] * blurred_[i];
}

}  // namespace procam::sim
