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

// Gaussian of σ sampled at integers, truncated at 3σ (rounded up; at least
// 1), normalised.
std::vector<float> gaussian_kernel(double sigma) {
  if (!(sigma > 1e-3)) return {1.f};
  const int r = std::max(1, static_cast<int>(std::ceil(3.0 * sigma)));
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

// Separable blur of a w×h grid with `kernel` (zero outside): out = K ∗ in.
// Both passes run along rows as one saxpy per tap (vectorised), rows split
// over threads. `tmp` is scratch of w·h floats.
void blur_separable(const float* in, float* out, float* tmp, uint32_t w, uint32_t h,
                    const std::vector<float>& kernel, int threads) {
  const auto r = static_cast<int64_t>(kernel.size() / 2);
  const auto W = static_cast<int64_t>(w), H = static_cast<int64_t>(h);
  detail::parallel_rows(h, threads, [&](uint32_t b, uint32_t e) {
    for (uint32_t y = b; y < e; ++y) {
      const float* src = in + size_t{y} * w;
      float* dst = tmp + size_t{y} * w;
      std::fill(dst, dst + w, 0.f);
      for (int64_t j = -r; j <= r; ++j) {
        const float k = kernel[static_cast<size_t>(j + r)];
        const int64_t lo = std::max<int64_t>(0, -j), hi = std::min<int64_t>(W, W - j);
        for (int64_t x = lo; x < hi; ++x) dst[x] += k * src[x + j];
      }
    }
  });
  detail::parallel_rows(h, threads, [&](uint32_t b, uint32_t e) {
    for (uint32_t y = b; y < e; ++y) {
      float* dst = out + size_t{y} * w;
      std::fill(dst, dst + w, 0.f);
      for (int64_t j = -r; j <= r; ++j) {
        const int64_t yy = static_cast<int64_t>(y) + j;
        if (yy < 0 || yy >= H) continue;
        const float k = kernel[static_cast<size_t>(j + r)];
        const float* src = tmp + static_cast<size_t>(yy) * w;
        for (uint32_t x = 0; x < w; ++x) dst[x] += k * src[x];
      }
    }
  });
}

// Level l+1 of a pyramid: sums of 2×2 cells of level l (cells past the edge are 0).
void sum_2x2(const float* fine, uint32_t fw, uint32_t fh, float* coarse, uint32_t cw, uint32_t ch) {
  for (uint32_t y = 0; y < ch; ++y)
    for (uint32_t x = 0; x < cw; ++x) {
      float s = 0;
      for (uint32_t dy = 0; dy < 2; ++dy)
        for (uint32_t dx = 0; dx < 2; ++dx) {
          const uint32_t fx = 2 * x + dx, fy = 2 * y + dy;
          if (fx < fw && fy < fh) s += fine[size_t{fy} * fw + fx];
        }
      coarse[size_t{y} * cw + x] = s;
    }
}

// fine += bilinear 2× upsampling of coarse (cell centres: fine i ↔ coarse
// i/2 − ¼, i.e. weights ¾ / ¼ to the nearer / farther coarse cell; clamped).
void add_upsampled_2x(const float* coarse, uint32_t cw, uint32_t ch, float* fine, uint32_t fw, uint32_t fh) {
  auto taps = [](uint32_t i, uint32_t n, uint32_t& a, uint32_t& b) {
    const uint32_t k = i / 2;
    a = k;
    if (i % 2 == 0) b = k > 0 ? k - 1 : k;
    else b = k + 1 < n ? k + 1 : k;
  };
  for (uint32_t y = 0; y < fh; ++y) {
    uint32_t ya, yb;
    taps(y, ch, ya, yb);
    const float* ra = coarse + size_t{std::min(ya, ch - 1)} * cw;
    const float* rb = coarse + size_t{std::min(yb, ch - 1)} * cw;
    float* dst = fine + size_t{y} * fw;
    for (uint32_t x = 0; x < fw; ++x) {
      uint32_t xa, xb;
      taps(x, cw, xa, xb);
      xa = std::min(xa, cw - 1);
      xb = std::min(xb, cw - 1);
      const float top = 0.75f * ra[xa] + 0.25f * ra[xb];
      const float bot = 0.75f * rb[xa] + 0.25f * rb[xb];
      dst[x] += 0.75f * top + 0.25f * bot;
    }
  }
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
