// The system concept shared by the generic integrators (after odeint: a system is anything
// callable as sys(t, x, dxdt)). A System type provides
//   using State = Eigen::Matrix<double, N, 1>;   (N may be Eigen::Dynamic)
//   int dim() const;
//   void operator()(double t, const State& x, State& dxdt) const;          right-hand side
// and, for stiff solvers and tangent-linear Lyapunov exponents,
//   using Jacobian = Eigen::Matrix<double, N, N>;
//   void Jac(double t, const State& x, Jacobian& J, State& dfdt) const;     J = ∂f/∂x, dfdt = ∂f/∂t
// and optionally int tangent_dims() const (TangentDims below).
// Integrators never know which model they run.
#ifndef BISTABLE_DYNAMICS_ODE_H_
#define BISTABLE_DYNAMICS_ODE_H_

#include <algorithm>
#include <cmath>

#include <Eigen/Dense>

namespace bistable {

// The state components a model's tangent starts on (Benettin's LLE): a model that declares tangent_dims()
// (the rig or a term model without a resonator: 2 of its 4) starts its tangent on those only, the rest 0 —
// components whose tangent equations are dw = 0 would otherwise hold a constant floor under |w|, and a regular
// orbit's LLE read 0 instead of its negative rate. Others: every component.
template <class M>
int TangentDims(const M& m, int dim) {
  if constexpr (requires { m.tangent_dims(); })
    return m.tangent_dims();
  else
    return dim;
}

// How an adaptive integration ended (non-convergence is a result, not an error).
enum class OdeTermination { kOk, kStepSizeUnderflow, kMaxSteps, kNonFinite };
const char* OdeTerminationName(OdeTermination t);

struct AdaptiveOptions {
  double rtol = 1e-6;
  double atol = 1e-9;
  double h0 = 0;         // initial step; 0 picks one from the problem
  double h_max = 0;      // 0 = unlimited
  double h_min = 1e-14;  // relative to |t|+1; below this the run ends with kStepSizeUnderflow
  long max_steps = 50'000'000;
};

struct OdeSummary {
  OdeTermination termination = OdeTermination::kOk;
  long accepted = 0, rejected = 0;
  long rhs_evals = 0, jac_evals = 0, lu_decompositions = 0;
  double t_reached = 0;
};

// Step-size bookkeeping shared by the adaptive steppers: limits, landing on the end time, the
// controller's factor and the summary.
class AdaptiveControl {
 public:
  explicit AdaptiveControl(AdaptiveOptions opt) : opt_(opt) {}
  const AdaptiveOptions& options() const { return opt_; }

  // Before a trial step from t toward t1 with proposed size h: caps h at h_max, stretches or cuts the
  // last step to land on t1 (sets last). Returns kOk to go on, or the termination that ends the run.
  OdeTermination NextStep(double t, double t1, double& h, bool& last) {
    if (summary_.accepted + summary_.rejected >= opt_.max_steps) return End(OdeTermination::kMaxSteps, t);
    if (opt_.h_max > 0 && h > opt_.h_max) h = opt_.h_max;
    last = false;
    if (t + 1.01 * h >= t1) h = t1 - t, last = true;
    if (h < opt_.h_min * (std::fabs(t) + 1.0)) return End(OdeTermination::kStepSizeUnderflow, t);
    return OdeTermination::kOk;
  }
  // Step-size factor for scaled error norm err (≤ 1: accepted) of a method whose error estimate is
  // O(h^order): safety·err^(−1/order), clamped to [0.2, grow_max].
  static double Factor(double err, double order, double safety, double grow_max) {
    const double f = safety * std::pow(std::max(err, 1e-10), -1.0 / order);
    return std::min(grow_max, std::max(0.2, f));
  }
  OdeTermination End(OdeTermination term, double t) {
    summary_.termination = term;
    summary_.t_reached = t;
    return term;
  }
  OdeSummary& summary() { return summary_; }
  const OdeSummary& summary() const { return summary_; }

 private:
  AdaptiveOptions opt_;
  OdeSummary summary_;
};

}  // namespace bistable

#endif  // BISTABLE_DYNAMICS_ODE_H_
