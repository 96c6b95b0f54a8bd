// Poincaré (stroboscopic) sections of a point (model.md §3): a period-n orbit gives n points, the
// phase convention against the linear oscillator's closed form, and the double-well Duffing
// oscillator's strange attractor at γ = αΩ² = 0.5 (η = 0.3, Ω = 1.2) as a cloud over a 2-D region.
#include <algorithm>
#include <cmath>
#include <set>
#include <utility>
#include <vector>

#include <gtest/gtest.h>

#include "dynamics/point.h"
#include "tests/eval_point.h"

namespace bistable {
namespace {

// y'' + 0.3 y' − y + y³ = γ sin 1.2τ: the stand-alone model with η = 0.3, Ω = 1.2, αΩ² = γ.
PointSpec Duffing(double gamma, double t_keep, double t_end) {
  PointSpec s;
  s.model = ModelKind::kStandalone;
  s.params.eta = 0.3;
  s.omega = 1.2;
  s.alpha = gamma / (1.2 * 1.2);
  s.integration.t_keep = t_keep;
  s.integration.t_end = t_end;
  s.metrics.rosenstein = false;
  return s;
}

// Largest distance (max norm over y, y') between section points i and j of the same residue mod n.
double SpreadWithinResidues(const PointResult& r, int n) {
  double worst = 0;
  for (size_t i = 0; i < r.section_y.size(); ++i) {
    const size_t j = i % n;
    worst = std::max({worst, std::fabs(r.section_y[i] - r.section_y[j]), std::fabs(r.section_v[i] - r.section_v[j])});
  }
  return worst;
}

TEST(Poincare, PeriodOneOrbitIsOnePointRepeated) {
  const PointResult r = Eval(Duffing(0.2, 1000, 2000));
  ASSERT_EQ(r.period, 1);
  ASSERT_EQ(r.section_y.size(), r.section_v.size());
  ASSERT_GE(r.section_y.size(), 190u);  // 1000 τ of periods 2π/1.2 = 5.24
  EXPECT_LT(SpreadWithinResidues(r, 1), 1e-9);
  EXPECT_TRUE(r.section_yr.empty());  // no resonator
}

TEST(Poincare, PeriodTwoOrbitIsTwoPoints) {
  const PointResult r = Eval(Duffing(0.28, 1000, 2000));  // after the first period doubling
  ASSERT_EQ(r.period, 2);
  EXPECT_LT(SpreadWithinResidues(r, 2), 1e-9);
  const double apart = std::hypot(r.section_y[0] - r.section_y[1], r.section_v[0] - r.section_v[1]);
  EXPECT_GT(apart, 0.01) << "two distinct points";
}

TEST(Poincare, PhaseConventionMatchesTheLinearClosedForm) {
  // y'' + η y' + y = αΩ² sin Ωτ settles on y = A sin(Ωτ − θ): the section at phase φ is
  // (A sin(φ − θ), AΩ cos(φ − θ)) at every τ_k = (φ + 2πk)/Ω.
  PointSpec s;
  s.model = ModelKind::kLinear;
  s.params.eta = 0.5;
  s.alpha = 0.3;
  s.omega = 0.9;
  s.integration.t_keep = 400;
  s.integration.t_end = 600;
  s.metrics.rosenstein = false;
  const double amp = s.alpha * s.omega * s.omega / std::hypot(1 - s.omega * s.omega, s.params.eta * s.omega);
  const double theta = std::atan2(s.params.eta * s.omega, 1 - s.omega * s.omega);
  for (double phase : {0.0, 1.0, M_PI, 6.0}) {
    s.metrics.poincare_phase = phase;
    const PointResult r = Eval(s);
    ASSERT_FALSE(r.section_y.empty());
    // The first strobe is the first τ_k ≥ t_keep.
    const double tau0 = (phase + 2 * M_PI * r.section_k0) / s.omega;
    EXPECT_GE(tau0, s.integration.t_keep);
    EXPECT_LT(tau0 - 2 * M_PI / s.omega, s.integration.t_keep);
    EXPECT_EQ(r.section_y.size(),
              static_cast<size_t>(std::floor((s.integration.t_end - tau0) * s.omega / (2 * M_PI))) + 1);
    for (size_t i = 0; i < r.section_y.size(); ++i) {
      EXPECT_NEAR(r.section_y[i], amp * std::sin(phase - theta), 1e-8) << "phase " << phase << " point " << i;
      EXPECT_NEAR(r.section_v[i], amp * s.omega * std::cos(phase - theta), 1e-8) << "phase " << phase << " point " << i;
    }
  }
}

TEST(Poincare, CoupledSectionCarriesTheResonator) {
  PointSpec s;
  s.model = ModelKind::kCoupled;
  s.alpha = 1.0;
  s.omega = 1.2;
  s.metrics.rosenstein = false;
  const PointResult r = Eval(s);
  ASSERT_GT(r.section_y.size(), 40u);
  EXPECT_EQ(r.section_yr.size(), r.section_y.size());
  EXPECT_EQ(r.section_vr.size(), r.section_y.size());
}

TEST(Poincare, PhaseIsRejectedOutsideOneTurn) {
  PointSpec s = Duffing(0.2, 250, 500);
  for (double bad : {-0.1, 2 * M_PI, 7.0, std::nan("")}) {
    s.metrics.poincare_phase = bad;
    auto r = EvaluatePoint(s);
    ASSERT_FALSE(r.ok()) << bad;
    EXPECT_EQ(r.status().field(), "poincare_phase");
    EXPECT_NE(r.status().message().find("in [0, 2 pi)"), std::string::npos) << r.status().message();
  }
}

// Occupied cells of an n × n grid over the points' bounding box.
size_t OccupiedCells(const std::vector<double>& y, const std::vector<double>& v, int n) {
  const auto [ylo, yhi] = std::minmax_element(y.begin(), y.end());
  const auto [vlo, vhi] = std::minmax_element(v.begin(), v.end());
  std::set<std::pair<int, int>> cells;
  for (size_t i = 0; i < y.size(); ++i) {
    const int a = std::min(n - 1, static_cast<int>((y[i] - *ylo) / (*yhi - *ylo) * n));
    const int b = std::min(n - 1, static_cast<int>((v[i] - *vlo) / (*vhi - *vlo) * n));
    cells.insert({a, b});
  }
  return cells.size();
}

TEST(Poincare, DuffingStrangeAttractorFillsATwoDimensionalRegion) {
  // 5001 forcing periods after τ = 250 (what `bistable point --poincare-periods 5000` runs).
  const double period = 2 * M_PI / 1.2;
  const double t_end = 250 + std::ceil(5001 * period / 0.01) * 0.01;
  const PointResult r = Eval(Duffing(0.5, 250, t_end));
  EXPECT_EQ(r.motion, Motion::kChaotic);
  EXPECT_GT(r.lle, 0.05);  // measured 0.107 per unit τ
  EXPECT_EQ(r.period, 0);
  ASSERT_GE(r.section_y.size(), 5000u);
  // A period-n orbit occupies n cells, a closed curve about n·(cells per side); this cloud occupies
  // 229 of 32 × 32 (measured), and its box count grows like ε^-1.3 between 1/16 and 1/64.
  const size_t c16 = OccupiedCells(r.section_y, r.section_v, 16), c32 = OccupiedCells(r.section_y, r.section_v, 32),
               c64 = OccupiedCells(r.section_y, r.section_v, 64);
  EXPECT_GE(c32, 150u) << c32;
  const double slope = std::log(static_cast<double>(c64) / c16) / std::log(4.0);
  EXPECT_GT(slope, 1.15) << "box-counting slope " << slope << " (" << c16 << ", " << c32 << ", " << c64 << " cells)";
  // Both wells are visited.
  EXPECT_LT(*std::min_element(r.section_y.begin(), r.section_y.end()), -1.0);
  EXPECT_GT(*std::max_element(r.section_y.begin(), r.section_y.end()), 0.9);
}

}  // namespace
}  // namespace bistable
