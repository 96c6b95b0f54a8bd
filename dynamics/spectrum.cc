#include "dynamics/spectrum.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <complex>
#include <memory>
#include <numeric>

#include <unsupported/Eigen/FFT>

#include "dynamics/lane_fft.h"

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
// (n cosines) and the FFT's twiddle tables cost as much as the transform itself.
template <int W>
struct SpectrumCache {
  std::unique_ptr<LaneRealFft<W>> fft;
  std::vector<double> window;
  double window_sum = 0;
  std::vector<Vec<W>> xw, re, im;
  void Prepare(size_t n) {
    if (fft && fft->size() == n) return;
    fft = std::make_unique<LaneRealFft<W>>(n);
    window.resize(n);
    window_sum = 0;
    for (size_t i = 0; i < n; ++i) {
      window[i] = 0.5 - 0.5 * std::cos(2.0 * M_PI * static_cast<double>(i) / static_cast<double>(n));
      window_sum += window[i];
    }
    xw.resize(n);
    re.resize(fft->bins());
    im.resize(fft->bins());
  }
};

template <int W>
SpectrumCache<W>& Cache() {
  thread_local SpectrumCache<W> cache;
  return cache;
}

// n ≤ W series of one length ≥ 4 (each lane's arithmetic is that of W = 1).
template <int W>
void SpectraOfLength(const std::vector<double>* const* xs, const double* dts, int n, Spectrum* out) {
  using V = Vec<W>;
  const size_t len = xs[0]->size(), nf = FastFftLength(len), skip = len - nf;
  SpectrumCache<W>& c = Cache<W>();
  c.Prepare(nf);
  // Into lanes by strided scalar stores (element inserts into a vector compile to a broadcast and a
  // blend each, and cost more than the FFT).
  double* xw = reinterpret_cast<double*>(c.xw.data());
  for (int l = 0; l < W; ++l) {
    if (l < n) {
      const double* x = xs[l]->data() + skip;
      for (size_t i = 0; i < nf; ++i) xw[i * W + l] = x[i];
    } else {
      for (size_t i = 0; i < nf; ++i) xw[i * W + l] = 0.0;
    }
  }
  V sum = Splat<W>(0.0);
  for (size_t i = 0; i < nf; ++i) sum += c.xw[i];
  const V mean = sum / Splat<W>(static_cast<double>(nf));
  for (size_t i = 0; i < nf; ++i) c.xw[i] = (c.xw[i] - mean) * Splat<W>(c.window[i]);
  c.fft->Forward(c.xw.data(), c.re.data(), c.im.data());
  const size_t bins = c.fft->bins();
  const V two = Splat<W>(2.0), wsum = Splat<W>(c.window_sum);
  for (int l = 0; l < n; ++l) {
    out[l].d_omega = 2.0 * M_PI / (static_cast<double>(nf) * dts[l]);
    out[l].amp.resize(bins);
  }
  for (size_t k = 0; k < bins; ++k) c.re[k] = two * Sqrt<W>(c.re[k] * c.re[k] + c.im[k] * c.im[k]) / wsum;
  const double* amp = reinterpret_cast<const double*>(c.re.data());
  for (int l = 0; l < n; ++l) {
    double* a = out[l].amp.data();
    for (size_t k = 0; k < bins; ++k) a[k] = amp[k * W + l];
  }
}

}  // namespace

template <int W>
void AmplitudeSpectra(const std::vector<double>* const* xs, const double* dts, int n, Spectrum* out) {
  std::array<bool, W> done{};
  for (int l = 0; l < n; ++l) {
    out[l] = Spectrum{};
    if (xs[l]->size() < 4) done[l] = true;
  }
  for (int l = 0; l < n; ++l) {
    if (done[l]) continue;
    // Every not-yet-done series of this length, side by side.
    std::array<const std::vector<double>*, W> group;
    std::array<double, W> group_dt;
    std::array<int, W> where;
    int g = 0;
    for (int j = l; j < n; ++j)
      if (!done[j] && xs[j]->size() == xs[l]->size()) {
        group[g] = xs[j], group_dt[g] = dts[j], where[g++] = j;
        done[j] = true;
      }
    std::array<Spectrum, W> got;
    SpectraOfLength<W>(group.data(), group_dt.data(), g, got.data());
    for (int i = 0; i < g; ++i) out[where[i]] = std::move(got[i]);
  }
}

template void AmplitudeSpectra<1>(const std::vector<double>* const*, const double*, int, Spectrum*);
template void AmplitudeSpectra<2>(const std::vector<double>* const*, const double*, int, Spectrum*);
template void AmplitudeSpectra<4>(const std::vector<double>* const*, const double*, int, Spectrum*);
template void AmplitudeSpectra<8>(const std::vector<double>* const*, const double*, int, Spectrum*);
template void AmplitudeSpectra<16>(const std::vector<double>* const*, const double*, int, Spectrum*);

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

void ReleaseThreadSpectrumCaches() {
  Cache<1>() = {}, Cache<2>() = {}, Cache<4>() = {}, Cache<8>() = {}, Cache<16>() = {};
  HalfFft() = Eigen::FFT<double>();
  HalfFft().SetFlag(Eigen::FFT<double>::HalfSpectrum);
  FullFft() = Eigen::FFT<double>();
}

size_t NextFastFftLength(size_t n) {
  size_t best = SIZE_MAX;
  for (size_t a = 1; a < 2 * n + 2; a *= 2)
    for (size_t b = a; b < 2 * n + 2; b *= 3)
      for (size_t c = b; c < 2 * n + 2; c *= 5)
        if (c >= n) best = std::min(best, c);
  return best;
}

Spectrum AmplitudeSpectrum(const std::vector<double>& x, double dt) {
  const std::vector<double>* xs = &x;
  Spectrum s;
  AmplitudeSpectra<1>(&xs, &dt, 1, &s);
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

namespace {

// Hann-weighted sums Σ w_i (x_i − mean) cos(ω t_i), … sin(ω t_i) and Σ w_i (false when n < 4).
bool ToneSums(const double* x, size_t n, double dt, double w, double* re_out, double* im_out, double* wsum_out) {
  if (n < 4) return false;
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
  *re_out = re, *im_out = im, *wsum_out = wsum;
  return true;
}

}  // namespace

double ToneAmplitude(const double* x, size_t n, double dt, double w) {
  double re = 0, im = 0, wsum = 0;
  if (!ToneSums(x, n, dt, w, &re, &im, &wsum)) return 0.0;
  return 2.0 * std::hypot(re, im) / wsum;
}

std::complex<double> TonePhasor(const double* x, size_t n, double dt, double w) {
  double re = 0, im = 0, wsum = 0;
  if (!ToneSums(x, n, dt, w, &re, &im, &wsum)) return 0.0;
  return std::complex<double>(re, -im) * (2.0 / wsum);
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
