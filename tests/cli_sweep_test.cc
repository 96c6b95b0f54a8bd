// End-to-end: `bistable run | sweeps | map | query` as real processes on real files — JSON shapes,
// h5py reading the map, Ctrl-C and kill -9 followed by a resume that gives a bit-identical map.
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <set>
#include <thread>

#include <gtest/gtest.h>

#include "tests/map_compare.h"
#include "tests/process_util.h"
#include <nlohmann/json.hpp>

#include "storage/index_db.h"
#include "storage/map_file.h"

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
  const int rc = std::system(("/usr/bin/python3 " BISTABLE_TESTS_DIR "/h5py_check.py " + h5 + " 6 5 > /dev/null").c_str());
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

  const ProcessResult png = Bistable("map " + id + " --metric motion --format png --out " + dir + "/m.png --data " + dir + "/data");
  ASSERT_EQ(png.exit_code, 0) << png.err;
  EXPECT_GT(fs::file_size(dir + "/m.png"), 1000u);

  const ProcessResult q = Bistable("query " + id + " \"frf_db < 0 or motion == chaotic\" --json --data " + dir + "/data");
  ASSERT_EQ(q.exit_code, 0) << q.err;
  const auto qj = nlohmann::json::parse(q.out);
  for (const char* k : {"count", "total", "fraction", "area_fraction", "points"}) EXPECT_TRUE(qj.contains(k)) << k;
  EXPECT_EQ(qj["total"], 30);
  EXPECT_EQ(qj["points"].size(), qj["count"].get<size_t>());

  const ProcessResult ls = Bistable("sweeps --json --data " + dir + "/data");
  ASSERT_EQ(ls.exit_code, 0);
  const auto lj = nlohmann::json::parse(ls.out);
  ASSERT_EQ(lj.size(), 1u);
  EXPECT_EQ(lj[0]["id"], id);
  EXPECT_EQ(lj[0]["status"], "done");
  fs::remove_all(dir);
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
  const ProcessResult bada = Bistable("map " + id + " --metric frf_db --at alpha=0.77 --data " + dir + "/data");
  EXPECT_NE(bada.err.find("not on the axis"), std::string::npos) << bada.err;
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
    ::execl(BISTABLE_CLI, BISTABLE_CLI, "run", spec.c_str(), "--data", data.c_str(), "--threads", "1", "--job-items", "16",
            "--no-plots", static_cast<char*>(nullptr));
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
  EXPECT_EQ((*rows)[0].state, signal_number == SIGKILL ? bistable::SweepState::kRunning : bistable::SweepState::kInterrupted);
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
  std::ofstream(dir + "/big.toml") << "model = \"coupled\"\n[axes]\nalpha = { linspace = [0.1, 3, 150] }\n"
                                      "omega = { linspace = [0.1, 3, 150] }\n[integration]\nt_end = 20.0\nt_keep = 10.0\n";
  const ProcessResult big = Bistable("run " + dir + "/big.toml --data " + mnt + " --no-plots --quiet");
  EXPECT_EQ(big.exit_code, 2) << big.err;
  EXPECT_EQ(big.err.rfind("error: ", 0), 0u) << big.err;
  EXPECT_TRUE(big.err.find("disk full") != std::string::npos || big.err.find("No space") != std::string::npos) << big.err;
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
  fs::remove_all(dir);
}

}  // namespace
