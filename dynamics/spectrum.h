// One-sided amplitude spectra of sampled signals (Hann window, mean removed) and the harmonic
// diffusion measures of model.md §3 (paper Fig. 6). Response spectra by the lane FFT
// (dynamics/lane_fft.h), W points at a time in sweeps; other transforms (chirps, Welch) by Eigen's FFT
// module (kissfft backend, double).
#ifndef BISTABLE_DYNAMICS_SPECTRUM_H_
#define BISTABLE_DYNAMICS_SPECTRUM_H_

#include <complex>
#include <vector>

#include "dynamics/point_spec.h"

namespace bistable {

struct Spectrum {
  double d_omega = 0;       // bin spacing, rad per unit time: 2π/(N dt)
  std::vector<double> amp;  // amp[k] at ω_k = k·d_omega; a pure sinusoid of amplitude A peaks at ≈ A
};

// Mean removed, Hann-windowed, amplitude-normalised (2|X_k| / Σw). Uses the last FastFftLength(N)
// samples so the FFT never falls back to a slow prime-length transform (5001 = 3 · 1667 would).
Spectrum AmplitudeSpectrum(const std::vector<double>& x, double dt);

// The same for n ≤ W series side by side in lanes: out[l] is bit for bit AmplitudeSpectrum(*xs[l],
// dts[l]) at any W. Series of different lengths are grouped by length.
template <int W>
void AmplitudeSpectra(const std::vector<double>* const* xs, const double* dts, int n, Spectrum* out);

// Every FFT of the project goes through these three (one translation unit instantiates kissfft).
// Two differently compiled copies of its inline code in one binary — a sweep's and an identification
// module's — made the embedded map differ from the workers' in the last bit of hd_index (found by the
// distributed bit-for-bit test); keep all transforms here.
// Half spectrum (n/2 + 1 bins) of a real series; fast for n = 2^a 3^b 5^c.
void RealFftHalf(const std::vector<double>& x, std::vector<std::complex<double>>* X);
// Full spectrum (n bins) of a real series.
void RealFftFull(const std::vector<double>& x, std::vector<std::complex<double>>* X);
// Real series from a full (Hermitian) spectrum of n bins.
void InverseFftReal(const std::vector<std::complex<double>>& X, std::vector<double>* x);

// Frees the calling thread's transform caches (the last length's FFT tables, Hann window and buffers at
// every lane width; Eigen's plans), which a thread that transformed one long series keeps otherwise (a
// dashboard cell: up to 2^20 samples, about 25 MB). The next transform builds them again.
void ReleaseThreadSpectrumCaches();

// Largest n' ≤ n of the form 2^a 3^b 5^c (n ≥ 1).
size_t FastFftLength(size_t n);
// Smallest n' ≥ n of that form (for zero padding).
size_t NextFastFftLength(size_t n);

// Power-weighted mean frequency in cycles per unit time (Rosenstein's mean period is its inverse).
double MeanFrequency(const std::vector<double>& x, double dt);

// Local maxima with amplitude ≥ level × the largest, strongest first, at most top_k; peak
// frequency refined by a parabola through the log-amplitudes of the three bins around it.
std::vector<HdPeak> SpectralPeaks(const Spectrum& s, double level, int top_k);

// Fraction of spectral power (Σ amp², bins k ≥ 1) farther than `tol_bins` bins from every integer
// multiple nΩ (n ≥ 0). 0 for a period-1 response; grows with sub-harmonics, quasi-periodicity and chaos.
// tol_bins = 3 covers the Hann main lobe (±2 bins) with one bin to spare.
double HarmonicDiffusionIndex(const Spectrum& s, double omega, double tol_bins = 3.0);

// Amplitude of the component at angular frequency w in x[0..n) sampled every dt (Hann-weighted
// projection; a sinusoid of amplitude A at w gives ≈ A).
double ToneAmplitude(const double* x, size_t n, double dt, double w);
// The same projection as a phasor P: x ≈ Re(P e^{iωt}) with t = i·dt, so |P| is the amplitude (as
// ToneAmplitude) and arg P the phase φ of A cos(ωt + φ).
std::complex<double> TonePhasor(const double* x, size_t n, double dt, double w);

// Fraction of spectral power within `tol_bins` of the sub-harmonics kΩ/n with k not a multiple of n:
// the spectral signature of period-n motion (0 for n = 1).
double SubharmonicFraction(const Spectrum& s, double omega, int n, double tol_bins = 3.0);

}  // namespace bistable

#endif  // BISTABLE_DYNAMICS_SPECTRUM_H_
