// Multiple shooting with re-estimated segment states (the shooting objective, Objective::kShooting, of fit.h):
// one record's segments simulated from states fitted per segment, and the states a fit carries from one
// evaluation to the next. Internal to identify/ (the objective of fit.cc and sim_cost.cc).
#ifndef BISTABLE_IDENTIFY_SHOOTING_H_
#define BISTABLE_IDENTIFY_SHOOTING_H_

#include <utility>
#include <vector>

#include "identify/model.h"

namespace bistable {

// Multiple shooting with re-estimated states (Objective::kShooting) on one record: segments of `every`
// samples, each from its own start state x_k. For the given θ every x_k is fitted by Levenberg–Marquardt
// on its segment's weighted error (all segments in one simulation pass per iteration; a segment whose
// trial step raises its error keeps its state and raises its damping), started from the measured
// (smoothed) state. `out` receives the outputs at the fitted states; with `extra` (sensitivities asked
// for) also d: ∂out/∂θ with each segment's state directions projected out (Kaufman's variable-projection
// Jacobian: the derivative of the error with the states re-fitted). Only the states the model moves and
// the data constrain are fitted: p, p' (main body), r, r' with a resonator, w with a piezo and a
// measured voltage. `start` (optional): states fitted at an earlier θ of the same fit (ShootCache) — the
// start instead of the scan below (multiple shooting proper carries its states from iteration to
// iteration); empty or of another size: a cold start. `start_is_fitted`: `start` holds the states fitted at
// this θ already (ShootCache::At), so no pass runs. `fitted` (optional) receives the states fitted.
// False when the simulation at the start diverges.
bool ShootRecord(const IdentModel& m, const std::vector<double>& th, const std::vector<const TermDef*>* extra,
                 const PreparedRecord& r, const Setup& setup, int substeps, int every, SimOutputs* out,
                 const std::vector<double>* start = nullptr, std::vector<double>* fitted = nullptr, int threads = 1,
                 bool start_is_fitted = false);

// The shooting objective's segment states within one fit: the anchor every evaluation starts from (the
// states at the last accepted point), and the states fitted at the last few evaluated θ, one of which
// the fit promotes when it accepts that point (LocalStage's iteration callback). Only accepted points may
// become the anchor: with the last evaluation's states instead, a rejected trial step far from the
// solution (or a line-search probe) moved the anchor into other minima, the objective jumped between
// evaluations at almost the same θ, and Ceres refused every step (seen on the harvester).
struct ShootCache {
  std::vector<std::vector<double>> anchor;  // per record; empty: cold starts
  int version = 0;                          // changes with the anchor
  struct Fitted {
    std::vector<double> th;
    int version;  // the anchor they were fitted from
    std::vector<std::vector<double>> states;
  };
  std::vector<Fitted> recent;
  void Remember(const std::vector<double>& th, int from_version, std::vector<std::vector<double>> states) {
    if (recent.size() >= 8) recent.erase(recent.begin());
    recent.push_back({th, from_version, states});
    if (anchor.empty())
      anchor = std::move(states), ++version;  // the fit's first evaluation (its start) anchors the first steps
  }
  void Promote(const std::vector<double>& th) {
    for (auto it = recent.rbegin(); it != recent.rend(); ++it)
      if (it->th == th) {
        anchor = it->states;
        ++version;
        return;
      }
  }
  // A new round of a stage (other substeps held): the states fitted so far were fitted under the old
  // substeps, so none is reused as fitted; the anchor stays the next evaluations' start.
  void NewRound() {
    recent.clear();
    ++version;
  }
  // The states fitted at th from today's anchor, if they are at hand. Ceres evaluates an accepted point
  // again for its Jacobian, and the state fit from the same anchor is deterministic: it would give the
  // same states (on a coupled record with 240 segments each evaluation ran 60 passes, three times per θ).
  const std::vector<std::vector<double>>* At(const std::vector<double>& th) const {
    for (auto it = recent.rbegin(); it != recent.rend(); ++it)
      if (it->version == version && it->th == th) return &it->states;
    return nullptr;
  }
};

}  // namespace bistable

#endif  // BISTABLE_IDENTIFY_SHOOTING_H_
