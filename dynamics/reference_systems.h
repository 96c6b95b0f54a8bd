// Systems with published Lyapunov exponents, used to verify the LLE estimators.
#ifndef BISTABLE_DYNAMICS_REFERENCE_SYSTEMS_H_
#define BISTABLE_DYNAMICS_REFERENCE_SYSTEMS_H_

#include <cmath>

#include <Eigen/Dense>

namespace bistable {

// Lorenz (1963): x' = σ(y − x), y' = x(ρ − z) − y, z' = xy − βz. σ 10, ρ 28, β 8/3: LLE ≈ 0.9056.
struct LorenzSystem {
  using State = Eigen::Vector3d;
  using Jacobian = Eigen::Matrix3d;
  double sigma = 10, rho = 28, beta = 8.0 / 3.0;
  int dim() const { return 3; }
  void operator()(double, const State& x, State& dx) const {
    dx << sigma * (x[1] - x[0]), x[0] * (rho - x[2]) - x[1], x[0] * x[1] - beta * x[2];
  }
  void Jac(double, const State& x, Jacobian& J, State& dfdt) const {
    J << -sigma, sigma, 0, rho - x[2], -1, -x[0], x[1], x[0], -beta;
    dfdt.setZero();
  }
};

// Forced double-well Duffing x'' + δx' − x + x³ = γ cos(ωt) (Guckenheimer & Holmes' classic).
struct DuffingSystem {
  using State = Eigen::Vector2d;
  using Jacobian = Eigen::Matrix2d;
  double delta = 0.3, gamma = 0.5, omega = 1.2;
  int dim() const { return 2; }
  void operator()(double t, const State& x, State& dx) const {
    dx << x[1], -delta * x[1] + x[0] - x[0] * x[0] * x[0] + gamma * std::cos(omega * t);
  }
  void Jac(double t, const State& x, Jacobian& J, State& dfdt) const {
    J << 0, 1, 1 - 3 * x[0] * x[0], -delta;
    dfdt << 0, -gamma * omega * std::sin(omega * t);
  }
};

}  // namespace bistable

#endif  // BISTABLE_DYNAMICS_REFERENCE_SYSTEMS_H_
