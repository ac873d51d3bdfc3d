// SPDX-License-Identifier: MIT
// Sub-surface diffusion: dipole profile, its Gaussian fit, the per-object pyramid and its component.
#include "procam/hw/sim/global.hpp"

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <map>
#include <mutex>
#include <random>

#include "global_internal.hpp"
#include "parallel.hpp"
#include "procam/hw/sim/raycast.hpp"

namespace procam::sim {
using detail::add_upsampled_2x;
using detail::blur_separable;
using detail::gaussian_kernel;
using detail::sum_2x2;
using detail::view_normal;
using detail::view_point;

// ---- Diffusion -----------------------------------------------------------------

double dipole_profile(const Material& m, double r_mm) {
  // Jensen et al. 2001, Eq. 4–5: σ_t' = 1/ℓ, σ_a = (1 − α')σ_t', σ_tr =
  // √(3σ_aσ_t'), real source at z_r = 1/σ_t', virtual at z_v = z_r(1 + 4A/3),
  // A = (1 + F_dr)/(1 − F_dr), F_dr = −1.440/n² + 0.710/n + 0.668 + 0.0636n.
  const double st = 1.0 / m.mean_free_path_mm;
  const double sa = (1.0 - m.scattering_albedo) * st;
  const double str = std::sqrt(3.0 * sa * st);
  const double n = m.ior;
  const double fdr = -1.440 / (n * n) + 0.710 / n + 0.668 + 0.0636 * n;
  const double A = (1 + fdr) / (1 - fdr);
  const double zr = 1.0 / st, zv = zr * (1 + 4.0 * A / 3.0);
  const double dr = std::sqrt(r_mm * r_mm + zr * zr), dv = std::sqrt(r_mm * r_mm + zv * zv);
  return m.scattering_albedo / (4 * M_PI) *
         (zr * (1 + str * dr) * std::exp(-str * dr) / (dr * dr * dr) +
          zv * (1 + str * dv) * std::exp(-str * dv) / (dv * dv * dv));
}

std::vector<std::pair<double, double>> fit_dipole_gaussians(const Material& m, double px_per_mm) {
  // Target: the fraction of the dipole's energy within radius r (px), on a
  // log grid; basis: the same for a delta (1) and Gaussians σ = ½·2^j px,
  // 1 − exp(−r²/2σ²), up to σ ≥ 2ℓ_d. Fit: non-negative least squares by
  // cyclic coordinate descent (small, convex), then weights normalised to 1.
  const double ld_px = m.diffusion_length_mm() * px_per_mm;
  std::vector<double> sig{0.0};
  for (double sg = 1.0; sg < std::max(1.0, 2.0 * ld_px) && sig.size() < 12; sg *= 2) sig.push_back(sg);
  if (sig.back() < 2.0 * ld_px) sig.push_back(sig.back() * 2);
  // Cumulative energy of the dipole by the trapezoid rule on r in mm (log spaced).
  const double r_max_mm = 12.0 * m.diffusion_length_mm() + 20.0 * m.mean_free_path_mm;
  const int N = 4000;
  std::vector<double> rr(N + 1), cum(N + 1, 0.0);
  const double r_min_mm = 1e-4 * m.mean_free_path_mm;
  for (int k = 0; k <= N; ++k) rr[static_cast<size_t>(k)] = r_min_mm * std::pow(r_max_mm / r_min_mm, double(k) / N);
  auto f = [&](double r) { return dipole_profile(m, r) * 2 * M_PI * r; };
  cum[0] = f(rr[0]) * rr[0] / 2;  // ∫_0^{r_min} ≈ triangle
  for (size_t k = 1; k <= static_cast<size_t>(N); ++k) cum[k] = cum[k - 1] + 0.5 * (f(rr[k - 1]) + f(rr[k])) * (rr[k] - rr[k - 1]);
  const double total = cum.back();
  std::vector<double> rk, target;
  for (double r_px = 0.25; r_px < r_max_mm * px_per_mm; r_px *= 1.189207) {  // 2^(1/4)
    const double r_mm = r_px / px_per_mm;
    const auto it = std::lower_bound(rr.begin(), rr.end(), r_mm);
    const auto k = static_cast<size_t>(std::clamp<ptrdiff_t>(it - rr.begin(), 1, N));
    const double t = (r_mm - rr[k - 1]) / (rr[k] - rr[k - 1]);
    rk.push_back(r_px);
    target.push_back((cum[k - 1] + std::clamp(t, 0.0, 1.0) * (cum[k] - cum[k - 1])) / total);
  }
  const size_t J = sig.size(), K = rk.size();
  std::vector<double> B(K * J);
  for (size_t k = 0; k < K; ++k)
    for (size_t j = 0; j < J; ++j)
      B[k * J + j] = sig[j] == 0 ? 1.0 : 1.0 - std::exp(-rk[k] * rk[k] / (2 * sig[j] * sig[j]));
  std::vector<double> w(J, 1.0 / static_cast<double>(J)), res(K);
  for (size_t k = 0; k < K; ++k) {
    double s = 0;
    for (size_t j = 0; j < J; ++j) s += B[k * J + j] * w[j];
    res[k] = s - target[k];
  }
  for (int sweep = 0; sweep < 400; ++sweep)
    for (size_t j = 0; j < J; ++j) {
      double num = 0, den = 0;
      for (size_t k = 0; k < K; ++k) {
        num += B[k * J + j] * res[k];
        den += B[k * J + j] * B[k * J + j];
      }
      if (!(den > 0)) continue;
      const double nw = std::max(0.0, w[j] - num / den), dw = nw - w[j];
      if (dw == 0) continue;
      for (size_t k = 0; k < K; ++k) res[k] += B[k * J + j] * dw;
      w[j] = nw;
    }
  double sum = 0;
  for (double x : w) sum += x;
  std::vector<std::pair<double, double>> out;
  for (size_t j = 0; j < J; ++j)
    if (w[j] > 1e-4 * sum) out.emplace_back(sig[j], w[j] / sum);
  return out;
}

namespace {

// Builds the pyramid and the terms of a model from its (σ, weight) list.
void build_pyramid(DiffusionModel& m, const PreparedView& view,
                   const std::vector<std::pair<double, double>>& terms) {
  uint32_t top = 0;
  auto level_of = [](double sigma) {
    uint32_t l = 0;
    while (l < 6 && double(2u << l) <= sigma) ++l;  // 2^(l+1) ≤ σ → go up
    return l;
  };
  for (const auto& t : terms) top = std::max(top, level_of(t.first));
  m.levels.resize(top + 1);
  for (uint32_t l = 0; l <= top; ++l) {
    DiffusionLevel& L = m.levels[l];
    L.factor = 1u << l;
    if (l == 0) {
      L.cw = m.x1 - m.x0;
      L.ch = m.y1 - m.y0;
      L.mask.assign(size_t{L.cw} * L.ch, 0.f);
      for (uint32_t y = m.y0; y < m.y1; ++y)
        for (uint32_t x = m.x0; x < m.x1; ++x)
          if (view.object[size_t{y} * view.width + x] == m.object) L.mask[size_t{y - m.y0} * L.cw + (x - m.x0)] = 1.f;
    } else {
      const DiffusionLevel& F = m.levels[l - 1];
      L.cw = (F.cw + 1) / 2;
      L.ch = (F.ch + 1) / 2;
      L.mask.assign(size_t{L.cw} * L.ch, 0.f);
      sum_2x2(F.mask.data(), F.cw, F.ch, L.mask.data(), L.cw, L.ch);
    }
  }
  std::vector<float> blurred, tmp;
  for (const auto& [sigma, weight] : terms) {
    const uint32_t l = level_of(sigma);
    DiffusionLevel& L = m.levels[l];
    DiffusionTerm t;
    t.weight = weight;
    t.sigma_px = sigma;
    const double f = L.factor;
    double var = sigma * sigma;
    if (l > 0) var -= (f * f - 1) / 12.0;
    for (uint32_t k = 1; k <= l; ++k) var -= double(1u << (2 * k)) / 6.0;
    t.kernel = gaussian_kernel(std::sqrt(std::max(0.0, var)) / f);
    blurred.assign(L.mask.size(), 0.f);
    tmp.assign(L.mask.size(), 0.f);
    blur_separable(L.mask.data(), blurred.data(), tmp.data(), L.cw, L.ch, t.kernel, 1);
    t.inv_mask.resize(L.mask.size());
    for (size_t c = 0; c < L.mask.size(); ++c) t.inv_mask[c] = blurred[c] > 1e-6f ? 1.f / blurred[c] : 0.f;
    L.terms.push_back(std::move(t));
  }
}

}  // namespace

std::vector<DiffusionModel> build_diffusion(const Scene& scene, const PreparedView& view,
                                            const Rigid3& world_from_cam) {
  std::vector<DiffusionModel> out;
  const SceneTracer tracer(scene);
  for (size_t o = 0; o < scene.objects.size(); ++o) {
    const Material& mat = scene.objects[o].material;
    if (!mat.translucent() && !mat.sheet()) continue;
    DiffusionModel m;
    m.object = static_cast<int32_t>(o);
    m.sheet = mat.sheet();
    m.x0 = view.width;
    m.y0 = view.height;
    std::vector<float> depths, behind, behind_albedo;
    for (uint32_t y = 0; y < view.height; ++y)
      for (uint32_t x = 0; x < view.width; ++x) {
        const size_t i = size_t{y} * view.width + x;
        if (view.object[i] != m.object) continue;
        m.x0 = std::min(m.x0, x);
        m.y0 = std::min(m.y0, y);
        m.x1 = std::max(m.x1, x + 1);
        m.y1 = std::max(m.y1, y + 1);
        depths.push_back(view.depth_mm[i]);
        if (m.sheet && (x % 16 == 0) && (y % 16 == 0)) {
          // Distance to the surface behind the sheet, along the back normal.
          const Vec3 p = world_from_cam * view_point(view, i);
          const Vec3 back = -(world_from_cam.rotation * view_normal(view, i));
          Hit h;
          if (tracer.first_hit(p + back * 0.05, back, 1e-6, h)) {
            behind.push_back(static_cast<float>(h.t));
            behind_albedo.push_back(static_cast<float>(tracer.material(h.object).albedo));
          }
        }
      }
    if (depths.empty()) continue;
    auto median = [](std::vector<float> v) {
      std::nth_element(v.begin(), v.begin() + static_cast<ptrdiff_t>(v.size() / 2), v.end());
      return static_cast<double>(v[v.size() / 2]);
    };
    const double z = median(depths);
    m.px_per_mm = view.camera.intrinsics.fx / z;
    std::vector<std::pair<double, double>> terms;
    if (m.sheet) {
      if (behind.empty()) continue;  // nothing behind: the transmitted light leaves the scene
      m.behind_mm = median(behind);
      m.behind_albedo = median(behind_albedo);
      m.sigma_mm = 0.77 * m.behind_mm;
      m.gain = mat.transmittance * mat.transmittance * m.behind_albedo / M_PI;
      m.sigma_px = m.sigma_mm * m.px_per_mm;
      terms.emplace_back(m.sigma_px, 1.0);
    } else {
      m.sigma_mm = mat.diffusion_length_mm();
      m.gain = (mat.albedo - mat.direct_albedo()) / M_PI;
      m.sigma_px = m.sigma_mm * m.px_per_mm;
      terms = fit_dipole_gaussians(mat, m.px_per_mm);
    }
    build_pyramid(m, view, terms);
    out.push_back(std::move(m));
  }
  return out;
}

void DiffusionComponent::begin_frame(const FrameContext& frame, int threads) {
  const PreparedView& v = frame.view;
  d_.resize(models_.size());
  s_.resize(models_.size());
  for (size_t k = 0; k < models_.size(); ++k) {
    const DiffusionModel& m = models_[k];
    auto& D = d_[k];
    auto& S = s_[k];
    const size_t top = m.levels.size();
    D.resize(top);
    S.resize(top);
    const DiffusionLevel& L0 = m.levels[0];
    const bool level0 = !L0.terms.empty();
    // Level 0 (only when a term lives there): the object's irradiance over
    // its bbox. Level 1: 2×2 sums, straight from the irradiance (one pass
    // over the full-resolution pixels either way). Higher levels: 2×2 sums.
    if (level0) {
      D[0].resize(size_t{L0.cw} * L0.ch);
      detail::parallel_rows(L0.ch, threads, [&](uint32_t b, uint32_t e) {
        for (uint32_t y = b; y < e; ++y) {
          const float* mask = L0.mask.data() + size_t{y} * L0.cw;
          const float* irr = frame.irradiance + size_t{y + m.y0} * v.width + m.x0;
          float* dst = D[0].data() + size_t{y} * L0.cw;
          for (uint32_t x = 0; x < L0.cw; ++x) dst[x] = mask[x] * irr[x];
        }
      });
    }
    if (top > 1) {
      const DiffusionLevel& L1 = m.levels[1];
      D[1].resize(size_t{L1.cw} * L1.ch);
      detail::parallel_rows(L1.ch, threads, [&](uint32_t b, uint32_t e) {
        for (uint32_t cy = b; cy < e; ++cy) {
          float* dst = D[1].data() + size_t{cy} * L1.cw;
          std::fill(dst, dst + L1.cw, 0.f);
          for (uint32_t dy = 0; dy < 2 && 2 * cy + dy < L0.ch; ++dy) {
            const uint32_t y = 2 * cy + dy;
            const float* mask = L0.mask.data() + size_t{y} * L0.cw;
            const float* irr = frame.irradiance + size_t{y + m.y0} * v.width + m.x0;
            for (uint32_t x = 0; x < L0.cw; ++x) dst[x / 2] += mask[x] * irr[x];
          }
        }
      });
    }
    for (size_t l = 2; l < top; ++l) {
      const DiffusionLevel& F = m.levels[l - 1];
      const DiffusionLevel& L = m.levels[l];
      D[l].resize(size_t{L.cw} * L.ch);
      sum_2x2(D[l - 1].data(), F.cw, F.ch, D[l].data(), L.cw, L.ch);
    }
    // Per level: Σ_t w_t (G_t ∗ D) / (G_t ∗ mask).
    for (size_t l = level0 ? 0 : 1; l < top; ++l) {
      const DiffusionLevel& L = m.levels[l];
      const size_t n = size_t{L.cw} * L.ch;
      S[l].assign(n, 0.f);
      for (const DiffusionTerm& t : L.terms) {
        const float w = static_cast<float>(t.weight);
        const float* src = D[l].data();
        if (t.kernel.size() > 1) {
          blurred_.resize(n);
          tmp_.resize(n);
          blur_separable(D[l].data(), blurred_.data(), tmp_.data(), L.cw, L.ch, t.kernel, n > 65536 ? threads : 1);
          src = blurred_.data();
        }
        float* dst = S[l].data();
        const float* inv = t.inv_mask.data();
        for (size_t c = 0; c < n; ++c) dst[c] += w * src[c] * inv[c];
      }
    }
    // Down to level 1; apply() adds level 1 (2× upsampled) and level 0.
    for (size_t l = top - 1; l > 1; --l) {
      const DiffusionLevel& F = m.levels[l - 1];
      const DiffusionLevel& L = m.levels[l];
      add_upsampled_2x(S[l].data(), L.cw, L.ch, S[l - 1].data(), F.cw, F.ch);
    }
  }
}

void DiffusionComponent::apply(const FrameContext& frame, uint32_t row_begin, uint32_t row_end,
                               float* radiance) const {
  const PreparedView& v = frame.view;
  std::vector<float> row;
  for (size_t k = 0; k < models_.size(); ++k) {
    const DiffusionModel& m = models_[k];
    const auto gain = static_cast<float>(m.gain);
    const DiffusionLevel& L0 = m.levels[0];
    const bool level0 = !L0.terms.empty(), level1 = m.levels.size() > 1;
    for (uint32_t y = std::max(row_begin, m.y0); y < std::min(row_end, m.y1); ++y) {
      const uint32_t ly = y - m.y0;
      row.assign(L0.cw, 0.f);
      if (level0) std::copy_n(s_[k][0].data() + size_t{ly} * L0.cw, L0.cw, row.data());
      if (level1) {
        // The level-1 result at this row, bilinear (¾/¼ taps, as add_upsampled_2x).
        const DiffusionLevel& L1 = m.levels[1];
        const float* S1 = s_[k][1].data();
        const uint32_t ya = ly / 2;
        const uint32_t yb = ly % 2 == 0 ? (ya > 0 ? ya - 1 : ya) : std::min(ya + 1, L1.ch - 1);
        const float* ra = S1 + size_t{ya} * L1.cw;
        const float* rb = S1 + size_t{yb} * L1.cw;
        for (uint32_t x = 0; x < L0.cw; ++x) {
          const uint32_t xa = x / 2;
          const uint32_t xb = x % 2 == 0 ? (xa > 0 ? xa - 1 : xa) : std::min(xa + 1, L1.cw - 1);
          const float top = 0.75f * ra[xa] + 0.25f * ra[xb], bot = 0.75f * rb[xa] + 0.25f * rb[xb];
          row[x] += 0.75f * top + 0.25f * bot;
        }
      }
      const float* mask = L0.mask.data() + size_t{ly} * L0.cw;
      float* out = radiance + size_t{y} * v.width + m.x0;
      for (uint32_t x = 0; x < L0.cw; ++x) out[x] += gain * mask[x] * row[x];
    }
  }
}

}  // namespace procam::sim
