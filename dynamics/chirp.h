// Frequency sweeps (paper §5, Figs. 22–24): the base follows a linear chirp, up or down, and the
// response is recorded; the FRF is the ratio of the output's and the input's Fourier magnitudes
// (absolute velocities, as the paper's Eq. 10), and the spectrogram the short-time Fourier magnitude
// of the output. Non-dimensional models (τ, Ω in rad/τ) and the dimensional model (s, Hz) alike.
#ifndef BISTABLE_DYNAMICS_CHIRP_H_
#define BISTABLE_DYNAMICS_CHIRP_H_

#include <string>
#include <vector>

#include "base/status.h"
#include "dynamics/dimensional_model.h"
#include "dynamics/point_spec.h"

namespace bistable {

struct ChirpOptions {
  // A non-dimensional cell (standalone/coupled/linear/linear-coupled) ...
  ModelKind model = ModelKind::kCoupled;
  NondimParams params;
  double alpha = 0.5;           // base amplitude α
  double from = 0.2, to = 3.0;  // angular frequency range Ω (rad/τ), swept linearly in time
  double duration = 2000;       // τ
  double dt = 0.01;             // RK4 step
  // ... or model = kDimensional: A0 [m], frequencies in Hz, time in s, parameters in `dim`.
  DimensionalParams dim = DimensionalParams::BistableTable2();
  double a0_m = 0.01;
  double rtol = 1e-6, atol = 1e-9;
  int sample_every = 5;  // output sampling, steps (dimensional: output step = dt)
};

struct ChirpRecord {
  double dt = 0;  // sampling interval of the series (τ or s)
  std::vector<double> t, x0, v0, y,
      v_abs;                      // time, base displacement and velocity, y_m, absolute velocity of the main mass
  std::vector<double> inst_freq;  // instantaneous forcing frequency (rad/τ, or Hz for dimensional)
  bool diverged = false;
};

Status ValidateChirpOptions(const ChirpOptions& o);
StatusOr<ChirpRecord> RunChirp(const ChirpOptions& o);

// FRF from the Fourier magnitudes: f in the run's frequency unit (rad/τ, or Hz), in/out magnitudes
// and 20 log10(|OUT| / |IN|), over the bins inside [f_lo, f_hi].
struct FrfEstimate {
  std::vector<double> freq, in_mag, out_mag, db;
};
FrfEstimate FftFrf(const std::vector<double>& in, const std::vector<double>& out, double dt, double f_lo, double f_hi,
                   bool hz);

// Welch-averaged FRF: Hann-windowed segments of `segment` samples with 50 % overlap (mean removed per
// segment); H1 = Σ conj(X) Y / Σ |X|² (unbiased by output noise), the coherence
// γ² = |Σ conj(X) Y|² / (Σ |X|² Σ |Y|²) in [0, 1] (1 for a noise-free linear system; lower where the
// output has power the input does not explain: noise, harmonics, jumps), and the averaged amplitude
// spectra sqrt(Σ |X|² / K)·2/Σw (a sinusoid of amplitude A gives ≈ A), over the bins inside [f_lo, f_hi].
// segment <= 0: the largest power of two ≤ n/4 (at least 64), so about 7 segments are averaged.
struct H1Estimate {
  std::vector<double> freq, in_mag, out_mag, db, coherence;
  int segments = 0, segment = 0;
};
H1Estimate WelchH1(const std::vector<double>& in, const std::vector<double>& out, double dt, double f_lo, double f_hi,
                   bool hz, int segment = 0);

// Short-time Fourier magnitude (dB re the largest) with a Hann window of `window` samples and hop
// window/4: times (window centres), frequencies (rad per time unit, or Hz), values [time][freq].
struct Spectrogram {
  std::vector<double> time, freq;
  std::vector<std::vector<double>> db;
};
Spectrogram ComputeSpectrogram(const std::vector<double>& x, double dt, int window, double f_max, bool hz);

}  // namespace bistable

#endif  // BISTABLE_DYNAMICS_CHIRP_H_
