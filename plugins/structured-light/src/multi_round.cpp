// SPDX-License-Identifier: MIT
// Multi-code binary round: layout, pattern rendering, streaming binarization
// and per-code decode (thesis §3.2–3.3; see multi_round.hpp).
#include "multi_round.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <mutex>
#include <stdexcept>
#include <utility>

#include "correction.hpp"
#include "decode.hpp"

namespace procam::sl {

MultiLayout make_multi_layout(const std::vector<ProjectedCode>& codes, bool inverse, bool black) {
  MultiLayout l;
  l.inverse = inverse;
  l.black = black;
  l.frames.push_back({FrameKind::white, 0, 0, -1, "white"});
  if (black) l.frames.push_back({FrameKind::black, 0, 0, -1, "black"});
  for (uint32_t c = 0; c < codes.size(); ++c) {
    const uint32_t bits = codes[c].bits();
    l.bits.push_back(bits);
    for (uint32_t p = 0; p < bits; ++p) {
      const std::string base = codes[c].id + " bit " + std::to_string(bits - 1 - p);
      const auto idx = static_cast<int32_t>(l.frames.size());
      l.frames.push_back({FrameKind::plane, c, p, -1, base});
      if (inverse) {
        l.frames.push_back({FrameKind::inverse, c, p, idx, base + " inverse"});
        l.frames[static_cast<size_t>(idx)].partner = idx + 1;
      }
    }
  }
  return l;
}

void render_multi_plan(const MultiLayout& layout, const std::vector<ProjectedCode>& codes,
                       uint32_t width, uint32_t height, const std::vector<uint8_t>* mask,
                       sdk::Plan& plan, const std::vector<uint8_t>* skip) {
  for (const ProjectedCode& c : codes)
    if (c.length() != width)
      throw std::invalid_argument("render_multi_plan: code length differs from projector width");
  if (mask != nullptr && mask->size() != size_t{width} * height)
    throw std::invalid_argument("render_multi_plan: mask size differs from projector size");
  std::vector<uint8_t> line(width);
  for (size_t fi = 0; fi < layout.frames.size(); ++fi) {
    if (skip != nullptr && fi < skip->size() && (*skip)[fi] != 0) continue;
    const MultiFrame& f = layout.frames[fi];
    const uint32_t i = plan.add_frame(f.label, width, height, PROCAM_PIXEL_U8);
    std::span<uint8_t> px = plan.pattern_u8(i);
    switch (f.kind) {
      case FrameKind::white: std::fill(line.begin(), line.end(), uint8_t{255}); break;
      case FrameKind::black: std::fill(line.begin(), line.end(), uint8_t{0}); break;
      case FrameKind::plane:
      case FrameKind::inverse: {
        const bool inv = f.kind == FrameKind::inverse;
        for (uint32_t x = 0; x < width; ++x)
          line[x] = codes[f.code].bit(f.plane, x) != inv ? 255 : 0;
        break;
      }
    }
    for (uint32_t y = 0; y < height; ++y) {
      uint8_t* row = px.data() + size_t{y} * width;
      if (mask == nullptr) {
        std::memcpy(row, line.data(), width);
      } else {
        const uint8_t* m = mask->data() + size_t{y} * width;
        for (uint32_t x = 0; x < width; ++x) row[x] = m[x] != 0 ? line[x] : uint8_t{0};
      }
    }
  }
}

namespace {
StreamLayout stream_layout(const MultiLayout& l, const std::vector<ProjectedCode>& codes,
                           uint32_t max_weak_error_px) {
  StreamLayout s;
  s.inverse = l.inverse;
  s.white = 0;
  s.black = l.black_index();
  s.bits = l.bits;
  for (const ProjectedCode& c : codes)
    s.tolerable.push_back(tolerable_planes(plane_error_bounds(c), max_weak_error_px));
  for (const MultiFrame& f : l.frames) s.frames.push_back({f.kind, f.code, f.plane, f.partner, f.label});
  return s;
}
}  // namespace

MultiCodeDecoder::MultiCodeDecoder(MultiLayout layout, const std::vector<ProjectedCode>& codes,
                                   uint32_t width, uint32_t height, uint32_t threads,
                                   uint32_t max_weak_error_px, Output output)
    : layout_(std::move(layout)),
      codes_(codes),
      width_(width),
      height_(height),
      stream_(stream_layout(layout_, codes_, max_weak_error_px), width, height, threads) {
  for (const ProjectedCode& c : codes_) {
    index_map_.push_back(word_map(c.code));
    std::vector<int32_t> key(c.coord_of.size());  // code index -> 2 x column (span centres: x.5)
    for (size_t i = 0; i < key.size(); ++i)
      key[i] = static_cast<int32_t>(std::lround(2.0 * static_cast<double>(c.coord_of[i])));
    key_map_.push_back(word_map(c.code, &key));
    all_on_index_.push_back(index_map_.back().table.back());  // table: 2^bits words
    all_on_key_.push_back(key_map_.back().table.back());
  }
  allocate_result(output);
  stream_.set_intensity_output(result_.intensity.data());
}

void recycle_maps(MultiResult&& r) noexcept {
  for (AxisMaps& m : r.codes) {
    sdk::give_map(std::move(m.coord));
    sdk::give_map(std::move(m.valid));
    sdk::give_map(std::move(m.confidence));
    sdk::give_map(std::move(m.uncertainty));
  }
  sdk::give_map(std::move(r.vote.coord));
  sdk::give_map(std::move(r.vote.valid));
  sdk::give_map(std::move(r.vote.confidence));
  sdk::give_map(std::move(r.vote.cls));
  sdk::give_map(std::move(r.lit));
  sdk::give_map(std::move(r.intensity));
}

void MultiCodeDecoder::allocate_result(Output output) {
  const size_t n = size_t{width_} * height_;
  // Every page written now, not after the last frame.
  MapBatch maps;
  if (output == Output::per_code) {
    result_.codes.resize(codes_.size());
    for (AxisMaps& m : result_.codes) {
      maps.add(m.coord, n);
      maps.add(m.valid, n);
      maps.add(m.confidence, n);
    }
  } else {
    VoteMaps& v = result_.vote;
    maps.add(v.coord, n);
    maps.add(v.valid, n);
    maps.add(v.confidence, n);
    maps.add(v.cls, n);
  }
  maps.add(result_.lit, n);
  if (result_.intensity.size() != n) {  // a new map: written at finish, not from the white frame
    stream_.set_intensity_output(nullptr);
    maps.add(result_.intensity, n);
  }
  maps.run(stream_.pool());
}

DecodeThresholds MultiCodeDecoder::thresholds(double min_contrast, double min_bit_margin) const {
  DecodeThresholds t;
  t.min_contrast_abs = static_cast<float>(min_contrast * static_cast<double>(stream_.full_scale()));
  t.min_bit_margin = static_cast<float>(min_bit_margin);
  t.clipped_white_invalid = !layout_.inverse;  // W + B - L is not the inverse where W clips
  return t;
}

MultiResult& MultiCodeDecoder::finish(double min_contrast, double min_bit_margin, double noise_k) {
  stream_.require_complete("MultiCodeDecoder");
  allocate_result(Output::per_code);  // no-op unless a caller moved maps out
  MultiResult& r = result_;
  r.full_scale = static_cast<double>(stream_.full_scale());
  DecodeThresholds t = thresholds(min_contrast, min_bit_margin);
  r.noise = apply_noise_rule(stream_, layout_.inverse ? noise_k : 0.0, t, r.noise_k);
  const DecodeContext ctx(stream_, t);
  const float nan = std::numeric_limits<float>::quiet_NaN();
  const size_t n = size_t{width_} * height_;
  std::vector<UncertainRule> rule(codes_.size());
  if (uncertain_)
    for (size_t c = 0; c < codes_.size(); ++c) {
      sdk::take_map(r.codes[c].uncertainty, n);  // every element written below
      // In code-index units: a code index spans >= 1 coordinate, so this
      // bound never rejects what the coordinate bound below would keep.
      rule[c] = {tolerable_mask(stream_.code(c).tolerable, codes_[c].bits()), max_uncertainty_, false};
    }
  decode_rows(stream_, ctx, r.lit.data(), stream_.intensity_to_write(r.intensity), codes_.size(),
              r.weak, [&](size_t b, size_t e, const BaseRow& base, int32_t* idx, size_t* weak) {
                for (size_t c = 0; c < codes_.size(); ++c) {
                  AxisMaps& m = r.codes[c];
                  const size_t tolerated = decode_code(ctx, c, index_map_[c], b, e, base, idx,
                                                       m.confidence.data() + b);
                  const float* coord_of = codes_[c].coord_of.data();
                  float* coord = m.coord.data() + b;
                  uint8_t* valid = m.valid.data() + b;
                  for (size_t k = 0; k < e - b; ++k) {
                    const bool ok = idx[k] >= 0;
                    coord[k] = ok ? coord_of[ok ? idx[k] : 0] : nan;
                    valid[k] = ok ? 255 : 0;
                  }
                  if (!uncertain_) {
                    weak[c] += tolerated;
                    continue;
                  }
                  // The interval in code-index space (decode_uncertain writes
                  // its centre into `centre`; exact pixels keep their value,
                  // only tested for NaN there), then mapped to projector
                  // coordinates.
                  float* unc = m.uncertainty.data() + b;
                  std::vector<float> centre(coord, coord + (e - b));
                  weak[c] += decode_uncertain(ctx, c, index_map_[c], rule[c], b, e, base, centre.data(), valid, unc);
                  const size_t last = codes_[c].coord_of.size() - 1;
                  for (size_t k = 0; k < e - b; ++k) {
                    if (valid[k] == 0) {
                      coord[k] = nan;
                      unc[k] = nan;
                      continue;
                    }
                    if (!(unc[k] > 0.0f)) continue;  // exact: coord_of[idx] above
                    const size_t lo = static_cast<size_t>(std::lround(centre[k] - unc[k]));
                    const size_t hi = std::min(last, static_cast<size_t>(std::lround(centre[k] + unc[k])));
                    const float half = 0.5f * (coord_of[hi] - coord_of[lo]);
                    if (half > max_uncertainty_) {
                      coord[k] = nan;
                      unc[k] = nan;
                      valid[k] = 0;
                      --weak[c];
                      continue;
                    }
                    coord[k] = 0.5f * (coord_of[lo] + coord_of[hi]);
                    unc[k] = half;
                  }
                }
                if (layout_.black || codes_.size() < 2) return;
                // Shadow rule (multi_round.hpp), in chunks: one flag pass per
                // code (vectorizable), then clear the few flagged pixels.
                constexpr size_t kChunk = 1024;
                uint8_t flag[kChunk];
                for (size_t k0 = b; k0 < e; k0 += kChunk) {
                  const size_t m = std::min(kChunk, e - k0);
                  std::fill(flag, flag + m, uint8_t{1});
                  for (size_t c = 0; c < codes_.size(); ++c) {
                    const int32_t on = all_on_index_[c];
                    if (on < 0) {  // the all-ones word is no code word: that code is invalid there
                      const uint8_t* va = r.codes[c].valid.data() + k0;
                      for (size_t k = 0; k < m; ++k) flag[k] &= static_cast<uint8_t>(va[k] == 0);
                    } else {
                      const float want = codes_[c].coord_of[static_cast<size_t>(on)];
                      const float* co = r.codes[c].coord.data() + k0;
                      for (size_t k = 0; k < m; ++k) flag[k] &= static_cast<uint8_t>(co[k] == want);
                    }
                  }
                  for (size_t k = 0; k < m; ++k) {
                    if (flag[k] == 0) continue;
                    r.lit[k0 + k] = 0;
                    for (AxisMaps& am : r.codes) {
                      am.coord[k0 + k] = nan;
                      am.valid[k0 + k] = 0;
                      am.confidence[k0 + k] = 0.0f;
                    }
                  }
                }
              });
  return r;
}

MultiResult& MultiCodeDecoder::finish_vote(double min_contrast, double min_bit_margin,
                                           const VoteSpec& spec) {
  stream_.require_complete("MultiCodeDecoder");
  for (uint32_t k = 0; k < kEnsembleCodes; ++k) {
    const int32_t c = spec.round_code[k];
    if (c >= static_cast<int32_t>(codes_.size()) || (c < 0 && spec.external[k] == nullptr))
      throw std::invalid_argument("MultiCodeDecoder::finish_vote: ensemble slot without a map");
  }
  allocate_result(Output::vote);
  MultiResult& r = result_;
  r.full_scale = static_cast<double>(stream_.full_scale());
  const DecodeContext ctx(stream_, thresholds(min_contrast, min_bit_margin));
  const int32_t agree2 = agree_key_threshold(spec.agree_px);
  const float nan = std::numeric_limits<float>::quiet_NaN();
  std::mutex conflicts_mutex;
  r.conflicts = 0;
  r.counts = MultiResult::Counts{};
  decode_rows(stream_, ctx, r.lit.data(), stream_.intensity_to_write(r.intensity), codes_.size(),
              r.weak, [&](size_t b, size_t e, const BaseRow& base, int32_t* scratch, size_t* weak) {
                const int32_t* key_rows[kEnsembleCodes];
                for (uint32_t k = 0; k < kEnsembleCodes; ++k) {
                  int32_t* key = scratch + k * (e - b);  // 4 scratch rows
                  key_rows[k] = key;
                  const int32_t c = spec.round_code[k];
                  if (c < 0) {  // earlier round's columns (multiples of 0.5)
                    const float* ext = spec.external[k] + b;
                    for (size_t i = 0; i < e - b; ++i)
                      key[i] = std::isnan(ext[i]) ? -1 : static_cast<int32_t>(std::lround(2.0f * ext[i]));
                    continue;
                  }
                  const auto cu = static_cast<size_t>(c);
                  weak[cu] += decode_code(ctx, cu, key_map_[cu], b, e, base, key, nullptr);
                }
                if (!layout_.black && codes_.size() >= 2) {  // shadow rule (multi_round.hpp)
                  // This round's codes (>= 2); unused slots repeat the first
                  // so the loop is a fixed, branch-free 4-way compare.
                  const int32_t* rows[kEnsembleCodes];
                  int32_t on[kEnsembleCodes];
                  size_t nr = 0;
                  for (uint32_t k = 0; k < kEnsembleCodes; ++k)
                    if (spec.round_code[k] >= 0) {
                      rows[nr] = key_rows[k];
                      on[nr++] = all_on_key_[static_cast<size_t>(spec.round_code[k])];
                    }
                  for (size_t j = nr; j < kEnsembleCodes; ++j) {
                    rows[j] = rows[0];
                    on[j] = on[0];
                  }
                  const int32_t *r0 = rows[0], *r1 = rows[1], *r2 = rows[2], *r3 = rows[3];
                  const int32_t o0 = on[0], o1 = on[1], o2 = on[2], o3 = on[3];
                  uint8_t* lit = r.lit.data() + b;
                  for (size_t i = 0; i < e - b; ++i) {
                    const int32_t all_on = (r0[i] == o0) & (r1[i] == o1) & (r2[i] == o2) & (r3[i] == o3);
                    lit[i] = static_cast<uint8_t>(lit[i] & (all_on - 1));  // all_on: 0, else keep
                  }
                }
                for (uint32_t k = 0; k < kEnsembleCodes; ++k) {  // per-code maps, shadows invalid
                  if (spec.round_code[k] < 0 || spec.keep[k] == nullptr) continue;
                  const int32_t* key = key_rows[k];
                  const uint8_t* lit = r.lit.data() + b;
                  float* keep = spec.keep[k] + b;
                  for (size_t i = 0; i < e - b; ++i)
                    keep[i] = key[i] >= 0 && lit[i] != 0 ? 0.5f * static_cast<float>(key[i]) : nan;
                }
                vote_keys(key_rows, r.lit.data() + b, e - b, agree2, r.vote.coord.data() + b,
                          r.vote.valid.data() + b, r.vote.confidence.data() + b,
                          r.vote.cls.data() + b);
                if (spec.conflicts) {
                  const size_t got = label_conflicts_keys(key_rows, agree2, e - b, r.vote.coord.data() + b,
                                                          r.vote.valid.data() + b, r.vote.confidence.data() + b,
                                                          r.vote.cls.data() + b);
                  const std::lock_guard<std::mutex> lock(conflicts_mutex);
                  r.conflicts += got;
                }
                if (spec.count) {  // the final maps of this band, still in cache
                  MultiResult::Counts c;
                  count_classes(r.lit.data() + b, r.vote.valid.data() + b, r.vote.cls.data() + b, e - b, c);
                  const std::lock_guard<std::mutex> lock(conflicts_mutex);
                  r.counts.lit += c.lit;
                  r.counts.valid += c.valid;
                  r.counts.flagged += c.flagged;
                  for (uint32_t k = 0; k < kTransportClassCount; ++k) r.counts.cls[k] += c.cls[k];
                }
              });
  return r;
}

}  // namespace procam::sl
