// SPDX-License-Identifier: MIT
// The indirect signal A of a participating medium (thesis Eq. 5.12): light
// scattered forward by small angles that still reaches a surface, or still
// reaches the camera from a surface. Model (docs/media.md "Indirect signal A"):
// single forward scattering on EACH leg, in the slab approximation of
// forward_scatter(), so that A is reciprocal (swapping source and camera swaps
// the two legs and leaves A unchanged, as Helmholtz stereo, Eq. 5.32, assumes):
//
//   L_s(x) = ρ/π · [E(x) + R(ℓ_L(x)) · N_L[E](x)]         (surface radiance)
//   I_s(x) = T_C(x) · [L_s(x) + R(ℓ_C(x)) · N_C[L_s](x)]   (what the camera sees)
//   A(x)   = I_s(x) − T_C(x) · ρ/π · E(x)
//
// E the surface irradiance of the unscattered light (already × T_L), R(ℓ) =
// F_A/e^{−σℓ} of a leg of ℓ mm in the medium (forward_scatter()), ℓ_L, ℓ_C the
// light's and the camera's leg. N[f] = Ê · (G ∗ f)/(G ∗ Ê) is a normalised
// Gaussian blur (G of the leg's landing spread): Ê is the flood irradiance
// without cast shadows (for N_C: the flood surface radiance ρ/π·Ê·(1 + R_L)),
// so a flood on an unshadowed surface gives N[f] = f exactly, whatever part
// of the surface the camera sees. The blur itself runs in camera-image space
// and a camera sees only part of the surface, so an unnormalised blur of a
// kernel as wide as the image (σ ≈ 40 px on the Helmholtz rig) would weigh
// the image border, differently in each camera: not reciprocal.
// The camera leg is the in-leg with source and receiver swapped: light
// leaving the surface at a lateral offset ρ from the pixel's foot point and
// scattered at distance t from the camera by angle α (ρ = (ℓ_C − t)·tan α)
// travels the same path as the in-leg's (t counted from the light), so its
// share of the unscattered radiance is the same R(ℓ_C) with the same landing
// spread. On a smooth flood A/D = (1 + R_L)(1 + R_C) − 1 (the R_L·R_C term:
// light scattered forward on both legs).
// Approximations: each Gaussian's σ is the median landing offset of the view's
// surface points; blurs leak across depth edges, and a shadowed point
// receives its lit neighbours' scattered light (a penumbra); the camera-leg
// term blurs only the direct and in-leg light (not ambient or interreflections).
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

void prepare_indirect(const Medium& m, const ProjectorModel& projector, const Rigid3& world_from_proj,
                      const PreparedView& v, MediumTaps& taps, int threads) {
  const size_t n = v.pixel_count();
  const Rigid3 world_from_cam = world_from_proj * v.camera.cam_from_proj.inverse();
  const Vec3 proj_c = world_from_proj.translation_mm, cam_c = world_from_cam.translation_mm;
  const double intensity = projector.irradiance_at_1m * 1.0e6;  // iu·mm², as fill_view_rows()
  const double pw = static_cast<double>(v.proj_width), ph = static_cast<double>(v.proj_height);
  // forward_scatter() tabulated over the legs' lengths (64 steps, linear
  // interpolation); flood irradiance without cast shadows (Ê).
  double max_len = 0;
  std::vector<double> len_l(n, 0.0), len_c(n, 0.0);
  std::vector<float> flood(n, 0.f);
  for (size_t i = 0; i < n; ++i) {
    if (!std::isfinite(v.depth_mm[i])) continue;
    const Vec3 x = world_from_cam * Vec3{static_cast<double>(v.point_mm[3 * i]), static_cast<double>(v.point_mm[3 * i + 1]),
                                         static_cast<double>(v.point_mm[3 * i + 2])};
    len_l[i] = medium_length(m, proj_c, x);
    len_c[i] = medium_length(m, cam_c, x);
    max_len = std::max({max_len, len_l[i], len_c[i]});
    if (v.irradiance_gain[i] > 0.f) {
      flood[i] = v.irradiance_gain[i];
      continue;
    }
    const double xp = static_cast<double>(v.proj_x[i]), yp = static_cast<double>(v.proj_y[i]);
    if (!(xp >= -0.5 && xp < pw - 0.5 && yp >= -0.5 && yp < ph - 0.5)) continue;  // outside the field (or NaN)
    const Vec3 n_world = world_from_cam.rotation * Vec3{static_cast<double>(v.normal[3 * i]),
                                                        static_cast<double>(v.normal[3 * i + 1]),
                                                        static_cast<double>(v.normal[3 * i + 2])};
    const Vec3 to_proj = proj_c - x;
    const double dist = norm(to_proj), cos_p = dot(n_world, to_proj) / dist;
    if (cos_p > 0)
      flood[i] = static_cast<float>(intensity * cos_p / (dist * dist) * std::exp(-m.sigma_t_per_mm * len_l[i]));
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
  taps.indirect_reflect.assign(n, 0.f);
  taps.indirect_cam_ratio.assign(n, 0.f);
  std::vector<double> spread_l_px, spread_c_px;
  for (size_t i = 0; i < n; ++i) {
    if (!(len_l[i] > 0) && !(len_c[i] > 0)) continue;
    // direct_albedo/π: the direct gain per irradiance where lit, else albedo/π.
    const double k = v.irradiance_gain[i] > 0.f
                         ? static_cast<double>(v.direct_gain[i]) / static_cast<double>(v.irradiance_gain[i])
                         : static_cast<double>(v.albedo[i]) / M_PI;
    const double px_per_mm = v.camera.intrinsics.fx / static_cast<double>(v.depth_mm[i]);
    taps.indirect_reflect[i] = static_cast<float>(k);
    if (len_l[i] > 0) {
      const ForwardScatter fs = lookup(len_l[i]);
      taps.indirect_gain[i] = static_cast<float>(k * fs.ratio);
      spread_l_px.push_back(fs.sigma_lat_mm * px_per_mm);
    }
    if (len_c[i] > 0) {
      const ForwardScatter fs = lookup(len_c[i]);
      taps.indirect_cam_ratio[i] = static_cast<float>(fs.ratio);
      spread_c_px.push_back(fs.sigma_lat_mm * px_per_mm);
    }
  }
  auto median = [](std::vector<double>& x) {
    if (x.empty()) return 0.0;
    std::nth_element(x.begin(), x.begin() + static_cast<ptrdiff_t>(x.size() / 2), x.end());
    return x[x.size() / 2];
  };
  taps.indirect_sigma_px = median(spread_l_px);
  taps.indirect_cam_sigma_px = median(spread_c_px);
  // Normalisers Ê/(G ∗ Ê) of N_L and N_C (0 where the blurred flood is 0).
  auto normaliser = [&](const std::vector<float>& e, double sigma_px) {
    std::vector<float> blurred = e, tmp;
    detail::gaussian_blur3(blurred, tmp, v.width, v.height, sigma_px, threads);
    std::vector<float> w(n, 0.f);
    for (size_t i = 0; i < n; ++i)
      if (blurred[i] > 0.f && e[i] > 0.f) w[i] = e[i] / blurred[i];
    return w;
  };
  taps.indirect_norm = normaliser(flood, taps.indirect_sigma_px);
  std::vector<float> flood_radiance(n);
  for (size_t i = 0; i < n; ++i)
    flood_radiance[i] = taps.indirect_reflect[i] * flood[i] + taps.indirect_gain[i] * flood[i];
  taps.indirect_cam_norm = normaliser(flood_radiance, taps.indirect_cam_sigma_px);
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
  const size_t n = frame.view.pixel_count();
  blurred_.clear();
  blurred_cam_.clear();
  if (t.indirect_gain.size() != n || t.indirect_reflect.size() != n || t.indirect_cam_ratio.size() != n ||
      t.indirect_norm.size() != n || t.indirect_cam_norm.size() != n)
    return;
  // In-leg: N_L[E] = Ê·(G_L ∗ E)/(G_L ∗ Ê).
  blurred_.assign(frame.irradiance, frame.irradiance + n);
  detail::gaussian_blur3(blurred_, tmp_, frame.view.width, frame.view.height, t.indirect_sigma_px, threads);
  for (size_t i = 0; i < n; ++i) blurred_[i] *= t.indirect_norm[i];
  // Out-leg: N_C[L_s], L_s = ρ/π·E + ρ/π·R_L·N_L[E] (the surface radiance, before T_C).
  blurred_cam_.resize(n);
  for (size_t i = 0; i < n; ++i)
    blurred_cam_[i] = t.indirect_reflect[i] * frame.irradiance[i] + t.indirect_gain[i] * blurred_[i];
  detail::gaussian_blur3(blurred_cam_, tmp_, frame.view.width, frame.view.height, t.indirect_cam_sigma_px, threads);
  for (size_t i = 0; i < n; ++i) blurred_cam_[i] *= t.indirect_cam_norm[i];
}

void MediumIndirectComponent::apply(const FrameContext& frame, uint32_t row_begin, uint32_t row_end,
                                    float* radiance) const {
  const std::vector<float>& k = taps_->indirect_gain;
  const std::vector<float>& rc = taps_->indirect_cam_ratio;
  if (k.size() != frame.view.pixel_count() || blurred_.size() != k.size() || blurred_cam_.size() != k.size()) return;
  const size_t b = size_t{row_begin} * frame.view.width, e = size_t{row_end} * frame.view.width;
  for (size_t i = b; i < e; ++i) radiance[i] += k[i] * blurred_[i] + rc[i] * blurred_cam_[i];
}

}  // namespace procam::sim
