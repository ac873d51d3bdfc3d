// SPDX-License-Identifier: MIT
// End-of-scan estimates of S, B, p, the stripe map and the quality measures
// (see estimate.hpp; thesis Eq. 5.4–5.10).
#include "estimate.hpp"

#include <algorithm>
#include <atomic>
#include <map>
#include <mutex>
#include <cmath>

#include "media_model.hpp"
#include "procam/sdk/map_cache.hpp"

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

// p given (>= 0) or estimated; records how in m.dop.
double choose_dop(const Config& cfg, std::span<const float> best, std::span<const float> worst, const Levels& lv,
                  Maps& m) {
  double p = cfg.p;
  if (p >= 0) {
    m.dop = {{"source", "param p"}, {"value", p}};
  } else {
    p = estimate_dop(best, worst, lv.dop_min_sum, cfg.dop_percentile);
    m.dop = {{"source", "estimated"},
             {"rule", "quantile dop_percentile of (E_w - E_b) / (E_w + E_b) over pixels with E_w + E_b > 40 noise "
                      "sigma; equals p where a pixel sees only medium, less where it sees an object"},
             {"min_sum_dn", lv.dop_min_sum},
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
  fill_quality(m, {}, {}, lv, cfg.threads);
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
  const double p = choose_dop(cfg, b_ok, w_ok, lv, m);
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
  fill_quality(m, {}, {}, lv, cfg.threads);
  return m;
}

Maps estimate_striping(const StripeStack& best, const StripeStack* worst, const Config& cfg, const Levels& lv,
                       uint32_t proj_width) {
  const uint32_t w = best.width(), h = best.height();
  const size_t n = size_t{w} * h;
  Maps m;
  m.width = w;
  m.height = h;
  // Every map below is written in full by the loops (no NaN pre-fill pass);
  // storage from the map cache.
  for (auto* v : {&m.image, &m.enhanced, &m.backscatter, &m.stripe, &m.col}) sdk::take_map(*v, n);
  std::vector<float> d, a, bg_b, bg_w;  // scratch, given back on return
  struct GiveBack {
    std::vector<float>* v[4];
    ~GiveBack() {
      for (auto* x : v)
        if (!x->empty()) sdk::give_map(std::move(*x));
    }
  } give_back{{&d, &a, &bg_b, &bg_w}};
  for (auto* v : {&d, &bg_b}) sdk::take_map(*v, n);
  const auto ds = StripeDecodeSettings::make(lv.sigma, cfg.margin_sigma, lv.saturation, best.frames());
  // Stripe centres by index, once (index -> projector column).
  std::vector<double> centre(cfg.stripes + 1);
  for (uint32_t k = 0; k < cfg.stripes; ++k) centre[k] = stripe_columns(proj_width, cfg.stripes, cfg.stripe_px, k).centre;
  centre[cfg.stripes] = centre[cfg.stripes - 1];
  const bool polarised = worst != nullptr;
  std::atomic<size_t> valid{0};
  // Pass 1, per pixel: composite (Eq. 5.7), stripe decision, column, D^;
  // unpolarised: B^ = background (A counted in it), S^ = D^.
  sdk::parallel_rows(h, cfg.threads, [&](uint32_t y0, uint32_t y1) {
    size_t band_valid = 0;
    for (size_t i = size_t{y0} * w; i < size_t{y1} * w; ++i) {
      const StripePixel px = decode_stripe_pixel(best, i, ds);
      m.image[i] = best.top1(i);
      bg_b[i] = px.background;
      m.stripe[i] = px.stripe;  // NaN when invalid
      m.col[i] = kNaN;
      d[i] = kNaN;
      if (px.valid) {
        const auto k0 = static_cast<uint32_t>(px.stripe);
        const double frac = double(px.stripe) - double(k0);
        m.col[i] = static_cast<float>(centre[k0] + frac * (centre[k0 + 1] - centre[k0]));
        d[i] = px.rise;
        ++band_valid;
      }
      if (!polarised) {
        m.backscatter[i] = double(best.top2(i)) < lv.saturation ? bg_b[i] : kNaN;  // every unclipped pixel
        m.enhanced[i] = d[i];
      }
    }
    valid += band_valid;
  });
  m.valid = valid;
  if (!polarised) {
    fill_quality(m, {}, {}, lv, cfg.threads);
    return m;
  }
  // Pass 2: the worst analyser's background where neither is clipped (bg_b
  // NaN elsewhere too, for the DOP estimate).
  sdk::take_map(bg_w, n);
  sdk::parallel_rows(h, cfg.threads, [&](uint32_t y0, uint32_t y1) {
    for (size_t i = size_t{y0} * w; i < size_t{y1} * w; ++i) {
      if (double(worst->top2(i)) < lv.saturation && double(best.top2(i)) < lv.saturation) {
        bg_w[i] = decode_stripe_pixel(*worst, i, ds).background;
      } else {
        bg_w[i] = kNaN;
        bg_b[i] = kNaN;
      }
    }
  });
  const double p = choose_dop(cfg, bg_b, bg_w, lv, m);
  const bool separate = p >= cfg.p_min;
  m.p = separate ? p : 0.0;
  // Pass 3: B^, A^ by Eq. 5.6 on the backgrounds; D^ = 2 rise; S^ = D^ + A^.
  sdk::take_map(a, n);
  std::atomic<size_t> dropped{0};
  sdk::parallel_rows(h, cfg.threads, [&](uint32_t y0, uint32_t y1) {
    size_t band_dropped = 0;
    for (size_t i = size_t{y0} * w; i < size_t{y1} * w; ++i) {
      a[i] = m.enhanced[i] = m.backscatter[i] = kNaN;
      if (!std::isfinite(bg_w[i])) {  // a clipped background: no estimate, no stripe
        if (std::isfinite(m.stripe[i])) ++band_dropped, m.stripe[i] = m.col[i] = d[i] = kNaN;
        continue;
      }
      const SignalBackscatter sb =
          separate ? signal_from_polarized(bg_b[i], bg_w[i], p) : SignalBackscatter{0.0f, bg_b[i] + bg_w[i]};
      m.backscatter[i] = sb.backscatter;
      if (!std::isfinite(m.stripe[i])) continue;
      d[i] = 2.0f * d[i];  // the best analyser passes half of the depolarised direct light
      a[i] = sb.signal;    // the other sheets' depolarised light on the surface: A
      m.enhanced[i] = d[i] + a[i];
    }
    dropped += band_dropped;
  });
  m.valid -= dropped;
  fill_quality(m, d, a, lv, cfg.threads);
  return m;
}

void fill_quality(Maps& m, const std::vector<float>& d, const std::vector<float>& a, const Levels& lv,
                  uint32_t threads) {
  const size_t n = m.enhanced.size();
  for (auto* v : {&m.cqm, &m.weight}) sdk::take_map(*v, n);
  if (!d.empty()) sdk::take_map(m.gqm, n);
  const uint32_t w = m.width;
  sdk::parallel_rows(m.height, threads, [&](uint32_t y0, uint32_t y1) {
    for (size_t i = size_t{y0} * w; i < size_t{y1} * w; ++i) {
      const float s = m.enhanced[i], b = m.backscatter[i];
      m.cqm[i] = m.weight[i] = kNaN;
      if (!d.empty()) m.gqm[i] = kNaN;
      if (!std::isfinite(s)) continue;
      m.weight[i] = static_cast<float>(snr_weight(s, lv.mu, lv.z));              // Eq. 5.10
      if (!std::isfinite(b)) continue;                                           // B unknown
      m.cqm[i] = static_cast<float>(cqm(s, b, m.p));                             // Eq. 5.8
      if (!d.empty()) m.gqm[i] = static_cast<float>(gqm(d[i], a[i], b, m.p));    // Eq. 5.9
    }
  });
}

namespace {

// Sums for the report, over one band of rows; merged in band order so the
// report is the same bit for bit from run to run.
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

nlohmann::json mean_or_null(double sum, size_t n) { return n ? nlohmann::json(sum / double(n)) : nlohmann::json(nullptr); }


}  // namespace

nlohmann::json quality_report(const Maps& m, uint32_t threads) {
  const bool has_gqm = !m.gqm.empty();
  std::map<uint32_t, QualitySums> bands;  // by first row
  std::mutex mu;
  sdk::parallel_rows(m.height, threads, [&](uint32_t y0, uint32_t y1) {
    QualitySums q;
    for (size_t i = size_t{y0} * m.width; i < size_t{y1} * m.width; ++i) {
      const double w = m.weight[i], c = m.cqm[i], im = m.image[i], e = m.enhanced[i];
      if (std::isfinite(im)) q.img += im, q.img2 += im * im, ++q.n_img;
      if (std::isfinite(e)) q.enh += e, q.enh2 += e * e, ++q.n_enh;
      if (std::isfinite(w)) q.w += w, ++q.n_w;
      if (std::isfinite(c)) q.cqm += c, ++q.n_cqm;
      if (std::isfinite(c) && std::isfinite(w)) q.cqm_w += c * w, ++q.n_cqm_w;
      if (has_gqm) {
        const double g = m.gqm[i];
        if (std::isfinite(g)) q.gqm += g, ++q.n_gqm;
        if (std::isfinite(g) && std::isfinite(w)) q.gqm_w += g * w, ++q.n_gqm_w;
      }
    }
    const std::lock_guard lock(mu);
    bands[y0] = q;
  });
  QualitySums t;
  for (const auto& [y0, q] : bands) t.add(q);
  return {{"cqm_mean", mean_or_null(t.cqm, t.n_cqm)},
          {"gqm_mean", has_gqm ? mean_or_null(t.gqm, t.n_gqm) : nlohmann::json(nullptr)},
          {"snr_weight_mean", mean_or_null(t.w, t.n_w)},
          {"cqm_w_mean", mean_or_null(t.cqm_w, t.n_cqm_w)},
          {"gqm_w_mean", has_gqm ? mean_or_null(t.gqm_w, t.n_gqm_w) : nlohmann::json(nullptr)},
          {"image", to_json(summary_from_sums(t.img, t.img2, t.n_img))},
          {"enhanced", to_json(summary_from_sums(t.enh, t.enh2, t.n_enh))},
          {"dop_used", m.p}};
}

}  // namespace procam::polarized_striping
