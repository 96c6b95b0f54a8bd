// Classical fixed-step fourth-order Runge–Kutta for any System (see ode.h).
#ifndef BISTABLE_DYNAMICS_RK4_H_
#define BISTABLE_DYNAMICS_RK4_H_

#include <cmath>

#include "dynamics/ode.h"

namespace bistable {

template <class System>
class Rk4 {
 public:
  using State = typename System::State;
  explicit Rk4(const System& sys) : sys_(sys) {
    const int n = sys.dim();
    k1_.resize(n), k2_.resize(n), k3_.resize(n), k4_.resize(n), tmp_.resize(n);
  }
  // Advances x from t to t + h.
  void Step(double t, State& x, double h) {
    sys_(t, x, k1_);
    tmp_ = x + (0.5 * h) * k1_;
    sys_(t + 0.5 * h, tmp_, k2_);
    tmp_ = x + (0.5 * h) * k2_;
    sys_(t + 0.5 * h, tmp_, k3_);
    tmp_ = x + h * k3_;
    sys_(t + h, tmp_, k4_);
    x += (h / 6.0) * (k1_ + 2.0 * k2_ + 2.0 * k3_ + k4_);
  }
  // n steps of size h from t0; observer(t, x) is called after each step when given.
  template <class Observer>
  void Integrate(double t0, State& x, double h, long n, Observer&& observer) {
    for (long i = 1; i <= n; ++i) {
      Step(t0 + static_cast<double>(i - 1) * h, x, h);
      observer(t0 + static_cast<double>(i) * h, x);
    }
  }
  void Integrate(double t0, State& x, double h, long n) {
    Integrate(t0, x, h, n, [](double, const State&) {});
  }

 private:
  const System& sys_;
  State k1_, k2_, k3_, k4_, tmp_;
};

}  // namespace bistable

#endif  // BISTABLE_DYNAMICS_RK4_H_
