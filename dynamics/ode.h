// The system concept shared by the generic integrators (after odeint: a system is anything
// callable as sys(t, x, dxdt)). A System type provides
//   using State = Eigen::Matrix<double, N, 1>;   (N may be Eigen::Dynamic)
//   int dim() const;
//   void operator()(double t, const State& x, State& dxdt) const;          right-hand side
// and, for stiff solvers and tangent-linear Lyapunov exponents,
//   using Jacobian = Eigen::Matrix<double, N, N>;
//   void Jac(double t, const State& x, Jacobian& J, State& dfdt) const;     J = ∂f/∂x, dfdt = ∂f/∂t
// Integrators never know which model they run.
#ifndef BISTABLE_DYNAMICS_ODE_H_
#define BISTABLE_DYNAMICS_ODE_H_

#include <Eigen/Dense>

namespace bistable {

// How an adaptive integration ended (non-convergence is a result, not an error).
enum class OdeTermination { kOk, kStepSizeUnderflow, kMaxSteps, kNonFinite };
const char* OdeTerminationName(OdeTermination t);

struct AdaptiveOptions {
  double rtol = 1e-6;
  double atol = 1e-9;
  double h0 = 0;           // initial step; 0 picks one from the problem
  double h_max = 0;        // 0 = unlimited
  double h_min = 1e-14;    // relative to |t|+1; below this the run ends with kStepSizeUnderflow
  long max_steps = 50'000'000;
};

struct OdeSummary {
  OdeTermination termination = OdeTermination::kOk;
  long accepted = 0, rejected = 0;
  long rhs_evals = 0, jac_evals = 0, lu_decompositions = 0;
  double t_reached = 0;
};

}  // namespace bistable

#endif  // BISTABLE_DYNAMICS_ODE_H_
