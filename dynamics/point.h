// One (α, Ω) point of a non-dimensional model: integrate, then compute every metric of model.md §3.
// The RK4 path runs the same ensemble kernel as sweeps (lane width 1 here; any width gives the
// same bits); the adaptive path runs Dormand–Prince 5(4) and feeds the same window recorder.
#ifndef BISTABLE_DYNAMICS_POINT_H_
#define BISTABLE_DYNAMICS_POINT_H_

#include "dynamics/ensemble_rk4.h"
#include "dynamics/point_spec.h"
#include "dynamics/window_recorder.h"

namespace bistable {

// Validates, integrates, measures. Errors for invalid specs, and CancelledStatus() when cancellation
// (dynamics/cancel.h) stopped the integration: a cancelled point has no result at all. A diverging
// run is a result (termination != kOk, metrics NaN).
StatusOr<PointResult> EvaluatePoint(const PointSpec& spec);

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

// Window record → metrics (FRF, LLE, motion, period, spectrum, energy ratios, Rosenstein).
PointResult ComputePointMetrics(RawLane raw, const PointSpec& spec);
// The same for the n ≤ W lanes of a block (raw is moved from): the response spectra are computed
// side by side in lanes, and out[l] equals ComputePointMetrics(raw[l], specs[l]) bit for bit.
template <int W>
void ComputeBlockMetrics(RawLane* raw, const PointSpec* specs, int n, PointResult* out);

}  // namespace bistable

#endif  // BISTABLE_DYNAMICS_POINT_H_
