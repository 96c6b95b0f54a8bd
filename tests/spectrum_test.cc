// Spectra and harmonic-diffusion measures on signals with known content.
#include <cmath>
#include <vector>

#include <gtest/gtest.h>

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

}  // namespace
}  // namespace bistable
