// SPDX-License-Identifier: MIT
// Global transport components: radiosity inter-reflection with glossy
// transport, and screen-space diffusion (sub-surface scattering, thin sheets).
#include "procam/hw/sim/global.hpp"

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <map>
#include <mutex>
#include <random>

#include "parallel.hpp"
#include "procam/hw/sim/raycast.hpp"

namespace procam::sim {
namespace {

double ms_since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
}

Vec3 view_point(const PreparedView& v, size_t i) {
  return {static_cast<double>(v.point_mm[3 * i]), static_cast<double>(v.point_mm[3 * i + 1]),
          static_cast<double>(v.point_mm[3 * i + 2])};
}
Vec3 view_normal(const PreparedView& v, size_t i) {
  return {static_cast<double>(v.normal[3 * i]), static_cast<double>(v.normal[3 * i + 1]),
          static_cast<double>(v.normal[3 * i + 2])};
}

// Footprint of camera pixel i on its surface, mm²: z²/(fx·fy) / cosθ_c, with
// cosθ_c clamped at 0.1 (grazing pixels).
double pixel_area(const PreparedView& v, size_t i) {
  const Vec3 p = view_point(v, i);
  const Vec3 n = view_normal(v, i);
  const double cos_c = std::max(0.1, std::abs(dot(n, p)) / norm(p));
  return p.z * p.z / (v.camera.intrinsics.fx * v.camera.intrinsics.fy) / cos_c;
}

// Solves X = A⁻¹·R in place (R becomes X) for A strictly diagonally dominant
// by rows (no pivoting needed). Both N×N row-major doubles.
void solve_dense(std::vector<double>& A, std::vector<double>& R, size_t n, int threads) {
  for (size_t k = 0; k < n; ++k) {
    const double pivot = A[k * n + k];
    const double* ak = &A[k * n];
    const double* rk = &R[k * n];
    // Eliminate column k from every other row (Gauss–Jordan).
    detail::parallel_rows(static_cast<uint32_t>(n), threads, [&](uint32_t b, uint32_t e) {
      for (size_t i = b; i < e; ++i) {
        if (i == k) continue;
        const double l = A[i * n + k] / pivot;
        if (l == 0) continue;
        double* ai = &A[i * n];
        double* ri = &R[i * n];
        for (size_t j = k; j < n; ++j) ai[j] -= l * ak[j];
        for (size_t j = 0; j < n; ++j) ri[j] -= l * rk[j];
      }
    });
  }
  for (size_t i = 0; i < n; ++i) {
    const double d = A[i * n + i];
    for (size_t j = 0; j < n; ++j) R[i * n + j] /= d;
  }
}

// Gaussian of σ sampled at integers, truncated at 3σ + 1, normalised.
std::vector<float> gaussian_kernel(double sigma) {
  if (!(sigma > 1e-3)) return {1.f};
  const int r = static_cast<int>(std::ceil(3.0 * sigma + 1.0));
  std::vector<double> w(static_cast<size_t>(2 * r + 1));
  double sum = 0;
  for (int j = -r; j <= r; ++j) {
    w[static_cast<size_t>(j + r)] = std::exp(-0.5 * j * j / (sigma * sigma));
    sum += w[static_cast<size_t>(j + r)];
  }
  std::vector<float> out(w.size());
  for (size_t k = 0; k < w.size(); ++k) out[k] = static_cast<float>(w[k] / sum);
  return out;
}

// Separable blur of a cw×ch grid with `kernel` (zero outside).
void blur_grid(std::vector<float>& g, uint32_t cw, uint32_t ch, const std::vector<float>& kernel) {
  if (kernel.size() <= 1) return;
  const auto r = static_cast<int64_t>(kernel.size() / 2);
  std::vector<float> tmp(g.size(), 0.f);
  for (uint32_t y = 0; y < ch; ++y)
    for (int64_t x = 0; x < cw; ++x) {
      float s = 0;
      for (int64_t j = -r; j <= r; ++j) {
        const int64_t xx = x + j;
        if (xx >= 0 && xx < cw) s += kernel[static_cast<size_t>(j + r)] * g[size_t{y} * cw + static_cast<size_t>(xx)];
      }
      tmp[size_t{y} * cw + static_cast<size_t>(x)] = s;
    }
  for (int64_t y = 0; y < ch; ++y)
    for (uint32_t x = 0; x < cw; ++x) {
      float s = 0;
      for (int64_t j = -r; j <= r; ++j) {
        const int64_t yy = y + j;
        if (yy >= 0 && yy < ch) s += kernel[static_cast<size_t>(j + r)] * tmp[static_cast<size_t>(yy) * cw + x];
      }
      g[static_cast<size_t>(y) * cw + x] = s;
    }
}

// Bilinear sample of a coarse grid at fine pixel (x, y) of a model's bbox.
float sample_coarse(const DiffusionModel& m, const std::vector<float>& g, uint32_t x, uint32_t y) {
  const double f = m.factor;
  double cx = (static_cast<double>(x - m.x0) + 0.5) / f - 0.5;
  double cy = (static_cast<double>(y - m.y0) + 0.5) / f - 0.5;
  cx = std::clamp(cx, 0.0, static_cast<double>(m.cw - 1));
  cy = std::clamp(cy, 0.0, static_cast<double>(m.ch - 1));
  const auto ix = std::min(static_cast<uint32_t>(cx), m.cw > 1 ? m.cw - 2 : 0u);
  const auto iy = std::min(static_cast<uint32_t>(cy), m.ch > 1 ? m.ch - 2 : 0u);
  const auto fx = static_cast<float>(cx - ix), fy = static_cast<float>(cy - iy);
  const uint32_t ix1 = m.cw > 1 ? ix + 1 : ix, iy1 = m.ch > 1 ? iy + 1 : iy;
  const float a = g[size_t{iy} * m.cw + ix], b = g[size_t{iy} * m.cw + ix1];
  const float c = g[size_t{iy1} * m.cw + ix], d = g[size_t{iy1} * m.cw + ix1];
  const float top = a + fx * (b - a), bot = c + fx * (d - c);
  return top + fy * (bot - top);
}

// Sum of values (value(i) for the model's object pixels, 0 elsewhere) per
// coarse cell.
template <typename F>
std::vector<float> downsample(const DiffusionModel& m, const PreparedView& v, F value) {
  std::vector<float> g(size_t{m.cw} * m.ch, 0.f);
  for (uint32_t y = m.y0; y < m.y1; ++y)
    for (uint32_t x = m.x0; x < m.x1; ++x) {
      const size_t i = size_t{y} * v.width + x;
      if (v.object[i] != m.object) continue;
      g[size_t{(y - m.y0) / m.factor} * m.cw + (x - m.x0) / m.factor] += value(i);
    }
  return g;
}

}  // namespace

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

void add_glossy_transport(const Scene& scene, const PreparedView& view, const ProjectorModel& projector,
                          const Rigid3& world_from_cam, const Rigid3& world_from_proj,
                          const GlobalOptions& options, RadiosityModel& m) {
  bool any = false;
  for (const auto& o : scene.objects) any = any || o.material.glossy();
  if (!any || m.size() == 0) return;
  const SceneTracer tracer(scene);
  const Intrinsics& Kp = projector.intrinsics;
  const Intrinsics& K = view.camera.intrinsics;
  const Rigid3 cam_from_world = world_from_cam.inverse();
  const uint32_t g = std::max(1u, options.glossy_block_px);
  const uint32_t S = std::max(1u, options.glossy_samples);
  m.glossy_block_px = g;
  const double intensity = projector.irradiance_at_1m * 1.0e6;  // iu·mm² per sr
  const Vec3 pc = world_from_proj.translation_mm;
  std::map<std::pair<uint32_t, uint32_t>, double> entries;  // (block, patch) → iu per unit emitted
  std::mt19937 rng(12345);
  std::normal_distribution<double> gauss(0.0, 1.0);
  for (uint32_t by = 0; by + g <= Kp.height; by += g)
    for (uint32_t bx = 0; bx + g <= Kp.width; bx += g) {
      const double xp = bx + 0.5 * (g - 1), yp = by + 0.5 * (g - 1);
      const Vec3 ray_p = Kp.ray(xp, yp);  // z = 1
      const Vec3 d = normalized(world_from_proj.rotation * ray_p);
      Hit h;
      if (!tracer.first_hit(pc, d, 1e-9, h)) continue;
      const Material& mat = tracer.material(h.object);
      if (!mat.glossy()) continue;
      Vec3 n = h.normal;
      if (dot(n, d) > 0) n = -n;
      // Power leaving the projector through the block per unit emitted:
      // I · Ω, Ω = g² / (fx·fy·|ray|³) (pixel solid angle off axis).
      const double rn = norm(ray_p);
      const double power = intensity * g * g / (Kp.fx * Kp.fy * rn * rn * rn) * mat.specular / S;
      const Vec3 mirror = d - n * (2.0 * dot(d, n));
      const Vec3 t1 = normalized(std::abs(mirror.x) < 0.9 ? cross(mirror, Vec3{1, 0, 0}) : cross(mirror, Vec3{0, 1, 0}));
      const Vec3 t2 = cross(mirror, t1);
      const uint32_t block = static_cast<uint32_t>(m.glossy_blocks.size());
      bool used = false;
      for (uint32_t s = 0; s < S; ++s) {
        const Vec3 dir = normalized(mirror + t1 * (mat.roughness_rad * gauss(rng)) + t2 * (mat.roughness_rad * gauss(rng)));
        if (dot(dir, n) <= 0) continue;  // into the surface: absorbed
        Hit y;
        if (!tracer.first_hit(h.point_mm + n * 0.05, dir, 1e-6, y)) continue;
        const Vec3 yc = cam_from_world * y.point_mm;
        if (!(yc.z > 0)) continue;
        double u = 0, v = 0;
        K.project(yc, u, v);
        const auto iu = static_cast<int64_t>(std::floor(u + 0.5)), iv = static_cast<int64_t>(std::floor(v + 0.5));
        if (iu < 0 || iv < 0 || iu >= K.width || iv >= K.height) continue;
        const size_t i = static_cast<size_t>(iv) * view.width + static_cast<size_t>(iu);
        if (view.object[i] != y.object || std::abs(static_cast<double>(view.depth_mm[i]) - yc.z) > 1.0 + 0.01 * yc.z)
          continue;  // not what the camera sees there: hidden from the camera
        const int32_t p = m.pixel_patch[i];
        if (p < 0) continue;
        entries[{block, static_cast<uint32_t>(p)}] += power / m.patches[static_cast<size_t>(p)].area_mm2;
        used = true;
      }
      if (used) m.glossy_blocks.push_back(by * Kp.width + bx);
    }
  m.glossy.reserve(entries.size());
  for (const auto& [key, w] : entries) m.glossy.push_back({key.second, key.first, static_cast<float>(w)});
}

void InterreflectionComponent::begin_frame(const FrameContext& frame, int threads) {
  const PreparedView& v = frame.view;
  const size_t n = model_.size();
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
  const auto inv_pi = static_cast<float>(1.0 / M_PI);
  for (size_t i = size_t{row_begin} * v.width; i < size_t{row_end} * v.width; ++i) {
    if (v.object[i] < 0) continue;
    float e = 0;
    for (size_t s = 0; s < 4; ++s) {
      const int32_t p = model_.gather_patch[4 * i + s];
      if (p < 0) break;
      e += model_.gather_weight[4 * i + s] * e_global_[static_cast<size_t>(p)];
    }
    radiance[i] += v.albedo[i] * inv_pi * e;
  }
}

// ---- Glossy, camera side -------------------------------------------------------

GlossyViewModel build_glossy_view(const Scene& scene, const PreparedView& view, const ProjectorModel& projector,
                                  const Rigid3& world_from_cam, const Rigid3& world_from_proj,
                                  const GlobalOptions& options) {
  GlossyViewModel out;
  bool any = false;
  for (const auto& o : scene.objects) any = any || o.material.glossy();
  if (!any) return out;
  const SceneTracer tracer(scene);
  const Intrinsics& Kp = projector.intrinsics;
  const Rigid3 proj_from_world = world_from_proj.inverse();
  const Vec3 pc = world_from_proj.translation_mm;
  const double intensity = projector.irradiance_at_1m * 1.0e6;
  const uint32_t S = std::max(1u, options.glossy_samples / 4);
  const int64_t stride = static_cast<int64_t>(Kp.width) + 2;
  const double W = Kp.width, H = Kp.height;
  std::mt19937 rng(54321);
  std::normal_distribution<double> gauss(0.0, 1.0);
  for (size_t i = 0; i < view.pixel_count(); ++i) {
    if (view.object[i] < 0) continue;
    const Material& mat = scene.objects[static_cast<size_t>(view.object[i])].material;
    if (!mat.glossy()) continue;
    const Vec3 x = world_from_cam * view_point(view, i);
    const Vec3 n = normalized(world_from_cam.rotation * view_normal(view, i));
    const Vec3 d = normalized(x - world_from_cam.translation_mm);
    const Vec3 mirror = d - n * (2.0 * dot(d, n));
    const Vec3 t1 = normalized(std::abs(mirror.x) < 0.9 ? cross(mirror, Vec3{1, 0, 0}) : cross(mirror, Vec3{0, 1, 0}));
    const Vec3 t2 = cross(mirror, t1);
    for (uint32_t s = 0; s < S; ++s) {
      const Vec3 dir = normalized(mirror + t1 * (mat.roughness_rad * gauss(rng)) + t2 * (mat.roughness_rad * gauss(rng)));
      if (dot(dir, n) <= 0) continue;
      Hit y;
      if (!tracer.first_hit(x + n * 0.05, dir, 1e-6, y)) continue;
      Vec3 ny = y.normal;
      if (dot(ny, dir) > 0) ny = -ny;  // facing the glossy point
      const Vec3 to_p = pc - y.point_mm;
      const double dist = norm(to_p);
      const double cos_p = dot(ny, to_p) / dist;
      if (!(cos_p > 0)) continue;
      const Vec3 yp = proj_from_world * y.point_mm;
      if (!(yp.z > 0)) continue;
      double u = 0, v = 0;
      Kp.project(yp, u, v);
      if (!(u >= -0.5 && u < W - 0.5 && v >= -0.5 && v < H - 0.5)) continue;
      Hit first;
      if (tracer.first_hit(pc, y.point_mm - pc, 1e-12, first) && first.t < 1.0 - 1e-6) continue;  // shadowed
      const double albedo_y = tracer.material(y.object).albedo;
      const double w = mat.specular / S * albedo_y / M_PI * intensity * cos_p / (dist * dist);
      if (!(w > 0)) continue;
      const auto iu = static_cast<int64_t>(std::floor(u + 0.5)), iv = static_cast<int64_t>(std::floor(v + 0.5));
      out.pixel.push_back(static_cast<uint32_t>(i));
      out.source.push_back(static_cast<int32_t>((iv + 1) * stride + iu + 1));
      out.weight.push_back(static_cast<float>(w));
    }
  }
  return out;
}

void GlossyViewComponent::apply(const FrameContext& frame, uint32_t row_begin, uint32_t row_end,
                                float* radiance) const {
  const float* l0 = frame.pattern.level(0);
  const auto b = static_cast<uint32_t>(size_t{row_begin} * frame.view.width);
  const auto e = static_cast<uint32_t>(size_t{row_end} * frame.view.width);
  auto it = std::lower_bound(model_.pixel.begin(), model_.pixel.end(), b);
  for (auto k = static_cast<size_t>(it - model_.pixel.begin()); k < model_.pixel.size() && model_.pixel[k] < e; ++k)
    radiance[model_.pixel[k]] += model_.weight[k] * l0[model_.source[k]];
}

// ---- Diffusion -----------------------------------------------------------------

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
    const double px_per_mm = view.camera.intrinsics.fx / z;
    if (m.sheet) {
      if (behind.empty()) continue;  // nothing behind: the transmitted light leaves the scene
      m.behind_mm = median(behind);
      m.behind_albedo = median(behind_albedo);
      m.sigma_mm = 0.77 * m.behind_mm;
      m.gain = mat.transmittance * mat.transmittance * m.behind_albedo / M_PI;
    } else {
      m.sigma_mm = mat.diffusion_length_mm();
      m.gain = (mat.albedo - mat.direct_albedo()) / M_PI;
    }
    m.sigma_px = m.sigma_mm * px_per_mm;
    // Coarse grid: cell f ≈ σ/2 (σ ≥ 2f keeps σ' > 0); the cell box (variance
    // (f² − 1)/12) and the bilinear upsampling tent (f²/6) are taken out of σ².
    m.factor = std::clamp(static_cast<uint32_t>(m.sigma_px / 2.0), 1u, 32u);
    const double f = m.factor;
    double var = m.sigma_px * m.sigma_px;
    if (m.factor > 1) var -= (f * f - 1) / 12.0 + f * f / 6.0;
    const double sigma_c = std::sqrt(std::max(0.0, var)) / f;
    m.kernel = gaussian_kernel(sigma_c);
    m.cw = (m.x1 - m.x0 + m.factor - 1) / m.factor;
    m.ch = (m.y1 - m.y0 + m.factor - 1) / m.factor;
    m.mask_blurred = downsample(m, view, [](size_t) { return 1.f; });
    blur_grid(m.mask_blurred, m.cw, m.ch, m.kernel);
    out.push_back(std::move(m));
  }
  return out;
}

void DiffusionComponent::begin_frame(const FrameContext& frame, int threads) {
  blurred_.resize(models_.size());
  const PreparedView& v = frame.view;
  for (size_t k = 0; k < models_.size(); ++k) {
    const DiffusionModel& m = models_[k];
    std::vector<float>& g = blurred_[k];
    g.assign(size_t{m.cw} * m.ch, 0.f);
    // Rows of coarse cells in parallel: chunk boundaries on cell rows.
    detail::parallel_rows(m.ch, threads, [&](uint32_t cb, uint32_t ce) {
      for (uint32_t y = m.y0 + cb * m.factor; y < std::min(m.y1, m.y0 + ce * m.factor); ++y)
        for (uint32_t x = m.x0; x < m.x1; ++x) {
          const size_t i = size_t{y} * v.width + x;
          if (v.object[i] != m.object) continue;
          g[size_t{(y - m.y0) / m.factor} * m.cw + (x - m.x0) / m.factor] += frame.irradiance[i];
        }
    });
    blur_grid(g, m.cw, m.ch, m.kernel);
  }
}

void DiffusionComponent::apply(const FrameContext& frame, uint32_t row_begin, uint32_t row_end,
                               float* radiance) const {
  const PreparedView& v = frame.view;
  for (size_t k = 0; k < models_.size(); ++k) {
    const DiffusionModel& m = models_[k];
    const auto gain = static_cast<float>(m.gain);
    for (uint32_t y = std::max(row_begin, m.y0); y < std::min(row_end, m.y1); ++y)
      for (uint32_t x = m.x0; x < m.x1; ++x) {
        const size_t i = size_t{y} * v.width + x;
        if (v.object[i] != m.object) continue;
        const float den = sample_coarse(m, m.mask_blurred, x, y);
        if (!(den > 1e-6f)) continue;
        radiance[i] += gain * sample_coarse(m, blurred_[k], x, y) / den;
      }
  }
}

// ---- Assembly ------------------------------------------------------------------

Result<std::unique_ptr<Renderer>> make_scene_renderer(const Scene& scene, const ProjectorModel& projector,
                                                      const CameraCalibration& camera,
                                                      const Rigid3& world_from_proj,
                                                      const GlobalOptions& options, int threads,
                                                      PrepStats* stats) {
  PrepStats st;
  auto t0 = std::chrono::steady_clock::now();
  auto view = prepare_view(scene, projector, camera, world_from_proj, threads);
  if (!view.ok()) return view.status();
  st.view_ms = ms_since(t0);
  const Rigid3 world_from_cam = world_from_proj * camera.cam_from_proj.inverse();
  std::unique_ptr<InterreflectionComponent> inter;
  if (options.interreflection) {
    t0 = std::chrono::steady_clock::now();
    auto model = build_radiosity(scene, *view, world_from_cam, options.patch_px, threads);
    if (!model.ok()) return model.status();
    st.radiosity_ms = ms_since(t0);
    st.patches = model->size();
    if (options.glossy) {
      t0 = std::chrono::steady_clock::now();
      add_glossy_transport(scene, *view, projector, world_from_cam, world_from_proj, options, *model);
      st.glossy_ms = ms_since(t0);
      st.glossy_entries = model->glossy.size();
    }
    inter = std::make_unique<InterreflectionComponent>(std::move(model).value());
  }
  std::unique_ptr<GlossyViewComponent> glossy_view;
  if (options.glossy) {
    t0 = std::chrono::steady_clock::now();
    GlossyViewModel gv = build_glossy_view(scene, *view, projector, world_from_cam, world_from_proj, options);
    st.glossy_ms += ms_since(t0);
    st.glossy_entries += gv.pixel.size();
    if (!gv.pixel.empty()) glossy_view = std::make_unique<GlossyViewComponent>(std::move(gv));
  }
  std::unique_ptr<DiffusionComponent> diff;
  if (options.diffusion) {
    t0 = std::chrono::steady_clock::now();
    auto models = build_diffusion(scene, *view, world_from_cam);
    st.diffusion_ms = ms_since(t0);
    st.diffusion_objects = models.size();
    if (!models.empty()) diff = std::make_unique<DiffusionComponent>(std::move(models));
  }
  auto r = std::make_unique<Renderer>(std::move(view).value(), projector, threads);
  if (inter) r->add_component(std::move(inter));
  if (glossy_view) r->add_component(std::move(glossy_view));
  if (diff) r->add_component(std::move(diff));
  if (stats) *stats = st;
  return r;
}

}  // namespace procam::sim
