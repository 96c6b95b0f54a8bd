// Spectra and harmonic-diffusion measures on signals with known content.
#include <cmath>
#include <complex>
#include <cstring>
#include <random>
#include <vector>

#include <gtest/gtest.h>

#include "dynamics/lane_fft.h"
#include "dynamics/spectrum.h"

namespace bistable {
namespace {

std::vector<double> Signal(double dt, int n, std::initializer_list<std::pair<double, double>> tones) {
  std::vector<double> x(n, 0.3);  // a mean offset, as in intrawell motion
  for (int i = 0; i < n; ++i)
    for (auto [w, a] : tones) x[i] += a * std::sin(w * dt * i + 0.4);
  return x;
}

TEST(Spectrum, SinusoidPeakHasItsAmplitudeAndFrequency) {
  const double dt = 0.05;
  const auto x = Signal(dt, 5000, {{1.3, 0.8}});
  const Spectrum s = AmplitudeSpectrum(x, dt);
  const auto peaks = SpectralPeaks(s, 0.01, 5);
  ASSERT_FALSE(peaks.empty());
  EXPECT_NEAR(peaks[0].freq, 1.3, 0.25 * s.d_omega);  // parabolic refinement: well inside a bin
  EXPECT_NEAR(peaks[0].amp, 0.8, 0.8 * 0.16);         // Hann scalloping loss ≤ 1.42 dB (16 %)
  EXPECT_NEAR(ToneAmplitude(x.data(), x.size(), dt, 1.3), 0.8, 0.01);
}

TEST(Spectrum, HarmonicDiffusionIndexSeparatesHarmonicsFromSubharmonics) {
  const double dt = 0.05, omega = 1.2;
  const Spectrum harmonics = AmplitudeSpectrum(Signal(dt, 5000, {{omega, 1.0}, {3 * omega, 0.2}}), dt);
  EXPECT_LT(HarmonicDiffusionIndex(harmonics, omega), 1e-3);
  EXPECT_LT(SubharmonicFraction(harmonics, omega, 2), 1e-3);
  // Equal power at Ω and Ω/2: half the power is off the multiples of Ω.
  const Spectrum halved = AmplitudeSpectrum(Signal(dt, 5000, {{omega, 1.0}, {omega / 2, 1.0}}), dt);
  EXPECT_NEAR(HarmonicDiffusionIndex(halved, omega), 0.5, 0.02);
  EXPECT_NEAR(SubharmonicFraction(halved, omega, 2), 0.5, 0.02);
  EXPECT_LT(SubharmonicFraction(halved, omega, 3), 0.01);
}

TEST(Spectrum, MeanFrequencyOfASinusoid) {
  const double dt = 0.01;
  EXPECT_NEAR(MeanFrequency(Signal(dt, 20000, {{2 * M_PI * 1.5, 1.0}}), dt), 1.5, 0.01);
}

TEST(Spectrum, PeaksBelowTheLevelAreDropped) {
  const double dt = 0.05;
  const Spectrum s = AmplitudeSpectrum(Signal(dt, 5000, {{1.0, 1.0}, {2.0, 0.005}}), dt);
  EXPECT_EQ(SpectralPeaks(s, 0.01, 10).size(), 1u);
  EXPECT_EQ(SpectralPeaks(s, 0.001, 10).size(), 2u);
}

// The direct DFT in long double: the ruler for the lane FFT.
std::vector<std::complex<long double>> Dft(const std::vector<std::complex<double>>& z) {
  const size_t n = z.size();
  std::vector<std::complex<long double>> out(n);
  for (size_t k = 0; k < n; ++k) {
    std::complex<long double> acc = 0;
    for (size_t j = 0; j < n; ++j) {
      const long double a = -2.0L * 3.14159265358979323846264338327950288L * static_cast<long double>((j * k) % n) / n;
      acc += std::complex<long double>(z[j]) * std::complex<long double>(std::cos(a), std::sin(a));
    }
    out[k] = acc;
  }
  return out;
}

std::vector<std::complex<double>> Noise(size_t n, unsigned seed) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> g;
  std::vector<std::complex<double>> z(n);
  for (auto& v : z) v = {g(rng), g(rng)};
  return z;
}

// Every radix (4, 2, 3, 5 and the direct DFT of other primes) against the DFT: error at the level
// of rounding (≈ ε log n relative to the spectrum's norm), not of an approximation.
TEST(LaneFft, MatchesTheDirectDftForMixedRadices) {
  for (size_t n : {1, 2, 3, 4, 5, 7, 8, 12, 16, 30, 49, 77, 128, 132, 154, 221, 250, 500}) {
    const auto z = Noise(n, n);
    LaneFft<2> fft(n);
    std::vector<Vec<2>> re(n), im(n), wr(n), wi(n);
    for (size_t j = 0; j < n; ++j) re[j] = Vec<2>{z[j].real(), -z[j].real()}, im[j] = Vec<2>{z[j].imag(), -z[j].imag()};
    fft.Forward(re.data(), im.data(), wr.data(), wi.data());
    const auto ref = Dft(z);
    long double err = 0, norm = 0;
    for (size_t k = 0; k < n; ++k) {
      err = std::max(err, std::abs(std::complex<long double>(re[k][0], im[k][0]) - ref[k]));
      norm = std::max(norm, std::abs(ref[k]));
      ASSERT_EQ(re[k][1], -re[k][0]) << "n " << n << " bin " << k;  // the second lane is the negated input
      ASSERT_EQ(im[k][1], -im[k][0]) << "n " << n << " bin " << k;
    }
    EXPECT_LT(static_cast<double>(err / norm), 2e-15 * (1 + std::log2(static_cast<double>(n)))) << "n " << n;
  }
}

TEST(LaneFft, RealTransformMatchesTheDirectDftForEvenAndOddLengths) {
  for (size_t n : {2, 3, 4, 15, 26, 98, 250, 600}) {
    auto z = Noise(n, 7 * n);
    for (auto& v : z) v = {v.real(), 0.0};
    LaneRealFft<1> fft(n);
    std::vector<Vec<1>> x(n), re(fft.bins()), im(fft.bins());
    for (size_t j = 0; j < n; ++j) x[j][0] = z[j].real();
    fft.Forward(x.data(), re.data(), im.data());
    const auto ref = Dft(z);
    long double err = 0, norm = 0;
    for (size_t k = 0; k < fft.bins(); ++k) {
      err = std::max(err, std::abs(std::complex<long double>(re[k][0], im[k][0]) - ref[k]));
      norm = std::max(norm, std::abs(ref[k]));
    }
    EXPECT_LT(static_cast<double>(err / norm), 2e-15 * (1 + std::log2(static_cast<double>(n)))) << "n " << n;
    EXPECT_EQ(im[0][0], 0.0);  // the mean's bin of a real series is real
  }
}

// The same spectra whether points go one at a time or W side by side (map == point), including lanes
// of other lengths, too-short lanes and a lane of non-finite samples.
template <int W>
void ExpectSameSpectraAsOneAtATime() {
  std::vector<std::vector<double>> xs(W);
  std::vector<double> dts(W);
  for (int l = 0; l < W; ++l) {
    const int n = l % 3 == 2 ? 4000 : (l == 1 ? 3 : 5000);
    xs[l] = Signal(0.05, n, {{1.0 + 0.1 * l, 0.5}, {3.0, 0.1 * l}});
    dts[l] = 0.05 * (1 + l % 2);
  }
  if (W > 3) xs[3][17] = std::numeric_limits<double>::infinity();
  std::vector<const std::vector<double>*> ptrs(W);
  for (int l = 0; l < W; ++l) ptrs[l] = &xs[l];
  std::vector<Spectrum> block(W);
  AmplitudeSpectra<W>(ptrs.data(), dts.data(), W, block.data());
  for (int l = 0; l < W; ++l) {
    const Spectrum one = AmplitudeSpectrum(xs[l], dts[l]);
    ASSERT_EQ(one.amp.size(), block[l].amp.size()) << "W " << W << " lane " << l;
    EXPECT_EQ(std::memcmp(&one.d_omega, &block[l].d_omega, sizeof(double)), 0);
    for (size_t k = 0; k < one.amp.size(); ++k)
      ASSERT_EQ(std::memcmp(&one.amp[k], &block[l].amp[k], sizeof(double)), 0)
          << "W " << W << " lane " << l << " bin " << k;
  }
}

TEST(LaneFft, SpectraInLanesEqualOneAtATimeBitForBit) {
  ExpectSameSpectraAsOneAtATime<2>();
  ExpectSameSpectraAsOneAtATime<4>();
  ExpectSameSpectraAsOneAtATime<8>();
  ExpectSameSpectraAsOneAtATime<16>();
}

// Against kissfft (Eigen's FFT, which the chirp and Welch estimates use): the same half spectrum to
// rounding.
TEST(LaneFft, AgreesWithKissfft) {
  const size_t n = 5000;
  auto z = Noise(n, 3);
  std::vector<double> x(n);
  for (size_t j = 0; j < n; ++j) x[j] = z[j].real();
  std::vector<std::complex<double>> kiss;
  RealFftHalf(x, &kiss);
  LaneRealFft<1> fft(n);
  std::vector<Vec<1>> xv(n), re(fft.bins()), im(fft.bins());
  for (size_t j = 0; j < n; ++j) xv[j][0] = x[j];
  fft.Forward(xv.data(), re.data(), im.data());
  ASSERT_EQ(kiss.size(), fft.bins());
  double err = 0, norm = 0;
  for (size_t k = 0; k < kiss.size(); ++k) {
    err = std::max(err, std::abs(kiss[k] - std::complex<double>(re[k][0], im[k][0])));
    norm = std::max(norm, std::abs(kiss[k]));
  }
  EXPECT_LT(err / norm, 1e-14);
}

}  // namespace
}  // namespace bistable
