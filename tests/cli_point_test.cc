// End-to-end: the real `bistable` executable, run as a process, for the `point` contract
// (JSON keys scripts rely on, --trace, error messages and exit codes).
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <sstream>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include <nlohmann/json.hpp>
#include "tests/process_util.h"

namespace {

using bistable_test::Bistable;
using bistable_test::ProcessResult;

// The README's `bistable point` example: the command it shows, run, prints every line the README shows (but "...",
// which stands for lines left out; trailing blanks ignored), in that order.
TEST(CliPoint, ReadmeExampleMatchesTheOutput) {
  std::ifstream in(BISTABLE_README);
  ASSERT_TRUE(in) << BISTABLE_README;
  std::string line, command;
  std::vector<std::string> shown;
  while (std::getline(in, line)) {
    if (command.empty()) {
      if (line.rfind("$ bistable point ", 0) == 0) command = line.substr(std::string("$ bistable ").size());
      continue;
    }
    if (line.rfind("```", 0) == 0) break;
    if (line != "  ...") shown.push_back(line);
  }
  ASSERT_FALSE(command.empty()) << "no '$ bistable point ...' line in the README";
  ASSERT_GE(shown.size(), 5u);
  const ProcessResult r = Bistable(command);
  ASSERT_EQ(r.exit_code, 0) << r.err;
  std::vector<std::string> printed;
  std::istringstream out(r.out);
  while (std::getline(out, line)) printed.push_back(line.substr(0, line.find_last_not_of(' ') + 1));
  size_t at = 0;
  for (const std::string& want : shown) {
    while (at < printed.size() && printed[at] != want) ++at;
    EXPECT_LT(at, printed.size()) << "README line not printed (in order): '" << want << "'\n" << r.out;
    if (at == printed.size()) break;
  }
}

TEST(CliPoint, JsonHasTheContractKeys) {
  const ProcessResult r = Bistable("point --model coupled --alpha 1 --omega 1.2 --json");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const auto j = nlohmann::json::parse(r.out);
  for (const char* key : {"frf_db", "lle", "lle_rosenstein", "motion", "period", "hd_index", "hd_peaks", "edr_b",
                          "edr_r", "edr_t", "energy_balance_residual", "settings"})
    EXPECT_TRUE(j.contains(key)) << key;
  EXPECT_EQ(j["motion"], "chaotic");
  EXPECT_TRUE(j["period"].is_number_integer());
  ASSERT_TRUE(j["hd_peaks"].is_array());
  ASSERT_FALSE(j["hd_peaks"].empty());
  EXPECT_TRUE(j["hd_peaks"][0].contains("freq"));
  EXPECT_TRUE(j["hd_peaks"][0].contains("amp"));
  // Settings reproduce the run: paper defaults and the well start.
  const auto& s = j["settings"];
  EXPECT_EQ(s["model"], "coupled");
  EXPECT_EQ(s["eta"], 0.1);
  EXPECT_EQ(s["eta_r"], 0.075);
  EXPECT_EQ(s["phi"], 2.0);
  EXPECT_EQ(s["lambda"], 0.8);
  EXPECT_EQ(s["t_end"], 500.0);
  EXPECT_EQ(s["t_keep"], 250.0);
  EXPECT_EQ(s["integrator"], "rk4");
  EXPECT_EQ(s["ic"], nlohmann::json({1.0, 0.0, 1.0, 0.0}));
  EXPECT_TRUE(s.contains("numerics_version"));
}

// The script contract of --spectrum: the state space's exponents (largest first, the first within 1e-9
// of `lle` of the same run), their sum against the exact divergence, and the Kaplan–Yorke dimension.
TEST(CliPoint, SpectrumJsonContract) {
  const ProcessResult r = Bistable("point --model coupled --alpha 1 --omega 1 --t-end 1000 --spectrum --json");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const auto j = nlohmann::json::parse(r.out);
  ASSERT_TRUE(j["lyapunov_spectrum"].is_array());
  ASSERT_EQ(j["lyapunov_spectrum"].size(), 4u);
  EXPECT_NEAR(j["lyapunov_spectrum"][0].get<double>(), j["lle"].get<double>(), 1e-9);
  EXPECT_NEAR(j["lyapunov_sum"].get<double>(), -0.325, 1e-3);
  EXPECT_DOUBLE_EQ(j["divergence"].get<double>(), -0.325);
  EXPECT_GT(j["kaplan_yorke"].get<double>(), 2.0);
  const ProcessResult text = Bistable("point --model standalone --alpha 0.3 --omega 2 --spectrum");
  ASSERT_EQ(text.exit_code, 0) << text.err;
  EXPECT_NE(text.out.find("Lyapunov spectrum"), std::string::npos);
  EXPECT_NE(text.out.find("Kaplan-Yorke"), std::string::npos);
  const ProcessResult bad = Bistable("point --alpha 1 --omega 1 --integrator adaptive --spectrum");
  EXPECT_NE(bad.exit_code, 0);
  EXPECT_NE(bad.err.find("integrator"), std::string::npos) << bad.err;
}

TEST(CliPoint, SettingsFromJsonReproduceTheResult) {
  const ProcessResult a = Bistable("point --model standalone --alpha 0.3 --omega 2 --eta 0.12 --json");
  ASSERT_EQ(a.exit_code, 0) << a.err;
  const auto ja = nlohmann::json::parse(a.out);
  const auto& s = ja["settings"];
  const auto& ic = s["ic"];
  const std::string again =
      "point --model " + s["model"].get<std::string>() + " --alpha " + std::to_string(s["alpha"].get<double>()) +
      " --omega " + std::to_string(s["omega"].get<double>()) + " --eta " + std::to_string(s["eta"].get<double>()) +
      " --ic " + std::to_string(ic[0].get<double>()) + "," + std::to_string(ic[1].get<double>()) + " --json";
  const ProcessResult b = Bistable(again);
  ASSERT_EQ(b.exit_code, 0) << b.err;
  EXPECT_EQ(nlohmann::json::parse(b.out)["lle"], ja["lle"]);
  EXPECT_EQ(nlohmann::json::parse(b.out)["frf_db"], ja["frf_db"]);
}

TEST(CliPoint, TraceWritesTheWindow) {
  const std::string dir = bistable_test::FreshDir("cli_point", "trace");
  const std::string path = dir + "/trace.csv";
  const ProcessResult r = Bistable("point --model coupled --alpha 0.3 --omega 0.8 --trace " + path);
  ASSERT_EQ(r.exit_code, 0) << r.err;
  std::ifstream in(path);
  std::string header, first, line, last;
  std::getline(in, header);
  std::getline(in, first);
  size_t rows = 1;
  while (std::getline(in, line)) last = line, ++rows;
  EXPECT_EQ(header, "tau,y_m,dy_m,y_r,dy_r");
  EXPECT_EQ(first.substr(0, 4), "250,");
  EXPECT_EQ(last.substr(0, 4), "500,");
  EXPECT_EQ(rows, 250 / 0.05 + 1);
  for (const auto& e : std::filesystem::directory_iterator(dir))  // the AtomicFile temporary is gone
    EXPECT_EQ(e.path().filename().string().find(".bistable-out-"), std::string::npos) << "left behind: " << e.path();
  // "-": the same CSV on standard output, alone.
  const ProcessResult s = Bistable("point --model coupled --alpha 0.3 --omega 0.8 --trace -");
  ASSERT_EQ(s.exit_code, 0) << s.err;
  std::ifstream again(path);
  const std::string file((std::istreambuf_iterator<char>(again)), {});
  EXPECT_EQ(s.out, file);
  std::filesystem::remove_all(dir);
}

TEST(CliPoint, BadInputNamesFieldAndExitsNonZero) {
  struct Case {
    const char* args;
    const char* expect;  // fragment of stderr
  };
  const Case cases[] = {
      {"point --alpha -1 --omega 1", "alpha = -1 violates alpha > 0"},
      {"point --alpha 0 --omega 1", "alpha"},
      {"point --alpha nan --omega 1", "alpha"},
      {"point --alpha 1 --omega 1 --eta -0.5", "eta = -0.5 violates eta >= 0"},
      {"point --alpha 1 --omega 1 --t-keep 600", "t_keep = 600 violates t_keep < t_end"},
      {"point --model duffing --alpha 1 --omega 1", "model = 'duffing' violates model in"},
      {"point --alpha 1 --omega 1 --integrator euler", "integrator"},
      {"point --alpha 1 --omega 1 --ic 1,2,3", "ic"},
      {"point --alpha 1", "omega"},              // missing required option
      {"point --alpha abc --omega 1", "alpha"},  // not a number
      {"frobnicate", "frobnicate"},              // unknown subcommand
  };
  for (const Case& c : cases) {
    const ProcessResult r = Bistable(c.args);
    EXPECT_NE(r.exit_code, 0) << c.args;
    EXPECT_NE(r.exit_code, -1) << c.args << " (crashed?)";
    EXPECT_EQ(r.err.rfind("error: ", 0), 0u) << c.args << ": " << r.err;
    EXPECT_NE(r.err.find(c.expect), std::string::npos) << c.args << ": " << r.err;
    EXPECT_TRUE(r.out.empty()) << c.args;
  }
}

// --poincare: a CSV file (one header line, units in brackets), its count and file in --json; "-" with
// --json puts the points into the JSON; the plot; bad values name the flag and the bound.
TEST(CliPoint, PoincareSectionFileJsonAndPlot) {
  const std::string dir = bistable_test::FreshDir("cli_point", "poincare");
  const std::string duffing =
      "point --model standalone --alpha 0.3472222222222222 --omega 1.2 --eta 0.3 --no-rosenstein ";
  const ProcessResult r = Bistable(duffing + "--poincare-periods 3000 --poincare " + dir + "/s.csv --poincare-plot " +
                                   dir + "/s.png --json");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const auto j = nlohmann::json::parse(r.out);
  EXPECT_EQ(j["motion"], "chaotic");
  EXPECT_EQ(j["poincare"]["count"], 3000);
  EXPECT_EQ(j["poincare"]["file"], dir + "/s.csv");
  EXPECT_EQ(j["poincare"]["columns"], nlohmann::json({"k", "tau", "y_m", "dy_m"}));
  EXPECT_EQ(j["poincare"]["units"], nlohmann::json({"", "1/omega_n", "delta_s", "delta_s/tau"}));
  EXPECT_FALSE(j["poincare"].contains("points")) << "points go to the file, not the JSON";
  std::ifstream in(dir + "/s.csv");
  std::string line;
  std::getline(in, line);
  EXPECT_EQ(line, "k,tau [1/omega_n],y_m [delta_s],dy_m [delta_s/tau]");
  size_t rows = 0;
  while (std::getline(in, line)) ++rows;
  EXPECT_EQ(rows, 3000u);
  EXPECT_GT(std::filesystem::file_size(dir + "/s.png"), 10000u);
  for (const auto& e : std::filesystem::directory_iterator(dir))
    EXPECT_EQ(e.path().filename().string().find(".bistable-out-"), std::string::npos) << "left behind: " << e.path();

  // "-" with --json: the points inside the JSON (coupled: six columns, the resonator's too), at the phase.
  const ProcessResult c = Bistable(
      "point --model coupled --alpha 0.3 --omega 0.8 --no-rosenstein --poincare - --poincare-phase 1.5 --json");
  ASSERT_EQ(c.exit_code, 0) << c.err;
  const auto jc = nlohmann::json::parse(c.out);
  ASSERT_EQ(jc["poincare"]["points"].size(), jc["poincare"]["count"].get<size_t>());
  ASSERT_GT(jc["poincare"]["count"].get<int>(), 20);
  const auto& first = jc["poincare"]["points"][0];
  ASSERT_EQ(first.size(), 6u);
  EXPECT_NEAR(first[1].get<double>(), (1.5 + 2 * M_PI * first[0].get<double>()) / 0.8, 1e-9);
  EXPECT_EQ(jc["poincare"]["phase"], 1.5);
  // "-" alone: standard output is the CSV.
  const ProcessResult csv = Bistable("point --model standalone --alpha 0.3 --omega 1.2 --no-rosenstein --poincare -");
  ASSERT_EQ(csv.exit_code, 0) << csv.err;
  EXPECT_EQ(csv.out.rfind("k,tau [1/omega_n],y_m [delta_s],dy_m [delta_s/tau]\n", 0), 0u) << csv.out.substr(0, 200);
  EXPECT_GT(std::count(csv.out.begin(), csv.out.end(), '\n'), 40);

  struct Case {
    std::string args, expect;
  };
  for (const Case& bad : std::vector<Case>{
           {"--poincare-periods 0", "--poincare-periods = 0 violates --poincare-periods in [1, 100000]"},
           {"--poincare-periods 100001", "--poincare-periods = 100001 violates --poincare-periods in [1, 100000]"},
           {"--poincare-periods -3", "--poincare-periods = -3 violates --poincare-periods in [1, 100000]"},
           {"--poincare-periods abc", "--poincare-periods"},
           {"--poincare-periods 10 --t-end 600", "--t-end excludes --poincare-periods"},
           {"--poincare-phase 6.3", "poincare_phase = 6.3 violates poincare_phase in [0, 2 pi)"},
           {"--poincare-phase -1", "poincare_phase = -1 violates poincare_phase in [0, 2 pi)"},
           {"--poincare-plot " + dir + "/x.pdf", "--poincare-plot ends in .png or .svg"},
           {"--poincare " + dir + "/missing/x.csv", "poincare"},
       }) {
    const ProcessResult e = Bistable("point --model standalone --alpha 0.3 --omega 0.01 " + bad.args);
    EXPECT_EQ(e.exit_code, 2) << bad.args;
    EXPECT_NE(e.err.find(bad.expect), std::string::npos) << bad.args << ": " << e.err;
    EXPECT_TRUE(e.out.empty()) << bad.args;
  }
  // The steps-per-point limit, said in terms of the flag.
  const ProcessResult far = Bistable("point --model standalone --alpha 0.3 --omega 0.01 --poincare-periods 100000");
  EXPECT_EQ(far.exit_code, 2);
  EXPECT_NE(far.err.find("--poincare-periods = 100000 violates --poincare-periods <= 1590"), std::string::npos)
      << far.err;
  std::filesystem::remove_all(dir);
}

TEST(CliPoint, HelpDocumentsUnits) {
  const ProcessResult r = Bistable("point --help");
  EXPECT_EQ(r.exit_code, 0);
  EXPECT_NE(r.out.find("--alpha"), std::string::npos);
  EXPECT_NE(r.out.find("non-dimensional"), std::string::npos);
  EXPECT_NE(r.out.find("--poincare-periods"), std::string::npos);
  EXPECT_NE(r.out.find("tau_k = (phase + 2 pi k)/Omega"), std::string::npos);
}

}  // namespace

namespace {

TEST(CliHbm, JsonHasBranchesWithTheContractKeys) {
  const ProcessResult r =
      Bistable("hbm --model standalone --continue omega --from 0.2 --to 2 --alpha 0.3 --harmonics 3 --json");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const auto j = nlohmann::json::parse(r.out);
  ASSERT_TRUE(j["branches"].is_array());
  ASSERT_FALSE(j["branches"].empty());
  const auto& p = j["branches"][0]["points"][0];
  for (const char* k : {"omega", "alpha", "amplitude", "mean", "stable", "harmonics"}) EXPECT_TRUE(p.contains(k)) << k;
  EXPECT_EQ(p["harmonics"].size(), 7u);  // c0 + 3 (a, b) pairs
  EXPECT_EQ(j["settings"]["harmonics"], 3);
  bool intrawell = false;
  for (const auto& b : j["branches"]) intrawell |= std::fabs(b["points"][0]["mean"].get<double>() - 1.0) < 0.05;
  EXPECT_TRUE(intrawell) << "an intrawell branch about +1";
  EXPECT_TRUE(j["notes"].is_array());
}

// A period doubling whose doubled branch cannot be seeded is said, not dropped silently (H = 5 at
// alpha 0.3 fails near Omega 0.55; more harmonics succeed).
TEST(CliHbm, FailedBranchSwitchIsReported) {
  const ProcessResult r = Bistable("hbm --model standalone --alpha 0.3 --switch-pd 1 --json");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const auto j = nlohmann::json::parse(r.out);
  ASSERT_TRUE(j["notes"].is_array());
  bool said = false;
  for (const auto& n : j["notes"]) said |= n.get<std::string>().find("period doubling") != std::string::npos;
  bool doubled = false;
  for (const auto& b : j["branches"]) doubled |= b["period"] == 2;
  EXPECT_TRUE(said || doubled) << r.out.substr(0, 400);  // either the branch or the reason
  EXPECT_FALSE(said && doubled && j["notes"].size() > 4);
}

// Period doublings flagged with their located values and the switched period-2 branch; fold curves
// with a cusp (the double-well Duffing cases of tests/hbm_test.cc).
TEST(CliHbm, JsonHasPeriodDoublingsSwitchedBranchesAndFoldCurves) {
  ProcessResult r =
      Bistable("hbm --continue alpha --omega 1.2 --eta 0.3 --from 0.1 --to 0.25 --harmonics 10 --switch-pd 1 --json");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  auto j = nlohmann::json::parse(r.out);
  int pd = 0, period2 = 0;
  for (const auto& b : j["bifurcations"])
    if (b["kind"] == "period_doubling" && b["period"] == 1) {
      EXPECT_NEAR(b["alpha"].get<double>(), 0.18443, 1e-5);
      EXPECT_NEAR(b["multiplier"][0].get<double>(), -1.0, 1e-6);
      const auto& p = j["branches"][b["branch"].get<int>()]["points"][b["point"].get<int>()];
      EXPECT_TRUE(p["period_doubling"].get<bool>());
      EXPECT_EQ(p["period_doubling_at"]["alpha"], b["alpha"]);
      EXPECT_EQ(p["multipliers"].size(), 2u);
      ++pd;
    }
  for (const auto& b : j["branches"])
    if (b["period"] == 2) {
      ++period2;
      EXPECT_EQ(b["points"][0]["period"], 2);
      EXPECT_EQ(b["start"].get<std::string>().rfind("period-doubling at alpha = 0.18443", 0), 0u) << b["start"];
    }
  EXPECT_EQ(pd, 2);       // the +well orbit and its mirror image
  EXPECT_EQ(period2, 2);  // one doubled branch from each
  r = Bistable("hbm --alpha 0.3 --fold-curve --json");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  j = nlohmann::json::parse(r.out);
  ASSERT_GE(j["fold_curves"].size(), 1u);
  int cusps = 0;
  for (const auto& c : j["fold_curves"])
    for (const auto& p : c["points"]) {
      for (const char* k : {"alpha", "omega", "amplitude", "mean", "cusp", "well"}) ASSERT_TRUE(p.contains(k)) << k;
      cusps += p["cusp"].get<bool>();
    }
  EXPECT_EQ(cusps, 1);
}

TEST(CliHbm, BadInputNamesTheField) {
  for (auto [args, expect] : std::vector<std::pair<std::string, std::string>>{
           {"hbm --harmonics 0", "harmonics = 0 violates harmonics in [1, 50]"},
           {"hbm --from 1 --to 1", "to"},
           {"hbm --continue eta", "continue = 'eta' violates continue in {omega, alpha}"},
           {"hbm --model duffing", "model"},
           {"hbm --alpha -2", "alpha"},
           {"hbm --switch-pd 4", "switch_pd = 4 violates switch_pd in [0, 3]"},
           {"hbm --fold-curve --alpha-range 2,1", "alpha_range = 1 violates alpha_range > its low end 2"},
           {"hbm --fold-curve --omega-range 0,1", "omega_range = 0 violates omega_range > 0"},
           {"hbm --over-map x.h5", "over_map: draws fold curves: add --fold-curve"},
           {"hbm --fold-curve --over-map no-such-sweep --data /nonexistent", "over_map"},
       }) {
    const ProcessResult r = Bistable(args);
    EXPECT_EQ(r.exit_code, 2) << args;
    EXPECT_NE(r.err.find(expect), std::string::npos) << args << ": " << r.err;
  }
}

}  // namespace

namespace {

TEST(CliChirp, WritesFrfSpectrogramAndSeries) {
  const std::string out = bistable_test::FreshDir("cli_point", "chirp") + "/chirp";
  const ProcessResult r = Bistable(
      "chirp --model coupled --alpha 0.2 --from 0.3 --to 2 --duration 600 --direction both --json --out " + out);
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const auto j = nlohmann::json::parse(r.out);
  ASSERT_EQ(j["sweeps"].size(), 2u);
  for (const auto& f : j["files"]) EXPECT_GT(std::filesystem::file_size(f.get<std::string>()), 100u) << f;
  EXPECT_EQ(j["unit"], "rad/tau");
  const ProcessResult bad = Bistable("chirp --direction sideways --out " + out);
  EXPECT_EQ(bad.exit_code, 2);
  EXPECT_NE(bad.err.find("direction"), std::string::npos);
  std::filesystem::remove_all(out);
}

}  // namespace
