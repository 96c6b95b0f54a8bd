// Largest Lyapunov exponent of a model by the tangent-linear (Benettin et al. 1980) method:
// integrate x' = f(t, x) together with w' = J(t, x) w by RK4, renormalise w every `renorm_every`
// steps and average log|w| growth after a transient. Generic over any System with Jac (ode.h).
// (The SIMD ensemble kernel does the same inline for the paper's models.)
#ifndef BISTABLE_DYNAMICS_BENETTIN_H_
#define BISTABLE_DYNAMICS_BENETTIN_H_

#include <cmath>
#include <vector>

#include "dynamics/eigen_bounds.h"
#include "dynamics/rk4.h"

namespace bistable {

BISTABLE_EIGEN_BOUNDS_BEGIN  // blocks of run-time size n over the systems' fixed-size states

    // The system (x, w) ↦ (f(t, x), J(t, x) w) of size 2n.
    template <class System>
    class TangentSystem {
 public:
  using State = Eigen::VectorXd;
  explicit TangentSystem(const System& sys) : sys_(sys), n_(sys.dim()) {
    x_.resize(n_), fx_.resize(n_), dfdt_.resize(n_);
    J_.resize(n_, n_);
  }
  int dim() const { return 2 * n_; }
  void operator()(double t, const State& z, State& dz) const {
    x_ = z.head(n_);
    sys_(t, x_, fx_);
    sys_.Jac(t, x_, J_, dfdt_);
    dz.head(n_) = fx_;
    dz.tail(n_) = J_ * z.tail(n_);
  }

 private:
  const System& sys_;
  int n_;
  mutable typename System::State x_, fx_, dfdt_;
  mutable typename System::Jacobian J_;
};

struct BenettinOptions {
  double h = 0.01;           // RK4 step
  double t_transient = 100;  // discarded before averaging
  double t_average = 1000;   // averaging length
  int renorm_every = 10;     // steps between renormalisations
};

struct BenettinResult {
  double lle = 0;               // per unit time
  std::vector<double> running;  // running estimate after each renormalisation in the average
};

template <class System>
BenettinResult BenettinLle(const System& sys, const typename System::State& x0, double t0, const BenettinOptions& opt) {
  const int n = sys.dim();
  TangentSystem<System> tan(sys);
  Eigen::VectorXd z(2 * n);
  z.head(n) = x0;
  z.tail(n).setConstant(1.0 / std::sqrt(static_cast<double>(n)));
  Rk4<TangentSystem<System>> rk(tan);
  const long n_tr = std::lround(opt.t_transient / opt.h), n_av = std::lround(opt.t_average / opt.h);
  BenettinResult res;
  double sum = 0, t = t0;
  for (long i = 1; i <= n_tr + n_av; ++i) {
    rk.Step(t, z, opt.h);
    t = t0 + static_cast<double>(i) * opt.h;
    if (i % opt.renorm_every == 0 || i == n_tr || i == n_tr + n_av) {
      const double nrm = z.tail(n).norm();
      z.tail(n) /= nrm;
      if (i > n_tr) {
        sum += std::log(nrm);
        res.running.push_back(sum / (static_cast<double>(i - n_tr) * opt.h));
      }
    }
  }
  res.lle = sum / (static_cast<double>(n_av) * opt.h);
  return res;
}

BISTABLE_EIGEN_BOUNDS_END

}  // namespace bistable

#endif  // BISTABLE_DYNAMICS_BENETTIN_H_
