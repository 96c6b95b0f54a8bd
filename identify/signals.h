// Signal processing of sampled records for identification: a cubic spline of the input, smoothed and
// band-limited derivatives, integrals, cutoffs and noise levels. No model here (model.h uses these).
#ifndef BISTABLE_IDENTIFY_SIGNALS_H_
#define BISTABLE_IDENTIFY_SIGNALS_H_

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <vector>

#include "dynamics/lanes.h"  // BISTABLE_INLINE

namespace bistable {

// Natural cubic spline through uniform samples; value and first derivative anywhere in range.
class UniformSpline {
 public:
  UniformSpline() = default;
  UniformSpline(double t0, double dt, std::vector<double> y);
  // Inline: called at every RK4 stage of every simulation (with its divisions, 16 % of the spectral loop's
  // profile when it was out of line).
  BISTABLE_INLINE void Eval(double t, double* value, double* slope) const {
    const size_t n = y_.size();
    if (n <= 1) [[unlikely]] {
      *value = n == 0 ? 0.0 : y_[0], *slope = 0;
      return;
    }
    const double s = (t - t0_) / dt_;
    const long i = std::clamp<long>(static_cast<long>(std::floor(s)), 0, static_cast<long>(n) - 2);
    const double a = s - static_cast<double>(i);  // in [0, 1] inside the range
    const double b = 1.0 - a;
    const double h = dt_;
    const double y0 = y_[i], y1 = y_[i + 1], m0 = m_[i], m1 = m_[i + 1];
    *value = b * y0 + a * y1 + ((b * b * b - b) * m0 + (a * a * a - a) * m1) * h * h / 6.0;
    *slope = dy_[i] + ((-3.0 * b * b + 1.0) * m0 + (3.0 * a * a - 1.0) * m1) * h / 6.0;
  }

 private:
  double t0_ = 0, dt_ = 1;
  std::vector<double> y_, m_;  // samples and second derivatives
  std::vector<double> dy_;     // (y_{i+1} − y_i) / dt per interval
};

// Savitzky–Golay smoothed derivative (order `deriv` 0, 1 or 2) of uniform samples: local cubic fits
// over 2·half+1 samples (one-sided fits at the ends).
std::vector<double> SavitzkyGolay(const std::vector<double>& y, double dt, int half, int deriv);
// Band-limited derivative (order 0, 1, 2) by FFT: mirror-extended (no jump at the ends), multiplied by
// (i2πf)^order and a raised-cosine low-pass that falls from 1 at 0.8 f_cut to 0 at f_cut. Unbiased
// inside the band, unlike local polynomial smoothing at a few samples per period.
std::vector<double> SpectralDerivative(const std::vector<double>& y, double dt, int order, double f_cut_hz);
// A cutoff for SpectralDerivative: four times the frequency below which 99.9 % of the signal's power lies
// (harmonics of the response carry the nonlinear terms), at most 0.45 of the sampling rate.
double AutoCutoff(const std::vector<double>& y, double dt);
// The drive's band edge [Hz] for an input record (PreparedRecord::f_drive): the SpectralDerivative cutoff
// (order 0) whose flat part ends at twice the highest frequency where the input's power spectrum (Hann
// periodogram, 7-bin moving average) stands 10× above its own white noise floor (NoiseLevel's: the median
// above AutoCutoff). 0 — no band limit — when the cut would take away more than 1 % of the input's power
// (then what lies above it is not noise, or no floor was found), the band reaches 0.9 of Nyquist, or the
// floor is more than 120 dB below the input (roundoff of a computed input).
double DriveCutoff(const std::vector<double>& input, double dt);
// Zero-mean integral of a sampled signal by FFT (1/(iω) per bin, DC and bins below f_min dropped):
// base velocity from base acceleration, displacement from velocity.
std::vector<double> IntegrateFft(const std::vector<double>& y, double dt, double f_min_hz);

// A noise level of a sampled signal: the spectral floor, σ = sqrt(median Hann-windowed periodogram /
// ln 2 / Σ w²) over the bins above min(AutoCutoff, 0.6 × Nyquist) (white noise's power is flat; the
// signal's lies below the cutoff). Per-output weights of a joint fit come from it.
double NoiseLevel(const std::vector<double>& y, double dt);

}  // namespace bistable

#endif  // BISTABLE_IDENTIFY_SIGNALS_H_
