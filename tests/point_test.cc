// Per-point metrics of model.md §3 on the paper's models: closed forms, exact energy balance,
// lane-width independence, motion classification, and validation of bad input.
#include <cmath>
#include <cstring>
#include <string>
#include <tuple>
#include <vector>

#include <gtest/gtest.h>

#include "dynamics/point.h"
#include "tests/eval_point.h"

namespace bistable {
namespace {

PointSpec Spec(ModelKind m, double alpha, double omega) {
  PointSpec s;
  s.model = m;
  s.alpha = alpha;
  s.omega = omega;
  s.metrics.rosenstein = false;
  return s;
}

// Absolute-velocity transmissibility of y'' + ηy' + y = αΩ² sin Ωτ: |1 + iηΩ| / |1 − Ω² + iηΩ|.
double LinearTransmissibilityDb(double eta, double omega) {
  return 20 * std::log10(std::hypot(1.0, eta * omega) / std::hypot(1.0 - omega * omega, eta * omega));
}

TEST(PointFrf, LinearOscillatorMatchesClosedFormTransmissibility) {
  for (IntegratorKind integ : {IntegratorKind::kRk4, IntegratorKind::kAdaptive}) {
    for (double omega = 0.1; omega <= 3.0001; omega += 0.1) {
      PointSpec s = Spec(ModelKind::kLinear, 0.5, omega);
      s.integration.integrator = integ;
      const PointResult r = Eval(s);
      // 0.01 dB is the acceptance bound; the transient has decayed by e^{−ηt_keep/2} ≈ 4e-6 at the window.
      EXPECT_NEAR(r.frf_db, LinearTransmissibilityDb(0.1, omega), 0.01) << IntegratorName(integ) << " omega " << omega;
      EXPECT_EQ(r.motion, Motion::kIntrawell);
    }
  }
}

TEST(PointEnergy, BalanceClosesOnCoupledPeriodicAndChaoticRuns) {
  struct Case {
    double alpha, omega;
    Motion expect;
  };
  for (const Case c :
       {Case{0.6, 1.2, Motion::kIntrawell}, Case{1.0, 1.2, Motion::kChaotic}, Case{2.0, 3.0, Motion::kInterwell}}) {
    for (IntegratorKind integ : {IntegratorKind::kRk4, IntegratorKind::kAdaptive}) {
      PointSpec s = Spec(ModelKind::kCoupled, c.alpha, c.omega);
      s.integration.integrator = integ;
      const PointResult r = Eval(s);
      EXPECT_EQ(r.motion, c.expect) << c.alpha << "," << c.omega;
      EXPECT_LT(r.energy_balance_residual, 1e-6) << IntegratorName(integ) << " " << c.alpha << "," << c.omega;
      EXPECT_GT(r.w_in, 0);
      EXPECT_GT(r.w_r, 0);
      EXPECT_NEAR(r.edr_t, r.edr_b + r.edr_r, 1e-9);
      // W_m + W_r = ∫P − ΔE ≤ W_in − ΔE: dissipation cannot exceed the gross input plus released energy.
      EXPECT_LE(r.edr_t, 100.0 * (1.0 - r.delta_e / r.w_in) + 1e-6);
    }
  }
}

TEST(PointEnergy, StandaloneResonatorTermsAreZero) {
  const PointResult r = Eval(Spec(ModelKind::kStandalone, 0.3, 2.0));
  EXPECT_EQ(r.w_r, 0.0);
  EXPECT_EQ(r.edr_r, 0.0);
  EXPECT_LT(r.energy_balance_residual, 1e-6);
}

// A point's result must not depend on the lane width or on the other points in the block:
// sweeps run 16 lanes, `bistable point` runs one. Chaotic points amplify any rounding difference
// exponentially, so they are the sharp test.
// Every field of a lane's raw record, bit for bit (memcmp: NaNs and signed zeros included).
void ExpectSameBits(const RawLane& a, const RawLane& b, const std::string& where) {
  auto same = [](const double& x, const double& y) { return std::memcmp(&x, &y, sizeof(double)) == 0; };
  auto same_vec = [](const std::vector<double>& x, const std::vector<double>& y) {
    return x.size() == y.size() && (x.empty() || std::memcmp(x.data(), y.data(), x.size() * sizeof(double)) == 0);
  };
  for (auto [name, x, y] : {std::tuple{"vabs_max", a.vabs_max, b.vabs_max},
                            {"y_min", a.y_min, b.y_min},
                            {"y_max", a.y_max, b.y_max},
                            {"log_growth", a.log_growth, b.log_growth},
                            {"q_p", a.q_p, b.q_p},
                            {"q_in", a.q_in, b.q_in},
                            {"q_m", a.q_m, b.q_m},
                            {"q_r", a.q_r, b.q_r},
                            {"e_start", a.e_start, b.e_start},
                            {"e_end", a.e_end, b.e_end}})
    EXPECT_TRUE(same(x, y)) << where << ": " << name << " " << x << " vs " << y;
  for (int d = 0; d < 4; ++d) EXPECT_TRUE(same(a.final_state[d], b.final_state[d])) << where << ": final_state " << d;
  EXPECT_TRUE(same_vec(a.y_samples, b.y_samples)) << where << ": y_samples";
  EXPECT_TRUE(same_vec(a.strobe_y, b.strobe_y)) << where << ": strobe_y";
  EXPECT_TRUE(same_vec(a.strobe_v, b.strobe_v)) << where << ": strobe_v";
  EXPECT_TRUE(same_vec(a.strobe_yr, b.strobe_yr)) << where << ": strobe_yr";
  EXPECT_TRUE(same_vec(a.strobe_vr, b.strobe_vr)) << where << ": strobe_vr";
  EXPECT_EQ(a.strobe_k0, b.strobe_k0) << where << ": strobe_k0";
  EXPECT_TRUE(same_vec(a.turning_points, b.turning_points)) << where << ": turning_points";
  EXPECT_EQ(a.diverged, b.diverged) << where;
  EXPECT_EQ(a.steps, b.steps) << where;
}

template <int W>
void ExpectLaneEqualsOnePoint(const PointSpec& s, const RawLane& one, int position) {
  const KernelSettings ks = KernelSettingsFor(s);
  std::vector<LaneInput> lanes(W);
  for (int l = 0; l < W; ++l) lanes[l] = LaneFor(Spec(ModelKind::kCoupled, 0.2 + 0.15 * l, 0.3 + 0.17 * l));
  lanes[position] = LaneFor(s);
  std::vector<RawLane> many(W);
  ASSERT_TRUE(RunKernel<W>(s.model, lanes.data(), W, ks, many.data()));
  ExpectSameBits(one, many[position], "width " + std::to_string(W) + " lane " + std::to_string(position));
}

TEST(EnsembleKernel, SectionAtAPhaseIsBitIdenticalAtAnyWidthAndPosition) {
  // The Poincaré section's phase shifts every lane's strobes (and so the steps the general loop takes).
  PointSpec s = Spec(ModelKind::kCoupled, 1.0, 1.2);
  s.metrics.poincare_phase = 2.5;
  const LaneInput target = LaneFor(s);
  RawLane one;
  ASSERT_TRUE(RunKernel<1>(s.model, &target, 1, KernelSettingsFor(s), &one));
  ASSERT_GT(one.strobe_yr.size(), 30u);
  ExpectLaneEqualsOnePoint<4>(s, one, 3);
  ExpectLaneEqualsOnePoint<16>(s, one, 5);
}

TEST(EnsembleKernel, LaneResultsAreBitIdenticalAtAnyWidthAndPosition) {
  // A chaotic point with many turning points (the recorder's buffer fills and is flushed several
  // times), strobes and samples, among neighbours whose strobes and crossings fall elsewhere.
  PointSpec s = Spec(ModelKind::kCoupled, 1.0, 1.0);
  const KernelSettings ks = KernelSettingsFor(s);
  const LaneInput target = LaneFor(s);
  RawLane one;
  ASSERT_TRUE(RunKernel<1>(s.model, &target, 1, ks, &one));
  ASSERT_GE(one.turning_points.size(), 64u);  // > 2 buffers of 32
  ASSERT_GT(one.strobe_y.size(), 30u);
  ExpectLaneEqualsOnePoint<2>(s, one, 1);
  ExpectLaneEqualsOnePoint<4>(s, one, 2);
  ExpectLaneEqualsOnePoint<8>(s, one, 7);
  ExpectLaneEqualsOnePoint<8>(s, one, 0);
  ExpectLaneEqualsOnePoint<16>(s, one, 11);
  // And through the metric layer: EvaluatePoint equals the lane's metrics.
  std::vector<RawLane> many(8);
  std::vector<LaneInput> lanes(8, target);
  ASSERT_TRUE(RunKernel<8>(s.model, lanes.data(), 8, ks, many.data()));
  const PointResult p = Eval(s), q = ComputePointMetrics(many[8 - 1], s);
  EXPECT_EQ(std::memcmp(&p.frf_db, &q.frf_db, sizeof(double)), 0);
  EXPECT_EQ(std::memcmp(&p.lle, &q.lle, sizeof(double)), 0);
  EXPECT_EQ(p.hd_index, q.hd_index);
  EXPECT_EQ(p.turning_points, q.turning_points);
}

// A trace (keep_rows) runs every step through the general loop; the fast loop must give the same bits.
TEST(EnsembleKernel, FastLoopEqualsTheGeneralLoop) {
  const PointSpec s = Spec(ModelKind::kCoupled, 1.0, 1.0);
  KernelSettings ks = KernelSettingsFor(s);
  const LaneInput target = LaneFor(s);
  RawLane fast, general;
  ASSERT_TRUE(RunKernel<1>(s.model, &target, 1, ks, &fast));
  ks.keep_rows = true;
  ASSERT_TRUE(RunKernel<1>(s.model, &target, 1, ks, &general));
  ExpectSameBits(fast, general, "keep_rows");
  EXPECT_FALSE(general.rows.empty());
}

TEST(EnsembleKernel, AdaptivePathAgreesWithRk4OnPeriodicPoints) {
  for (auto [m, a, w] : {std::tuple{ModelKind::kCoupled, 0.6, 1.2}, std::tuple{ModelKind::kStandalone, 0.6, 2.0}}) {
    PointSpec s = Spec(m, a, w);
    const PointResult rk = Eval(s);
    s.integration.integrator = IntegratorKind::kAdaptive;
    const PointResult ad = Eval(s);
    EXPECT_NEAR(rk.frf_db, ad.frf_db, 0.01);
    EXPECT_NEAR(rk.lle, ad.lle, 0.005);
    EXPECT_EQ(rk.motion, ad.motion);
    EXPECT_EQ(rk.period, ad.period);
    EXPECT_NEAR(rk.edr_t, ad.edr_t, 0.05);
  }
}

TEST(PointMotion, ClassifiesIntrawellInterwellChaoticAndPeriod) {
  struct Case {
    ModelKind m;
    double alpha, omega;
    Motion motion;
    int period;
  };
  const Case cases[] = {
      {ModelKind::kStandalone, 0.1, 0.8, Motion::kIntrawell, 1},
      {ModelKind::kStandalone, 0.1, 3.0, Motion::kIntrawell, 2},  // period doubling inside the well
      {ModelKind::kStandalone, 0.6, 2.0, Motion::kInterwell, 1},
      {ModelKind::kStandalone, 1.0, 1.2, Motion::kInterwell, 2},
      {ModelKind::kStandalone, 0.3, 2.0, Motion::kChaotic, 0},
      {ModelKind::kCoupled, 1.0, 1.2, Motion::kChaotic, 0},
      {ModelKind::kCoupled, 0.6, 3.0, Motion::kInterwell, 5},
  };
  for (const Case& c : cases) {
    const PointResult r = Eval(Spec(c.m, c.alpha, c.omega));
    EXPECT_EQ(r.motion, c.motion) << ModelName(c.m) << " " << c.alpha << "," << c.omega;
    EXPECT_EQ(r.period, c.period) << ModelName(c.m) << " " << c.alpha << "," << c.omega;
    if (c.motion == Motion::kChaotic) {
      EXPECT_GT(r.lle, 3 * PointSpec{}.metrics.chaos_threshold);
      EXPECT_GT(r.hd_index, 0.3);
    }
    if (c.period == 1) {
      EXPECT_LT(r.hd_index, 1e-3);
    }
  }
}

TEST(PointMotion, SlowTransientAliasingOntoSubharmonicIsNotAPeriod) {
  // Coupled α 0.1, Ω 3: a lightly damped mode (decay ≈ 0.015/τ) near Ω/5 is still alive at τ = 250.
  // Its stroboscopic samples nearly repeat after 5 periods, but it decays: no period in the
  // default window; settled to period 1 when the run is long enough.
  PointSpec s = Spec(ModelKind::kCoupled, 0.1, 3.0);
  EXPECT_EQ(Eval(s).period, 0);
  s.integration.t_end = 2000;
  EXPECT_EQ(Eval(s).period, 1);
}

TEST(PointMotion, SpectralPeaksIncludeTheForcingFrequencyAndItsSubharmonic) {
  const PointResult r = Eval(Spec(ModelKind::kStandalone, 0.1, 3.0));
  ASSERT_GE(r.hd_peaks.size(), 2u);
  bool at_omega = false, at_half = false;
  for (const HdPeak& p : r.hd_peaks) {
    at_omega |= std::fabs(p.freq - 3.0) < 0.01;
    at_half |= std::fabs(p.freq - 1.5) < 0.01;
  }
  EXPECT_TRUE(at_omega);
  EXPECT_TRUE(at_half);
}

TEST(PointResult, DivergingIntegrationIsAResultNotACrash) {
  PointSpec s = Spec(ModelKind::kStandalone, 3.0, 3.0);
  s.integration.dt = 1.0;  // far beyond RK4's stability limit for the cubic stiffness at this amplitude
  s.integration.t_end = 500;
  s.integration.t_keep = 250;
  auto r = EvaluatePoint(s);
  ASSERT_TRUE(r.ok());
  EXPECT_EQ(r->termination, Termination::kDiverged);
  EXPECT_TRUE(std::isnan(r->frf_db));
  EXPECT_TRUE(std::isnan(r->lle));
  // Issue 39: extremes and energies are undefined too, not 0.0 (a value a real run can have).
  for (double v : {r->y_min, r->y_max, r->w_in, r->w_net, r->w_m, r->w_r, r->delta_e, r->edr_b, r->edr_t,
                   r->energy_balance_residual})
    EXPECT_TRUE(std::isnan(v)) << v;
}

TEST(PointResult, DefaultInitialStateIsRestInThePositiveWell) {
  PointSpec s = Spec(ModelKind::kCoupled, 1, 1);
  s.params.eps = 4;
  EXPECT_EQ(InitialState(s), (std::array<double, 4>{0.5, 0, 0.5, 0}));
  s.model = ModelKind::kLinear;
  EXPECT_EQ(InitialState(s), (std::array<double, 4>{0, 0, 0, 0}));
  s.ic_given = true;
  s.ic = {0.1, 0.2, 0.3, 0.4};
  EXPECT_EQ(InitialState(s), s.ic);
}

struct BadCase {
  const char* name;
  void (*mutate)(PointSpec&);
  const char* field;
  const char* bound;  // a fragment the message must contain
};

TEST(PointValidation, BadInputsNameTheFieldAndTheBound) {
  const BadCase cases[] = {
      {"nan alpha", [](PointSpec& s) { s.alpha = NAN; }, "alpha", "finite"},
      {"alpha zero", [](PointSpec& s) { s.alpha = 0; }, "alpha", "alpha > 0"},
      {"alpha negative", [](PointSpec& s) { s.alpha = -1; }, "alpha", "alpha = -1 violates alpha > 0"},
      {"omega inf", [](PointSpec& s) { s.omega = INFINITY; }, "omega", "finite"},
      {"negative damping", [](PointSpec& s) { s.params.eta = -0.1; }, "eta", "eta >= 0"},
      {"negative resonator damping", [](PointSpec& s) { s.params.eta_r = -1; }, "eta_r", "eta_r >= 0"},
      {"zero mass ratio", [](PointSpec& s) { s.params.phi = 0; }, "phi", "phi > 0"},
      {"eps zero", [](PointSpec& s) { s.params.eps = 0; }, "eps", "eps > 0"},
      {"window after run", [](PointSpec& s) { s.integration.t_keep = 600; }, "t_keep", "< t_end"},
      {"window equals run", [](PointSpec& s) { s.integration.t_keep = 500; }, "t_keep", "< t_end"},
      {"negative step", [](PointSpec& s) { s.integration.dt = -0.01; }, "dt", "dt > 0"},
      {"t_end not whole steps", [](PointSpec& s) { s.integration.t_end = 500.005; }, "t_end", "whole multiple of dt"},
      {"nan initial state", [](PointSpec& s) { s.ic[2] = NAN; }, "ic[2]", "finite"},
  };
  for (const BadCase& c : cases) {
    PointSpec s = Spec(ModelKind::kCoupled, 1, 1);
    c.mutate(s);
    auto r = EvaluatePoint(s);
    ASSERT_FALSE(r.ok()) << c.name;
    EXPECT_EQ(r.status().code(), Status::Code::kInvalidArgument) << c.name;
    EXPECT_EQ(r.status().field(), c.field) << c.name;
    EXPECT_NE(r.status().message().find(c.bound), std::string::npos) << c.name << ": " << r.status().message();
  }
  auto m = ParseModel("duffing");
  ASSERT_FALSE(m.ok());
  EXPECT_EQ(m.status().field(), "model");
  EXPECT_NE(m.status().message().find("standalone, coupled, linear"), std::string::npos);
}

}  // namespace
}  // namespace bistable
