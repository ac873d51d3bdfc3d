// SPDX-License-Identifier: MIT
// Fitting sigma, g and beta to an HDR image of the tank (thesis §4.3, Eq. 4.4–4.7; M2, M5).
//
// 1. radial_profile(): the image depends on (x, y) only through the lateral
//    distance rho to the bulb (orthographic view, scatter_model.hpp), so the
//    valid pixels (inside the ROI, outside the bulb's own image) are binned
//    by rho (a bin holding a NaN = saturated pixel is dropped: its other
//    pixels are the darker, noise-selected part of a saturated ring): 1-px bins up to 100 px, then bins 1 % of rho
//    wide. A bin keeps its pixel count n, mean rho and mean and spread of the
//    radiance. Sum_bins n (mean - f(rho))^2 equals the full-pixel sum of
//    squares minus the within-bin variance (a constant) up to the model's
//    variation inside a bin (< 1e-4 relative at these widths): the fit on
//    bins is the full-pixel least-squares fit, with ~400 terms instead of 1 M.
//    The model's bin value is its mean over the bin, to second order:
//    (K(rho - sd) + K(rho + sd)) / 2 with rho, sd the bin's pixel mean and
//    spread (in the 1-px bins near the bulb, where K ~ 1 / rho curves most;
//    K(rho) alone would bias sigma by ~1 %).
// 2. sigma and g minimise the normalised error of Eq. 4.6–4.7
//    (objective = normalized: E / max E - K / max K, maxima over the bins'
//    means) or, optionally, with beta I0 profiled out exactly
//    (objective = profiled: E - s K, s the least-squares scale; the elimination
//    Eq. 4.6 approximates, immune to the noise on max E).
//    Search: Nelder–Mead in (ln sigma, atanh g), which makes both unbounded
//    and about equally sensitive, started from the best three nodes of a
//    10 x 10 grid (sigma log-spaced over [sigma_min, sigma_max], g over
//    [-0.6, 0.99]) so a start in a far valley is not needed; the thesis uses
//    NM (fminsearch) from random starts and finds one minimum (§4.3.2).
// 3. beta I0 by linear least squares on Eq. 4.4–4.5 at the optimum; beta =
//    that / I0 (I0 from FitSettings: source_intensity, or water_radiance x
//    pi R^2 for a Lambertian sphere of radius R; else beta stays relative).
// 4. M5: if g > legendre_above_g, the fit is redone with the truncated Legendre
//    expansion of H-G (§4.3.3) and kept when its objective is not worse (the
//    truncated series rings in the tail, so on media that H-G does describe it
//    fits worse and H-G stays; the report says which and why). If beta is not significant (below 1.96 of its
//    standard error) or beta / sigma < absorber_albedo, the medium is a pure
//    absorber: g is undefined, beta = 0, and kappa = sigma comes from the
//    attenuation of the bulb's direct image against its pure-water radiance
//    (Eq. 4.3 with radiance: E_bulb = W exp(-sigma l), l the path from the
//    bulb's front surface to the front face).
// 5. 95 % confidence intervals by the delta method over the bins' means:
//    cov(sigma, g, beta I0) = sum_j a_j a_j^T var(mean_j), a_j the
//    derivative of the estimate with respect to bin j's mean (for the
//    normalized objective by the implicit-function theorem, including the
//    brightest bin's role as Eq. 4.6's normaliser: its noise shifts every
//    normalised sample together), var(mean_j) the pixel variance measured
//    inside bin j (less the model's own slope across it) over its n. If the
//    profile's residuals exceed that noise (chi^2 per degree of freedom > 1),
//    the variances are scaled up by it. Assumes independent pixel noise and
//    an exact I0; see parameter_covariance() in fit.cpp.
//
// Units: radiance in DN/us, rho in px and mm, sigma/beta/kappa in 1/mm.
// Threads: pure functions; call from any thread. Errors: FitResult::error
// says what was wrong and what to do (no exceptions).
#pragma once

#include <cstdint>
#include <limits>
#include <string>
#include <vector>

#include "scatter_model.hpp"

namespace procam::medium {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

enum class Objective { normalized, profiled };

// Pixel weights of the objective. uniform: the thesis's least squares (every
// pixel counts the same; under shot or multiplicative noise the bright pixels
// next to the bulb, noisiest in absolute terms, dominate). noise: each bin's
// squared residual is divided by its pixel noise variance from the stated
// model  var(E) = (noise_relative E)^2 + noise_shot E + noise_read^2  (E in
// DN/us; noise_read 0 = 10^-3 of the brightest bin, so a black bin never gets
// an infinite weight), evaluated at the bin's mean radiance (averaged over the
// bin's pixels, so its own noise barely moves its weight). Generalised least
// squares; the reported errors (rms_percent, rms_normalized_percent: Eq.
// 4.6-4.7) stay unweighted.
enum class Weights { uniform, noise };

struct FitSettings {
  TankGeometry tank;
  double bulb_x_px = 0, bulb_y_px = 0;  // the bulb centre's image (pixel centres at integers)
  double mm_per_px = 1;                 // image scale at the tank (orthographic)
  double bulb_radius_mm = 0;            // 0 = point source
  double mask_radius_px = 10;           // pixels closer than this to the bulb centre are not fitted
  int32_t roi_x0 = 0, roi_y0 = 0, roi_x1 = -1, roi_y1 = -1;  // inclusive pixel box; -1 = image edge
  Objective objective = Objective::normalized;
  Weights weights = Weights::uniform;
  double noise_relative = 0.03;  // multiplicative part (fraction; an HDR merge of a geometric bracket is ~this)
  double noise_shot = 0;         // shot part: variance per unit radiance, DN/us
  double noise_read = 0;         // read/floor part, DN/us; 0 = 1e-3 of the brightest bin
  double sigma_min = 1e-4, sigma_max = 0.2;  // 1/mm: the search range
  double legendre_above_g = 0.95;
  int legendre_terms = 99;
  double absorber_albedo = 0.01;        // beta / sigma below this: pure absorber
  double source_intensity = 0;          // I0 (DN/us mm^2); 0 = from water_radiance, or relative
  double water_radiance = 0;            // bulb's direct radiance in pure water (DN/us); 0 = unknown
  // Bins whose mean radiance is below this (DN/us) are not fitted: dark in
  // every exposure, their merged value is biased by the camera's clip at
  // black (radial_profile). 0 = fit every bin (radiance not from a bracket).
  double min_bin_radiance = 0;
};

struct Bin {
  double rho_px = 0, rho_mm = 0;  // mean over the bin's pixels
  double rho_sd_px = 0;           // standard deviation of rho over the bin's pixels
  double mean = 0, sumsq_dev = 0; // radiance mean and sum of squared deviations from it
  // Pixel noise variance inside the bin: the radiance's residual variance
  // about a least-squares quadratic in rho over the bin's pixels (RSS / (n - 3)),
  // so the profile's own fall-off across the bin (~3 % of K over a 1-px ring
  // next to the bulb) is not counted as noise; NaN when the bin has < 8
  // pixels (step 5 then takes a neighbour's).
  double noise_var = kNaN;
  uint64_t n = 0;
};

struct RadialProfile {
  std::vector<Bin> bins;
  uint64_t pixels = 0;      // fitted pixels
  uint64_t bins_dropped = 0;  // rings with a NaN (saturated) pixel: not fitted
  uint64_t bins_dark = 0;     // rings darker than FitSettings::min_bin_radiance: not fitted
  uint64_t pixels_dark = 0;   // their pixels
  double within_ss = 0;     // sum of bins' sumsq_dev
};

RadialProfile radial_profile(const std::vector<float>& radiance, uint32_t width, uint32_t height, const FitSettings& s);

struct Estimate {
  double value = kNaN, ci95 = kNaN;  // ci95: half-width of the 95 % interval
};

struct FitResult {
  std::string error;  // empty when the fit ran
  Estimate sigma, beta, g, kappa;
  bool g_defined = true, beta_absolute = false;
  Phase phase = Phase::henyey_greenstein;
  std::string model = "henyey_greenstein", model_reason;
  double scale = kNaN;                   // beta I0 (DN/us mm^2 ... the LS scale of the unit model)
  double source_intensity = kNaN;        // I0 used
  double rms_percent = kNaN;             // profile RMS / mean radiance x 100
  double rms_normalized_percent = kNaN;  // RMS of Eq. 4.6 over pixels x 100
  double objective = kNaN;
  double legendre_objective = kNaN;      // the truncated-Legendre refit's objective, when tried
  int evaluations = 0;
  std::vector<double> fit;               // scale x K at each bin
  std::vector<std::string> notes;
};

// Nelder–Mead from one start (sigma0, g0) with phase `phase`: the minimum of
// the objective in (ln sigma, atanh g). For the random-start test and the polish.
struct Minimum {
  double sigma = kNaN, g = kNaN, objective = kNaN;
  int evaluations = 0;
};
Minimum minimise_from(const RadialProfile& p, const FitSettings& s, Phase phase, double sigma0, double g0);

// The whole fit (steps 2–5) on a profile; `radiance` is used only for the
// pure-absorber attenuation (the bulb's direct image).
FitResult fit_profile(const RadialProfile& p, const FitSettings& s, const std::vector<float>& radiance, uint32_t width,
                      uint32_t height);

// Mean radiance of the bulb's direct image: pixels within R/2 of its centre
// (1 px for a point source), finite and > 0; NaN if none.
double bulb_radiance(const FitSettings& s, const std::vector<float>& radiance, uint32_t width, uint32_t height);

// sigma from the attenuation of the bulb's direct image against its
// pure-water radiance W (Eq. 4.3 with radiance: E = W exp(-sigma l), l the
// path from the bulb's front surface, B - sqrt(R^2 - s^2), to the front
// face): least squares through the origin on ln(W / E) = sigma l over the
// bulb's central pixels; ci95 from their spread. On failure `why` says why.
Estimate sigma_from_attenuation(const FitSettings& s, double water_radiance, const std::vector<float>& radiance,
                                uint32_t width, uint32_t height, std::string& why);

// The fitted model at every pixel (DN/us), NaN inside the mask radius; for
// the residual map.
std::vector<float> model_image(const FitResult& r, const FitSettings& s, uint32_t width, uint32_t height);

}  // namespace procam::medium
