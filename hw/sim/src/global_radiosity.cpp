// SPDX-License-Identifier: MIT
// Radiosity inter-reflection: patches, form factors, the transport matrix and its per-frame component.
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
using detail::pixel_area;
using detail::solve_dense;
using detail::view_normal;
using detail::view_point;

// ---- Radiosity ---------------------------------------------------------------

Result<RadiosityModel> build_radiosity(const Scene& scene, const PreparedView& view, const Rigid3& world_from_cam,
                                       uint32_t patch_px, int threads) {
  if (patch_px < 2) return Error(Code::invalid_argument, "radiosity: patch_px must be >= 2");
  RadiosityModel m;
  const size_t n_px = view.pixel_count();
  m.pixel_patch.assign(n_px, -1);
  m.pixel_area_mm2.assign(n_px, 0.f);
  const uint32_t bw = (view.width + patch_px - 1) / patch_px, bh = (view.height + patch_px - 1) / patch_px;
  // Patches per block: (object → patch id).
  std::vector<std::vector<std::pair<int32_t, int32_t>>> block_patches(size_t{bw} * bh);
  struct Acc {
    Vec3 centroid, normal;
    double area = 0, albedo = 0;
  };
  std::vector<Acc> acc;
  for (uint32_t y = 0; y < view.height; ++y)
    for (uint32_t x = 0; x < view.width; ++x) {
      const size_t i = size_t{y} * view.width + x;
      const int32_t obj = view.object[i];
      if (obj < 0) continue;
      auto& list = block_patches[size_t{y / patch_px} * bw + x / patch_px];
      int32_t id = -1;
      for (const auto& [o, p] : list)
        if (o == obj) id = p;
      if (id < 0) {
        id = static_cast<int32_t>(acc.size());
        list.emplace_back(obj, id);
        acc.push_back({});
      }
      const double a = pixel_area(view, i);
      m.pixel_patch[i] = id;
      m.pixel_area_mm2[i] = static_cast<float>(a);
      Acc& s = acc[static_cast<size_t>(id)];
      s.centroid = s.centroid + view_point(view, i) * a;
      s.normal = s.normal + view_normal(view, i) * a;
      s.area += a;
      s.albedo += a * scene.objects[static_cast<size_t>(obj)].material.albedo;
    }
  const size_t n = acc.size();
  m.patches.resize(n);
  std::vector<double> best(n, std::numeric_limits<double>::infinity());
  for (size_t k = 0; k < n; ++k) acc[k].centroid = acc[k].centroid * (1.0 / acc[k].area);
  for (size_t i = 0; i < n_px; ++i) {
    const int32_t id = m.pixel_patch[i];
    if (id < 0) continue;
    const auto k = static_cast<size_t>(id);
    const Vec3 d = view_point(view, i) - acc[k].centroid;
    if (dot(d, d) < best[k]) {
      best[k] = dot(d, d);
      m.patches[k].point_mm = world_from_cam * view_point(view, i);
      m.patches[k].object = view.object[i];
    }
  }
  for (size_t k = 0; k < n; ++k) {
    m.patches[k].normal = normalized(world_from_cam.rotation * acc[k].normal);
    m.patches[k].area_mm2 = acc[k].area;
    m.patches[k].albedo = acc[k].albedo / acc[k].area;
  }

  // Sub-patches for the near field: each patch split by a 4×4 grid of its block.
  struct Sub {
    Vec3 p, n;
    double a = 0;
  };
  std::vector<std::array<Sub, 16>> subs(n);
  const uint32_t q = std::max(1u, patch_px / 4);
  for (uint32_t y = 0; y < view.height; ++y)
    for (uint32_t x = 0; x < view.width; ++x) {
      const size_t i = size_t{y} * view.width + x;
      const int32_t id = m.pixel_patch[i];
      if (id < 0) continue;
      const size_t k = std::min(3u, (y % patch_px) / q) * 4 + std::min(3u, (x % patch_px) / q);
      Sub& sb = subs[static_cast<size_t>(id)][k];
      const double a = static_cast<double>(m.pixel_area_mm2[i]);
      sb.p = sb.p + (world_from_cam * view_point(view, i)) * a;
      sb.n = sb.n + (world_from_cam.rotation * view_normal(view, i)) * a;
      sb.a += a;
    }
  for (auto& arr : subs)
    for (auto& sb : arr)
      if (sb.a > 0) {
        sb.p = sb.p * (1.0 / sb.a);
        sb.n = normalized(sb.n);
      }

  // Form factors with visibility (upper triangle, mirrored through reciprocity):
  // G_ij = Σ cosθ_i cosθ_j A_i A_j / (π r² + (A_i + A_j)/2) over the patch
  // pair, or over their 16 × 16 sub-patch pairs when r < 3 patch sizes (the
  // near field, e.g. across a concave edge); F_ij = G_ij / A_i.
  const SceneTracer tracer(scene);
  m.form_factor.assign(n * n, 0.f);
  constexpr double kOffsetMm = 0.05;
  detail::parallel_rows(static_cast<uint32_t>(n), threads, [&](uint32_t b, uint32_t e) {
    for (size_t i = b; i < e; ++i) {
      const Patch& pi = m.patches[i];
      const Vec3 oi = pi.point_mm + pi.normal * kOffsetMm;
      for (size_t j = i + 1; j < n; ++j) {
        const Patch& pj = m.patches[j];
        const Vec3 d = pj.point_mm - pi.point_mm;
        const double r2 = dot(d, d);
        if (!(r2 > 0)) continue;
        const double r = std::sqrt(r2);
        const double cos_i = dot(pi.normal, d) / r, cos_j = -dot(pj.normal, d) / r;
        const bool near = r2 < 9.0 * std::max(pi.area_mm2, pj.area_mm2);
        if (!near && !(cos_i > 1e-6 && cos_j > 1e-6)) continue;
        if (cos_i > 1e-6 && cos_j > 1e-6) {
          const Vec3 seg = pj.point_mm + pj.normal * kOffsetMm - oi;
          Hit h;
          if (tracer.first_hit(oi, seg, 1e-6, h) && h.t < 0.999) continue;
        }
        double g = 0;
        if (!near) {
          g = cos_i * cos_j * pi.area_mm2 * pj.area_mm2 / (M_PI * r2 + 0.5 * (pi.area_mm2 + pj.area_mm2));
        } else {
          for (const Sub& sa : subs[i]) {
            if (!(sa.a > 0)) continue;
            for (const Sub& sb : subs[j]) {
              if (!(sb.a > 0)) continue;
              const Vec3 dd = sb.p - sa.p;
              const double rr2 = dot(dd, dd);
              if (!(rr2 > 0)) continue;
              const double rr = std::sqrt(rr2);
              const double ca = dot(sa.n, dd) / rr, cb = -dot(sb.n, dd) / rr;
              if (ca > 0 && cb > 0) g += ca * cb * sa.a * sb.a / (M_PI * rr2 + 0.5 * (sa.a + sb.a));
            }
          }
        }
        m.form_factor[i * n + j] = static_cast<float>(g / pi.area_mm2);
        m.form_factor[j * n + i] = static_cast<float>(g / pj.area_mm2);
      }
    }
  });
  // A patch cannot send more than all its light: rescale rows summing above 1
  // (only possible through the point estimate's error for near patches).
  for (size_t i = 0; i < n; ++i) {
    double s = 0;
    for (size_t j = 0; j < n; ++j) s += static_cast<double>(m.form_factor[i * n + j]);
    if (s > 1.0)
      for (size_t j = 0; j < n; ++j) m.form_factor[i * n + j] = static_cast<float>(static_cast<double>(m.form_factor[i * n + j]) / s);
  }

  // H = (I − F·D)⁻¹·F·D.
  std::vector<double> A(n * n), R(n * n);
  for (size_t i = 0; i < n; ++i)
    for (size_t j = 0; j < n; ++j) {
      const double fd = static_cast<double>(m.form_factor[i * n + j]) * m.patches[j].albedo;
      R[i * n + j] = fd;
      A[i * n + j] = (i == j ? 1.0 : 0.0) - fd;
    }
  solve_dense(A, R, n, threads);
  m.transport.resize(n * n);
  for (size_t k = 0; k < n * n; ++k) m.transport[k] = static_cast<float>(R[k]);

  // Gather weights: a tent of one block width around each patch's pixel
  // centroid (= bilinear interpolation over block centres for whole blocks;
  // follows the object for blocks it only partly covers), over the same
  // object's patches in the 3×3 neighbouring blocks, 4 largest kept, normalised.
  std::vector<double> cu(n, 0.0), cv(n, 0.0), cnt(n, 0.0);
  for (uint32_t y = 0; y < view.height; ++y)
    for (uint32_t x = 0; x < view.width; ++x) {
      const int32_t p = m.pixel_patch[size_t{y} * view.width + x];
      if (p < 0) continue;
      cu[static_cast<size_t>(p)] += x;
      cv[static_cast<size_t>(p)] += y;
      cnt[static_cast<size_t>(p)] += 1;
    }
  for (size_t k = 0; k < n; ++k) {
    cu[k] /= cnt[k];
    cv[k] /= cnt[k];
  }
  m.gather_patch.assign(4 * n_px, -1);
  m.gather_weight.assign(4 * n_px, 0.f);
  const double P = patch_px;
  for (uint32_t y = 0; y < view.height; ++y)
    for (uint32_t x = 0; x < view.width; ++x) {
      const size_t i = size_t{y} * view.width + x;
      const int32_t obj = view.object[i];
      if (obj < 0) continue;
      std::pair<double, int32_t> best4[4] = {{0, -1}, {0, -1}, {0, -1}, {0, -1}};
      const int64_t bx = x / patch_px, by = y / patch_px;
      for (int64_t cy = by - 1; cy <= by + 1; ++cy)
        for (int64_t cx = bx - 1; cx <= bx + 1; ++cx) {
          if (cx < 0 || cy < 0 || cx >= bw || cy >= bh) continue;
          for (const auto& [o, p] : block_patches[static_cast<size_t>(cy) * bw + static_cast<size_t>(cx)]) {
            if (o != obj) continue;
            const auto k = static_cast<size_t>(p);
            const double w = std::max(0.0, 1 - std::abs(x - cu[k]) / P) * std::max(0.0, 1 - std::abs(y - cv[k]) / P);
            if (!(w > 0)) continue;
            size_t worst = 0;
            for (size_t s2 = 1; s2 < 4; ++s2)
              if (best4[s2].first < best4[worst].first) worst = s2;
            if (w > best4[worst].first) best4[worst] = {w, p};
          }
        }
      double wsum = 0;
      for (const auto& b : best4) wsum += b.first;
      if (!(wsum > 0)) {
        m.gather_patch[4 * i] = m.pixel_patch[i];
        m.gather_weight[4 * i] = 1.f;
        continue;
      }
      size_t slot = 0;
      for (const auto& b : best4)
        if (b.second >= 0) {
          m.gather_patch[4 * i + slot] = b.second;
          m.gather_weight[4 * i + slot] = static_cast<float>(b.first / wsum);
          ++slot;
        }
    }
  return m;
}

void InterreflectionComponent::begin_frame(const FrameContext& frame, int threads) {
  const PreparedView& v = frame.view;
  const size_t n = model_.size();
  if (!compact_ && n > 0 && n <= 65536 && model_.gather_patch.size() == 4 * v.pixel_count()) {
    const size_t m = model_.gather_patch.size();
    gather_p16_.assign(m, 0);
    gather_w_.assign(m, 0.f);
    for (size_t k = 0; k < m; ++k) {
      const size_t i = k / 4;
      const int32_t q = model_.gather_patch[k];
      if (q < 0 || v.object[i] < 0) continue;
      gather_p16_[k] = static_cast<uint16_t>(q);
      gather_w_[k] = static_cast<float>(static_cast<double>(model_.gather_weight[k]) * static_cast<double>(v.albedo[i]) / M_PI);
    }
    compact_ = true;
  }
  sum_.assign(n, 0.0);
  std::mutex merge;
  detail::parallel_rows(v.height, threads, [&](uint32_t rb, uint32_t re) {
    std::vector<float> local(n, 0.f);  // per-chunk partial sums (one patch row spans ≤ patch_px rows)
    for (size_t i = size_t{rb} * v.width; i < size_t{re} * v.width; ++i) {
      const int32_t p = model_.pixel_patch[i];
      if (p >= 0) local[static_cast<size_t>(p)] += model_.pixel_area_mm2[i] * frame.irradiance[i];
    }
    const std::lock_guard<std::mutex> lock(merge);
    for (size_t k = 0; k < n; ++k) sum_[k] += static_cast<double>(local[k]);
  });
  e_direct_.resize(n);
  for (size_t k = 0; k < n; ++k) e_direct_[k] = static_cast<float>(sum_[k] / model_.patches[k].area_mm2);
  // Glossy: mean emitted light of each block (sharp pattern, level 0).
  e_total_ = e_direct_;
  std::vector<float> e_gl(n, 0.f);
  if (!model_.glossy.empty()) {
    const float* l0 = frame.pattern.level(0);
    const size_t stride = frame.pattern.stride();
    const uint32_t g = model_.glossy_block_px;
    block_mean_.resize(model_.glossy_blocks.size());
    for (size_t b = 0; b < model_.glossy_blocks.size(); ++b) {
      const uint32_t x0 = model_.glossy_blocks[b] % v.proj_width, y0 = model_.glossy_blocks[b] / v.proj_width;
      float s = 0;
      for (uint32_t y = y0; y < y0 + g; ++y)
        for (uint32_t x = x0; x < x0 + g; ++x) s += l0[(size_t{y} + 1) * stride + x + 1];
      block_mean_[b] = s / static_cast<float>(g * g);
    }
    for (const auto& e : model_.glossy) e_gl[e.patch] += e.irradiance * block_mean_[e.block];
    for (size_t k = 0; k < n; ++k) e_total_[k] += e_gl[k];
  }
  e_global_.assign(n, 0.f);
  detail::parallel_rows(static_cast<uint32_t>(n), threads, [&](uint32_t b, uint32_t e) {
    for (size_t i = b; i < e; ++i) {
      const float* h = &model_.transport[i * n];
      float s = 0;
      for (size_t j = 0; j < n; ++j) s += h[j] * e_total_[j];
      e_global_[i] = s + e_gl[i];
    }
  });
}

void InterreflectionComponent::apply(const FrameContext& frame, uint32_t row_begin, uint32_t row_end,
                                     float* radiance) const {
  const PreparedView& v = frame.view;
  const size_t b = size_t{row_begin} * v.width, e = size_t{row_end} * v.width;
  const float* eg = e_global_.data();
  if (compact_) {
    const uint16_t* p = gather_p16_.data();
    const float* w = gather_w_.data();
    for (size_t i = b; i < e; ++i)
      radiance[i] += w[4 * i] * eg[p[4 * i]] + w[4 * i + 1] * eg[p[4 * i + 1]] + w[4 * i + 2] * eg[p[4 * i + 2]] +
                     w[4 * i + 3] * eg[p[4 * i + 3]];
    return;
  }
  const auto inv_pi = static_cast<float>(1.0 / M_PI);
  for (size_t i = b; i < e; ++i) {
    if (v.object[i] < 0) continue;
    float sum = 0;
    for (size_t s = 0; s < 4; ++s) {
      const int32_t q = model_.gather_patch[4 * i + s];
      if (q < 0) break;
      sum += model_.gather_weight[4 * i + s] * eg[static_cast<size_t>(q)];
    }
    radiance[i] += v.albedo[i] * inv_pi * sum;
  }
}

}  // namespace procam::sim
