// End-to-end: `bistable run | sweeps | map | query` as real processes on real files — JSON shapes
// (categories by name, integers, ISO times), `map --out -`,
// h5py reading the map, Ctrl-C and kill -9 followed by a resume that gives a bit-identical map.
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <set>
#include <sstream>
#include <thread>

#include <gtest/gtest.h>

#include <nlohmann/json.hpp>
#include "tests/map_compare.h"
#include "tests/process_util.h"

#include "base/iso_time.h"
#include "engine/metric_catalog.h"
#include "storage/index_db.h"
#include "storage/map_file.h"
#include "tests/iso_time_parse.h"

namespace {

namespace fs = std::filesystem;

using bistable_test::Bistable;
using bistable_test::ProcessResult;

std::string Dir(const std::string& name) { return bistable_test::FreshDir("bistable_cli", name); }

std::string WriteSpec(const std::string& dir, const std::string& text) {
  const std::string path = dir + "/spec.toml";
  std::ofstream(path) << text;
  return path;
}

constexpr const char* kGrid = R"(
name = "cli test"
model = "coupled"
[axes]
alpha = { linspace = [0.2, 2.0, 6] }
omega = { linspace = [0.4, 2.4, 5] }
)";

TEST(CliSweep, RunMapQueryAndSweepsHaveTheirJsonShapes) {
  const std::string dir = Dir("json");
  const std::string spec = WriteSpec(dir, kGrid);
  const ProcessResult run = Bistable("run " + spec + " --data " + dir + "/data --json");
  ASSERT_EQ(run.exit_code, 0) << run.err;
  const auto j = nlohmann::json::parse(run.out);
  for (const char* k : {"id", "data", "files", "points", "seconds"}) EXPECT_TRUE(j.contains(k)) << k;
  EXPECT_EQ(j["points"], 30);
  const std::string id = j["id"];
  const std::string h5 = j["files"][0];
  EXPECT_TRUE(fs::exists(h5));
  for (size_t i = 1; i < j["files"].size(); ++i) EXPECT_GT(fs::file_size(j["files"][i].get<std::string>()), 1000u);

  // h5py (Debian's python3-h5py) opens it with the obvious shapes.
  const int rc =
      std::system(("/usr/bin/python3 " BISTABLE_TESTS_DIR "/h5py_check.py " + h5 + " 6 5 > /dev/null").c_str());
  EXPECT_EQ(rc, 0) << "h5py_check.py failed on " << h5;

  const ProcessResult map = Bistable("map " + id + " --metric frf_db --format json --data " + dir + "/data");
  ASSERT_EQ(map.exit_code, 0) << map.err;
  const auto m = nlohmann::json::parse(map.out);
  EXPECT_EQ(m["metric"], "frf_db");
  EXPECT_EQ(m["axes"]["alpha"].size(), 6u);
  EXPECT_EQ(m["axes"]["omega"].size(), 5u);
  EXPECT_TRUE(m["fixed"].is_object());
  ASSERT_EQ(m["values"].size(), 6u);     // nested lists in axis order: alpha rows ...
  EXPECT_EQ(m["values"][0].size(), 5u);  // ... of omega columns

  const ProcessResult curve = Bistable("map " + id + " --metric lle --at alpha=2 --format csv --data " + dir + "/data");
  ASSERT_EQ(curve.exit_code, 0) << curve.err;
  EXPECT_EQ(curve.out.substr(0, curve.out.find('\n')), "omega,lle");
  EXPECT_EQ(std::count(curve.out.begin(), curve.out.end(), '\n'), 6);

  const ProcessResult png =
      Bistable("map " + id + " --metric motion --format png --out " + dir + "/m.png --data " + dir + "/data");
  ASSERT_EQ(png.exit_code, 0) << png.err;
  EXPECT_GT(fs::file_size(dir + "/m.png"), 1000u);

  const ProcessResult q =
      Bistable("query " + id + " \"frf_db < 0 or motion == chaotic\" --json --data " + dir + "/data");
  ASSERT_EQ(q.exit_code, 0) << q.err;
  const auto qj = nlohmann::json::parse(q.out);
  for (const char* k : {"count", "total", "fraction", "area_fraction", "points"}) EXPECT_TRUE(qj.contains(k)) << k;
  EXPECT_EQ(qj["total"], 30);
  EXPECT_EQ(qj["points"].size(), qj["count"].get<size_t>());
  EXPECT_EQ(qj["truncated"], false);
  ASSERT_GE(qj["count"].get<int>(), 3) << q.out;

  // --json --limit N: the first N matches, count still every match, and truncated says the list was cut.
  const ProcessResult q2 =
      Bistable("query " + id + " \"frf_db < 0 or motion == chaotic\" --json --limit 2 --data " + dir + "/data");
  ASSERT_EQ(q2.exit_code, 0) << q2.err;
  const auto q2j = nlohmann::json::parse(q2.out);
  EXPECT_EQ(q2j["points"].size(), 2u);
  EXPECT_EQ(q2j["points"][0], qj["points"][0]);
  EXPECT_EQ(q2j["count"], qj["count"]);
  EXPECT_EQ(q2j["truncated"], true);
  const ProcessResult q_all = Bistable("query " + id + " \"frf_db < 0 or motion == chaotic\" --json --limit " +
                                       std::to_string(qj["count"].get<int>()) + " --data " + dir + "/data");
  ASSERT_EQ(q_all.exit_code, 0) << q_all.err;
  EXPECT_EQ(nlohmann::json::parse(q_all.out)["truncated"], false);
  // The text output keeps its own default (20) and says how many more there are.
  const ProcessResult qt =
      Bistable("query " + id + " \"frf_db < 0 or motion == chaotic\" --limit 1 --data " + dir + "/data");
  ASSERT_EQ(qt.exit_code, 0) << qt.err;
  EXPECT_NE(qt.out.find(std::to_string(qj["count"].get<int>() - 1) + " more; --json lists all"), std::string::npos)
      << qt.out;
  // Out of bounds: refused, naming --limit and its bounds (0 with --json: nothing to list).
  for (const char* bad : {"0", "10000001", "-3", "1e3", "99999999999999999999", "abc"}) {
    const ProcessResult r =
        Bistable("query " + id + " \"lle < 1e9\" --json --limit " + bad + " --data " + dir + "/data");
    EXPECT_EQ(r.exit_code, 2) << bad;
    EXPECT_NE(r.err.find("--limit = " + std::string(bad) + " violates 1 <= --limit <= 10000000 with --json"),
              std::string::npos)
        << r.err;
    EXPECT_TRUE(r.out.empty()) << r.out;
  }

  const ProcessResult ls = Bistable("sweeps --json --data " + dir + "/data");
  ASSERT_EQ(ls.exit_code, 0);
  const auto lj = nlohmann::json::parse(ls.out);
  ASSERT_EQ(lj.size(), 1u);
  EXPECT_EQ(lj[0]["id"], id);
  EXPECT_EQ(lj[0]["status"], "done");
  // Times are ISO 8601 UTC, read back strictly: created before finished, both within this test's run.
  const double now = std::chrono::duration<double>(std::chrono::system_clock::now().time_since_epoch()).count();
  const double created = bistable_test::ParseIsoTimeUtc(lj[0]["created"].get<std::string>());
  const double finished = bistable_test::ParseIsoTimeUtc(lj[0]["finished"].get<std::string>());
  EXPECT_LE(created, finished) << lj[0].dump();
  EXPECT_GT(created, now - 600) << lj[0].dump();
  EXPECT_LE(finished, now + 1) << lj[0].dump();
  // Map ranges of integer metrics are integers.
  for (const auto& mm : lj[0]["maps"])
    if (mm["metric"] == "motion" || mm["metric"] == "period" || mm["metric"] == "termination") {
      EXPECT_TRUE(mm["min"].is_number_integer() && mm["max"].is_number_integer()) << mm.dump();
    }
  fs::remove_all(dir);
}

// `map --at` off the grid takes the nearest grid value and says which on stderr (alpha's grid: 0.2, 0.56, 0.92,
// 1.28, 1.64, 2; half a step 0.18); beyond the axis's range by more than half a step it is refused, naming --at and
// the range.
TEST(CliSweep, MapAtTakesTheNearestGridValue) {
  const std::string dir = Dir("map_at");
  const std::string spec = WriteSpec(dir, kGrid);
  const ProcessResult run = Bistable("run " + spec + " --data " + dir + "/data --json --no-plots");
  ASSERT_EQ(run.exit_code, 0) << run.err;
  const std::string id = nlohmann::json::parse(run.out)["id"];
  const auto map_at = [&](const std::string& at, const std::string& format = "json") {
    return Bistable("map " + id + " --metric lle --at " + at + " --format " + format + " --out " + dir + "/m." +
                    format + " --data " + dir + "/data");
  };
  const auto written = [&] { return nlohmann::json::parse(bistable_test::ReadText(dir + "/m.json")); };
  const auto fixed_alpha = [&] { return written()["fixed"]["alpha"].get<double>(); };
  const ProcessResult exact = map_at("alpha=0.92");
  ASSERT_EQ(exact.exit_code, 0) << exact.err;
  EXPECT_EQ(exact.err.find("nearest"), std::string::npos) << exact.err;  // on the grid: nothing to say
  const nlohmann::json exact_curve = written()["values"];
  const ProcessResult near = map_at("alpha=1.0");
  ASSERT_EQ(near.exit_code, 0) << near.err;
  EXPECT_NE(near.err.find("map: --at alpha=1 \u2192 nearest grid value 0.92"), std::string::npos) << near.err;
  EXPECT_NEAR(fixed_alpha(), 0.92, 1e-12);
  EXPECT_EQ(written()["values"], exact_curve);
  for (const char* inside : {"alpha=2.17", "alpha=0.03"}) {
    const ProcessResult r = map_at(inside);
    EXPECT_EQ(r.exit_code, 0) << inside << ": " << r.err;
    EXPECT_NE(r.err.find("nearest grid value"), std::string::npos) << r.err;
  }
  EXPECT_NEAR(fixed_alpha(), 0.2, 1e-12);
  const ProcessResult png = map_at("alpha=1.3", "png");
  ASSERT_EQ(png.exit_code, 0) << png.err;
  EXPECT_NE(png.err.find("nearest grid value 1.28"), std::string::npos) << png.err;
  EXPECT_GT(fs::file_size(dir + "/m.png"), 1000u);
  for (const char* outside : {"alpha=2.19", "alpha=0.01", "alpha=-1e300", "alpha=1e300"}) {
    const ProcessResult r = map_at(outside);
    EXPECT_EQ(r.exit_code, 2) << outside;
    EXPECT_NE(r.err.find("--at " + std::string(outside).substr(0, 6)), std::string::npos) << r.err;
    EXPECT_NE(r.err.find("is outside the axis: alpha runs from 0.2 to 2 (6 values"), std::string::npos) << r.err;
  }
  fs::remove_all(dir);
}

// A map records where it was written: the CPU (/proc/cpuinfo's model name), the build's vector unit and
// the engine's lane width, as HDF5 attributes of a real file, and `bistable info` prints them (and,
// without an id, the same for this build on this CPU).
TEST(Provenance, MapFileCarriesTheHostCpuIsaAndLaneWidth) {
  const std::string dir = Dir("provenance");
  const std::string spec = WriteSpec(dir, kGrid);
  const ProcessResult run = Bistable("run " + spec + " --data " + dir + "/data --json --no-plots");
  ASSERT_EQ(run.exit_code, 0) << run.err;
  const auto j = nlohmann::json::parse(run.out);
  const std::string id = j["id"], h5 = j["files"][0];
  auto attr = [&](const char* name) {
    auto v = bistable::ReadMapAttribute(h5, name);
    EXPECT_TRUE(v.ok()) << name;
    return v.ok() ? *v : std::string();
  };
  // The oracle: /proc/cpuinfo as the kernel lists it (first CPU).
  std::ifstream f("/proc/cpuinfo");
  std::string line, model, flags;
  while (std::getline(f, line)) {
    const size_t colon = line.find(':');
    if (colon == std::string::npos) continue;
    std::string value = line.substr(colon + 1);
    value.erase(0, value.find_first_not_of(" \t"));
    value.erase(value.find_last_not_of(" \t") + 1);
    if (model.empty() && line.rfind("model name", 0) == 0) model = value;
    if (flags.empty() && line.rfind("flags", 0) == 0) flags = " " + value + " ";
  }
  const std::string cpu = attr("host_cpu_model"), isa = attr("host_simd_isa"), width = attr("host_lane_width");
  EXPECT_EQ(cpu, model.empty() ? "unknown CPU" : model);
  EXPECT_TRUE(isa == "AVX-512" || isa == "AVX2+FMA" || isa == "AVX+FMA" || isa == "scalar") << isa;
  EXPECT_EQ(width, isa == "AVX-512" ? "8" : "4");
  if (!flags.empty() && flags.find(" avx512f ") == std::string::npos) {
    EXPECT_NE(isa, "AVX-512") << flags;
  }
  const std::string note = attr("host_note");
  EXPECT_NE(note.find("| lanes: " + width + " (fixed at compile time: -march="), std::string::npos) << note;

  const ProcessResult info = Bistable("info " + id + " --json --data " + dir + "/data");
  ASSERT_EQ(info.exit_code, 0) << info.err;
  const auto ij = nlohmann::json::parse(info.out);
  EXPECT_EQ(ij["sweep_id"], id);
  EXPECT_EQ(ij["host_cpu_model"], cpu);
  EXPECT_EQ(ij["host_simd_isa"], isa);
  EXPECT_EQ(ij["host_lane_width"], std::stoi(width));
  const ProcessResult text = Bistable("info " + h5);
  ASSERT_EQ(text.exit_code, 0) << text.err;
  EXPECT_NE(text.out.find("host_lane_width   " + width + "\n"), std::string::npos) << text.out;
  EXPECT_NE(text.out.find("host_cpu_model    " + cpu + "\n"), std::string::npos) << text.out;
  const ProcessResult here = Bistable("info");
  ASSERT_EQ(here.exit_code, 0) << here.err;
  ASSERT_FALSE(here.out.empty());
  EXPECT_NE(note.find("(" + here.out.substr(0, here.out.size() - 1) + ")"), std::string::npos)
      << "the map's line and this build's on this CPU: " << here.out << note;
  fs::remove_all(dir);
}

// JSON prints a category by its name (the map files' motion_codes) and an integer metric as an
// integer, in `map --format json` and `query --json`; CSV keeps the codes.
TEST(CliSweep, JsonPrintsMotionByNameAndIntegersAsIntegers) {
  const std::string dir = Dir("names");
  const std::string spec = WriteSpec(dir, kGrid);
  const ProcessResult run = Bistable("run " + spec + " --data " + dir + "/data --json --no-plots");
  ASSERT_EQ(run.exit_code, 0) << run.err;
  const std::string id = nlohmann::json::parse(run.out)["id"];
  const std::string data = " --data " + dir + "/data";
  const std::set<std::string> names = {"intrawell", "interwell", "chaotic", "undefined"};

  const ProcessResult mj = Bistable("map " + id + " --metric motion --format json" + data);
  ASSERT_EQ(mj.exit_code, 0) << mj.err;
  const ProcessResult mc = Bistable("map " + id + " --metric motion --format csv" + data);
  ASSERT_EQ(mc.exit_code, 0) << mc.err;
  const auto m = nlohmann::json::parse(mj.out);
  EXPECT_TRUE(m["unit"].is_null()) << "names have no unit";
  // The CSV rows (alpha, omega, code) in the JSON's order: each code is the name's code.
  std::istringstream csv(mc.out);
  std::string line;
  std::getline(csv, line);
  EXPECT_EQ(line, "alpha,omega,motion");
  std::set<std::string> seen;
  for (const auto& row : m["values"])
    for (const auto& v : row) {
      ASSERT_TRUE(v.is_string()) << v;
      ASSERT_TRUE(names.count(v.get<std::string>())) << v;
      seen.insert(v.get<std::string>());
      ASSERT_TRUE(std::getline(csv, line));
      const double code = std::stod(line.substr(line.rfind(',') + 1));
      int want = 0;
      ASSERT_TRUE(bistable::MotionCodeOfName(v.get<std::string>(), &want));
      EXPECT_EQ(code, want) << line << " vs " << v;
    }
  EXPECT_GE(seen.size(), 2u) << "the grid shows more than one kind of motion";

  const ProcessResult pj = Bistable("map " + id + " --metric period --format json" + data);
  ASSERT_EQ(pj.exit_code, 0) << pj.err;
  for (const auto& row : nlohmann::json::parse(pj.out)["values"])
    for (const auto& v : row) EXPECT_TRUE(v.is_number_integer()) << v;

  const ProcessResult q = Bistable("query " + id + " \"period >= 0 and motion != undefined\" --json" + data);
  ASSERT_EQ(q.exit_code, 0) << q.err;
  const auto qj = nlohmann::json::parse(q.out);
  ASSERT_GT(qj["count"].get<long>(), 0);
  for (const auto& pt : qj["points"]) {
    EXPECT_TRUE(pt["period"].is_number_integer()) << pt;
    ASSERT_TRUE(pt["motion"].is_string()) << pt;
    EXPECT_TRUE(names.count(pt["motion"].get<std::string>())) << pt;
    EXPECT_NE(pt["motion"], "undefined");
    EXPECT_TRUE(pt["alpha"].is_number_float()) << pt;
  }
  // The query language reads the names JSON prints: as many chaotic points as the map shows.
  long chaotic = 0;
  for (const auto& row : m["values"])
    for (const auto& v : row) chaotic += v == "chaotic";
  const ProcessResult qc = Bistable("query " + id + " \"motion == chaotic\" --json" + data);
  ASSERT_EQ(qc.exit_code, 0) << qc.err;
  EXPECT_EQ(nlohmann::json::parse(qc.out)["count"].get<long>(), chaotic);
  fs::remove_all(dir);
}

// A continuation sweep's query names its item dimension as the map file does: "direction" (0 up, 1 down), not "ic".
TEST(CliSweep, QueryOfAContinuationSweepNamesTheDirection) {
  const std::string dir = Dir("query_direction");
  const std::string spec = WriteSpec(dir,
                                     "name = \"up and down\"\nmodel = \"standalone\"\n[axes]\nalpha = [0.1]\n"
                                     "omega = { linspace = [0.5, 1.3, 9] }\n[continuation]\naxis = \"omega\"\n"
                                     "direction = \"both\"\n[integration]\nt_end = 60\nt_keep = 30\n");
  const std::string data = " --data " + dir + "/data";
  const ProcessResult run = Bistable("run " + spec + " --no-plots --quiet --json" + data);
  ASSERT_EQ(run.exit_code, 0) << run.err;
  const std::string id = nlohmann::json::parse(run.out)["id"];
  const ProcessResult q = Bistable("query " + id + " \"frf_db > -1000\" --json" + data);
  ASSERT_EQ(q.exit_code, 0) << q.err;
  const auto j = nlohmann::json::parse(q.out);
  ASSERT_EQ(j["count"].get<long>(), 18) << "9 frequencies, up and down";
  std::set<long> directions;
  for (const auto& pt : j["points"]) {
    EXPECT_FALSE(pt.contains("ic")) << pt;
    ASSERT_TRUE(pt.contains("direction")) << pt;
    directions.insert(pt["direction"].get<long>());
  }
  EXPECT_EQ(directions, (std::set<long>{0, 1}));
}

// `map --out -` is standard output, for every format: the bytes equal the file --out FILE writes.
TEST(CliSweep, OutDashWritesTheFileBytesToStdout) {
  const std::string dir = Dir("dash");
  const std::string spec = WriteSpec(dir,
                                     "name = \"dash\"\nmodel = \"standalone\"\n[axes]\nalpha = [0.5, 1.0]\n"
                                     "omega = [0.8, 1.2]\n[integration]\nt_end = 20.0\nt_keep = 10.0\n");
  const ProcessResult run = Bistable("run " + spec + " --data " + dir + "/data --json --no-plots");
  ASSERT_EQ(run.exit_code, 0) << run.err;
  const std::string id = nlohmann::json::parse(run.out)["id"];
  // Plots for stdout are drawn in a private directory under $TMPDIR, removed afterwards.
  fs::create_directories(dir + "/tmp");
  const auto map = [&](std::vector<std::string> args, const std::string& tmpdir) {
    std::vector<std::string> argv = {BISTABLE_CLI, "map", id, "--data", dir + "/data"};
    argv.insert(argv.end(), args.begin(), args.end());
    return bistable_test::RunArgv(argv, dir, {{"TMPDIR", tmpdir}}, 120);
  };
  for (const std::string format : {"csv", "json", "svg", "png"}) {
    SCOPED_TRACE(format);
    const std::string file = dir + "/lle." + format;
    const auto to_file = map({"--metric", "lle", "--format", format, "--out", file}, dir + "/tmp");
    ASSERT_EQ(to_file.exit_code, 0) << to_file.err;
    const auto to_stdout = map({"--metric", "lle", "--format", format, "--out", "-"}, dir + "/tmp");
    ASSERT_EQ(to_stdout.exit_code, 0) << to_stdout.err;
    std::ifstream in(file, std::ios::binary);
    const std::string bytes((std::istreambuf_iterator<char>(in)), {});
    ASSERT_GT(bytes.size(), 10u);
    EXPECT_EQ(to_stdout.out.size(), bytes.size());
    EXPECT_TRUE(to_stdout.out == bytes) << "stdout differs from the file";
    if (format == "png") {
      EXPECT_EQ(to_stdout.out.substr(1, 3), "PNG");
    }
    EXPECT_FALSE(fs::exists(dir + "/-")) << "a file named '-' was written";
    if (format == "csv" || format == "json") {
      EXPECT_EQ(map({"--metric", "lle", "--format", format}, dir + "/tmp").out, bytes) << "no --out prints the same";
    }
  }
  // The Fig. 6 scatter too.
  const auto hd = map({"--metric", "hd_scatter", "--at", "alpha=0.5", "--out", "-"}, dir + "/tmp");
  ASSERT_EQ(hd.exit_code, 0) << hd.err;
  EXPECT_EQ(hd.out.substr(1, 3), "PNG");
  EXPECT_FALSE(fs::exists(dir + "/-"));
  EXPECT_TRUE(fs::is_empty(dir + "/tmp")) << "a temporary plot directory was left behind";
  for (const auto& e : fs::directory_iterator(dir))
    EXPECT_NE(e.path().filename().string().rfind(".bistable-", 0), 0u) << e.path();
  // A temporary directory that cannot be made is a clear error naming out.
  const auto notmp = map({"--metric", "lle", "--format", "svg", "--out", "-"}, dir + "/no/such/dir");
  EXPECT_EQ(notmp.exit_code, 2);
  EXPECT_TRUE(notmp.out.empty());
  EXPECT_NE(notmp.err.find("(out: cannot create a temporary directory for the plot in '" + dir + "/no/such/dir'"),
            std::string::npos)
      << notmp.err;
  fs::remove_all(dir);
}

// The one time format and the category names, in process.
TEST(JsonOut, TimesAreIso8601UtcToTheMillisecond) {
  EXPECT_EQ(bistable::IsoTimeUtc(0), "1970-01-01T00:00:00.000Z");
  EXPECT_EQ(bistable::IsoTimeUtc(1795381445.123), "2026-11-22T21:04:05.123Z");
  EXPECT_EQ(bistable::IsoTimeUtc(1795381445.9996), "2026-11-22T21:04:06.000Z");  // the carry reaches the second
  EXPECT_EQ(bistable::IsoTimeUtc(951782400.5), "2000-02-29T00:00:00.500Z");
  EXPECT_EQ(bistable::IsoTimeUtc(253402300799.0), "9999-12-31T23:59:59.000Z");
  for (double bad : {-1.0, 253402300800.0, double(NAN), double(INFINITY)})
    EXPECT_EQ(bistable::IsoTimeUtc(bad), "") << bad;
  for (double t : {0.0, 1.5, 1795381445.123, 1e9 + 0.999})
    EXPECT_NEAR(bistable_test::ParseIsoTimeUtc(bistable::IsoTimeUtc(t)), t, 5e-4) << t;
  EXPECT_TRUE(std::isnan(bistable_test::ParseIsoTimeUtc("2026-11-22 21:04:05.123Z")));
  EXPECT_TRUE(std::isnan(bistable_test::ParseIsoTimeUtc("1795381445.123")));
}

TEST(JsonOut, CategoryCodesNameTheirMotionAndTermination) {
  using bistable::CategoryName;
  EXPECT_STREQ(CategoryName("motion", 0), "intrawell");
  EXPECT_STREQ(CategoryName("motion", 1), "interwell");
  EXPECT_STREQ(CategoryName("motion", 2), "chaotic");
  EXPECT_STREQ(CategoryName("motion", -1), "undefined");
  EXPECT_STREQ(CategoryName("motion", 3), "quasi-periodic");  // settled labels (issue 38)
  EXPECT_STREQ(CategoryName("motion", 4), "unresolved");
  EXPECT_EQ(CategoryName("motion", 5), nullptr);
  EXPECT_EQ(CategoryName("motion", 0.5), nullptr);
  EXPECT_EQ(CategoryName("motion", NAN), nullptr);
  EXPECT_STREQ(CategoryName("termination", 0), "ok");
  EXPECT_STREQ(CategoryName("termination", 1), "diverged");
  EXPECT_EQ(CategoryName("period", 1), nullptr);
  EXPECT_TRUE(bistable::IsCategoryMetric("motion") && bistable::IsCategoryMetric("termination"));
  EXPECT_FALSE(bistable::IsCategoryMetric("period"));
  // Every name the map files' motion_codes attribute lists is a name JSON prints, with its code.
  const std::string text = bistable::MotionCodesText();
  for (int code : {0, 1, 2, 3, 4, -1})
    EXPECT_NE(text.find(std::to_string(code) + " " + CategoryName("motion", code)), std::string::npos) << code;
}

// A stored Poincaré section (metric "poincare", poincare_points = 12, a phase): datasets poincare_y
// and poincare_v shaped (alpha, poincare_point) with CF attributes, equal bit for bit to the last 12
// points of `bistable point --poincare -` (map == point), period 1 one point repeated, period 2 two.
TEST(CliSweep, PoincareDatasetsEqualThePointSection) {
  const std::string dir = Dir("poincare");
  // The Duffing oscillator of the examples at γ = αΩ² = 0.2 (period 1), 0.28 (period 2), 0.5 (chaos).
  const std::string spec = WriteSpec(dir, R"(
model = "standalone"
[params]
eta = 0.3
omega = 1.2
[axes]
alpha = [0.1388888888888889, 0.19444444444444445, 0.3472222222222222]
[integration]
t_keep = 1000.0
t_end = 2000.0
[metrics]
store = ["period", "lle", "poincare"]
poincare_points = 12
poincare_phase = 0.75
)");
  const ProcessResult run = Bistable("run " + spec + " --data " + dir + "/data --json --no-plots");
  ASSERT_EQ(run.exit_code, 0) << run.err;
  const std::string h5 = nlohmann::json::parse(run.out)["files"][0];
  auto y = bistable::ReadMapMetric(h5, "poincare_y");
  auto v = bistable::ReadMapMetric(h5, "poincare_v");
  auto period = bistable::ReadMapMetric(h5, "period");
  ASSERT_TRUE(y.ok() && v.ok() && period.ok()) << y.status().ToString() << v.status().ToString();
  EXPECT_EQ(y->dims, (std::vector<size_t>{3, 12}));
  EXPECT_EQ(y->dim_names, (std::vector<std::string>{"alpha", "poincare_point"}));
  EXPECT_EQ(y->unit, "delta_s");
  EXPECT_EQ(v->unit, "delta_s/tau");
  EXPECT_NE(y->definition.find("phase = poincare_phase = 0.75"), std::string::npos) << y->definition;
  EXPECT_EQ(period->values, (std::vector<double>{1, 2, 0}));
  const double alphas[] = {0.1388888888888889, 0.19444444444444445, 0.3472222222222222};
  for (int p = 0; p < 3; ++p) {
    char args[256];
    std::snprintf(
        args, sizeof args,
        "point --model standalone --alpha %.17g --omega 1.2 --eta 0.3 --t-keep 1000 --t-end 2000 --no-rosenstein "
        "--poincare - --poincare-phase 0.75 --json",
        alphas[p]);
    const ProcessResult pt = Bistable(args);
    ASSERT_EQ(pt.exit_code, 0) << pt.err;
    const auto pts = nlohmann::json::parse(pt.out)["poincare"]["points"];
    ASSERT_GE(pts.size(), 12u);
    for (int k = 0; k < 12; ++k) {
      const auto& row = pts[pts.size() - 12 + k];
      const double ym = row[2].get<double>(), vm = row[3].get<double>();
      EXPECT_EQ(std::memcmp(&ym, &y->values[p * 12 + k], sizeof(double)), 0) << "point " << p << " k " << k;
      EXPECT_EQ(std::memcmp(&vm, &v->values[p * 12 + k], sizeof(double)), 0) << "point " << p << " k " << k;
    }
  }
  auto spread = [&](int p, int n) {
    double worst = 0;
    for (int k = n; k < 12; ++k)
      worst = std::max({worst, std::fabs(y->values[p * 12 + k] - y->values[p * 12 + k - n]),
                        std::fabs(v->values[p * 12 + k] - v->values[p * 12 + k - n])});
    return worst;
  };
  EXPECT_LT(spread(0, 1), 1e-9) << "period 1: one point";
  EXPECT_LT(spread(1, 2), 1e-9) << "period 2: two points";
  EXPECT_GT(std::fabs(y->values[12] - y->values[13]), 0.01) << "period 2: two distinct points";
  EXPECT_GT(spread(2, 1), 0.1) << "chaos: scattered";

  // CF metadata as h5py sees it (every variable has long_name; a scaled, dimensionless one no units but its scale in
  // `unit`, which xarray labels plots with).
  const int rc =
      std::system(("/usr/bin/python3 -c \"import h5py,sys; f=h5py.File(sys.argv[1]); "
                   "d=f['poincare_y']; assert d.shape==(3,12), d.shape; "
                   "assert 'units' not in d.attrs and d.attrs['unit']=='delta_s' and 'long_name' in d.attrs; "
                   "assert f['poincare_v'].attrs['unit_label']=='delta_s/tau'; "
                   "assert list(f['poincare_point'][:])==list(range(12))\" " +
                   h5)
                      .c_str());
  EXPECT_EQ(rc, 0);

  // Bad settings name the field and the bound.
  struct Case {
    std::string text, expect;
  };
  for (const Case& c : std::vector<Case>{
           {"store = [\"poincare\"]\npoincare_points = 65",
            "metrics.poincare_points = 65 violates metrics.poincare_points in [1, 64]"},
           {"store = [\"poincare\"]\npoincare_points = 0",
            "metrics.poincare_points = 0 violates metrics.poincare_points in [1, 64]"},
           {"store = [\"lle\"]\npoincare_points = 8", "metrics.poincare_points needs \"poincare\" in metrics.store"},
           {"poincare_phase = 6.5", "metrics.poincare_phase = 6.5 violates metrics.poincare_phase in [0, 2 pi)"},
       }) {
    std::ofstream(dir + "/bad.toml") << "model = \"standalone\"\n[axes]\nalpha = [0.1, 0.2]\n[metrics]\n"
                                     << c.text << "\n";
    const ProcessResult r = Bistable("run " + dir + "/bad.toml --data " + dir + "/data --no-plots");
    EXPECT_EQ(r.exit_code, 2) << c.text;
    EXPECT_NE(r.err.find(c.expect), std::string::npos) << c.text << "\n" << r.err;
  }
}

TEST(CliSweep, BadInputIsAClearErrorAndLosesNothing) {
  const std::string dir = Dir("bad");
  const std::string good = WriteSpec(dir, kGrid);
  ASSERT_EQ(Bistable("run " + good + " --data " + dir + "/data --quiet --no-plots").exit_code, 0);
  const auto before = fs::file_size(dir + "/data/index.sqlite");
  struct Case {
    std::string args, expect;
  };
  std::ofstream(dir + "/typo.toml") << "model = \"coupled\"\n[axes]\nalpah = [1, 2]\n";
  std::ofstream(dir + "/broken.toml") << "model = \"coupled\"\n[axes\n";
  const Case cases[] = {
      {"run " + dir + "/typo.toml --data " + dir + "/data", "did you mean 'alpha'"},
      {"run " + dir + "/broken.toml --data " + dir + "/data", "broken.toml:2"},
      {"run " + dir + "/missing.toml --data " + dir + "/data", "cannot read spec file"},
      {"run " + good + " --data /proc/no/such/dir", "/proc/no/such/dir"},
      {"map nosuchid --metric frf_db --data " + dir + "/data", "no sweep 'nosuchid'"},
      {"query nosuchid \"lle > 0\" --data " + dir + "/data", "no sweep"},
  };
  for (const Case& c : cases) {
    const ProcessResult r = Bistable(c.args);
    EXPECT_EQ(r.exit_code, 2) << c.args << "\n" << r.err;
    EXPECT_EQ(r.err.rfind("error: ", 0), 0u) << r.err;
    EXPECT_NE(r.err.find(c.expect), std::string::npos) << c.args << "\n" << r.err;
  }
  const std::string id = nlohmann::json::parse(Bistable("sweeps --json --data " + dir + "/data").out)[0]["id"];
  const ProcessResult badq = Bistable("query " + id + " \"frf < 0\" --data " + dir + "/data");
  EXPECT_NE(badq.err.find("did you mean 'frf_db'"), std::string::npos) << badq.err;
  // Off the grid, inside the axis: the nearest grid value (CliSweep.MapAtTakesTheNearestGridValue); beyond it: refused.
  const ProcessResult bada = Bistable("map " + id + " --metric frf_db --at alpha=7.7 --data " + dir + "/data");
  EXPECT_EQ(bada.exit_code, 2) << bada.err;
  EXPECT_NE(bada.err.find("--at alpha=7.7 is outside the axis: alpha runs from 0.2 to 2"), std::string::npos)
      << bada.err;
  const ProcessResult badm = Bistable("map " + id + " --metric frf --data " + dir + "/data");
  EXPECT_NE(badm.err.find("did you mean 'frf_db'"), std::string::npos) << badm.err;
  // Nothing stored was lost or rewritten.
  EXPECT_GE(fs::file_size(dir + "/data/index.sqlite"), before);
  EXPECT_EQ(nlohmann::json::parse(Bistable("sweeps --json --data " + dir + "/data").out)[0]["status"], "done");
  fs::remove_all(dir);
}

// A sweep big enough to interrupt: 60 × 60 points, short run, one thread, small jobs.
constexpr const char* kLong = R"(
model = "coupled"
[axes]
alpha = { linspace = [0.1, 3.0, 60] }
omega = { linspace = [0.1, 3.0, 60] }
[integration]
t_end = 200.0
t_keep = 100.0
)";

long PointsDone(const std::string& data) {
  if (!fs::exists(data + "/index.sqlite")) return 0;
  auto db = bistable::IndexDb::Open(data + "/index.sqlite");
  if (!db.ok()) return 0;
  auto rows = (*db)->ListSweeps();
  return rows.ok() && !rows->empty() ? (*rows)[0].items_done : 0;
}

pid_t Spawn(const std::string& spec, const std::string& data) {
  std::fflush(nullptr);  // the child must not re-emit our buffered output
  const pid_t pid = ::fork();
  if (pid == 0) {
    ::freopen("/dev/null", "w", stderr);
    ::freopen("/dev/null", "w", stdout);
    ::execl(BISTABLE_CLI, BISTABLE_CLI, "run", spec.c_str(), "--data", data.c_str(), "--threads", "1", "--job-items",
            "16", "--no-plots", static_cast<char*>(nullptr));
    ::_exit(127);
  }
  return pid;
}

using bistable_test::ExpectSameMaps;

void InterruptThenResume(int signal_number) {
  const std::string dir = Dir(signal_number == SIGKILL ? "kill" : "int");
  const std::string spec = WriteSpec(dir, kLong);
  const std::string data = dir + "/data";
  const pid_t pid = Spawn(spec, data);
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(60);
  while (PointsDone(data) < 400 && std::chrono::steady_clock::now() < deadline)
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  ASSERT_EQ(::kill(pid, signal_number), 0);
  int status = 0;
  ::waitpid(pid, &status, 0);
  if (signal_number == SIGKILL) {
    EXPECT_TRUE(WIFSIGNALED(status));
  } else {
    ASSERT_TRUE(WIFEXITED(status));
    EXPECT_EQ(WEXITSTATUS(status), 130);
  }
  const long stored = PointsDone(data);
  ASSERT_GE(stored, 400);
  ASSERT_LT(stored, 3600) << "the run finished before it could be interrupted; make kLong bigger";
  // The index names no map file for the unfinished sweep, and no map file exists yet.
  auto db = bistable::IndexDb::Open(data + "/index.sqlite");
  ASSERT_TRUE(db.ok());
  auto rows = (*db)->ListSweeps();
  ASSERT_TRUE(rows.ok());
  EXPECT_EQ((*rows)[0].file, "");
  EXPECT_EQ((*rows)[0].state,
            signal_number == SIGKILL ? bistable::SweepState::kRunning : bistable::SweepState::kInterrupted);
  for (const auto& e : fs::directory_iterator(data + "/sweeps")) EXPECT_NE(e.path().extension(), ".h5") << e.path();

  const ProcessResult resume = Bistable("run " + spec + " --data " + data + " --json --no-plots");
  ASSERT_EQ(resume.exit_code, 0) << resume.err;
  const auto j = nlohmann::json::parse(resume.out);
  EXPECT_EQ(j["cached"], stored) << "every item acknowledged before the interruption is reused";
  EXPECT_EQ(j["computed"].get<long>() + stored, 3600);

  const ProcessResult clean = Bistable("run " + spec + " --data " + dir + "/clean --json --no-plots");
  ASSERT_EQ(clean.exit_code, 0) << clean.err;
  ExpectSameMaps(j["files"][0], nlohmann::json::parse(clean.out)["files"][0]);
  fs::remove_all(dir);
}

// A full disk: a 1 MB tmpfs holds a small sweep; a big one then runs out of space. The big run must
// fail with a clear message and exit 2, and the small sweep (index row, map file) must stay intact.
TEST(CliSweep, FullDiskIsAClearErrorAndLosesNothing) {
  if (::geteuid() != 0) GTEST_SKIP() << "needs root to mount a small tmpfs";
  const std::string dir = Dir("full");
  const std::string mnt = dir + "/mnt";
  fs::create_directories(mnt);
  if (std::system(("mount -t tmpfs -o size=1m tmpfs " + mnt + " 2>/dev/null").c_str()) != 0)
    GTEST_SKIP() << "mounting a tmpfs is not permitted here";
  const std::string small = WriteSpec(dir, kGrid);
  const ProcessResult first = Bistable("run " + small + " --data " + mnt + " --json --no-plots");
  ASSERT_EQ(first.exit_code, 0) << first.err;
  const std::string first_map = nlohmann::json::parse(first.out)["files"][0];
  std::ofstream(dir + "/big.toml")
      << "model = \"coupled\"\n[axes]\nalpha = { linspace = [0.1, 3, 150] }\n"
         "omega = { linspace = [0.1, 3, 150] }\n[integration]\nt_end = 20.0\nt_keep = 10.0\n";
  const ProcessResult big = Bistable("run " + dir + "/big.toml --data " + mnt + " --no-plots --quiet");
  EXPECT_EQ(big.exit_code, 2) << big.err;
  EXPECT_EQ(big.err.rfind("error: ", 0), 0u) << big.err;
  EXPECT_TRUE(big.err.find("disk full") != std::string::npos || big.err.find("No space") != std::string::npos)
      << big.err;
  // Nothing stored was lost: the first sweep is listed as done and its map reads back.
  const ProcessResult ls = Bistable("sweeps --json --data " + mnt);
  ASSERT_EQ(ls.exit_code, 0) << ls.err;
  const auto rows = nlohmann::json::parse(ls.out);
  bool found = false;
  for (const auto& r : rows)
    if (r["file"] == first_map) found = r["status"] == "done";
  EXPECT_TRUE(found) << ls.out;
  auto m = bistable::ReadMapMetric(first_map, "frf_db");
  EXPECT_TRUE(m.ok()) << m.status().ToString();
  for (const auto& e : fs::directory_iterator(mnt + "/sweeps")) EXPECT_NE(e.path().extension(), ".tmp") << e.path();
  std::system(("umount " + mnt).c_str());
  fs::remove_all(dir);
}

TEST(CliSweep, KillNineLosesNoFinishedJobAndRerunResumesToTheSameMap) { InterruptThenResume(SIGKILL); }
TEST(CliSweep, CtrlCStopsCleanlyAndRerunResumesToTheSameMap) { InterruptThenResume(SIGINT); }

}  // namespace

namespace {

// The CI version of `bistable reproduce paper`: coarse grids, fast sweeps; every figure file exists,
// the page lists every claim with our number and a verdict.
TEST(CliReproduce, QuickModeRegeneratesEveryFigureAndTheClaimsPage) {
  const std::string dir = Dir("reproduce");
  const ProcessResult r = Bistable("reproduce paper --quick --json --out " + dir);
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const auto j = nlohmann::json::parse(r.out);
  ASSERT_GE(j["claims"].size(), 18u);
  EXPECT_EQ(j["labels"], "paper") << "the claims are checked in the paper's window whatever the default label mode";
  std::set<std::string> figures;
  for (const auto& c : j["claims"]) {
    figures.insert(c["figure"].get<std::string>().substr(0, 2));
    EXPECT_FALSE(c["ours"].get<std::string>().empty());
    for (const auto& f : c["files"]) EXPECT_GT(fs::file_size(f.get<std::string>()), 1000u) << f;
  }
  for (const char* fig : {"3", "4", "6", "7", "8a", "9", "10", "11", "12", "13", "22", "23", "24"})
    EXPECT_TRUE(figures.count(std::string(fig).substr(0, 2))) << "no claim checked for Fig. " << fig;
  std::ifstream page(j["report"].get<std::string>());
  const std::string text((std::istreambuf_iterator<char>(page)), {});
  EXPECT_NE(text.find("| Fig. | the paper's claim | our number | verdict |"), std::string::npos);
  EXPECT_NE(text.find("labels paper"), std::string::npos);
  EXPECT_NE(Bistable("reproduce paper --quick --labels window --out " + dir).exit_code, 0);
  fs::remove_all(dir);
}

}  // namespace
