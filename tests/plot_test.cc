// Every figure type, rendered by the installed gnuplot into a PNG and decoded (tests/png_stats.py,
// Debian's python3-pil): not blank, and the data's own colours are on the page (a figure whose data
// block gnuplot skipped has axes and a title but none of them). Small data, so the suite stays fast.
// Also: discrete codes keep "none found" apart, legends name only what is drawn (SVG text), and
// `bistable run` without gnuplot keeps the map, says what is missing and succeeds.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <functional>
#include <map>
#include <sstream>
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
  std::map<std::string, std::vector<int>> extent;  // with rows: each colour's bounding box {row0, row1, col0, col1}
  std::map<std::string, long> box;                 // with a box: the colours' pixels inside it
  long border_ink = -1;                            // non-background pixels within 2 px of the canvas edge
};

// Options: "--rows", "--box x0 y0 x1 y1" (one string), "--border" (2 px) are passed on to png_stats.py.
PngStats Stats(const std::string& png, const std::vector<std::string>& colours = {}, bool rows = false,
               const std::string& box = "") {
  std::vector<std::string> argv = {"/usr/bin/python3", BISTABLE_TESTS_DIR "/png_stats.py", "--border", "2"};
  if (rows) argv.push_back("--rows");
  if (!box.empty()) {
    argv.push_back("--box");
    std::istringstream in(box);
    for (std::string f; in >> f;) argv.push_back(f);
  }
  argv.push_back(png);
  argv.insert(argv.end(), colours.begin(), colours.end());
  const bistable_test::ExecResult r = RunArgv(argv);
  EXPECT_EQ(r.exit_code, 0) << r.err;
  PngStats s;
  if (r.exit_code != 0) return s;
  const auto j = nlohmann::json::parse(r.out);
  s.width = j["width"], s.height = j["height"], s.distinct = j["distinct"], s.non_background = j["non_background"];
  s.border_ink = j["border_ink"];
  for (const auto& [k, v] : j["colours"].items()) s.colours[k] = v.get<long>();
  if (j.contains("rows"))
    for (const auto& [k, v] : j["rows"].items())
      if (!v.is_null()) s.rows[k] = {v[0].get<int>(), v[1].get<int>()};
  if (j.contains("extent"))
    for (const auto& [k, v] : j["extent"].items())
      if (!v.is_null()) s.extent[k] = v.get<std::vector<int>>();
  if (j.contains("box"))
    for (const auto& [k, v] : j["box"].items()) s.box[k] = v.get<long>();
  return s;
}

// Rendered, the size asked, not blank, each of `data_colours` covers at least `min_pixels`, and nothing
// touches the canvas' edge (text or a legend cut by it: docs/figures.md, "no text outside the canvas").
void ExpectDrawn(const bistable::Status& st, const std::string& png, int width, int height,
                 const std::vector<std::string>& data_colours, long min_pixels = 200) {
  ASSERT_TRUE(st.ok()) << st.ToString();
  PngStats s = Stats(png, data_colours);
  EXPECT_EQ(s.width, width);
  EXPECT_EQ(s.height, height);
  EXPECT_GT(s.distinct, 20) << "a figure has anti-aliased text and lines";
  EXPECT_GT(s.non_background, 0.01);
  EXPECT_EQ(s.border_ink, 0) << "something is drawn on the canvas' edge (cut off): " << png;
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

// A term model's parameters (model = "terms", issue 42) as short symbols, so that a subtitle of eleven of them
// stays on the canvas.
TEST_F(Figures, TermModelParametersAreShortSymbolsAndTheirSubtitleStaysOnTheCanvas) {
  EXPECT_EQ(bistable::SymbolOf("main.stiffness_y3.k3"), "k_3");
  EXPECT_EQ(bistable::SymbolOf("main.linear.k_lin"), "k_{lin}");
  EXPECT_EQ(bistable::SymbolOf("res.friction.F_s"), "F_{s,r}");
  EXPECT_EQ(bistable::SymbolOf("res.viscous.c0"), "c_{0,r}");
  EXPECT_EQ(bistable::SymbolOf("res.linear.x"), "x_r");
  EXPECT_EQ(bistable::SymbolOf("other.thing_1.k"), "other.thing\\_1.k");  // not a term: literal
  bistable::PlotData d = Map("frf_db", 12);
  for (int i = 0; i < 144; ++i) d.values.push_back(i < 72 ? -20.0 : 20.0);
  const std::pair<const char*, const char*> kRig[] = {{"main.linear.k_lin", "N/m"},
                                                      {"main.stiffness_y3.k3", "N/m^3"},
                                                      {"main.viscous.c0", "N s/m"},
                                                      {"main.damping_y2.c2", "N s/m^3"},
                                                      {"main.friction.F_s", "N"},
                                                      {"main.friction.F_c", "N"},
                                                      {"res.linear.k_lin", "N/m"},
                                                      {"res.viscous.c0", "N s/m"},
                                                      {"res.damping_z2.c2", "N s/m^3"},
                                                      {"res.friction.F_s", "N"},
                                                      {"res.friction.F_c", "N"},
                                                      {"m_main", "kg"},
                                                      {"m_res", "kg"},
                                                      {"v_sp", "m/s"},
                                                      {"v_t", "m/s"}};
  for (const auto& [name, unit] : kRig) d.subtitle.push_back(bistable::ParameterItem(name, -1234.5678, unit));
  const std::string out = File("terms.png");
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

// Marks (`bistable map --mark`): a white disc ringed in black on every colour of a categorical map (the four
// motion codes side by side, a mark on each), labels beside their points and inside the canvas wherever the
// point sits (the drawn range's corners and edges, 80-character labels wrapped), labels as literal SVG text.
TEST_F(Figures, MarksReadOnEveryCodeColourAndTheirLabelsStayOnTheCanvas) {
  bistable::PlotData d = Map("motion", 12);
  for (int i = 0; i < 144; ++i) d.values.push_back(static_cast<double>(i % 12 / 3) - 1);  // x bands: -1, 0, 1, 2
  d.codes = bistable::MetricCodes("motion", d.values);
  ASSERT_EQ(d.codes.size(), 4u);
  std::vector<std::string> colours;
  for (const auto& c : d.codes) colours.push_back(c.colour);
  const auto [x0, x1] = bistable::HeatmapAxisRange(d.axis_values[1]);
  const auto [y0, y1] = bistable::HeatmapAxisRange(d.axis_values[0]);
  const double xc = 0.5 * (x0 + x1), yc = 0.5 * (y0 + y1);
  const std::string long_label = "run 12: 20 mm at 9.5 Hz, chaotic, wrapped wherever it sits on the plot area, ok!";
  ASSERT_EQ(long_label.size(), 80u);
  const std::string markup = "{/Symbol a} x^2 y_1 @m \"q\" `b`";
  bistable::PlotData plain = d;
  for (const auto& [x, y] : std::vector<std::pair<double, double>>{{x1, y1}, {x0, y1}, {x1, y0}, {xc, y0}})
    d.marks.push_back({x, y, long_label});
  d.marks.push_back({x0, y0, "run 3 at the corner: one line on its open side"});
  d.marks.push_back({xc, y1, markup});
  for (int k = 0; k < 4; ++k) d.marks.push_back({x0 + (x1 - x0) * (k + 0.5) / 4, yc, ""});  // one on each colour
  const std::string png = File("marks.png"), bare = File("bare.png");
  ExpectDrawn(bistable::RenderPlot(d, png), png, 900, 700, colours, 2000);
  ASSERT_TRUE(bistable::RenderPlot(plain, bare).ok());
  // The plot area spans x 100..750 px (the legend of codes right of it): band k's centre at 100 + 650 (k + 0.5) / 4.
  for (int k = 0; k < 4; ++k) {
    const double cx = (100 + 650 * (k + 0.5) / 4) / 900;
    const std::string box = std::to_string(cx - 0.03) + " 0.4 " + std::to_string(cx + 0.03) + " 0.6";
    PngStats with = Stats(png, {"#ffffff", "#000000", colours[k]}, false, box);
    PngStats without = Stats(bare, {"#ffffff", "#000000", colours[k]}, false, box);
    SCOPED_TRACE(d.codes[k].name);
    EXPECT_EQ(without.box["#ffffff"] + without.box["#000000"], 0) << "the bare map has only its colour there";
    EXPECT_GE(with.box["#ffffff"], 20) << "the white disc";
    EXPECT_GE(with.box["#000000"], 20) << "the black ring and centre";
    EXPECT_GE(with.box[colours[k]], 200) << "the map's colour around it";
  }
  const std::string svg = File("marks.svg");
  ASSERT_TRUE(bistable::RenderPlot(d, svg).ok());
  const std::string text = bistable_test::ReadText(svg);
  EXPECT_NE(text.find("<text>run 3 at the corner: one line on its open side</text>"), std::string::npos);
  for (const char* word : {"run 12:", "chaotic,", "wrapped", "area, ok!"})
    EXPECT_NE(text.find(word), std::string::npos) << word;
  EXPECT_NE(text.find("<text>{/Symbol a} x^2 y_1 @m \"q\" `b`</text>"), std::string::npos) << "not markup, literally";
  // Outside the drawn range: refused, naming the flag's field.
  d.marks = {{x1 + 0.01 * (x1 - x0), yc, "off"}};
  const bistable::Status off = bistable::RenderPlot(d, File("off.png"));
  ASSERT_FALSE(off.ok());
  EXPECT_EQ(off.field(), "mark");
}

// The widest labels a user may give (80 characters of W, @ or m: about 1200 px in one line) wrap onto as many
// lines as they need beside their point, wherever it sits, and stay on the canvas.
TEST_F(Figures, TheWidestMarkLabelsWrapAndStayOnTheCanvas) {
  bistable::PlotData d = Map("frf_db", 8);
  for (int i = 0; i < 64; ++i) d.values.push_back(i < 32 ? -10.0 : 10.0);
  const auto [x0, x1] = bistable::HeatmapAxisRange(d.axis_values[1]);
  const auto [y0, y1] = bistable::HeatmapAxisRange(d.axis_values[0]);
  const double xc = 0.5 * (x0 + x1), yc = 0.5 * (y0 + y1);
  const std::string w(80, 'W'), at = std::string(40, '@') + std::string(40, 'm'), spaced = "WWWW MMMM @@@@ mmmm ";
  std::string words;
  for (int i = 0; i < 4; ++i) words += spaced;
  d.marks = {{xc, yc, w},  {xc, y1, at}, {xc, y0, words}, {x0, yc, w},
             {x1, yc, at}, {x0, y0, w},  {x1, y1, words}, {0.5 * (xc + x1), 0.5 * (yc + y1), w}};
  const std::string png = File("wide.png");
  ExpectDrawn(bistable::RenderPlot(d, png), png, 900, 700, {"#2166ac", "#b2182b"}, 2000);
  const std::string pdf = File("wide.pdf");
  ASSERT_TRUE(bistable::RenderPlot(d, pdf).ok());
  EXPECT_GT(fs::file_size(pdf), 1000u);
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
  // Compact: one entry per name, one for the dashed unstable runs (a cascade of branches must not fill the canvas).
  for (const char* drawn : {">+well<", ">interwell<", ">unstable (dashed)<", ">fold<"})
    EXPECT_NE(text.find(drawn), std::string::npos) << drawn;
  EXPECT_EQ(text.find(", stable"), std::string::npos);
  // Nothing unstable drawn: no entry for it.
  d.branches = {plus};
  ASSERT_TRUE(bistable::RenderBranches(d, svg).ok());
  EXPECT_EQ(bistable_test::ReadText(svg).find("unstable"), std::string::npos) << "no unstable run is drawn";
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
  // The legend's samples are big enough to see: with one data point each (a dot of a few pixels), the legend's
  // dots cover > 40 px each.
  bistable::BifurcationData key = d;
  for (auto* v : {&key.x_up, &key.y_up, &key.x_down, &key.y_down}) v->resize(1);
  const std::string legend = File("bif_key.png");
  ASSERT_TRUE(bistable::RenderBifurcation(key, legend).ok());
  const PngStats ks = Stats(legend, {"#2166ac", "#b2182b"});
  EXPECT_GT(ks.colours.at("#2166ac"), 40);
  EXPECT_GT(ks.colours.at("#b2182b"), 40);
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
  // H1 is drawn only where the coherence reaches the threshold: with none anywhere, its line is gone (the
  // curve's colour keeps only rows 1 and 3), and the SVG says the threshold.
  const long with_h1 = Stats(out, {"#2166ac"}).colours.at("#2166ac");
  for (double& g : d.curves[0].coherence) g = 0.1;
  const std::string low = File("frf_low.png"), svg = File("frf.svg");
  ASSERT_TRUE(bistable::RenderChirpFrf(d, low).ok());
  EXPECT_LT(Stats(low, {"#2166ac"}).colours.at("#2166ac"), with_h1 * 0.8) << "H1 drawn where the coherence is 0.1";
  ASSERT_TRUE(bistable::RenderChirpFrf(d, svg).ok());
  EXPECT_NE(bistable_test::ReadText(svg).find("H1 where coh. >= 0.5"), std::string::npos);
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

// ---- map figures as `bistable run` and `map --format` draw them (MapFigure, docs/figures.md) --------------

// A map of `metric` over alpha (rows) x omega (columns) on [0.1, 3]^2 with values f(alpha, omega).
bistable::MapArray MapOf(const std::string& metric, const std::string& unit, int n,
                         const std::function<double(double, double)>& f) {
  bistable::MapArray m;
  m.metric = metric;
  m.unit = unit;
  m.axes = {{"alpha", Range(n, 0.1, 3)}, {"omega", Range(n, 0.1, 3)}};
  m.dims = {static_cast<size_t>(n), static_cast<size_t>(n)};
  m.dim_names = {"alpha", "omega"};
  for (double a : m.axes[0].values)
    for (double o : m.axes[1].values) m.values.push_back(f(a, o));
  return m;
}

// The coupled model's fixed parameters, as a spec gives them.
bistable::MapContext Coupled() {
  bistable::MapContext c;
  c.name = "fig test";
  c.id = "0123456789ab";
  c.fixed = {{"eta", 0.1, "c/(m_m omega_n)", ""},
             {"eta_r", 0.075, "c_r/(m_r omega_n)", ""},
             {"lambda", 0.8, "omega_r/omega_n", ""},
             {"phi", 2.0, "m_r/m_m", ""}};
  c.chaos_threshold = 0.01;
  return c;
}

// The plot area of a 900 x 700 map with a colour bar, as fractions (x0 y0 x1 y1, y from the top), a little inside.
constexpr const char* kPlotBox = "0.125 0.15 0.79 0.8";

// Every map figure: the metric's long name as the title (not its id, not the spec's name), the fixed
// parameters typeset in a subtitle, the name and id in the footer, the axes and the colour bar with
// symbols and units; the plot fills the canvas (before: a 440 x 490 square in 900 x 700).
TEST_F(Figures, FrfMapHasTitleSubtitleZeroDbContourAndFillsTheCanvas) {
  const auto m = MapOf("frf_db", "dB", 60, [](double, double o) { return 14 * (o - 1.55); });
  auto d = bistable::MapFigure(m, {}, Coupled());
  ASSERT_TRUE(d.ok()) << d.status().ToString();
  ASSERT_EQ(d->contours.size(), 1u);
  const std::string png = File("frf.png"), svg = File("frf.svg");
  ExpectDrawn(bistable::RenderPlot(*d, png), png, 900, 700, {"#2166ac", "#b2182b"}, 2000);
  // The 0 dB contour: black inside the plot area (the cells are blue, white and red; the tics point outward).
  const PngStats in = Stats(png, {"#000000", "#2166ac", "#b2182b"}, true, kPlotBox);
  EXPECT_GT(in.box.at("#000000"), 300) << "no 0 dB contour drawn inside the plot";
  // The map fills the canvas: the data's colours span more than half of it (the old square spanned a third).
  ASSERT_TRUE(in.extent.count("#2166ac") && in.extent.count("#b2182b"));
  const auto& blue = in.extent.at("#2166ac");
  const auto& red = in.extent.at("#b2182b");
  const double rows = std::max(blue[1], red[1]) - std::min(blue[0], red[0]);
  const double cols = std::max(blue[3], red[3]) - std::min(blue[2], red[2]);
  EXPECT_GT(rows * cols / (900.0 * 700.0), 0.45) << rows << " x " << cols << " px of data in 900 x 700";
  // Without the crossing, no contour and no legend entry.
  auto flat = bistable::MapFigure(MapOf("frf_db", "dB", 60, [](double, double o) { return 5 + o; }), {}, Coupled());
  ASSERT_TRUE(flat.ok());
  const std::string none = File("flat.png");
  ASSERT_TRUE(bistable::RenderPlot(*flat, none).ok());
  EXPECT_LT(Stats(none, {"#000000"}, false, kPlotBox).box.at("#000000"), 20);
  ASSERT_TRUE(bistable::RenderPlot(*d, svg).ok());
  const std::string text = bistable_test::ReadText(svg);
  for (const char* want : {"Frequency response of the main mass", "FRF = 0 dB", "\u03b7 = 0.1", "0.075", "\u03bb = 0.8",
                           "\u03c6 = 2", "fig test", "sweep 0123456789ab", "\u03b1 = A", "\u03a9 = \u03c9", "[dB]"})
    EXPECT_NE(text.find(want), std::string::npos) << want;
  for (const char* never : {"frf_db", "fig test: ", "[1]"}) EXPECT_EQ(text.find(never), std::string::npos) << never;
}

TEST_F(Figures, LleMapMarksTheChaosThreshold) {
  const auto m = MapOf("lle", "1/tau", 50, [](double a, double) { return 0.1 * (a - 1.55); });
  auto d = bistable::MapFigure(m, {}, Coupled());
  ASSERT_TRUE(d.ok());
  const std::string png = File("lle.png"), svg = File("lle.svg");
  ExpectDrawn(bistable::RenderPlot(*d, png), png, 900, 700, {"#2166ac", "#b2182b"}, 2000);
  EXPECT_GT(Stats(png, {"#000000"}, false, kPlotBox).box.at("#000000"), 100) << "no threshold line";
  ASSERT_TRUE(bistable::RenderPlot(*d, svg).ok());
  const std::string text = bistable_test::ReadText(svg);
  for (const char* want : {"Largest Lyapunov exponent", "chaos threshold LLE = 0.01", "LLE [1/\u03c4]"})
    EXPECT_NE(text.find(want), std::string::npos) << want;
  EXPECT_EQ(text.find("1/tau"), std::string::npos) << "the unit in ASCII";
}

// Integer codes: a legend of flat colours with names, no continuous colour bar (no tick at 2.5, no "[1]"),
// "none found" grey; periods beyond the 11th value share one class.
TEST_F(Figures, PeriodMapIsDiscreteWithNoneFoundGrey) {
  const auto m = MapOf("period", "forcing periods", 40, [](double a, double o) {
    return std::floor(std::fmod(a * 7 + o * 3, 17.0));  // 0 .. 16: more than 12 values
  });
  auto d = bistable::MapFigure(m, {}, Coupled());
  ASSERT_TRUE(d.ok());
  ASSERT_EQ(d->codes.size(), 12u);
  EXPECT_EQ(d->codes.front().name, "none found");
  EXPECT_TRUE(d->codes.back().at_least);
  const std::string png = File("period.png"), svg = File("period.svg");
  ExpectDrawn(bistable::RenderPlot(*d, png), png, 900, 700, {"#bdbdbd", "#1b9e77", "#444444"}, 500);
  ASSERT_TRUE(bistable::RenderPlot(*d, svg).ok());
  const std::string text = bistable_test::ReadText(svg);
  for (const char* want : {">none found<", ">1<", ">10<", "\u2265 11", "Stroboscopic period"})
    EXPECT_NE(text.find(want), std::string::npos) << want;
  for (const char* never : {">0.5<", ">2.5<", "[1]", ">16<"}) EXPECT_EQ(text.find(never), std::string::npos) << never;
  // A refinement level is a code too: by number, never "[1]".
  auto levels = bistable::MapFigure(MapOf("refine_level", "1", 20, [](double a, double) { return a < 1 ? 0 : 2; }), {},
                                    Coupled());
  ASSERT_TRUE(levels.ok());
  ASSERT_EQ(levels->codes.size(), 2u);
  const std::string lsvg = File("levels.svg");
  ASSERT_TRUE(bistable::RenderPlot(*levels, lsvg).ok());
  EXPECT_EQ(bistable_test::ReadText(lsvg).find("[1]"), std::string::npos);
}

// EDR colour bars stop at 100 % and the figure says which values pass it and why.
TEST_F(Figures, EdrClippingIsSaid) {
  const auto m = MapOf("edr_t", "%", 30, [](double a, double o) { return std::min(102.0, 40 * a + 10 * o); });
  auto d = bistable::MapFigure(m, {}, Coupled());
  ASSERT_TRUE(d.ok());
  const std::string png = File("edr.png"), svg = File("edr.svg");
  ExpectDrawn(bistable::RenderPlot(*d, png), png, 900, 700, {"#fde725"}, 2000);
  ASSERT_TRUE(bistable::RenderPlot(*d, svg).ok());
  const std::string text = bistable_test::ReadText(svg);
  for (const char* want : {"values above 100 %", "up to 102 %", "stored energy", "Total energy dissipation ratio"})
    EXPECT_NE(text.find(want), std::string::npos) << want;
}

// Basin maps: attractors named in words with their basin fractions; axes with symbols and units.
TEST_F(Figures, BasinLegendNamesAttractorsWithFractions) {
  bistable::MapArray m;
  m.metric = "attractor";
  m.unit = "code";
  m.axes = {{"vm0", Range(40, -2, 2)}, {"ym0", Range(40, -2, 2)}};
  m.dims = {40, 40};
  m.dim_names = {"vm0", "ym0"};
  m.categories = {{0, "A0_P1_-well_y-1.286_v-0.361"}, {1, "A1_P1_+well_y0.418_v-0.163"}};
  for (int i = 0; i < 40; ++i)
    for (int j = 0; j < 40; ++j) m.values.push_back(j < 30 ? 0 : 1);  // 75 % and 25 %
  bistable::MapContext c;
  c.fixed = {{"alpha", 0.1389, "A0/delta_s", ""}, {"omega", 1.2, "omega0/omega_n", ""}, {"eta", 0.3, "", ""}};
  auto d = bistable::MapFigure(m, {}, c);
  ASSERT_TRUE(d.ok());
  const std::string png = File("basins.png"), svg = File("basins.svg");
  ExpectDrawn(bistable::RenderPlot(*d, png), png, 900, 700, {"#1b9e77", "#d95f02"}, 2000);
  ASSERT_TRUE(bistable::RenderPlot(*d, svg).ok());
  const std::string text = bistable_test::ReadText(svg);
  for (const char* want : {"period-1, -well (75.0 %)", "period-1, +well (25.0 %)", "Basins of attraction", "(0) [",
                           "\u03b4", "\u03a9 = 1.2"})
    EXPECT_NE(text.find(want), std::string::npos) << want;
  for (const char* never : {"A1 P1", "ym0", "vm0"}) EXPECT_EQ(text.find(never), std::string::npos) << never;
  const auto shares = bistable::BasinShares(m);
  ASSERT_EQ(shares.size(), 2u);
  EXPECT_EQ(shares[0].name, "period-1, -well");
  EXPECT_DOUBLE_EQ(shares[0].fraction, 0.75);
}

// A 1601 x 1601 map draws from at most 600 values per axis, fast, and says so.
TEST_F(Figures, BigMapsAreDecimatedForDrawing) {
  const auto m =
      MapOf("lle", "1/tau", 1601, [](double a, double o) { return 0.05 * std::sin(3 * a) * std::cos(2 * o); });
  auto d = bistable::MapFigure(m, {}, Coupled());
  ASSERT_TRUE(d.ok());
  const std::string svg = File("big.svg"), png = File("big.png");
  const auto t0 = std::chrono::steady_clock::now();
  ExpectDrawn(bistable::RenderPlot(*d, png), png, 900, 700, {"#b2182b"}, 1000);
  EXPECT_LT(std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count(), 20.0);
  ASSERT_TRUE(bistable::RenderPlot(*d, svg).ok());
  EXPECT_NE(bistable_test::ReadText(svg).find("drawn from 535 x 535 of the 1601 x 1601 grid values"),
            std::string::npos);
}

// Vector output: `run --plot-format pdf` and `map --format pdf` go through RenderPlot's pdf terminal.
TEST_F(Figures, MapsRenderAsPdfAndSvg) {
  auto d =
      bistable::MapFigure(MapOf("motion", "code", 10, [](double a, double) { return a < 1.5 ? 0 : 1; }), {}, Coupled());
  ASSERT_TRUE(d.ok());
  const std::string pdf = File("m.pdf");
  ASSERT_TRUE(bistable::RenderPlot(*d, pdf).ok());
  EXPECT_EQ(bistable_test::ReadText(pdf).rfind("%PDF", 0), 0u);
  EXPECT_FALSE(bistable::RenderPlot(*d, File("m.eps"), "eps").ok());
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
