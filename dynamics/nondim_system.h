// Adapters that present the non-dimensional models (nondim_models.h) as generic Systems (ode.h),
// with the base forcing f(τ) = αΩ² sin(Ωτ) evaluated directly.
#ifndef BISTABLE_DYNAMICS_NONDIM_SYSTEM_H_
#define BISTABLE_DYNAMICS_NONDIM_SYSTEM_H_

#include <cmath>

#include <Eigen/Dense>

#include "dynamics/lanes.h"
#include "dynamics/nondim_models.h"

namespace bistable {

// State (x, w, q): model state x, tangent w (w' = J w) and the four window quadratures
// q = (∫P, ∫max(P,0), W_m, W_r), which advance only while set_window(true).
template <class Model>
class AugmentedNondimSystem {
 public:
  static constexpr int D = Model::kDim;
  static constexpr int N = 2 * D + 4;
  using State = Eigen::Matrix<double, N, 1>;

  AugmentedNondimSystem(const CellCoeffs<double>& c, double alpha, double omega)
      : c_{{c.k_lin}, {c.eps}, {c.eta}, {c.eta_r}, {c.phi}, {c.lambda2}}, amp_(alpha * omega * omega), omega_(omega) {}
  int dim() const { return N; }
  void set_window(bool on) { window_ = on; }
  void operator()(double t, const State& z, State& dz) const {
    Vec<1> x[D], w[D], dx[D], dw[D];
    for (int d = 0; d < D; ++d) x[d][0] = z[d], w[d][0] = z[D + d];
    const Vec<1> f = {amp_ * std::sin(omega_ * t)};
    Model::Rhs(c_, x, f, dx);
    Model::Tangent(c_, x, w, dw);
    for (int d = 0; d < D; ++d) dz[d] = dx[d][0], dz[D + d] = dw[d][0];
    if (window_) {
      const double p = Model::Power(c_, x, f)[0];
      dz[2 * D] = p;
      dz[2 * D + 1] = p > 0 ? p : 0.0;
      dz[2 * D + 2] = Model::DissMain(c_, x)[0];
      dz[2 * D + 3] = Model::DissRes(c_, x)[0];
    } else {
      dz.template tail<4>().setZero();
    }
  }

 private:
  CellCoeffs<Vec<1>> c_;
  double amp_, omega_;
  bool window_ = false;
};

// Plain model state as a System with Jacobian (for generic integrators and Benettin).
template <class Model>
class NondimSystem {
 public:
  static constexpr int D = Model::kDim;
  using State = Eigen::Matrix<double, D, 1>;
  using Jacobian = Eigen::Matrix<double, D, D>;
  NondimSystem(const CellCoeffs<double>& c, double alpha, double omega)
      : c_{{c.k_lin}, {c.eps}, {c.eta}, {c.eta_r}, {c.phi}, {c.lambda2}}, amp_(alpha * omega * omega), omega_(omega) {}
  int dim() const { return D; }
  void operator()(double t, const State& z, State& dz) const {
    Vec<1> x[D], dx[D];
    for (int d = 0; d < D; ++d) x[d][0] = z[d];
    Model::Rhs(c_, x, Vec<1>{amp_ * std::sin(omega_ * t)}, dx);
    for (int d = 0; d < D; ++d) dz[d] = dx[d][0];
  }
  // Columns of J by the model's tangent map applied to unit vectors.
  void Jac(double t, const State& z, Jacobian& J, State& dfdt) const {
    Vec<1> x[D], e[D], col[D];
    for (int d = 0; d < D; ++d) x[d][0] = z[d];
    for (int j = 0; j < D; ++j) {
      for (int d = 0; d < D; ++d) e[d][0] = (d == j);
      Model::Tangent(c_, x, e, col);
      for (int d = 0; d < D; ++d) J(d, j) = col[d][0];
    }
    const double df = amp_ * omega_ * std::cos(omega_ * t);
    dfdt.setZero();
    dfdt[1] = df;
    if constexpr (D > 2) dfdt[3] = df;
  }

 private:
  CellCoeffs<Vec<1>> c_;
  double amp_, omega_;
};

}  // namespace bistable

#endif  // BISTABLE_DYNAMICS_NONDIM_SYSTEM_H_
