// Harmonic balance against closed forms (linear transmissibility, the one-harmonic balance), against
// long time integration (stable period-1 points), continuation through folds, stability flags that
// time integration confirms, and intrawell branches about ±1 that the paper's Eq. 9 cannot produce.
// Period doubling of the double-well Duffing against a brute-force bifurcation diagram, the switched
// period-2 branch against the integrated period-2 orbit, and fold curves in (α, Ω) against
// one-parameter continuations.
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
  return HasResonator(o.model) ? TimeIntegrateModel<CoupledModel>(o, omega, x0)
                               : TimeIntegrateModel<SingleModel>(o, omega, x0);
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
    if (mean0 > 0.9) {
      EXPECT_EQ(WellOf(b.points.front()), OrbitWell::kPlus) << b.start;
    }
    if (mean0 < -0.9) {
      EXPECT_EQ(WellOf(b.points.front()), OrbitWell::kMinus) << b.start;
    }
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
        for (int k = 1; k <= o.harmonics; ++k)
          y0 += p.z[dof * per + 2 * k - 1], v0 += k * p.omega * p.z[dof * per + 2 * k];
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

// ---- Period doubling, branch switching and fold curves ----------------------------------------------

// The double-well Duffing y'' + 0.3 y' − y + y³ = αΩ² sin Ωτ at Ω = 1.2 (forcing amplitude 1.44 α, the
// classic γ cos ωt case of Guckenheimer & Holmes): the intrawell orbit of the + well period-doubles
// near α = 0.1844, the period-2 orbit near α = 0.1991 (a cascade follows).
HbmOptions DuffingCascade() {
  HbmOptions o;
  o.model = ModelKind::kStandalone;
  o.params.eta = 0.3;
  o.omega = 1.2;
  o.param = ContinuationParam::kAlpha;
  o.from = 0.1;
  o.to = 0.25;
  o.harmonics = 10;
  o.switch_depth = 1;
  return o;
}

// Brute-force bifurcation diagram: α stepped up over a grid, each run continuing from the previous
// one's final state (DP5, rtol 1e-10), 300 forcing periods of transient, then the stroboscopic samples
// (y, y') at τ = kT, k = 0..4, and max |y| over those 4 periods (400 dense samples per period).
struct Strobes {
  double alpha;
  std::array<double, 5> y, v;
  double amplitude;
  double Split(int n) const { return std::hypot(y[n] - y[0], v[n] - v[0]); }  // |s_n − s_0|
};
std::vector<Strobes> BruteForceDiagram(const HbmOptions& o, double a0, double da, int count) {
  using Sys = NondimSystem<SingleModel>;
  AdaptiveOptions ao;
  ao.rtol = 1e-10;
  ao.atol = 1e-12;
  const double period = 2 * M_PI / o.omega;
  Sys::State x;
  x[0] = 1, x[1] = 0;
  double t = 0;
  std::vector<Strobes> out;
  for (int k = 0; k < count; ++k) {
    PointSpec s;
    s.model = o.model;
    s.params = o.params;
    s.omega = o.omega;
    s.alpha = a0 + k * da;
    Sys sys(LaneFor(s).coeffs, s.alpha, o.omega);
    Dopri5<Sys> dp(sys, ao);
    dp.Integrate(t, x, t + 300 * period);
    t += 300 * period;
    Strobes st{s.alpha, {}, {}, 0};
    for (int n = 0; n < 5; ++n) {
      st.y[n] = x[0], st.v[n] = x[1];
      if (n == 4) break;
      Dopri5<Sys> step(sys, ao);
      const double t0 = t;
      int m = 0;
      Sys::State xi;
      step.Integrate(t, x, t + period, [&](const Dopri5<Sys>& d) {
        for (; m < 400 && t0 + m * period / 400 <= d.t(); ++m) {
          d.Interpolate(t0 + m * period / 400, xi);
          st.amplitude = std::max(st.amplitude, std::fabs(xi[0]));
        }
      });
      t += period;
    }
    out.push_back(st);
  }
  return out;
}

// The first flagged period doubling of the +well branch of `period` (mean > 0).
const HbmPoint* FirstPeriodDoubling(const HbmResult& r, int period, size_t* branch = nullptr) {
  for (size_t b = 0; b < r.branches.size(); ++b)
    if (r.branches[b].period == period && r.branches[b].points.front().mean > 0)
      for (const HbmPoint& p : r.branches[b].points)
        if (p.period_doubling) {
          if (branch) *branch = b;
          return &p;
        }
  return nullptr;
}

TEST(HbmPeriodDoubling, CascadeOfTheDoubleWellDuffingMatchesABruteForceBifurcationDiagram) {
  const HbmOptions o = DuffingCascade();
  auto r = ContinueBranches(o);
  ASSERT_TRUE(r.ok()) << r.status().ToString();
  size_t b1 = 0;
  const HbmPoint* pd1 = FirstPeriodDoubling(*r, 1, &b1);
  ASSERT_NE(pd1, nullptr);
  ASSERT_TRUE(pd1->period_doubling_at.valid());
  const double a_pd1 = pd1->period_doubling_at.alpha;
  // Located by bisection inside the step that ends at the flagged point, the multiplier at −1.
  const HbmPoint& before = (&*pd1)[-1];
  EXPECT_GT(a_pd1, before.alpha);
  EXPECT_LT(a_pd1, pd1->alpha);
  EXPECT_GT(pd1->alpha - a_pd1, 1e-3) << "the flagged point is a step away; the located one is not";
  EXPECT_NEAR(pd1->period_doubling_at.multiplier.real(), -1.0, 1e-6);
  EXPECT_EQ(pd1->period_doubling_at.multiplier.imag(), 0.0);
  EXPECT_TRUE(before.stable);
  EXPECT_FALSE(pd1->stable);
  // The period-2 branch's own period doubling (period 4), the cascade's next step.
  const HbmPoint* pd2 = FirstPeriodDoubling(*r, 2);
  ASSERT_NE(pd2, nullptr);
  ASSERT_TRUE(pd2->period_doubling_at.valid());
  const double a_pd2 = pd2->period_doubling_at.alpha;
  EXPECT_GT(a_pd2, a_pd1 + 0.01);

  // Brute force over α in [0.180, 0.2025], step 0.0005: period 2 where |s1 − s0| > 1e-3 and
  // |s2 − s0| < 0.1 |s1 − s0|, period 4 where |s2 − s0| > 1e-3 and |s4 − s0| < 0.1 |s2 − s0| (near a
  // period doubling 300 periods do not settle the samples to rounding: |μ| ≈ 1).
  const double da = 0.0005;
  const std::vector<Strobes> diagram = BruteForceDiagram(o, 0.180, da, 46);
  double first2 = NAN, first4 = NAN;
  for (const Strobes& s : diagram) {
    const bool p2 =
        s.Split(1) > 1e-3 && s.Split(2)<0.1 * s.Split(1), p4 = s.Split(2)> 1e-3 && s.Split(4) < 0.1 * s.Split(2);
    if (std::isnan(first2) && p2) first2 = s.alpha;
    if (std::isnan(first4) && p4) first4 = s.alpha;
  }
  ASSERT_FALSE(std::isnan(first2));
  ASSERT_FALSE(std::isnan(first4));
  // The grid agrees to its step (near a period doubling, a run's transient from the previous grid
  // point decays as |μ|^n with |μ| ≈ 1 and may still look doubled one step early).
  EXPECT_LT(std::fabs(a_pd1 - first2), da);
  EXPECT_LT(std::fabs(a_pd2 - first4), da);
  // Sharper: past a period doubling the doubled splitting grows as √(α − α_pd), so |s_n − s0|² is
  // linear in α; a least-squares line through the 4 grid points after the first doubled one crosses 0
  // at the brute-force α_pd.
  auto extrapolate = [&](double first, int n) {
    double sx = 0, sy = 0, sxx = 0, sxy = 0;
    int count = 0;
    for (const Strobes& s : diagram)
      if (s.alpha > first + 0.5 * da && s.alpha < first + 4.5 * da) {
        const double d2 = s.Split(n) * s.Split(n);
        sx += s.alpha, sy += d2, sxx += s.alpha * s.alpha, sxy += s.alpha * d2, ++count;
      }
    EXPECT_EQ(count, 4);
    const double slope = (count * sxy - sx * sy) / (count * sxx - sx * sx), intercept = (sy - slope * sx) / count;
    return -intercept / slope;
  };
  const double a_brute = extrapolate(first2, 1), a_brute2 = extrapolate(first4, 2);
  EXPECT_NEAR(a_pd1, a_brute, 1e-5) << "brute force " << a_brute << ", continuation " << a_pd1;
  EXPECT_NEAR(a_pd2, a_brute2, 1e-4) << "brute force " << a_brute2 << ", continuation " << a_pd2;
  RecordProperty("alpha_pd1_hbm", std::to_string(a_pd1));
  RecordProperty("alpha_pd1_brute", std::to_string(a_brute));
  std::printf(
      "period doubling 1: continuation %.8f, brute force %.8f (grid: first period 2 at %.4f); "
      "period doubling 2: continuation %.8f, brute force %.8f (grid: first period 4 at %.4f)\n",
      a_pd1, a_brute, first2, a_pd2, a_brute2, first4);

  // The switched period-2 branch against the integrated period-2 orbit at α = 0.19 (a grid point).
  const double a = 0.19;
  const Strobes* s19 = nullptr;
  for (const Strobes& s : diagram)
    if (std::fabs(s.alpha - a) < 1e-12) s19 = &s;
  ASSERT_NE(s19, nullptr);
  ASSERT_GT(s19->Split(1), 0.1);
  const HbmBranch* two = nullptr;
  for (const HbmBranch& b : r->branches)
    if (b.period == 2 && b.points.front().mean > 0) two = &b;
  ASSERT_NE(two, nullptr);
  EXPECT_NE(two->start.find("period-doubling at alpha = 0.18443"), std::string::npos) << two->start;
  for (const HbmPoint& p : two->points) EXPECT_EQ(p.period, 2);
  HbmOptions o2 = o;
  o2.subharmonic = 2;
  o2.harmonics = 20;
  const HarmonicBalance hb2(o2);
  Eigen::VectorXd z;
  for (size_t i = 1; i < two->points.size() && z.size() == 0; ++i) {
    const HbmPoint &p = two->points[i - 1], &q = two->points[i];
    if ((p.alpha - a) * (q.alpha - a) <= 0) z = p.z + (a - p.alpha) / (q.alpha - p.alpha) * (q.z - p.z);
  }
  ASSERT_EQ(z.size(), hb2.size()) << "the period-2 branch passes alpha 0.19";
  ASSERT_GE(hb2.Solve(&z, o.omega, a), 0);
  const HbmPoint p2 = hb2.Describe(z, o.omega, a, o.floquet_steps);
  EXPECT_TRUE(p2.stable);
  EXPECT_NEAR(p2.amplitude, s19->amplitude, 2e-4 * s19->amplitude);
  // The orbit's stroboscopic pair y(0), y(T) (the harmonics of Ω/2 at τ = 0 and τ = 2π/Ω) is the
  // integration's pair of samples, in one order or the other.
  double y0 = z[0], yt = z[0];
  for (int k = 1; k <= 20; ++k) y0 += z[2 * k - 1], yt += z[2 * k - 1] * (k % 2 ? -1.0 : 1.0);
  const double d_same = std::max(std::fabs(y0 - s19->y[0]), std::fabs(yt - s19->y[1]));
  const double d_swap = std::max(std::fabs(y0 - s19->y[1]), std::fabs(yt - s19->y[0]));
  EXPECT_LT(std::min(d_same, d_swap), 1e-6)
      << "HBM " << y0 << ", " << yt << "; integration " << s19->y[0] << ", " << s19->y[1];
  std::printf(
      "period-2 orbit at alpha 0.19: amplitude %.6f (HBM) vs %.6f (integration); strobes %.8f %.8f vs %.8f %.8f\n",
      p2.amplitude, s19->amplitude, y0, yt, s19->y[0], s19->y[1]);
}

TEST(HbmFoldCurve, FoldsOfOneParameterContinuationsLieOnTheFoldCurveAndItsCuspEndsTheHysteresis) {
  HbmOptions o = Options(ModelKind::kStandalone, 0.3);
  auto r = ContinueBranches(o);
  ASSERT_TRUE(r.ok());
  auto curves = ContinueFoldCurves(o, FoldCurveOptions{}, *r);
  ASSERT_TRUE(curves.ok()) << curves.status().ToString();
  // The +well softening resonance: one curve through both of its folds at α = 0.3, with one cusp.
  const FoldCurve* c = nullptr;
  for (const FoldCurve& fc : *curves)
    if (fc.start.find("positive well") != std::string::npos) c = &fc;
  ASSERT_NE(c, nullptr);
  EXPECT_TRUE(c->converged);
  const FoldCurvePoint* cusp = nullptr;
  int cusps = 0;
  for (const FoldCurvePoint& p : c->points)
    if (p.cusp) cusp = &p, ++cusps;
  ASSERT_EQ(cusps, 1);
  EXPECT_LT(cusp->alpha, 0.05);
  // Points of the curve on either side of the cusp, low and high: a continuation in Ω at that α has a
  // located fold at that Ω.
  for (double target : {0.1, 0.6}) {
    for (int side = 0; side < 2; ++side) {
      const FoldCurvePoint* q = nullptr;
      for (const FoldCurvePoint& p : c->points) {
        const bool left = &p < cusp;
        if (left == (side == 0) && (!q || std::fabs(p.alpha - target) < std::fabs(q->alpha - target))) q = &p;
      }
      ASSERT_NE(q, nullptr);
      HbmOptions one = o;
      one.alpha = q->alpha;
      auto r1 = ContinueBranches(one);
      ASSERT_TRUE(r1.ok());
      double nearest = INFINITY;
      for (const HbmBranch& b : r1->branches)
        for (const HbmPoint& p : b.points)
          if (p.fold && p.fold_at.valid()) nearest = std::min(nearest, std::fabs(p.fold_at.omega - q->omega));
      EXPECT_LT(nearest, 1e-6) << "alpha " << q->alpha << ", Omega on the fold curve " << q->omega;
      std::printf("fold curve point alpha %.6f Omega %.8f: one-parameter fold within %.2e\n", q->alpha, q->omega,
                  nearest);
    }
  }
  // Below the cusp the +well resonance does not fold (one orbit per Ω: no hysteresis); above it, twice.
  for (double f : {0.7, 1.5}) {
    HbmOptions one = o;
    one.alpha = f * cusp->alpha;
    auto r1 = ContinueBranches(one);
    ASSERT_TRUE(r1.ok());
    int folds = -1;
    for (const HbmBranch& b : r1->branches)
      if (b.points.front().mean > 0.9) {
        folds = 0;
        for (const HbmPoint& p : b.points) folds += p.fold;
      }
    EXPECT_EQ(folds, f < 1 ? 0 : 2) << "alpha " << one.alpha;
  }
}

// The coupled model (paper defaults, α 0.2) loses stability through Neimark–Sacker points: located
// where a complex pair is on the unit circle, the stability changing across the step.
TEST(HbmNeimarkSacker, LocatedWhereAComplexPairCrossesTheUnitCircle) {
  HbmOptions o = Options(ModelKind::kCoupled, 0.2);
  o.harmonics = 7;
  auto r = ContinueBranches(o);
  ASSERT_TRUE(r.ok());
  int located = 0;
  for (const HbmBranch& b : r->branches)
    for (size_t i = 1; i < b.points.size(); ++i) {
      const HbmPoint& p = b.points[i];
      if (!p.neimark_sacker || !p.neimark_sacker_at.valid()) continue;
      const std::complex<double> mu = p.neimark_sacker_at.multiplier;
      EXPECT_NEAR(std::abs(mu), 1.0, 1e-6) << b.start << " Omega " << p.neimark_sacker_at.omega;
      EXPECT_GT(std::fabs(mu.imag()), 0.1);
      const double lo = std::min(b.points[i - 1].omega, p.omega), hi = std::max(b.points[i - 1].omega, p.omega);
      EXPECT_GE(p.neimark_sacker_at.omega, lo);
      EXPECT_LE(p.neimark_sacker_at.omega, hi);
      if (!p.period_doubling && !p.fold) {
        EXPECT_NE(p.stable, b.points[i - 1].stable);
      }
      ++located;
    }
  EXPECT_GE(located, 2);
}

TEST(HbmFoldCurve, BadOptionsNameTheField) {
  HbmOptions o = Options(ModelKind::kStandalone, 0.3);
  FoldCurveOptions f;
  f.alpha_lo = 2, f.alpha_hi = 1;
  EXPECT_EQ(ContinueFoldCurve(o, f, Eigen::VectorXd::Zero(11), 1.0, 0.3).status().field(), "alpha_range");
  f = FoldCurveOptions{};
  f.omega_lo = -1;
  EXPECT_EQ(ContinueFoldCurve(o, f, Eigen::VectorXd::Zero(11), 1.0, 0.3).status().field(), "omega_range");
  o.switch_depth = 4;
  EXPECT_EQ(ContinueBranches(o).status().field(), "switch_pd");
}

}  // namespace
}  // namespace bistable
