// End-to-end, issue 43: the job-array path as real processes on real files. `bistable run SPEC --shard i/N` for
// every i, then `bistable merge`, gives the embedded `bistable run`'s map: deploy/compare-maps.py compares every
// dataset (shape, dtype, bytes) and every attribute, skipping only the when/where/how-made ones, which must be
// exactly history (the time written; for a merge it also says "merged from N shards"), the host_* attributes
// (the writing process's CPU) and merged_from_shards (only in the merged map). A shard killed mid-run resumes
// from its store; merge refuses, writing nothing, a missing, duplicated, incomplete, foreign or other-version
// shard.
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <string>
#include <thread>

#include <gtest/gtest.h>

#include <nlohmann/json.hpp>
#include "tests/process_util.h"

#include "storage/index_db.h"
#include "storage/map_file.h"

namespace {

namespace fs = std::filesystem;

using bistable_test::Bistable;
using bistable_test::ProcessResult;

std::string Dir(const std::string& name) { return bistable_test::FreshDir("bistable_shard", name); }

std::string WriteSpec(const std::string& dir, const std::string& name, const std::string& text) {
  const std::string path = dir + "/" + name + ".toml";
  std::ofstream(path) << text;
  return path;
}

constexpr const char* kGrid = R"(
name = "shard grid"
model = "coupled"
[axes]
alpha = { linspace = [0.2, 2.0, 7] }
omega = { linspace = [0.4, 2.4, 6] }
[initial_conditions]
states = [[0.0, 0.0, 0.0, 0.0], [1.0, 0.0, 0.0, 0.0]]
[integration]
t_end = 300.0
t_keep = 150.0
)";  // 42 points x 2 initial conditions: the multistability fractions need both of a point's items

constexpr const char* kChains = R"(
name = "shard chains"
model = "coupled"
[axes]
alpha = [0.3, 0.9, 1.5]
omega = { linspace = [0.5, 2.5, 9] }
[continuation]
axis = "omega"
direction = "both"
[metrics]
store = ["y_max", "y_min", "motion", "turning_points", "frf_db", "lle"]
[integration]
t_end = 300.0
t_keep = 150.0
)";  // 6 chains of 9 (3 lines x 2 directions), dealt whole

// The map an embedded run of `spec` writes into `data`.
std::string EmbeddedMap(const std::string& spec, const std::string& data) {
  const ProcessResult run = Bistable("run " + spec + " --data " + data + " --json --no-plots --quiet");
  EXPECT_EQ(run.exit_code, 0) << run.err;
  return run.exit_code == 0 ? nlohmann::json::parse(run.out)["files"][0].get<std::string>() : "";
}

// Runs every shard i/n of `spec` into `data`, then merges: the merged map's path.
std::string ShardedMap(const std::string& spec, const std::string& data, int n) {
  for (int i = 0; i < n; ++i) {
    const ProcessResult r = Bistable("run " + spec + " --shard " + std::to_string(i) + "/" + std::to_string(n) +
                                     " --data " + data + " --json --threads 2");
    EXPECT_EQ(r.exit_code, 0) << r.err;
  }
  const ProcessResult merge = Bistable("merge " + spec + " --data " + data + " --json");
  EXPECT_EQ(merge.exit_code, 0) << merge.err;
  if (merge.exit_code != 0) return "";
  const auto j = nlohmann::json::parse(merge.out);
  EXPECT_EQ(j["shards"], n);
  return j["files"][0];
}

// deploy/compare-maps.py on two maps: its exit code and its line.
ProcessResult CompareMaps(const std::string& a, const std::string& b) {
  const std::string out = ::testing::TempDir() + "/compare_" + std::to_string(::getpid()) + ".txt";
  const int rc = std::system(
      ("/usr/bin/python3 " BISTABLE_DEPLOY_DIR "/compare-maps.py " + a + " " + b + " > " + out + " 2>&1").c_str());
  ProcessResult r{WIFEXITED(rc) ? WEXITSTATUS(rc) : -1, bistable_test::ReadText(out), ""};
  fs::remove(out);
  return r;
}

void ExpectMergedIsEmbedded(const char* text, int shards) {
  const std::string dir = Dir("same");
  const std::string spec = WriteSpec(dir, "spec", text);
  const std::string embedded = EmbeddedMap(spec, dir + "/embedded");
  const std::string merged = ShardedMap(spec, dir + "/array", shards);
  ASSERT_FALSE(embedded.empty() || merged.empty());
  const ProcessResult same = CompareMaps(embedded, merged);
  EXPECT_EQ(same.exit_code, 0) << same.out;
  EXPECT_NE(same.out.find("identical in shape, dtype and bits"), std::string::npos) << same.out;
  // What differs legitimately, and nothing else: when it was written (history), where (host_*), how (merged).
  EXPECT_NE(same.out.find("skipped attributes: history, host_cpu_model, host_lane_width, host_note, host_simd_isa, "
                          "merged_from_shards\n"),
            std::string::npos)
      << same.out;
  auto n = bistable::ReadMapAttribute(merged, "merged_from_shards");
  ASSERT_TRUE(n.ok()) << n.status().ToString();
  EXPECT_EQ(*n, std::to_string(shards));
  EXPECT_EQ(*bistable::ReadMapAttribute(embedded, "merged_from_shards"), "");
  EXPECT_NE(bistable::ReadMapAttribute(merged, "history")->find("merged from " + std::to_string(shards) + " shards"),
            std::string::npos);
  // The comparison can fail: the map of a sweep with one value changed is another map.
  std::string other = text;
  other.replace(other.find("t_end = 300.0"), 13, "t_end = 301.0");
  const ProcessResult differs = CompareMaps(embedded, EmbeddedMap(WriteSpec(dir, "other", other), dir + "/other"));
  EXPECT_EQ(differs.exit_code, 1) << differs.out;
  // The merged sweep is indexed as a run's: listed done, its map readable by id.
  const ProcessResult ls = Bistable("sweeps --json --data " + dir + "/array");
  ASSERT_EQ(ls.exit_code, 0) << ls.err;
  EXPECT_NE(ls.out.find("\"done\""), std::string::npos) << ls.out;
  fs::remove_all(dir);
}

TEST(Shards, EveryShardThenMergeIsTheEmbeddedMapBitForBit) { ExpectMergedIsEmbedded(kGrid, 3); }

TEST(Shards, ContinuationChainsShardWholeAndMergeToTheEmbeddedMap) { ExpectMergedIsEmbedded(kChains, 4); }

TEST(Shards, MoreShardsThanItemsLeaveEmptyShardsThatMergeAlike) {
  const std::string dir = Dir("many");
  const std::string spec = WriteSpec(dir, "spec", R"(
model = "coupled"
[axes]
alpha = [0.5, 1.0, 1.5]
[integration]
t_end = 200.0
t_keep = 100.0
)");
  const std::string embedded = EmbeddedMap(spec, dir + "/embedded");
  const std::string merged = ShardedMap(spec, dir + "/array", 5);  // 3 items: shards 3/5 and 4/5 are empty
  ASSERT_FALSE(embedded.empty() || merged.empty());
  EXPECT_EQ(CompareMaps(embedded, merged).exit_code, 0);
  fs::remove_all(dir);
}

TEST(Shards, ARefinedSweepIsRefusedWithTheReason) {
  const std::string dir = Dir("refined");
  const std::string spec = WriteSpec(dir, "spec", R"(
model = "coupled"
[axes]
alpha = { linspace = [0.015, 1.2, 17] }
omega = { linspace = [0.3, 3.0, 17] }
[refine]
levels = 2
criterion = "frf_0db"
)");
  const ProcessResult r = Bistable("run " + spec + " --shard 0/2 --data " + dir + "/data");
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.err.find("shard: sweep"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("is refined ([refine])"), std::string::npos) << r.err;
  EXPECT_FALSE(fs::exists(dir + "/data/shards")) << "nothing written";
}

// The store's sweep row: items of the shard stored so far.
long StoredItems(const std::string& store) {
  if (!fs::exists(store + "/index.sqlite")) return 0;
  auto db = bistable::IndexDb::Open(store + "/index.sqlite");
  if (!db.ok()) return 0;
  auto rows = (*db)->ListSweeps();
  return rows.ok() && !rows->empty() ? (*rows)[0].items_done : 0;
}

TEST(Shards, AShardKilledMidRunResumesFromItsStoreAndMergeRefusesItUntilThen) {
  const std::string dir = Dir("resume");
  const std::string spec = WriteSpec(dir, "spec", R"(
model = "coupled"
[axes]
alpha = { linspace = [0.1, 3.0, 40] }
omega = { linspace = [0.1, 3.0, 40] }
[integration]
t_end = 200.0
t_keep = 100.0
)");  // 1600 items, 800 a shard
  const std::string data = dir + "/array";
  const ProcessResult first = Bistable("run " + spec + " --shard 0/2 --data " + data + " --json");
  ASSERT_EQ(first.exit_code, 0) << first.err;
  const std::string store = nlohmann::json::parse(first.out)["store"];
  const std::string id = nlohmann::json::parse(first.out)["id"];
  const std::string store1 = data + "/shards/" + id + "-1-of-2";
  const pid_t pid = bistable_test::SpawnLogged(
      {BISTABLE_CLI, "run", spec, "--shard", "1/2", "--data", data, "--threads", "1", "--job-items", "16", "--quiet"},
      dir + "/shard1.out");
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(60);
  while (StoredItems(store1) < 200 && std::chrono::steady_clock::now() < deadline)
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  ASSERT_EQ(::kill(pid, SIGKILL), 0);
  int status = 0;
  ::waitpid(pid, &status, 0);
  EXPECT_TRUE(WIFSIGNALED(status));
  const long stored = StoredItems(store1);
  ASSERT_GE(stored, 200);
  ASSERT_LT(stored, 800) << "the shard finished before it could be killed; make the grid bigger";

  // Merge refuses the interrupted shard, naming it and what it holds, and writes nothing.
  const ProcessResult early = Bistable("merge " + spec + " --data " + data);
  EXPECT_EQ(early.exit_code, 2);
  EXPECT_NE(early.err.find("shard 1/2 ('" + store1 + "') is incomplete: " + std::to_string(stored) + " of 800 items "),
            std::string::npos)
      << early.err;
  EXPECT_NE(early.err.find("its run did not finish"), std::string::npos) << early.err;
  EXPECT_FALSE(fs::exists(data + "/sweeps/" + id + ".h5"));

  // The rerun computes only what the kill lost.
  const ProcessResult resume = Bistable("run " + spec + " --shard 1/2 --data " + data + " --json");
  ASSERT_EQ(resume.exit_code, 0) << resume.err;
  const auto j = nlohmann::json::parse(resume.out);
  EXPECT_EQ(j["cached"], stored) << "every item stored before the kill is reused";
  EXPECT_EQ(j["computed"].get<long>() + stored, 800);
  const ProcessResult merge = Bistable("merge " + spec + " --data " + data + " --json");
  ASSERT_EQ(merge.exit_code, 0) << merge.err;
  const ProcessResult same = CompareMaps(EmbeddedMap(spec, dir + "/embedded"),
                                         nlohmann::json::parse(merge.out)["files"][0].get<std::string>());
  EXPECT_EQ(same.exit_code, 0) << same.out;
  fs::remove_all(dir);
}

TEST(Shards, MergeRefusesMissingDuplicatedForeignAndOtherVersionShardsAndWritesNothing) {
  const std::string dir = Dir("refuse");
  const std::string spec = WriteSpec(dir, "spec", kGrid);
  std::string other_text = kGrid;
  other_text.replace(other_text.find("shard grid"), 10, "other grid");  // (a name is not part of the sweep id)
  other_text.replace(other_text.find("t_end = 300.0"), 13, "t_end = 310.0");
  const std::string other = WriteSpec(dir, "other", other_text);
  const std::string data = dir + "/array";
  std::string id, other_id;
  for (int i = 0; i < 3; ++i) {
    const ProcessResult r = Bistable("run " + spec + " --shard " + std::to_string(i) + "/3 --data " + data + " --json");
    ASSERT_EQ(r.exit_code, 0) << r.err;
    id = nlohmann::json::parse(r.out)["id"];
  }
  const ProcessResult o = Bistable("run " + other + " --shard 1/3 --data " + dir + "/other --json");
  ASSERT_EQ(o.exit_code, 0) << o.err;
  other_id = nlohmann::json::parse(o.out)["id"];
  const ProcessResult four = Bistable("run " + spec + " --shard 1/4 --data " + dir + "/four --json");
  ASSERT_EQ(four.exit_code, 0) << four.err;
  const std::string s0 = data + "/shards/" + id + "-0-of-3", s1 = data + "/shards/" + id + "-1-of-3",
                    s2 = data + "/shards/" + id + "-2-of-3";
  auto refused = [&](const std::string& stores, const std::string& why) {
    const ProcessResult r = Bistable("merge " + spec + " " + stores + " --data " + data);
    EXPECT_EQ(r.exit_code, 2) << stores;
    EXPECT_NE(r.err.find("error: invalid argument (stores: merge refused: "), std::string::npos) << r.err;
    EXPECT_NE(r.err.find(why), std::string::npos) << "expected '" << why << "' in: " << r.err;
    EXPECT_FALSE(fs::exists(data + "/sweeps/" + id + ".h5")) << "a refused merge writes no map";
  };
  refused(s0 + " " + s2, "1 of 3 shards missing: 1/3");
  refused(s0 + " " + s1 + " " + s1 + " " + s2, "shard 1/3 is given twice: '" + s1 + "' and '" + s1 + "'");
  fs::create_directories(dir + "/copy");
  fs::copy(s1, dir + "/copy/s1", fs::copy_options::recursive);
  refused(s0 + " " + s1 + " " + dir + "/copy/s1 " + s2, "shard 1/3 is given twice");
  refused(s0 + " " + dir + "/other/shards/" + other_id + "-1-of-3 " + s2,
          "is a shard of another spec: sweep " + other_id + " ('other grid'), not sweep " + id + " ('shard grid')");
  refused(s0 + " " + s1 + " " + s2 + " " + dir + "/four/shards/" + id + "-1-of-4",
          "the stores are shards of different counts N");
  refused(s0 + " " + dir + " " + s2, "'" + dir + "' is not a shard store");
  // Another numerics version: the manifest of a store made by another build.
  fs::copy(s2, dir + "/copy/s2", fs::copy_options::recursive);
  std::string manifest = bistable_test::ReadText(dir + "/copy/s2/shard.json");
  manifest.replace(manifest.find("\"numerics_version\": \"") + 21, 5, "1.4.0");
  std::ofstream(dir + "/copy/s2/shard.json") << manifest;
  refused(s0 + " " + s1 + " " + dir + "/copy/s2",
          "'" + dir + "/copy/s2' was computed with numerics version 1.4.0, this bistable is numerics version");
  // Every shard once: merged.
  const ProcessResult ok = Bistable("merge " + spec + " " + s2 + " " + s0 + " " + s1 + " --data " + data);
  EXPECT_EQ(ok.exit_code, 0) << ok.err;
  EXPECT_TRUE(fs::exists(data + "/sweeps/" + id + ".h5"));
  fs::remove_all(dir);
}

}  // namespace
