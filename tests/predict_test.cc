// identify/predict.h: the model's wells and small-orbit frequencies from its parameters, the amplitude
// at the drive frequency.
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "identify/predict.h"
#include "tests/harvester_flags.h"
#include "tests/process_util.h"

namespace bistable {
namespace {

IdentModel Model(const std::string& terms, double mass = 1.0) {
  IdentModel m;
  m.terms = *ParseTerms(terms);
  m.m_main = mass;
  return m;
}

TEST(IdentifyPredict, RealRootsOfAPolynomial) {
  // (y − 1)(y + 2)(y − 3) = y³ − 2y² − 5y + 6, and the same scaled by 1e12 with roots 1e-4 times as large.
  EXPECT_EQ(RealPolynomialRoots({6, -5, -2, 1}).size(), 3u);
  const auto r = RealPolynomialRoots({6, -5, -2, 1});
  EXPECT_NEAR(r[0], -2, 1e-12);
  EXPECT_NEAR(r[1], 1, 1e-12);
  EXPECT_NEAR(r[2], 3, 1e-12);
  const double s = 1e-4;
  const auto q = RealPolynomialRoots({6 * s * s * s * 1e12, -5 * s * s * 1e12, -2 * s * 1e12, 1e12});
  ASSERT_EQ(q.size(), 3u);
  EXPECT_NEAR(q[0] / s, -2, 1e-10);
  EXPECT_NEAR(q[2] / s, 3, 1e-10);
  EXPECT_EQ(RealPolynomialRoots({1, 0, 1}).size(), 0u);  // y² + 1
  EXPECT_EQ(RealPolynomialRoots({5}).size(), 0u);
  EXPECT_EQ(RealPolynomialRoots({-2, 4, 0, 0, 0, 0}).size(), 1u);  // trailing zeros: linear
}

TEST(IdentifyPredict, SymmetricDuffingWellsAndSmallOrbitFrequency) {
  // F = −k y + k3 y³ per mass m: wells at ±sqrt(k/k3), barrier 0, K = 2k in each well, f = sqrt(2k/m)/(2π),
  // depth k²/(4 k3); the viscous damping gives ζ = c0 / (2 sqrt(K m)).
  const double k = 1128, k3 = 3.57e6, c0 = 0.52, mass = 0.5;
  IdentModel m = Model("main.linear,main.stiffness_y3,main.viscous", mass);
  const auto st = AnalyseStatics(m, {-k, k3, c0});
  ASSERT_TRUE(st.ok()) << st.status().ToString();
  ASSERT_TRUE(st->bistable);
  ASSERT_EQ(st->wells.size(), 2u);
  EXPECT_EQ(st->wells[0].side, "left");
  EXPECT_NEAR(st->wells[0].at.y, -std::sqrt(k / k3), 1e-12);
  EXPECT_NEAR(st->wells[1].at.y, std::sqrt(k / k3), 1e-12);
  EXPECT_NEAR(st->barrier.y, 0.0, 1e-15);
  for (const Well& w : st->wells) {
    EXPECT_NEAR(w.at.stiffness, 2 * k, 1e-9 * k);
    EXPECT_NEAR(w.small_orbit_hz, std::sqrt(2 * k / mass) / (2 * M_PI), 1e-12);
    EXPECT_NEAR(w.depth, k * k / (4 * k3), 1e-12);
    EXPECT_NEAR(w.damping_ratio, c0 / (2 * std::sqrt(2 * k * mass)), 1e-12);
    EXPECT_FALSE(w.with_circuit);
  }
}

TEST(IdentifyPredict, ABiasShiftsTheWellsUnequally) {
  // F = f_b − k y + k3 y³: both wells move against the bias, by different amounts; the depths differ.
  const double k = 1000, k3 = 2e6, fb = 2.0;
  const auto st = AnalyseStatics(Model("main.linear,main.stiffness_y3,main.bias"), {-k, k3, fb});
  ASSERT_TRUE(st.ok() && st->bistable);
  const double l = st->wells[0].at.y, r = st->wells[1].at.y, y0 = std::sqrt(k / k3);
  for (double y : {l, r, st->barrier.y}) EXPECT_NEAR(fb - k * y + k3 * y * y * y, 0.0, 1e-9);
  EXPECT_LT(l, -y0);
  EXPECT_LT(r, y0);
  EXPECT_GT(st->barrier.y, 0.0);
  EXPECT_GT(std::abs(std::abs(l) - std::abs(r)), 1e-4);
  EXPECT_GT(st->wells[0].depth, st->wells[1].depth * 1.1) << "the bias deepens the left well";
  // y² stiffness likewise: unequal wells around a barrier at 0.
  const auto st2 = AnalyseStatics(Model("main.linear,main.stiffness_y2,main.stiffness_y3"), {-k, 3e4, k3});
  ASSERT_TRUE(st2.ok() && st2->bistable);
  EXPECT_NEAR(st2->barrier.y, 0.0, 1e-12);
  EXPECT_GT(std::abs(st2->wells[0].at.y), std::abs(st2->wells[1].at.y));
}

TEST(IdentifyPredict, AQuinticWithOuterRimsKeepsTheInnerWells) {
  // k5 < 0: the force turns back beyond the outer rims (unstable); the wells are the inner stable roots.
  const auto st = AnalyseStatics(Model("main.linear,main.stiffness_y3,main.stiffness_y5"), {-950, 1.93e6, -1e8});
  ASSERT_TRUE(st.ok()) << st.status().ToString();
  ASSERT_EQ(st->equilibria.size(), 5u);
  EXPECT_FALSE(st->equilibria[0].stable);
  EXPECT_FALSE(st->equilibria[4].stable);
  ASSERT_TRUE(st->bistable);
  EXPECT_NEAR(st->barrier.y, 0, 1e-12);
  EXPECT_NEAR(st->wells[0].at.y, -st->wells[1].at.y, 1e-12);
  // A monostable model: one well, no barrier.
  const auto mono = AnalyseStatics(Model("main.linear,main.stiffness_y3"), {1763, 1e7});
  ASSERT_TRUE(mono.ok());
  EXPECT_FALSE(mono->bistable);
  ASSERT_EQ(mono->wells.size(), 1u);
  EXPECT_EQ(mono->wells[0].side, "only");
  EXPECT_NEAR(mono->wells[0].small_orbit_hz, std::sqrt(1763.0) / (2 * M_PI), 1e-12);
  // Errors: no restoring force; not finite.
  EXPECT_FALSE(AnalyseStatics(Model("main.viscous"), {1.0}).ok());
  EXPECT_FALSE(AnalyseStatics(Model("main.linear,main.stiffness_y3"), {-1000, NAN}).ok());
  EXPECT_FALSE(AnalyseStatics(Model("main.linear"), {-1000}).ok()) << "an unstable linear spring has no well";
}

TEST(IdentifyPredict, ThePiezoCircuitInTheWell) {
  // b = 0: the circuit is a pure stiffness a c (w = −c y): the coupled pair is sqrt((K + a c)/m).
  // b ≫ ω: a pure damping a c / b. In between, the added stiffness and damping at ω as documented.
  const double k = 1000, k3 = 2e6, a = -130, c = -9;
  const double K = 2 * k;
  auto st = AnalyseStatics(Model("main.linear,main.stiffness_y3,main.piezo"), {-k, k3, a, 0.0, c});
  ASSERT_TRUE(st.ok() && st->bistable);
  const Well& w = st->wells[1];
  ASSERT_TRUE(w.with_circuit);
  EXPECT_NEAR(w.coupled.hz, std::sqrt(K + a * c) / (2 * M_PI), 1e-9);
  EXPECT_NEAR(w.coupled.damping_ratio, 0.0, 1e-9);
  EXPECT_NEAR(w.piezo_stiffness, a * c, 1e-9);
  EXPECT_NEAR(w.piezo_damping, 0.0, 1e-12);
  const double b = 1e5;
  st = AnalyseStatics(Model("main.linear,main.stiffness_y3,main.piezo"), {-k, k3, a, b, c});
  ASSERT_TRUE(st.ok());
  const Well& v = st->wells[0];
  EXPECT_NEAR(v.coupled.damping_ratio, (a * c / b) / (2 * std::sqrt(K)), 1e-3 * (a * c / b) / (2 * std::sqrt(K)));
  EXPECT_NEAR(v.coupled.hz, std::sqrt(K) / (2 * M_PI), 1e-3);
  const double om = 2 * M_PI * v.small_orbit_hz;
  EXPECT_NEAR(v.piezo_damping, a * c * b / (b * b + om * om), 1e-12);
  // The general case against the cubic's definition: s solves (s² + C s + K)(s + b) + a c s = 0.
  const LinearMode mode = CoupledMode(1.0, 0.3, K, a, 6.7, c);
  const double wn = 2 * M_PI * mode.hz, zeta = mode.damping_ratio;
  const std::complex<double> s(-zeta * wn, wn * std::sqrt(1 - zeta * zeta));
  const std::complex<double> res = (s * s + 0.3 * s + K) * (s + 6.7) + a * c * s;
  EXPECT_LT(std::abs(res), 1e-6 * std::abs(s * s * s));
  EXPECT_GT(zeta, 0) << "a c > 0 damps";
}

TEST(IdentifyPredict, AmplitudeAtTheDriveFrequency) {
  const double dt = 1.0 / 640, f = 6.5;
  std::vector<double> x;
  for (int i = 0; i < 640 * 8; ++i) {
    const double t = i * dt;
    x.push_back(0.37 * std::sin(2 * M_PI * f * t + 0.3) + 0.05 * std::sin(2 * M_PI * 2 * f * t) + 0.02 * std::cos(2 * M_PI * 0.8 * t) + 0.01);
  }
  EXPECT_NEAR(AmplitudeAt(x, dt, f), 0.37, 2e-3);
  EXPECT_NEAR(AmplitudeAt(x, dt, ForcingFrequency(x, dt)), 0.37, 2e-3);
  EXPECT_TRUE(std::isnan(AmplitudeAt({}, dt, f)));
  x[3] = NAN;
  EXPECT_TRUE(std::isnan(AmplitudeAt(x, dt, f)));
}

}  // namespace
}  // namespace bistable
