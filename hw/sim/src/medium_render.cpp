// SPDX-License-Identifier: MIT
// Per-frame backscatter of a participating medium: row prefix sums of the
// sharp emitted pattern, the sparse gather over each pixel's chunks
// (medium.hpp MediumChunk) and the polariser/analyser combination.
//
// Polarization (thesis appendix, Eq. 5.35-5.36, with U): per pixel the chunk
// sum S0 = Σ v (v a chunk's intensity share) and S1 = m12·S0, S2 = m33·S0
// (m12, m33 the pixel's normalised Mueller entries, MediumTaps) give the
// scattered Stokes vector
// for incident light of Stokes angle χ (polariser; unpolarized: no χ terms):
//   I = S0 + cos2χ·S1,   Q = S1 + m22·cos2χ·S0,   U = sin2χ·S2,
// and an ideal analyser at Stokes angle φ passes (I + Q cos2φ + U sin2φ)/2
// (Malus' law for partially polarized light). Without an analyser: I.
// Multiple scattering (MediumTaps::ms_*), when on, adds I_ms: its share
// ms_keep joins S0 (polarized like single scattering), the rest is
// depolarized (all of it through no analyser, half through one).
// The projector polariser is assumed to pass the projector's full intensity
// (an LCD projector's light is already polarized), so B and D keep their
// unpolarized magnitudes; see docs/media.md.
#include <algorithm>
#include <cmath>

#include "medium.hpp"
#include "parallel.hpp"

namespace procam::sim {
namespace detail {

void RowPrefix::build(const PreparedPattern& pattern, int threads) {
  width = pattern.width();
  height = pattern.height();
  stride = pattern.stride();
  level0 = pattern.level(0);
  const size_t w1 = size_t{width} + 1;
  c.resize(w1 * height);
  m.resize(w1 * height);
  parallel_rows(height, threads, [&](uint32_t b, uint32_t e) {
    for (uint32_t r = b; r < e; ++r) {
      const float* p = level0 + (size_t{r} + 1) * stride + 1;
      double* cr = c.data() + size_t{r} * w1;
      double* mr = m.data() + size_t{r} * w1;
      double sc = 0, sm = 0;
      cr[0] = mr[0] = 0;
      for (uint32_t k = 0; k < width; ++k) {
        const double ek = static_cast<double>(p[k]);
        sc += ek;
        sm += static_cast<double>(k) * ek;
        cr[k + 1] = sc;
        mr[k + 1] = sm;
      }
    }
  });
}

double RowPrefix::sum(const MediumTaps& taps, size_t i) const {
  double s0 = 0;
  const size_t w1 = size_t{width} + 1;
  const int kmax = static_cast<int>(width) - 1;
  // ∫_{−1/2}^{x} e and ∫_{−1/2}^{x} x' e along row r over box pixels (pixel k spans [k − ½, k + ½)).
  auto at = [&](int32_t r, double x, double& cx, double& mx) {
    const double* cr = c.data() + static_cast<size_t>(r) * w1;
    const double* mr = m.data() + static_cast<size_t>(r) * w1;
    const float* p = level0 + (static_cast<size_t>(r) + 1) * stride + 1;
    const double t = x + 0.5;
    const int k = std::clamp(static_cast<int>(t), 0, kmax);
    const double f = t - k, e = static_cast<double>(p[k]), xl = k - 0.5;
    cx = cr[k] + f * e;
    mx = mr[k] + e * 0.5 * (x * x - xl * xl);
  };
  // Consecutive chunks of a ray usually share an end (same row, x_hi = next
  // x_lo): the last end's integrals are reused.
  int32_t last_row = -1;
  float last_x = 0;
  double last_c = 0, last_m = 0;
  for (uint32_t j = taps.offset[i]; j < taps.offset[i + 1]; ++j) {
    const MediumChunk& ch = taps.chunks[j];
    double c0 = 0, m0 = 0, c1 = 0, m1 = 0;
    const double xlo = static_cast<double>(ch.x_lo), xhi = static_cast<double>(ch.x_hi);
    const bool from_lo = ch.row == last_row && ch.x_lo == last_x;
    if (from_lo || (ch.row == last_row && ch.x_hi == last_x)) {
      const float x_new = from_lo ? ch.x_hi : ch.x_lo;
      double c_new = 0, m_new = 0;
      at(ch.row, static_cast<double>(x_new), c_new, m_new);
      (from_lo ? c0 : c1) = last_c;
      (from_lo ? m0 : m1) = last_m;
      (from_lo ? c1 : c0) = c_new;
      (from_lo ? m1 : m0) = m_new;
      last_x = x_new;
      last_c = c_new;
      last_m = m_new;
    } else {
      at(ch.row, xlo, c0, m0);
      at(ch.row, xhi, c1, m1);
      last_row = ch.row;
      // The ray runs towards +x or −x in the projector: keep the end the next chunk starts from.
      const bool up = j + 1 < taps.offset[i + 1] && taps.chunks[j + 1].x_lo == ch.x_hi;
      last_x = up ? ch.x_hi : ch.x_lo;
      last_c = up ? c1 : c0;
      last_m = up ? m1 : m0;
    }
    const double dc = c1 - c0, xc = 0.5 * (xlo + xhi);
    s0 += static_cast<double>(ch.a) * dc + static_cast<double>(ch.b) * ((m1 - m0) - xc * dc);
  }
  return s0;
}

void multiple_scattering(const MediumTaps& taps, const RowPrefix& prefix, std::vector<float>& single,
                         std::vector<float>& ms, std::vector<float>& tmp, int threads) {
  const size_t n = taps.pixel_count();
  single.assign(n, 0.f);
  ms.assign(n, 0.f);
  if (taps.ms_gain.size() != n) return;
  parallel_rows(taps.height, threads, [&](uint32_t b, uint32_t e) {
    for (size_t i = size_t{b} * taps.width; i < size_t{e} * taps.width; ++i)
      if (taps.offset[i] != taps.offset[i + 1]) single[i] = static_cast<float>(prefix.sum(taps, i));
  });
  ms = single;
  gaussian_blur3(ms, tmp, taps.width, taps.height, taps.ms_sigma_px, threads);
  for (size_t i = 0; i < n; ++i) ms[i] *= taps.ms_gain[i];
}

}  // namespace detail

namespace {

// cos 2·deg and sin 2·deg of a device angle in degrees (once per frame).
struct Angle2 {
  double c = 0, s = 0;
  explicit Angle2(double deg) : c(std::cos(deg * M_PI / 90.0)), s(std::sin(deg * M_PI / 90.0)) {}
};

// cos2χ, sin2χ of a device angle through a pixel's angle map (medium.hpp).
void stokes_angle(const float* k, const Angle2& a, double& c2, double& s2) {
  const double ca = a.c, sa = a.s;
  c2 = static_cast<double>(k[0]) * ca + static_cast<double>(k[1]) * sa;
  s2 = static_cast<double>(k[2]) * ca + static_cast<double>(k[3]) * sa;
}

}  // namespace

void MediumComponent::begin_frame(const FrameContext& frame, int threads) {
  prefix_.build(frame.pattern, threads);
  const MediumTaps& t = *taps_;
  if (!t.ms_gain.empty() && t.width == frame.view.width && t.proj_width == prefix_.width &&
      t.proj_height == prefix_.height)
    detail::multiple_scattering(t, prefix_, single_, ms_, tmp_, threads);
  else
    ms_.clear();
}

void MediumComponent::apply(const FrameContext& frame, uint32_t row_begin, uint32_t row_end, float* radiance) const {
  const MediumTaps& t = *taps_;
  if (t.width != frame.view.width || t.proj_width != prefix_.width || t.proj_height != prefix_.height) return;
  const bool pol_in = std::isfinite(frame.projector_polarizer_deg) && t.polarizing;
  const bool analyser = std::isfinite(frame.analyser_deg);
  const size_t b = size_t{row_begin} * t.width, e = size_t{row_end} * t.width;
  const Angle2 pol(pol_in ? frame.projector_polarizer_deg : 0.0), ana(analyser ? frame.analyser_deg : 0.0);
  const bool multiple = ms_.size() == t.pixel_count();
  // Multiple-scattered light is depolarized: an ideal analyser passes half.
  const double ms_pass = analyser ? 0.5 : 1.0;
  for (size_t i = b; i < e; ++i) {
    // B_ms: its share ms_keep polarized like single scattering (joins S),
    // the rest depolarized.
    const double ms = multiple ? static_cast<double>(ms_[i]) : 0.0;
    radiance[i] += static_cast<float>(ms_pass * (1.0 - t.ms_keep) * ms);
    if (t.offset[i] == t.offset[i + 1] && !(ms > 0)) continue;
    const double s0 = (multiple ? static_cast<double>(single_[i]) : prefix_.sum(t, i)) + t.ms_keep * ms;
    const double s1 = s0 * static_cast<double>(t.m12[i]), s2 = s0 * static_cast<double>(t.m33[i]);
    double c2x = 0, s2x = 0;
    if (pol_in) stokes_angle(&t.pol_proj[4 * i], pol, c2x, s2x);
    const double I = s0 + c2x * s1;
    double out = I;
    if (analyser) {
      const double Q = s1 + t.m22 * c2x * s0, U = s2x * s2;
      double c2p = 0, s2p = 0;
      if (t.polarizing) stokes_angle(&t.pol_cam[4 * i], ana, c2p, s2p);
      out = 0.5 * (I + Q * c2p + U * s2p);
    }
    radiance[i] += static_cast<float>(out);
  }
}

BackscatterStokes backscatter_stokes(const MediumTaps& taps, const PreparedPattern& pattern, double projector_deg,
                                     int threads) {
  BackscatterStokes st;
  const size_t n = taps.pixel_count();
  st.i.assign(n, 0.f);
  st.q.assign(n, 0.f);
  st.u.assign(n, 0.f);
  st.i_multiple.assign(n, 0.f);
  if (pattern.width() != taps.proj_width || pattern.height() != taps.proj_height) return st;
  detail::RowPrefix prefix;
  prefix.build(pattern, threads);
  std::vector<float> single, tmp;
  detail::multiple_scattering(taps, prefix, single, st.i_multiple, tmp, threads);
  const bool pol_in = std::isfinite(projector_deg) && taps.polarizing;
  const Angle2 pol(pol_in ? projector_deg : 0.0);
  detail::parallel_rows(taps.height, threads, [&](uint32_t b, uint32_t e) {
    for (size_t i = size_t{b} * taps.width; i < size_t{e} * taps.width; ++i) {
      const double ms = static_cast<double>(st.i_multiple[i]);
      const double s0 = prefix.sum(taps, i) + taps.ms_keep * ms;
      const double s1 = s0 * static_cast<double>(taps.m12[i]), s2 = s0 * static_cast<double>(taps.m33[i]);
      double c2x = 0, s2x = 0;
      if (pol_in) stokes_angle(&taps.pol_proj[4 * i], pol, c2x, s2x);
      st.i[i] = static_cast<float>(s0 + c2x * s1 + (1.0 - taps.ms_keep) * ms);
      st.q[i] = static_cast<float>(s1 + taps.m22 * c2x * s0);
      st.u[i] = static_cast<float>(s2x * s2);
    }
  });
  return st;
}

}  // namespace procam::sim
