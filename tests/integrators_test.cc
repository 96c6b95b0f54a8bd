// Convergence order of the integrators on problems with known solutions (after odeint's
// test/numeric/runge_kutta.cpp): halve the step, the global error must fall by 2^p.
#include <cmath>

#include <gtest/gtest.h>

#include "dynamics/dopri5.h"
#include "dynamics/rk4.h"
#include "dynamics/rosenbrock23.h"

namespace bistable {
namespace {

// x'' = −x, x(0) = 1, x'(0) = 0: x = cos t.
struct Harmonic {
  using State = Eigen::Vector2d;
  using Jacobian = Eigen::Matrix2d;
  int dim() const { return 2; }
  void operator()(double, const State& x, State& dx) const { dx << x[1], -x[0]; }
  void Jac(double, const State&, Jacobian& J, State& dfdt) const {
    J << 0, 1, -1, 0;
    dfdt.setZero();
  }
};

// Non-autonomous: y' = y cos t, y(0) = 1: y = exp(sin t).
struct ExpSin {
  using State = Eigen::Matrix<double, 1, 1>;
  using Jacobian = Eigen::Matrix<double, 1, 1>;
  int dim() const { return 1; }
  void operator()(double t, const State& x, State& dx) const { dx[0] = x[0] * std::cos(t); }
  void Jac(double t, const State& x, Jacobian& J, State& dfdt) const {
    J(0, 0) = std::cos(t);
    dfdt[0] = -x[0] * std::sin(t);
  }
};

// Prothero–Robinson, stiff: y' = −10⁴ (y − cos t) − sin t, y(0) = 1: y = cos t.
struct ProtheroRobinson {
  using State = Eigen::Matrix<double, 1, 1>;
  using Jacobian = Eigen::Matrix<double, 1, 1>;
  int dim() const { return 1; }
  void operator()(double t, const State& x, State& dx) const { dx[0] = -1e4 * (x[0] - std::cos(t)) - std::sin(t); }
  void Jac(double t, const State&, Jacobian& J, State& dfdt) const {
    J(0, 0) = -1e4;
    dfdt[0] = -1e4 * std::sin(t) - std::cos(t);
  }
};

// Fixed steps from an adaptive stepper: a tolerance it can always meet and h0 = h_max = h.
AdaptiveOptions FixedStep(double h) {
  AdaptiveOptions o;
  o.rtol = 1e30;
  o.atol = 1e30;
  o.h0 = h;
  o.h_max = h;
  return o;
}

template <class Sys, class Integrate>
double ObservedOrder(const Sys& sys, double h, Integrate integrate) {
  const double e1 = integrate(sys, h), e2 = integrate(sys, h / 2);
  return std::log2(e1 / e2);
}

// Orders are measured between h and h/2 in the asymptotic range; ±0.15 allows for the
// next-order term at these step sizes, far below the distance to the neighbouring order.
constexpr double kOrderTolerance = 0.15;

TEST(Rk4, ConvergesAtFourthOrderOnHarmonicOscillator) {
  auto err = [](const Harmonic& sys, double h) {
    Rk4<Harmonic> rk(sys);
    Harmonic::State x(1, 0);
    rk.Integrate(0.0, x, h, std::lround(10.0 / h));
    return std::hypot(x[0] - std::cos(10.0), x[1] + std::sin(10.0));
  };
  EXPECT_NEAR(ObservedOrder(Harmonic{}, 0.1, err), 4.0, kOrderTolerance);
  EXPECT_NEAR(ObservedOrder(Harmonic{}, 0.05, err), 4.0, kOrderTolerance);
}

TEST(Rk4, ConvergesAtFourthOrderOnNonAutonomousProblem) {
  auto err = [](const ExpSin& sys, double h) {
    Rk4<ExpSin> rk(sys);
    ExpSin::State x;
    x[0] = 1;
    rk.Integrate(0.0, x, h, std::lround(5.0 / h));
    return std::fabs(x[0] - std::exp(std::sin(5.0)));
  };
  EXPECT_NEAR(ObservedOrder(ExpSin{}, 0.1, err), 4.0, kOrderTolerance);
}

TEST(Dopri5, ConvergesAtFifthOrderWithFixedSteps) {
  auto err = [](const ExpSin& sys, double h) {
    Dopri5<ExpSin> dp(sys, FixedStep(h));
    ExpSin::State x;
    x[0] = 1;
    EXPECT_EQ(dp.Integrate(0.0, x, 5.0), OdeTermination::kOk);
    return std::fabs(x[0] - std::exp(std::sin(5.0)));
  };
  EXPECT_NEAR(ObservedOrder(ExpSin{}, 0.05, err), 5.0, 0.3);
  EXPECT_NEAR(ObservedOrder(Harmonic{}, 0.2,
                            [](const Harmonic& sys, double h) {
                              Dopri5<Harmonic> dp(sys, FixedStep(h));
                              Harmonic::State x(1, 0);
                              dp.Integrate(0.0, x, 10.0);
                              return std::hypot(x[0] - std::cos(10.0), x[1] + std::sin(10.0));
                            }),
              5.0, 0.3);
}

TEST(Dopri5, DenseOutputIsFourthOrderBetweenSteps) {
  // Max interpolation error at off-step times over [0, 10], fixed steps h and h/2.
  auto err = [](const Harmonic& sys, double h) {
    Dopri5<Harmonic> dp(sys, FixedStep(h));
    Harmonic::State x(1, 0), xi;
    double worst = 0;
    dp.Integrate(0.0, x, 10.0, [&](const Dopri5<Harmonic>& st) {
      for (double s : {0.3, 0.5, 0.77}) {
        const double t = st.t_old() + s * (st.t() - st.t_old());
        st.Interpolate(t, xi);
        worst = std::max(worst, std::fabs(xi[0] - std::cos(t)));
      }
    });
    return worst;
  };
  EXPECT_GT(ObservedOrder(Harmonic{}, 0.2, err), 4.0 - kOrderTolerance);
}

TEST(Dopri5, AdaptiveErrorFollowsTolerance) {
  double prev = 1;
  for (double tol : {1e-4, 1e-6, 1e-8, 1e-10}) {
    AdaptiveOptions o;
    o.rtol = tol;
    o.atol = tol;
    Dopri5<Harmonic> dp(Harmonic{}, o);
    Harmonic::State x(1, 0);
    ASSERT_EQ(dp.Integrate(0.0, x, 20.0), OdeTermination::kOk);
    const double e = std::hypot(x[0] - std::cos(20.0), x[1] + std::sin(20.0));
    EXPECT_LT(e, 100 * tol) << "tol " << tol;  // global error stays within two decades of the local tolerance
    EXPECT_LT(e, prev) << "tol " << tol;
    prev = e;
  }
}

TEST(Rosenbrock23, ConvergesAtSecondOrderWithFixedSteps) {
  auto err = [](const ExpSin& sys, double h) {
    Rosenbrock23<ExpSin> rb(sys, FixedStep(h));
    ExpSin::State x;
    x[0] = 1;
    rb.Integrate(0.0, x, 5.0);
    return std::fabs(x[0] - std::exp(std::sin(5.0)));
  };
  EXPECT_NEAR(ObservedOrder(ExpSin{}, 0.01, err), 2.0, kOrderTolerance);
}

TEST(Rosenbrock23, StaysAccurateAndCheapOnStiffProblemWhereDopri5Crawls) {
  AdaptiveOptions o;
  o.rtol = 1e-5;
  o.atol = 1e-7;
  Rosenbrock23<ProtheroRobinson> rb(ProtheroRobinson{}, o);
  Dopri5<ProtheroRobinson> dp(ProtheroRobinson{}, o);
  ProtheroRobinson::State a, b;
  a[0] = b[0] = 1;
  ASSERT_EQ(rb.Integrate(0.0, a, 10.0), OdeTermination::kOk);
  ASSERT_EQ(dp.Integrate(0.0, b, 10.0), OdeTermination::kOk);
  EXPECT_NEAR(a[0], std::cos(10.0), 1e-4);
  EXPECT_NEAR(b[0], std::cos(10.0), 1e-4);
  // Explicit stability bound |hλ| ≤ 3.3 forces ≥ 30000 steps on [0, 10]; the L-stable method needs
  // only what accuracy asks for.
  EXPECT_GT(dp.summary().accepted, 25000);
  EXPECT_LT(rb.summary().accepted * 5, dp.summary().accepted);
}

TEST(Dopri5, ReportsStepSizeUnderflowInsteadOfLooping) {
  // y' = y², y(0) = 1 blows up at t = 1: the run must end with a termination code, not hang.
  struct Blowup {
    using State = Eigen::Matrix<double, 1, 1>;
    int dim() const { return 1; }
    void operator()(double, const State& x, State& dx) const { dx[0] = x[0] * x[0]; }
  };
  AdaptiveOptions o;
  o.max_steps = 100000;
  Dopri5<Blowup> dp(Blowup{}, o);
  Blowup::State x;
  x[0] = 1;
  const OdeTermination t = dp.Integrate(0.0, x, 2.0);
  EXPECT_NE(t, OdeTermination::kOk);
  EXPECT_LT(dp.summary().t_reached, 1.0 + 1e-6);
}

}  // namespace
}  // namespace bistable
