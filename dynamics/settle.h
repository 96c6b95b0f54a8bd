// Settled labels (issue 38; docs/numerics.md, "Settled labels"): a point is integrated in a chain of
// windows (EnsembleRk4::RunChain) until its label has settled, instead of being read from one fixed
// window. A lane's windows are `settle_window` τ long (several, for a low Ω, so that each spans
// `settle_min_strobes` forcing periods); after every window of the lane:
//  - λ and its block-average error σ_λ come from the cumulative log-stretch over the second half of the
//    run since t_keep ([T/2, T] in τ − t_keep), in ≥ 10 blocks of the kernel's growth batches;
//  - periodic: the last two windows give the same period n ≥ 1 (strobe recurrence) and the same well,
//    λ + 2σ < 0, and for n ≥ 2 the strobe cloud keeps its rms size within 3 % (a decaying flip
//    transient alternates from strobe to strobe and passes the recurrence while it shrinks);
//  - chaotic: the run has reached t_keep + settle_confirm, λ − 2σ > chaos_threshold, the last two
//    windows are chaotic with no period, and the 0-1 test on the strobes of [T/2, T] agrees (K > 1/2);
//  - quasi-periodic/marginal: the run has reached t_keep + settle_confirm, no period in the last two
//    windows, |λ| ≤ quasi_lle, λ + 2σ < chaos_threshold, and the strobe cloud keeps its size (ratio of the
//    two windows' rms spreads in [0.8, 1.25]: a decaying transient shrinks);
//  - otherwise the run goes on, and at t_keep + settle_cap (at least two windows) the label is
//    "unresolved".
// Lanes that have not settled are suspended at tier boundaries (t_keep + 2 windows, then every window) and resumed
// side by side in fresh blocks; a resumed lane continues exactly (state, tangent and forcing phase as
// the kernel carries them), so a point's bits do not depend on its block, and `bistable point` (one
// lane) equals the map.
#ifndef BISTABLE_DYNAMICS_SETTLE_H_
#define BISTABLE_DYNAMICS_SETTLE_H_

#include <cstddef>

#include "dynamics/point_spec.h"

namespace bistable {

// The 0-1 test for chaos (settle.cc): K, the median over 16 fixed c of the correlation of the modified
// mean square displacement with its lag, on the latest ≤ 400 of phi[0..n); NaN when n < 64.
double ZeroOneTestK(const double* phi, size_t n);

// Evaluates specs[0..n) (cell models, RK4, labels = settled, one sweep: the same model, step, window,
// cap and t_keep) W lanes at a time into out[0..n). False when cancelled (out then holds no result).
template <int W>
bool EvaluateSettled(const PointSpec* specs, size_t n, PointResult* out);

}  // namespace bistable

#endif  // BISTABLE_DYNAMICS_SETTLE_H_
