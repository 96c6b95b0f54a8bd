// Design search (issue 17, `bistable design`): fields checked by name, the search against a closed
// form, the Pareto front, reuse of cached candidates, and the CLI's JSON contract. Real engine, real
// data directories.
#include <cmath>
#include <complex>
#include <filesystem>
#include <fstream>
#include <set>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "client/design_run.h"
#include "design/design_search.h"
#include "design/design_spec.h"
#include "tests/process_util.h"

namespace bistable {
namespace {

std::string TempDir(const std::string& name) { return bistable_test::FreshDir("design-test", name); }

// The linear tuned-mass-damper limit: linear-coupled model, whose FRF has a closed form.
const char* kLinearTmd = R"(
name = "linear TMD"
model = "linear-coupled"
[params]
eta = 0.1
[design]
bounds = { lambda = [0.5, 1.5], phi = [0.05, 0.5], eta_r = [0.01, 0.5] }
alpha = 1.0
omega = { linspace = [0.2, 3.0, 29] }
budget = 40
maps = 0
)";

// |x_abs / x_base| of the linear-coupled model (docs/model.md §1 with k_lin = +1, eps = 0): with s = iΩ,
// X/U = (η s + 1) / (s² + η s + 1 + φ s² (η_r s + λ²)/(s² + η_r s + λ²)).
double ClosedFormDb(double w, double lambda, double phi, double eta_r, double eta = 0.1) {
  const std::complex<double> s(0, w);
  const auto g = (eta_r * s + lambda * lambda) / (s * s + eta_r * s + lambda * lambda);
  return 20 * std::log10(std::abs((eta * s + 1.0) / (s * s + eta * s + 1.0 + phi * s * s * g)));
}

double ClosedFormBand(const std::vector<double>& omega, const DesignPoint& x) {
  std::vector<double> f, zeros(omega.size(), 0.0);
  for (double w : omega) f.push_back(ClosedFormDb(w, x[0], x[1], x[2]));
  return ScoreDesign(omega, 1, f, zeros, std::vector<double>(omega.size(), -1.0), 0.01).band_width;
}

TEST(DesignSpec, EveryFieldIsCheckedByName) {
  struct Row {
    std::string edit, field, says;
  };
  const std::vector<Row> rows = {
      {"bounds = { lambda = [0.5, 1.5], phi = [0, 0.5] }", "design.bounds.phi[0]",
       "design.bounds.phi[0] = 0 violates design.bounds.phi[0] in [0.001, 100]"},
      {"bounds = { lambda = [1.5, 0.5] }", "design.bounds.lambda[1]", ">= design.bounds.lambda[0] = 1.5"},
      {"bounds = { eta_r = [0.1, 200] }", "design.bounds.eta_r[1]", "in [0, 100]"},
      {"bounds = { lamda = [0.5, 1.5] }", "design.bounds.lamda", "did you mean 'lambda'"},
      {"bounds = { lambda = [1, 1] }", "design.bounds", "no parameter is free"},
      {"budget = 0", "design.budget", "design.budget = 0 violates design.budget a whole number in [1, 10000]"},
      {"budgte = 3", "design.budgte", "did you mean 'budget'"},
      {"alpha = -1", "design.alpha", "design.alpha = -1 violates design.alpha > 0"},
      {"maps = 4", "design.maps", "[0, 3]"},
      {"optimizer = \"nelder\"", "design.optimizer", "direct-l"},
      {"omega = { linspace = [0.2, 3.0, 1] }", "design.omega", "count >= 2"},
      {"omega = { linspace = [3.0, 0.2, 9] }", "design.omega", "strictly increasing"},
      // An integer beyond double's exact range is a number out of range (was "must be a number").
      {"seed = 99999999999999999", "design.seed", "a whole number in [0, 2147483647]"},
      // The map grid that map_alpha spans with omega is map_alpha's (was reported as design.omega).
      {"maps = 1\nmap_alpha = { linspace = [0.1, 3.0, 1000000] }", "design.map_alpha", "more than 4194304 points"},
  };
  for (const Row& r : rows) {
    const std::string key = r.edit.substr(0, r.edit.find(' '));
    std::string text = kLinearTmd;
    // Replace the line that sets `key` (or append the new key).
    const size_t at = text.find("\n" + key + " ");
    if (at != std::string::npos) text.erase(at + 1, text.find('\n', at + 1) - at);
    text += r.edit + "\n";
    auto s = ParseDesignSpec(text, "t.toml");
    ASSERT_FALSE(s.ok()) << r.edit;
    EXPECT_EQ(s.status().field(), r.field) << r.edit << ": " << s.status().ToString();
    EXPECT_NE(s.status().message().find(r.says), std::string::npos) << r.edit << ": " << s.status().ToString();
  }
  auto standalone = ParseDesignSpec(
      std::string(kLinearTmd).replace(std::string(kLinearTmd).find("linear-coupled"), 14, "standalone"), "t");
  ASSERT_FALSE(standalone.ok());
  EXPECT_EQ(standalone.status().field(), "model");
  auto axes = ParseDesignSpec(std::string(kLinearTmd) + "[axes]\neta = [0.1, 0.2]\n", "t");
  ASSERT_FALSE(axes.ok());
  EXPECT_EQ(axes.status().field(), "axes");
  EXPECT_TRUE(ParseDesignSpec(kLinearTmd, "t").ok());
}

TEST(DesignSpec, ShippedDesignExamplesParse) {
  int found = 0;
  for (const auto& entry : std::filesystem::directory_iterator(BISTABLE_EXAMPLES_DIR)) {
    if (entry.path().extension() != ".toml") continue;
    std::ifstream in(entry.path());
    const std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    if (text.find("\n[design]") == std::string::npos) continue;
    ++found;
    auto d = ParseDesignSpec(text, entry.path().string());
    EXPECT_TRUE(d.ok()) << entry.path() << ": " << d.status().ToString();
  }
  EXPECT_GE(found, 1);
}

// The design id (and so the report directory DATA/designs/<id>) hashes an unambiguous text of
// everything that determines the result: bounds that join to the same digits, cost, maps, map_alpha.
TEST(DesignSpec, IdSeparatesEveryFieldThatChangesTheResult) {
  auto with = [](const std::string& key, const std::string& line) {
    std::string text = kLinearTmd;
    const size_t at = text.find("\n" + key + " ");
    if (at != std::string::npos) text.erase(at + 1, text.find('\n', at + 1) - at);
    auto s = ParseDesignSpec(text + line + "\n", "t.toml");
    EXPECT_TRUE(s.ok()) << line << ": " << s.status().ToString();
    return s.ok() ? s->id : std::string();
  };
  const std::string base = with("budget", "budget = 40");
  EXPECT_EQ(base.size(), 12u);
  EXPECT_EQ(with("budget", "budget = 40"), base);  // deterministic
  // lo 0.1, hi 12 and lo 0.11, hi 2 once joined to the same "0.112".
  const std::string a = with("bounds", "bounds = { lambda = [0.5, 1.5], phi = [0.1, 12], eta_r = [0.01, 0.5] }");
  const std::string b = with("bounds", "bounds = { lambda = [0.5, 1.5], phi = [0.11, 2], eta_r = [0.01, 0.5] }");
  EXPECT_NE(a, b);
  std::set<std::string> ids = {base, a, b};
  for (const auto& [key, line] : std::vector<std::pair<std::string, std::string>>{
           {"cost", "cost = \"lambda\""},
           {"maps", "maps = 1"},
           {"map_alpha", "map_alpha = { linspace = [0.1, 2.0, 7] }"},
           {"seed", "seed = 2"},
           {"optimizer", "optimizer = \"crs2\""},
           {"budget", "budget = 41"},
           {"bounds", "bounds = { lambda = [0.5, 1.5], phi = [0.05, 0.5], eta_r = [0.01, 0.50000000000001] }"}}) {
    const std::string id = with(key, line);
    EXPECT_TRUE(ids.insert(id).second) << line << " shares id " << id;
  }
}

TEST(DesignScore, BandIsTheMeasureBelowZeroDbWithChaosCounted) {
  const std::vector<double> w = {1, 2, 3, 4};
  // g: +1, -1 (crossing at 1.5), -1, +3 (crossing at 3.25): band [1.5, 3.25] = 1.75.
  const std::vector<double> f = {1, -1, -1, 3}, calm = {0, 0, 0, 0}, lle = {-1, -1, -1, -1};
  DesignScore s = ScoreDesign(w, 1, f, calm, lle, 0.01);
  EXPECT_DOUBLE_EQ(s.band_width, 1.75);
  EXPECT_DOUBLE_EQ(s.safe_band_width, 1.75);
  EXPECT_TRUE(s.feasible());
  EXPECT_DOUBLE_EQ(s.band_lo, 1.5);
  EXPECT_DOUBLE_EQ(s.band_hi, 3.25);
  // A chaotic point in the band: infeasible, share 1/2, its cells leave the safe width.
  const std::vector<double> chaos = {0, 2, 0, 0};
  s = ScoreDesign(w, 1, f, chaos, lle, 0.01);
  EXPECT_FALSE(s.feasible());
  EXPECT_DOUBLE_EQ(s.chaotic_share_band, 0.5);
  EXPECT_DOUBLE_EQ(s.chaotic_share, 0.25);
  EXPECT_DOUBLE_EQ(s.safe_band_width, 0.25);  // only [3, 3.25] is left
  EXPECT_DOUBLE_EQ(s.unsafe_share_band, 0.5);
  // A diverged band point (motion undefined, FRF finite): not chaotic, but unsafe; the front sees it.
  const std::vector<double> diverged = {0, -1, 0, 0};
  s = ScoreDesign(w, 1, f, diverged, lle, 0.01);
  EXPECT_FALSE(s.feasible());
  EXPECT_DOUBLE_EQ(s.chaotic_share_band, 0);
  EXPECT_DOUBLE_EQ(s.unsafe_share_band, 0.5);
  Candidate wide_diverged, clean;
  wide_diverged.score = s;
  wide_diverged.cost = clean.cost = 1;
  clean.score = ScoreDesign(w, 1, f, calm, lle, 0.01);
  wide_diverged.score.band_width = clean.score.band_width + 0.5;  // wider, but with a diverged band point
  wide_diverged.x = {1, 1, 1};
  clean.x = {2, 2, 2};
  clean.index = 1;
  EXPECT_FALSE(Dominates(wide_diverged, clean));
  EXPECT_FALSE(Dominates(clean, wide_diverged));
  EXPECT_EQ(ParetoFront({wide_diverged, clean}).size(), 2u);  // the clean design stays on the front
  Candidate narrower_diverged = wide_diverged;
  narrower_diverged.score.band_width = clean.score.band_width;
  EXPECT_TRUE(Dominates(clean, narrower_diverged));  // same band, no unsafe point: dominates
  // Several amplitudes: the band must hold at each (the max over alpha).
  const std::vector<double> two = {1, -1, -1, 3, 1, 1, -1, 3};
  s = ScoreDesign(w, 2, two, std::vector<double>(8, 0), std::vector<double>(8, -1), 0.01);
  EXPECT_DOUBLE_EQ(s.band_width, 0.5 + 0.25);
}

// The search on the linear TMD limit finds the widest band that the closed form gives anywhere in the
// bounds (searched densely), on the same Omega line; the Pareto front is non-dominated; a second run
// computes nothing.
TEST(DesignSearch, FindsTheClosedFormBandOfTheLinearTmdAndReusesEveryCandidate) {
  auto spec = ParseDesignSpec(kLinearTmd, "t");
  ASSERT_TRUE(spec.ok()) << spec.status().ToString();
  // The closed form's optimum over a 41 x 19 x 25 grid of the bounds, then refined by coordinate steps.
  double best = 0;
  DesignPoint bx{};
  for (int i = 0; i <= 40; ++i)
    for (int j = 0; j <= 18; ++j)
      for (int k = 0; k <= 24; ++k) {
        const DesignPoint x = {0.5 + i * 0.025, 0.05 + j * 0.025, 0.01 + k * (0.49 / 24)};
        const double b = ClosedFormBand(spec->omega, x);
        if (b > best) best = b, bx = x;
      }
  ASSERT_GT(best, 2.0);  // the absorber widens the band of the bare oscillator (Ω > √2: 1.58 on this line)

  const std::string data = TempDir("tmd");
  auto sweeps = OpenEmbeddedSweeps(data, 0);
  ASSERT_TRUE(sweeps.ok()) << sweeps.status().ToString();
  auto runner = [&](const std::string& t) { return sweeps.value()->Run(t); };
  auto r = RunDesignSearch(*spec, runner, {});
  ASSERT_TRUE(r.ok()) << r.status().ToString();
  ASSERT_EQ(static_cast<int>(r->candidates.size()), 40);
  ASSERT_GE(r->best, 0);
  const Candidate& b = r->candidates[r->best];
  EXPECT_GT(r->computed, 0);
  // Within 3 % of the closed form's optimum (closed-form optimum at lambda, phi, eta_r = bx).
  EXPECT_GE(b.score.band_width, 0.97 * best)
      << "closed-form optimum " << best << " at " << bx[0] << ", " << bx[1] << ", " << bx[2];
  // The simulated band of the best design equals the closed form's band of that design.
  EXPECT_NEAR(b.score.band_width, ClosedFormBand(spec->omega, b.x), 0.01);
  EXPECT_EQ(b.score.chaotic_in_band, 0);

  // Pareto front: no member dominated by any candidate, every other candidate dominated by a member
  // or a repeat of a member's design; no design listed twice.
  ASSERT_FALSE(r->front.empty());
  for (int i : r->front)
    for (const Candidate& c : r->candidates)
      EXPECT_FALSE(Dominates(c, r->candidates[i])) << c.index << " dominates " << i;
  for (size_t a = 0; a < r->front.size(); ++a)
    for (size_t b = a + 1; b < r->front.size(); ++b)
      EXPECT_FALSE(r->candidates[r->front[a]].x == r->candidates[r->front[b]].x);
  for (const Candidate& c : r->candidates) {
    if (std::find(r->front.begin(), r->front.end(), c.index) != r->front.end()) continue;
    bool dominated = false, repeat = false;  // a design evaluated twice is listed once
    for (int i : r->front)
      dominated = dominated || Dominates(r->candidates[i], c), repeat = repeat || r->candidates[i].x == c.x;
    EXPECT_TRUE(dominated || repeat) << c.index;
  }

  // Run again (a new process would open the same data directory): every candidate comes from the cache.
  sweeps.value().reset();
  auto again = OpenEmbeddedSweeps(data, 0);
  ASSERT_TRUE(again.ok());
  auto r2 = RunDesignSearch(*spec, [&](const std::string& t) { return again.value()->Run(t); }, {});
  ASSERT_TRUE(r2.ok());
  EXPECT_EQ(r2->computed, 0);
  EXPECT_EQ(r2->items, r->items);
  ASSERT_EQ(r2->candidates.size(), r->candidates.size());
  for (size_t i = 0; i < r->candidates.size(); ++i) EXPECT_EQ(r2->candidates[i].sweep_id, r->candidates[i].sweep_id);
  std::filesystem::remove_all(data);
}

TEST(DesignCli, JsonContractAndBadFlags) {
  const std::string dir = TempDir("cli");
  const std::string spec = dir + "/tmd.toml";
  std::ofstream(spec) << std::string(kLinearTmd).replace(std::string(kLinearTmd).find("budget = 40"), 11, "budget = 8");
  auto r = bistable_test::Bistable("design " + spec + " --data " + dir + "/data --json --no-plots --brute-force 2");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const auto j = nlohmann::json::parse(r.out);
  for (const char* k : {"design_id", "candidates", "front", "best", "search", "brute_force", "report_dir", "files"})
    EXPECT_TRUE(j.contains(k)) << k;
  ASSERT_EQ(j["candidates"].size(), 8u);
  for (const auto& c : j["candidates"]) {
    EXPECT_EQ(c["sweep_id"].get<std::string>().size(), 12u);
    for (const char* k : {"design", "cost", "band_width", "chaotic_share_band", "unsafe_share_band", "chaotic_share",
                          "feasible", "items", "computed"})
      EXPECT_TRUE(c.contains(k)) << k;
  }
  EXPECT_EQ(j["search"]["points"].get<long>(), 8 * 29);
  EXPECT_EQ(j["brute_force"]["points"].get<long>(), 8 * 29);  // 2 x 2 x 2 designs
  EXPECT_TRUE(std::filesystem::exists(j["report_dir"].get<std::string>() + "/report.json"));
  // The candidates are ordinary sweeps: `bistable map` reads one.
  auto m = bistable_test::Bistable("map " + j["best"]["sweep_id"].get<std::string>() +
                                   " --metric frf_db --format json --data " + dir + "/data");
  EXPECT_EQ(m.exit_code, 0) << m.err;
  // Again: nothing computed.
  auto again = bistable_test::Bistable("design " + spec + " --data " + dir + "/data --json --no-plots");
  ASSERT_EQ(again.exit_code, 0) << again.err;
  EXPECT_EQ(nlohmann::json::parse(again.out)["search"]["computed"].get<long>(), 0);

  auto bad = bistable_test::Bistable("design " + spec + " --data " + dir + "/data --budget 0");
  EXPECT_EQ(bad.exit_code, 2);
  EXPECT_NE(bad.err.find("design.budget = 0 violates"), std::string::npos) << bad.err;
  auto bf = bistable_test::Bistable("design " + spec + " --data " + dir + "/data --brute-force 1");
  EXPECT_EQ(bf.exit_code, 2);
  EXPECT_NE(bf.err.find("brute-force = 1 violates brute-force in [2, 64]"), std::string::npos) << bf.err;
  auto flag = bistable_test::Bistable("design " + spec + " --budgte 3");
  EXPECT_NE(flag.exit_code, 0);
  EXPECT_NE(flag.err.find("budgte"), std::string::npos) << flag.err;
  std::filesystem::remove_all(dir);
}

}  // namespace
}  // namespace bistable
