// Dormand–Prince 5(4) with error control and 4th-order dense output (Hairer, Nørsett & Wanner,
// "Solving ODEs I", DOPRI5 with CONTD5), for any System (see ode.h). FSAL: 6 evaluations per step.
#ifndef BISTABLE_DYNAMICS_DOPRI5_H_
#define BISTABLE_DYNAMICS_DOPRI5_H_

#include <algorithm>
#include <cmath>

#include "dynamics/ode.h"

namespace bistable {

template <class System>
class Dopri5 {
 public:
  using State = typename System::State;

  Dopri5(const System& sys, AdaptiveOptions opt) : sys_(sys), ctl_(opt) {
    const int n = sys.dim();
    for (State* s : {&k1_, &k2_, &k3_, &k4_, &k5_, &k6_, &k7_, &y1_, &tmp_, &r1_, &r2_, &r3_, &r4_, &r5_}) s->resize(n);
  }

  // Integrates x from t0 to t1 (t1 > t0). After every accepted step observer(*this) may call
  // t_old(), t() and Interpolate(t, out) for t in [t_old, t]. Returns how it ended.
  template <class Observer>
  OdeTermination Integrate(double t0, State& x, double t1, Observer&& observer) {
    OdeSummary& sum = ctl_.summary();
    double t = t0;
    sys_(t, x, k1_);
    ++sum.rhs_evals;
    double h = h_next_ > 0 ? h_next_ : (ctl_.options().h0 > 0 ? ctl_.options().h0 : InitialStep(t, x));
    while (t < t1) {
      bool last = false;
      if (const OdeTermination term = ctl_.NextStep(t, t1, h, last); term != OdeTermination::kOk) return term;
      const double err = TrialStep(t, x, h);
      if (!std::isfinite(err)) {
        h *= 0.2;
        ++sum.rejected;
        continue;
      }
      if (err <= 1.0) {
        PrepareDense(x, h);
        t_old_ = t;
        t = last ? t1 : t + h;
        t_ = t;
        x = y1_;
        k1_ = k7_;  // FSAL
        ++sum.accepted;
        observer(*this);
        h_next_ = h * AdaptiveControl::Factor(err, 5.0, 0.9, 10.0);
        if (!last) h = h_next_;
      } else {
        ++sum.rejected;
        h *= AdaptiveControl::Factor(err, 5.0, 0.9, 1.0);
      }
    }
    return ctl_.End(OdeTermination::kOk, t);
  }
  OdeTermination Integrate(double t0, State& x, double t1) {
    return Integrate(t0, x, t1, [](const Dopri5&) {});
  }

  double t_old() const { return t_old_; }
  double t() const { return t_; }
  // Dense output on the last accepted step, 4th order.
  void Interpolate(double t, State& out) const {
    const double s = (t - t_old_) / h_dense_, s1 = 1.0 - s;
    out = r1_ + s * (r2_ + s1 * (r3_ + s * (r4_ + s1 * r5_)));
  }
  const OdeSummary& summary() const { return ctl_.summary(); }

 private:
  double Norm(const State& e, const State& a, const State& b) const {
    double sum = 0;
    for (int i = 0; i < e.size(); ++i) {
      const double sk = ctl_.options().atol + ctl_.options().rtol * std::max(std::fabs(a[i]), std::fabs(b[i]));
      sum += (e[i] / sk) * (e[i] / sk);
    }
    return std::sqrt(sum / static_cast<double>(e.size()));
  }

  double InitialStep(double t, const State& x) {
    const double d0 = Norm(x, x, x), d1 = Norm(k1_, x, x);
    double h0 = (d0 < 1e-5 || d1 < 1e-5) ? 1e-6 : 0.01 * d0 / d1;
    tmp_ = x + h0 * k1_;
    sys_(t + h0, tmp_, k2_);
    ++ctl_.summary().rhs_evals;
    const double d2 = Norm(State(k2_ - k1_), x, x) / h0;
    const double dm = std::max(d1, d2);
    const double h1 = dm <= 1e-15 ? std::max(1e-6, h0 * 1e-3) : std::pow(0.01 / dm, 0.2);
    return std::min(100 * h0, h1);
  }

  // Computes the stages for a step of size h from (t, x), y1_ = 5th-order solution; returns the
  // scaled error norm.
  double TrialStep(double t, const State& x, double h) {
    static constexpr double a21 = 1.0 / 5, a31 = 3.0 / 40, a32 = 9.0 / 40, a41 = 44.0 / 45, a42 = -56.0 / 15,
                            a43 = 32.0 / 9, a51 = 19372.0 / 6561, a52 = -25360.0 / 2187, a53 = 64448.0 / 6561,
                            a54 = -212.0 / 729, a61 = 9017.0 / 3168, a62 = -355.0 / 33, a63 = 46732.0 / 5247,
                            a64 = 49.0 / 176, a65 = -5103.0 / 18656, a71 = 35.0 / 384, a73 = 500.0 / 1113,
                            a74 = 125.0 / 192, a75 = -2187.0 / 6784, a76 = 11.0 / 84;
    static constexpr double e1 = 71.0 / 57600, e3 = -71.0 / 16695, e4 = 71.0 / 1920, e5 = -17253.0 / 339200,
                            e6 = 22.0 / 525, e7 = -1.0 / 40;
    tmp_ = x + h * (a21 * k1_);
    sys_(t + h / 5, tmp_, k2_);
    tmp_ = x + h * (a31 * k1_ + a32 * k2_);
    sys_(t + 3 * h / 10, tmp_, k3_);
    tmp_ = x + h * (a41 * k1_ + a42 * k2_ + a43 * k3_);
    sys_(t + 4 * h / 5, tmp_, k4_);
    tmp_ = x + h * (a51 * k1_ + a52 * k2_ + a53 * k3_ + a54 * k4_);
    sys_(t + 8 * h / 9, tmp_, k5_);
    tmp_ = x + h * (a61 * k1_ + a62 * k2_ + a63 * k3_ + a64 * k4_ + a65 * k5_);
    sys_(t + h, tmp_, k6_);
    y1_ = x + h * (a71 * k1_ + a73 * k3_ + a74 * k4_ + a75 * k5_ + a76 * k6_);
    sys_(t + h, y1_, k7_);
    ctl_.summary().rhs_evals += 6;
    tmp_ = h * (e1 * k1_ + e3 * k3_ + e4 * k4_ + e5 * k5_ + e6 * k6_ + e7 * k7_);
    return Norm(tmp_, x, y1_);
  }

  void PrepareDense(const State& x, double h) {
    static constexpr double d1 = -12715105075.0 / 11282082432.0, d3 = 87487479700.0 / 32700410799.0,
                            d4 = -10690763975.0 / 1880347072.0, d5 = 701980252875.0 / 199316789632.0,
                            d6 = -1453857185.0 / 822651844.0, d7 = 69997945.0 / 29380423.0;
    r1_ = x;
    r2_ = y1_ - x;
    r3_ = h * k1_ - r2_;
    r4_ = r2_ - h * k7_ - r3_;
    r5_ = h * (d1 * k1_ + d3 * k3_ + d4 * k4_ + d5 * k5_ + d6 * k6_ + d7 * k7_);
    h_dense_ = h;
  }

  const System& sys_;
  AdaptiveControl ctl_;
  State k1_, k2_, k3_, k4_, k5_, k6_, k7_, y1_, tmp_, r1_, r2_, r3_, r4_, r5_;
  double t_old_ = 0, t_ = 0, h_dense_ = 1, h_next_ = 0;
};

}  // namespace bistable

#endif  // BISTABLE_DYNAMICS_DOPRI5_H_
