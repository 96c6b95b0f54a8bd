// The loop's diagnostics (identify/invariants.h, identify/diagnostics.h): the invariants of chaotic
// records on point clouds and signals with known answers, the residual whiteness test, correlations
// and drift, a loop whose structured residual no candidate explains, and the JSON contract through
// the CLI (the harvester's chaotic record when the measured data are present).
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <random>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "dynamics/spectrum.h"
#include "identify/diagnostics.h"
#include "identify/loop.h"
#include "identify/synthetic.h"
#include "tests/harvester_flags.h"
#include "tests/process_util.h"

namespace bistable {
namespace {

using bistable_test::Bistable;
using bistable_test::FreshDir;

Eigen::MatrixXd Gaussian(long n, long dims, double mean, unsigned seed) {
  std::mt19937 g(seed);
  std::normal_distribution<double> d(mean, 1.0);
  Eigen::MatrixXd x(n, dims);
  for (long i = 0; i < n; ++i)
    for (long j = 0; j < dims; ++j) x(i, j) = d(g);
  return x;
}

// D² of N(0, 1) against N(μ, 1): 2 E|X − Y| − E|X − X'| − E|Y − Y'| with X − Y ~ N(μ, 2).
double GaussianEnergy(double mu) {
  return 4.0 / std::sqrt(M_PI) * (std::exp(-mu * mu / 4) - 1) + 2 * mu * std::erf(mu / 2);
}

TEST(IdentifyInvariants, EnergyDistanceOfGaussiansMatchesTheClosedForm) {
  const Eigen::MatrixXd a = Gaussian(2000, 1, 0.0, 1);
  for (double mu : {0.5, 1.0, 2.0}) {
    const Eigen::MatrixXd b = Gaussian(2000, 1, mu, 2);
    EXPECT_NEAR(EnergyDistanceSquared(a, b), GaussianEnergy(mu), 0.06 * GaussianEnergy(mu) + 0.004) << "mu " << mu;
  }
  // The same sample shifted: D² = 2 ∫ (F_n(x) − F_n(x − δ))² dx, → δ²/√π for a small shift.
  Eigen::MatrixXd s = a;
  s.array() += 0.05;
  EXPECT_NEAR(EnergyDistanceSquared(a, s), 0.05 * 0.05 / std::sqrt(M_PI), 0.1 * 0.05 * 0.05 / std::sqrt(M_PI));
}

TEST(IdentifyInvariants, EnergyCoefficientIsZeroForIdenticalCloudsAndGrowsWithTheShift) {
  const Eigen::MatrixXd a = Gaussian(500, 2, 0.0, 3);
  EXPECT_EQ(EnergyCoefficient(a, a), 0.0);
  double last = 0;
  for (double shift : {0.1, 0.3, 1.0, 3.0, 10.0}) {
    Eigen::MatrixXd b = a;
    b.col(0).array() += shift;
    const double h = EnergyCoefficient(a, b);
    EXPECT_GT(h, last) << "shift " << shift;
    EXPECT_LE(h, 1.0);
    last = h;
  }
  EXPECT_GT(last, 0.8) << "clouds ten standard deviations apart";
  // Two samples of one distribution: small; scale-free (each axis divided by its pooled spread).
  const Eigen::MatrixXd b = Gaussian(500, 2, 0.0, 4);
  EXPECT_LT(EnergyCoefficient(a, b), 0.01);
  Eigen::MatrixXd as = a, bs = b;
  as.col(1) *= 1e-3, bs.col(1) *= 1e-3;
  EXPECT_NEAR(EnergyCoefficient(as, bs), EnergyCoefficient(a, b), 1e-9);
  // 1-D, analytic: H = D² / (2 E|X − Y|) for N(0, 1) against N(1, 1).
  const double d2 = GaussianEnergy(1.0), cross = 2 / std::sqrt(M_PI) * std::exp(-0.25) + std::erf(0.5);
  EXPECT_NEAR(EnergyCoefficient(Gaussian(2000, 1, 0.0, 5), Gaussian(2000, 1, 1.0, 6)), d2 / (2 * cross), 0.02);
  EXPECT_TRUE(std::isnan(EnergyCoefficient(Eigen::MatrixXd(0, 2), a)));
}

TEST(IdentifyInvariants, ForcingFrequencyAndTheStroboscopicSection) {
  const double dt = 1.0 / 512, f = 6.5, w = 2 * M_PI * f, phi = 0.7;
  std::vector<double> in, y, yd;
  for (int i = 0; i < 4096; ++i) {  // 8 s, 52 periods, with a harmonic
    const double t = i * dt;
    in.push_back(3 * std::cos(w * t + phi) + 0.4 * std::cos(2 * w * t));
    y.push_back(0.01 * std::sin(w * t + phi));
    yd.push_back(0.01 * w * std::cos(w * t + phi));
  }
  EXPECT_NEAR(ForcingFrequency(in, dt), f, 1e-4);
  // Sampled where the input's fundamental peaks (ωt + φ = 2πk): y = 0, y' = 0.01 ω, every period.
  const Eigen::MatrixXd s = StroboscopicSection(y, yd, in, dt, ForcingFrequency(in, dt));
  EXPECT_EQ(s.rows(), 52);
  for (long i = 0; i < s.rows(); ++i) {
    EXPECT_NEAR(s(i, 0), 0.0, 1e-4);
    EXPECT_NEAR(s(i, 1), 0.01 * w, 1e-3);
  }
}

TEST(IdentifyInvariants, SwitchesAndVelocityHistograms) {
  // Two wells at ±1 with small oscillations inside: 7 switches; oscillations of ±0.3 about 0 cross
  // nothing with hysteresis 0.5.
  std::vector<double> y, wiggle;
  for (int i = 0; i < 8000; ++i) {
    const double well = (i / 1000) % 2 ? 1.0 : -1.0;
    y.push_back(well + 0.2 * std::sin(0.3 * i));
    wiggle.push_back(0.3 * std::sin(0.3 * i));
  }
  EXPECT_EQ(CountSwitches(y, 0.0, 0.5), 7);
  EXPECT_EQ(CountSwitches(wiggle, 0.0, 0.5), 0);
  const Eigen::MatrixXd a = Gaussian(20000, 1, 0.0, 7), b = Gaussian(20000, 1, 0.0, 8), c = Gaussian(20000, 1, 1.0, 9);
  auto vec = [](const Eigen::MatrixXd& m) { return std::vector<double>(m.data(), m.data() + m.size()); };
  EXPECT_EQ(HistogramHellinger(vec(a), vec(a)), 0.0);
  EXPECT_LT(HistogramHellinger(vec(a), vec(b)), 0.03);
  // N(0, 1) against N(1, 1): H² = 1 − exp(−μ²/8).
  EXPECT_NEAR(HistogramHellinger(vec(a), vec(c)), std::sqrt(1 - std::exp(-1.0 / 8)), 0.03);
  std::vector<double> far = vec(a);
  for (double& v : far) v += 100;
  EXPECT_NEAR(HistogramHellinger(vec(a), far), 1.0, 1e-12);
}

// A step whose free run stops changing well, or leaves the measured section, is said to lose the
// attractor the model before it had; one that keeps both (or never had them) is not.
TEST(IdentifyInvariants, AttractorLossNamesWhatTheFreeRunLost) {
  Invariants before;
  before.switching_rate = 2.23, before.switching_rate_measured = 0.50;
  before.poincare = 0.031, before.poincare_floor = 0.156;
  before.right_well_fraction = 0.42;
  Invariants after = before;
  EXPECT_EQ(AttractorLoss(before, after), "");
  after.switching_rate = 0.0;
  after.right_well_fraction = NAN;  // one well
  EXPECT_EQ(AttractorLoss(before, after),
            "no change of well over the record (2.23/s before, measured 0.5/s, one well)");
  after.poincare = 0.398;
  EXPECT_EQ(AttractorLoss(before, after),
            "no change of well over the record (2.23/s before, measured 0.5/s, one well); the Poincaré section beyond "
            "the measured floor "
            "(H 0.031 -> 0.398, floor 0.156)");
  after = Invariants{};  // the free run diverged: ComputeInvariants gives no field, the measured ones neither
  EXPECT_EQ(AttractorLoss(before, after),
            "no change of well over the record (2.23/s before, measured 0.5/s, the free run diverged); the Poincaré "
            "section beyond the "
            "measured floor (H 0.031 -> nan, floor 0.156)");
  after = before;
  after.switching_rate = 0.0;  // two wells, but no change between them
  EXPECT_EQ(AttractorLoss(before, after), "no change of well over the record (2.23/s before, measured 0.5/s)");
  Invariants never = before;  // a model that never switched, or a record that never does: nothing to lose
  never.switching_rate = 0.0;
  after = never;
  EXPECT_EQ(AttractorLoss(never, after), "");
  Invariants still = before;
  still.switching_rate_measured = 0.0;
  after = still;
  after.switching_rate = 0.0;
  EXPECT_EQ(AttractorLoss(still, after), "");
  Invariants outside = before;  // already beyond the floor: getting worse there is not a loss of it
  outside.poincare = 0.3;
  after = outside;
  after.poincare = 0.5;
  EXPECT_EQ(AttractorLoss(outside, after), "");
}

// Wells by forcing period: an orbit wider than the wells' distance switches at every half period by the
// barrier rule but never changes well; the period rule counts the changes of well only, whatever the
// displacement's mean (a velocity sensor loses it), each series by its own split.
TEST(IdentifyInvariants, WellsByForcingPeriodIgnoreWideOrbitsAndTheMean) {
  const double dt = 1e-3, f = 5.0;                                             // 200 samples per period
  const std::vector<int> wells = {-1, -1, 1, 1, 1, -1, 1, 1, -1, -1, -1, -1};  // 4 changes, 5 of 12 periods right
  auto record = [&](double offset, double orbit, const std::vector<int>& pattern) {
    std::vector<double> y;
    for (size_t k = 0; k < pattern.size(); ++k)
      for (int i = 0; i < 200; ++i)
        y.push_back(offset + 0.02 * pattern[k] + orbit * std::sin(2 * M_PI * f * (200 * k + i) * dt));
    return y;
  };
  const std::vector<double> y = record(0.0, 0.05, wells);  // orbit ±50 mm about wells at ±20 mm
  EXPECT_GE(CountSwitches(y, 0.0, 0.01), 23) << "the barrier rule counts the orbit";
  const PeriodMotion p = PeriodsOf(y, dt, f);
  ASSERT_EQ(p.mean.size(), wells.size());
  EXPECT_NEAR(p.spread[0], 0.05 / std::sqrt(2.0), 1e-9);
  const WellSplit s = SplitWells(p);
  ASSERT_TRUE(s.two_wells);
  EXPECT_NEAR(s.centre_left, -0.02, 1e-9);
  EXPECT_NEAR(s.centre_right, 0.02, 1e-9);
  const WellCount c = CountWells(p.mean, s);
  EXPECT_EQ(c.switches, 4);
  EXPECT_EQ(c.right, 5);
  EXPECT_EQ(c.left, 7);
  // A mean of 7 mm (a zero-mean integral of an unequal occupancy) changes nothing.
  const WellSwitching shifted =
      WellsOf(record(0.007, 0.05, wells), record(0.007, 0.05, std::vector<int>(12, 1)), dt, f);
  EXPECT_EQ(shifted.measured.switches, 4);
  EXPECT_EQ(shifted.simulated.switches, 0) << "a model staying in one well";
  EXPECT_FALSE(shifted.simulated_split.two_wells);
  // A model mostly in one well with a visit to the other: its zero-mean periods sit near 0 and far
  // below; its own split sees the two wells where the measured split would not.
  std::vector<int> mostly_right(12, 1);
  mostly_right[5] = mostly_right[6] = -1;
  const WellSwitching visit = WellsOf(y, record(-0.0133, 0.003, mostly_right), dt, f);
  EXPECT_EQ(visit.simulated.switches, 2);
  EXPECT_EQ(visit.simulated.right, 10);
  EXPECT_NEAR(shifted.seconds, 12 / f, 1e-12);
  // One well with a noisy orbit: the period means cluster by their scatter only; no wells, no switches.
  std::vector<double> one = record(0.0, 0.003, std::vector<int>(12, 1));
  for (size_t i = 0; i < one.size(); ++i) one[i] += 1e-4 * std::sin(0.37 * i * i);
  const WellSplit s1 = SplitWells(PeriodsOf(one, dt, f));
  EXPECT_FALSE(s1.two_wells);
  EXPECT_EQ(CountWells(PeriodsOf(one, dt, f).mean, s1).switches, 0);
  // ...and a model that switches where the measurement stays in one well counts its own switches.
  const WellSwitching w = WellsOf(one, y, dt, f);
  EXPECT_EQ(w.simulated.switches, 4);
  std::vector<double> broken = y;
  broken[1000] = NAN;  // a simulation that went non-finite: no count, rather than "no switches"
  EXPECT_FALSE(WellsOf(y, broken, dt, f).finite);
  EXPECT_TRUE(WellsOf(y, y, dt, f).finite);
  EXPECT_TRUE(PeriodsOf(y, dt, 0.0).mean.empty());
  EXPECT_TRUE(PeriodsOf(y, dt, NAN).mean.empty());
}

// A record under a force input with a displacement output: periodic forcing, the output given.
PreparedRecord ForcedRecord(const std::vector<double>& out, double dt) {
  Record r;
  r.dt = dt;
  for (size_t i = 0; i < out.size(); ++i)
    r.t.push_back(i * dt), r.input.push_back(std::cos(2 * M_PI * 6.5 * i * dt)), r.output.push_back(out[i]);
  bistable::Setup s;
  s.input = InputKind::kForce;
  s.output = OutputKind::kDisplacement;
  return *PrepareRecord(r, s, 0, r.t.size(), 0.0, "forced");
}

TEST(IdentifyInvariants, BroadbandResponsesToPeriodicForcingAreMarkedChaotic) {
  const double dt = 1.0 / 512;
  std::mt19937 g(10);
  std::normal_distribution<double> n(0, 1);
  std::vector<double> locked, broad;
  double lp = 0;
  for (int i = 0; i < 4096; ++i) {
    const double t = i * dt;
    locked.push_back(0.01 * std::sin(2 * M_PI * 6.5 * t) + 0.002 * std::sin(2 * M_PI * 19.5 * t));
    lp += 0.05 * (n(g) - lp);  // low-passed noise: a broadband response
    broad.push_back(0.01 * lp + 0.002 * std::sin(2 * M_PI * 6.5 * t));
  }
  bistable::Setup s;
  s.input = InputKind::kForce;
  s.output = OutputKind::kDisplacement;
  const ChaosCheck c = CheckChaos({ForcedRecord(locked, dt), ForcedRecord(broad, dt)}, s, Objective::kTime);
  EXPECT_NEAR(c.forcing_hz[0], 6.5, 1e-3);
  EXPECT_LT(c.input_broadband[0], kPeriodicInput);
  EXPECT_LT(c.output_broadband[0], 0.01);
  EXPECT_GT(c.output_broadband[1], kBroadbandChaotic);
  EXPECT_FALSE(c.record_chaotic[0]);
  EXPECT_TRUE(c.record_chaotic[1]);
  EXPECT_TRUE(c.chaotic);
  EXPECT_TRUE(CheckChaos({ForcedRecord(locked, dt)}, s, Objective::kFft).chaotic)
      << "the spectral objective marks every record";
}

std::vector<double> WhiteNoise(size_t n, unsigned seed) {
  std::mt19937 g(seed);
  std::normal_distribution<double> d(0, 1);
  std::vector<double> x(n);
  for (double& v : x) v = d(g);
  return x;
}

TEST(IdentifyWhiteness, WhiteNoisePassesAndASinusoidInNoiseFailsWithItsFrequency) {
  const double dt = 1.0 / 120;
  int passed = 0;
  for (unsigned seed = 1; seed <= 10; ++seed) {
    const Whiteness w = WhitenessTest({WhiteNoise(2400, seed), WhiteNoise(2400, seed + 100)}, {dt, dt}, {0.0, 0.0});
    EXPECT_EQ(w.dof, 40);
    EXPECT_GT(w.flatness, 0.9);
    passed += w.white;
  }
  EXPECT_GE(passed, 9) << "white noise passes (α = 1e-3)";
  std::vector<double> e = WhiteNoise(2400, 3);
  for (size_t i = 0; i < e.size(); ++i) e[i] += 1.5 * std::sin(2 * M_PI * 17.3 * i * dt);
  const Whiteness w = WhitenessTest({e}, {dt}, {0.0});
  EXPECT_FALSE(w.white);
  EXPECT_LT(w.p_value, 1e-10);
  ASSERT_FALSE(w.dominant_hz.empty());
  EXPECT_NEAR(w.dominant_hz[0], 17.3, 0.05);
}

// What `bistable identify` prints of a white residual says what was tested and what p means, in each case the
// verdict can take: p above alpha, p below alpha with too small a predictable share, and nothing tested.
TEST(IdentifyWhiteness, VerdictSaysWhatIsTestedAndWhatPMeans) {
  const double dt = 1.0 / 120;
  const Whiteness w = WhitenessTest({WhiteNoise(2400, 1)}, {dt}, {0.0});
  ASSERT_TRUE(w.white);
  ASSERT_GE(w.p_value, w.alpha);
  EXPECT_EQ(WhitenessVerdict(w),
            "residual indistinguishable from white noise: Ljung\u2013Box test of its "
            "autocorrelation on 20 lags, p = " +
                FormatSignificant(w.p_value, 2) +
                " (p: the chance that white noise correlates this much; p < 0.001 would say it "
                "is not white)");
  Whiteness small = w;  // the synthetic null case: p = 5.7e-4 on 60 lags, 3.3 % predictable
  small.dof = 60, small.p_value = 5.7e-4, small.flatness = 0.967;
  EXPECT_EQ(WhitenessVerdict(small),
            "residual counted as white: Ljung\u2013Box test of its autocorrelation on 60 lags, p = 0.00057 < 0.001 "
            "finds structure white noise would rarely show, but only 3.3 % of it is predictable from its past (not "
            "white needs p < 0.001 and a predictable share >= 10 %)");
  Whiteness none;
  EXPECT_NE(WhitenessVerdict(none).find("not tested"), std::string::npos) << WhitenessVerdict(none);
}

TEST(IdentifyWhiteness, OversampledNoiseIsWhiteInItsBand) {
  // White noise low-passed to 10 Hz and sampled at 120 Hz: correlated sample to sample, white at the
  // band's Nyquist rate — tested in its band [0, 10 Hz] it passes, over the whole band it does not.
  const double dt = 1.0 / 120;
  std::vector<std::complex<double>> X;
  RealFftFull(WhiteNoise(7200, 5), &X);
  for (size_t k = 0; k < X.size(); ++k) {
    const double f = std::min(k, X.size() - k) / (X.size() * dt);
    if (f > 10.0) X[k] = 0;
  }
  std::vector<double> x;
  InverseFftReal(X, &x);
  EXPECT_TRUE(WhitenessTest({x}, {dt}, {10.0}).white);
  const Whiteness all = WhitenessTest({x}, {dt}, {0.0});
  EXPECT_FALSE(all.white);
  EXPECT_NEAR(WhitenessTest({x}, {dt}, {10.0}).n_eff, 7200.0 / 6, 1.0);
}

TEST(IdentifyDiagnostics, CorrelationsAndDrift) {
  Eigen::MatrixXd cov(3, 3);
  cov << 4, 1.9, 0.1, 1.9, 1, 0, 0.1, 0, 9;
  const auto c = StrongCorrelations({"a", "b", "c"}, cov);
  ASSERT_EQ(c.size(), 1u);
  EXPECT_EQ(c[0].a, "a");
  EXPECT_EQ(c[0].b, "b");
  EXPECT_NEAR(c[0].rho, 0.95, 1e-12);
  IdentModel m;
  m.terms = *ParseTerms("main.linear,main.viscous");
  m.m_main = 1;
  m.theta = {100, 2};
  FitResult before, after;
  before.theta = {100, 2}, before.sigma = {1, 0.1};
  after.theta = {101, 3, 5};
  const IdentModel m2 = m.With(*FindTerm("main.drag"), {5});
  const auto d = DriftOf(m, before, m2, after);
  ASSERT_EQ(d.size(), 2u);
  EXPECT_EQ(d[1].name, "main.viscous.c0");
  EXPECT_NEAR(d[1].relative, 0.5, 1e-12);
  EXPECT_NEAR(d[1].in_sigma, 10.0, 1e-12);
  EXPECT_NEAR(d[0].relative, 0.01, 1e-12);
}

// A structured residual no candidate can explain: a 17 Hz hum on the position sensor of a synthetic
// chirp record (the declared model is complete): nothing is added, and the residual is reported as
// unexplained with the hum's frequency.
TEST(IdentifyDiagnostics, AStructuredResidualNoCandidateExplainsIsUnexplained) {
  DimensionalParams p = DimensionalParams::LinearTable2();
  p.has_resonator = false;
  SyntheticOptions o;
  o.a0_m = 0.014;
  o.seed = 21;
  Record r = *MakeSyntheticRecord(p, o, "chirp with hum");
  for (size_t i = 0; i < r.t.size(); ++i) r.output[i] += 0.3e-3 * std::sin(2 * M_PI * 17.0 * r.t[i]);
  const auto rec = PrepareRecord(r, bistable::Setup{}, 0, r.t.size(), 0.0, r.name);
  ASSERT_TRUE(rec.ok()) << rec.status().ToString();
  IdentModel m;
  m.terms = *ParseTerms("main.linear,main.viscous,main.damping_y2,main.friction");
  m.m_main = 0.282;
  IdentifyOptions opt;
  opt.fit.global_evals = 0;
  opt.candidates = *ParseTerms("main.stiffness_y2,main.stiffness_y3,main.damping_v3,main.drag,main.bias");
  const IdentifyResult res = Identify(m, {*rec}, bistable::Setup{}, opt);
  EXPECT_TRUE(res.added.empty()) << res.added[0].term;
  const LoopDiagnostics& d = res.diagnostics;
  EXPECT_FALSE(d.whiteness.white);
  EXPECT_FALSE(d.unexplained.empty());
  ASSERT_FALSE(d.whiteness.dominant_hz.empty());
  EXPECT_NEAR(d.whiteness.dominant_hz[0], 17.0, 0.1);
  EXPECT_FALSE(d.chaos.chaotic) << "a chirp is not a periodic forcing";
  std::printf("hum: %s\n%.1f s\n", d.unexplained.c_str(), res.seconds);
}

// The JSON contract on the harvester's chaotic record: invariants before/after every step, the
// whiteness test, unexplained, correlations and drift — and the existing keys.
TEST(IdentifyDiagnostics, CliReportsInvariantsOfTheChaoticHarvesterRecord) {
  const std::string data = bistable_test::HarvesterFile("bistable_sym_interwell_6p5Hz.csv");
  if (!std::filesystem::exists(data)) GTEST_SKIP() << data << " absent";
  const auto p =
      Bistable("identify --data " + data + bistable_test::kHarvesterFlags +
               " --columns input=base_acc_g,output=laser_V"
               " --candidates main.stiffness_y2,main.stiffness_y5,main.damping_y2,main.damping_v3,main.drag,main.bias"
               " --objective fft --max-seconds 8 --decimate 4 --json");
  ASSERT_EQ(p.exit_code, 0) << p.err;
  const auto j = nlohmann::json::parse(p.out);
  for (const char* key : {"error_before", "error_after", "effects_added", "params", "records", "seconds", "invariants",
                          "unexplained", "correlations", "whiteness", "chaos_check", "refits", "separability"})
    EXPECT_TRUE(j.contains(key)) << key;
  EXPECT_TRUE(j["chaos_check"]["chaotic"].get<bool>());
  EXPECT_NEAR(j["chaos_check"]["records"][0]["forcing_hz"].get<double>(), 6.5, 1e-3);
  const auto& inv = j["invariants"];
  ASSERT_TRUE(inv.is_object());
  for (const char* when : {"before", "after"})
    for (const char* key : {"poincare_energy", "poincare_floor", "switching_rate_hz", "switching_rate_measured_hz",
                            "velocity_hellinger", "spectral_error_percent"})
      EXPECT_TRUE(inv[when][key].is_number()) << when << "." << key;
  EXPECT_EQ(inv["steps"].size(), j["refits"].size());
  EXPECT_TRUE(inv["attractor_lost"].is_null() || inv["attractor_lost"].is_string());
  for (const auto& s : inv["steps"]) EXPECT_TRUE(s.contains("attractor_lost")) << s.dump();
  EXPECT_NEAR(inv["before"]["spectral_error_percent"].get<double>(), j["fft_error_before"].get<double>(), 1e-9);
  EXPECT_GT(inv["before"]["switching_rate_measured_hz"].get<double>(), 1.0) << "cross-well motion";
  for (const auto& e : j["effects_added"]) EXPECT_TRUE(e.contains("drift")) << e.dump();
  ASSERT_TRUE(j["unexplained"].is_object()) << "a chaotic record's residual is far from white here";
  for (const char* key : {"statistic", "p_value", "dominant_frequencies_hz", "message"})
    EXPECT_TRUE(j["unexplained"].contains(key)) << key;
}

// A record without periodic forcing: invariants null; a white residual: unexplained null.
TEST(IdentifyDiagnostics, CliGivesNullInvariantsAndUnexplainedForAWhiteNonChaoticFit) {
  const std::string dir = FreshDir("identify", "diag");
  DimensionalParams p = DimensionalParams::LinearTable2();
  p.has_resonator = false;
  SyntheticOptions o;
  o.a0_m = 0.010;
  o.seed = 5;
  ASSERT_TRUE(WriteRecordCsv(*MakeSyntheticRecord(p, o, "chirp"), dir + "/c.csv").ok());
  const auto r = Bistable(
      "identify --data " + dir +
      "/c.csv --terms main.linear,main.viscous,main.damping_y2,main.friction --known m_main=0.282 --max-added 0 "
      "--global-evals 0 --json");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const auto j = nlohmann::json::parse(r.out);
  EXPECT_TRUE(j["invariants"].is_null());
  EXPECT_TRUE(j["unexplained"].is_null()) << j["whiteness"].dump();
  EXPECT_TRUE(j["whiteness"]["white"].get<bool>());
  EXPECT_TRUE(j["correlations"].is_array());
  EXPECT_TRUE(j["seconds"].is_number());
  std::filesystem::remove_all(dir);
}

}  // namespace
}  // namespace bistable
