// SPDX-License-Identifier: MIT
// One capture round of several column codes sharing a white (and optionally a
// black) frame — the form of the single XOR / min-SW methods (one code) and of
// the ensemble (four codes, thesis §3.3.3) — streamed through binarization as
// frames arrive (thesis §3.2, Eq. 3.5; binarize.hpp) and decoded per code.
//
// Frame order (plan order and offline file order):
//   0 "white"; 1 "black" (when the layout has a black frame); then per code in
//   the given order, per plane from the most significant bit k = bits-1 .. 0:
//   "<code> bit k" [, "<code> bit k inverse"].
// Binarization: with inverses, bit = L > L̄ (Eq. 3.5); without, L̄ = W + B − L
// (§3.2 footnote 2, generalised; B = 0 when no black frame is projected — the
// thesis's 41-image ensemble), i.e. L is compared with (W + B) / 2.
// Pixels whose white frame is clipped (W >= full scale) are invalid in that
// mode: W + B − L is then not the inverse image.
// Masked rounds (error correction, §3.4): every pattern, white included, is
// ANDed with a projector mask, so decoding needs no change — pixels lit only
// by switched-off projector pixels fail the contrast rule and stay invalid.
// Inputs: one-channel U8 / U16 (bit_depth 1..16) / F32 frames of one format.
// Streaming and per-pixel state: the shared engine of bitplane_stream.hpp
// (the same as BinaryRoundDecoder's).
// Thread-safety: thread-bound (docs/threading.md); uses `threads` workers (a WorkPool owned by
// the decoder) for per-pixel loops.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "binarize.hpp"
#include "codes.hpp"
#include "plan_layout.hpp"
#include "procam/plugin_sdk.hpp"
#include "round_decoder.hpp"
#include "vote.hpp"

namespace procam::sl {

struct MultiFrame {
  FrameKind kind = FrameKind::white;
  uint32_t code = 0;     // index into the code list (plane / inverse)
  uint32_t plane = 0;    // 0 = most significant
  int32_t partner = -1;  // plane <-> inverse
  std::string label;
};

struct MultiLayout {
  bool inverse = false;
  bool black = true;
  std::vector<uint32_t> bits;  // per code
  std::vector<MultiFrame> frames;
  int32_t black_index() const { return black ? 1 : -1; }
};

MultiLayout make_multi_layout(const std::vector<ProjectedCode>& codes, bool inverse, bool black);

// Appends the layout's patterns (projector W x H, U8 0/255, vertical stripes)
// to `plan`, leaving out layout frames i with (*skip)[i] != 0 (the session
// already holds those frames from an earlier round, e.g. a probe, and feeds
// them to the decoder itself). `mask` (W*H, nonzero = may be lit) switches
// projector pixels off in every pattern, white included; null = all on.
void render_multi_plan(const MultiLayout& layout, const std::vector<ProjectedCode>& codes,
                       uint32_t width, uint32_t height, const std::vector<uint8_t>* mask,
                       sdk::Plan& plan, const std::vector<uint8_t>* skip = nullptr);

struct MultiResult {
  std::vector<AxisMaps> codes;   // per code: projector column (span centre), valid, confidence
                                 // (finish(); empty after finish_vote())
  VoteMaps vote;                 // ensemble vote (finish_vote(); empty after finish())
  std::vector<uint8_t> lit;      // 255 where W - B passes the contrast rule (decode.hpp rule 1)
  std::vector<float> intensity;  // white / full scale in [0, 1]
  std::vector<size_t> weak;      // per code: valid pixels kept through a tolerated weak plane
                                 // or (uncertain output) given an interval
  double full_scale = 0;
  NoiseFit noise;                // finish() with noise_k > 0 and inverse frames
  double noise_k = 0;            // the noise rule's k (0: off or not measured)
  size_t conflicts = 0;          // finish_vote with VoteSpec::conflicts: pixels set to kConflict
  // finish_vote with VoteSpec::count: the per-pixel counts of the final maps
  // (lit, vote.valid, vote.cls after the conflict rule), taken in the vote's
  // own pass over each row band while it is in cache (issue 17: a second pass
  // over 7 MB after the last frame). flagged: correction.hpp flagged().
  using Counts = PixelCounts;  // vote.hpp count_classes
  Counts counts;
};

// Gives every map of `r` to the map cache (map_cache.hpp), as the session
// does when it ends, so the next decoder of the same size reuses the pages.
void recycle_maps(MultiResult&& r) noexcept;

// What finish_vote() votes with, per ensemble slot (vote.hpp order gray,
// xor02, xor04, minsw): this round's code `round_code[k]`, or, where that is
// -1, an earlier round's column map `external[k]` (NaN = invalid).
// keep[k] (optional): also write this round's code's own column map there (NaN where that
// code is invalid or the pixel is unlit, shadow rule included).
struct VoteSpec {
  int32_t round_code[kEnsembleCodes] = {-1, -1, -1, -1};
  const float* external[kEnsembleCodes] = {nullptr, nullptr, nullptr, nullptr};
  float* keep[kEnsembleCodes] = {nullptr, nullptr, nullptr, nullptr};
  float agree_px = 1.0f;
  // Also apply the conflict rule (correction.hpp label_conflicts_keys) to the
  // vote's maps in the same pass; MultiResult::conflicts counts the pixels.
  bool conflicts = false;
  // Also fill MultiResult::counts in the same pass.
  bool count = false;
};

class MultiCodeDecoder {
 public:
  enum class Output { per_code, vote };
  // max_weak_error_px: tolerated weak planes (decode.hpp; 0 = every plane
  // strict). `output` picks which result maps the constructor allocates:
  // per-code maps for finish(), the vote maps for finish_vote().
  MultiCodeDecoder(MultiLayout layout, const std::vector<ProjectedCode>& codes, uint32_t width,
                   uint32_t height, uint32_t threads, uint32_t max_weak_error_px = 0,
                   Output output = Output::per_code);

  // Frame `index` of the layout, each once; BAD_FRAME / STATE errors as
  // BinaryRoundDecoder. The image is only read during the call.
  sdk::Error add_frame(uint32_t index, const procam_image& frame) {
    return stream_.add_frame(index, frame);
  }
  bool complete() const { return stream_.complete(); }

  // Decode rules of decode.hpp per code (min_contrast: fraction of full scale).
  // Requires complete() (std::logic_error otherwise). The maps live in the
  // decoder: they are allocated and touched by the constructor (while frames
  // are still being captured), so the work after the last frame does not pay
  // for page faults. Callers may move the maps out; a later call re-allocates.
  // noise_k > 0 adds the noise rule (decode.hpp) with the noise fitted to
  // this capture's pattern/inverse pairs (layouts with inverses only; without
  // them it is skipped and result.noise.measured stays false).
  MultiResult& finish(double min_contrast, double min_bit_margin, double noise_k = 0);

  // With true, finish() gives a pixel with uncertain planes (at most
  // kTrackedPlanes strict ones plus the tolerated weak ones) the interval of
  // every projector coordinate its uncertain bits allow, when all candidates
  // are code words of consecutive code indices and the interval's half-width
  // in projector coordinates is at most max_half (codes[c].coord = its
  // centre, codes[c].uncertainty = the half-width; 0 where every plane is
  // certain, NaN where invalid); such a pixel is invalid otherwise. The same
  // rule as BinaryRoundDecoder's (decode_uncertain), in code-index space and
  // then mapped through the code's stretched columns (codes.hpp: a min-SW
  // code column spans 1-2 projector columns on a projector wider than 1024).
  // Why it matters most for min-SW: adjacent columns differ in one bit and
  // the code spreads its 1023 bit changes evenly over its planes, so every
  // camera pixel lies within half a column of *some* plane's stripe edge;
  // blurred there, that plane's margin is small, and without intervals the
  // margin rule rejects the pixel (issue 16: 33-54 % of lit pixels kept on
  // real captures). Call before the first frame; finish() only (the vote
  // does not use intervals).
  void set_uncertain_output(bool on, float max_half = 1.5f) {
    uncertain_ = on;
    max_uncertainty_ = max_half;
    stream_.track_single_planes(on);
  }
  // Shadow rule (both finish functions): without a black frame B = 0 is
  // assumed, so a pixel lit only by ambient light reads "on" in every plane
  // and each code decodes its all-ones word. With two or more codes no
  // projector column is the all-ones word of every code at once, so such a
  // pixel is marked unlit (lit = 0, every code invalid) instead of decoding
  // to the columns where those words happen to agree.

  // Decode + ensemble vote in one pass (vote.hpp, vote_keys): no per-code
  // maps are written (except VoteSpec::keep); fills result.vote, lit,
  // intensity and weak. Same requirements and map ownership as finish().
  MultiResult& finish_vote(double min_contrast, double min_bit_margin, const VoteSpec& spec);

  const MultiLayout& layout() const { return layout_; }
  // The decoder's worker threads (the rig's `threads`), for the session's
  // own row loops after the round (outputs()): they are the threads that
  // just ran the vote, still spinning or warm, so a job there starts at
  // once; the calling thread's sdk::parallel_rows pool would be a second
  // set of threads woken from sleep while these spin on the same cores.
  // Same contract as WorkPool (one job at a time, from the session's thread).
  WorkPool& pool() { return stream_.pool(); }

 private:
  void allocate_result(Output output);
  DecodeThresholds thresholds(double min_contrast, double min_bit_margin) const;

  MultiLayout layout_;
  std::vector<ProjectedCode> codes_;
  std::vector<WordMap> index_map_;  // per code: word -> code index (-1: none)
  std::vector<WordMap> key_map_;    // per code: word -> 2 x column (-1: none)
  std::vector<int32_t> all_on_index_, all_on_key_;  // per code: the all-ones word's index / key
  uint32_t width_, height_;
  BitPlaneStream stream_;
  MultiResult result_;  // pre-allocated output maps
  bool uncertain_ = false;
  float max_uncertainty_ = 1.5f;
};

}  // namespace procam::sl
