// Term models in lanes (dynamics/term_model.h, issue 42): the paper's rig written as effect-library terms runs
// in the lane kernel to the hand-written rig kernel's numbers, a lane's bits do not depend on the lane
// width or its neighbours' parameters, and what the lane model cannot run is refused by name.
#include "dynamics/term_model.h"

#include <cmath>
#include <vector>

#include <gtest/gtest.h>

#include "dynamics/ensemble_generic.h"

namespace bistable {
namespace {

KernelSettings Short() { return KernelSettings::Window(1e-3, 1.5); }

TermLaneInput Lane(const TermModel* m, double a0_mm, double f0_hz, const double* theta = nullptr) {
  TermLaneInput in;
  in.model = m;
  in.theta = theta;
  in.base_amp = a0_mm * 1e-3;
  in.omega = 2 * M_PI * f0_hz;
  in.amp = in.base_amp * in.omega * in.omega;
  in.x0[0] = 0.023;
  return in;
}

TEST(TermModel, TheRigAsTermsRunsToTheHandKernelsNumbers) {
  const DimensionalParams rig = DimensionalParams::BistableTable2();
  auto m = TermModel::FromDimensional(rig);
  ASSERT_TRUE(m.ok()) << m.status().ToString();
  ASSERT_TRUE(ValidateTermModel(*m).ok());
  EXPECT_EQ(m->NumParams(), 11);
  EXPECT_EQ(m->IndexOf("main.stiffness_y3.k3"), 1);
  EXPECT_EQ(m->theta[1], rig.k3);
  const KernelSettings ks = Short();
  const int substeps = Rk4Substeps(rig, ks.h);
  EXPECT_EQ(TermRk4Substeps(*m, m->theta.data(), ks.h), substeps);  // the same rule, from the terms
  for (double a0 : {2.0, 11.0}) {                                   // one intrawell orbit, one that snaps through
    DimensionalLaneInput hand;
    hand.params = rig;
    const TermLaneInput term = Lane(&*m, a0, 3.0);
    hand.base_amp = term.base_amp, hand.omega = term.omega, hand.amp = term.amp, hand.x0 = term.x0;
    RawLane a, b;
    ASSERT_TRUE(RunDimensionalLanes<1>(&hand, 1, ks, substeps, &a));
    ASSERT_TRUE(RunTermLanes<1>(&term, 1, ks, substeps, &b));
    EXPECT_NEAR(b.vabs_max, a.vabs_max, 1e-12 * a.vabs_max) << a0;
    EXPECT_NEAR(b.y_min, a.y_min, 1e-12) << a0;
    EXPECT_NEAR(b.y_max, a.y_max, 1e-12) << a0;
    EXPECT_NEAR(b.log_growth, a.log_growth, 1e-9) << a0;
  }
}

TEST(TermModel, ALanesBitsDoNotDependOnTheWidthOrItsNeighboursParameters) {
  auto m = TermModel::FromDimensional(DimensionalParams::BistableTable2());
  ASSERT_TRUE(m.ok());
  std::vector<std::vector<double>> thetas(4, m->theta);
  for (int l = 0; l < 4; ++l) thetas[l][4] *= 1.0 + 0.1 * l;  // main.friction F_s per lane
  std::vector<TermLaneInput> in;
  for (int l = 0; l < 4; ++l) in.push_back(Lane(&*m, 4.0 + l, 3.0, thetas[l].data()));
  const KernelSettings ks = Short();
  std::vector<RawLane> four(4);
  ASSERT_TRUE(RunTermLanes<4>(in.data(), 4, ks, 5, four.data()));
  for (int l = 0; l < 4; ++l) {
    RawLane one;
    ASSERT_TRUE(RunTermLanes<1>(&in[l], 1, ks, 5, &one));
    EXPECT_EQ(one.vabs_max, four[l].vabs_max) << l;
    EXPECT_EQ(one.log_growth, four[l].log_growth) << l;
    EXPECT_EQ(one.y_max, four[l].y_max) << l;
  }
  TermLaneInput shared = in[3];  // lane 3 with the model's own parameters: its own F_s was used
  shared.theta = nullptr;
  RawLane base;
  ASSERT_TRUE(RunTermLanes<1>(&shared, 1, ks, 5, &base));
  EXPECT_NE(base.vabs_max, four[3].vabs_max);
}

TEST(TermModel, WhatTheLaneModelCannotRunIsRefusedByName) {
  auto m = TermModel::FromDimensional(DimensionalParams::BistableTable2());
  ASSERT_TRUE(m.ok());
  TermModel bad = *m;
  bad.theta.pop_back();
  EXPECT_NE(ValidateTermModel(bad).ToString().find("theta"), std::string::npos);
  bad = *m;
  bad.m_res = 0;
  EXPECT_NE(ValidateTermModel(bad).ToString().find("m_res"), std::string::npos);
  bad = *m;
  bad.terms.push_back(*FindTerm("main.piezo"));
  bad.theta.insert(bad.theta.end(), {1, 1, 1});
  EXPECT_NE(ValidateTermModel(bad).ToString().find("main.piezo"), std::string::npos);
  bad = *m;
  bad.theta[0] = NAN;
  EXPECT_NE(ValidateTermModel(bad).ToString().find("main.linear.k_lin"), std::string::npos);
  DimensionalParams two = DimensionalParams::BistableTable2();
  two.fric_r.v_t = 0.002;
  EXPECT_FALSE(TermModel::FromDimensional(two).ok());
}

// The lane form of every force term (coefficients per lane, the hand kernel's operations) against the basis
// form identify simulates with (TermForce: θ·φ over TermBasisSlopes), force and both slopes, at states from
// rest to fast sliding, both signs, on the main body and the resonator.
TEST(TermModel, TheLaneFormIsTheBasisForm) {
  int checked = 0;
  for (const TermDef& def : EffectLibrary()) {
    if (!def.IsForce()) continue;
    TermModel m;
    m.m_main = 0.5, m.m_res = 0.25;
    m.terms.push_back(&def);
    for (size_t k = 0; k < def.params.size(); ++k) m.theta.push_back(k == 0 ? 1.7 : -0.6);  // F_s, F_c: 1.7, −0.6
    ASSERT_TRUE(ValidateTermModel(m).ok()) << def.id << ": " << ValidateTermModel(m).ToString();
    TermLaneInput in;
    in.model = &m;
    TermLaneModel::Lanes<1> lanes(in);
    lanes.Load(0, in);
    for (double q : {-0.03, -1e-4, 0.0, 2e-3, 0.02})
      for (double v : {-0.5, -3e-3, -1e-4, 0.0, 5e-4, 2e-3, 0.08}) {
        double f, fq, fv;
        TermForce(m, def.body, m.theta.data(), q, v, &f, &fq, &fv);
        Vec<1> x[4] = {Splat<1>(0.0), Splat<1>(0.0), Splat<1>(0.0), Splat<1>(0.0)}, dx[4];
        const bool main = def.body == Body::kMain;
        x[main ? 0 : 2] = Splat<1>(q), x[main ? 1 : 3] = Splat<1>(v);
        TermLaneModel::Lanes<1>::Jac j(lanes);
        lanes.Eval(x, Splat<1>(0.0), dx, &j);
        // main: dx[1] = −F/m_main; resonator: G enters dx[1] as +G/m_main, its slopes are j.gz, j.gzd
        const double lane_f = main ? -dx[1][0] * m.m_main : dx[1][0] * m.m_main;
        const double lane_fq = main ? -j.fy[0] : j.gz[0], lane_fv = main ? -j.fyd[0] : j.gzd[0];
        const double tol = 1e-13 * (1 + std::fabs(f) + std::fabs(fq) + std::fabs(fv));
        EXPECT_NEAR(lane_f, f, tol * (1 + std::fabs(f))) << def.id << " q " << q << " v " << v;
        EXPECT_NEAR(lane_fq, fq, 1e-13 * (1 + std::fabs(fq))) << def.id << " q " << q << " v " << v;
        EXPECT_NEAR(lane_fv, fv, 1e-12 * (1 + std::fabs(fv))) << def.id << " q " << q << " v " << v;
        ++checked;
      }
  }
  EXPECT_GE(checked, 35 * 10);  // ten or more force terms of the library, 35 states each
}

}  // namespace
}  // namespace bistable
