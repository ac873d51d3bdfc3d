// SPDX-License-Identifier: MIT
// One-pass end of a striping scan on packed StripeStacks (U8 frames, <= 256
// stripes, >= 3 frames): stripe decision and column, composite (Eq. 5.7),
// S/A/B (Eq. 5.6 on the backgrounds), CQM, GQM, W (Eq. 5.8–5.10) and the
// report's sums. An AVX2 kernel and its scalar twin (striping_pass.cpp);
// estimate_striping() keeps the general double-precision pass as reference.
// Contracts: writes only pixels [i0, i1) of the maps and `q`; thread-safe for
// disjoint ranges. Units: DN of the frames.
#pragma once

#include <cstddef>
#include <cstdint>

namespace procam::polarized_striping {

// Sums for the report over one band of rows; bands are merged in row order so
// the report is the same bit for bit from run to run.
struct QualitySums {
  double cqm = 0, gqm = 0, w = 0, cqm_w = 0, gqm_w = 0, img = 0, img2 = 0, enh = 0, enh2 = 0;
  size_t n_cqm = 0, n_gqm = 0, n_w = 0, n_cqm_w = 0, n_gqm_w = 0, n_img = 0, n_enh = 0;
  void add(const QualitySums& o) {
    cqm += o.cqm, gqm += o.gqm, w += o.w, cqm_w += o.cqm_w, gqm_w += o.gqm_w;
    img += o.img, img2 += o.img2, enh += o.enh, enh2 += o.enh2;
    n_cqm += o.n_cqm, n_gqm += o.n_gqm, n_w += o.n_w, n_cqm_w += o.n_cqm_w, n_gqm_w += o.n_gqm_w;
    n_img += o.n_img, n_enh += o.n_enh;
  }
};

// A packed stack's arrays: keys (value << 8) | (255 - k) of the top two, the
// 16-bit sum, and the number of frames folded in.
struct PackedView {
  const uint16_t* key1 = nullptr;
  const uint16_t* key2 = nullptr;
  const uint16_t* sum = nullptr;
  uint32_t frames = 0;
};

// The decision's and the quality measures' settings.
struct PassSettings {
  double margin = 5, saturation = 250;  // DN (StripeDecodeSettings)
  double mu = 3, z = 1;                 // SNR weight (Eq. 5.10)
  double p = 0;                         // DOP used
  bool separate = false;                // p >= p_min: Eq. 5.6
  const float* centre = nullptr;        // projector column of stripe k's centre, k = 0..256
};

// Output maps (full image size). The composite goes to `image` (F32) or
// `image_u8` (U8: it is a frame value, top1), whichever is not null;
// enhanced, backscatter and stripe are required; col, cqm, weight and gqm may
// be null: not written (and `col` not computed). The
// report's sums are the same whichever maps are written (GQM's only when
// polarised).
struct PassMaps {
  float* image = nullptr;
  uint8_t* image_u8 = nullptr;
  float *enhanced = nullptr, *backscatter = nullptr, *stripe = nullptr;
  float *col = nullptr, *cqm = nullptr, *weight = nullptr, *gqm = nullptr;
  // Whether to add Eq. 5.8-5.10 and the enhanced image's sums to the
  // report's sums (QualitySums: cqm, gqm, w, cqm_w, gqm_w, enh, enh2 and
  // their counts). Off: those sums are left alone and, when no quality map
  // is requested either, their arithmetic is skipped; the maps, the valid
  // count and the composite's sums (img, img2, n_img) are the same either way.
  bool quality = true;
};

enum class PassKernel { best, scalar, avx2 };

// Whether `kernel` can run on this CPU (avx2: AVX2 and FMA).
bool pass_kernel_available(PassKernel kernel);

// For tests: how many integers n in [-2^17, 2^17 + 7] the AVX2 kernel's
// multiply-add quotient n / d (it replaces the division by K - 2) gets
// different from the division, bit for bit; 0 where the AVX2 kernel cannot run.
size_t exact_quotients_mismatches(int32_t d);

// Pixels [i0, i1): writes the maps that are not null, adds to q, returns the
// number of valid stripes. Every written value is the same bit for bit
// whichever other maps are requested.
size_t striping_pass(const PackedView& best, const PackedView* worst, const PassSettings& s, const PassMaps& m,
                     size_t i0, size_t i1, QualitySums& q, PassKernel kernel = PassKernel::best);

// The DOP estimate of a polarized striping scan (estimate_dop's rule, Eq.
// 5.4–5.5, on the backgrounds bg = (sum - top1 - top2) / (K - 2) of both
// stacks): r = (bg_w - bg_b) / (bg_w + bg_b) at entries 0, s, ..., (count -
// 1) s of the views (the full stacks with s = dop_sample_stride(pixels), or
// a stack's compact DOP sample with s = 1) where neither top2 reaches `saturation` and
// bg_w + bg_b > min_sum; the `percentile` quantile of r, clamped to [0, 1];
// NaN with fewer than min_pixels samples. The same value, bit for bit, as
// estimate_dop() on the float backgrounds of those pixels (what the
// reference pass does), without its serial steps: the sample is drawn on
// `threads` workers (sdk::parallel_rows), each keeping a histogram of its
// keys' top 16 bits, and the two order statistics are then picked from the
// merged histogram and the few keys of the chosen buckets. O(count) time,
// no dependence on thread count or order. Threads: reentrant; runs workers
// itself (sdk::parallel_rows); keeps its scratch (~1.3 MB) per calling
// thread for the next call. Errors: std::bad_alloc only.
//
// DopSelect::best (issue 13, fifth round) first tries pivots from a strided
// subsample of ~2048 entries (Floyd-Rivest): one parallel pass counts the
// keys below the lower pivot and keeps only those between the pivots, and the
// two order statistics come from that window when it holds both ranks; the
// radix selection above runs only when it does not (then the sample is drawn
// twice). Same value either way, bit for bit; `by_pivots` (may be null) says
// which path answered. DopSelect::radix: the radix selection only (tests).
enum class DopSelect { best, radix };
double packed_dop(const PackedView& best, const PackedView& worst, size_t count, size_t stride, double saturation,
                  double min_sum, double percentile, uint32_t threads, size_t min_pixels = 16,
                  DopSelect select = DopSelect::best, bool* by_pivots = nullptr);

}  // namespace procam::polarized_striping
