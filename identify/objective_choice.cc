// The objective chosen from the records (issue 37): whether each record's long simulation can mean anything,
// the short horizons where it cannot (ChooseHorizons), and the shooting fit continued to the long simulation
// where the model follows every record (ContinueToLongSimulation). The loop that uses them is identify/loop.cc.
#include "dynamics/cancel.h"
#include "identify/loop.h"

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <iterator>
#include <optional>
#include <random>
#include <thread>
#include <utility>

#include "base/beside.h"
#include "base/cpus.h"

#include "identify/loop_parts.h"

namespace bistable {

ObjectiveChoice ChooseHorizons(const IdentModel& m, std::vector<PreparedRecord>* recs, const Setup& setup,
                               const IdentifyOptions& opt) {
  const auto t0 = std::chrono::steady_clock::now();
  ObjectiveChoice c;
  c.made = true;
  const double horizon = opt.fit.shooting_horizon_s > 0 ? opt.fit.shooting_horizon_s : 0.5;
  c.model = "regression start";
  bool refine = false;
  for (PreparedRecord& r : *recs) {
    r.horizon_s = 0;
    Predictability p = TestPredictability(m, m.theta, r, setup, horizon);
    refine = refine || !p.long_meaningful || p.well_changes >= 2;
    r.snaps = p.well_changes >= 2;
    c.records.push_back(std::move(p));
  }
  if (refine && !CancelRequested()) {
    // A model near the vector field: the declared model fitted on short horizons only (a tenth of a second
    // from band-limited states, where the true model of a snap-through record stays at its noise floor).
    const double pre = std::min(horizon, kPrefitHorizon);
    std::vector<PreparedRecord> shortened = *recs;
    for (PreparedRecord& r : shortened) r.horizon_s = pre, BandLimitedRestarts(&r);
    FitOptions fo = opt.fit;
    fo.global_evals = 0;
    fo.shooting_horizon_s = pre;
    std::vector<double> sigma0(m.theta.size(), NAN);
    const FitResult f = Fit(m, ScaleOf(m, m.theta, sigma0, shortened, setup), shortened, setup, fo);
    if (std::all_of(f.theta.begin(), f.theta.end(), [](double v) { return std::isfinite(v); })) {
      c.model = "short-horizon fit";
      c.theta = f.theta;
      c.records.clear();
      for (PreparedRecord& r : *recs) {
        c.records.push_back(TestPredictability(m, f.theta, r, setup, horizon, /*require_followed=*/true));
        r.snaps = r.snaps || c.records.back().well_changes >= 2;
      }
    }
  }
  const std::vector<double>& decider = c.theta.empty() ? m.theta : c.theta;
  for (size_t i = 0; i < recs->size(); ++i) {
    PreparedRecord& r = (*recs)[i];
    r.horizon_s = 0;
    r.chaotic = c.records[i].fit_horizon_s > 0;
    if (!r.chaotic) continue;
    BandLimitedRestarts(&r);
    // Segments the state fit can follow (kFollowableGrowth): halve the twins' horizon until the decision
    // model's shooting error on it is within kFollowableGrowth of its error on kPrefitHorizon segments.
    Predictability& p = c.records[i];
    const double h0 = std::min(kPrefitHorizon, p.fit_horizon_s);
    if (p.fit_horizon_s > h0 && !CancelRequested()) {
      const double e0 = Evaluate(m, decider, {r}, setup, h0).shooting;
      double h = p.fit_horizon_s, e = Evaluate(m, decider, {r}, setup, h).shooting;
      const double twins_h = h, twins_e = e;
      while (h > h0 && !(e <= kFollowableGrowth * e0) && !CancelRequested()) {
        h = std::max(h0, 0.5 * h);
        e = h > h0 ? Evaluate(m, decider, {r}, setup, h).shooting : e0;
      }
      if (h < twins_h) {
        char buf[240];
        std::snprintf(buf, sizeof buf,
                      "; shortened to %.3g s: from fitted states the model's error on %.3g s segments is %.3g %%, "
                      "%.3g× its %.3g %% on "
                      "%.3g s segments (at most %.3g×: the segment's state fit no longer finds the orbit)",
                      h, twins_h, twins_e, twins_e / e0, e0, h0, kFollowableGrowth);
        p.reason += buf;
        p.fit_horizon_s = h;
      }
    }
    c.objective = Objective::kShooting;
    c.horizon_s = c.horizon_s > 0 ? std::min(c.horizon_s, c.records[i].fit_horizon_s) : c.records[i].fit_horizon_s;
  }
  c.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return c;
}

// Horizon continuation (ObjectiveChoice::Continuation): the final model m (fitted as *fit by multiple
// shooting) is tested again;
// where it follows every record and its twins stay together, m's long simulation is fitted from *fit (local
// stage: the start is in the valley) and replaces *fit when its long simulation error is lower. The errors
// keep the shooting error too (the objective the loop ran).
void ContinueToLongSimulation(const IdentModel& m, FitResult* fit, const std::vector<PreparedRecord>& recs,
                              const Setup& setup, const IdentifyOptions& opt, ObjectiveChoice::Continuation* c) {
  *c = ObjectiveChoice::Continuation{};
  const double horizon = opt.fit.shooting_horizon_s;
  std::vector<PreparedRecord> whole = recs;  // the records as the time objective sees them
  for (PreparedRecord& r : whole) r.horizon_s = 0, r.chaotic = false;
  c->tried = true;
  bool all = true;
  for (const PreparedRecord& r : whole) {
    c->records.push_back(TestPredictability(m, fit->theta, r, setup, horizon, /*require_followed=*/true));
    all = all && c->records.back().long_meaningful;
  }
  c->long_before = fit->errors.long_nrmse;
  if (!all) {
    c->reason = "the final model does not follow every record within " +
                std::to_string(static_cast<int>(kMeaningfulFloor)) +
                " % with predictable twins: the shooting fit stands";
    return;
  }
  FitOptions fo = opt.fit;
  fo.objective = Objective::kTime;
  fo.shooting_horizon_s = 0;  // from the shooting fit: no short-horizon stages, no global stage
  fo.global_evals = 0;
  IdentModel start = m;
  start.theta = fit->theta;
  FitResult t = Fit(start, ScaleOf(start, start.theta, fit->sigma, whole, setup), whole, setup, fo);
  t.errors = Evaluate(m, t.theta, recs, setup, horizon);
  c->long_after = t.errors.long_nrmse;
  const bool finite = std::all_of(t.theta.begin(), t.theta.end(), [](double v) { return std::isfinite(v); });
  if (!finite || !Physical(m, t.theta) || !(t.errors.long_nrmse < fit->errors.long_nrmse)) {
    c->reason =
        "the final model follows every record, but its long simulation's fit did not lower the long simulation error: "
        "the shooting fit stands";
    return;
  }
  c->ran = true;
  char buf[320];
  std::snprintf(buf, sizeof buf,
                "the final model follows every record with predictable twins: its long simulation was fitted from the "
                "shooting fit "
                "(long simulation error %.3g %% -> %.3g %%; short-horizon error %.3g %% -> %.3g %%)",
                fit->errors.long_nrmse, t.errors.long_nrmse, fit->errors.shooting, t.errors.shooting);
  c->reason = buf;
  t.simulations += fit->simulations;
  *fit = std::move(t);
}

}  // namespace bistable
