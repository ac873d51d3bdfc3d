// SPDX-License-Identifier: MIT
// Scene preparation (ray casting, shadows, Lambertian gains), thin-lens defocus
// maps, blurred pattern stacks and the direct transport component.
#include "procam/hw/sim/renderer.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <utility>

#include "global_internal.hpp"
#include "medium.hpp"
#include "tank.hpp"
#include "parallel.hpp"
#include "procam/hw/sim/raycast.hpp"
#include "procam/hw/sim/texture.hpp"

namespace procam::sim {
namespace {

constexpr float kNaN = std::numeric_limits<float>::quiet_NaN();

// Shadow-ray tolerance: the first hit along the projector ray counts as the
// point itself when it lies within this fraction of the distance to it.
constexpr double kShadowRelEps = 1e-6;

void fill_view_rows(const Scene& scene, const SceneTracer& tracer, const ProjectorModel& projector,
                    const Rigid3& world_from_cam, const Rigid3& proj_from_world,
                    const Vec3& proj_centre_world, PreparedView& v, uint32_t row_begin,
                    uint32_t row_end) {
  const Intrinsics& K = v.camera.intrinsics;
  const Intrinsics& Kp = projector.intrinsics;
  const double intensity = projector.irradiance_at_1m * 1.0e6;  // iu·mm²
  const double W = static_cast<double>(Kp.width), H = static_cast<double>(Kp.height);
  const int64_t stride = static_cast<int64_t>(Kp.width) + 2;
  const Vec3 origin = world_from_cam.translation_mm;
  for (uint32_t row = row_begin; row < row_end; ++row) {
    for (uint32_t col = 0; col < v.width; ++col) {
      const size_t i = size_t{row} * v.width + col;
      const Vec3 d_cam = K.ray(static_cast<double>(col), static_cast<double>(row));
      const Vec3 d_world = world_from_cam.rotation * d_cam;
      Hit hit;
      if (!tracer.first_hit(origin, d_world, 1e-9, hit)) continue;  // defaults: no surface
      const Vec3 x_cam = d_cam * hit.t;  // d_cam has z = 1, so z = t
      Vec3 n_world = hit.normal;
      if (dot(n_world, d_world) > 0) n_world = -n_world;  // face the camera
      const Vec3 n_cam = world_from_cam.rotation.transposed() * n_world;
      const Object& obj = scene.objects[static_cast<size_t>(hit.object)];
      // A textured plane: the texture's mean over this pixel's footprint
      // (texture.hpp, anti-aliased); else the material's albedo.
      const Plane* plane = obj.texture ? std::get_if<Plane>(&obj.shape) : nullptr;
      const double albedo =
          plane != nullptr ? footprint_albedo(*obj.texture, *plane, obj.material.albedo, K, world_from_cam,
                                              static_cast<double>(col), static_cast<double>(row))
                           : obj.material.albedo;
      v.depth_mm[i] = static_cast<float>(x_cam.z);
      v.point_mm[3 * i + 0] = static_cast<float>(x_cam.x);
      v.point_mm[3 * i + 1] = static_cast<float>(x_cam.y);
      v.point_mm[3 * i + 2] = static_cast<float>(x_cam.z);
      v.normal[3 * i + 0] = static_cast<float>(n_cam.x);
      v.normal[3 * i + 1] = static_cast<float>(n_cam.y);
      v.normal[3 * i + 2] = static_cast<float>(n_cam.z);
      v.object[i] = hit.object;
      v.albedo[i] = static_cast<float>(albedo);

      const Vec3 x_proj = proj_from_world * hit.point_mm;
      if (!(x_proj.z > 0)) continue;  // behind the projector: not lit, no coordinates
      double xp = 0, yp = 0;
      Kp.project(x_proj, xp, yp);
      v.proj_x[i] = static_cast<float>(xp);
      v.proj_y[i] = static_cast<float>(yp);
      v.proj_z_mm[i] = static_cast<float>(x_proj.z);

      const bool inside = xp >= -0.5 && xp < W - 0.5 && yp >= -0.5 && yp < H - 0.5;
      const Vec3 to_proj = proj_centre_world - hit.point_mm;
      const double dist = norm(to_proj);
      const double cos_p = dot(n_world, to_proj) / dist;
      if (!inside || !(cos_p > 0)) continue;
      // Occlusion: the first surface along the projector ray must be this point.
      Hit first;
      const Vec3 ray = hit.point_mm - proj_centre_world;  // t = 1 at the point
      if (tracer.first_hit(proj_centre_world, ray, 1e-12, first) && first.t < 1.0 - kShadowRelEps)
        continue;
      v.lit[i] = 1;
      const double irr = intensity * cos_p / (dist * dist);
      v.irradiance_gain[i] = static_cast<float>(irr);
      // Textured surfaces are opaque (the parser checks), so their direct albedo is the albedo.
      const double direct_albedo = plane != nullptr ? albedo : obj.material.direct_albedo();
      v.direct_gain[i] = static_cast<float>(direct_albedo / M_PI * irr);
      const auto ix = static_cast<int64_t>(std::floor(xp + 0.5));
      const auto iy = static_cast<int64_t>(std::floor(yp + 0.5));
      v.nearest[i] = static_cast<int32_t>((iy + 1) * stride + (ix + 1));
      const double x0 = std::floor(xp), y0 = std::floor(yp);
      v.bilinear[i] = static_cast<int32_t>((static_cast<int64_t>(y0) + 1) * stride + (static_cast<int64_t>(x0) + 1));
      v.frac_x[i] = static_cast<float>(xp - x0);
      v.frac_y[i] = static_cast<float>(yp - y0);
    }
  }
}

// Standard normal CDF.
double phi(double x) { return 0.5 * std::erfc(-x / std::sqrt(2.0)); }

// Gaussian of σ integrated over each unit pixel box (so level k = box image ∗ G_σ
// sampled at pixel centres), truncated at ~3σ + 1 and renormalised.
std::vector<float> box_gaussian_kernel(double sigma) {
  const int r = static_cast<int>(std::ceil(3.0 * sigma + 1.0));
  std::vector<double> w(static_cast<size_t>(2 * r + 1));
  double sum = 0;
  for (int j = -r; j <= r; ++j) {
    const double wj = phi((j + 0.5) / sigma) - phi((j - 0.5) / sigma);
    w[static_cast<size_t>(j + r)] = wj;
    sum += wj;
  }
  std::vector<float> out(w.size());
  for (size_t k = 0; k < w.size(); ++k) out[k] = static_cast<float>(w[k] / sum);
  return out;
}

}  // namespace

Result<PreparedView> prepare_view(const Scene& scene, const ProjectorModel& projector,
                                  const CameraCalibration& camera, const Rigid3& world_from_proj,
                                  int threads) {
  if (!camera.intrinsics.valid())
    return Error(Code::invalid_argument, "camera intrinsics invalid: width, height, fx, fy must be > 0");
  if (!projector.intrinsics.valid())
    return Error(Code::invalid_argument, "projector intrinsics invalid: width, height, fx, fy must be > 0");
  PreparedView v;
  v.width = camera.intrinsics.width;
  v.height = camera.intrinsics.height;
  v.proj_width = projector.intrinsics.width;
  v.proj_height = projector.intrinsics.height;
  v.camera = camera;
  v.projector = projector.intrinsics;
  const size_t n = v.pixel_count();
  v.depth_mm.assign(n, kNaN);
  v.point_mm.assign(3 * n, kNaN);
  v.normal.assign(3 * n, 0.f);
  v.object.assign(n, -1);
  v.albedo.assign(n, 0.f);
  v.proj_x.assign(n, kNaN);
  v.proj_y.assign(n, kNaN);
  v.proj_z_mm.assign(n, kNaN);
  v.lit.assign(n, 0);
  v.direct_gain.assign(n, 0.f);
  v.irradiance_gain.assign(n, 0.f);
  v.ambient.assign(n, 0.f);
  v.nearest.assign(n, -1);
  v.bilinear.assign(n, -1);
  v.frac_x.assign(n, 0.f);
  v.frac_y.assign(n, 0.f);

  const SceneTracer tracer(scene);
  // world_from_cam = world_from_proj · proj_from_cam
  const Rigid3 world_from_cam = world_from_proj * camera.cam_from_proj.inverse();
  const Rigid3 proj_from_world = world_from_proj.inverse();
  const Vec3 proj_centre_world = world_from_proj.translation_mm;
  detail::parallel_rows(v.height, threads, [&](uint32_t b, uint32_t e) {
    fill_view_rows(scene, tracer, projector, world_from_cam, proj_from_world, proj_centre_world, v, b, e);
  });
  for (size_t i = 0; i < n; ++i)
    v.ambient[i] = static_cast<float>(static_cast<double>(v.albedo[i]) / M_PI * scene.ambient);
  if (scene.medium)
    if (Status st = prepare_medium(scene, projector, world_from_cam, world_from_proj, v, threads); !st.ok()) return st;
  return v;
}

Result<PreparedView> prepare_view(const Scene& scene, const ProjectorModel& projector,
                                  const CameraCalibration& camera, int threads) {
  return prepare_view(scene, projector, camera, camera.cam_from_proj, threads);
}

namespace detail {
// Blur-stack level k (σ_k ≤ σ < σ_{k+1}, σ clamped to the top level) and the
// weight of level k + 1 that matches the variance: w = (σ² − σ_k²)/(σ_{k+1}² − σ_k²).
std::pair<uint8_t, float> blur_level(double sigma) {
  constexpr size_t L = kBlurLevelSigmaPx.size();
  size_t k = 0;
  while (k + 1 < L && static_cast<double>(kBlurLevelSigmaPx[k + 1]) <= sigma) ++k;
  double w = 0;
  if (k + 1 < L) {
    const double s0 = static_cast<double>(kBlurLevelSigmaPx[k]), s1 = static_cast<double>(kBlurLevelSigmaPx[k + 1]);
    w = (sigma * sigma - s0 * s0) / (s1 * s1 - s0 * s0);
  }
  return {static_cast<uint8_t>(k), static_cast<float>(w)};
}
}  // namespace detail
using detail::blur_level;

DefocusMap compute_defocus(const PreparedView& view, const ProjectorModel& projector, double focus_mm) {
  DefocusMap d;
  d.focus_mm = focus_mm;
  const size_t n = view.pixel_count();
  d.sigma_px.assign(n, 0.f);
  d.level.assign(n, 0);
  d.weight.assign(n, 0.f);
  size_t needed = 1;
  for (size_t i = 0; i < n; ++i) {
    if (!view.lit[i]) continue;
    const double z = static_cast<double>(view.proj_z_mm[i]);
    const double sigma = projector.aperture_mm > 0 ? projector.blur_sigma_px(z, focus_mm) : 0.0;
    d.sigma_px[i] = static_cast<float>(sigma);
    const auto [k, w] = blur_level(sigma);
    d.level[i] = k;
    d.weight[i] = w;
    needed = std::max(needed, size_t{k} + (w > 0 ? 2u : 1u));
  }
  d.levels_needed = needed;
  return d;
}

// ---- PreparedPattern -------------------------------------------------------

Result<PreparedPattern> PreparedPattern::from_pattern(const procam_image& pattern, const ProjectorModel& projector,
                                                      int threads) {
  PreparedPattern p;
  if (Status st = p.assign(pattern, projector, threads); !st.ok()) return st;
  return p;
}

Status PreparedPattern::assign(const procam_image& pattern, const ProjectorModel& projector, int threads) {
  if (const char* bad = validate_view(pattern))
    return Error(Code::invalid_argument, std::string("pattern image is malformed: ") + bad);
  if (pattern.channels != 1)
    return Error(Code::invalid_argument, "pattern must have 1 channel, got " + std::to_string(pattern.channels));
  if (pattern.width != projector.intrinsics.width || pattern.height != projector.intrinsics.height)
    return Error(Code::invalid_argument,
                 "pattern is " + std::to_string(pattern.width) + "x" + std::to_string(pattern.height) +
                     " but the projector is " + std::to_string(projector.intrinsics.width) + "x" +
                     std::to_string(projector.intrinsics.height),
                 "render patterns at the projector resolution from the rig description");
  // Storage of an earlier pattern of the same size is reused (its zero
  // border stays zero; every interior value is overwritten).
  PreparedPattern& p = *this;
  const bool same_size = p.width_ == pattern.width && p.height_ == pattern.height && !p.levels_.empty();
  p.width_ = pattern.width;
  p.height_ = pattern.height;
  const size_t stride = p.stride();
  if (p.levels_.empty()) p.levels_.resize(1);
  p.built_ = 1;
  std::vector<float>& l0 = p.levels_[0];
  if (!same_size) l0.assign(stride * (size_t{p.height_} + 2), 0.f);
  const auto* base = static_cast<const uint8_t*>(pattern.data);
  if (pattern.pixel_type == PROCAM_PIXEL_U8 || pattern.pixel_type == PROCAM_PIXEL_U16) {
    const bool u8 = pattern.pixel_type == PROCAM_PIXEL_U8;
    const uint32_t max_code = (1u << pattern.bit_depth) - 1u;
    std::vector<float> lut(u8 ? 256u : 65536u);
    for (size_t c = 0; c < lut.size(); ++c)
      lut[c] = static_cast<float>(projector.emitted(static_cast<double>(c) / static_cast<double>(max_code)));
    detail::parallel_rows(p.height_, threads, [&](uint32_t yb, uint32_t ye) {
      for (uint32_t y = yb; y < ye; ++y) {
        float* dst = l0.data() + (size_t{y} + 1) * stride + 1;
        const uint8_t* row = base + size_t{y} * pattern.stride_bytes;
        if (u8) {
          for (uint32_t x = 0; x < p.width_; ++x) dst[x] = lut[row[x]];
        } else {
          const auto* r16 = reinterpret_cast<const uint16_t*>(row);
          for (uint32_t x = 0; x < p.width_; ++x) dst[x] = lut[r16[x]];
        }
      }
    });
  } else {
    // F32: emitted curve tabulated at 65536 steps, linearly interpolated
    // (error < 1e-9 for gamma >= 1); exact at 0 and 1.
    constexpr size_t N = 65536;
    std::vector<float> lut(N + 1);
    for (size_t c = 0; c <= N; ++c)
      lut[c] = static_cast<float>(projector.emitted(static_cast<double>(c) / static_cast<double>(N)));
    for (uint32_t y = 0; y < p.height_; ++y) {
      float* dst = l0.data() + (size_t{y} + 1) * stride + 1;
      const auto* row = reinterpret_cast<const float*>(base + size_t{y} * pattern.stride_bytes);
      for (uint32_t x = 0; x < p.width_; ++x) {
        float v = row[x];
        v = std::isnan(v) ? 0.f : std::clamp(v, 0.f, 1.f);
        const float f = v * static_cast<float>(N);
        const auto i0 = std::min(static_cast<size_t>(f), N - 1);
        const float t = f - static_cast<float>(i0);
        dst[x] = lut[i0] + t * (lut[i0 + 1] - lut[i0]);
      }
    }
  }
  return Status::Ok();
}

Result<PreparedPattern> PreparedPattern::from_emitted(const Image& emitted) {
  if (emitted.empty() || emitted.type() != PixelType::f32 || emitted.channels() != 1)
    return Error(Code::invalid_argument, "emitted light must be a non-empty 1-channel F32 image");
  PreparedPattern p;
  p.width_ = emitted.width();
  p.height_ = emitted.height();
  const size_t stride = p.stride();
  p.levels_.resize(1);
  p.built_ = 1;
  p.levels_[0].assign(stride * (size_t{p.height_} + 2), 0.f);
  for (uint32_t y = 0; y < p.height_; ++y) {
    const float* src = emitted.row<float>(y);
    float* dst = p.levels_[0].data() + (size_t{y} + 1) * stride + 1;
    for (uint32_t x = 0; x < p.width_; ++x) {
      if (!std::isfinite(src[x]))
        return Error(Code::invalid_argument, "emitted light has a non-finite value at (" + std::to_string(x) +
                                                 ", " + std::to_string(y) + ")");
      dst[x] = src[x];
    }
  }
  return p;
}

size_t PreparedPattern::levels_built() const { return built_; }

const float* PreparedPattern::level(size_t k) const {
  if (k >= built_) return nullptr;
  return levels_[k].data();
}

void PreparedPattern::build_levels(size_t count, int threads) {
  if (levels_.empty()) return;
  count = std::min(count, kBlurLevelSigmaPx.size());
  if (levels_.size() < count) levels_.resize(count);
  const size_t stride = this->stride();
  const size_t rows = size_t{height_} + 2;
  tmp_.resize(stride * rows);
  for (size_t k = built_; k < count; ++k) {
    const std::vector<float> kernel = box_gaussian_kernel(static_cast<double>(kBlurLevelSigmaPx[k]));
    const auto r = static_cast<int64_t>(kernel.size() / 2);
    const std::vector<float>& src = levels_[0];
    // Horizontal pass over the padded image (zero outside): per tap a saxpy
    // along the row, which the compiler vectorises.
    detail::parallel_rows(static_cast<uint32_t>(rows), threads, [&](uint32_t b, uint32_t e) {
      for (uint32_t y = b; y < e; ++y) {
        const float* in = src.data() + size_t{y} * stride;
        float* out = tmp_.data() + size_t{y} * stride;
        std::fill(out, out + stride, 0.f);
        for (int64_t j = -r; j <= r; ++j) {
          const float w = kernel[static_cast<size_t>(j + r)];
          const int64_t x_lo = std::max<int64_t>(0, -j);
          const int64_t x_hi = std::min<int64_t>(static_cast<int64_t>(stride), static_cast<int64_t>(stride) - j);
          for (int64_t x = x_lo; x < x_hi; ++x) out[x] += w * in[x + j];
        }
      }
    });
    std::vector<float>& dst = levels_[k];
    dst.resize(stride * rows);
    detail::parallel_rows(static_cast<uint32_t>(rows), threads, [&](uint32_t b, uint32_t e) {
      for (uint32_t y = b; y < e; ++y) {
        float* out = dst.data() + size_t{y} * stride;
        std::fill(out, out + stride, 0.f);
        for (int64_t j = -r; j <= r; ++j) {
          const int64_t yy = static_cast<int64_t>(y) + j;
          if (yy < 0 || yy >= static_cast<int64_t>(rows)) continue;
          const float w = kernel[static_cast<size_t>(j + r)];
          const float* in = tmp_.data() + static_cast<size_t>(yy) * stride;
          for (size_t x = 0; x < stride; ++x) out[x] += w * in[x];
        }
      }
    });
    built_ = k + 1;
  }
}

// ---- Direct component -------------------------------------------------------

namespace {
// out[i] += gain[i] · (blurred emitted light at pixel i's projector point),
// for pixels [row_begin, row_end) that are lit.
void add_sampled(const FrameContext& frame, const std::vector<float>& gain, uint32_t row_begin,
                 uint32_t row_end, float* out) {
  const PreparedView& v = frame.view;
  const DefocusMap& d = frame.defocus;
  const size_t stride = frame.pattern.stride();
  const float* levels[kBlurLevelSigmaPx.size()] = {};
  for (size_t k = 0; k < kBlurLevelSigmaPx.size(); ++k) levels[k] = frame.pattern.level(k);
  const float* l0 = levels[0];
  auto bilinear = [&](const float* L, size_t i) {
    const float* p = L + v.bilinear[i];
    const float fx = v.frac_x[i], fy = v.frac_y[i];
    const float top = p[0] + fx * (p[1] - p[0]);
    const float bot = p[stride] + fx * (p[stride + 1] - p[stride]);
    return top + fy * (bot - top);
  };
  const size_t b = size_t{row_begin} * v.width, e = size_t{row_end} * v.width;
  for (size_t i = b; i < e; ++i) {
    if (!v.lit[i]) continue;
    const size_t k = d.level[i];
    const float w = d.weight[i];
    const float a = k == 0 ? l0[v.nearest[i]] : bilinear(levels[k], i);
    const float value = w > 0.f ? a + w * (bilinear(levels[k + 1], i) - a) : a;
    out[i] += gain[i] * value;
  }
}
}  // namespace

void DirectComponent::apply(const FrameContext& frame, uint32_t row_begin, uint32_t row_end,
                            float* radiance) const {
  if (frame.irradiance == nullptr || frame.direct_per_irradiance == nullptr) {
    add_sampled(frame, frame.view.direct_gain, row_begin, row_end, radiance);
    return;
  }
  const size_t b = size_t{row_begin} * frame.view.width, e = size_t{row_end} * frame.view.width;
  const float* k = frame.direct_per_irradiance;
  const float* irr = frame.irradiance;
  for (size_t i = b; i < e; ++i) radiance[i] += k[i] * irr[i];
}

// ---- Renderer ---------------------------------------------------------------

Renderer::Renderer(PreparedView view, ProjectorModel projector, int threads)
    : view_(std::move(view)), projector_(std::move(projector)), threads_(threads < 1 ? 1 : threads) {
  defocus_ = compute_defocus(view_, projector_, projector_.focus_mm);
  components_.push_back(std::make_unique<DirectComponent>());
  if (view_.tank) {
    components_.push_back(std::make_unique<TankComponent>(view_.tank, TankComponent::Part::scatter));
    components_.push_back(std::make_unique<TankComponent>(view_.tank, TankComponent::Part::source));
  }
  if (view_.medium) {
    components_.push_back(std::make_unique<MediumComponent>(view_.medium));
    if (!view_.medium->indirect_gain.empty())
      components_.push_back(std::make_unique<MediumIndirectComponent>(view_.medium));
  }
  direct_per_irradiance_.assign(view_.pixel_count(), 0.f);
  for (size_t i = 0; i < view_.pixel_count(); ++i)
    if (view_.irradiance_gain[i] > 0.f) direct_per_irradiance_[i] = view_.direct_gain[i] / view_.irradiance_gain[i];
}

void Renderer::set_focus_mm(double focus_mm) {
  if (!(focus_mm > 0) || !std::isfinite(focus_mm)) focus_mm = projector_.focus_mm;
  if (focus_mm == defocus_.focus_mm) return;
  defocus_ = compute_defocus(view_, projector_, focus_mm);
}

void Renderer::set_camera_lens(const CameraLens& lens) {
  lens_ = lens;
  cam_levels_ = 1;
  cam_level_.clear();
  cam_weight_.clear();
  if (!(lens.aperture_mm > 0) || !(lens.focus_mm > 0)) return;
  const size_t n = view_.pixel_count();
  cam_level_.assign(n, 0);
  cam_weight_.assign(n, 0.f);
  for (size_t i = 0; i < n; ++i) {
    const double sigma = lens.blur_sigma_px(view_.camera.intrinsics.fx, static_cast<double>(view_.depth_mm[i]));
    const auto [k, w] = blur_level(sigma);
    cam_level_[i] = k;
    cam_weight_[i] = w;
    cam_levels_ = std::max(cam_levels_, size_t{k} + (w > 0 ? 2u : 1u));
  }
}

void Renderer::blur_camera(float* radiance) const {
  const uint32_t W = view_.width, H = view_.height;
  const size_t n = view_.pixel_count();
  cam_stack_.resize(cam_levels_);
  cam_tmp_.resize(n);
  for (size_t k = 1; k < cam_levels_; ++k) {
    const std::vector<float> kernel = box_gaussian_kernel(static_cast<double>(kBlurLevelSigmaPx[k]));
    const auto r = static_cast<int64_t>(kernel.size() / 2);
    std::vector<float>& dst = cam_stack_[k];
    dst.resize(n);
    // Separable, clamped to the border (no darkening at the image edge).
    detail::parallel_rows(H, threads_, [&](uint32_t b, uint32_t e) {
      for (uint32_t y = b; y < e; ++y) {
        const float* in = radiance + size_t{y} * W;
        float* out = cam_tmp_.data() + size_t{y} * W;
        for (uint32_t x = 0; x < W; ++x) {
          float s = 0;
          for (int64_t j = -r; j <= r; ++j)
            s += kernel[static_cast<size_t>(j + r)] * in[std::clamp<int64_t>(int64_t{x} + j, 0, int64_t{W} - 1)];
          out[x] = s;
        }
      }
    });
    detail::parallel_rows(H, threads_, [&](uint32_t b, uint32_t e) {
      for (uint32_t y = b; y < e; ++y) {
        float* out = dst.data() + size_t{y} * W;
        std::fill(out, out + W, 0.f);
        for (int64_t j = -r; j <= r; ++j) {
          const float w = kernel[static_cast<size_t>(j + r)];
          const float* in = cam_tmp_.data() + static_cast<size_t>(std::clamp<int64_t>(int64_t{y} + j, 0, int64_t{H} - 1)) * W;
          for (uint32_t x = 0; x < W; ++x) out[x] += w * in[x];
        }
      }
    });
  }
  detail::parallel_rows(H, threads_, [&](uint32_t b, uint32_t e) {
    for (size_t i = size_t{b} * W; i < size_t{e} * W; ++i) {
      const size_t k = cam_level_[i];
      const float w = cam_weight_[i];
      const float a = k == 0 ? radiance[i] : cam_stack_[k][i];
      radiance[i] = w > 0.f ? a + w * (cam_stack_[k + 1][i] - a) : a;
    }
  });
}

void Renderer::add_component(std::unique_ptr<TransportComponent> component) {
  if (component) components_.push_back(std::move(component));
}

Status Renderer::render_radiance(PreparedPattern& pattern, float* radiance, bool include_ambient) const {
  return render_radiance_parts(pattern, radiance, include_ambient, Parts::all);
}

Status Renderer::render_component(PreparedPattern& pattern, float* radiance, const std::string& name) const {
  return render_selected(pattern, radiance, false, [&name](const TransportComponent& c) { return c.name() == name; });
}

Status Renderer::render_radiance_parts(PreparedPattern& pattern, float* radiance, bool include_ambient,
                                       Parts parts) const {
  if (parts == Parts::volume_only) include_ambient = false;
  return render_selected(pattern, radiance, include_ambient, [parts](const TransportComponent& c) {
    if (parts == Parts::volume_only) return c.is_volume();
    return parts == Parts::all || (parts == Parts::global_only) == c.is_global();
  });
}

Status Renderer::render_selected(PreparedPattern& pattern, float* radiance, bool include_ambient,
                                 const std::function<bool(const TransportComponent&)>& wanted) const {
  if (pattern.empty() || pattern.width() != view_.proj_width || pattern.height() != view_.proj_height)
    return Error(Code::invalid_argument,
                 "prepared pattern is " + std::to_string(pattern.width()) + "x" + std::to_string(pattern.height()) +
                     ", the projector is " + std::to_string(view_.proj_width) + "x" + std::to_string(view_.proj_height));
  if (radiance == nullptr) return Error(Code::invalid_argument, "render_radiance: null output buffer");
  size_t levels = defocus_.levels_needed;
  for (const auto& c : components_) levels = std::max(levels, c->levels_needed(defocus_.focus_mm));
  pattern.build_levels(levels, threads_);
  bool need_irr = false;
  for (const auto& c : components_) need_irr = need_irr || (wanted(*c) && c->needs_irradiance());
  FrameContext frame{view_, defocus_, pattern, nullptr};
  frame.projector_polarizer_deg = projector_polarizer_deg_;
  frame.analyser_deg = analyser_deg_;
  // Surface light: depolarized by reflection, so an ideal analyser passes half
  // of it; attenuated on the camera leg through a medium (Eq. 5.11).
  const float surface_scale = std::isfinite(analyser_deg_) ? 0.5f : 1.f;
  const float* cam_t = view_.camera_transmittance.empty() ? nullptr : view_.camera_transmittance.data();
  if (need_irr) {
    irradiance_.resize(view_.pixel_count());
    detail::parallel_rows(view_.height, threads_, [&](uint32_t b, uint32_t e) {
      std::fill(irradiance_.begin() + static_cast<ptrdiff_t>(size_t{b} * view_.width),
                irradiance_.begin() + static_cast<ptrdiff_t>(size_t{e} * view_.width), 0.f);
      add_sampled(frame, view_.irradiance_gain, b, e, irradiance_.data());
    });
    frame.irradiance = irradiance_.data();
    frame.direct_per_irradiance = direct_per_irradiance_.data();
  }
  for (const auto& c : components_)
    if (wanted(*c)) c->begin_frame(frame, threads_);
  detail::parallel_rows(view_.height, threads_, [&](uint32_t b, uint32_t e) {
    const size_t i0 = size_t{b} * view_.width, i1 = size_t{e} * view_.width;
    if (include_ambient) std::copy(view_.ambient.begin() + static_cast<ptrdiff_t>(i0),
                                   view_.ambient.begin() + static_cast<ptrdiff_t>(i1), radiance + i0);
    else std::fill(radiance + i0, radiance + i1, 0.f);
    for (const auto& c : components_)
      if (wanted(*c) && !c->is_volume()) c->apply(frame, b, e, radiance);
    if (cam_t != nullptr)
      for (size_t i = i0; i < i1; ++i) radiance[i] *= surface_scale * cam_t[i];
    else if (surface_scale != 1.f)
      for (size_t i = i0; i < i1; ++i) radiance[i] *= surface_scale;
    for (const auto& c : components_)
      if (wanted(*c) && c->is_volume()) c->apply(frame, b, e, radiance);
  });
  if (cam_levels_ > 1) blur_camera(radiance);
  return Status::Ok();
}

}  // namespace procam::sim
