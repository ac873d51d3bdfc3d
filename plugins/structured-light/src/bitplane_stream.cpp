// SPDX-License-Identifier: MIT
// Streaming bit-plane engine (thesis §3.2, Eq. 3.5; see bitplane_stream.hpp).
#include "bitplane_stream.hpp"

#include <sys/mman.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <mutex>
#include <unordered_map>
#include <new>
#include <limits>
#include <stdexcept>
#include <utility>
#if defined(__SSE2__)
#include <emmintrin.h>
#endif

namespace procam::sl {

namespace {
constexpr size_t kHugePage = size_t{2} << 20;
constexpr uint32_t kCopyAheadRows = 3;  // keep(): rows prefetched ahead of the copy
}

// Process-wide cache of released state buffers: a scan's decoder state
// (~35 MB at 1920x1200, ~10 MB at 1280x800 in 1 MB buffers) would otherwise
// be fresh memory every round, which the kernel faults in and zeroes page by
// page (at 1280x800 that was half of a Gray decode). Buffers of at least
// kCacheMinBytes are reused by exact rounded size (2 MiB, huge pages advised,
// from kHugePage / 2 up; 4 KiB pages below); at most kCacheBytes stay cached
// while no decoder holds them.
namespace {
constexpr size_t kCacheBytes = size_t{96} << 20;
constexpr size_t kCacheMinBytes = size_t{64} << 10;
constexpr size_t kPage = 4096;
struct BufferCache {
  std::mutex mutex;
  std::vector<std::pair<size_t, void*>> free;  // (rounded bytes, pointer)
  size_t cached = 0;
  std::unordered_map<void*, size_t> sizes;     // live huge buffers: pointer -> rounded bytes
};
BufferCache& cache() {
  static BufferCache* c = new BufferCache;  // never destroyed: buffers may be freed at exit
  return *c;
}
}  // namespace

void FreeDeleter::operator()(void* p) const noexcept {
  if (p == nullptr) return;
  BufferCache& c = cache();
  std::lock_guard<std::mutex> lock(c.mutex);
  const auto it = c.sizes.find(p);
  if (it == c.sizes.end()) {
    std::free(p);
    return;
  }
  const size_t bytes = it->second;
  if (c.cached + bytes <= kCacheBytes) {
    c.free.emplace_back(bytes, p);
    c.cached += bytes;
    return;
  }
  c.sizes.erase(it);
  std::free(p);
}

void* allocate_pixels(size_t bytes) {
  if (bytes >= kCacheMinBytes) {
    const bool huge = bytes >= kHugePage / 2;
    const size_t unit = huge ? kHugePage : kPage;
    const size_t rounded = (bytes + unit - 1) / unit * unit;
    BufferCache& c = cache();
    {
      std::lock_guard<std::mutex> lock(c.mutex);
      for (size_t i = 0; i < c.free.size(); ++i)
        if (c.free[i].first == rounded) {
          void* p = c.free[i].second;
          c.free[i] = c.free.back();
          c.free.pop_back();
          c.cached -= rounded;
          return p;
        }
    }
    void* p = std::aligned_alloc(unit, rounded);
    if (p == nullptr) throw std::bad_alloc();
    if (huge) sdk::advise_huge_pages(p, rounded);
    std::lock_guard<std::mutex> lock(c.mutex);
    c.sizes.emplace(p, rounded);
    return p;
  }
  void* p = std::malloc(bytes > 0 ? bytes : 1);
  if (p == nullptr) throw std::bad_alloc();
  return p;
}


BitPlaneStream::BitPlaneStream(StreamLayout layout, uint32_t width, uint32_t height,
                               uint32_t threads)
    : layout_(std::move(layout)),
      width_(width),
      height_(height),
      pool_(std::make_unique<WorkPool>(std::max(1u, threads))) {
  codes_.resize(layout_.bits.size());
  for (size_t c = 0; c < codes_.size(); ++c) {
    CodeState& s = codes_[c];
    s.bits = layout_.bits[c];
    s.tolerable.assign(s.bits, 0);
    if (c < layout_.tolerable.size())
      for (uint32_t p = 0; p < s.bits && p < layout_.tolerable[c].size(); ++p)
        s.tolerable[p] = layout_.tolerable[c][p] != 0 ? 1 : 0;
    s.has_weak = std::any_of(s.tolerable.begin(), s.tolerable.end(), [](uint8_t t) { return t; });
    s.plane_done.assign(s.bits, 0);
  }
  waiting_.resize(layout_.frames.size());
  added_.assign(layout_.frames.size(), 0);
}

sdk::Error BitPlaneStream::check(uint32_t index, const procam_image& frame) const {
  if (index >= layout_.frames.size())
    return sdk::invalid_argument("frame index " + std::to_string(index) + " is out of range (" +
                                 std::to_string(layout_.frames.size()) + " frames)");
  const std::string what = "frame " + std::to_string(index) + " (" + layout_.frames[index].label + ")";
  if (added_[index]) return sdk::state_error(what + " was already added");
  if (sdk::Error e = sdk::check_frame(&frame, width_, height_, 1, what); !e.ok()) return e;
  if (have_format_ && (frame.pixel_type != pixel_type_ ||
                       (pixel_type_ != PROCAM_PIXEL_F32 && frame.bit_depth != bit_depth_))) {
    const procam_image first{.width = width_, .height = height_, .channels = 1,
                             .pixel_type = pixel_type_, .bit_depth = bit_depth_, .reserved = 0,
                             .stride_bytes = 0, .data = nullptr};
    return sdk::bad_frame(what + " is " + sdk::describe_image(frame) +
                          " but earlier frames of this round are " + sdk::describe_image(first) +
                          "; all frames of a round must share one format");
  }
  return sdk::ok();
}

// The first frame fixes the format and with it the state's representation.
void BitPlaneStream::set_format(const procam_image& frame) {
  pixel_type_ = frame.pixel_type;
  bit_depth_ = frame.bit_depth;
  full_scale_ = static_cast<float>(sdk::full_scale(frame));
  u8_ = frame.pixel_type == PROCAM_PIXEL_U8 && frame.bit_depth == 8;
  have_format_ = true;
  const size_t n = size_t{width_} * height_;
  if (layout_.inverse) {
    const size_t sn = size_t{width_} * ((height_ + kNoiseRowStep - 1) / kNoiseRowStep);
    noise_n_ = sn;
    noise_sum_ = make_pixel_array<double>(sn);  // cached buffers: zeroing only
    noise_sq_ = make_pixel_array<double>(sn);
    noise_bad_ = make_pixel_array<uint8_t>(sn);
    std::fill_n(noise_sum_.get(), sn, 0.0);
    std::fill_n(noise_sq_.get(), sn, 0.0);
    std::fill_n(noise_bad_.get(), sn, uint8_t{0});
  }
  if (layout_.inverse && keep_code_ >= 0 && static_cast<size_t>(keep_code_) < codes_.size()) {
    kept_bytes_ = sdk::bytes_per_sample(frame.pixel_type);
    // Every byte is written by the fold of its plane (all planes are folded
    // before the kept samples are read: require_complete).
    kept_ = make_pixel_array<uint8_t>(2 * size_t{codes_[static_cast<size_t>(keep_code_)].bits} * n * kept_bytes_);
  }
  for (CodeState& s : codes_) {
    const int margins = s.has_weak ? 2 : 1;
    s.tracked = track_;
    if (track_) {
      for (auto& p : s.t_plane) p = make_pixel_array<uint8_t>(n);
      for (int k = 0; k <= CodeState::kTracked; ++k) {
        if (u8_)
          s.t8[k] = make_pixel_array<uint8_t>(n);
        else
          s.tf[k] = make_pixel_array<float>(n);
      }
    }
    if (u8_) {  // written (not OR-ed / min-ed) by the first plane: no initialisation
      s.wbyte[0] = make_pixel_array<uint8_t>(n);
      if (s.bits > 8) s.wbyte[1] = make_pixel_array<uint8_t>(n);
      for (int k = 0; k < margins; ++k) s.m8[k] = make_pixel_array<uint8_t>(n);
    } else {
      s.word = make_pixel_array<uint16_t>(n);
      std::fill_n(s.word.get(), n, uint16_t{0});
      s.flags = make_pixel_array<uint8_t>(n);
      std::fill_n(s.flags.get(), n, uint8_t{0});
      for (int k = 0; k < margins; ++k) {
        s.mf[k] = make_pixel_array<float>(n);
        std::fill_n(s.mf[k].get(), n, std::numeric_limits<float>::infinity());
      }
    }
  }
}

void BitPlaneStream::keep(uint32_t index, const procam_image& frame) {
  Copy& c = waiting_[index];
  const size_t row_bytes = size_t{width_} * sdk::bytes_per_sample(frame.pixel_type);
  if (!spare_.empty()) {
    c.bytes = std::move(spare_.back());
    spare_.pop_back();
  } else {
    c.bytes = make_pixel_array<uint8_t>(row_bytes * height_);
  }
  uint8_t* dst = c.bytes.get();
  pool_->run(height_, [&](uint32_t y0, uint32_t y1) {
    for (uint32_t y = y0; y < y1; ++y) {
      // The frame comes from DRAM: prefetch a few rows ahead (a hint).
      if (y + kCopyAheadRows < y1) {
        const uint8_t* ahead = sdk::row_bytes(frame, y + kCopyAheadRows);
        for (size_t x = 0; x < row_bytes; x += 64) __builtin_prefetch(ahead + x);
      }
      std::memcpy(dst + y * row_bytes, sdk::row_bytes(frame, y), row_bytes);
    }
  });
  c.view = frame;
  c.view.data = dst;
  c.view.stride_bytes = row_bytes;
}

void BitPlaneStream::release(uint32_t index) {
  Copy& c = waiting_[index];
  if (c.bytes) spare_.push_back(std::move(c.bytes));
  c = Copy{};
}

void BitPlaneStream::store_reference(const procam_image& frame, PixelArray<uint8_t>& r8,
                                     PixelArray<float>& rf) {
  const size_t w = width_;
  const bool white = &r8 == &white8_;
  float* intensity = white ? intensity_out_ : nullptr;
  const float inv_scale = 1.0f / full_scale_;
  if (u8_) {
    r8 = make_pixel_array<uint8_t>(w * height_);
    uint8_t* dst = r8.get();
    pool_->run(height_, [&](uint32_t y0, uint32_t y1) {
      for (uint32_t y = y0; y < y1; ++y) {
        const uint8_t* src = sdk::row_bytes(frame, y);
        std::memcpy(dst + y * w, src, w);
        if (intensity != nullptr) intensity_u8(src, w, inv_scale, intensity + y * w);
      }
    });
  } else {
    rf = make_pixel_array<float>(w * height_);
    float* dst = rf.get();
    pool_->run(height_, [&](uint32_t y0, uint32_t y1) {
      for (uint32_t y = y0; y < y1; ++y) {
        sdk::read_row(frame, y, dst + y * w);
        if (intensity != nullptr)
          for (size_t x = 0; x < w; ++x) {
            const float v = dst[y * w + x] * inv_scale;
            intensity[y * w + x] = std::isfinite(v) ? std::clamp(v, 0.0f, 1.0f) : 0.0f;
          }
      }
    });
  }
  if (intensity != nullptr) intensity_written_ = intensity;
}

bool BitPlaneStream::have_reference() const {
  return added_[static_cast<size_t>(layout_.white)] != 0 &&
         (layout_.black < 0 || added_[static_cast<size_t>(layout_.black)] != 0);
}

namespace {

// keep_pairs' copy: the kept rows are read only after the last frame, so they
// are written with non-temporal stores (no read-for-ownership of the
// destination, no eviction of the fold's working set). Caller: sfence_kept()
// before another thread may read them (the pool's join follows it).
void copy_kept(uint8_t* dst, const uint8_t* src, size_t n) {
#if defined(__SSE2__)
  const size_t head = std::min(n, (16 - reinterpret_cast<uintptr_t>(dst) % 16) % 16);
  std::memcpy(dst, src, head);
  size_t i = head;
  for (; i + 64 <= n; i += 64) {
    const __m128i a = _mm_loadu_si128(reinterpret_cast<const __m128i*>(src + i));
    const __m128i b = _mm_loadu_si128(reinterpret_cast<const __m128i*>(src + i + 16));
    const __m128i c = _mm_loadu_si128(reinterpret_cast<const __m128i*>(src + i + 32));
    const __m128i d = _mm_loadu_si128(reinterpret_cast<const __m128i*>(src + i + 48));
    _mm_stream_si128(reinterpret_cast<__m128i*>(dst + i), a);
    _mm_stream_si128(reinterpret_cast<__m128i*>(dst + i + 16), b);
    _mm_stream_si128(reinterpret_cast<__m128i*>(dst + i + 32), c);
    _mm_stream_si128(reinterpret_cast<__m128i*>(dst + i + 48), d);
  }
  std::memcpy(dst + i, src + i, n - i);
#else
  std::memcpy(dst, src, n);
#endif
}

void sfence_kept() {
#if defined(__SSE2__)
  _mm_sfence();
#endif
}

}  // namespace

void BitPlaneStream::fold(const StreamFrame& role, const procam_image& plane,
                          const procam_image* inverse) {
  CodeState& s = codes_[role.code];
  const uint32_t position = s.bits - 1 - role.plane;
  const int which = s.tolerable[role.plane] != 0 ? 1 : 0;
  const bool first = s.folded[which] == 0;
  const uint32_t byte = u8_ ? position / 8 : 0;
  const bool first_word = s.bytes_folded[byte] == 0;
  const size_t w = width_;
  const bool track = s.tracked && which == 0;  // strict planes only
  const auto plane_index = static_cast<uint8_t>(role.plane);
  // keep_pairs: the pair's rows copied as they are folded (in cache then).
  uint8_t* kept_plane = nullptr;
  size_t kept_row = 0, kept_stride = 0;
  if (inverse != nullptr && pairs_kept(role.code)) {
    kept_row = w * kept_bytes_;
    kept_stride = size_t{height_} * kept_row;
    kept_plane = kept_.get() + size_t{role.plane} * 2 * kept_stride;
  }
  auto keep_rows = [&](uint32_t y) {
    if (kept_plane == nullptr) return;
    copy_kept(kept_plane + y * kept_row, static_cast<const uint8_t*>(sdk::row_bytes(plane, y)), kept_row);
    copy_kept(kept_plane + kept_stride + y * kept_row,
              static_cast<const uint8_t*>(sdk::row_bytes(*inverse, y)), kept_row);
  };
  if (u8_) {
    uint8_t* word = s.wbyte[byte].get();
    const uint32_t bit = position % 8;
    uint8_t* margin = s.m8[which].get();
    const uint8_t* white = white8_.get();
    const uint8_t* black = black8();
    pool_->run(height_, [&](uint32_t y0, uint32_t y1) {
      for (uint32_t y = y0; y < y1; ++y) {
        const size_t off = size_t{y} * w;
        if (inverse != nullptr) {
          fold_u8_inverse(sdk::row_bytes(plane, y), sdk::row_bytes(*inverse, y), w, bit, first,
                          first_word, word + off, margin + off);
          if (y % kNoiseRowStep == 0) sample_noise(plane, *inverse, y);
        } else {  // binarize "white": footnote 2, generalised (binarize.hpp)
          fold_u8_synthetic(sdk::row_bytes(plane, y), white + off,
                            black != nullptr ? black + off : nullptr, w, bit, first,
                            first_word, word + off, margin + off);
        }
        if (track)
          track_u8(sdk::row_bytes(plane, y), inverse != nullptr ? sdk::row_bytes(*inverse, y) : white + off,
                   inverse != nullptr || black == nullptr ? nullptr : black + off, inverse == nullptr, w,
                   plane_index, first, TrackRow<uint8_t>::at(s.t8, s.t_plane, off));
        keep_rows(y);
      }
      if (kept_plane != nullptr) sfence_kept();
    });
  } else {
    uint16_t* word = s.word.get();
    float* margin = s.mf[which].get();
    uint8_t* flags = s.flags.get();
    const float* white = white_f_.get();
    const float* black = black_f();
    pool_->run(height_, [&](uint32_t y0, uint32_t y1) {
      std::vector<float> row_l(w), row_lb(w);
      for (uint32_t y = y0; y < y1; ++y) {
        const size_t off = size_t{y} * w;
        sdk::read_row(plane, y, row_l.data());
        if (inverse != nullptr) {
          sdk::read_row(*inverse, y, row_lb.data());
          if (y % kNoiseRowStep == 0) sample_noise(plane, *inverse, y);
        } else
          synthesize_inverse(row_l.data(), white + off, black != nullptr ? black + off : nullptr,
                             w, row_lb.data());
        fold_plane(row_l.data(), row_lb.data(), w, position, full_scale_, word + off,
                   margin + off, flags + off);
        if (track)
          track_f(row_l.data(), row_lb.data(), w, plane_index, first, TrackRow<float>::at(s.tf, s.t_plane, off));
        keep_rows(y);
      }
      if (kept_plane != nullptr) sfence_kept();
    });
  }
  if (inverse != nullptr) ++noise_pairs_;
  ++s.folded[which];
  ++s.bytes_folded[byte];
  s.plane_done[role.plane] = 1;
}

// Row y (a multiple of kNoiseRowStep) of a pattern/inverse pair into the
// noise sums; each sampled row belongs to one band, so no two threads write
// the same sample.
void BitPlaneStream::sample_noise(const procam_image& plane, const procam_image& inverse,
                                  uint32_t y) {
  const size_t w = width_, off = size_t{y / kNoiseRowStep} * w;
  double* sum = noise_sum_.get() + off;
  double* sq = noise_sq_.get() + off;
  uint8_t* bad = noise_bad_.get() + off;
  const float fs = full_scale_;
  auto add = [&](size_t x, float l, float lb) {
    const double s = double{l} + double{lb};
    sum[x] += s;
    sq[x] += s * s;
    const bool ok = std::isfinite(s) && l > 0.0f && lb > 0.0f && l < fs && lb < fs;
    bad[x] = static_cast<uint8_t>(bad[x] | (ok ? 0 : 1));
  };
  if (u8_) {
    const uint8_t* l = sdk::row_bytes(plane, y);
    const uint8_t* lb = sdk::row_bytes(inverse, y);
    for (size_t x = 0; x < w; ++x) add(x, static_cast<float>(l[x]), static_cast<float>(lb[x]));
    return;
  }
  std::vector<float> l(w), lb(w);
  sdk::read_row(plane, y, l.data());
  sdk::read_row(inverse, y, lb.data());
  for (size_t x = 0; x < w; ++x) add(x, l[x], lb[x]);
}

namespace {
// fit_noise_samples (bitplane_stream.hpp) over `count` samples read through
// `sample(i, s, var)` (false: skip sample i). Two passes (count per bin, then
// scatter into one buffer), so a fit allocates one array, not a growing
// vector per bin: it runs once per scan on ~130 k samples and must not cost
// more page faults than the decode it serves.
template <class Sample>
NoiseFit fit_binned(size_t count, const Sample& sample, uint32_t pairs, double full_scale) {
  NoiseFit f;
  f.pairs = pairs;
  if (pairs < 3 || count == 0 || !(full_scale > 0)) return f;
  constexpr size_t kBins = 64, kMinBin = 20;
  const double nu = pairs - 1.0;
  const double median_factor = std::pow(1.0 - 2.0 / (9.0 * nu), 3.0);  // median(chi2_nu) / nu
  auto bin_of = [&](double s) {
    return std::min(kBins - 1, static_cast<size_t>(s / (2.0 * full_scale) * kBins));
  };
  auto usable = [](double s, double v) { return std::isfinite(s) && std::isfinite(v) && s >= 0; };
  std::array<size_t, kBins + 1> start{};
  std::array<double, kBins> bin_s{};
  double s = 0, v = 0;
  for (size_t i = 0; i < count; ++i)
    if (sample(i, s, v) && usable(s, v)) {
      const size_t b = bin_of(s);
      ++start[b + 1];
      bin_s[b] += s;
    }
  for (size_t b = 0; b < kBins; ++b) start[b + 1] += start[b];
  std::vector<double> sorted(start[kBins]);
  std::array<size_t, kBins> fill{};
  for (size_t i = 0; i < count; ++i)
    if (sample(i, s, v) && usable(s, v)) {
      const size_t b = bin_of(s);
      sorted[start[b] + fill[b]++] = v;
    }
  double sw = 0, ss = 0, sy = 0, sss = 0, ssy = 0;
  size_t used_bins = 0;
  for (size_t b = 0; b < kBins; ++b) {
    const size_t n = start[b + 1] - start[b];
    if (n < kMinBin) continue;
    auto first = sorted.begin() + static_cast<std::ptrdiff_t>(start[b]);
    auto mid = first + static_cast<std::ptrdiff_t>(n / 2);
    std::nth_element(first, mid, first + static_cast<std::ptrdiff_t>(n));
    const double y = *mid / median_factor;
    const double sb = bin_s[b] / static_cast<double>(n);
    const auto w = static_cast<double>(n);
    sw += w, ss += w * sb, sy += w * y, sss += w * sb * sb, ssy += w * sb * y;
    f.pixels += n;
    ++used_bins;
  }
  if (used_bins == 0) return f;
  f.measured = true;
  const double det = sw * sss - ss * ss;
  if (used_bins >= 2 && det > 0) {
    f.b = (sw * ssy - ss * sy) / det;
    f.a = (sy - f.b * ss) / sw;
  } else {
    f.a = sy / sw;
  }
  if (f.b < 0) {  // no shot-noise term in the data: constant variance
    f.b = 0;
    f.a = sy / sw;
  }
  if (f.a < 0) {  // shot noise only: through the origin
    f.a = 0;
    f.b = sss > 0 ? ssy / sss : 0;
  }
  return f;
}
}  // namespace

NoiseFit BitPlaneStream::fit_noise() const {
  if (noise_pairs_ < 3) return NoiseFit{};
  const double n = noise_pairs_;
  return fit_binned(
      noise_n_,
      [&](size_t i, double& mean, double& var) {
        if (noise_bad_[i] != 0) return false;
        mean = noise_sum_[i] / n;
        var = std::max(0.0, (noise_sq_[i] - n * mean * mean) / (n - 1.0));
        return true;
      },
      noise_pairs_, full_scale_);
}

NoiseFit fit_noise_samples(const std::vector<double>& mean_sum, const std::vector<double>& variance,
                           uint32_t pairs, double full_scale) {
  return fit_binned(
      std::min(mean_sum.size(), variance.size()),
      [&](size_t i, double& mean, double& var) {
        mean = mean_sum[i];
        var = variance[i];
        return true;
      },
      pairs, full_scale);
}

void BitPlaneStream::fold_waiting_planes() {
  for (size_t i = 0; i < layout_.frames.size(); ++i) {
    const StreamFrame& role = layout_.frames[i];
    if (role.kind != FrameKind::plane || waiting_[i].view.data == nullptr) continue;
    fold(role, waiting_[i].view, nullptr);
    release(static_cast<uint32_t>(i));
  }
}

sdk::Error BitPlaneStream::add_frame(uint32_t index, const procam_image& frame) {
  if (sdk::Error e = check(index, frame); !e.ok()) return e;
  if (!have_format_) set_format(frame);
  const StreamFrame& role = layout_.frames[index];
  switch (role.kind) {
    case FrameKind::white: store_reference(frame, white8_, white_f_); break;
    case FrameKind::black: store_reference(frame, black8_, black_f_); break;
    case FrameKind::plane:
    case FrameKind::inverse:
      if (layout_.inverse) {
        const auto partner = static_cast<uint32_t>(role.partner);
        if (added_[partner]) {
          const procam_image& other = waiting_[partner].view;
          if (role.kind == FrameKind::plane)
            fold(role, frame, &other);
          else
            fold(layout_.frames[partner], other, &frame);
          release(partner);
        } else {
          keep(index, frame);
        }
      } else if (have_reference()) {
        fold(role, frame, nullptr);
      } else {
        keep(index, frame);
      }
      break;
  }
  added_[index] = 1;
  ++added_count_;
  if (!layout_.inverse && (role.kind == FrameKind::white || role.kind == FrameKind::black) &&
      have_reference())
    fold_waiting_planes();
  return sdk::ok();
}

void BitPlaneStream::require_complete(const char* who) const {
  if (!complete()) throw std::logic_error(std::string(who) + ": finish before all frames added");
  for (const CodeState& s : codes_)
    for (uint8_t done : s.plane_done)
      if (!done) throw std::logic_error(std::string(who) + ": a plane was never folded");
}

}  // namespace procam::sl
