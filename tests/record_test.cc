// Loading measured records: the real Silverbox and harvester files, and bad CSVs named precisely.
#include <cmath>
#include <filesystem>
#include <fstream>

#include <gtest/gtest.h>

#include "identify/record.h"

namespace bistable {
namespace {

const std::string kData = BISTABLE_MEASURED_DIR;

// The measured files live beside the repository (../shared/data/measured, not redistributable here);
// a checkout elsewhere skips these tests and says why.
#define REQUIRE_MEASURED(file)                                                                       \
  if (!std::filesystem::exists(kData + "/" + file))                                                  \
  GTEST_SKIP() << "measured data not found at " << kData << "/" << file                               \
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
  c.input_scale = 9.81;   // g → m/s²
  c.output = "laser_V";
  c.output_kind = OutputKind::kVelocity;
  c.output_scale = 0.1;   // the authors' 100 mm/s per V
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
      {write("jitter.csv", "t,x0,x\n0,0,0\n0.1,0,0\n0.3,0,0\n0.4,0,0\n0.5,0,0\n"), "sampling is not uniform"},  // a dropped sample
      {write("empty.csv", "t,x0,x\n"), "no rows"},
      {dir + "/missing.csv", "cannot read data file"},
  };
  for (const Case& k : cases) {
    auto r = LoadRecords(k.file, c);
    ASSERT_FALSE(r.ok()) << k.file;
    EXPECT_NE(r.status().message().find(k.expect), std::string::npos) << k.file << ": " << r.status().ToString();
  }
}

}  // namespace
}  // namespace bistable
