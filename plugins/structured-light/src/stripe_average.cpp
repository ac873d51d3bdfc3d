// SPDX-License-Identifier: MIT
// Stripe-averaged margins behind an image-level gate (see stripe_average.hpp).
#include "stripe_average.hpp"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <limits>
#include <mutex>

namespace procam::sl {

namespace {

// White, black of pixel i in input units.
float white_at(const BitPlaneStream& s, size_t i) {
  return s.u8() ? static_cast<float>(s.white8()[i]) : s.white_f()[i];
}
float black_at(const BitPlaneStream& s, size_t i) {
  if (s.u8()) return s.black8() != nullptr ? static_cast<float>(s.black8()[i]) : 0.0f;
  return s.black_f() != nullptr ? s.black_f()[i] : 0.0f;
}

// scipy.ndimage's "reflect" border (half-sample symmetric): x[-1] = x[0].
inline int64_t mirror(int64_t i, int64_t n) {
  while (i < 0 || i >= n) i = i < 0 ? -i - 1 : 2 * n - i - 1;
  return i;
}

}  // namespace

void gaussian_blur(WorkPool& pool, const float* src, float* dst, float* tmp, uint32_t w,
                   uint32_t h, float sigma) {
  const int r = static_cast<int>(4.0f * sigma + 0.5f);
  std::vector<float> k(2 * static_cast<size_t>(r) + 1);
  double sum = 0;
  for (int j = -r; j <= r; ++j) sum += std::exp(-0.5 * j * j / (double{sigma} * double{sigma}));
  for (int j = -r; j <= r; ++j)
    k[static_cast<size_t>(j + r)] = static_cast<float>(std::exp(-0.5 * j * j / (double{sigma} * double{sigma})) / sum);
  const int64_t W = w, H = h;
  pool.run(h, [&](uint32_t y0, uint32_t y1) {  // along rows: src -> tmp
    for (uint32_t y = y0; y < y1; ++y) {
      const float* s = src + size_t{y} * w;
      float* o = tmp + size_t{y} * w;
      for (int64_t x = 0; x < W; ++x) {
        float a = 0;
        if (x >= r && x + r < W)
          for (int j = -r; j <= r; ++j) a += k[static_cast<size_t>(j + r)] * s[x + j];
        else
          for (int j = -r; j <= r; ++j) a += k[static_cast<size_t>(j + r)] * s[mirror(x + j, W)];
        o[x] = a;
      }
    }
  });
  pool.run(h, [&](uint32_t y0, uint32_t y1) {  // along columns: tmp -> dst
    for (uint32_t y = y0; y < y1; ++y) {
      float* o = dst + size_t{y} * w;
      std::fill_n(o, w, 0.0f);
      for (int j = -r; j <= r; ++j) {
        const float kj = k[static_cast<size_t>(j + r)];
        const float* s = tmp + static_cast<size_t>(mirror(int64_t{y} + j, H)) * w;
        for (uint32_t x = 0; x < w; ++x) o[x] += kj * s[x];
      }
    }
  });
}

void stripe_gate(WorkPool& pool, const DecodeContext& ctx, size_t c, StripeAverageReport& r) {
  const BitPlaneStream& s = ctx.s;
  r.available = false;
  r.f_noise = 0;
  r.gate_lit = 0;
  if (!s.pairs_kept(c)) {
    r.why_not = "no pattern/inverse pairs kept (binarize=white has none)";
    return;
  }
  if (!(ctx.t.noise_k > 0.0f)) {
    r.why_not = "noise rule off or its noise not measured";
    return;
  }
  const uint32_t bits = s.code(c).bits;
  if (bits < 4 || s.width() < 2 || s.height() < 2) {
    r.why_not = "code or image too small for the stripe direction";
    return;
  }
  r.available = true;
  r.why_not.clear();
  const uint32_t finest = bits - 1, w = s.width();
  const uint32_t rows = (s.height() + kGateRowStep - 1) / kGateRowStep;
  std::atomic<size_t> lit{0}, bound{0};
  pool.run(rows, [&](uint32_t r0, uint32_t r1) {
    BaseRow base(w);
    size_t l = 0, nb = 0;
    for (uint32_t ry = r0; ry < r1; ++ry) {
      const size_t b = size_t{ry} * kGateRowStep * w;
      decode_base(ctx, b, b + w, base, nullptr, nullptr);
      for (uint32_t x = 0; x < w; ++x) {
        if (base.base_ok[x] == 0) continue;
        ++l;
        const size_t i = b + x;
        const float d = s.kept(finest, false, i) - s.kept(finest, true, i);
        if (!(std::fabs(d) <= base.thr[x])) continue;  // finest plane certain
        const float W = white_at(s, i), B = black_at(s, i);
        // Noise-bound: the noise term sets the threshold (decode_base's max).
        if (noise_threshold(ctx.t, W + B) >= ctx.t.min_bit_margin * (W - B)) ++nb;
      }
    }
    lit.fetch_add(l);
    bound.fetch_add(nb);
  });
  r.gate_lit = lit.load();
  r.f_noise = r.gate_lit > 0 ? static_cast<double>(bound.load()) / static_cast<double>(r.gate_lit) : 0.0;
}

size_t stripe_average(WorkPool& pool, const DecodeContext& ctx, size_t c, const WordMap& words,
                      const UncertainRule& rule, const std::vector<uint8_t>& tolerable,
                      uint32_t half_length, float* coord, uint8_t* valid, float* uncertainty,
                      StripeAverageReport& r) {
  const BitPlaneStream& s = ctx.s;
  r.fired = false;
  r.added = r.candidates = r.planes_decided = 0;
  r.averaged = NoiseFit{};
  if (!r.available || !s.pairs_kept(c)) return 0;
  r.fired = true;
  const uint32_t bits = s.code(c).bits, w = s.width(), h = s.height();
  const size_t n = size_t{w} * h;
  const float fs = s.full_scale();
  const float c_floor = fs / 255.0f;  // the model's max(C, 1) at 8 bit, in input units
  const auto hl = static_cast<int>(half_length);
  const int taps = 2 * hl + 1;
  auto dval = [&](uint32_t p, size_t i) { return s.kept(p, false, i) - s.kept(p, true, i); };
  auto sval = [&](uint32_t p, size_t i) { return s.kept(p, false, i) + s.kept(p, true, i); };

  // Per pixel: contrast, W + B, threshold (decode_base) and usable = lit
  // (rule 1), clean (flags), every pair finite and not clipped on both sides.
  // Uninitialised, from the stream's array cache (bitplane_stream.hpp
  // make_pixel_array): every element is written below before it is read,
  // so no zeroing pass and, from the second scan on, no page faults (value-
  // initialised vectors were ~40 % of this function's time).
  PixelArray<float> contrast = make_pixel_array<float>(n), sum_wb = make_pixel_array<float>(n),
                    thr = make_pixel_array<float>(n);
  PixelArray<uint8_t> usable = make_pixel_array<uint8_t>(n);
  const CodeState& st = s.code(c);
  pool.run(h, [&](uint32_t y0, uint32_t y1) {
    BaseRow base(w);
    for (uint32_t y = y0; y < y1; ++y) {
      const size_t b = size_t{y} * w;
      decode_base(ctx, b, b + w, base, nullptr, nullptr);
      for (uint32_t x = 0; x < w; ++x) {
        const size_t i = b + x;
        const float W = white_at(s, i), B = black_at(s, i);
        contrast[i] = W - B;
        sum_wb[i] = W + B;
        thr[i] = base.thr[x];
        bool ok = base.base_ok[x] != 0 && (s.u8() || st.flags[i] == 0);
        for (uint32_t p = 0; ok && p < bits; ++p) {
          const float l = s.kept(p, false, i), lb = s.kept(p, true, i);
          ok = std::isfinite(l) && std::isfinite(lb) && !(l >= fs && lb >= fs);
        }
        usable[i] = ok ? 1 : 0;
      }
    }
  });

  // 1. Structure tensor of the planes of stripe width 8..128 (2^(bits - p)).
  PixelArray<float> v = make_pixel_array<float>(n), g = make_pixel_array<float>(n),
                    tmp = make_pixel_array<float>(n), jxx = make_pixel_array<float>(n),
                    jxy = make_pixel_array<float>(n), jyy = make_pixel_array<float>(n);
  bool first_plane = true;  // the first tensor plane assigns J, the others add
  for (uint32_t p = 0; p < bits; ++p) {
    const uint32_t width_log2 = bits - p;
    if (width_log2 < 3 || width_log2 > 7) continue;
    pool.run(h, [&](uint32_t y0, uint32_t y1) {
      for (size_t i = size_t{y0} * w; i < size_t{y1} * w; ++i)
        v[i] = dval(p, i) / std::max(contrast[i], c_floor);
    });
    gaussian_blur(pool, v.get(), g.get(), tmp.get(), w, h, 1.0f);
    pool.run(h, [&](uint32_t y0, uint32_t y1) {
      for (uint32_t y = y0; y < y1; ++y)
        for (uint32_t x = 0; x < w; ++x) {
          const size_t i = size_t{y} * w + x;
          // numpy.gradient: central differences, one-sided at the border.
          const float gx = x == 0 ? g[i + 1] - g[i]
                           : x + 1 == w ? g[i] - g[i - 1]
                                        : 0.5f * (g[i + 1] - g[i - 1]);
          const float gy = y == 0 ? g[i + w] - g[i]
                           : y + 1 == h ? g[i] - g[i - w]
                                        : 0.5f * (g[i + w] - g[i - w]);
          if (first_plane) {
            jxx[i] = gx * gx;
            jxy[i] = gx * gy;
            jyy[i] = gy * gy;
          } else {
            jxx[i] += gx * gx;
            jxy[i] += gx * gy;
            jyy[i] += gy * gy;
          }
        }
    });
    first_plane = false;
  }
  if (first_plane) return 0;  // no plane of stripe width 8..128 (bits >= 4 has one)
  for (PixelArray<float>* j : {&jxx, &jxy, &jyy}) {
    gaussian_blur(pool, j->get(), g.get(), tmp.get(), w, h, 3.0f);
    j->swap(g);
  }
  // The 2h + 1 pixels on the stripe through pixel i = (x, y); false when one
  // is outside the image or not usable.
  auto line = [&](uint32_t x, uint32_t y, size_t* at) {
    const size_t i = size_t{y} * w + x;
    const double phi = 0.5 * std::atan2(2.0 * double{jxy[i]}, double{jxx[i]} - double{jyy[i]});
    const double tx = -std::sin(phi), ty = std::cos(phi);
    for (int j = -hl; j <= hl; ++j) {
      const double xs = std::nearbyint(x + j * tx), ys = std::nearbyint(y + j * ty);
      if (xs < 0 || ys < 0 || xs >= w || ys >= h) return false;
      const size_t k = static_cast<size_t>(ys) * w + static_cast<size_t>(xs);
      if (usable[k] == 0) return false;
      at[j + hl] = k;
    }
    return true;
  };

  // 2a. Noise of the averaged margins: the spread across planes of the pair
  // sums averaged along the same lines, every kGateRowStep-th row.
  {
    std::vector<double> means, vars;
    std::mutex mutex;
    const uint32_t rows = (h + kGateRowStep - 1) / kGateRowStep;
    pool.run(rows, [&](uint32_t r0, uint32_t r1) {
      std::vector<double> m, va;
      std::vector<size_t> at(static_cast<size_t>(taps));
      std::vector<double> sp(bits);
      for (uint32_t ry = r0; ry < r1; ++ry) {
        const uint32_t y = ry * kGateRowStep;
        for (uint32_t x = 0; x < w; ++x) {
          if (usable[size_t{y} * w + x] == 0 || !line(x, y, at.data())) continue;
          double mean = 0;
          for (uint32_t p = 0; p < bits; ++p) {
            double a = 0;
            for (size_t k : at) a += double{sval(p, k)};
            sp[p] = a / taps;
            mean += sp[p];
          }
          mean /= bits;
          double var = 0;
          for (double q : sp) var += (q - mean) * (q - mean);
          m.push_back(mean);
          va.push_back(var / (bits - 1));
        }
      }
      std::lock_guard<std::mutex> lock(mutex);
      means.insert(means.end(), m.begin(), m.end());
      vars.insert(vars.end(), va.begin(), va.end());
    });
    r.averaged = fit_noise_samples(means, vars, bits, fs);
  }
  if (!r.averaged.measured) return 0;
  const double a_bar = r.averaged.a, b_bar = r.averaged.b, k_noise = ctx.t.noise_k;

  // 2b, 3. Rejected usable pixels: decide uncertain planes by their average,
  // then the normal rule (decode_uncertain) with those planes certain.
  const int32_t* table = words.table.data();
  const int32_t scale = std::max(words.scale, 1);
  constexpr int kT = CodeState::kTracked;
  std::atomic<size_t> added{0}, candidates{0}, decided_planes{0};
  pool.run(h, [&](uint32_t y0, uint32_t y1) {
    std::vector<size_t> at(static_cast<size_t>(taps));
    size_t add = 0, cand = 0, dec = 0;
    for (uint32_t y = y0; y < y1; ++y)
      for (uint32_t x = 0; x < w; ++x) {
        const size_t i = size_t{y} * w + x;
        if (!std::isnan(coord[i]) || usable[i] == 0 || !line(x, y, at.data())) continue;
        ++cand;
        const float t = thr[i];
        const double limit = k_noise * std::sqrt(std::max(a_bar + b_bar * double{sum_wb[i]}, 1e-6));
        uint32_t word = 0, mask = 0;
        int n_strict = 0, decided = 0;
        bool weak_unc = false, tie = false;
        for (uint32_t p = 0; p < bits; ++p) {
          const float d = dval(p, i);
          bool unc = !(std::fabs(d) > t);
          bool bit = d > 0.0f;
          if (unc) {
            double avg = 0;
            for (size_t k : at) avg += double{dval(p, k)};
            avg /= taps;
            if (std::fabs(avg) > limit) {
              unc = false;
              bit = avg > 0;
              ++decided;
            }
          }
          const uint32_t pos = bits - 1 - p;
          word |= (bit ? 1u : 0u) << pos;
          if (!unc) continue;
          tie = tie || !(std::fabs(d) > 0.0f);
          if (tolerable.size() > p && tolerable[p] != 0) {
            weak_unc = true;
          } else {
            ++n_strict;
            mask |= 1u << pos;
          }
        }
        if (decided == 0 || n_strict > kT) continue;
        if (tie && !(rule.ties && white_at(s, i) < fs)) continue;
        if (weak_unc) mask |= rule.weak_mask;
        int32_t vlo = std::numeric_limits<int32_t>::max(), vhi = -1, count = 0;
        for (uint32_t sub = mask;; sub = (sub - 1) & mask) {  // every subset, the empty one last
          const int32_t val = table[word ^ sub];
          if (val >= 0) {
            vlo = std::min(vlo, val);
            vhi = std::max(vhi, val);
            ++count;
          }
          if (sub == 0) break;
        }
        // As decode_uncertain: every candidate a code word, contiguous, narrow.
        if (vhi < 0 || count != (int32_t{1} << __builtin_popcount(mask)) ||
            (vhi - vlo) / scale + 1 != count)
          continue;
        const float half = 0.5f * static_cast<float>(vhi - vlo) / static_cast<float>(scale);
        if (!(half <= rule.max_half)) continue;
        coord[i] = 0.5f * static_cast<float>(vlo + vhi) / static_cast<float>(scale);
        if (valid != nullptr) valid[i] = 255;
        uncertainty[i] = half;
        ++add;
        dec += static_cast<size_t>(decided);
      }
    added.fetch_add(add);
    candidates.fetch_add(cand);
    decided_planes.fetch_add(dec);
  });
  r.added = added.load();
  r.candidates = candidates.load();
  r.planes_decided = decided_planes.load();
  return r.added;
}

}  // namespace procam::sl
