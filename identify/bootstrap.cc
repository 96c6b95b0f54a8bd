#include "identify/bootstrap.h"

#include <algorithm>
#include <chrono>
#include <cmath>

#include "base/beside.h"
#include "dynamics/cancel.h"
#include "identify/loop_parts.h"
#include "identify/predictability.h"

namespace bistable {

BootstrapResult BootstrapFit(const IdentModel& m, const FitResult& fit, const std::vector<PreparedRecord>& recs,
                             const Setup& setup, FitOptions fo, int twins) {
  const auto t0 = std::chrono::steady_clock::now();
  BootstrapResult b;
  b.twins = twins;
  b.gauss_newton_sigma = fit.sigma;
  const double horizon = fo.objective == Objective::kShooting ? fo.shooting_horizon_s : 0.0;
  // Twin sets two at a time (twin k's noise depends on k alone: the same twins as all at once), so memory holds
  // two sets of records, not N (256 twins of 21 long records would be gigabytes).
  auto pair = [&](int k) {
    return TwinRecords(m, fit.theta, recs, setup, std::min(2, twins - k), horizon, TwinNoise::kResidualBlocks, k);
  };
  std::vector<std::vector<PreparedRecord>> sets = pair(0);
  if (sets.empty()) {
    b.note = setup.input == InputKind::kForce ? "a force input cannot be recorded again (no twin records)"
             : setup.output == OutputKind::kVelocity && setup.frame == OutputFrame::kRelative
                 ? "a velocity output in the relative frame cannot be recorded again (no twin records)"
                 : "the final model's simulation of a record diverged (no twin records)";
    return b;
  }
  // Each refit: the final objective's local stage from the final parameters (the twins' truth), one thread.
  fo.global_evals = 0;
  fo.threads = 1;
  if (fo.objective == Objective::kTime) fo.shooting_horizon_s = 0;
  IdentModel start = m;
  start.theta = fit.theta;
  const std::vector<double> scale = ScaleOf(start, start.theta, fit.sigma, recs, setup);
  std::vector<std::vector<double>> thetas(static_cast<size_t>(twins));
  auto one = [&](int k, size_t i) {
    if (i >= sets.size() || CancelRequested()) return;
    const FitResult f = Fit(start, scale, sets[i], setup, fo);
    const bool finite = std::all_of(f.theta.begin(), f.theta.end(), [](double v) { return std::isfinite(v); });
    if (finite && Physical(m, f.theta)) thetas[static_cast<size_t>(k + static_cast<int>(i))] = f.theta;
  };
  for (int k = 0; k < twins && !CancelRequested(); k += 2) {
    if (k > 0) sets = pair(k);
    RunBeside([&] { one(k, 1); }, [&] { one(k, 0); });
  }
  const long p = static_cast<long>(fit.theta.size());
  std::vector<Eigen::VectorXd> got;
  for (const std::vector<double>& th : thetas)
    if (static_cast<long>(th.size()) == p) got.push_back(Eigen::Map<const Eigen::VectorXd>(th.data(), p));
  b.fitted = static_cast<int>(got.size());
  b.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  if (b.fitted < p + 1) {  // fewer samples than parameters + 1: a covariance of lower rank than the model's
    b.note = std::to_string(b.fitted) + " of the " + std::to_string(twins) +
             " refits ended finite and physical, fewer than the parameters + 1 (" + std::to_string(p + 1) +
             "): the Gauss–Newton covariance stands";
    return b;
  }
  Eigen::VectorXd mean = Eigen::VectorXd::Zero(p);
  for (const Eigen::VectorXd& v : got) mean += v;
  mean /= static_cast<double>(got.size());
  Eigen::MatrixXd cov = Eigen::MatrixXd::Zero(p, p);
  for (const Eigen::VectorXd& v : got) cov += (v - mean) * (v - mean).transpose();
  cov /= static_cast<double>(got.size() - 1);
  b.mean.assign(mean.data(), mean.data() + p);
  for (long i = 0; i < p; ++i)
    if (!(cov(i, i) > 0)) {  // every refit at the same value (a bound): "exact" is not an uncertainty
      b.note = "parameter " + std::to_string(i) +
               " took the same value in every refit (a bound?): the Gauss–Newton covariance stands";
      return b;
    }
  b.covariance = cov;
  return b;
}

}  // namespace bistable
