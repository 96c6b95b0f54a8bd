// Pieces of a lane run shared by the cell kernel (ensemble_rk4.h) and the lane kernel of the other
// models (ensemble_generic.h): the forcing phase's re-anchoring, the schedule of the steps that need
// the general loop body, and the record of a cancelled run.
#ifndef BISTABLE_DYNAMICS_LANE_RUN_H_
#define BISTABLE_DYNAMICS_LANE_RUN_H_

#include <algorithm>
#include <cmath>

#include "dynamics/lanes.h"
#include "dynamics/window_recorder.h"

namespace bistable {

// (sin, cos)(Ω_l · step·h) per lane, from libm (the exact anchor the rotation restarts from).
template <int W>
void AnchorPhase(const double* omega, long step, double h, Vec<W>* sn, Vec<W>* cs) {
  const double t = static_cast<double>(step) * h;
  for (int l = 0; l < W; ++l) {
    (*sn)[l] = std::sin(omega[l] * t);
    (*cs)[l] = std::cos(omega[l] * t);
  }
}

inline long RoundUpTo(long n, long m) { return (n + m - 1) / m * m; }

// The first step ≥ step that needs the general loop body: the window's first step or the step before
// it (a renormalisation point), a step with a strobe due (next_strobe), a re-anchoring step (every
// `reanchor`), the next renormalisation the caller keeps in the general loop (next_renorm), or the last
// step n_total. The steps before it are ordinary: a call-free fast loop can do them.
inline long NextSpecialStep(long step, long n_total, long n_keep, long reanchor, long next_strobe, long next_renorm) {
  const long stop = std::min({n_total, next_renorm, RoundUpTo(step, reanchor)});
  if (step <= n_keep) return std::min(stop, n_keep);
  if (step == n_keep + 1) return step;
  return std::min(stop, next_strobe);
}

// Out of the hot loop: lanes of a cancelled run carry no result (marked diverged, steps short of the end).
[[gnu::cold, gnu::noinline]] inline bool MarkCancelled(int n, long step, RawLane* out) {
  for (int l = 0; l < n; ++l) {
    out[l] = RawLane{};
    out[l].diverged = true;
    out[l].steps = step;
  }
  return false;
}

}  // namespace bistable

#endif  // BISTABLE_DYNAMICS_LANE_RUN_H_
