#include "dynamics/spectrum.h"

#include <algorithm>
#include <cmath>
#include <complex>
#include <numeric>

#include <unsupported/Eigen/FFT>

namespace bistable {

size_t FastFftLength(size_t n) {
  size_t best = 1;
  for (size_t a = 1; a <= n; a *= 2)
    for (size_t b = a; b <= n; b *= 3)
      for (size_t c = b; c <= n; c *= 5) best = std::max(best, c);
  return best;
}

namespace {

// Per-thread caches: sweeps transform thousands of same-length series, and both the Hann window
// (n cosines) and kissfft's twiddle tables (held by the FFT object per length) cost as much as the
// transform itself.
struct FftCache {
  Eigen::FFT<double> fft;
  size_t n = 0;
  std::vector<double> window;
  double window_sum = 0;
  std::vector<double> xw;
  std::vector<std::complex<double>> spectrum;
  FftCache() { fft.SetFlag(Eigen::FFT<double>::HalfSpectrum); }
  void Prepare(size_t len) {
    if (len == n) return;
    n = len;
    window.resize(n);
    window_sum = 0;
    for (size_t i = 0; i < n; ++i) {
      window[i] = 0.5 - 0.5 * std::cos(2.0 * M_PI * static_cast<double>(i) / static_cast<double>(n));
      window_sum += window[i];
    }
    xw.resize(n);
  }
};

FftCache& Cache() {
  thread_local FftCache cache;
  return cache;
}

}  // namespace

namespace {
Eigen::FFT<double>& HalfFft() {
  thread_local Eigen::FFT<double> fft = [] {
    Eigen::FFT<double> f;
    f.SetFlag(Eigen::FFT<double>::HalfSpectrum);
    return f;
  }();
  return fft;
}
Eigen::FFT<double>& FullFft() {
  thread_local Eigen::FFT<double> fft;
  return fft;
}
}  // namespace

void RealFftHalf(const std::vector<double>& x, std::vector<std::complex<double>>* X) { HalfFft().fwd(*X, x); }
void RealFftFull(const std::vector<double>& x, std::vector<std::complex<double>>* X) { FullFft().fwd(*X, x); }
void InverseFftReal(const std::vector<std::complex<double>>& X, std::vector<double>* x) { FullFft().inv(*x, X); }

size_t NextFastFftLength(size_t n) {
  size_t best = SIZE_MAX;
  for (size_t a = 1; a < 2 * n + 2; a *= 2)
    for (size_t b = a; b < 2 * n + 2; b *= 3)
      for (size_t c = b; c < 2 * n + 2; c *= 5)
        if (c >= n) best = std::min(best, c);
  return best;
}

Spectrum AmplitudeSpectrum(const std::vector<double>& x_all, double dt) {
  Spectrum s;
  if (x_all.size() < 4) return s;
  const size_t n = FastFftLength(x_all.size());
  const double* x = x_all.data() + (x_all.size() - n);
  const double mean = std::accumulate(x, x + n, 0.0) / static_cast<double>(n);
  FftCache& c = Cache();
  c.Prepare(n);
  for (size_t i = 0; i < n; ++i) c.xw[i] = (x[i] - mean) * c.window[i];
  const double wsum = c.window_sum;
  std::vector<std::complex<double>>& X = c.spectrum;
  c.fft.fwd(X, c.xw);
  s.d_omega = 2.0 * M_PI / (static_cast<double>(n) * dt);
  s.amp.resize(X.size());
  // |X| as sqrt(re² + im²): the amplitudes are far from overflow, and std::abs (hypot) costs a
  // library call per bin.
  for (size_t k = 0; k < X.size(); ++k) s.amp[k] = 2.0 * std::sqrt(std::norm(X[k])) / wsum;
  return s;
}

double MeanFrequency(const std::vector<double>& x, double dt) {
  const Spectrum s = AmplitudeSpectrum(x, dt);
  double p = 0, fp = 0;
  for (size_t k = 1; k < s.amp.size(); ++k) {
    const double pk = s.amp[k] * s.amp[k];
    p += pk;
    fp += pk * static_cast<double>(k) * s.d_omega / (2.0 * M_PI);
  }
  return p > 0 ? fp / p : 0.0;
}

std::vector<HdPeak> SpectralPeaks(const Spectrum& s, double level, int top_k) {
  std::vector<HdPeak> peaks;
  const size_t n = s.amp.size();
  if (n < 3) return peaks;
  const double top = *std::max_element(s.amp.begin() + 1, s.amp.end());
  if (!(top > 0)) return peaks;
  for (size_t k = 1; k + 1 < n; ++k) {
    const double a = s.amp[k];
    if (a < level * top || a < s.amp[k - 1] || a <= s.amp[k + 1]) continue;
    double delta = 0;
    if (s.amp[k - 1] > 0 && s.amp[k + 1] > 0) {
      const double l0 = std::log(s.amp[k - 1]), l1 = std::log(a), l2 = std::log(s.amp[k + 1]);
      const double den = l0 - 2 * l1 + l2;
      if (den < 0) delta = std::clamp(0.5 * (l0 - l2) / den, -0.5, 0.5);
    }
    peaks.push_back({(static_cast<double>(k) + delta) * s.d_omega, a});
  }
  std::sort(peaks.begin(), peaks.end(), [](const HdPeak& a, const HdPeak& b) { return a.amp > b.amp; });
  if (static_cast<int>(peaks.size()) > top_k) peaks.resize(top_k);
  return peaks;
}

double HarmonicDiffusionIndex(const Spectrum& s, double omega, double tol_bins) {
  double total = 0, off = 0;
  const double tol = tol_bins * s.d_omega;
  for (size_t k = 1; k < s.amp.size(); ++k) {
    const double w = static_cast<double>(k) * s.d_omega;
    const double p = s.amp[k] * s.amp[k];
    // nearbyint, not round: they differ only at exact half-way points, where the distance to the
    // nearest harmonic is the same either way (and nearbyint is one instruction).
    const double nearest = std::nearbyint(w / omega) * omega;
    total += p;
    if (std::fabs(w - nearest) > tol) off += p;
  }
  return total > 0 ? off / total : 0.0;
}

double ToneAmplitude(const double* x, size_t n, double dt, double w) {
  if (n < 4) return 0.0;
  double mean = 0;
  for (size_t i = 0; i < n; ++i) mean += x[i];
  mean /= static_cast<double>(n);
  // The Hann window's and the tone's phasors advance by rotation, re-anchored with sin/cos every
  // kAnchor samples (rounding drift stays ~1e-15; no library call per sample).
  constexpr size_t kAnchor = 64;
  const double a_win = 2.0 * M_PI / static_cast<double>(n), a_ph = w * dt;
  const std::complex<double> r_win = std::polar(1.0, a_win), r_ph = std::polar(1.0, a_ph);
  std::complex<double> z_win, z_ph;
  double re = 0, im = 0, wsum = 0;
  for (size_t i = 0; i < n; ++i) {
    if (i % kAnchor == 0) {
      z_win = std::polar(1.0, a_win * static_cast<double>(i));
      z_ph = std::polar(1.0, a_ph * static_cast<double>(i));
    }
    const double win = 0.5 - 0.5 * z_win.real();
    const double xi = win * (x[i] - mean);
    re += xi * z_ph.real();
    im += xi * z_ph.imag();
    wsum += win;
    z_win *= r_win;
    z_ph *= r_ph;
  }
  return 2.0 * std::hypot(re, im) / wsum;
}

double SubharmonicFraction(const Spectrum& s, double omega, int n, double tol_bins) {
  if (n <= 1) return 0.0;
  const double base = omega / n, tol = tol_bins * s.d_omega;
  double total = 0, sub = 0;
  for (size_t k = 1; k < s.amp.size(); ++k) {
    const double w = static_cast<double>(k) * s.d_omega, p = s.amp[k] * s.amp[k];
    total += p;
    const long j = std::lround(w / base);
    if (j % n != 0 && std::fabs(w - static_cast<double>(j) * base) <= tol) sub += p;
  }
  return total > 0 ? sub / total : 0.0;
}

}  // namespace bistable
