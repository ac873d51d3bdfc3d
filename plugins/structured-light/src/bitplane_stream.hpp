// SPDX-License-Identifier: MIT
// BitPlaneStream: the one streaming bit-plane engine behind both binary-code
// decoders — BinaryRoundDecoder (Gray columns [+ rows], inverse or white
// mode) and MultiCodeDecoder (several column codes sharing white [+ black]).
// It owns the frame bookkeeping: format checks, waiting copies, fold order,
// and the per-pixel state of every code (binarize.hpp); decode.hpp reads it.
//
// Streaming: a plane is folded into its code's state as soon as both it and
// its reference are present — its inverse frame ("inverse" mode) or the white
// and (when projected) black frames ("white" mode, L̄ = W + B − L). Until then
// a copy of the frame is kept in its own pixel format (the host's memory is
// call-scoped); copies are recycled, so in plan order no frame after the
// first few allocates. Frames may arrive in any order.
//
// Inputs: one-channel U8, U16 (any bit_depth 1..16) or F32 frames, all of a
// round in the same format; full scale = 2^bit_depth − 1 (F32: 1.0), also the
// saturation level. U8 frames with bit_depth 8 take the integer kernels (no
// float conversion); others the float kernels.
//
// Weak ("tolerable") planes: planes flagged tolerable keep their own min
// margin (decode.hpp, max_weak_error_px), the others the strict min margin.
//
// Noise samples (decode.hpp, noise rule): in "inverse" mode every
// kNoiseRowStep-th row keeps, per pixel, the sum and the sum of squares of
// S_p = L_p + L̄_p over the folded pairs p. Under linear light transport S_p
// is the same for every pattern (P + P̄ = white), so its spread across the
// planes is noise only: Var(S_p) = sigma^2(L) + sigma^2(L̄) = Var(L - L̄) =
// sigma_d^2 — the variance of the margin, measured without knowing the bits.
// fit_noise() fits sigma_d^2 = a + b S to those samples.
//
// Errors: add_frame returns INVALID_ARGUMENT (index out of range), STATE
// (frame added twice) or BAD_FRAME (size, channels, format differing from
// earlier frames); nothing changes on error.
// Thread-safety: thread-bound (docs/threading.md) (one session); per-pixel loops run on its own
// WorkPool of `threads` threads.
#pragma once

#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <type_traits>
#include <vector>

#include "binarize.hpp"
#include "procam/sdk/map_cache.hpp"
#include "plan_layout.hpp"
#include "procam/plugin_sdk.hpp"
#include "procam/base/work_pool.hpp"

namespace procam::sl {

struct StreamFrame {
  FrameKind kind = FrameKind::white;
  uint32_t code = 0;     // plane / inverse: which code's state (accumulator)
  uint32_t plane = 0;    // 0 = most significant
  int32_t partner = -1;  // plane <-> inverse frame index
  std::string label;
};

struct StreamLayout {
  bool inverse = false;              // inverse frames projected
  int32_t white = 0;                 // frame index of white
  int32_t black = -1;                // frame index of black, -1 = none (B = 0)
  std::vector<uint32_t> bits;        // per code
  std::vector<std::vector<uint8_t>> tolerable;  // per code, per plane: weak plane (may be empty)
  std::vector<StreamFrame> frames;
};

// Uninitialised per-pixel array of a trivial type (pages are first touched by
// the kernel that writes them, not by a memset), 2 MiB aligned and advised
// for transparent huge pages: a 1920x1200 round allocates ~35 MB of state
// per scan, and 4 KiB page faults would cost more than the binarization.
// Released arrays of >= 1 MiB go to a process-wide cache (at most 96 MiB,
// reused by size by the next round or scan, in the daemon as in benchmarks),
// so steady-state scans do not pay the kernel's page zeroing for them.
// Thread-safe (the cache has a mutex).
struct FreeDeleter {
  void operator()(void* p) const noexcept;
};
template <class T>
using PixelArray = std::unique_ptr<T[], FreeDeleter>;
void* allocate_pixels(size_t bytes);  // throws std::bad_alloc
template <class T>
PixelArray<T> make_pixel_array(size_t n) {
  return PixelArray<T>(static_cast<T*>(allocate_pixels(n * sizeof(T))));
}
// Output maps: sdk::allocate_map and sdk::advise_huge_pages (procam/sdk/map_cache.hpp).
// (Pre-faulting with MADV_POPULATE_WRITE was tried: 2500 -> 130 page faults
// per ensemble scan, but no faster here and slower where malloc reuses
// already-mapped heap memory, as for the Gray round's maps.)

// Several map allocations spread over a pool's threads (the first touch
// of ~35 MB of fresh output maps is a memset the threads can share).
class MapBatch {
 public:
  // F32 and U8 maps come from the map cache when it has storage of that
  // size (stale contents: the decoders write every element; map_cache.hpp).
  template <class T>
  void add(std::vector<T>& v, size_t n) {
    if (v.size() == n) return;
    if constexpr (std::is_same_v<T, float> || std::is_same_v<T, uint8_t>)
      jobs_.push_back([&v, n] { sdk::take_map(v, n); });
    else
      jobs_.push_back([&v, n] { sdk::allocate_map(v, n); });
  }
  void run(WorkPool& pool) {
    pool.run(static_cast<uint32_t>(jobs_.size()), [&](uint32_t a, uint32_t b) {
      for (uint32_t i = a; i < b; ++i) jobs_[i]();
    });
    jobs_.clear();
  }

 private:
  std::vector<std::function<void()>> jobs_;
};

// Per-pixel state of one code: the word (bit position bits-1-p set where
// plane p has L > L̄) — 8-bit input: low and high byte arrays wbyte[0/1]
// (wbyte[1] only for codes of more than 8 bits), float input: `word` — and
// margins: m8 (8-bit input) or mf + flags (float input).
// Margin [0] = strict planes, [1] = tolerable planes (allocated only when the
// code has some). (Bit planes of 1 bit per pixel were tried: the folds got
// 25% faster, but re-assembling words per pixel after the last frame cost
// more than that, so words stay.)
struct CodeState {
  uint32_t bits = 0;
  std::vector<uint8_t> tolerable;   // per plane
  std::vector<uint8_t> plane_done;  // per plane
  bool has_weak = false;
  PixelArray<uint16_t> word;        // float input
  PixelArray<uint8_t> wbyte[2];     // 8-bit input: word bits 0-7, 8-15
  PixelArray<uint8_t> m8[2];
  PixelArray<float> mf[2];
  PixelArray<uint8_t> flags;
  uint32_t folded[2] = {0, 0};      // planes folded into margin [0] / [1]
  uint32_t bytes_folded[2] = {0, 0};  // planes folded into wbyte[0] / [1] (or word)
  // Uncertain-plane tracking over the strict planes (binarize.hpp track_u8 /
  // track_f; only with BitPlaneStream::track_single_planes): the kTracked
  // smallest margins in ascending order with their planes (0 = most
  // significant), and the next smallest margin t8/tf[kTracked].
  static constexpr int kTracked = kTrackedPlanes;
  PixelArray<uint8_t> t8[kTracked + 1], t_plane[kTracked];  // 8-bit margins
  PixelArray<float> tf[kTracked + 1];                        // float margins
  bool tracked = false;
};

// sigma_d^2 = a + b * S (input units^2, S = W + B ~ L + L̄), fitted per
// capture (BitPlaneStream::fit_noise); measured false when no pairs were
// folded ("white" mode, or fewer than 3 pairs).
struct NoiseFit {
  bool measured = false;
  double a = 0, b = 0;
  size_t pixels = 0;   // sample pixels used
  uint32_t pairs = 0;  // pattern/inverse pairs per pixel
};

// Fit of sigma_d^2 = a + b S from per-pixel sample variances (n pairs each,
// unbiased, n >= 3) at mean sums S: the variances are binned by S (64 bins
// over [0, 2 full scale]); a bin's value is its median divided by the median
// of chi^2_nu / nu (Wilson-Hilferty (1 - 2 / (9 nu))^3, nu = n - 1), robust to
// the few pixels where transport is not linear (clipping, motion); a and b
// come from count-weighted least squares over bins of >= 20 pixels, clamped
// to a, b >= 0. Exposed for tests.
NoiseFit fit_noise_samples(const std::vector<double>& mean_sum, const std::vector<double>& variance,
                           uint32_t pairs, double full_scale);

class BitPlaneStream {
 public:
  static constexpr uint32_t kNoiseRowStep = 8;
  BitPlaneStream(StreamLayout layout, uint32_t width, uint32_t height, uint32_t threads);

  sdk::Error add_frame(uint32_t index, const procam_image& frame);
  bool complete() const { return added_count_ == layout_.frames.size(); }
  // Throws std::logic_error("<who>: ...") unless complete and every plane folded.
  void require_complete(const char* who) const;

  // Where to write the intensity map (white / full scale clipped to [0, 1],
  // 0 if not finite; width * height floats) as soon as the white frame
  // arrives, off the work after the last frame. intensity_written() is the
  // pointer it was written to (null before the white frame).
  void set_intensity_output(float* out) {
    intensity_out_ = out;
    intensity_written_ = nullptr;
  }
  const float* intensity_written() const { return intensity_written_; }
  // The map finish still has to write: null when the white frame already did.
  float* intensity_to_write(std::vector<float>& map) const {
    return intensity_written_ == map.data() ? nullptr : map.data();
  }

  const StreamLayout& layout() const { return layout_; }
  uint32_t width() const { return width_; }
  uint32_t height() const { return height_; }
  WorkPool& pool() { return *pool_; }
  bool u8() const { return u8_; }  // 8-bit integer state (m8, white8/black8)
  float full_scale() const { return full_scale_; }
  const CodeState& code(size_t c) const { return codes_[c]; }
  size_t code_count() const { return codes_.size(); }
  // References: 8-bit (u8()) or float; black null when not projected (B = 0).
  const uint8_t* white8() const { return white8_.get(); }
  const uint8_t* black8() const { return layout_.black >= 0 ? black8_.get() : nullptr; }
  const float* white_f() const { return white_f_.get(); }
  const float* black_f() const { return layout_.black >= 0 ? black_f_.get() : nullptr; }
  // Track, per pixel and code, the CodeState::kTracked smallest strict
  // margins, their planes and the next margin (CodeState::t8 / tf /
  // t_plane); call before the first frame.
  void track_single_planes(bool on) { track_ = on; }
  // The noise model of this capture (see above); call when complete.
  NoiseFit fit_noise() const;
  // Keep the raw samples of code `code`'s pattern/inverse pairs ("inverse"
  // mode only) until the stream is destroyed: the stripe-averaged rule
  // (stripe_average.hpp) needs every plane's margin d = L - L̄ and pair sum
  // S = L + L̄ at any pixel, and whether it runs is known only after the last
  // frame. Call before the first frame; -1 = keep none. Cost: the two rows
  // of each pair are copied while they are folded (already in cache), in
  // their own format: 2 x bits x width x height x bytes per sample (8-bit
  // 1280x1024, 10 column planes: 26 MB; 16-bit: 52 MB).
  void keep_pairs(int32_t code) { keep_code_ = code; }
  // True when code `code`'s pairs were kept (keep_pairs, "inverse" mode).
  bool pairs_kept(size_t code) const {
    return kept_ != nullptr && static_cast<int64_t>(code) == keep_code_;
  }
  // Kept sample of plane p (0 = most significant) of the kept code at pixel
  // i: the pattern (inverse false) or its inverse, in input units (the
  // frame's value as a float, as the float kernels read it).
  float kept(uint32_t plane, bool inverse, size_t i) const {
    const size_t n = size_t{width_} * height_;
    const size_t at = (size_t{plane} * 2 + (inverse ? 1 : 0)) * n + i;
    switch (kept_bytes_) {
      case 1: return static_cast<float>(kept_[at]);
      case 2: return static_cast<float>(reinterpret_cast<const uint16_t*>(kept_.get())[at]);
      default: return reinterpret_cast<const float*>(kept_.get())[at];
    }
  }

 private:
  struct Copy {  // a waiting frame, copied in its own format
    PixelArray<uint8_t> bytes;
    procam_image view{};
  };
  sdk::Error check(uint32_t index, const procam_image& frame) const;
  void set_format(const procam_image& frame);
  void keep(uint32_t index, const procam_image& frame);
  void release(uint32_t index);
  void store_reference(const procam_image& frame, PixelArray<uint8_t>& r8, PixelArray<float>& rf);
  void fold(const StreamFrame& role, const procam_image& plane, const procam_image* inverse);
  void fold_waiting_planes();
  void sample_noise(const procam_image& plane, const procam_image& inverse, uint32_t y);
  bool have_reference() const;

  StreamLayout layout_;
  uint32_t width_, height_;
  std::unique_ptr<WorkPool> pool_;
  std::vector<CodeState> codes_;
  PixelArray<uint8_t> white8_, black8_;
  PixelArray<float> white_f_, black_f_;
  std::vector<Copy> waiting_;                 // per frame: copy while it waits
  std::vector<PixelArray<uint8_t>> spare_;    // released copies, reused
  std::vector<uint8_t> added_;
  size_t added_count_ = 0;
  bool have_format_ = false, u8_ = false;
  uint32_t pixel_type_ = 0, bit_depth_ = 0;
  float full_scale_ = 0;
  size_t noise_n_ = 0;                          // sampled pixels (rows y % kNoiseRowStep == 0)
  PixelArray<double> noise_sum_, noise_sq_;     // per sampled pixel (row y / kNoiseRowStep)
  PixelArray<uint8_t> noise_bad_;               // 1: some value clipped, <= 0 or non-finite
  uint32_t noise_pairs_ = 0;
  bool track_ = false;
  int32_t keep_code_ = -1;                      // keep_pairs
  PixelArray<uint8_t> kept_;                    // [plane][pattern, inverse][pixel], raw samples
  size_t kept_bytes_ = 0;                       // bytes per kept sample
  float* intensity_out_ = nullptr;
  const float* intensity_written_ = nullptr;
};

}  // namespace procam::sl
