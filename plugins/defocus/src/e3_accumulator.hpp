// SPDX-License-Identifier: MIT
// Streaming E(3, f): the magnitude of the 3rd DFT coefficient of each camera
// pixel's temporal profile under a period-24 pattern shifted one projector
// pixel per frame, one profile per focus setting f (thesis §2.2, Eq. 2.5–2.7).
//
// Model. At focus setting f the pixel sees e_t = the pattern shifted by t
// (t = 0..23) blurred by defocus and global light (Eq. 2.4). Its DFT at
// w = 3 is E(3, f) = Σ_t e_t exp(-2πi·3t/24) = Σ_t e_t ω^t with ω = e^{-iπ/4}.
// ω has period 8 and ω^{t+4} = -ω^t, so with D_b = Σ_{t ≡ b (mod 4)} s_t e_t,
// s_t = +1 for t mod 8 < 4 and -1 otherwise (b = 0..3),
//   E = D_0 + ω D_1 + ω² D_2 + ω³ D_3
//     re = D_0 + (D_1 - D_3)/√2,   im = -D_2 - (D_1 + D_3)/√2.
// Each frame adds or subtracts its pixels into exactly one bucket D_b: one
// integer add per pixel per frame (int16 for 8-bit frames, int32 for 9-16
// bit, float for F32). When the 24th frame of a focus setting arrives, its
// buckets are folded into E3(f) = 2|E|/24 (the amplitude of the profile's 3rd
// harmonic, in DN) and recycled. The profile's mean (DC / 24, DN) is summed
// over the frames of focus setting 0 only: blur and global light both conserve
// the mean, so one setting gives it.
//
// State: F float maps (E3 per setting) + a mean map + a flag map + 4 buckets
// per focus setting in progress (one set when frames arrive in plan order):
// O(pixels × F), never O(pixels × frames).
//
// Saturation, one bit per pixel (so the per-frame check costs no memory
// traffic): set when some frame
// reached the camera's full scale - 2^bits - 1, or 1.0 for F32 frames - or
// an F32 value was not finite).
//
// Deferred last fold (the multi-focal hot path, issue 12): with
// defer_final_fold(true) and 8-bit frames, the setting whose 24th frame
// completes the sweep (other than setting 0, whose fold also makes the mean)
// is not folded into its E3 map: its buckets stay, pending_buckets() shows
// them, and fbar_depth_map folds them per pixel inside its own pass (the
// same float operations as fold(), e3_from_buckets below), which saves one
// write and one read of a float map after the last frame. Until
// fold_pending() runs, e3() of that setting must not be read.
//
// Errors: sdk::Error (bad frame type/size, index outside the sweep, a frame
// added twice); the state is unchanged on error. Threads: thread-bound
// (docs/threading.md); add() uses `threads` workers of the calling thread's
// pool (sdk::parallel_rows) on disjoint row bands.
#pragma once

#include <cmath>
#include <cstdint>
#include <memory>
#include <vector>

#include "procam/plugin_sdk.hpp"

namespace procam::defocus {

inline constexpr uint32_t kPeriodPx = 24;  // pattern period = shifts per focus setting (§2.3.2)
inline constexpr uint32_t kHarmonic = 3;   // DFT coefficient used (§2.2: "the most informative")

// E3 = 2|D_0 + ω D_1 + ω² D_2 + ω³ D_3| / 24 from the four buckets (Eq. 2.5
// at w = 3, see above): the one definition of the fold's float operations
// (mul and add, no FMA, in this order), which the AVX2 kernel repeats lane
// by lane so a deferred fold gives the same bits.
inline float e3_from_buckets(float a0, float a1, float a2, float a3) noexcept {
  constexpr float kInvSqrt2 = 0.70710678118654752f;
  constexpr float kScale = 2.0f / static_cast<float>(kPeriodPx);
  const float re = a0 + kInvSqrt2 * (a1 - a3);
  const float im = -a2 - kInvSqrt2 * (a1 + a3);
  return kScale * std::sqrt(re * re + im * im);
}

class E3Accumulator {
 public:
  // Frames are width x height of `pixel_type` (PROCAM_PIXEL_U8 / U16 / F32);
  // `full_scale` is the largest DN (2^bits - 1; 1.0 for F32): reaching it
  // marks the pixel saturated.
  // focus_count >= 1. Throws std::bad_alloc only.
  E3Accumulator(uint32_t width, uint32_t height, uint32_t focus_count, uint32_t pixel_type,
                double full_scale, uint32_t threads);
  ~E3Accumulator();
  E3Accumulator(const E3Accumulator&) = delete;
  E3Accumulator& operator=(const E3Accumulator&) = delete;
  E3Accumulator(E3Accumulator&&) noexcept;
  E3Accumulator& operator=(E3Accumulator&&) noexcept;

  // Adds frame (focus, shift), shift in [0, 24). Any order, each once.
  sdk::Error add(uint32_t focus, uint32_t shift, const procam_image& frame);

  uint32_t width() const noexcept { return width_; }
  uint32_t height() const noexcept { return height_; }
  uint32_t focus_count() const noexcept { return focus_count_; }
  // True when all 24 frames of every focus setting were added.
  bool complete() const noexcept;
  // See "Deferred last fold" above. Set before the last frame; honoured for
  // 8-bit frames only (other types fold as usual).
  void defer_final_fold(bool on) noexcept { defer_final_fold_ = on; }
  // The deferred setting's buckets: D_b of pixel i at d[b * n + i], n =
  // width*height; d == nullptr when no fold is pending.
  struct PendingBuckets {
    const int16_t* d = nullptr;
    uint32_t focus = 0;
  };
  PendingBuckets pending_buckets() const noexcept;
  // Folds a pending setting into its E3 map (no-op when none is pending).
  void fold_pending();
  // E3 of focus setting f (2|E|/24, DN), width*height; valid once its 24
  // frames are in (zeros before) and, for a deferred setting, folded.
  const std::vector<float>& e3(uint32_t focus) const { return e3_[focus]; }
  // Mean of the profile (DN) over focus setting 0's frames.
  const std::vector<float>& mean() const noexcept { return mean_; }
  // Moves the mean map out (for a session's outputs, once: mean() is empty
  // afterwards and must not be used again).
  std::vector<float> take_mean() noexcept { return std::move(mean_); }
  // Whether pixel (x, y) saturated (kSaturated) in any frame.
  bool saturated(uint32_t x, uint32_t y) const noexcept {
    return (sat_bits_[size_t{y} * bit_stride_ + x / 8] >> (x % 8)) & 1u;
  }
  // Row y of the saturation bits: bit x % 8 of byte x / 8.
  const uint8_t* saturation_row(uint32_t y) const noexcept { return sat_bits_.data() + size_t{y} * bit_stride_; }

 private:
  struct Buckets;
  uint32_t width_, height_, focus_count_, pixel_type_, threads_;
  double full_scale_;
  std::vector<std::vector<float>> e3_;
  std::vector<float> mean_;
  std::vector<float> dc_;     // running sum over focus 0 (float: exact for integer DN sums < 2^24)
  std::vector<uint8_t> sat_bits_;  // 1 bit per pixel, rows of bit_stride_ bytes
  size_t bit_stride_ = 0;
  std::vector<uint32_t> seen_;       // per focus: bit t set when shift t was added
  std::vector<std::unique_ptr<Buckets>> active_;  // per focus in progress
  std::vector<std::unique_ptr<Buckets>> spare_;   // recycled bucket sets
  bool defer_final_fold_ = false;
  int64_t pending_ = -1;  // the deferred setting, -1: none
  void fold(uint32_t focus);
};

}  // namespace procam::defocus
