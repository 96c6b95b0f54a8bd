// Models: Jacobians against finite differences, the energy identity, the series model reducing to
// the coupled one, and the dimensional model reducing to the non-dimensional one (model.md §5).
#include <cmath>
#include <random>

#include <gtest/gtest.h>

#include "dynamics/dimensional_model.h"
#include "dynamics/dopri5.h"
#include "dynamics/eigen_bounds.h"
#include "dynamics/nondim_system.h"
#include "dynamics/point.h"
#include "dynamics/series_model.h"

namespace bistable {
namespace {

// Central differences: truncation O(δ²) ≈ 1e-12 relative and rounding ≈ 1e-16/δ ≈ 1e-10; 1e-6
// relative (to the largest entry) leaves margin for the stiff friction slopes.
template <class Sys>
void ExpectJacobianMatchesFiniteDifferences(const Sys& sys, double t, const typename Sys::State& x) {
  const int n = sys.dim();
  typename Sys::Jacobian J(n, n);
  typename Sys::State dfdt(n), fp(n), fm(n);
  sys.Jac(t, x, J, dfdt);
  const double scale = std::max(1.0, J.cwiseAbs().maxCoeff());
  for (int j = 0; j < n; ++j) {
    const double d = 1e-6 * std::max(1e-3, std::fabs(x[j]));
    typename Sys::State xp = x, xm = x;
    xp[j] += d;
    xm[j] -= d;
    sys(t, xp, fp);
    sys(t, xm, fm);
    for (int i = 0; i < n; ++i)
      EXPECT_NEAR(J(i, j), (fp[i] - fm[i]) / (2 * d), 1e-6 * scale) << "J(" << i << "," << j << ")";
  }
  const double dt = 1e-6;
  sys(t + dt, x, fp);
  sys(t - dt, x, fm);
  for (int i = 0; i < n; ++i)
    EXPECT_NEAR(dfdt[i], (fp[i] - fm[i]) / (2 * dt), 1e-6 * std::max(1.0, dfdt.cwiseAbs().maxCoeff()));
}

CellCoeffs<double> Coeffs(ModelKind m) {
  PointSpec s;
  s.model = m;
  s.params = {1.3, 0.1, 0.2, 1.7, 0.8};
  return LaneFor(s).coeffs;
}

TEST(NondimModels, JacobiansMatchFiniteDifferences) {
  NondimSystem<CoupledModel> coupled(Coeffs(ModelKind::kCoupled), 0.7, 1.3);
  ExpectJacobianMatchesFiniteDifferences(coupled, 0.4, Eigen::Vector4d(0.8, -0.3, 1.1, 0.5));
  NondimSystem<SingleModel> single(Coeffs(ModelKind::kStandalone), 0.7, 1.3);
  ExpectJacobianMatchesFiniteDifferences(single, 2.1, Eigen::Vector2d(-1.2, 0.9));
}

// ∇E · F = P − W_m' − W_r' at any state and forcing: the identity behind the energy balance.
template <class Model>
void ExpectEnergyIdentity(const CellCoeffs<double>& c) {
  constexpr int D = Model::kDim;
  const CellCoeffs<Vec<1>> cv{{c.k_lin}, {c.eps}, {c.eta}, {c.eta_r}, {c.phi}, {c.lambda2}};
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(-2, 2);
  for (int trial = 0; trial < 20; ++trial) {
    Vec<1> x[D], dx[D], xp[D], xm[D];
    for (int d = 0; d < D; ++d) x[d][0] = u(rng);
    const Vec<1> f = {u(rng)};
    Model::Rhs(cv, x, f, dx);
    const double eps = 1e-6;
    for (int d = 0; d < D; ++d) xp[d] = x[d] + eps * dx[d], xm[d] = x[d] - eps * dx[d];
    const double dE = (Model::Energy(cv, xp)[0] - Model::Energy(cv, xm)[0]) / (2 * eps);
    const double rhs = Model::Power(cv, x, f)[0] - Model::DissMain(cv, x)[0] - Model::DissRes(cv, x)[0];
    EXPECT_NEAR(dE, rhs, 1e-7 * std::max(1.0, std::fabs(rhs)));
  }
}

TEST(NondimModels, EnergyRateEqualsPowerMinusDissipation) {
  ExpectEnergyIdentity<CoupledModel>(Coeffs(ModelKind::kCoupled));
  ExpectEnergyIdentity<SingleModel>(Coeffs(ModelKind::kStandalone));
  ExpectEnergyIdentity<CoupledModel>(Coeffs(ModelKind::kLinearCoupled));
  ExpectEnergyIdentity<SingleModel>(Coeffs(ModelKind::kLinear));
}

TEST(SeriesModel, OneCellEqualsTheCoupledModel) {
  const SeriesCell cell{true, 1.3, 0.1, true, 0.2, 1.7, 0.8};
  SeriesModel series = SeriesModel::Uniform(1, cell, 0.7, 1.3);
  NondimSystem<CoupledModel> coupled(Coeffs(ModelKind::kCoupled), 0.7, 1.3);
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> u(-2, 2);
  for (int trial = 0; trial < 10; ++trial) {
    Eigen::Vector4d x(u(rng), u(rng), u(rng), u(rng)), a;
    BISTABLE_EIGEN_BOUNDS_BEGIN
    Eigen::VectorXd xs = x, b(4);
    BISTABLE_EIGEN_BOUNDS_END
    const double t = u(rng);
    coupled(t, x, a);
    series(t, xs, b);
    for (int i = 0; i < 4; ++i) EXPECT_DOUBLE_EQ(a[i], b[i]);
  }
}

TEST(SeriesModel, OneCellWithoutResonatorEqualsTheStandaloneModel) {
  SeriesCell cell{true, 1.0, 0.1, false};
  SeriesModel series = SeriesModel::Uniform(1, cell, 0.5, 0.9);
  ASSERT_EQ(series.dim(), 2);
  NondimSystem<SingleModel> single_eps1(LaneFor([] {
                                          PointSpec s;
                                          s.model = ModelKind::kStandalone;
                                          return s;
                                        }())
                                            .coeffs,
                                        0.5, 0.9);
  Eigen::Vector2d x(0.3, -0.7), a;
  BISTABLE_EIGEN_BOUNDS_BEGIN
  Eigen::VectorXd xs = x, b(2);
  BISTABLE_EIGEN_BOUNDS_END
  single_eps1(0.9, x, a);
  series(0.9, xs, b);
  EXPECT_DOUBLE_EQ(a[0], b[0]);
  EXPECT_DOUBLE_EQ(a[1], b[1]);
}

TEST(SeriesModel, JacobianMatchesFiniteDifferencesWithMixedCells) {
  std::vector<SeriesCell> cells = {
      {true, 1.0, 0.1, true, 0.075, 2.0, 0.8}, {false, 0.0, 0.2, false}, {true, 1.5, 0.05, true, 0.3, 0.5, 1.2}};
  SeriesModel m(cells, 0.8, 1.1);
  ASSERT_EQ(m.dim(), 10);
  Eigen::VectorXd x(10);
  x << 0.9, 0.1, 1.0, -0.2, 1.7, 0.3, 2.4, -0.5, 2.2, 0.4;
  ExpectJacobianMatchesFiniteDifferences(m, 0.3, x);
  EXPECT_TRUE(ValidateSeriesCells(cells).ok());
  cells[2].lambda = -1;
  const Status st = ValidateSeriesCells(cells);
  EXPECT_EQ(st.field(), "cells[2].lambda");
}

TEST(Stribeck, PeaksAtStaticForceAndTendsToCoulomb) {
  const Stribeck f{1.2, 0.44, 0.002, 0.001};
  EXPECT_NEAR(f.Force(0.002), 1.2, 1e-12);
  EXPECT_NEAR(f.Force(0.5), 0.44, 1e-9);
  EXPECT_DOUBLE_EQ(f.Force(-0.01), -f.Force(0.01));
  EXPECT_DOUBLE_EQ(f.Force(0.0), 0.0);
  const double d = 1e-9;
  for (double v : {-0.01, -0.002, 0.0, 0.0005, 0.003})
    EXPECT_NEAR(f.Slope(v), (f.Force(v + d) - f.Force(v - d)) / (2 * d), 1e-3 * std::fabs(f.Slope(v)) + 1e-3);
}

TEST(DimensionalModel, JacobianMatchesFiniteDifferencesWithFriction) {
  DimensionalModel m(DimensionalParams::BistableTable2(), SineBase(0.01, 4.0));
  ExpectJacobianMatchesFiniteDifferences(m, 0.13, Eigen::Vector4d(0.02, 0.05, -0.003, 0.01));
  ExpectJacobianMatchesFiniteDifferences(m, 0.27, Eigen::Vector4d(-0.01, 0.0015, 0.002, -0.0007));
  DimensionalModel chirp(DimensionalParams::LinearTable2(), ChirpBase(0.01, 1.0, 8.0, 60.0));
  ExpectJacobianMatchesFiniteDifferences(chirp, 11.3, Eigen::Vector4d(0.004, -0.02, 0.001, 0.03));
}

TEST(DimensionalModel, ValidationNamesFieldAndBound) {
  DimensionalParams p = DimensionalParams::BistableTable2();
  p.fric_m.v_t = 0;
  EXPECT_EQ(ValidateDimensionalParams(p).field(), "v_t_m");
  p = DimensionalParams::BistableTable2();
  p.k3 = 0;
  const Status st = ValidateDimensionalParams(p);
  EXPECT_EQ(st.field(), "k3");
  EXPECT_NE(st.message().find("k3 > 0"), std::string::npos);
}

// Without friction and c2, the dimensional model is the non-dimensional one in other units:
// y/δs(τ/ωn) must follow the non-dimensional solution (model.md §1, §5).
TEST(DimensionalModel, ReducesToNondimensionalModelWithoutFriction) {
  DimensionalParams p = DimensionalParams::BistableTable2();
  p.c2_m = p.c2_r = 0;
  p.fric_m.f_s = p.fric_m.f_c = p.fric_r.f_s = p.fric_r.f_c = 0;
  const double delta_s = std::sqrt(-p.k_lin / p.k3), wn = std::sqrt(-p.k_lin / p.m_m);
  const double alpha = 0.4, omega = 0.9;
  DimensionalModel dim(p, SineBase(alpha * delta_s, omega * wn / (2 * M_PI)));
  PointSpec s;
  s.model = ModelKind::kCoupled;
  s.params.eps = 1.0;
  s.params.eta = p.c0_m / (p.m_m * wn);
  s.params.eta_r = p.c0_r / (p.m_r * wn);
  s.params.phi = p.m_r / p.m_m;
  s.params.lambda = std::sqrt(p.k_r / p.m_r) / wn;
  NondimSystem<CoupledModel> nd(LaneFor(s).coeffs, alpha, omega);

  AdaptiveOptions o;
  o.rtol = 1e-11;
  o.atol = 1e-13;
  const double tau_end = 30;
  Eigen::Vector4d xn(1, 0, 1, 0);        // at rest in the positive well
  Eigen::Vector4d xd(delta_s, 0, 0, 0);  // y = δs, z = x_r − x_m = 0
  Dopri5<NondimSystem<CoupledModel>> a(nd, o);
  Dopri5<DimensionalModel> b(dim, o);
  ASSERT_EQ(a.Integrate(0.0, xn, tau_end), OdeTermination::kOk);
  o.atol = 1e-13 * delta_s;
  ASSERT_EQ(b.Integrate(0.0, xd, tau_end / wn), OdeTermination::kOk);
  EXPECT_NEAR(xd[0] / delta_s, xn[0], 1e-7);
  EXPECT_NEAR(xd[1] / (delta_s * wn), xn[1], 1e-7);
  EXPECT_NEAR((xd[2] + xd[0]) / delta_s, xn[2], 1e-7);  // y_r = (x_r − x0)/δs = (z + y)/δs
}

}  // namespace
}  // namespace bistable
