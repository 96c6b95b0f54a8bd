// Settled labels (issue 38, dynamics/settle.h): a chain of windows until the label settles; lanes that
// have not settled are suspended and resumed in fresh blocks, and the result is the same bits as one
// lane alone (`bistable point`) — map == point.
#include <algorithm>
#include <cmath>
#include <cstring>
#include <tuple>
#include <vector>

#include <gtest/gtest.h>

#include "dynamics/point.h"
#include "dynamics/settle.h"
#include "engine/sweep_spec.h"

namespace bistable {
namespace {

PointSpec Settled(ModelKind m, double alpha, double omega) {
  PointSpec s;
  s.model = m;
  s.alpha = alpha;
  s.omega = omega;
  s.metrics.rosenstein = false;
  s.integration.labels = LabelMode::kSettled;
  return s;
}

bool SameBits(double a, double b) { return std::memcmp(&a, &b, sizeof a) == 0; }

void ExpectSame(const PointResult& a, const PointResult& b, const char* what) {
  SCOPED_TRACE(what);
  EXPECT_EQ(a.motion, b.motion);
  EXPECT_EQ(a.period, b.period);
  EXPECT_EQ(a.steps, b.steps);
  for (auto [x, y, name] : {std::tuple{a.lle, b.lle, "lle"},
                            {a.lle_sigma, b.lle_sigma, "lle_sigma"},
                            {a.settle_time, b.settle_time, "settle_time"},
                            {a.label_confidence, b.label_confidence, "label_confidence"},
                            {a.frf_db, b.frf_db, "frf"},
                            {a.hd_index, b.hd_index, "hd"},
                            {a.edr_t, b.edr_t, "edr_t"},
                            {a.y_min, b.y_min, "y_min"},
                            {a.strobe_y, b.strobe_y, "strobe_y"}})
    EXPECT_TRUE(SameBits(x, y)) << name << ": " << x << " vs " << y;
  for (int d = 0; d < 4; ++d) EXPECT_TRUE(SameBits(a.final_state[d], b.final_state[d]));
}

// Points that settle at different times (periodic at once, a slow transient, chaos, a cap), so the
// blocks of 8 are suspended and resumed in other company across the tiers.
std::vector<PointSpec> Mixed(ModelKind m) {
  const double pts[][2] = {{1.0, 2.5}, {0.3, 1.2}, {1.0, 1.0}, {0.2, 2.5}, {2.0, 0.8}, {0.5, 0.5},
                           {1.5, 1.4}, {0.1, 3.0}, {2.5, 1.9}, {0.8, 0.3}, {1.2, 1.6}};
  std::vector<PointSpec> v;
  for (auto& p : pts) {
    PointSpec s = Settled(m, p[0], p[1]);
    s.integration.settle_confirm = 1200;  // chaos settles past two tiers (τ 750, 1250): resumed twice
    s.integration.settle_cap = 2000;
    v.push_back(s);
  }
  return v;
}

TEST(Settle, MapEqualsPointAtAnyWidthWithSuspendedLanes) {
  for (ModelKind m : {ModelKind::kCoupled, ModelKind::kStandalone}) {
    const std::vector<PointSpec> specs = Mixed(m);
    std::vector<PointResult> eight(specs.size()), four(specs.size());
    ASSERT_TRUE(EvaluateSettled<8>(specs.data(), specs.size(), eight.data()));
    ASSERT_TRUE(EvaluateSettled<4>(specs.data(), specs.size(), four.data()));
    std::vector<double> times;
    for (size_t i = 0; i < specs.size(); ++i) {
      auto one = EvaluatePoint(specs[i]);
      ASSERT_TRUE(one.ok());
      ExpectSame(*one, eight[i], "point vs 8 lanes");
      ExpectSame(*one, four[i], "point vs 4 lanes");
      times.push_back(one->settle_time);
    }
    // The sample does exercise suspension: some settle at the first chance, some much later.
    EXPECT_LE(*std::min_element(times.begin(), times.end()), 500.0);
    EXPECT_GE(*std::max_element(times.begin(), times.end()), 1450.0);
  }
}

TEST(Settle, SlowTransientSettlesToItsPeriodNotToATransientOne) {
  // Coupled α 0.3, Ω 1.2: the paper's window reads period 0, τ 500–750 period 2; the orbit is period 1
  // (docs/numerics.md, "Known limits of the window metrics").
  auto r = EvaluatePoint(Settled(ModelKind::kCoupled, 0.3, 1.2));
  ASSERT_TRUE(r.ok());
  EXPECT_EQ(r->period, 1);
  EXPECT_NE(r->motion, Motion::kChaotic);
  EXPECT_NE(r->motion, Motion::kUnresolved);
  EXPECT_GT(r->settle_time, 750.0);
  EXPECT_LT(r->lle + 2 * r->lle_sigma, 0.0);
  EXPECT_GE(r->label_confidence, 0.5);
}

TEST(Settle, ChaosNeedsItsErrorBarAndTheConfirmationTime) {
  PointSpec s = Settled(ModelKind::kCoupled, 1.0, 1.0);
  auto r = EvaluatePoint(s);
  ASSERT_TRUE(r.ok());
  ASSERT_EQ(r->motion, Motion::kChaotic);
  EXPECT_GT(r->lle - 2 * r->lle_sigma, s.metrics.chaos_threshold);
  EXPECT_GE(r->settle_time, s.integration.t_keep + s.integration.settle_confirm);
  EXPECT_GT(r->label_confidence, 0.97);
  // Below the confirmation time the same orbit cannot be called chaotic: the cap ends it unresolved.
  s.integration.settle_cap = 1000;
  auto u = EvaluatePoint(s);
  ASSERT_TRUE(u.ok());
  EXPECT_EQ(u->motion, Motion::kUnresolved);
  EXPECT_EQ(u->label_confidence, 0.0);
  EXPECT_DOUBLE_EQ(u->settle_time, 1250.0);
}

TEST(Settle, PeriodicPointSettlesAfterTwoWindows) {
  PointSpec s = Settled(ModelKind::kCoupled, 1.0, 2.5);
  auto r = EvaluatePoint(s);
  ASSERT_TRUE(r.ok());
  EXPECT_EQ(r->period, 1);
  EXPECT_EQ(r->motion, Motion::kInterwell);
  EXPECT_DOUBLE_EQ(r->settle_time, s.integration.t_keep + 2 * s.integration.settle_window);
  EXPECT_LT(r->hd_index, 1e-3);
}

TEST(Settle, PaperModeIsTheDefaultAndUntouched) {
  PointSpec s;
  s.metrics.rosenstein = false;
  EXPECT_EQ(s.integration.labels, LabelMode::kPaper);
  auto r = EvaluatePoint(s);
  ASSERT_TRUE(r.ok());
  EXPECT_TRUE(std::isnan(r->settle_time));
  EXPECT_TRUE(std::isnan(r->lle_sigma));
  EXPECT_EQ(r->steps, 50000);
}

TEST(Settle, SpecReadsTheLabelMode) {
  const std::string base = "model = \"coupled\"\n[axes]\nalpha = [0.5, 1.0]\nomega = [1.0]\n[integration]\n";
  auto ok = ParseSweepSpec(base + "labels = \"settled\"\nsettle_window = 100.0\nsettle_cap = 3000.0\n", "t");
  ASSERT_TRUE(ok.ok()) << ok.status().ToString();
  EXPECT_EQ(ok->base.integration.labels, LabelMode::kSettled);
  EXPECT_EQ(ok->base.integration.settle_window, 100.0);
  auto paper = ParseSweepSpec(base + "labels = \"paper\"\n", "t");
  ASSERT_TRUE(paper.ok());
  EXPECT_NE(ok->Id(), paper->Id());
  auto none = ParseSweepSpec(base, "t");
  ASSERT_TRUE(none.ok());
  EXPECT_EQ(none->Id(), paper->Id());  // the paper's mode keeps its ids
  auto bad = ParseSweepSpec(base + "labels = \"long\"\n", "t");
  EXPECT_FALSE(bad.ok());
  auto window = ParseSweepSpec(base + "labels = \"settled\"\nsettle_window = 0.005\n", "t");
  EXPECT_FALSE(window.ok());
}

}  // namespace
}  // namespace bistable

namespace bistable {
namespace {

// The 0-1 test (Gottwald & Melbourne): K ≈ 1 on a chaotic series (the logistic map at r = 4), ≈ 0 on a
// regular one (a quasi-periodic sum of two incommensurate tones, a period-3 cycle); NaN when too short.
TEST(Settle, ZeroOneTestTellsChaosFromRegularSeries) {
  std::vector<double> chaos(400), torus(400), cycle(400);
  double x = 0.3;
  for (size_t j = 0; j < chaos.size(); ++j) {
    x = 4 * x * (1 - x);
    chaos[j] = x;
    torus[j] = std::sin(0.7 * j) + 0.5 * std::sin(0.7 * std::sqrt(2.0) * j);
    cycle[j] = j % 3 == 0 ? 0.2 : j % 3 == 1 ? 0.9 : 0.5;
  }
  EXPECT_GT(ZeroOneTestK(chaos.data(), chaos.size()), 0.9);
  EXPECT_LT(std::fabs(ZeroOneTestK(torus.data(), torus.size())), 0.2);
  EXPECT_LT(std::fabs(ZeroOneTestK(cycle.data(), cycle.size())), 0.2);
  EXPECT_TRUE(std::isnan(ZeroOneTestK(chaos.data(), 63)));
}

// A chaotic point carries its 0-1 K; a periodic one NaN; a veto above every K turns chaos into an
// extended run that ends unresolved at the cap.
TEST(Settle, ChaoticLabelsCarryTheirZeroOneTestAndTheVetoHolds) {
  PointSpec s = Settled(ModelKind::kStandalone, 0.3472222222222222, 1.2);  // Ueda/Holmes Duffing attractor
  s.params.eta = 0.3;
  auto r = EvaluatePoint(s);
  ASSERT_TRUE(r.ok());
  ASSERT_EQ(r->motion, Motion::kChaotic);
  EXPECT_GT(r->chaos_01, 0.5);  // 0.78 from the ~190 strobes of [T/2, T]
  PointSpec p = Settled(ModelKind::kCoupled, 1.0, 2.5);
  auto q = EvaluatePoint(p);
  ASSERT_TRUE(q.ok());
  EXPECT_NE(q->motion, Motion::kChaotic);
  if (q->period >= 1) {
    EXPECT_TRUE(std::isnan(q->chaos_01));
  }
  s.metrics.chaos_01_min = 1.0;
  s.integration.settle_cap = 3000;
  auto v = EvaluatePoint(s);
  ASSERT_TRUE(v.ok());
  EXPECT_EQ(v->motion, Motion::kUnresolved);
  EXPECT_DOUBLE_EQ(v->settle_time, 3250.0);
}

}  // namespace
}  // namespace bistable
