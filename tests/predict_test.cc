// identify/predict.h: the model's wells and small-orbit frequencies from its parameters, the amplitude
// at the drive frequency; and `bistable identify --predict` as a process (fit → --json → --predict).
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
    x.push_back(0.37 * std::sin(2 * M_PI * f * t + 0.3) + 0.05 * std::sin(2 * M_PI * 2 * f * t) +
                0.02 * std::cos(2 * M_PI * 0.8 * t) + 0.01);
  }
  EXPECT_NEAR(AmplitudeAt(x, dt, f), 0.37, 2e-3);
  EXPECT_NEAR(AmplitudeAt(x, dt, ForcingFrequency(x, dt)), 0.37, 2e-3);
  EXPECT_TRUE(std::isnan(AmplitudeAt({}, dt, f)));
  x[3] = NAN;
  EXPECT_TRUE(std::isnan(AmplitudeAt(x, dt, f)));
}

// --- `bistable identify --predict` as a process ---------------------------------------------------

using bistable_test::Bistable;

void WriteFile(const std::string& path, const std::string& text) {
  std::ofstream f(path);
  f << text;
}

// The harvester flags with both outputs and the piezo declared.
std::string PiezoFlags() {
  std::string f = bistable_test::kHarvesterFlags;
  const std::string v = "main.viscous";
  f.replace(f.find(v), v.size(), "main.viscous,main.piezo");
  return f + " --columns input=base_acc_g,output=laser_V,output2=piezo_V";
}

double Num(const nlohmann::json& j) { return j.is_number() ? j.get<double>() : NAN; }

TEST(IdentifyPredict, CliPredictsTheFittedRecordWithTheFitsErrors) {
  // fit → --json → --predict on the same 4 s of the symmetric interwell record: nothing refitted, so
  // every error the fit reported comes back (the JSON's parameters round-trip exactly); then the right
  // intrawell record, started in the model's right well.
  const std::string inter = bistable_test::HarvesterFile("bistable_sym_interwell_6p5Hz.csv");
  const std::string intra = bistable_test::HarvesterFile("bistable_sym_intrawell_right_6p5Hz.csv");
  if (!std::filesystem::exists(inter) || !std::filesystem::exists(intra))
    GTEST_SKIP() << "no measured data at " << inter;
  const std::string slice = " --objective fft --max-seconds 4 --decimate 4";
  const auto fit =
      Bistable("identify --data " + inter + PiezoFlags() + slice + " --global-evals 0 --max-added 0 --json");
  ASSERT_EQ(fit.exit_code, 0) << fit.err;
  const auto f = nlohmann::json::parse(fit.out);
  ASSERT_EQ(f["final_terms"].size(), 4u);
  EXPECT_EQ(f["final_terms"][3], "main.piezo");
  const std::string model = bistable_test::FreshDir("predict", "model") + "/model.json";
  WriteFile(model, fit.out);
  const auto pred =
      Bistable("identify --predict --model " + model + " --data " + inter + PiezoFlags() + slice + " --json");
  ASSERT_EQ(pred.exit_code, 0) << pred.err;
  const auto j = nlohmann::json::parse(pred.out);
  ASSERT_TRUE(j.contains("prediction"));
  const auto& p = j["prediction"];
  for (const char* key : {"model", "records", "error", "observability", "settings", "seconds"})
    EXPECT_TRUE(p.contains(key)) << key;
  for (const char* key :
       {"wells", "small_orbit_hz", "small_orbit_hz_with_circuit", "equilibria", "barrier", "piezo", "params", "terms"})
    EXPECT_TRUE(p["model"].contains(key)) << key;
  ASSERT_EQ(p["records"].size(), 1u);
  const auto& r = p["records"][0];
  for (const char* o : {"velocity", "voltage"}) {
    SCOPED_TRACE(o);
    const auto& po = r["outputs"][o];
    const auto& fo = f["errors_by_output"][o];
    EXPECT_NEAR(Num(po["nrmse"]), Num(fo["after"]), 1e-9 * Num(fo["after"]));
    EXPECT_NEAR(Num(po["spectral_error"]), Num(fo["fft_after"]), 1e-9 * Num(fo["fft_after"]));
    for (const char* k : {"amplitude_measured", "amplitude_predicted", "rms_measured", "rms_predicted"})
      EXPECT_GT(Num(po[k]), 0) << k;
  }
  EXPECT_NEAR(Num(p["error"]["nrmse"]), Num(f["error_after"]), 1e-9 * Num(f["error_after"]));
  EXPECT_NEAR(Num(r["forcing_hz"]), 6.5, 0.01);
  ASSERT_FALSE(r["invariants"].is_null()) << "a spectral-objective record is chaotic";
  EXPECT_NEAR(Num(r["invariants"]["poincare_energy"]), Num(f["invariants"]["after"]["poincare_energy"]), 1e-12);
  EXPECT_NEAR(Num(r["invariants"]["switching_rate_hz"]), Num(f["invariants"]["after"]["switching_rate_hz"]), 1e-12);
  EXPECT_TRUE(r["mean_displacement_m"]["measured"].is_null()) << "a velocity output does not give it";
  const auto& m = p["model"];
  ASSERT_TRUE(m["bistable"].get<bool>()) << m.dump();
  ASSERT_EQ(m["wells"].size(), 2u);
  const double k_lin = Num(f["params"]["main.linear.k_lin"]), k3 = Num(f["params"]["main.stiffness_y3.k3"]);
  EXPECT_NEAR(Num(m["wells"][1]["y_m"]), std::sqrt(-k_lin / k3), 1e-9);
  EXPECT_NEAR(Num(m["small_orbit_hz"][0]), std::sqrt(-2 * k_lin) / (2 * M_PI), 1e-9);
  EXPECT_GT(Num(m["small_orbit_hz_with_circuit"][0]), 0);
  // The report directory form of --model and the fit's frame: same numbers.
  const std::string dir = bistable_test::FreshDir("predict", "report");
  WriteFile(dir + "/report.json", fit.out);
  const auto again =
      Bistable("identify --predict --model " + dir + " --data " + inter + PiezoFlags() + slice + " --json");
  ASSERT_EQ(again.exit_code, 0) << again.err;
  EXPECT_EQ(nlohmann::json::parse(again.out)["prediction"]["records"], p["records"]);

  // Another record, started in the right well; the text table as well.
  const auto right = Bistable("identify --predict --model " + model + " --data " + intra + PiezoFlags() +
                              " --max-seconds 4 --decimate 4 --start-well right --json");
  ASSERT_EQ(right.exit_code, 0) << right.err;
  const auto right_json = nlohmann::json::parse(right.out);
  const auto& rr = right_json["prediction"]["records"][0];
  EXPECT_EQ(rr["start_well"], "right");
  EXPECT_GT(Num(rr["start_y_m"]), 0.5 * Num(m["wells"][1]["y_m"]));
  EXPECT_GT(Num(rr["mean_displacement_m"]["predicted"]), 0)
      << "the model stays in the right well at the intrawell drive";
  EXPECT_FALSE(rr["chaotic"].get<bool>());
  EXPECT_TRUE(rr["invariants"].is_null());
  const auto text = Bistable("identify --predict --model " + model + " --data " + intra + PiezoFlags() +
                             " --max-seconds 4 --decimate 4");
  ASSERT_EQ(text.exit_code, 0) << text.err;
  for (const char* s : {"small orbit [Hz]", "with circuit [Hz]", "velocity", "voltage", "not measured"})
    EXPECT_NE(text.out.find(s), std::string::npos) << s << "\n" << text.out;
  std::printf("%s", text.out.c_str());
}

TEST(IdentifyPredict, CliRefusesABadModelNamingTheField) {
  // A small record (base acceleration in, velocity out) and hand-written model files, each broken once.
  const std::string dir = bistable_test::FreshDir("predict", "bad");
  std::string csv = "t,a0,v\n";
  for (int i = 0; i < 800; ++i) {
    const double t = i / 200.0;
    csv += std::to_string(t) + "," + std::to_string(3 * std::sin(2 * M_PI * 6.5 * t)) + "," +
           std::to_string(0.05 * std::cos(2 * M_PI * 6.5 * t)) + "\n";
  }
  WriteFile(dir + "/d.csv", csv);
  const std::string flags = " --data " + dir + "/d.csv --input-kind base_acceleration --output-kind velocity";
  const std::string good =
      R"({"declared": "main.linear,main.stiffness_y3,main.viscous", "effects_added": [{"term": "main.bias"}],
          "params": {"main.linear.k_lin": -1000, "main.stiffness_y3.k3": 2e6, "main.viscous.c0": 1.5, "main.bias.f_b": 0.1},
          "settings": {"m_main": 1, "input_kind": "base_acceleration", "output_frame": "absolute"}})";
  WriteFile(dir + "/good.json", good);
  const auto ok = Bistable("identify --predict --model " + dir + "/good.json" + flags + " --start-well left --json");
  ASSERT_EQ(ok.exit_code, 0) << ok.err;
  const auto j = nlohmann::json::parse(ok.out)["prediction"];
  EXPECT_EQ(j["model"]["terms"].size(), 4u) << "declared + effects_added, in order";
  EXPECT_LT(Num(j["model"]["wells"][0]["y_m"]), -std::sqrt(1000 / 2e6)) << "the bias shifts the wells";
  EXPECT_TRUE(j["model"]["small_orbit_hz_with_circuit"].is_null());

  auto variant = [&](const std::string& from, const std::string& to) {
    std::string t = good;
    const size_t at = t.find(from);
    EXPECT_NE(at, std::string::npos) << from;
    if (at != std::string::npos) t.replace(at, from.size(), to);
    return t;
  };
  struct Case {
    std::string name, text, extra, expect;
  };
  const std::vector<Case> cases = {
      {"missing_model", "", "", "--predict needs --model FILE"},
      {"not_json", "{\"params\": ", "", "is not JSON"},
      {"not_object", "[1, 2]", "", "is not a JSON object"},
      {"no_params", "{\"declared\": \"main.linear\"}", "", "model.params"},
      {"missing_param", variant("\"main.stiffness_y3.k3\": 2e6, ", ""), "",
       "model.params.main.stiffness_y3.k3 is missing"},
      {"null_param", variant("\"main.viscous.c0\": 1.5", "\"main.viscous.c0\": null"), "",
       "model.params.main.viscous.c0 is not a number"},
      {"string_param", variant("\"main.viscous.c0\": 1.5", "\"main.viscous.c0\": \"1.5\""), "",
       "model.params.main.viscous.c0 is not a number"},
      {"huge_param", variant("2e6", "1e300"), "", "model.params.main.stiffness_y3.k3 = 1e+300 violates"},
      {"negative_damping", variant("1.5", "-1.5"), "", "model.params.main.viscous.c0 = -1.5 violates >= 0"},
      {"extra_param", variant("\"main.bias.f_b\": 0.1", "\"main.bias.f_b\": 0.1, \"main.drag.cq\": 1"), "",
       "'main.drag.cq', not a parameter"},
      {"unknown_term", variant("\"term\": \"main.bias\"", "\"term\": \"main.biass\""), "", "model.final_terms"},
      {"bad_final_terms", variant("\"declared\"", "\"final_terms\": [\"main.linear\", 3], \"declared\""), "",
       "model.final_terms[1] is not a string"},
      {"terms_mismatch", good, " --terms main.linear,main.viscous", "is neither the model's declared terms"},
      {"mass_mismatch", good, " --known m_main=0.3", "known.m_main"},
      {"input_mismatch", variant("\"base_acceleration\"", "\"base_displacement\""), "",
       "fitted with --input-kind base_displacement"},
      {"bad_mass", variant("\"m_main\": 1", "\"m_main\": -1"), "", "model.settings.m_main"},
      {"no_well", variant("-1000", "1000"), " --start-well right", "the model has one well"},
      {"deep", std::string(100, '[') + std::string(100, ']'), "", "nests deeper than 64"},
      {"bad_start_well", good, " --start-well middle", "start-well"},
      {"start_wells_count", good, " --start-well left,right", "one per file"},
  };
  for (const Case& c : cases) {
    SCOPED_TRACE(c.name);
    std::string model;
    if (c.name != "missing_model") {
      model = " --model " + dir + "/" + c.name + ".json";
      WriteFile(dir + "/" + c.name + ".json", c.text);
    }
    const auto r = Bistable("identify --predict" + model + flags + c.extra);
    EXPECT_EQ(r.exit_code, 2) << r.out;
    EXPECT_NE(r.err.find(c.expect), std::string::npos) << r.err;
  }
  const auto no_predict = Bistable("identify --model " + dir + "/good.json" + flags + " --terms main.linear");
  EXPECT_EQ(no_predict.exit_code, 2);
  EXPECT_NE(no_predict.err.find("--model is read by --predict"), std::string::npos) << no_predict.err;
}

}  // namespace
}  // namespace bistable
