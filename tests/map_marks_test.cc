// Record markers of `bistable map --mark X,Y,LABEL` / `--marks FILE.csv` (client/map_marks.h), in process:
// parsing, the label rules (printable UTF-8, at most 80 characters), the count bound, the file's header,
// comments and line ends, and the range check against the figure's axes (X horizontal, Y vertical).
// tests/hostile_cli_test.cc runs the same through the CLI with labels that try to reach gnuplot as code.
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "base/limits.h"
#include "client/map_marks.h"
#include "client/plot.h"
#include "tests/process_util.h"

namespace {

namespace fs = std::filesystem;
using bistable::MapMark;
using bistable::ParseMark;
using bistable::ParseMarks;

// The message of a refused mark (empty when it was accepted).
std::string Refusal(const std::string& text) {
  auto m = ParseMarks({text}, "");
  if (m.ok()) return "";
  EXPECT_EQ(m.status().code(), bistable::Status::Code::kInvalidArgument);
  EXPECT_EQ(m.status().field(), "mark");
  return m.status().message();
}

TEST(MapMarks, XYAndALabelThatMayHoldCommasAndCsvQuotes) {
  auto m = ParseMark(" 1.2 , 0.5 , run 3, 20 mm: chaotic ", "mark", "o");
  ASSERT_TRUE(m.ok()) << m.status().ToString();
  EXPECT_EQ(m->x, 1.2);
  EXPECT_EQ(m->y, 0.5);
  EXPECT_EQ(m->label, "run 3, 20 mm: chaotic");
  EXPECT_EQ(m->field, "mark");
  m = ParseMark("-1e-3,+2,\"say \"\"hi\"\", then go\"", "marks", "o");
  ASSERT_TRUE(m.ok()) << m.status().ToString();
  EXPECT_EQ(m->x, -1e-3);
  EXPECT_EQ(m->y, 2);
  EXPECT_EQ(m->label, "say \"hi\", then go");
  m = ParseMark("1,2,", "mark", "o");
  ASSERT_TRUE(m.ok()) << "an empty label draws the point alone";
  EXPECT_EQ(m->label, "");
  // Text that means something to gnuplot or a shell is a label like any other (GnuplotString makes it text).
  for (const std::string label : {"q\"; system(\"touch pwned\") #", "`touch pwned` $(x) @m", "{/Symbol a} x^2 \\ '",
                                  "\xce\xb1 = 0.5, caf\xc3\xa9 \xe2\x9c\x93"}) {
    m = ParseMark("1,2," + label, "mark", "o");
    ASSERT_TRUE(m.ok()) << label << ": " << m.status().ToString();
    EXPECT_EQ(m->label, label);
  }
}

TEST(MapMarks, NumbersMustBeFiniteAndThereMustBeThreeFields) {
  EXPECT_NE(Refusal("1,2").find("violates X,Y,LABEL"), std::string::npos) << Refusal("1,2");
  EXPECT_NE(Refusal("12").find("violates X,Y,LABEL"), std::string::npos);
  EXPECT_NE(Refusal("nan,2,A").find("X = 'nan' violates X a finite number"), std::string::npos) << Refusal("nan,2,A");
  EXPECT_NE(Refusal("1,inf,A").find("Y = 'inf' violates Y a finite number"), std::string::npos);
  EXPECT_NE(Refusal("1,1e999,A").find("Y = '1e999' violates"), std::string::npos);
  EXPECT_NE(Refusal(",2,A").find("X = '' violates"), std::string::npos);
  EXPECT_NE(Refusal("1 2,2,A").find("X = '1 2' violates"), std::string::npos);
  EXPECT_NE(Refusal("1x,2,A").find("X = '1x' violates"), std::string::npos);
  EXPECT_NE(Refusal(std::string("1\0x", 3) + ",2,A").find("violates X a finite number"), std::string::npos)
      << "text after a NUL is not ignored";
}

TEST(MapMarks, LabelsAreOneLineOfPrintableUtf8OfAtMost80Characters) {
  EXPECT_EQ(Refusal("1,2," + std::string(80, 'x')), "");
  EXPECT_EQ(Refusal("1,2," + std::string(80, 'x') + "   "), "") << "trailing spaces are dropped";
  std::string alphas;
  for (int i = 0; i < 80; ++i) alphas += "\xce\xb1";  // 160 bytes, 80 characters
  EXPECT_EQ(Refusal("1,2," + alphas), "");
  EXPECT_NE(Refusal("1,2," + std::string(81, 'x')).find("longer than 80 characters (violates label <= 80 characters)"),
            std::string::npos);
  EXPECT_NE(Refusal("1,2," + alphas + "b").find("violates label <= 80 characters"), std::string::npos);
  EXPECT_NE(Refusal("1,2," + std::string(1 << 20, 'x')).find("violates label <= 80"), std::string::npos);
  const struct {
    std::string label, says;
  } bad[] = {
      {"a\nset output '|touch pwned'", "character 2 of the label is U+000A"},
      {"a\rb", "U+000D"},
      {"tab\there", "character 4 of the label is U+0009"},
      {"del\x7f", "U+007F"},
      {"esc\x1b[2J", "U+001B"},
      {"c1 \xc2\x9b", "U+009B"},
      {"rtl \xe2\x80\xae evil", "U+202E"},
      {"ls \xe2\x80\xa8 x", "U+2028"},
      {"bom \xef\xbb\xbf", "U+FEFF"},
      {"bad \xff byte", "character 5 of the label is not UTF-8"},
      {"overlong \xc0\xaf", "is not UTF-8"},
      {"surrogate \xed\xa0\x80", "is not UTF-8"},
      {"cut \xce", "is not UTF-8"},
  };
  for (const auto& b : bad) {
    const std::string why = Refusal("1,2," + b.label);
    EXPECT_NE(why.find(b.says), std::string::npos) << "label '" << b.label << "': " << why;
    EXPECT_NE(why.find("violates label"), std::string::npos) << why;
    // The message shows the mark without its control bytes.
    EXPECT_EQ(why.find('\n'), std::string::npos);
    EXPECT_EQ(why.find('\x1b'), std::string::npos);
  }
}

class MarksFile : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = bistable_test::FreshDir("marks", ::testing::UnitTest::GetInstance()->current_test_info()->name());
  }
  void TearDown() override {
    if (!HasFailure()) fs::remove_all(dir_);
  }
  std::string Write(const std::string& name, const std::string& text) {
    const std::string path = (fs::path(dir_) / name).string();
    std::ofstream(path, std::ios::binary) << text;
    return path;
  }
  std::string dir_;
};

TEST_F(MarksFile, HeaderCommentsBlankLinesCrlfAndAByteOrderMark) {
  const std::string path = Write("m.csv",
                                 "\xef\xbb\xbf# measured 2024-05-02\r\n X , y , Label \r\n\r\n0.8,0.5,A: intrawell\r\n"
                                 "  # a comment\n1.1, 0.9 ,\"B, run #2\"\n   \n1.0,0.7,C\n");
  auto marks = ParseMarks({"0.9,0.6,first"}, path);
  ASSERT_TRUE(marks.ok()) << marks.status().ToString();
  ASSERT_EQ(marks->size(), 4u);
  EXPECT_EQ((*marks)[0].label, "first");
  EXPECT_EQ((*marks)[0].field, "mark");
  EXPECT_EQ((*marks)[1].label, "A: intrawell");
  EXPECT_EQ((*marks)[1].field, "marks");
  EXPECT_EQ((*marks)[2].x, 1.1);
  EXPECT_EQ((*marks)[2].label, "B, run #2");
  EXPECT_EQ((*marks)[3].label, "C");
  EXPECT_NE((*marks)[3].origin.find("line 8"), std::string::npos) << (*marks)[3].origin;
}

TEST_F(MarksFile, ABadRowIsNamedByItsLine) {
  const std::string path = Write("bad.csv", "x,y,label\n1,2,ok\n\n1,abc,no\n");
  auto marks = ParseMarks({}, path);
  ASSERT_FALSE(marks.ok());
  EXPECT_EQ(marks.status().field(), "marks");
  EXPECT_NE(marks.status().message().find("bad.csv' line 4: Y = 'abc' violates"), std::string::npos)
      << marks.status().ToString();
  // A header anywhere but first is a row like any other.
  marks = ParseMarks({}, Write("late.csv", "1,2,a\nx,y,label\n"));
  ASSERT_FALSE(marks.ok());
  EXPECT_NE(marks.status().message().find("line 2: X = 'x' violates"), std::string::npos) << marks.status().ToString();
}

TEST_F(MarksFile, AtMost200MarksWithBothFlagsTogether) {
  std::string rows;
  for (int i = 0; i < 200; ++i) rows += "1,2,m" + std::to_string(i) + "\n";
  auto marks = ParseMarks({}, Write("200.csv", rows));
  ASSERT_TRUE(marks.ok()) << marks.status().ToString();
  EXPECT_EQ(marks->size(), size_t{bistable::limits::kMaxMapMarks});
  marks = ParseMarks({"1,2,one more"}, Write("200b.csv", rows));
  ASSERT_FALSE(marks.ok());
  EXPECT_EQ(marks.status().field(), "marks");
  EXPECT_NE(marks.status().message().find("more than 200 marks"), std::string::npos);
  EXPECT_NE(marks.status().message().find("violate marks <= 200"), std::string::npos) << marks.status().ToString();
  const std::vector<std::string> many(201, "1,2,x");
  marks = ParseMarks(many, "");
  ASSERT_FALSE(marks.ok());
  EXPECT_EQ(marks.status().field(), "mark");
  EXPECT_NE(marks.status().message().find("violate marks <= 200"), std::string::npos);
}

TEST_F(MarksFile, MissingBigOrNotARegularFileIsRefusedNamingMarks) {
  for (const std::string& path :
       {(fs::path(dir_) / "none.csv").string(), dir_, Write("big.csv", std::string((1 << 20) + 1, '#'))}) {
    auto marks = ParseMarks({}, path);
    ASSERT_FALSE(marks.ok()) << path;
    EXPECT_EQ(marks.status().field(), "marks") << marks.status().ToString();
  }
}

bistable::PlotData Heatmap(int n_alpha, int n_omega) {
  bistable::PlotData d;
  d.metric = "motion";
  d.axis_names = {"alpha", "omega"};
  d.axis_units = {"A0/delta_s", "omega0/omega_n"};
  d.axis_values.resize(2);
  for (int i = 0; i < n_alpha; ++i) d.axis_values[0].push_back(0.5 + 0.5 * i);
  for (int j = 0; j < n_omega; ++j) d.axis_values[1].push_back(0.8 + 0.4 * j);
  d.values.assign(static_cast<size_t>(n_alpha * n_omega), 0.0);
  return d;
}

MapMark Mark(double x, double y, const std::string& label = "m") {
  return MapMark{x, y, label, "mark", "--mark '" + std::to_string(x) + "," + std::to_string(y) + "," + label + "'"};
}

// X is on the horizontal axis (the second free axis, omega), Y on the vertical (alpha); the drawn range is
// the grid and half a grid step beyond each end.
TEST(MapMarks, InsideTheDrawnRangeOnlyXHorizontalYVertical) {
  bistable::PlotData d = Heatmap(3, 2);  // alpha 0.5, 1, 1.5 (drawn 0.25..1.75); omega 0.8, 1.2 (drawn 0.6..1.4)
  const auto [x0, x1] = bistable::HeatmapAxisRange(d.axis_values[1]);
  EXPECT_DOUBLE_EQ(x0, 0.6);
  EXPECT_DOUBLE_EQ(x1, 1.4);
  ASSERT_TRUE(bistable::AddMarks({Mark(0.6, 0.25), Mark(1.4, 1.75), Mark(1.0, 1.0)}, &d).ok());
  ASSERT_EQ(d.marks.size(), 3u);
  EXPECT_EQ(d.marks[1].x, 1.4);
  EXPECT_EQ(d.marks[1].y, 1.75);
  bistable::Status st = bistable::AddMarks({Mark(1.5, 1.0, "far")}, &d);
  ASSERT_FALSE(st.ok());
  EXPECT_EQ(st.field(), "mark");
  EXPECT_NE(st.message().find("X = 1.5 is outside the figure's horizontal axis omega, drawn from 0.6 to 1.4 (its "
                              "grid values 0.8 to 1.2 and half a grid step beyond); X is on the horizontal axis "
                              "(omega), Y on the vertical (alpha)"),
            std::string::npos)
      << st.ToString();
  st = bistable::AddMarks({Mark(1.0, 0.2)}, &d);
  ASSERT_FALSE(st.ok());
  EXPECT_NE(st.message().find("Y = 0.2 is outside the figure's vertical axis alpha, drawn from 0.25 to 1.75"),
            std::string::npos)
      << st.ToString();
  // Swapped coordinates (alpha given as X) are caught when they leave the range.
  EXPECT_FALSE(bistable::AddMarks({Mark(1.5, 0.8)}, &d).ok());
}

TEST(MapMarks, ACurveTakesNoMarks) {
  bistable::PlotData d = Heatmap(3, 2);
  d.axis_names = {"omega"}, d.axis_units = {"omega0/omega_n"}, d.axis_values = {{0.8, 1.2}}, d.values = {0, 1};
  const bistable::Status st = bistable::AddMarks({Mark(1.0, 1.0)}, &d);
  ASSERT_FALSE(st.ok());
  EXPECT_EQ(st.field(), "mark");
  EXPECT_NE(st.message().find("--mark draws on a heatmap over two free axes; this figure has 1 (omega)"),
            std::string::npos)
      << st.ToString();
  // And the renderer refuses marks on a curve too.
  d.marks = {{1.0, 1.0, "m"}};
  const bistable::Status drawn = bistable::RenderPlot(d, "/nonexistent/x.svg");
  ASSERT_FALSE(drawn.ok());
  EXPECT_EQ(drawn.field(), "mark");
}

}  // namespace
