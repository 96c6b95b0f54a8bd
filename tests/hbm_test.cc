// Harmonic balance against closed forms (linear transmissibility, the one-harmonic balance), against
// long time integration (stable period-1 points), continuation through folds, stability flags that
// time integration confirms, and intrawell branches about ±1 that the paper's Eq. 9 cannot produce.
#include <cmath>

#include <gtest/gtest.h>

#include "dynamics/dopri5.h"
#include "dynamics/hbm.h"
#include "dynamics/nondim_system.h"
#include "dynamics/point.h"

namespace bistable {
namespace {

HbmOptions Options(ModelKind m, double alpha) {
  HbmOptions o;
  o.model = m;
  o.alpha = alpha;
  o.from = 0.1;
  o.to = 3.0;
  o.harmonics = 5;
  return o;
}

// Steady state of a long time integration from x0 (DP5, 400 forcing periods), then y_m over 20
// more periods on a uniform grid of 200 samples per period (dense output): max |y_m| and mean.
struct Steady {
  double amplitude, mean;
};
template <class Model>
Steady TimeIntegrateModel(const HbmOptions& o, double omega, std::array<double, 4> x0) {
  PointSpec s;
  s.model = o.model;
  s.params = o.params;
  s.alpha = o.alpha;
  s.omega = omega;
  using Sys = NondimSystem<Model>;
  Sys sys(LaneFor(s).coeffs, o.alpha, omega);
  AdaptiveOptions ao;
  ao.rtol = 1e-10;
  ao.atol = 1e-12;
  const double period = 2 * M_PI / omega;
  typename Sys::State x;
  for (int d = 0; d < Model::kDim; ++d) x[d] = x0[d];
  Dopri5<Sys> dp(sys, ao);
  dp.Integrate(0.0, x, 400 * period);
  double amp = 0, sum = 0;
  int n = 0;
  typename Sys::State xi;
  const double t0 = 400 * period, dt = period / 200;
  Dopri5<Sys> dp2(sys, ao);
  dp2.Integrate(t0, x, t0 + 20 * period, [&](const Dopri5<Sys>& st) {
    while (t0 + n * dt <= st.t() && n < 4000) {
      st.Interpolate(t0 + n * dt, xi);
      amp = std::max(amp, std::fabs(xi[0]));
      sum += xi[0], ++n;
    }
  });
  return {amp, sum / n};
}

Steady TimeIntegrate(const HbmOptions& o, double omega, std::array<double, 4> x0) {
  return HasResonator(o.model) ? TimeIntegrateModel<CoupledModel>(o, omega, x0) : TimeIntegrateModel<SingleModel>(o, omega, x0);
}

TEST(Hbm, LinearOscillatorMatchesExactAmplitude) {
  HbmOptions o = Options(ModelKind::kLinear, 0.5);
  o.harmonics = 3;
  HarmonicBalance hb(o);
  for (double omega : {0.3, 0.9, 1.0, 1.7, 2.8}) {
    Eigen::VectorXd z = Eigen::VectorXd::Zero(hb.size());
    ASSERT_GE(hb.Solve(&z, omega, o.alpha), 0);
    const HbmPoint p = hb.Describe(z, omega, o.alpha, 200);
    const double exact = o.alpha * omega * omega / std::hypot(1 - omega * omega, 0.1 * omega);
    EXPECT_NEAR(p.amplitude, exact, 1e-4 * exact) << omega;  // max over 256 samples of one period
    EXPECT_TRUE(p.stable);
    for (int k = 3; k < 7; ++k) EXPECT_NEAR(p.harmonics[k], 0.0, 1e-12);  // no higher harmonics
  }
}

// The corrected counterpart of the paper's Eq. 9 in closed form against the general balance with
// one harmonic and no constant term, stand-alone (Fig. 3a) and coupled with η_r 1.5, φ 2, λ 0.8 (Fig. 3b).
TEST(Hbm, OneHarmonicZeroMeanBalanceMatchesItsClosedForm) {
  for (ModelKind m : {ModelKind::kStandalone, ModelKind::kCoupled}) {
    HbmOptions o = Options(m, 2.0);
    o.params.eta_r = 1.5;
    o.harmonics = 1;
    o.zero_mean = true;
    HarmonicBalance hb(o);
    int checked = 0;
    for (double alpha : {0.2, 2.0})
      for (double omega : {0.5, 0.8, 1.5, 2.5}) {
        for (double root : Eq9Amplitudes(m, o.params, alpha, omega)) {
          // Start at y_m = q sin Ωτ with the resonator following; Newton finds both phases.
          Eigen::VectorXd z = Eigen::VectorXd::Zero(hb.size());
          z[2] = root;
          if (hb.dofs() == 2) z[5] = root;
          if (hb.Solve(&z, omega, alpha) < 0) continue;  // another root attracted Newton: checked below
          const double q = std::hypot(z[1], z[2]);
          const auto all = Eq9Amplitudes(m, o.params, alpha, omega);
          double nearest = INFINITY;
          for (double r : all) nearest = std::min(nearest, std::fabs(r - q));
          EXPECT_LT(nearest, 1e-9 * q) << ModelName(m) << " alpha " << alpha << " omega " << omega;
          EXPECT_EQ(z[0], 0.0);
          ++checked;
        }
      }
    EXPECT_GE(checked, 6) << ModelName(m);
  }
  // Multi-valued: at Ω = 1.5, α = 0.3 the stand-alone cubic has three positive roots.
  EXPECT_EQ(Eq9Amplitudes(ModelKind::kStandalone, NondimParams{}, 0.3, 1.5).size(), 3u);
  // Linear limit: the transmissibility of the relative motion.
  EXPECT_NEAR(Eq9Amplitudes(ModelKind::kLinear, NondimParams{}, 0.5, 1.0)[0], 0.5 / 0.1, 1e-12);
}

TEST(Hbm, ContinuationPassesFoldsAndFindsIntrawellBranchesAboutPlusMinusOne) {
  auto r = ContinueBranches(Options(ModelKind::kStandalone, 0.3));
  ASSERT_TRUE(r.ok()) << r.status().ToString();
  int intrawell_plus = 0, intrawell_minus = 0, interwell = 0, interwell_points = 0;
  for (const HbmBranch& b : r->branches) {
    const double mean0 = b.points.front().mean;
    if (mean0 > 0.9) ++intrawell_plus;
    if (mean0 < -0.9) ++intrawell_minus;
    if (b.points.front().amplitude > 2.0 || std::fabs(mean0) < 0.1) ++interwell;
    // The plots name branches by well (WellOf): the ±1 intrawell branches start in their well.
    if (mean0 > 0.9) EXPECT_EQ(WellOf(b.points.front()), OrbitWell::kPlus) << b.start;
    if (mean0 < -0.9) EXPECT_EQ(WellOf(b.points.front()), OrbitWell::kMinus) << b.start;
    for (const HbmPoint& p : b.points) {
      EXPECT_LE(p.y_min, p.mean + 1e-12);
      EXPECT_GE(p.y_max, p.mean - 1e-12);
      EXPECT_DOUBLE_EQ(p.amplitude, std::max(-p.y_min, p.y_max));
      if (WellOf(p) == OrbitWell::kInterwell) ++interwell_points;
    }
    int folds = 0, turns = 0;
    for (size_t i = 2; i < b.points.size(); ++i) {
      folds += b.points[i].fold;
      turns += (b.points[i].omega - b.points[i - 1].omega) * (b.points[i - 1].omega - b.points[i - 2].omega) < 0;
    }
    EXPECT_EQ(folds, turns) << b.start << ": every turning point of Ω along the branch is flagged, and only those";
    if (mean0 > 0.9) {
      EXPECT_EQ(folds, 2) << "the softening intrawell resonance bends back and forth once";
      EXPECT_LT(b.points.front().omega, 0.15);
      EXPECT_GT(b.points.back().omega, 2.9);  // through both folds to the far end of the range
    }
  }
  EXPECT_EQ(intrawell_plus, 1);
  EXPECT_EQ(intrawell_minus, 1);
  EXPECT_GE(interwell, 1);
  EXPECT_GT(interwell_points, 0) << "orbits crossing y = 0 are named interwell";
  EXPECT_STREQ(OrbitWellName(OrbitWell::kMinus), "-well");
  EXPECT_LT(r->truncation_change, 0.01) << "5 harmonics suffice at alpha 0.3";
}

class HbmVsTime : public ::testing::TestWithParam<ModelKind> {};

TEST_P(HbmVsTime, StablePointsAgreeWithTimeIntegrationAndUnstableOnesAreLeft) {
  const HbmOptions o = Options(GetParam(), 0.3);
  auto r = ContinueBranches(o);
  ASSERT_TRUE(r.ok());
  HarmonicBalance hb(o);
  int stable_checked = 0, unstable_checked = 0;
  for (const HbmBranch& b : r->branches) {
    std::vector<double> folds;
    for (const HbmPoint& p : b.points)
      if (p.fold) folds.push_back(p.omega);
    for (size_t i = 0; i < b.points.size(); i += 4) {
      const HbmPoint& p = b.points[i];
      // Within 0.02 of a fold, whether the orbit exists at all depends on where the 5-harmonic
      // truncation puts the fold (to about 1e-2 here): such points test the truncation, not the method.
      bool near_fold = false;
      for (double f : folds) near_fold |= std::fabs(p.omega - f) < 0.02;
      if (near_fold) continue;
      // Start the time integration on the orbit: y(0) = c0 + Σ a_k, y'(0) = Σ kΩ b_k, for every DOF.
      std::array<double, 4> x0{};
      const int per = 2 * o.harmonics + 1;
      for (int dof = 0; dof < hb.dofs(); ++dof) {
        double y0 = p.z[dof * per], v0 = 0;
        for (int k = 1; k <= o.harmonics; ++k) y0 += p.z[dof * per + 2 * k - 1], v0 += k * p.omega * p.z[dof * per + 2 * k];
        x0[2 * dof] = y0, x0[2 * dof + 1] = v0;
      }
      const Steady s = TimeIntegrate(o, p.omega, x0);
      if (p.stable && p.max_multiplier < 0.95) {  // clearly inside: 400 periods settle it
        EXPECT_NEAR(s.amplitude, p.amplitude, 0.01 * p.amplitude) << b.start << " Omega " << p.omega;
        EXPECT_NEAR(s.mean, p.mean, 0.01 * std::max(1.0, std::fabs(p.mean))) << b.start << " Omega " << p.omega;
        ++stable_checked;
      } else if (!p.stable && p.max_multiplier > 1.5) {
        // Rounding and truncation put the start near, not on, the orbit: an unstable orbit is not kept.
        const bool left = std::fabs(s.amplitude - p.amplitude) > 0.01 * p.amplitude ||
                          std::fabs(s.mean - p.mean) > 0.01 * std::max(1.0, std::fabs(p.mean));
        EXPECT_TRUE(left) << b.start << " Omega " << p.omega << " mu " << p.max_multiplier;
        ++unstable_checked;
      }
    }
  }
  EXPECT_GE(stable_checked, 8);
  EXPECT_GE(unstable_checked, 3);
}

INSTANTIATE_TEST_SUITE_P(Models, HbmVsTime, ::testing::Values(ModelKind::kStandalone, ModelKind::kCoupled),
                         [](const auto& info) { return std::string(ModelName(info.param)); });

TEST(Hbm, PeriodOnePointsOfTheSweepLieOnStableBranches) {
  // Where the point metrics say "period 1", harmonic balance has a stable orbit of the same amplitude.
  const HbmOptions o = Options(ModelKind::kStandalone, 0.3);
  auto r = ContinueBranches(o);
  ASSERT_TRUE(r.ok());
  for (double omega : {0.4, 0.8}) {
    PointSpec s;
    s.model = ModelKind::kStandalone;
    s.alpha = 0.3;
    s.omega = omega;
    s.metrics.rosenstein = false;
    auto pr = EvaluatePoint(s);
    ASSERT_TRUE(pr.ok());
    ASSERT_EQ(pr->period, 1) << omega;
    const double amp = std::max(std::fabs(pr->y_min), std::fabs(pr->y_max));
    bool found = false;
    for (const HbmBranch& b : r->branches)
      for (size_t i = 1; i < b.points.size(); ++i) {
        const HbmPoint &a = b.points[i - 1], &c = b.points[i];
        if ((a.omega - omega) * (c.omega - omega) > 0 || !a.stable || !c.stable) continue;
        const double f = (omega - a.omega) / (c.omega - a.omega);
        found |= std::fabs(a.amplitude + f * (c.amplitude - a.amplitude) - amp) < 0.01 * amp;
      }
    EXPECT_TRUE(found) << "no stable branch through Omega " << omega << " with amplitude " << amp;
  }
}

TEST(Hbm, CoupledModelContinuesAndReportsTruncation) {
  auto r = ContinueBranches(Options(ModelKind::kCoupled, 0.2));
  ASSERT_TRUE(r.ok());
  ASSERT_GE(r->branches.size(), 2u);
  EXPECT_GT(r->branches[0].points.size(), 20u);
  EXPECT_LT(r->truncation_change, 0.05);
}

TEST(Hbm, BadOptionsNameTheFieldAndNonConvergenceIsARecordedResult) {
  HbmOptions o = Options(ModelKind::kStandalone, 0.3);
  o.harmonics = 0;
  EXPECT_EQ(ContinueBranches(o).status().field(), "harmonics");
  o = Options(ModelKind::kStandalone, 0.3);
  o.to = o.from;
  EXPECT_EQ(ContinueBranches(o).status().field(), "to");
  o = Options(ModelKind::kStandalone, -1);
  EXPECT_EQ(ContinueBranches(o).status().field(), "alpha");
  // Newton allowed a single iteration: corrections fail, steps shrink below ds_min, the branch ends
  // with a point marked converged = false instead of an exception or a hang.
  o = Options(ModelKind::kStandalone, 0.3);
  o.newton_max_iter = 1;
  o.ds_min = 1e-3;
  auto r = ContinueBranches(o);
  ASSERT_TRUE(r.ok());
  bool any_failed = false;
  for (const auto& b : r->branches)
    for (const auto& p : b.points) any_failed |= !p.converged;
  EXPECT_TRUE(any_failed || r->branches.empty());
}

}  // namespace
}  // namespace bistable
