// Loading measured records: the real Silverbox and harvester files, what DAQ exports write (each quirk
// read to the same numbers as the plain CSV), and bad CSVs named precisely.
#include <sys/stat.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>

#include <gtest/gtest.h>

#include "base/limits.h"
#include "identify/record.h"

namespace bistable {
namespace {

const std::string kData = BISTABLE_MEASURED_DIR;

// The measured files live beside the repository (../shared/data/measured, not redistributable here);
// a checkout elsewhere skips these tests and says why.
#define REQUIRE_MEASURED(file)                                          \
  if (!std::filesystem::exists(kData + "/" + file))                     \
  GTEST_SKIP() << "measured data not found at " << kData << "/" << file \
               << " (the repository's sibling ../shared/data/measured)"

TEST(Records, SilverboxLoadsAsOneUniformRecord) {
  REQUIRE_MEASURED("silverbox/silverbox_SNLS80mV.csv");
  ColumnMap c;
  c.input = "u";
  c.input_kind = InputKind::kForce;
  c.output = "y";
  c.output_kind = OutputKind::kAnalogue;
  auto r = LoadRecords(kData + "/silverbox/silverbox_SNLS80mV.csv", c);
  ASSERT_TRUE(r.ok()) << r.status().ToString();
  ASSERT_EQ(r->size(), 1u);
  EXPECT_EQ((*r)[0].t.size(), 131072u);
  EXPECT_NEAR(1.0 / (*r)[0].dt, 610.35, 0.01);  // fs = 10^7 / 2^14 Hz
}

TEST(Records, HarvesterScalesToSIAndSplitsTheSteadySineRecords) {
  REQUIRE_MEASURED("bistable-harvester/bistable_sym_steady_sine_64Hz.csv");
  ColumnMap c;
  c.input = "base_acc_g";
  c.input_kind = InputKind::kBaseAcceleration;
  c.input_scale = 9.81;  // g → m/s²
  c.output = "laser_V";
  c.output_kind = OutputKind::kVelocity;
  c.output_scale = 0.1;  // the authors' 100 mm/s per V
  auto one = LoadRecords(kData + "/bistable-harvester/bistable_sym_intrawell_left_6p5Hz.csv", c);
  ASSERT_TRUE(one.ok()) << one.status().ToString();
  ASSERT_EQ(one->size(), 1u);
  EXPECT_NEAR(1.0 / (*one)[0].dt, 2560, 1e-6 * 2560);
  EXPECT_NEAR((*one)[0].input[0], 0.161185 * 9.81, 1e-9);
  EXPECT_NEAR((*one)[0].output[0], -1.14233 * 0.1, 1e-9);
  c.group = {"freq_hz", "drive_mV"};
  auto steady = LoadRecords(kData + "/bistable-harvester/bistable_sym_steady_sine_64Hz.csv", c);
  ASSERT_TRUE(steady.ok()) << steady.status().ToString();
  ASSERT_EQ(steady->size(), 10u);
  for (const Record& r : *steady) {
    EXPECT_EQ(r.t.size(), 4096u);
    EXPECT_NEAR(1.0 / r.dt, 64, 2e-3);  // end times printed to 1 ms over 64 s: rate to ~1e-3 Hz
    ASSERT_EQ(r.group_values.size(), 2u);
  }
  EXPECT_EQ((*steady)[0].group_values, (std::vector<double>{6.3, 25}));
}

TEST(Records, BadFilesNameTheRowColumnAndBound) {
  const std::string dir = ::testing::TempDir();
  auto write = [&](const std::string& name, const std::string& text) {
    std::ofstream(dir + "/" + name) << text;
    return dir + "/" + name;
  };
  ColumnMap c;  // t, x0, x
  struct Case {
    std::string file, expect;
  };
  const Case cases[] = {
      {write("typo.csv", "t,x0,disp\n0,0,0\n0.1,0,0\n"), "(output): unknown column 'x'"},
      {write("typo2.csv", "t,base_disp,x\n0,0,0\n0.1,0,0\n"), "unknown column 'x0'; did you mean 'x'?"},
      {write("cell.csv", "t,x0,x\n0,0,0\n0.1,abc,0\n"), "row 3 column 'x0': 'abc' is not a finite number"},
      {write("nan.csv", "t,x0,x\n0,0,0\n0.1,0,nan\n"), "row 3 column 'x': 'nan' is not a finite number"},
      {write("short.csv", "t,x0,x\n0,0,0\n0.1,0\n"), "row 3: 2 cells, the header has 3"},
      {write("jitter.csv", "t,x0,x\n0,0,0\n0.1,0,0\n0.3,0,0\n0.4,0,0\n0.5,0,0\n"),
       "sampling is not uniform"},  // a dropped sample
      {write("empty.csv", "t,x0,x\n"), "no rows"},
      {dir + "/missing.csv", "cannot read data file"},
  };
  for (const Case& k : cases) {
    auto r = LoadRecords(k.file, c);
    ASSERT_FALSE(r.ok()) << k.file;
    EXPECT_NE(r.status().message().find(k.expect), std::string::npos) << k.file << ": " << r.status().ToString();
  }
}

// ---- what DAQ exports write ------------------------------------------------------------------------

// The plain file every quirky variant must read as: t, x0, x at 100 Hz, 200 rows.
struct Plain {
  std::vector<double> t, x0, x;
};

Plain PlainValues() {
  Plain p;
  for (int i = 0; i < 200; ++i) {
    p.t.push_back(i * 0.01);
    p.x0.push_back(0.001 * std::sin(i * 0.3));
    p.x.push_back(-0.0012 * std::sin(i * 0.3 - 0.2));
  }
  return p;
}

// The values printed with `digits` digits, each scaled by `scale`, cells joined by `sep`; `dec` replaces
// the decimal point, `lead` precedes each row and `end` ends it.
std::string Rows(const Plain& p, const std::string& sep, double t_scale = 1, double v_scale = 1, char dec = '.',
                 const std::string& end = "\n", const std::string& quote = "") {
  std::string out;
  for (size_t i = 0; i < p.t.size(); ++i) {
    char b[3][40];
    std::snprintf(b[0], sizeof b[0], "%.17g", p.t[i] * t_scale);
    std::snprintf(b[1], sizeof b[1], "%.17g", p.x0[i] * v_scale);
    std::snprintf(b[2], sizeof b[2], "%.17g", p.x[i] * v_scale);
    for (auto& cell : b)
      for (char* c = cell; *c; ++c)
        if (*c == '.') *c = dec;
    out += quote + b[0] + quote + sep + quote + b[1] + quote + sep + quote + b[2] + quote + end;
  }
  return out;
}

std::string WriteFile(const std::string& name, const std::string& text) {
  const std::string path = ::testing::TempDir() + "/" + name;
  std::ofstream(path, std::ios::binary) << text;
  return path;
}

// A FIFO, a directory, a missing file: refused at once with the reason. The check is made on the opened
// descriptor (a non-blocking open), so a FIFO without a writer neither blocks the open nor the read.
TEST(Records, NonRegularDataFilesAreRefusedWithoutBlocking) {
  const std::string dir = ::testing::TempDir() + "/nonregular";
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir + "/a_directory.csv");
  const std::string fifo = dir + "/fifo.csv";
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
  ColumnMap c;
  const auto t0 = std::chrono::steady_clock::now();
  for (const auto& [file, expect] :
       std::vector<std::pair<std::string, std::string>>{{fifo, "data file '" + fifo + "' is not a regular file"},
                                                        {dir + "/a_directory.csv", "is not a regular file"},
                                                        {dir + "/missing.csv", "no such file"},
                                                        {"/dev/zero", "data file '/dev/zero' is not a regular file"}}) {
    auto r = LoadRecords(file, c);
    ASSERT_FALSE(r.ok()) << file;
    EXPECT_NE(r.status().ToString().find(expect), std::string::npos) << r.status().ToString();
  }
  EXPECT_LT(std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count(), 5.0);
  std::filesystem::remove_all(dir);
}

TEST(Records, DaqQuirksReadAsThePlainCsv) {
  const Plain p = PlainValues();
  const std::string plain_text = "t,x0,x\n" + Rows(p, ",");
  const std::string bom = "\xef\xbb\xbf";
  // A row in the middle, for comments and blank lines between rows.
  const std::string rows = Rows(p, ",");
  const size_t mid = rows.find('\n', rows.size() / 2) + 1;
  struct Case {
    std::string name, text;
  };
  const Case cases[] = {
      {"quoted_header.csv", "\"t\",\"x0\",\"x\"\n" + Rows(p, ",")},
      {"quoted_cells.csv", "\"t\",\"x0\",\"x\"\n" + Rows(p, ",", 1, 1, '.', "\n", "\"")},
      {"spaces.csv", " t , x0 ,x \n" + Rows(p, " , ")},
      {"tab.tsv", "t\tx0\tx\n" + Rows(p, "\t")},
      {"semicolon.csv", "t;x0;x\n" + Rows(p, ";")},
      {"semicolon_decimal_comma.csv", "t;x0;x\n" + Rows(p, ";", 1, 1, ',')},
      {"tab_decimal_comma.tsv", "t\tx0\tx\n" + Rows(p, "\t", 1, 1, ',')},
      {"comments_and_blank_lines.csv", "# exported by a DAQ\n#channels: 3\n\nt,x0,x\n# data follow\n" +
                                           rows.substr(0, mid) + "\n   \n# a marker\n" + rows.substr(mid) +
                                           "\n# end\n"},
      {"units_si.csv", "t [s],x0 (m),x [m]\n" + Rows(p, ",")},
      {"units_scaled.csv", "t [ms],x0 (mm),x [\xc2\xb5m]\n" + Rows(p, ",", 1e3, 1e3)},
      {"crlf.csv", "t,x0,x\r\n" + Rows(p, ",", 1, 1, '.', "\r\n")},
      {"bom.csv", bom + "t,x0,x\n" + Rows(p, ",")},
      {"no_final_newline.csv", plain_text.substr(0, plain_text.size() - 1)},
      {"trailing_separator.csv", "t;x0;x;\n" + Rows(p, ";", 1, 1, ',', ";\n")},
      {"everything.csv", bom + "# DAQ export\r\n\r\n\"t [ms]\";\"x0 (mm)\";\"x (mm)\"\r\n# rows\r\n" +
                             Rows(p, ";", 1e3, 1e3, ',', "\r\n", "\"") + "# end\r\n"},
  };
  ColumnMap c;
  auto plain = LoadRecords(WriteFile("plain.csv", plain_text), c);
  ASSERT_TRUE(plain.ok()) << plain.status().ToString();
  ASSERT_EQ(plain->size(), 1u);
  const Record& want = (*plain)[0];
  ASSERT_EQ(want.t.size(), 200u);
  for (size_t i = 0; i < 200; ++i) ASSERT_EQ(want.input[i], p.x0[i]) << "%.17g round-trips";
  for (const Case& k : cases) {
    SCOPED_TRACE(k.name);
    // units_scaled's "x [µm]": its values were printed x 1e3 (as mm), so µm reads them 1000 times
    // smaller; that column is compared after its own factor.
    auto got = LoadRecords(WriteFile(k.name, k.text), c);
    ASSERT_TRUE(got.ok()) << got.status().ToString();
    ASSERT_EQ(got->size(), 1u);
    const Record& r = (*got)[0];
    EXPECT_EQ(r.name, k.name);
    ASSERT_EQ(r.t.size(), want.t.size());
    const double out_factor = k.name == "units_scaled.csv" ? 1e-3 : 1.0;
    for (size_t i = 0; i < r.t.size(); ++i) {
      EXPECT_DOUBLE_EQ(r.t[i], want.t[i]) << i;
      EXPECT_DOUBLE_EQ(r.input[i], want.input[i]) << i;
      EXPECT_DOUBLE_EQ(r.output[i], want.output[i] * out_factor) << i;
    }
    EXPECT_DOUBLE_EQ(r.dt, want.dt);
  }
}

TEST(Records, HeaderUnitsConvertOrAreReadAsTheScaleSays) {
  const Plain p = PlainValues();
  // Base acceleration in g (standard gravity), velocity output in mm/s.
  ColumnMap c;
  c.input = "a0";
  c.input_kind = InputKind::kBaseAcceleration;
  c.output = "v";
  c.output_kind = OutputKind::kVelocity;
  auto g = LoadRecords(WriteFile("g.csv", "t [s],a0 [g],v [mm/s]\n" + Rows(p, ",")), c);
  ASSERT_TRUE(g.ok()) << g.status().ToString();
  EXPECT_DOUBLE_EQ((*g)[0].input[7], p.x0[7] * 9.80665);
  EXPECT_DOUBLE_EQ((*g)[0].output[7], p.x[7] * 1e-3);
  // A unit that is no unit of the quantity (a laser's volts) is read as is, and the scale applies.
  c.output_scale = 0.1;
  auto volts = LoadRecords(WriteFile("volts.csv", "t,a0 [m/s^2],v [V]\n" + Rows(p, ",")), c);
  ASSERT_TRUE(volts.ok()) << volts.status().ToString();
  EXPECT_DOUBLE_EQ((*volts)[0].input[7], p.x0[7]);
  EXPECT_DOUBLE_EQ((*volts)[0].output[7], p.x[7] * 0.1);
  // The full header text names a column too (needed when two share a name).
  ColumnMap full;
  full.output = "x [m]";
  std::string text = "t,x0,x [m],x [V]\n";
  for (size_t i = 0; i < p.t.size(); ++i) text += std::to_string(p.t[i]) + ",0," + std::to_string(p.x[i]) + ",9\n";
  auto named = LoadRecords(WriteFile("two.csv", text), full);
  ASSERT_TRUE(named.ok()) << named.status().ToString();
  EXPECT_NE((*named)[0].output[7], 9.0);
}

TEST(Records, MalformedDaqFilesNameTheLineColumnAndBound) {
  const Plain p = PlainValues();
  const std::string rows = Rows(p, ",");
  ColumnMap c;
  ColumnMap scaled;
  scaled.input_scale = 0.001;
  std::string long_line(limits::kMaxDataLineBytes + 1, '1');
  struct Case {
    std::string name, text;
    ColumnMap columns;
    std::string expect;
  };
  const Case cases[] = {
      {"long_line.csv", "t,x0,x\n0,0,0\n" + long_line + "\n", c,
       "long_line.csv row 3: the line is longer than 65536 bytes (violates line length <= 65536)"},
      {"long_header.csv", long_line, c, "long_header.csv row 1: the line is longer than 65536 bytes"},
      {"no_newline_ever.csv", std::string(200000, 'x'), c, "row 1: the line is longer than 65536 bytes"},
      {"open_quote.csv", "t,x0,x\n0,0,0\n0.01,\"0,0\n", c,
       "open_quote.csv row 3 column 2: a quote is not closed on its line"},
      {"after_quote.csv", "\"t\"s,x0,x\n0,0,0\n", c, "row 1 (header) column 1: text after the closing quote"},
      {"no_separator.csv", "t x0 x\n0 0 0\n", c, "row 1 (header): no separator splits it"},
      {"tie.csv", "t,x0;x;y,z\n", c, "row 1 (header): it splits as often at ','"},
      {"numbers_first.csv", "# t,x0,x\n0,0,0\n0.01,0,0\n", c,
       "row 2: the first line that is not a comment holds numbers"},
      {"comments_only.csv", "# nothing\n\n# here\n", c, "comments_only.csv is empty (a header line is required)"},
      {"utf16.csv", std::string("\xff\xfet\0,\0x\0", 8), c, "utf16.csv is UTF-16 text; save it as UTF-8"},
      {"time_unit.csv", "t [samples],x0,x\n" + rows, c, "column 't [samples]' (time): unknown time unit 'samples'"},
      {"time_in_mm.csv", "t [mm],x0,x\n" + rows, c,
       "column 't [mm]' (time): 'mm' is a unit of length; a time column takes s, ms"},
      {"x_in_s.csv", "t,x0,x [s]\n" + rows, c,
       "column 'x [s]' (output, length): 's' is a unit of time; a length column takes m, cm, mm"},
      {"a_in_g_for_disp.csv", "t,x0 [g],x\n" + rows, c,
       "column 'x0 [g]' (input, length): 'g' is a unit of acceleration"},
      {"twice.csv", "t,x0 [mm],x\n" + rows, scaled,
       "column 'x0 [mm]' (input, length): the header gives the unit mm, converted to m; input_scale = 0.001 would "
       "convert it again"},
      {"ambiguous.csv", "t,x0,x [m],x [V]\n", c, "(output): columns 'x [m]' and 'x [V]' both match 'x'"},
      {"decimal_comma_in_csv.csv", "t,x0,x\n0,\"0,5\",0\n", c, "row 2 column 'x0': '0,5' is not a finite number"},
      {"thousands.csv", "t;x0;x\n0;1.234,5;0\n", c, "row 2 column 'x0': '1.234,5' is not a finite number"},
      {"control_bytes.csv", "t,x0,x\n0,\x1b[31m,0\n", c, "row 2 column 'x0': '\\x1b[31m' is not a finite number"},
      {"typo_with_units.csv", "t [s],x0 [m],pos [m]\n" + rows, c, "unknown column 'x'"},
      {"misspelt_unit.csv", "t,x0 [mmm],x\n" + rows, c,
       "column 'x0 [mmm]' (input, length): 'mmm' is no unit of length (m, cm, mm, um, \xc2\xb5m, \xce\xbcm, nm); to "
       "read the "
       "column as is, give input_scale"},
  };
  for (const Case& k : cases) {
    auto r = LoadRecords(WriteFile(k.name, k.text), k.columns);
    ASSERT_FALSE(r.ok()) << k.name;
    EXPECT_NE(r.status().message().find(k.expect), std::string::npos) << k.name << ": " << r.status().ToString();
  }
}

TEST(Records, MoreRowsThanTheBoundIsRefusedWithTheRowAndBound) {
  std::string text = "t,x0,x\n";
  text.reserve(16 * (limits::kMaxDataRows + 2));
  char b[32];
  for (long i = 0; i <= limits::kMaxDataRows; ++i) text.append(b, std::snprintf(b, sizeof b, "%ld,0,0\n", i));
  const std::string path = WriteFile("rows.csv", text);
  text.clear();
  text.shrink_to_fit();
  auto r = LoadRecords(path, ColumnMap{});
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.status().message().find("rows.csv row 4194306: more than 4194304 data rows (violates rows <= 4194304"),
            std::string::npos)
      << r.status().ToString();
  std::filesystem::remove(path);
}

}  // namespace
}  // namespace bistable
