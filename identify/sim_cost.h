// Internal to identify/ (fit.cc and sim_cost.cc): the simulation error a fit minimises — every record simulated,
// the residual vectors of the objectives (fit.h), and the cost functions Ceres evaluates. Not part of identify's
// interface (fit.h, identify.h).
#ifndef BISTABLE_IDENTIFY_SIM_COST_H_
#define BISTABLE_IDENTIFY_SIM_COST_H_

#include <algorithm>
#include <array>
#include <cassert>
#include <memory>
#include <utility>
#include <vector>

#include <ceres/ceres.h>

#include "identify/fit.h"
#include "identify/model.h"
#include "identify/shooting.h"

namespace bistable {

// The records' simulations (SimulateAll); ok: none diverged.
struct Sims {
  std::vector<SimOutputs> o;  // per record: every output (and, when asked for, its sensitivities)
  bool ok = true;
};

// The substeps a simulation of record i at th runs: the held ones raised to what keeps RK4 stable (StableSubsteps),
// or, with none held, SubstepsFor's.
int SubstepsAt(const IdentModel& m, const std::vector<double>& th, const std::vector<PreparedRecord>& recs,
               const std::vector<int>& substeps, size_t i);

// Every record simulated (in parallel over records); with `extra` given, with sensitivities to the
// model's parameters and those terms'. `shoot`: the shooting objective's simulation (ShootRecord) with
// segments of horizon_s.
Sims SimulateAll(const IdentModel& m, const std::vector<double>& th, const std::vector<PreparedRecord>& recs,
                 const Setup& setup, const std::vector<int>& substeps, int threads, double horizon_s = 0,
                 const std::vector<const TermDef*>* extra = nullptr, std::vector<EarlyStop>* stops = nullptr,
                 bool shoot = false, const std::vector<std::vector<double>>* start = nullptr,
                 std::vector<std::vector<double>>* fitted = nullptr, bool whole = false, bool start_is_fitted = false);

// |FFT| / n of the velocity form of a compared output (the derivative of a displacement output), mean removed.
std::vector<double> VelocityMagnitudes(const std::vector<double>& series, double dt, bool displacement);

// The length of the objective's residual vector over the records.
size_t NumResiduals(const std::vector<PreparedRecord>& recs, Objective obj);

// Measured spectrum magnitudes per record and output slot (empty where not in the spectral objective).
using Magnitudes = std::vector<std::array<std::vector<double>, kOutputSlots>>;
Magnitudes MeasuredMagnitudes(const std::vector<PreparedRecord>& recs, const Setup& setup);

// The objective's residuals at scaled parameters u = θ / scale: the functor of Ceres' numeric differences and the
// cost of a fit's stages (copied, with other substeps, horizons or objectives, by each stage).
struct SimCost {
  const IdentModel* m;
  const std::vector<PreparedRecord>* recs;
  const Setup* setup;
  Objective obj;
  std::vector<int> substeps;
  std::vector<double> scale;
  Magnitudes meas_mag;
  int threads;
  double horizon_s = 0;  // > 0: short-horizon (multiple shooting) simulation error
  // Shooting objective: the segment states (ShootCache), shared by the copies of one fit's cost (one
  // evaluation at a time).
  std::shared_ptr<ShootCache> warm;
  mutable int calls = 0;
  std::vector<double> Theta(const double* u) const {
    std::vector<double> th(scale.size());
    for (size_t i = 0; i < th.size(); ++i) th[i] = u[i] * scale[i];
    return th;
  }
  bool operator()(double const* const* params, double* residuals) const;
  // The residuals at several scaled points u side by side (rs[l] for us[l]), records on `threads`: each record's
  // simulations in SIMD lanes (SimulateOutputsLanes) where they run the same substeps, one by one otherwise.
  // (Short horizons and segment states: one point after the other, through operator().)
  bool LaneResiduals(const std::vector<const double*>& us, std::vector<double>* rs, int threads) const;
  // Residuals and, when `jac` is given, their derivatives by the scaled parameters u (row-major,
  // Ceres' layout), from one sensitivity pass.
  bool Eval(const double* u, double* residuals, double* jac) const;
};

// The simulation error for Ceres with exact Jacobians (SimCost::Eval): one sensitivity pass per
// Jacobian where forward differences took a simulation per parameter.
class SimCostFunction : public ceres::DynamicCostFunction {
 public:
  // `start_tau` (optional): receives the correlation time (samples) of the first residual evaluated.
  explicit SimCostFunction(SimCost c, double* start_tau = nullptr) : c_(std::move(c)), start_tau_(start_tau) {}
  bool Evaluate(double const* const* params, double* residuals, double** jacobians) const override {
    const bool ok = c_.Eval(params[0], residuals, jacobians ? jacobians[0] : nullptr);
    if (ok && start_tau_ && !(*start_tau_ > 0))
      *start_tau_ = CorrelationTime(residuals, static_cast<size_t>(num_residuals()), 2000);
    return ok;
  }
  int Calls() const { return c_.calls; }

 private:
  SimCost c_;
  double* start_tau_;
};

// The spectral objective's forward-difference Jacobian: the arithmetic of Ceres'
// DynamicNumericDiffCostFunction<FORWARD> (step max(√ε, 1e-6 |u_j|), (r(u + δ e_j) − r(u)) · (1/δ)), so
// the same bits (Identify.ForwardDifferencesEqualCeresToTheBit). The residuals at u and the p columns'
// simulations run side by side in SIMD lanes, packs of up to kMaxSimLanes; more than one pack spread over
// `column_threads` (the CPUs the records leave idle), one pack with the records over the cost's threads.
class ForwardDiffFunction : public ceres::DynamicCostFunction {
 public:
  ForwardDiffFunction(SimCost c, int column_threads) : c_(std::move(c)), threads_(std::max(1, column_threads)) {
    assert(!c_.warm);  // segment states (shooting) are shared by copies: one evaluation at a time only
  }
  bool Evaluate(double const* const* params, double* residuals, double** jacobians) const override;

 private:
  SimCost c_;
  int threads_;
};

}  // namespace bistable

#endif  // BISTABLE_IDENTIFY_SIM_COST_H_
