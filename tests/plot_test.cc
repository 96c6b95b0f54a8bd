// Every figure type, rendered by the installed gnuplot into a PNG and decoded (tests/png_stats.py,
// Debian's python3-pil): not blank, and the data's own colours are on the page (a figure whose data
// block gnuplot skipped has axes and a title but none of them). Small data, so the suite stays fast.
// Also: discrete codes keep "none found" apart, legends name only what is drawn (SVG text), and
// `bistable run` without gnuplot keeps the map, says what is missing and succeeds.
#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "client/map_slice.h"
#include "client/plot.h"
#include "tests/process_util.h"

namespace fs = std::filesystem;
using bistable_test::RunArgv;

namespace {

struct PngStats {
  int width = 0, height = 0, distinct = 0;
  double non_background = 0;
  std::map<std::string, long> colours;  // pixels near each asked colour
  std::map<std::string, std::pair<int, int>>
      rows;  // with rows: the 5th and 95th percentile rows of each colour's pixels
};

PngStats Stats(const std::string& png, const std::vector<std::string>& colours = {}, bool rows = false) {
  std::vector<std::string> argv = {"/usr/bin/python3", BISTABLE_TESTS_DIR "/png_stats.py"};
  if (rows) argv.push_back("--rows");
  argv.push_back(png);
  argv.insert(argv.end(), colours.begin(), colours.end());
  const bistable_test::ExecResult r = RunArgv(argv);
  EXPECT_EQ(r.exit_code, 0) << r.err;
  PngStats s;
  if (r.exit_code != 0) return s;
  const auto j = nlohmann::json::parse(r.out);
  s.width = j["width"], s.height = j["height"], s.distinct = j["distinct"], s.non_background = j["non_background"];
  for (const auto& [k, v] : j["colours"].items()) s.colours[k] = v.get<long>();
  if (j.contains("rows"))
    for (const auto& [k, v] : j["rows"].items())
      if (!v.is_null()) s.rows[k] = {v[0].get<int>(), v[1].get<int>()};
  return s;
}

// Rendered, the size asked, not blank, and each of `data_colours` covers at least `min_pixels`.
void ExpectDrawn(const bistable::Status& st, const std::string& png, int width, int height,
                 const std::vector<std::string>& data_colours, long min_pixels = 200) {
  ASSERT_TRUE(st.ok()) << st.ToString();
  PngStats s = Stats(png, data_colours);
  EXPECT_EQ(s.width, width);
  EXPECT_EQ(s.height, height);
  EXPECT_GT(s.distinct, 20) << "a figure has anti-aliased text and lines";
  EXPECT_GT(s.non_background, 0.01);
  for (const std::string& c : data_colours) EXPECT_GE(s.colours[c], min_pixels) << c << " (data colour) in " << png;
}

class Figures : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = bistable_test::FreshDir("plot", ::testing::UnitTest::GetInstance()->current_test_info()->name());
  }
  void TearDown() override {
    if (!HasFailure()) fs::remove_all(dir_);
  }
  std::string File(const std::string& name) const { return (fs::path(dir_) / name).string(); }
  std::string dir_;
};

std::vector<double> Range(int n, double lo, double hi) {
  std::vector<double> v;
  for (int i = 0; i < n; ++i) v.push_back(lo + (hi - lo) * i / (n - 1));
  return v;
}

bistable::PlotData Map(const std::string& metric, int n) {
  bistable::PlotData d;
  d.title = "test: " + metric;
  d.metric = metric;
  d.unit = metric == "frf_db" ? "dB" : "";
  d.axis_names = {"alpha", "omega"};
  d.axis_units = {"A0/delta_s", "omega0/omega_n"};
  d.axis_values = {Range(n, 0.1, 3), Range(n, 0.1, 3)};
  return d;
}

TEST_F(Figures, HeatmapOfAContinuousMetricUsesItsDivergingPalette) {
  bistable::PlotData d = Map("frf_db", 12);
  for (int i = 0; i < 144; ++i) d.values.push_back(i < 72 ? -20.0 : 20.0);
  const std::string out = File("frf.png");
  ExpectDrawn(bistable::RenderPlot(d, out), out, 900, 700, {"#2166ac", "#b2182b"}, 2000);
}

TEST_F(Figures, SharedColourRangeIsTheGivenOne) {
  // Values only up to +1 dB on a shared range of ±20 dB: nearly white, never the range's deep red.
  bistable::PlotData d = Map("frf_db", 12);
  d.values.assign(144, 1.0);
  d.cb_lo = -20, d.cb_hi = 20;
  const std::string out = File("shared.png");
  ASSERT_TRUE(bistable::RenderPlot(d, out).ok());
  EXPECT_LT(Stats(out, {"#b2182b"}).colours["#b2182b"], 2000)
      << "the data drew the full red: the range was not applied";
  d.cb_lo = d.cb_hi = NAN;  // its own range: ±1 dB, so 1 dB is the deepest red
  ASSERT_TRUE(bistable::RenderPlot(d, out).ok());
  EXPECT_GT(Stats(out, {"#b2182b"}).colours["#b2182b"], 20000);
}

TEST_F(Figures, PeriodCodesAreDiscreteAndNoneFoundIsGrey) {
  bistable::PlotData d = Map("period", 10);
  for (int i = 0; i < 100; ++i) d.values.push_back(i % 3 == 0 ? 0.0 : i % 3 == 1 ? 1.0 : 2.0);
  d.codes = bistable::MetricCodes("period", d.values);
  ASSERT_EQ(d.codes.size(), 3u);
  EXPECT_EQ(d.codes[0].name, "none found");
  EXPECT_EQ(d.codes[0].colour, "#bdbdbd");
  const std::string out = File("period.png");
  // Grey for 0, then the qualitative palette's first two colours for 1 and 2: three flat colours.
  ExpectDrawn(bistable::RenderPlot(d, out), out, 900, 700, {"#bdbdbd", "#1b9e77", "#d95f02"}, 5000);
}

TEST_F(Figures, MotionCodesKeepTheirColoursEvenWhenOneKindIsAbsent) {
  const auto codes = bistable::MetricCodes("motion", {0, 0, 1});
  ASSERT_EQ(codes.size(), 3u) << "intrawell, interwell, chaotic always (undefined only when present)";
  EXPECT_EQ(codes[2].name, "chaotic");
  EXPECT_EQ(bistable::MetricCodes("motion", {-1, 0}).size(), 4u);
  // Settled labels: quasi-periodic (3) and unresolved (4) named in their own colours when present, unresolved grey.
  const auto settled = bistable::MetricCodes("motion", {0, 3, 4});
  ASSERT_EQ(settled.size(), 5u);
  EXPECT_EQ(settled[3].name, "quasi-periodic");
  EXPECT_EQ(settled[3].colour, "#7b3294");
  EXPECT_EQ(settled[4].name, "unresolved");
  EXPECT_EQ(settled[4].colour, "#636363");
  {
    bistable::PlotData q = Map("motion", 10);
    for (int i = 0; i < 100; ++i) q.values.push_back(i < 40 ? 0.0 : i < 70 ? 3.0 : 4.0);
    q.codes = bistable::MetricCodes("motion", q.values);
    const std::string qout = File("motion_settled.png");
    ExpectDrawn(bistable::RenderPlot(q, qout), qout, 900, 700, {"#2c7bb6", "#7b3294", "#636363"}, 5000);
  }
  EXPECT_TRUE(bistable::MetricCodes("frf_db", {1, 2}).empty());
  bistable::PlotData d = Map("motion", 10);
  for (int i = 0; i < 100; ++i) d.values.push_back(i < 50 ? 0.0 : 1.0);
  d.codes = bistable::MetricCodes("motion", d.values);
  const std::string out = File("motion.png");
  ExpectDrawn(bistable::RenderPlot(d, out), out, 900, 700, {"#2c7bb6", "#fdae61"}, 5000);
}

TEST_F(Figures, CurvesShowEverySeries) {
  bistable::PlotData d;
  d.title = "stepped sine";
  d.metric = "frf_db";
  d.unit = "dB";
  d.axis_names = {"omega"};
  d.axis_units = {"omega0/omega_n"};
  d.axis_values = {Range(40, 0.1, 3)};
  for (int k = 0; k < 2; ++k)
    for (int i = 0; i < 40; ++i) d.values.push_back(std::sin(0.2 * i) * 10 + 5 * k);
  d.series = {"sweep up", "sweep down"};
  const std::string out = File("curves.png");
  ExpectDrawn(bistable::RenderPlot(d, out), out, 900, 700, {"#2166ac", "#b2182b"});
}

TEST_F(Figures, CategoricalCurvesArePointsOnNamedRows) {
  bistable::PlotData d;
  d.title = "stepped sine: motion";
  d.metric = "motion";
  d.unit = "code";
  d.axis_names = {"omega"};
  d.axis_units = {"omega0/omega_n"};
  d.axis_values = {Range(30, 0.1, 3)};
  for (int k = 0; k < 2; ++k)
    for (int i = 0; i < 30; ++i) d.values.push_back(i < 10 ? 0 : i < 20 ? 2 : 1);
  d.series = {"sweep up", "sweep down"};
  d.codes = bistable::MetricCodes("motion", d.values);
  const std::string out = File("motion_curve.png");
  ExpectDrawn(bistable::RenderPlot(d, out), out, 900, 700, {"#2c7bb6", "#fdae61", "#d7191c"}, 50);
  // The rows are named (SVG text), not numbered.
  const std::string svg = File("motion_curve.svg");
  ASSERT_TRUE(bistable::RenderPlot(d, svg).ok());
  const std::string text = bistable_test::ReadText(svg);
  for (const char* name : {"intrawell", "interwell", "chaotic", "sweep up", "sweep down"})
    EXPECT_NE(text.find(name), std::string::npos) << name;
}

TEST_F(Figures, BranchLegendNamesOnlyWhatIsDrawn) {
  bistable::BranchPlot d;
  d.title = "branches";
  d.x_name = "omega";
  d.x_unit = "omega0/omega_n";
  d.y_label = "max |y_m|";
  bistable::BranchPlot::Branch plus{"+well", 5,    {0.1, 0.5, 1.0, 1.5}, {1.0, 1.1, 1.3, 1.2}, {true, true, true, true},
                                    {1.0},   {1.3}};
  bistable::BranchPlot::Branch inter{
      "interwell", 2, {0.8, 1.2, 1.6, 2.0}, {1.5, 1.8, 2.2, 2.6}, {false, false, true, true}, {}, {}};
  d.branches = {plus, inter};
  const std::string out = File("branches.png");
  ExpectDrawn(bistable::RenderBranches(d, out), out, 900, 700, {"#1b9e77", "#d95f02"}, 100);
  const std::string svg = File("branches.svg");
  ASSERT_TRUE(bistable::RenderBranches(d, svg).ok());
  const std::string text = bistable_test::ReadText(svg);
  for (const char* drawn : {"+well, stable", "interwell, stable", "interwell, unstable", "fold"})
    EXPECT_NE(text.find(drawn), std::string::npos) << drawn;
  EXPECT_EQ(text.find("+well, unstable"), std::string::npos) << "no unstable +well run is drawn";
}

// Period-doubling and Neimark–Sacker markers in their colours with legend entries; drawn only when
// the marker set has points.
TEST_F(Figures, BranchMarkersHaveTheirOwnLegendEntries) {
  bistable::BranchPlot d;
  d.title = "branches";
  d.x_name = "alpha";
  d.x_unit = "A0/delta_s";
  d.y_label = "max |y_m|";
  d.branches = {{"+well", 2, {0.1, 0.2, 0.3}, {1.0, 1.1, 1.2}, {true, true, false}, {}, {}}};
  d.markers = {{"period doubling", 7, "#d7191c", {0.25}, {1.15}}, {"Neimark-Sacker", 5, "#7b3294", {}, {}}};
  const std::string out = File("markers.png");
  ExpectDrawn(bistable::RenderBranches(d, out), out, 900, 700, {"#d7191c"}, 20);
  const std::string svg = File("markers.svg");
  ASSERT_TRUE(bistable::RenderBranches(d, svg).ok());
  const std::string text = bistable_test::ReadText(svg);
  EXPECT_NE(text.find("period doubling"), std::string::npos);
  EXPECT_EQ(text.find("Neimark"), std::string::npos) << "an empty marker set has no legend entry";
}

// Curves over a coded heatmap (fold curves over a motion map): drawn in their colour, named below.
TEST_F(Figures, HeatmapOverlaysAreDrawnWithALegend) {
  bistable::PlotData d;
  d.title = "motion with fold curves";
  d.metric = "motion";
  d.unit = "code";
  d.axis_names = {"alpha", "omega"};
  d.axis_units = {"A0/delta_s", "omega0/omega_n"};
  for (int i = 0; i < 20; ++i)
    d.axis_values.resize(2), d.axis_values[0].push_back(0.05 * (i + 1)), d.axis_values[1].push_back(0.1 * (i + 1));
  for (int i = 0; i < 20; ++i)
    for (int j = 0; j < 20; ++j) d.values.push_back(i + j < 20 ? 0 : 1);
  d.codes = bistable::MetricCodes("motion", d.values);
  bistable::PlotData::Overlay curve{"fold curves", {}, {}, false, "#ff00ff"};
  for (int k = 0; k <= 50; ++k) curve.x.push_back(0.2 + 0.03 * k), curve.y.push_back(0.9 - 0.015 * k);
  d.overlays = {curve};
  const std::string out = File("overlay.png");
  ExpectDrawn(bistable::RenderPlot(d, out), out, 900, 700, {"#ff00ff"}, 100);
  const std::string svg = File("overlay.svg");
  ASSERT_TRUE(bistable::RenderPlot(d, svg).ok());
  EXPECT_NE(bistable_test::ReadText(svg).find("fold curves"), std::string::npos);
}

TEST_F(Figures, HarmonicDiffusionScatter) {
  bistable::ScatterData d;
  d.title = "hd, alpha = " + bistable::PlotNumber(1.0 / 3);
  EXPECT_EQ(bistable::PlotNumber(1.0 / 3), "0.3333");
  for (int i = 1; i <= 40; ++i)
    for (int k = 1; k <= 3; ++k)
      d.x.push_back(0.075 * i), d.y.push_back(0.075 * i * k), d.amp.push_back(std::pow(10.0, -k));
  const std::string out = File("hd.png");
  ExpectDrawn(bistable::RenderHdScatter(d, out), out, 900, 700, {"#999999"}, 200);
}

TEST_F(Figures, BifurcationDiagram) {
  bistable::BifurcationData d;
  d.title = "bifurcation";
  d.x_name = "alpha";
  d.x_unit = "A0/delta_s";
  for (int i = 0; i < 200; ++i)
    for (int k = 0; k < 4; ++k) {
      d.x_up.push_back(0.015 * i), d.y_up.push_back(1 + 0.3 * std::sin(i + k));
      d.x_down.push_back(0.015 * i), d.y_down.push_back(-1 - 0.3 * std::sin(i + k));
    }
  const std::string out = File("bif.png");
  ExpectDrawn(bistable::RenderBifurcation(d, out), out, 900, 700, {"#2166ac", "#b2182b"}, 100);
}

TEST_F(Figures, ChirpFrfWithCoherence) {
  bistable::ChirpFrfPlot d;
  d.title = "chirp";
  d.freq_label = "frequency f [Hz]";
  d.mag_label = "velocity amplitude [m/s]";
  bistable::ChirpFrfPlot::Curve c;
  c.label = "sweep up";
  for (int i = 0; i < 100; ++i) {
    const double f = 1 + 0.07 * i;
    c.freq.push_back(f), c.in_mag.push_back(0.01 * f),
        c.out_mag.push_back(0.01 * f * (1 + 1 / (0.1 + std::fabs(f - 4))));
    c.db.push_back(20 * std::log10(c.out_mag.back() / c.in_mag.back())), c.coherence.push_back(0.5 + 0.5 * std::cos(f));
    c.raw_freq.push_back(f), c.raw_db.push_back(c.db.back() + 3 * std::sin(13 * f));
  }
  d.curves = {c};
  const std::string out = File("frf.png");
  ExpectDrawn(bistable::RenderChirpFrf(d, out), out, 1100, 1100, {"#2166ac", "#c6dbef"}, 200);
}

TEST_F(Figures, Spectrogram) {
  bistable::SpectrogramPlot d;
  d.title = "spectrogram of y_m";
  d.time_label = "time t [s]";
  d.freq_label = "frequency of y_m [Hz]";
  d.time = Range(30, 0, 30);
  d.freq = Range(40, 0, 10);
  for (double t : d.time) {
    std::vector<double> row;
    for (double f : d.freq) row.push_back(-60 + 60 * std::exp(-std::pow(f - (1 + 0.25 * t), 2)));
    d.db.push_back(row);
  }
  const std::string out = File("spec.png");
  // Viridis' dark end (-80..-60 dB) and its bright end (the ridge, 0 dB).
  ExpectDrawn(bistable::RenderSpectrogram(d, out), out, 900, 700, {"#fde725"}, 50);
}

TEST_F(Figures, PanelsShareAYRange) {
  // Two panels on one y range [-30, 40] mm: a 5 mm and a 25 mm sine. On the shared range the small one spans a
  // fifth of the large one's height; had the range been ignored, each panel would autoscale to its own curve
  // and both would fill their plots (checked below with the range off).
  auto figure = [](bool shared) {
    bistable::PanelPlot d;
    d.title = "panels";
    d.cols = 2;
    for (int p = 0; p < 2; ++p) {
      bistable::PanelPlot::Panel panel;
      panel.title = p ? "with" : "without";
      panel.x_label = "time t [s]";
      panel.y_label = "y [mm]";
      if (shared) panel.y_lo = -30, panel.y_hi = 40;
      bistable::PanelPlot::Series s{
          "", {}, {}, false, p ? "#2166ac" : "#d95f02"};  // no key: its line sample would count
      for (int i = 0; i < 500; ++i) s.x.push_back(0.05 * i), s.y.push_back((p ? 25 : 5) * std::sin(0.3 * i));
      panel.series.push_back(s);
      d.panels.push_back(panel);
    }
    return d;
  };
  auto span_ratio = [&](const std::string& png) {  // the small curve's height over the large one's
    const PngStats st = Stats(png, {"#d95f02", "#2166ac"}, true);
    if (st.rows.size() != 2) return -1.0;
    const auto small = st.rows.at("#d95f02"), large = st.rows.at("#2166ac");
    return static_cast<double>(small.second - small.first) / std::max(1, large.second - large.first);
  };
  const std::string out = File("panels.png"), own = File("panels_own.png");
  ExpectDrawn(bistable::RenderPanels(figure(true), out), out, 1040, 440, {"#2166ac", "#d95f02"}, 200);
  const double shared = span_ratio(out);
  EXPECT_GT(shared, 0.1);
  EXPECT_LT(shared, 0.35) << "10 mm of 70 against 50 of 70: about 0.2";
  ASSERT_TRUE(bistable::RenderPanels(figure(false), own).ok());
  EXPECT_GT(span_ratio(own), 0.6) << "each panel on its own range: both curves fill their plots";
}

// ---- without gnuplot: a real `bistable run` whose PATH has no gnuplot ------------------------------

TEST_F(Figures, RunWithoutGnuplotKeepsTheMapSaysWhatIsMissingAndSucceeds) {
  std::ofstream(File("spec.toml"))
      << "name = \"tiny\"\nmodel = \"standalone\"\n[axes]\nalpha = [0.2, 0.5]\nomega = [0.8, 1.2]\n"
         "[integration]\nt_end = 40\nt_keep = 20\n";
  fs::create_directories(File("bin"));  // a PATH with nothing in it
  const auto r = RunArgv({BISTABLE_CLI, "run", File("spec.toml"), "--data", File("data"), "--quiet", "--json"}, "",
                         {{"PATH", File("bin")}}, 120);
  EXPECT_EQ(r.signal, 0);
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const auto j = nlohmann::json::parse(r.out);
  ASSERT_EQ(j["files"].size(), 1u) << "the map only";
  const std::string map = j["files"][0];
  EXPECT_TRUE(fs::exists(fs::path(map).is_relative() ? fs::current_path() / map : fs::path(map)));
  EXPECT_NE(r.err.find("gnuplot not found"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("gnuplot-nox"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("--no-plots"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find(map), std::string::npos) << "names where the map is: " << r.err;
  EXPECT_EQ(j["warnings"].size(), 1u);
  size_t lines = 0;
  for (char ch : r.err) lines += ch == '\n';
  EXPECT_EQ(lines, 1u) << "one warning, not one per figure: " << r.err;
  // `reproduce` draws figures for a living: it refuses before computing anything.
  const auto rp =
      RunArgv({BISTABLE_CLI, "reproduce", "paper", "--quick", "--out", File("paper")}, "", {{"PATH", File("bin")}}, 60);
  EXPECT_EQ(rp.exit_code, 2) << rp.err;
  EXPECT_NE(rp.err.find("gnuplot not found"), std::string::npos) << rp.err;
  EXPECT_FALSE(fs::exists(File("paper/data"))) << "nothing computed";
}

}  // namespace
