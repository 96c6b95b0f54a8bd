// One (α, Ω) point of a non-dimensional model: integrate, then compute every metric of model.md §3.
// The RK4 path runs the same ensemble kernel as sweeps (lane width 1 here; any width gives the
// same bits); the adaptive path runs Dormand–Prince 5(4) and feeds the same window recorder.
#ifndef BISTABLE_DYNAMICS_POINT_H_
#define BISTABLE_DYNAMICS_POINT_H_

#include <vector>

#include "dynamics/ensemble_rk4.h"
#include "dynamics/point_spec.h"
#include "dynamics/window_recorder.h"

namespace bistable {

// Validates, integrates, measures. Errors for invalid specs, and CancelledStatus() when cancellation
// (dynamics/cancel.h) stopped the integration: a cancelled point has no result at all. A diverging
// run is a result (termination != kOk, metrics NaN).
StatusOr<PointResult> EvaluatePoint(const PointSpec& spec);

// The strobe recurrence of a window: the smallest n ≤ max_period for which the last max(4, (m − n)/2) strobes
// (y, v) repeat after n within tol; 0 when none (or too few strobes). The period metric checks n ≥ 2 further
// against the spectrum (point_metrics.cc); settled labels read it per window (settle.cc).
int StrobeRecurrence(const std::vector<double>& y, const std::vector<double>& v, int max_period, double tol);

// Kernel inputs/settings for a validated spec (sweeps build lanes from these too).
LaneInput LaneFor(const PointSpec& spec);
KernelSettings KernelSettingsFor(const PointSpec& spec);

// Runs the RK4 ensemble kernel on n ≤ W lanes of the given model. False when cancelled: out[0..n)
// then hold no result and must be discarded.
template <int W>
bool RunKernel(ModelKind model, const LaneInput* lanes, int n, const KernelSettings& s, RawLane* out) {
  if (HasResonator(model)) return EnsembleRk4<CoupledModel, W>::Run(lanes, n, s, out);
  return EnsembleRk4<SingleModel, W>::Run(lanes, n, s, out);
}

// The Lyapunov spectrum of a point (RK4 integrator only): the state space's exponents by QR
// (EnsembleRk4::RunSpectrum), at the point's settings (step, window, renormalisation interval).
struct LyapunovSpectrum {
  std::vector<double> exponents;  // per unit τ, in QR order: largest first up to finite-time error
  double sum = 0;                 // Σ exponents
  double divergence = 0;          // the exact phase-space contraction rate tr J = −η − η_r(1 + φ)
  double kaplan_yorke = 0;        // Kaplan–Yorke dimension of the flow (the exponents and the forcing
                                  // phase's 0), e.g. 1 for a periodic orbit, 2 + λ1/|λ3| for a
                                  // chaotic one-well cell; the Poincaré section's is one less
  bool diverged = false;          // the orbit blew up: no spectrum (NaNs)
};
StatusOr<LyapunovSpectrum> EvaluateLyapunovSpectrum(const PointSpec& spec);
// Kaplan–Yorke dimension of exponents sorted in descending order: j + (λ1 + … + λj)/|λ(j+1)| for the
// largest j whose partial sum is ≥ 0 (0 when λ1 < 0; the count when every partial sum is ≥ 0).
double KaplanYorkeDimension(std::vector<double> exponents);

// Time between the window's samples (y_m for the spectrum, PointResult::samples): dt · sample_every.
double SampleStep(const PointSpec& spec);
// Window record → metrics (FRF, LLE, motion, period, spectrum, energy ratios, Rosenstein).
PointResult ComputePointMetrics(RawLane raw, const PointSpec& spec);
// The same for the n ≤ W lanes of a block (raw is moved from): the response spectra are computed
// side by side in lanes, and out[l] equals ComputePointMetrics(raw[l], specs[l]) bit for bit.
template <int W>
void ComputeBlockMetrics(RawLane* raw, const PointSpec* specs, int n, PointResult* out);

}  // namespace bistable

#endif  // BISTABLE_DYNAMICS_POINT_H_
