// SPDX-License-Identifier: MIT
// End-of-scan estimates of S, B, p, the stripe map and the quality measures
// (see estimate.hpp; thesis Eq. 5.4–5.10).
#include "estimate.hpp"

#include <algorithm>
#include <atomic>
#include <cmath>

#include "media_model.hpp"
#include "procam/sdk/map_cache.hpp"
#include "procam/sdk/parallel.hpp"
#include "striping_pass.hpp"

namespace procam::polarized_striping {
namespace {

// A map of n values, all `v`, in recycled storage where the map cache has
// some (fresh pages fault one by one: on a VM that costs more than the math).
void nan_map(std::vector<float>& m, size_t n, float v = kNaN) {
  sdk::take_map(m, n);
  std::fill(m.begin(), m.end(), v);
}

Maps blank(uint32_t w, uint32_t h) {
  Maps m;
  m.width = w;
  m.height = h;
  const size_t n = size_t{w} * h;
  nan_map(m.enhanced, n);
  nan_map(m.backscatter, n);
  return m;
}

// p given (>= 0) or estimated by estimate() (estimate_dop's rule; called
// only when p is not given); records how in m.dop.
template <class Estimate>
double choose_dop(const Config& cfg, double min_sum, Maps& m, Estimate&& estimate) {
  double p = cfg.p;
  if (p >= 0) {
    m.dop = {{"source", "param p"}, {"value", p}};
  } else {
    p = estimate();
    m.dop = {{"source", "estimated"},
             {"rule", "quantile dop_percentile of (E_w - E_b) / (E_w + E_b) over pixels with E_w + E_b > 40 noise "
                      "sigma (of the images compared: one frame, or a background averaged over K - 2 frames); "
                      "equals p where a pixel sees only medium, less where it sees an object"},
             {"min_sum_dn", min_sum},
             {"percentile", cfg.dop_percentile}};
    if (!std::isfinite(p)) {
      m.notes.push_back("too few pixels above 40 noise sigma to estimate the DOP: backscatter not separated; pass "
                        "param p (the DOP of the medium's backscatter) or raise the exposure");
      p = 0;
    }
    m.dop["value"] = p;
  }
  if (p < cfg.p_min && p > 0)
    m.notes.push_back("DOP " + std::to_string(p) + " is below p_min: Eq. 5.6 not applied (its 1/p would amplify "
                      "noise); backscatter not separated");
  return p;
}

}  // namespace

Maps estimate_flood(std::vector<float> e, const Config& cfg, const Levels& lv, uint32_t w, uint32_t h) {
  Maps m = blank(w, h);
  std::vector<float> unclipped;
  unclipped.reserve(e.size());
  for (float v : e)
    if (double(v) < lv.saturation) unclipped.push_back(v);
  const double b = unclipped.empty() ? 0.0 : std::max(0.0, quantile(std::move(unclipped), cfg.backscatter_percentile));
  for (size_t i = 0; i < e.size(); ++i) {
    if (!(double(e[i]) < lv.saturation)) continue;
    m.enhanced[i] = static_cast<float>(std::max(0.0, double(e[i]) - b));
    m.backscatter[i] = static_cast<float>(b);
    ++m.valid;
  }
  m.image = std::move(e);
  fill_quality(m, lv, cfg.threads, cfg.all_maps);
  return m;
}

Maps estimate_polarized_flood(std::vector<float> eb, const std::vector<float>& ew, const Config& cfg,
                              const Levels& lv, uint32_t w, uint32_t h) {
  Maps m = blank(w, h);
  std::vector<float> b_ok, w_ok;  // unclipped pairs only (scratch from the map cache)
  nan_map(b_ok, eb.size());
  nan_map(w_ok, eb.size());
  for (size_t i = 0; i < eb.size(); ++i)
    if (double(eb[i]) < lv.saturation && double(ew[i]) < lv.saturation) b_ok[i] = eb[i], w_ok[i] = ew[i];
  const double p =
      choose_dop(cfg, lv.dop_min_sum, m, [&] { return estimate_dop(b_ok, w_ok, lv.dop_min_sum, cfg.dop_percentile); });
  const bool separate = p >= cfg.p_min;
  m.p = separate ? p : 0.0;
  for (size_t i = 0; i < eb.size(); ++i) {
    if (!std::isfinite(b_ok[i])) continue;  // clipped: invalid
    if (separate) {
      const SignalBackscatter sb = signal_from_polarized(eb[i], ew[i], p);  // Eq. 5.6
      m.enhanced[i] = sb.signal;
      m.backscatter[i] = sb.backscatter;
    } else {
      m.enhanced[i] = std::max(0.0f, eb[i] + ew[i]);  // no polarisation contrast: S + B
    }
    ++m.valid;
  }
  m.image = std::move(eb);
  sdk::give_map(std::move(b_ok));
  sdk::give_map(std::move(w_ok));
  fill_quality(m, lv, cfg.threads, cfg.all_maps);
  return m;
}

namespace {

nlohmann::json mean_or_null(double sum, size_t n) { return n ? nlohmann::json(sum / double(n)) : nlohmann::json(nullptr); }

// row_stride: the means of Eq. 5.8-5.10 and of `enhanced` are over every
// row_stride-th row (1: every pixel; see quality_row_stride).
nlohmann::json to_json(const QualitySums& t, bool has_gqm, double p, uint32_t row_stride = 1) {
  return {{"cqm_mean", mean_or_null(t.cqm, t.n_cqm)},
          {"gqm_mean", has_gqm ? mean_or_null(t.gqm, t.n_gqm) : nlohmann::json(nullptr)},
          {"snr_weight_mean", mean_or_null(t.w, t.n_w)},
          {"cqm_w_mean", mean_or_null(t.cqm_w, t.n_cqm_w)},
          {"gqm_w_mean", has_gqm ? mean_or_null(t.gqm_w, t.n_gqm_w) : nlohmann::json(nullptr)},
          {"image", to_json(summary_from_sums(t.img, t.img2, t.n_img))},
          {"enhanced", to_json(summary_from_sums(t.enh, t.enh2, t.n_enh))},
          {"dop_used", p},
          {"means_row_stride", row_stride},
          {"means_pixels", t.n_enh}};
}

// fn(y0, y1, sums) over row chunks on `threads` workers; the chunks' sums
// merged in row order. With more than one thread, kChunksPerThread chunks
// per thread, taken dynamically (procam::parallel_bands): a worker that the
// OS preempts or wakes late (another process on its core, even on a "quiet"
// 2-core machine) holds up one chunk while the others take the rest, instead
// of half the image (issue 13: the end of a scan). The sums' grouping
// depends only on the chunk count, never on which thread ran which chunk:
// the report is the same bit for bit from run to run.
constexpr uint32_t kChunksPerThread = 8;
template <class F>
QualitySums for_bands(uint32_t height, uint32_t threads, F&& fn) {
  const uint32_t chunks = threads <= 1 ? std::min(height, 1u) : std::min(height, threads * kChunksPerThread);
  std::vector<QualitySums> sums(chunks);
  procam::parallel_bands(chunks, threads, [&](uint32_t c) {
    QualitySums q;  // local: no false sharing of sums[] while the chunk runs
    fn(static_cast<uint32_t>(uint64_t{height} * c / chunks), static_cast<uint32_t>(uint64_t{height} * (c + 1) / chunks), q);
    sums[c] = q;
  });
  QualitySums t;
  for (const QualitySums& q : sums) t.add(q);
  return t;
}

// Pixel i's outputs from its estimates: enhanced S, backscatter B, and
// Eq. 5.8–5.10 (gqm only when has_gqm, from D and A); NaN where the inputs
// are not finite. Adds the pixel to the report's sums.
inline void finish_pixel(Maps& m, size_t i, float s, float b, float d, float a, bool has_gqm, const Levels& lv,
                         QualitySums& q) {
  m.enhanced[i] = s;
  m.backscatter[i] = b;
  const double im = m.image[i];
  if (std::isfinite(im)) q.img += im, q.img2 += im * im, ++q.n_img;
  float w = kNaN, c = kNaN, g = kNaN;
  if (std::isfinite(s)) {
    q.enh += double(s), q.enh2 += double(s) * double(s), ++q.n_enh;
    w = static_cast<float>(snr_weight(s, lv.mu, lv.z));  // Eq. 5.10
    q.w += double(w), ++q.n_w;
    if (std::isfinite(b)) {
      c = static_cast<float>(cqm(s, b, m.p));  // Eq. 5.8
      q.cqm += double(c), q.cqm_w += double(c) * double(w), ++q.n_cqm, ++q.n_cqm_w;
      if (has_gqm) {
        g = static_cast<float>(gqm(d, a, b, m.p));  // Eq. 5.9
        q.gqm += double(g), q.gqm_w += double(g) * double(w), ++q.n_gqm, ++q.n_gqm_w;
      }
    }
  }
  if (!m.weight.empty()) m.weight[i] = w;
  if (!m.cqm.empty()) m.cqm[i] = c;
  if (!m.gqm.empty()) m.gqm[i] = g;
}

// The per-pixel quality maps, when requested (Config::all_maps).
void take_quality_maps(Maps& m, size_t n, bool has_gqm, bool maps) {
  if (!maps) return;
  for (auto* v : {&m.cqm, &m.weight}) sdk::take_map(*v, n);
  if (has_gqm) sdk::take_map(m.gqm, n);
}

}  // namespace

Maps estimate_striping(const StripeStack& best, const StripeStack* worst, const Config& cfg, const Levels& lv,
                       uint32_t proj_width, StripingPass pass, bool want_col) {
  const uint32_t w = best.width(), h = best.height();
  const size_t n = size_t{w} * h;
  const bool polarised = worst != nullptr;
  Maps m;
  m.width = w;
  m.height = h;
  // Every map is written in full by the pass below (no NaN pre-fill);
  // storage from the map cache. The column map only where it is handed over
  // or triangulated.
  want_col = want_col || cfg.all_maps;
  // The report's quality means (Eq. 5.8-5.10, the enhanced image's mean and
  // contrast) over every qs-th row (quality_row_stride); the maps, the valid
  // count and the composite's summary cover every pixel.
  const uint32_t qs = quality_row_stride(w, h);
  for (auto* v : {&m.enhanced, &m.backscatter, &m.stripe}) sdk::take_map(*v, n);
  if (want_col) sdk::take_map(m.col, n);
  take_quality_maps(m, n, polarised, cfg.all_maps);
  const auto ds = StripeDecodeSettings::make(lv.sigma, cfg.margin_sigma, lv.saturation, best.frames());
  auto unclipped = [&](size_t i) {
    return double(best.top2(i)) < lv.saturation && (!polarised || double(worst->top2(i)) < lv.saturation);
  };
  // The one-pass kernels (striping_pass.hpp) need packed stacks of >= 3
  // frames; everything else takes the general (reference) pass below.
  const bool packed = best.packed() && best.frames() >= 3 &&
                      (!polarised || (worst->packed() && worst->frames() >= 3));
  if (!packed) pass = StripingPass::reference;
  // The composite of a packed scan is a frame value: U8, 1 byte a pixel.
  if (pass != StripingPass::reference) sdk::take_map(m.image_u8, n);
  else sdk::take_map(m.image, n);
  double p = 0;
  bool separate = false;
  if (polarised) {
    // The DOP from both backgrounds (A = 0 where a pixel sees only medium),
    // on the same <= 256k-pixel stride estimate_dop uses, before the pass.
    const double bg_min_sum = background_dop_min_sum(lv, best.frames());
    p = choose_dop(cfg, bg_min_sum, m, [&] {
      const size_t stride = dop_sample_stride(n);
      if (pass != StripingPass::reference) {  // parallel, no serial quantile; the same p bit for bit
        if (best.sample_current() && worst->sample_current())  // the compact copies kept at the last frame
          return packed_dop({best.sample_key1(), best.sample_key2(), best.sample_sum16(), best.frames()},
                            {worst->sample_key1(), worst->sample_key2(), worst->sample_sum16(), worst->frames()},
                            best.sample_size(), 1, lv.saturation, bg_min_sum, cfg.dop_percentile, cfg.threads);
        return packed_dop({best.key1(), best.key2(), best.sum16(), best.frames()},
                          {worst->key1(), worst->key2(), worst->sum16(), worst->frames()}, (n + stride - 1) / stride,
                          stride, lv.saturation, bg_min_sum, cfg.dop_percentile, cfg.threads);
      }
      std::vector<float> sb, sw;
      sb.reserve(n / stride + 1);
      sw.reserve(n / stride + 1);
      for (size_t i = 0; i < n; i += stride)
        if (unclipped(i)) {
          sb.push_back(decode_stripe_pixel(best, i, ds).background);
          sw.push_back(decode_stripe_pixel(*worst, i, ds).background);
        }
      return estimate_dop(sb, sw, bg_min_sum, cfg.dop_percentile);
    });
    separate = p >= cfg.p_min;
    m.p = separate ? p : 0.0;
  }
  // Stripe centres by index, once (index -> projector column).
  std::vector<double> centre(cfg.stripes + 1);
  for (uint32_t k = 0; k < cfg.stripes; ++k) centre[k] = stripe_columns(proj_width, cfg.stripes, cfg.stripe_px, k).centre;
  centre[cfg.stripes] = centre[cfg.stripes - 1];
  std::atomic<size_t> valid{0};
  if (pass != StripingPass::reference) {
    // Packed keys index at most 256 stripes: 257 float centres, padded with the last.
    std::vector<float> centre_f(257, float(centre[cfg.stripes]));
    for (uint32_t k = 0; k < cfg.stripes && k < 257; ++k) centre_f[k] = float(centre[k]);
    const PackedView vb{best.key1(), best.key2(), best.sum16(), best.frames()};
    PackedView vw;
    if (polarised) vw = {worst->key1(), worst->key2(), worst->sum16(), worst->frames()};
    const PassSettings ps{ds.margin_dn, ds.saturation_dn, lv.mu, lv.z, p, separate, centre_f.data()};
    const auto or_null = [](std::vector<float>& v) { return v.empty() ? nullptr : v.data(); };
    PassMaps pm;
    pm.image_u8 = m.image_u8.data();
    pm.enhanced = m.enhanced.data();
    pm.backscatter = m.backscatter.data();
    pm.stripe = m.stripe.data();
    pm.col = or_null(m.col);
    pm.cqm = or_null(m.cqm);
    pm.weight = or_null(m.weight);
    pm.gqm = or_null(m.gqm);
    const PassKernel kernel = pass == StripingPass::scalar ? PassKernel::scalar
                              : pass == StripingPass::avx2 ? PassKernel::avx2
                                                           : PassKernel::best;
    const QualitySums sums = for_bands(h, cfg.threads, [&](uint32_t y0, uint32_t y1, QualitySums& q) {
      // Runs of rows: a sampled row with the quality sums, the rows up to
      // the next sampled one without (every row when qs = 1: one call).
      size_t band_valid = 0;
      for (uint32_t y = y0; y < y1;) {
        const bool sampled = y % qs == 0;
        const uint32_t e = qs == 1 ? y1 : (sampled ? y + 1 : std::min(y1, (y / qs + 1) * qs));
        PassMaps run = pm;
        run.quality = sampled;
        band_valid += striping_pass(vb, polarised ? &vw : nullptr, ps, run, size_t{y} * w, size_t{e} * w, q, kernel);
        y = e;
      }
      valid += band_valid;
    });
    m.valid = valid;
    m.quality = to_json(sums, polarised, m.p, qs);
    return m;
  }
  // One pass per pixel: composite (Eq. 5.7), stripe decision and column,
  //   unpolarised: D^ = rise, B^ = background (A counted in it), S^ = D^;
  //   polarised:   D^ = 2 rise_b, B^/A^ by Eq. 5.6 on the backgrounds, S^ = D^ + A^;
  // then Eq. 5.8–5.10 and the report's sums.
  const QualitySums sums = for_bands(h, cfg.threads, [&](uint32_t y0, uint32_t y1, QualitySums& band_q) {
    size_t band_valid = 0;
    QualitySums unsampled;  // rows off the quality sample: only their composite sums are kept
    for (size_t i = size_t{y0} * w; i < size_t{y1} * w; ++i) {
      QualitySums& q = (i / w) % qs == 0 ? band_q : unsampled;
      const StripePixel px = decode_stripe_pixel(best, i, ds);
      m.image[i] = best.top1(i);
      const bool ok = unclipped(i);
      const bool stripe = px.valid && ok;
      m.stripe[i] = stripe ? px.stripe : kNaN;
      if (want_col) m.col[i] = kNaN;
      if (stripe) {
        const auto k0 = static_cast<uint32_t>(px.stripe);
        const double frac = double(px.stripe) - double(k0);
        if (want_col) m.col[i] = static_cast<float>(centre[k0] + frac * (centre[k0 + 1] - centre[k0]));
        ++band_valid;
      }
      float s = kNaN, b = kNaN, d = kNaN, a = kNaN;
      if (!polarised) {
        b = ok ? px.background : kNaN;
        d = s = stripe ? px.rise : kNaN;
      } else if (ok) {
        const float bw = decode_stripe_pixel(*worst, i, ds).background;
        const SignalBackscatter sb =
            separate ? signal_from_polarized(px.background, bw, p) : SignalBackscatter{0.0f, px.background + bw};
        b = sb.backscatter;
        if (stripe) {
          d = 2.0f * px.rise;  // the best analyser passes half of the depolarised direct light
          a = sb.signal;       // the other sheets' depolarised light on the surface: A
          s = d + a;
        }
      }
      finish_pixel(m, i, s, b, d, a, polarised, lv, q);
    }
    band_q.img += unsampled.img, band_q.img2 += unsampled.img2, band_q.n_img += unsampled.n_img;
    valid += band_valid;
  });
  m.valid = valid;
  m.quality = to_json(sums, polarised, m.p, qs);
  return m;
}

void fill_quality(Maps& m, const Levels& lv, uint32_t threads, bool maps) {
  take_quality_maps(m, m.enhanced.size(), false, maps);
  const uint32_t w = m.width;
  const QualitySums sums = for_bands(m.height, threads, [&](uint32_t y0, uint32_t y1, QualitySums& q) {
    for (size_t i = size_t{y0} * w; i < size_t{y1} * w; ++i)
      finish_pixel(m, i, m.enhanced[i], m.backscatter[i], kNaN, kNaN, false, lv, q);
  });
  m.quality = to_json(sums, false, m.p);
}

}  // namespace procam::polarized_striping
