// Rosenbrock 2(3), the L-stable pair of Shampine & Reichelt (SIAM J. Sci. Comput. 18, 1997;
// MATLAB's ode23s) for stiff systems: one Jacobian and one LU factorisation per step, three
// right-hand-side evaluations (FSAL), 2nd-order solution with a 3rd-order error estimate and
// free continuous output. Needs System::Jac (see ode.h). Chosen for the dimensional friction model,
// whose Stribeck/tanh terms at v_t = 1 mm/s make explicit methods crawl during sticking.
#ifndef BISTABLE_DYNAMICS_ROSENBROCK23_H_
#define BISTABLE_DYNAMICS_ROSENBROCK23_H_

#include <algorithm>
#include <cmath>

#include <Eigen/LU>

#include "dynamics/ode.h"

namespace bistable {

template <class System>
class Rosenbrock23 {
 public:
  using State = typename System::State;
  using Jacobian = typename System::Jacobian;

  Rosenbrock23(const System& sys, AdaptiveOptions opt) : sys_(sys), ctl_(opt) {
    const int n = sys.dim();
    for (State* s : {&f0_, &f1_, &f2_, &k1_, &k2_, &k3_, &dfdt_, &tmp_, &y1_, &x_old_}) s->resize(n);
    J_.resize(n, n);
    W_.resize(n, n);
  }

  template <class Observer>
  OdeTermination Integrate(double t0, State& x, double t1, Observer&& observer) {
    static const double d = 1.0 / (2.0 + std::sqrt(2.0)), e32 = 6.0 + std::sqrt(2.0);
    OdeSummary& sum = ctl_.summary();
    const AdaptiveOptions& opt = ctl_.options();
    double t = t0;
    sys_(t, x, f0_);
    ++sum.rhs_evals;
    double h = h_next_ > 0 ? h_next_ : (opt.h0 > 0 ? opt.h0 : 1e-4 * std::max(1.0, t1 - t0));
    bool need_jac = true;
    const int n = sys_.dim();
    while (t < t1) {
      bool last = false;
      if (const OdeTermination term = ctl_.NextStep(t, t1, h, last); term != OdeTermination::kOk) return term;
      if (need_jac) {
        sys_.Jac(t, x, J_, dfdt_);
        ++sum.jac_evals;
        need_jac = false;
      }
      W_ = Jacobian::Identity(n, n) - (h * d) * J_;
      Eigen::PartialPivLU<Jacobian> lu(W_);
      ++sum.lu_decompositions;
      k1_ = lu.solve(State(f0_ + (h * d) * dfdt_));
      tmp_ = x + (0.5 * h) * k1_;
      sys_(t + 0.5 * h, tmp_, f1_);
      k2_ = lu.solve(State(f1_ - k1_)) + k1_;
      y1_ = x + h * k2_;
      sys_(t + h, y1_, f2_);
      k3_ = lu.solve(State(f2_ - e32 * (k2_ - f1_) - 2.0 * (k1_ - f0_) + (h * d) * dfdt_));
      sum.rhs_evals += 2;
      tmp_ = (h / 6.0) * (k1_ - 2.0 * k2_ + k3_);
      double err = 0;
      for (int i = 0; i < n; ++i) {
        const double sk = opt.atol + opt.rtol * std::max(std::fabs(x[i]), std::fabs(y1_[i]));
        err = std::max(err, std::fabs(tmp_[i]) / sk);
      }
      if (!std::isfinite(err)) err = 1e10;
      if (err <= 1.0) {
        x_old_ = x;
        t_old_ = t;
        h_dense_ = h;
        t = last ? t1 : t + h;
        t_ = t;
        x = y1_;
        f0_ = f2_;
        ++sum.accepted;
        need_jac = true;
        observer(*this);
        h_next_ = h * AdaptiveControl::Factor(err, 3.0, 0.8, 5.0);
        if (!last) h = h_next_;
      } else {
        ++sum.rejected;
        h *= AdaptiveControl::Factor(err, 3.0, 0.8, 1.0);
      }
    }
    return ctl_.End(OdeTermination::kOk, t);
  }
  OdeTermination Integrate(double t0, State& x, double t1) {
    return Integrate(t0, x, t1, [](const Rosenbrock23&) {});
  }

  double t_old() const { return t_old_; }
  double t() const { return t_; }
  // Continuous extension of the last step (2nd order).
  void Interpolate(double t, State& out) const {
    static const double d = 1.0 / (2.0 + std::sqrt(2.0));
    const double s = (t - t_old_) / h_dense_;
    out = x_old_ + h_dense_ * ((s * (1 - s) / (1 - 2 * d)) * k1_ + (s * (s - 2 * d) / (1 - 2 * d)) * k2_);
  }
  const OdeSummary& summary() const { return ctl_.summary(); }

 private:
  const System& sys_;
  AdaptiveControl ctl_;
  State f0_, f1_, f2_, k1_, k2_, k3_, dfdt_, tmp_, y1_, x_old_;
  Jacobian J_, W_;
  double t_old_ = 0, t_ = 0, h_dense_ = 1, h_next_ = 0;
};

}  // namespace bistable

#endif  // BISTABLE_DYNAMICS_ROSENBROCK23_H_
