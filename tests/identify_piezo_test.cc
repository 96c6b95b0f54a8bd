// The piezo coupling (main.piezo: a voltage state, its back-force and circuit), a second output (the
// voltage) and the output-side terms: the sensitivity equations against finite differences of the
// simulation, the loop on a synthetic two-output record, and on the measured harvester's intrawell record.
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "identify/loop.h"
#include "tests/harvester_flags.h"
#include "tests/identify_synthetic.h"
#include "tests/process_util.h"

namespace bistable {
namespace {

using bistable_test::Bistable;
using bistable_test::HarvesterSetup;
using bistable_test::Model;
using bistable_test::SyntheticRecord;

// Linear intrawell-like beam with a piezo (values of the order the harvester's intrawell records give).
const char* kTerms = "main.linear,main.stiffness_y3,main.viscous,main.piezo";
std::vector<double> TrueTheta() { return {900.0, 1.3e8, 0.6, -130.0, 7.0, -9.0}; }

TEST(IdentifyPiezo, SensitivitiesMatchFiniteDifferences) {
  // Every column of the sensitivity pass — the model's parameters (the piezo's a, b, c among them), an
  // output term of each output, and a force candidate at value 0 — against central differences of the
  // plain simulation at the same substeps; for the whole record and with restarts (multiple shooting,
  // the voltage restarted from the measured one).
  IdentModel m = Model(std::string(kTerms) + ",out.velocity.scale,out.voltage.offset", TrueTheta());
  m.theta.push_back(0.02), m.theta.push_back(1e-3);
  const PreparedRecord r = SyntheticRecord(Model(kTerms, TrueTheta()), 1.5, 640);
  const bistable::Setup s = HarvesterSetup();
  const std::vector<const TermDef*> extra = {*FindTerm("main.damping_y2"), *FindTerm("out.velocity.offset")};
  const double hx[] = {10.0, 1e-4};  // steps of the extra terms' parameters (c2 acts on y² y' ~ 1e-6 m³/s)
  const int sub = SubstepsFor(m, m.theta, r) + 2;
  for (int restart : {0, 96}) {
    SCOPED_TRACE("restart every " + std::to_string(restart));
    SimOutputs so;
    ASSERT_TRUE(SimulateOutputs(m, m.theta, extra, r, s, sub, restart, true, &so));
    const int P = m.NumParams() + 2;
    ASSERT_EQ(so.d[0].cols(), P);
    ASSERT_EQ(so.d[2].cols(), P);
    for (int j = 0; j < P; ++j) {
      // The perturbed model: a parameter of m, or one of the extra terms at ±h.
      auto simulate = [&](double sign, SimOutputs* out) {
        if (j < m.NumParams()) {
          std::vector<double> th = m.theta;
          th[j] += sign * (1e-6 * std::abs(th[j]) + 1e-9);
          return SimulateOutputs(m, th, {}, r, s, sub, restart, false, out);
        }
        const IdentModel mc = m.With(extra[j - m.NumParams()], {sign * hx[j - m.NumParams()]});
        return SimulateOutputs(mc, mc.theta, {}, r, s, sub, restart, false, out);
      };
      const double h = j < m.NumParams() ? 1e-6 * std::abs(m.theta[j]) + 1e-9 : hx[j - m.NumParams()];
      SimOutputs plus, minus;
      ASSERT_TRUE(simulate(+1, &plus) && simulate(-1, &minus));
      for (int slot : {0, 2}) {
        double num = 0, den = 0, scale = 0;
        for (size_t i = 0; i < r.n(); ++i) {
          const double fd = (plus.out[slot][i] - minus.out[slot][i]) / (2 * h);
          num = std::max(num, std::abs(fd - so.d[slot](static_cast<long>(i), j)));
          den = std::max(den, std::abs(fd));
          scale = std::max(scale, std::abs(so.d[slot](static_cast<long>(i), j)));
        }
        SCOPED_TRACE("output " + std::to_string(slot) + " column " + std::to_string(j));
        if (den == 0 && scale == 0) continue;  // a column that does not reach this output
        EXPECT_LT(num, 2e-5 * std::max(den, scale)) << "max |fd - sens| " << num << " of " << den;
      }
    }
  }
}

TEST(IdentifyPiezo, TheLoopFindsTheCouplingOnASyntheticTwoOutputRecord) {
  // Declared without the piezo; the voltage output cannot be predicted then (the model says 0 V). The
  // trace must pick main.piezo, with a coupling that damps (a c > 0) and its values near the truth.
  const PreparedRecord r = SyntheticRecord(Model(kTerms, TrueTheta()), 4.0, 640, 2e-4, 2e-5);
  const Errors truth = Evaluate(Model(kTerms, TrueTheta()), TrueTheta(), {r}, HarvesterSetup());
  ASSERT_LT(truth.outputs[0].nrmse, 2.0) << "the true model reproduces its record (noise only)";
  IdentifyOptions o;
  o.fit.global_evals = 0;
  o.max_added = 1;
  o.candidates = *ParseTerms("main.damping_y2,main.bias,main.piezo,out.velocity.scale");
  const IdentifyResult res =
      Identify(Model("main.linear,main.stiffness_y3,main.viscous", {}), {r}, HarvesterSetup(), o);
  ASSERT_EQ(res.added.size(), 1u) << (res.steps.empty() ? "" : res.steps[0].verdict);
  EXPECT_EQ(res.added[0].term, "main.piezo");
  const auto& p = res.added[0].params;
  EXPECT_GT(p[0] * p[2], 0) << "a coupling that damps the beam";
  EXPECT_NEAR(p[0] * p[2], 130.0 * 9.0, 0.05 * 130.0 * 9.0);
  EXPECT_NEAR(p[1], 7.0, 0.5);
  ASSERT_EQ(res.after.errors.outputs.size(), 2u);
  EXPECT_EQ(res.after.errors.outputs[1].name, "voltage");
  EXPECT_NEAR(res.before.errors.outputs[1].nrmse, 100.0, 1.0);
  EXPECT_LT(res.after.errors.outputs[1].nrmse, 5.0);
  EXPECT_LT(res.after.errors.outputs[0].nrmse, 5.0);
}

TEST(IdentifyPiezo, OutputWeightsFollowTheResidualsFlooredAtTheNoise) {
  // λ_voltage = (e_velocity / e_voltage)² from a fit's errors while they exceed the noise; the noise
  // weights (SetOutputWeights) once both are below it; "moved" only when a weight changed by over 2×.
  std::vector<PreparedRecord> recs = {SyntheticRecord(Model(kTerms, TrueTheta()), 4.0, 640, 2e-4, 2e-5)};
  SetOutputWeights(&recs);
  const double noise_weight = recs[0].weight[2];
  auto errors = [](double velocity, double voltage) {
    Errors e;
    e.outputs.resize(2);
    e.outputs[0].name = "velocity", e.outputs[0].nrmse = velocity;
    e.outputs[1].name = "voltage", e.outputs[1].nrmse = voltage;
    return e;
  };
  std::vector<PreparedRecord> w = recs;
  const bool moved = ReweightOutputs(errors(40.0, 20.0), Objective::kTime, HarvesterSetup(), &w);
  EXPECT_DOUBLE_EQ(w[0].weight[2], 4.0);
  EXPECT_EQ(w[0].weight[0], 1.0);
  EXPECT_EQ(moved, !(noise_weight / 4.0 < 2.0 && noise_weight / 4.0 > 0.5)) << "noise weight " << noise_weight;
  EXPECT_FALSE(ReweightOutputs(errors(40.0, 20.0), Objective::kTime, HarvesterSetup(), &w)) << "nothing moved";
  EXPECT_TRUE(ReweightOutputs(errors(40.0, 2.0), Objective::kTime, HarvesterSetup(), &w)) << "400 against 4";
  EXPECT_DOUBLE_EQ(w[0].weight[2], kMaxOutputWeight) << "clipped";
  ReweightOutputs(errors(1e-9, 1e-9), Objective::kTime, HarvesterSetup(), &w);
  EXPECT_EQ(w[0].weight[2], noise_weight) << "below the noise: the noise weights";
  // The objective's own error is read: shooting errors, not the NRMSE.
  Errors e = errors(NAN, NAN);
  e.outputs[0].shooting = 30.0, e.outputs[1].shooting = 60.0;
  ReweightOutputs(e, Objective::kShooting, HarvesterSetup(), &w);
  EXPECT_DOUBLE_EQ(w[0].weight[2], 0.25);
}

// The measured harvester (skipped without the data): the left intrawell record, both outputs, the
// declared Duffing model; the loop must add main.piezo with a damping coupling, fit the voltage, and
// decide the velocity frame; the JSON contract holds.
TEST(IdentifyPiezo, CliFindsThePiezoOnTheIntrawellRecord) {
  const std::string file = bistable_test::HarvesterFile("bistable_sym_intrawell_left_6p5Hz.csv");
  if (!std::filesystem::exists(file)) GTEST_SKIP() << "no measured data at " << file;
  const auto p = Bistable("identify --data " + file + bistable_test::kHarvesterFlags +
                          " --columns input=base_acc_g,output=laser_V,output2=piezo_V"
                          " --candidates main.stiffness_y2,main.stiffness_y5,main.damping_y2,main.bias,main.piezo"
                          " --max-seconds 3 --decimate 4 --global-evals 40 --max-added 2 --output-frame auto --json");
  ASSERT_EQ(p.exit_code, 0) << p.err;
  const auto j = nlohmann::json::parse(p.out);
  for (const char* key :
       {"error_before", "error_after", "effects_added", "params", "records", "errors_by_output", "velocity_frame"})
    EXPECT_TRUE(j.contains(key)) << key;
  bool piezo = false;
  for (const auto& e : j["effects_added"]) {
    if (e["term"] != "main.piezo") continue;
    piezo = true;
    EXPECT_GT(e["params"]["a"].get<double>() * e["params"]["c"].get<double>(), 0) << "a coupling that damps the beam";
    EXPECT_TRUE(e["uncertainty"].contains("b"));
  }
  EXPECT_TRUE(piezo) << j["effects_added"].dump();
  const auto& v = j["errors_by_output"]["voltage"];
  EXPECT_NEAR(v["before"].get<double>(), 100.0, 2.0);
  EXPECT_LT(v["after"].get<double>(), 60.0);
  EXPECT_TRUE(j["errors_by_output"].contains("velocity"));
  // Both outputs' residuals are tested for whiteness; the verdict names the first far from white.
  for (const char* o : {"velocity", "voltage"}) EXPECT_TRUE(j["whiteness"]["by_output"][o]["p_value"].is_number()) << o;
  if (!j["unexplained"].is_null()) {
    const std::string msg = j["unexplained"]["message"];
    EXPECT_NE(msg.find(" output is far from white"), std::string::npos) << msg;
  }
  const auto& f = j["velocity_frame"];
  EXPECT_TRUE(f["chosen"] == "absolute" || f["chosen"] == "relative");
  EXPECT_TRUE(f["error_absolute"].is_number() && f["error_relative"].is_number());
  std::printf("intrawell left: error %.2f %% -> %.2f %%, voltage %.1f %% -> %.1f %%, frame %s (%.2f / %.2f %%)\n",
              j["error_before"].get<double>(), j["error_after"].get<double>(), v["before"].get<double>(),
              v["after"].get<double>(), f["chosen"].get<std::string>().c_str(), f["error_absolute"].get<double>(),
              f["error_relative"].get<double>());
}

}  // namespace
}  // namespace bistable
