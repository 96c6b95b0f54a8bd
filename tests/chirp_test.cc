// Frequency sweeps: the FFT-based FRF of a slow chirp approaches the closed-form transmissibility of
// the linear oscillator, ever closer as the sweep slows; spectrogram ridges follow the forcing.
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <vector>

#include <gtest/gtest.h>

#include "dynamics/chirp.h"

namespace bistable {
namespace {

// Sorted |FRF error| in dB against |1 + iηΩ| / |1 − Ω² + iηΩ| over Ω ∈ [0.4, 2.8].
std::vector<double> LinearChirpErrors(double duration) {
  ChirpOptions o;
  o.model = ModelKind::kLinear;
  o.alpha = 0.5;
  o.from = 0.2;
  o.to = 3.0;
  o.duration = duration;
  auto r = RunChirp(o);
  EXPECT_TRUE(r.ok());
  const FrfEstimate e = FftFrf(r->v0, r->v_abs, r->dt, 0.2, 3.0, false);
  std::vector<double> err;
  for (size_t i = 0; i < e.freq.size(); ++i) {
    const double w = e.freq[i];
    if (w < 0.4 || w > 2.8) continue;
    err.push_back(std::fabs(e.db[i] - 20 * std::log10(std::hypot(1, 0.1 * w) / std::hypot(1 - w * w, 0.1 * w))));
  }
  std::sort(err.begin(), err.end());
  return err;
}

TEST(Chirp, SlowSweepFrfOfTheLinearOscillatorApproachesTheClosedForm) {
  // Measured: τ 2000 → median 0.11 dB; 8000 → 0.06 dB (90 % 0.15); 20000 → 0.035 dB. The sweep's
  // finite rate and the band edges set the residual; bounds leave ~1.6x margin.
  const auto fast = LinearChirpErrors(2000), slow = LinearChirpErrors(8000);
  ASSERT_GT(slow.size(), 1000u);
  EXPECT_LT(slow[slow.size() / 2], 0.1);
  EXPECT_LT(slow[slow.size() * 9 / 10], 0.25);
  EXPECT_LT(slow[slow.size() / 2], fast[fast.size() / 2]) << "a slower sweep must be more accurate";
}

TEST(Chirp, SpectrogramRidgeFollowsTheInstantaneousFrequency) {
  ChirpOptions o;
  o.model = ModelKind::kLinear;
  o.alpha = 0.5;
  o.from = 0.5;
  o.to = 2.5;
  o.duration = 3000;
  auto r = RunChirp(o);
  ASSERT_TRUE(r.ok());
  const Spectrogram s = ComputeSpectrogram(r->x0, r->dt, 1024, 5.0, false);
  ASSERT_GT(s.time.size(), 10u);
  const double bin = s.freq[1] - s.freq[0];
  for (size_t i = 0; i < s.time.size(); ++i) {
    const size_t k = std::max_element(s.db[i].begin(), s.db[i].end()) - s.db[i].begin();
    const double expected = o.from + (o.to - o.from) * s.time[i] / o.duration;
    // Within the window the frequency moves by (to − from)·window·dt/duration ≈ 0.03: a bin and a half.
    EXPECT_NEAR(s.freq[k], expected, 1.5 * bin + 0.03) << "frame at tau " << s.time[i];
  }
}

TEST(Chirp, DimensionalSweepRunsInSecondsAndHertz) {
  ChirpOptions o;
  o.model = ModelKind::kDimensional;
  o.a0_m = 0.005;
  o.from = 1.0;
  o.to = 8.0;
  o.duration = 10.0;
  o.dt = 0.002;
  auto r = RunChirp(o);
  ASSERT_TRUE(r.ok()) << r.status().ToString();
  EXPECT_FALSE(r->diverged);
  EXPECT_NEAR(r->t.back(), 10.0, 1e-9);
  EXPECT_NEAR(r->inst_freq.back(), 8.0, 1e-9);
  const FrfEstimate e = FftFrf(r->v0, r->v_abs, r->dt, 1.0, 8.0, true);
  ASSERT_FALSE(e.freq.empty());
  EXPECT_NEAR(e.freq.front(), 1.0, 0.2);
}

// Welch H1 on a known linear system: out = 2·in delayed one sample, plus independent output noise.
// H1 stays at 2 (6.02 dB) whatever the noise (it divides by the input's auto-spectrum only), and the
// coherence is the share of output power the input explains: 4σx² / (4σx² + σn²) = 0.8 for σn² = σx².
TEST(Chirp, WelchH1IsUnbiasedByOutputNoiseAndCoherenceMeasuresIt) {
  uint64_t s = 88172645463325252ull;
  auto gauss = [&] {  // Box-Muller on xorshift64
    auto u = [&] {
      s ^= s << 13, s ^= s >> 7, s ^= s << 17;
      return (static_cast<double>(s >> 11) + 0.5) / 9007199254740992.0;
    };
    return std::sqrt(-2 * std::log(u())) * std::cos(2 * M_PI * u());
  };
  const size_t n = 1 << 16;
  std::vector<double> in(n), clean(n), noisy(n);
  for (size_t i = 0; i < n; ++i) in[i] = gauss();
  for (size_t i = 1; i < n; ++i) clean[i] = 2 * in[i - 1], noisy[i] = clean[i] + gauss();
  const H1Estimate a = WelchH1(in, clean, 0.01, 1.0, 40.0, true, 512);
  const H1Estimate b = WelchH1(in, noisy, 0.01, 1.0, 40.0, true, 512);
  ASSERT_GT(a.freq.size(), 100u);
  EXPECT_EQ(a.segments, 255);
  double db_a = 0, db_b = 0, coh_a = 0, coh_b = 0;
  for (size_t k = 0; k < a.freq.size(); ++k)
    db_a += a.db[k], db_b += b.db[k], coh_a += a.coherence[k], coh_b += b.coherence[k];
  const double m = static_cast<double>(a.freq.size());
  EXPECT_NEAR(db_a / m, 20 * std::log10(2.0), 0.02);
  EXPECT_NEAR(db_b / m, 20 * std::log10(2.0), 0.1);
  EXPECT_GT(coh_a / m, 0.99);
  EXPECT_NEAR(coh_b / m, 0.8, 0.03);
  // The averaged amplitude spectra: white noise of unit variance, output twice the input.
  EXPECT_NEAR(a.out_mag[a.freq.size() / 2] / a.in_mag[a.freq.size() / 2], 2.0, 0.4);
  // Default segment: the largest power of two <= n/4.
  EXPECT_EQ(WelchH1(in, clean, 0.01, 1.0, 40.0, true).segment, 1 << 14);
}

TEST(Chirp, BadOptionsNameTheField) {
  ChirpOptions o;
  o.from = 0;
  EXPECT_EQ(RunChirp(o).status().field(), "from");
  o = ChirpOptions{};
  o.sample_every = 100;  // Nyquist π/(0.01·100) = 3.1 rad/τ < 5 · 3
  EXPECT_EQ(RunChirp(o).status().field(), "sample_every");
  o = ChirpOptions{};
  o.model = ModelKind::kDimensional;
  o.dt = 0.05;  // 20 samples/s for an 8 Hz top frequency... from 0.2 to 3 Hz: 1/dt = 20 < 30
  EXPECT_EQ(RunChirp(o).status().field(), "dt");
}

}  // namespace
}  // namespace bistable
