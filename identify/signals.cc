#include "identify/signals.h"

#include <algorithm>
#include <cmath>
#include <complex>
#include <vector>

#include <Eigen/Dense>

#include "dynamics/spectrum.h"

namespace bistable {

UniformSpline::UniformSpline(double t0, double dt, std::vector<double> y) : t0_(t0), dt_(dt), y_(std::move(y)) {
  const size_t n = y_.size();
  m_.assign(n, 0.0);
  dy_.assign(n, 0.0);
  for (size_t i = 0; i + 1 < n; ++i) dy_[i] = (y_[i + 1] - y_[i]) / dt;
  if (n < 3) return;
  // Natural spline: M_0 = M_{n-1} = 0; M_{i-1} + 4 M_i + M_{i+1} = 6 (y_{i+1} − 2 y_i + y_{i-1}) / dt².
  std::vector<double> c(n, 0.0), d(n, 0.0);
  for (size_t i = 1; i + 1 < n; ++i) {
    const double rhs = 6.0 * (y_[i + 1] - 2.0 * y_[i] + y_[i - 1]) / (dt * dt);
    const double denom = 4.0 - (i > 1 ? c[i - 1] : 0.0);
    c[i] = 1.0 / denom;
    d[i] = (rhs - (i > 1 ? d[i - 1] : 0.0)) / denom;
  }
  for (size_t i = n - 2; i >= 1; --i) {
    m_[i] = d[i] - c[i] * m_[i + 1];
    if (i == 1) break;
  }
}

std::vector<double> SavitzkyGolay(const std::vector<double>& y, double dt, int half, int deriv) {
  const long n = static_cast<long>(y.size());
  std::vector<double> out(n, 0.0);
  if (n == 0) return out;
  const int order = 3;
  half = std::max(half, 2);
  const long w = std::min<long>(2 * half + 1, n);
  // For each window position (offset of the evaluation point within the window), the row of
  // (AᵀA)⁻¹Aᵀ giving the derivative of the local polynomial at that point.
  auto weights = [&](long offset) {
    const int p = static_cast<int>(std::min<long>(order, w - 1));
    Eigen::MatrixXd A(w, p + 1);
    for (long i = 0; i < w; ++i)
      for (int k = 0; k <= p; ++k) A(i, k) = std::pow(static_cast<double>(i - offset), k);
    const Eigen::MatrixXd pinv = (A.transpose() * A).ldlt().solve(A.transpose());
    Eigen::VectorXd row = Eigen::VectorXd::Zero(w);
    if (deriv <= p) row = pinv.row(deriv).transpose() * (deriv == 2 ? 2.0 : 1.0);
    return row;
  };
  const long hw = w / 2;
  const Eigen::VectorXd centre = weights(hw);
  const double scale = std::pow(dt, -deriv);
  for (long i = 0; i < n; ++i) {
    long start = i - hw;
    Eigen::VectorXd wts;
    if (start < 0)
      start = 0, wts = weights(i);
    else if (start + w > n)
      start = n - w, wts = weights(i - start);
    else
      wts = centre;
    double acc = 0;
    for (long k = 0; k < w; ++k) acc += wts[k] * y[start + k];
    out[i] = acc * scale;
  }
  return out;
}

std::vector<double> SpectralDerivative(const std::vector<double>& y, double dt, int order, double f_cut_hz) {
  const size_t n = y.size();
  if (n < 4) return std::vector<double>(n, 0.0);
  const size_t len = NextFastFftLength(2 * n);
  std::vector<double> x(len, y[0]);
  for (size_t i = 0; i < n; ++i) x[i] = y[i], x[2 * n - 1 - i] = y[i];  // mirror; the pad continues at y[0]
  std::vector<std::complex<double>> X;
  RealFftFull(x, &X);
  const double df = 1.0 / (static_cast<double>(len) * dt);
  for (size_t k = 0; k < X.size(); ++k) {
    const double f = (k <= len / 2 ? static_cast<double>(k) : -static_cast<double>(len - k)) * df;
    const double af = std::abs(f);
    double h = 1.0;
    if (af >= f_cut_hz)
      h = 0.0;
    else if (af > 0.8 * f_cut_hz)
      h = 0.5 * (1.0 + std::cos(M_PI * (af - 0.8 * f_cut_hz) / (0.2 * f_cut_hz)));
    std::complex<double> w(1.0, 0.0);
    for (int d = 0; d < order; ++d) w *= std::complex<double>(0.0, 2.0 * M_PI * f);
    if (order > 0 && k == len / 2 && len % 2 == 0) w = 0;  // Nyquist bin of an odd derivative: no sign
    X[k] *= h * w;
  }
  std::vector<double> out;
  InverseFftReal(X, &out);
  out.resize(n);
  return out;
}

double AutoCutoff(const std::vector<double>& y, double dt) {
  const size_t n = y.size();
  const double nyq = 0.5 / dt;
  if (n < 8) return 0.9 * nyq;
  double mean = 0;
  for (double v : y) mean += v;
  mean /= static_cast<double>(n);
  const size_t len = NextFastFftLength(2 * n);
  std::vector<double> x(len, y[0] - mean);
  for (size_t i = 0; i < n; ++i) x[i] = x[2 * n - 1 - i] = y[i] - mean;
  std::vector<std::complex<double>> X;
  RealFftFull(x, &X);
  std::vector<double> pw(len / 2 + 1);
  double total = 0;
  for (size_t k = 1; k < pw.size(); ++k) total += pw[k] = std::norm(X[k]);
  double acc = 0;
  const double df = 1.0 / (static_cast<double>(len) * dt);
  double f999 = nyq;
  for (size_t k = 1; k < pw.size(); ++k) {
    acc += pw[k];
    if (acc >= 0.999 * total) {
      f999 = static_cast<double>(k) * df;
      break;
    }
  }
  return std::clamp(4.0 * f999, 10.0 * df, 0.9 * nyq);
}

std::vector<double> IntegrateFft(const std::vector<double>& y, double dt, double f_min_hz) {
  const size_t n = y.size();
  if (n < 4) return std::vector<double>(n, 0.0);
  const size_t len = NextFastFftLength(n);
  double mean = 0;
  for (double v : y) mean += v;
  mean /= static_cast<double>(n);
  std::vector<double> x(len, 0.0);
  for (size_t i = 0; i < n; ++i) x[i] = y[i] - mean;
  // Pad with a mirrored tail tapering to zero so the periodic extension has no jump.
  for (size_t i = n; i < len; ++i) {
    const double frac = static_cast<double>(i - n + 1) / static_cast<double>(len - n + 1);
    x[i] = (1.0 - frac) * x[n - 1] + frac * x[0];
  }
  std::vector<std::complex<double>> X;
  RealFftFull(x, &X);
  const double df = 1.0 / (static_cast<double>(len) * dt);
  for (size_t k = 0; k < X.size(); ++k) {
    const size_t kk = k <= len / 2 ? k : len - k;
    const double f = static_cast<double>(kk) * df;
    if (kk == 0 || f < f_min_hz) {
      X[k] = 0;
      continue;
    }
    const double w = 2.0 * M_PI * f * (k <= len / 2 ? 1.0 : -1.0);
    X[k] /= std::complex<double>(0.0, w);
  }
  std::vector<double> out;
  InverseFftReal(X, &out);
  out.resize(n);
  double m2 = 0;
  for (double v : out) m2 += v;
  m2 /= static_cast<double>(n);
  for (double& v : out) v -= m2;
  return out;
}

namespace {

// Hann-windowed periodogram of y about its mean: power per bin k = 0 … len/2 (bin spacing 1/(len dt)), and
// Σ w² of the window (a white noise of variance σ² has mean bin power σ² Σ w²).
struct Periodogram {
  std::vector<double> power;
  double w2 = 0, df = 0;
};
Periodogram HannPeriodogram(const std::vector<double>& y, double dt) {
  const size_t n = y.size();
  double mean = 0;
  for (double v : y) mean += v;
  mean /= static_cast<double>(n);
  const size_t len = NextFastFftLength(n);
  std::vector<double> x(len, 0.0);
  Periodogram p;
  for (size_t i = 0; i < n; ++i) {
    const double w = 0.5 - 0.5 * std::cos(2.0 * M_PI * static_cast<double>(i) / static_cast<double>(n - 1));
    x[i] = (y[i] - mean) * w;
    p.w2 += w * w;
  }
  std::vector<std::complex<double>> X;
  RealFftFull(x, &X);
  p.power.resize(len / 2 + 1);
  for (size_t k = 0; k < p.power.size(); ++k) p.power[k] = std::norm(X[k]);
  p.df = 1.0 / (static_cast<double>(len) * dt);
  return p;
}

// NoiseLevel from y's periodogram pg.
double NoiseOf(const Periodogram& pg, const std::vector<double>& y, double dt) {
  const double nyq = 0.5 / dt;
  const double f_lo = std::min(AutoCutoff(y, dt), 0.6 * nyq);
  std::vector<double> pw;
  for (size_t k = 1; k < pg.power.size(); ++k)
    if (static_cast<double>(k) * pg.df >= f_lo) pw.push_back(pg.power[k]);
  if (pw.size() < 8) return NAN;
  std::nth_element(pw.begin(), pw.begin() + static_cast<long>(pw.size() / 2), pw.end());
  const double median = pw[pw.size() / 2];
  return std::sqrt(median / std::log(2.0) / pg.w2);
}

}  // namespace

double NoiseLevel(const std::vector<double>& y, double dt) {
  if (y.size() < 64) return NAN;
  return NoiseOf(HannPeriodogram(y, dt), y, dt);
}

double DriveCutoff(const std::vector<double>& input, double dt) {
  const size_t n = input.size();
  if (n < 64) return 0.0;
  const Periodogram pg = HannPeriodogram(input, dt);
  const double sigma = NoiseOf(pg, input, dt);
  if (!(sigma > 0) || !std::isfinite(sigma)) return 0.0;
  double mean = 0, ms = 0;
  for (double v : input) mean += v;
  mean /= static_cast<double>(n);
  for (double v : input) ms += (v - mean) * (v - mean);
  // A floor 120 dB below the input is roundoff, not noise (a computed input; no converter is that clean):
  // nothing to take away, and a chaotic model's orbit would notice the low-pass's own rounding.
  if (!(sigma > 1e-6 * std::sqrt(ms / static_cast<double>(n)))) return 0.0;
  const std::vector<double>& pw = pg.power;
  const size_t bins = pw.size();
  double total = 0;
  for (size_t k = 1; k < bins; ++k) total += pw[k];
  const double floor = sigma * sigma * pg.w2;  // a white noise bin's mean power (NoiseLevel's scale)
  constexpr int kHalf = 3;
  size_t top = 0;
  for (size_t k = 1; k < bins; ++k) {
    double s = 0;
    int c = 0;
    for (long j = static_cast<long>(k) - kHalf; j <= static_cast<long>(k) + kHalf; ++j)
      if (j >= 1 && j < static_cast<long>(bins)) s += pw[static_cast<size_t>(j)], ++c;
    if (s / c > 10.0 * floor) top = k;
  }
  const double nyq = 0.5 / dt, df = pg.df;
  // Flat to twice the band's top (a shaker's second harmonic, and the edge's leakage), then the taper. On a
  // chaotic coupled record (1–10 Hz, noise 0.05 mm) the true model's 0.5 s shooting error: 0.75 % driven by
  // the raw input; flat to 1×, 1.25×, 1.5×, 2×, 4× the top: 0.97, 0.49, 0.41, 0.45, 0.65 %; on a standalone
  // one 2.09, 1.04, 0.65 % at 1.25×, 1.5×, 2× (the narrow bands cut the drive's own edge).
  const double f_cut = 2.0 * static_cast<double>(top + kHalf + 1) * df / 0.8;
  if (top == 0 || !(f_cut < 0.9 * nyq)) return 0.0;
  double above = 0;
  for (size_t k = 1; k < bins; ++k)
    if (static_cast<double>(k) * df > 0.8 * f_cut) above += pw[k];
  return above <= 0.01 * total ? f_cut : 0.0;
}

}  // namespace bistable
