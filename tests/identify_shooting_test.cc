// The shooting objective (fit.h Objective::kShooting): segment start states as sensitivity columns
// against finite differences, the inner state fit reaching the noise on a record of the model itself,
// and a chaotic bistable record whose parameters the shooting fit recovers where a free run cannot be
// matched sample by sample.
#include <cmath>
#include <cstdio>

#include <gtest/gtest.h>

#include "identify/invariants.h"
#include "identify/loop.h"
#include "tests/identify_synthetic.h"

namespace bistable {
namespace {

using bistable_test::HarvesterSetup;
using bistable_test::Model;
using bistable_test::SyntheticRecord;

// A bistable beam with a piezo, per unit mass: wells at ±sqrt(k/k3) = ±3 mm, small-orbit frequency
// sqrt(2k)/(2π) ≈ 10 Hz, light damping; driven at 6.5 Hz hard enough to cross wells chaotically.
const char* kBistable = "main.linear,main.stiffness_y3,main.viscous,main.piezo";
std::vector<double> BistableTheta() { return {-1974.0, 2.19e8, 0.8, -130.0, 7.0, -9.0}; }
// Base acceleration [m/s²] at which its record is chaotic (output broadband share 0.63; at 3–5 m/s² it stays
// in a well, at 16 m/s² it locks onto a large periodic orbit).
constexpr double kChaoticDrive = 9.0;

// The chaotic record (seconds long, noise 2e-3 on both outputs, output weights set) and the true model
// with every parameter moved by ±off (alternately up and down): a fit's problem.
std::vector<PreparedRecord> ChaoticRecords(double seconds) {
  std::vector<PreparedRecord> recs = {
      SyntheticRecord(Model(kBistable, BistableTheta()), seconds, 640, 2e-3, 2e-3, kChaoticDrive)};
  SetOutputWeights(&recs);
  return recs;
}
IdentModel MovedStart(double off) {
  IdentModel m = Model(kBistable, BistableTheta());
  for (size_t i = 0; i < m.theta.size(); ++i) m.theta[i] *= i % 2 ? 1.0 - off : 1.0 + off;
  return m;
}
// Shooting over three forcing periods, local stage only.
FitOptions ShootingOptions(int threads = 0) {
  FitOptions o;
  o.objective = Objective::kShooting;
  o.shooting_horizon_s = 0.46;
  o.global_evals = 0;
  o.threads = threads;
  return o;
}

TEST(IdentifyShooting, SegmentStateSensitivitiesMatchFiniteDifferences) {
  // ds: the derivative of each output by its own segment's start state, against central differences of
  // simulations from perturbed given states (the parameters' columns are checked in identify_piezo_test).
  const IdentModel m = Model(kBistable, BistableTheta());
  const PreparedRecord r = SyntheticRecord(m, 2.0, 640, 0, 0, 4.0);
  const bistable::Setup s = HarvesterSetup();
  const int every = 60, sub = SubstepsFor(m, m.theta, r) + 2;
  const size_t nseg = NumSegments(r.n(), every);
  std::vector<double> states(nseg * kStateDim);
  for (size_t k = 0; k < nseg; ++k) {
    const auto x = MeasuredState(m, m.theta, r, s, k * every);
    for (int c = 0; c < kStateDim; ++c) states[k * kStateDim + c] = x[c] * (1.0 + 0.01 * c);  // off the measurement
  }
  SegmentStates seg{&states, true, false};
  SimOutputs so;
  ASSERT_TRUE(SimulateOutputs(m, m.theta, {}, r, s, sub, every, false, &so, nullptr, &seg));
  ASSERT_EQ(so.ds[0].cols(), kStateDim);
  ASSERT_EQ(so.d[0].size(), 0) << "no parameter columns asked for";
  const double h[kStateDim] = {1e-7, 1e-5, 1e-7, 1e-5, 1e-6};
  for (int c : {0, 1, 4}) {  // p, p', w (no resonator)
    for (size_t k : {size_t{0}, size_t{3}, nseg - 1}) {
      std::vector<double> plus = states, minus = states;
      plus[k * kStateDim + c] += h[c], minus[k * kStateDim + c] -= h[c];
      SimOutputs sp, sm;
      SegmentStates gp{&plus, false, true}, gm{&minus, false, true};
      ASSERT_TRUE(SimulateOutputs(m, m.theta, {}, r, s, sub, every, false, &sp, nullptr, &gp));
      ASSERT_TRUE(SimulateOutputs(m, m.theta, {}, r, s, sub, every, false, &sm, nullptr, &gm));
      for (int slot : {0, 2}) {
        double err = 0, scale = 0, outside = 0;
        for (size_t i = 0; i < r.n(); ++i) {
          const double fd = (sp.out[slot][i] - sm.out[slot][i]) / (2 * h[c]);
          if (SegmentOf(i, every) != k) {
            outside = std::max(outside, std::abs(fd));  // another segment's samples do not move
            continue;
          }
          err = std::max(err, std::abs(fd - so.ds[slot](static_cast<long>(i), c)));
          scale = std::max(scale, std::abs(fd));
        }
        SCOPED_TRACE("state " + std::to_string(c) + " segment " + std::to_string(k) + " output " +
                     std::to_string(slot));
        EXPECT_EQ(outside, 0.0);
        ASSERT_GT(scale, 0.0);
        EXPECT_LT(err, 1e-5 * scale) << "max |fd - ds| " << err << " of " << scale;
      }
    }
  }
}

TEST(IdentifyShooting, ReestimatedStatesReachTheNoiseOnTheModelsOwnChaoticRecord) {
  // At the true parameters the segment predictions from re-estimated states match the record to its
  // noise (the states measured from a noisy velocity are not good enough: restarts from them are worse).
  const IdentModel m = Model(kBistable, BistableTheta());
  const PreparedRecord r = SyntheticRecord(m, 8.0, 640, 2e-3, 2e-3, kChaoticDrive);
  const bistable::Setup s = HarvesterSetup();
  std::vector<PreparedRecord> recs = {r};
  SetOutputWeights(&recs);
  const ChaosCheck chaos = CheckChaos(recs, s, Objective::kTime);
  ASSERT_TRUE(chaos.record_chaotic[0]) << "the synthetic record must be chaotic: output broadband share "
                                       << chaos.output_broadband[0];
  const Errors e = Evaluate(m, m.theta, recs, s, 0.46);
  double rms = 0, mean = 0;
  for (double v : r.meas) mean += v;
  mean /= static_cast<double>(r.n());
  for (double v : r.meas) rms += (v - mean) * (v - mean);
  rms = std::sqrt(rms / static_cast<double>(r.n()));
  const double noise_pct = 100.0 * 2e-3 / rms;
  EXPECT_LT(e.outputs[0].shooting, 1.1 * noise_pct) << "velocity: noise alone is " << noise_pct << " %";
  SimOutputs restart;
  ASSERT_TRUE(SimulateOutputs(m, m.theta, {}, r, s, 0, ShootingSegment(0.46, r.dt), false, &restart));
  double e2 = 0;
  for (size_t i = 0; i < r.n(); ++i) e2 += (restart.out[0][i] - r.meas[i]) * (restart.out[0][i] - r.meas[i]);
  EXPECT_GT(100.0 * std::sqrt(e2 / static_cast<double>(r.n())) / rms, e.outputs[0].shooting);
}

TEST(IdentifyShooting, RecoversTheParametersOfAChaoticRecord) {
  // Started 25 % off, the shooting fit returns the true parameters within a few σ and a few per cent;
  // the same start's free run is no sample-by-sample match of a chaotic record (its NRMSE stays large).
  const std::vector<PreparedRecord> recs = ChaoticRecords(8.0);
  const IdentModel m = MovedStart(0.25);
  const FitResult f = Fit(m, m.theta, recs, HarvesterSetup(), ShootingOptions());
  const auto names = m.ParamNames();
  for (size_t i = 0; i < f.theta.size(); ++i) {
    SCOPED_TRACE(names[i]);
    const double t = BistableTheta()[i];
    EXPECT_NEAR(f.theta[i], t, std::max(0.03 * std::abs(t), 4 * f.sigma[i])) << "σ " << f.sigma[i];
    EXPECT_TRUE(std::isfinite(f.sigma[i]) && f.sigma[i] > 0);
  }
  EXPECT_LT(f.errors.shooting, 10.0);
  EXPECT_GT(f.errors.nrmse, 30.0) << "a free run of a chaotic record drifts off it";
}

TEST(IdentifyShooting, InvariantsCoverEveryOutput) {
  // A chaotic record with two outputs: the invariants hold a histogram distance and a spectral error for
  // each. The true model's free run reproduces both outputs' statistics roughly (8 s of chaos: Hellinger
  // 0.21 velocity, 0.17 voltage; voltage spectrum 47 % — not the samples); a model whose circuit gain θ/C_p
  // is doubled is told apart on the voltage (0.46, 114 %).
  const std::vector<PreparedRecord> recs = ChaoticRecords(8.0);
  const bistable::Setup s = HarvesterSetup();
  const ChaosCheck chaos = CheckChaos(recs, s, Objective::kShooting);
  const IdentModel m = Model(kBistable, BistableTheta());
  std::vector<double> wrong = BistableTheta();
  wrong[5] *= 2.0;
  const Invariants good = ComputeInvariants(m, m.theta, recs, s, chaos, Evaluate(m, m.theta, recs, s));
  const Invariants bad = ComputeInvariants(m, wrong, recs, s, chaos, Evaluate(m, wrong, recs, s));
  ASSERT_EQ(good.by_output.size(), 2u);
  ASSERT_EQ(bad.by_output.size(), 2u);
  EXPECT_EQ(good.by_output[0].name, "velocity");
  EXPECT_EQ(good.by_output[1].name, "voltage");
  std::printf(
      "  Hellinger velocity %.3f / %.3f, voltage %.3f / %.3f; spectral voltage %.1f / %.1f %% (true / doubled gain)\n",
      good.by_output[0].hellinger, bad.by_output[0].hellinger, good.by_output[1].hellinger, bad.by_output[1].hellinger,
      good.by_output[1].spectral_error, bad.by_output[1].spectral_error);
  EXPECT_TRUE(good.by_output[0].hellinger > 0 && good.by_output[0].hellinger < 1);
  EXPECT_LT(good.by_output[1].hellinger, 0.25);
  EXPECT_GT(bad.by_output[1].hellinger, 2 * good.by_output[1].hellinger);
  EXPECT_GT(bad.by_output[1].spectral_error, 2 * good.by_output[1].spectral_error);
}

TEST(IdentifyShooting, SegmentsSplitOverTwoThreadsGiveTheSameFit) {
  // One record: the second CPU simulates half of the segments; segments are independent, so the fit is
  // the one-thread fit to the bit.
  const std::vector<PreparedRecord> recs = ChaoticRecords(4.0);
  const IdentModel m = MovedStart(0.1);
  const FitResult one = Fit(m, m.theta, recs, HarvesterSetup(), ShootingOptions(1));
  const FitResult two = Fit(m, m.theta, recs, HarvesterSetup(), ShootingOptions(2));
  EXPECT_EQ(one.theta, two.theta);
  EXPECT_EQ(one.errors.shooting, two.errors.shooting);
  EXPECT_EQ(one.simulations, two.simulations);
}

}  // namespace
}  // namespace bistable
