// The sweep engine in process: spec validation, queries, map values equal to single-point runs bit
// for bit, and the content-keyed cache reusing points across overlapping sweeps. Real SQLite and
// HDF5 files in a temporary directory.
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <thread>

#include <gtest/gtest.h>
#include <sqlite3.h>
#include <future>

#include "base/sha256.h"
#include "dynamics/dopri5.h"
#include "dynamics/nondim_system.h"
#include "dynamics/point.h"
#include "engine/basins.h"
#include "engine/content_hash.h"
#include "engine/evaluate.h"
#include "engine/query.h"
#include "engine/refine.h"
#include "engine/sweep_kind.h"
#include "engine/sweep_spec.h"
#include "server/sweep_coordinator.h"
#include "storage/map_file.h"
#include "tests/map_compare.h"
#include "tests/process_util.h"
#include "tests/spec_fixture.h"

namespace bistable {
namespace {

std::string TempDir(const std::string& name) {
  const auto dir =
      std::filesystem::path(::testing::TempDir()) / ("bistable_" + name + "_" + std::to_string(::getpid()));
  std::filesystem::remove_all(dir);
  bistable_test::RemoveWhenAllPass(dir);
  return dir.string();
}

SweepSpec Parse(const std::string& toml) { return bistable_test::ParsedSpec(toml); }

// Runs a sweep like `bistable run` does, with `threads` worker threads; returns the map path.
std::string RunSweep(SweepCoordinator& c, const SweepSpec& spec, int threads, SweepPlan* plan) {
  auto p = c.Submit(spec, 16);
  EXPECT_TRUE(p.ok()) << p.status().ToString();
  *plan = *p;
  std::vector<std::thread> pool;
  for (int t = 0; t < threads; ++t)
    pool.emplace_back([&] {
      while (auto lease = c.Lease("test"))
        EXPECT_TRUE(c.Report(lease->lease_id, ComputeItems(spec, lease->items)).ok());
    });
  for (auto& th : pool) th.join();
  auto path = c.Publish(p->id);
  EXPECT_TRUE(path.ok()) << path.status().ToString();
  return path.ok() ? *path : "";
}

constexpr const char* kSmall = R"(
name = "test grid"
model = "coupled"
[axes]
alpha = { linspace = [0.2, 1.4, 5] }
omega = [0.8, 1.2, 2.0]
)";

// The sweep's state once it is no longer running (the publisher thread writes the map after the last
// report is acknowledged), waiting at most 10 s.
StatusOr<SweepInfo> AwaitFinalState(SweepCoordinator& c, const std::string& id) {
  for (int i = 0; i < 1000; ++i) {
    auto info = c.Info(id);
    if (!info.ok() || info->state != SweepState::kRunning) return info;
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  return c.Info(id);
}

TEST(SweepSpec, ParsesAxesDefaultsAndCanonicalOrder) {
  const SweepSpec s = Parse(R"(
model = "standalone"
[axes]
omega = { logspace = [0.1, 10, 3] }
alpha = { list = [0.5, 1.5] }
[params]
eta = 0.2
)");
  ASSERT_EQ(s.axes.size(), 2u);
  EXPECT_EQ(s.axes[0].name, "alpha");  // canonical order, whatever the file's order
  EXPECT_EQ(s.axes[1].name, "omega");
  EXPECT_NEAR(s.axes[1].values[1], 1.0, 1e-12);
  EXPECT_EQ(s.points(), 6);
  EXPECT_EQ(s.base.params.eta, 0.2);
  EXPECT_EQ(s.base.integration.t_end, 500.0);
  const PointSpec p = s.PointAt(4, 0);  // alpha index 1, omega index 1
  EXPECT_EQ(p.alpha, 1.5);
  EXPECT_NEAR(p.omega, 1.0, 1e-12);
  EXPECT_EQ(s.Id().size(), 12u);
  EXPECT_EQ(Parse(R"(
model = "standalone"
[params]
eta = 0.2
[axes]
alpha = { list = [0.5, 1.5] }
omega = { logspace = [0.1, 10, 3] }
)")
                .Id(),
            s.Id());  // ids depend on content, not on layout
}

TEST(SweepSpec, ShippedExamplesParse) {
  for (const auto& entry : std::filesystem::directory_iterator(BISTABLE_EXAMPLES_DIR)) {
    if (entry.path().extension() != ".toml") continue;
    std::ifstream in(entry.path());
    const std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    if (text.find("\n[design]") != std::string::npos) continue;  // design specs: tests/design_test.cc
    auto s = LoadSweepSpec(entry.path().string());
    EXPECT_TRUE(s.ok()) << entry.path() << ": " << s.status().ToString();
  }
}

TEST(SweepSpec, BadInputNamesTheFieldAndTheBound) {
  struct Case {
    const char* toml;
    const char* field;
    const char* fragment;
  };
  const Case cases[] = {
      {"model = \"coupled\"\n[axes\nalpha = [1]", "spec", "test.toml:2"},                       // malformed, with line
      {"model = \"coupled\"\n[params]\nlamda = 0.8", "params.lamda", "did you mean 'lambda'"},  // typo
      {"model = \"coupled\"\n[axis]\nalpha = [1]", "axis", "did you mean 'axes'"},
      {"model = \"duffing\"", "model", "model in {standalone, coupled"},
      {"[axes]\nalpha = [1]", "model", "required"},
      {"model = \"coupled\"\n[axes]\nalpha = { linspace = [0.1, 3.0, 0] }", "axes.alpha.linspace.count",
       "[1, 1048576]"},
      {"model = \"coupled\"\n[axes]\nalpha = { linspace = [3.0, 0.1, 5] }", "axes.alpha", "strictly increasing"},
      {"model = \"coupled\"\n[axes]\nalpha = []", "axes.alpha", "empty"},
      {"model = \"coupled\"\n[axes]\nalpha = [0.5, nan]", "axes.alpha[1]", "finite"},
      {"model = \"coupled\"\n[axes]\nalpha = [-1, 0.5]", "axes.alpha[0]", "alpha > 0"},
      {"model = \"coupled\"\n[params]\neta = -0.1", "params.eta", "eta >= 0"},
      {"model = \"coupled\"\n[axes]\nalpha = { linspace = [0.1, 3, 10000] }\nomega = { linspace = [0.1, 3, 10000] }",
       "axes.omega", "more than 4194304 points"},
      {"model = \"coupled\"\n[metrics]\nstore = [\"frf\"]", "metrics.store[0]", "did you mean 'frf_db'"},
      {"model = \"coupled\"\n[integration]\nt_keep = 600", "integration.t_keep", "< t_end"},
      {"model = \"coupled\"\n[axes]\nalpha = { linspace = [0.1, 3] }", "axes.alpha.linspace", "3 numbers"},
      {"model = \"coupled\"\n[initial_conditions]\nstates = [[1, 0, 1]]", "initial_conditions.states[0]", "[ym, vm"},
      // Settings [metrics] holds are named there (hd_level was reported as integration.hd_level).
      {"model = \"coupled\"\n[metrics]\nhd_level = 2.0", "metrics.hd_level", "in (0, 1)"},
      {"model = \"coupled\"\n[metrics]\nmax_period = 100", "metrics.max_period", "in [1, 64]"},
      // A long model name is cut in the message, not echoed whole.
      {"model = \"duffingduffingduffingduffingduffingduffingduffingduffingduffingduffingduffingduffingduffing\"",
       "model", "..."},
  };
  for (const Case& c : cases) {
    auto s = ParseSweepSpec(c.toml, "test.toml");
    ASSERT_FALSE(s.ok()) << c.toml;
    EXPECT_EQ(s.status().field(), c.field) << c.toml << "\n" << s.status().ToString();
    EXPECT_NE(s.status().message().find(c.fragment), std::string::npos) << c.toml << "\n" << s.status().ToString();
  }
}

TEST(Query, EvaluatesComparisonsConnectivesAndMotionNames) {
  const std::vector<std::string> names = {"alpha", "frf_db", "lle", "motion"};
  auto q = Query::Parse("frf_db < -3 and (lle < 0.01 or motion == chaotic) and not alpha >= 2", names);
  ASSERT_TRUE(q.ok()) << q.status().ToString();
  auto at = [](double a, double f, double l, double m) {
    return [=](int v) { return std::vector<double>{a, f, l, m}[v]; };
  };
  EXPECT_TRUE(q->Eval(at(1, -5, 0.0, 0)));
  EXPECT_TRUE(q->Eval(at(1, -5, 0.2, 2)));
  EXPECT_FALSE(q->Eval(at(1, -5, 0.2, 1)));
  EXPECT_FALSE(q->Eval(at(2, -5, 0.0, 0)));
  EXPECT_FALSE(q->Eval(at(1, NAN, 0.0, 0)));  // NaN never matches
  EXPECT_EQ(q->used().size(), 4u);
}

TEST(Query, CategoryWordsNameTheOtherSidesCodes) {
  // The names JSON prints are query words for both category metrics, either way round; a misspelt one is refused
  // with the metric's own names as suggestions.
  const std::vector<std::string> names = {"termination", "motion", "lle"};
  auto at = [](double t, double m) { return [=](int v) { return std::vector<double>{t, m, 0.0}[v]; }; };
  auto q = Query::Parse("termination == diverged or max_steps == termination", names);
  ASSERT_TRUE(q.ok()) << q.status().ToString();
  EXPECT_TRUE(q->Eval(at(1, 0)));
  EXPECT_TRUE(q->Eval(at(3, 0)));
  EXPECT_FALSE(q->Eval(at(0, 0)));
  auto m = Query::Parse("chaotic == motion and termination != diverged", names);
  ASSERT_TRUE(m.ok()) << m.status().ToString();
  EXPECT_TRUE(m->Eval(at(0, 2)));
  EXPECT_FALSE(m->Eval(at(1, 2)));
  auto bad = Query::Parse("termination == divreged", names);
  ASSERT_FALSE(bad.ok());
  EXPECT_NE(bad.status().message().find("termination value"), std::string::npos) << bad.status().message();
  EXPECT_NE(bad.status().message().find("did you mean 'diverged'"), std::string::npos) << bad.status().message();
  EXPECT_NE(bad.status().message().find("at 16"), std::string::npos)
      << "the word's position: " << bad.status().message();
  EXPECT_FALSE(Query::Parse("motion == diverged", names).ok()) << "a termination name is not a motion value";
}

TEST(Query, BadQueriesSayWhereAndSuggest) {
  const std::vector<std::string> names = {"frf_db", "lle"};
  auto a = Query::Parse("frf < 0", names);
  ASSERT_FALSE(a.ok());
  EXPECT_NE(a.status().message().find("did you mean 'frf_db'"), std::string::npos) << a.status().message();
  auto b = Query::Parse("frf_db < ", names);
  ASSERT_FALSE(b.ok());
  EXPECT_NE(b.status().message().find("expected a name or a number"), std::string::npos);
  auto c = Query::Parse("(lle < 0", names);
  ASSERT_FALSE(c.ok());
  EXPECT_NE(c.status().message().find("expected ')'"), std::string::npos);
  EXPECT_FALSE(Query::Parse("lle ! 0", names).ok());
}

// The issue's contract: a map value equals the one-point result bit for bit at the same settings,
// chaotic points included. The sweep runs 8 lanes per kernel call on 2 threads; the point runs alone.
TEST(SweepEngine, MapValuesEqualSinglePointRunsBitForBit) {
  const std::string dir = TempDir("bits");
  auto c = SweepCoordinator::Open(dir);
  ASSERT_TRUE(c.ok());
  const SweepSpec spec = Parse(R"(
model = "coupled"
[axes]
alpha = { linspace = [0.3, 2.0, 6] }
omega = { linspace = [0.5, 2.5, 7] }
)");
  SweepPlan plan;
  const std::string path = RunSweep(**c, spec, 2, &plan);
  auto frf = ReadMapMetric(path, "frf_db");
  auto lle = ReadMapMetric(path, "lle");
  auto hd = ReadMapMetric(path, "hd_index");
  ASSERT_TRUE(frf.ok() && lle.ok() && hd.ok());
  int chaotic = 0;
  for (long p = 0; p < spec.points(); p += 3) {
    auto r = EvaluatePoint(spec.PointAt(p, 0));
    ASSERT_TRUE(r.ok());
    EXPECT_EQ(std::memcmp(&r->frf_db, &frf->values[p], sizeof(double)), 0) << "point " << p;
    EXPECT_EQ(std::memcmp(&r->lle, &lle->values[p], sizeof(double)), 0) << "point " << p;
    EXPECT_EQ(std::memcmp(&r->hd_index, &hd->values[p], sizeof(double)), 0) << "point " << p;
    chaotic += r->motion == Motion::kChaotic;
  }
  EXPECT_GT(chaotic, 0) << "the sample must include chaotic points, where rounding differences would show";
  std::filesystem::remove_all(dir);
}

TEST(SweepEngine, OverlappingSweepReusesStoredPoints) {
  const std::string dir = TempDir("cache");
  auto c = SweepCoordinator::Open(dir);
  ASSERT_TRUE(c.ok());
  SweepPlan first, second;
  const SweepSpec a = Parse(kSmall);
  const std::string pa = RunSweep(**c, a, 2, &first);
  EXPECT_EQ(first.items_cached, 0);
  EXPECT_EQ(first.items_total, 15);
  // Same grid plus two more omega values: only the 10 new points are computed.
  const SweepSpec b = Parse(R"(
model = "coupled"
[axes]
alpha = { linspace = [0.2, 1.4, 5] }
omega = [0.8, 1.2, 1.6, 2.0, 2.4]
)");
  const std::string pb = RunSweep(**c, b, 2, &second);
  EXPECT_EQ(second.items_total, 25);
  EXPECT_EQ(second.items_cached, 15);
  EXPECT_EQ(second.jobs, 1);  // 10 missing items at 16 per job
  auto fa = ReadMapMetric(pa, "lle");
  auto fb = ReadMapMetric(pb, "lle");
  ASSERT_TRUE(fa.ok() && fb.ok());
  // omega 0.8 → column 0 in both; 2.0 → column 2 in a, 3 in b.
  for (int i = 0; i < 5; ++i) {
    EXPECT_EQ(fa->values[i * 3 + 0], fb->values[i * 5 + 0]);
    EXPECT_EQ(fa->values[i * 3 + 2], fb->values[i * 5 + 3]);
  }
  // Running the first spec again publishes nothing new and computes nothing.
  SweepPlan again;
  auto p = (*c)->Submit(a, 16);
  ASSERT_TRUE(p.ok());
  EXPECT_TRUE(p->already_published);
  std::filesystem::remove_all(dir);
}

TEST(SweepEngine, DuplicateReportIsAcknowledgedAndNotStoredTwice) {
  const std::string dir = TempDir("dup");
  auto c = SweepCoordinator::Open(dir);
  ASSERT_TRUE(c.ok());
  const SweepSpec spec = Parse(kSmall);
  auto plan = (*c)->Submit(spec, 8);
  ASSERT_TRUE(plan.ok());
  auto lease = (*c)->Lease("w1");
  ASSERT_TRUE(lease.has_value());
  const auto records = ComputeItems(spec, lease->items);
  ASSERT_TRUE((*c)->Report(lease->lease_id, records).ok());
  const long done = (*c)->progress(plan->id).items_done;
  ASSERT_TRUE((*c)->Report(lease->lease_id, records).ok());  // a retried report: acknowledged
  EXPECT_EQ((*c)->progress(plan->id).items_done, done);      // ... and not stored twice
  EXPECT_EQ((*c)->Report("no-such-lease", records).code(), Status::Code::kNotFound);
  auto other = (*c)->Lease("w2");
  ASSERT_TRUE(other.has_value());
  auto wrong_shape = records;
  wrong_shape.resize(3);  // jobs hold 8 and 7 items
  EXPECT_EQ((*c)->Report(other->lease_id, wrong_shape).field(), "values");
  auto nan_width = ComputeItems(spec, other->items);
  nan_width[0].v.pop_back();
  EXPECT_EQ((*c)->Report(other->lease_id, nan_width).field(), "records");
  std::filesystem::remove_all(dir);
}

// The sweep list (`bistable sweeps`, the dashboard) says what Info says of each sweep: a sweep finished before
// this process started, from its index row; an active one with the workers holding its leases.
TEST(SweepEngine, SweepListAgreesWithInfo) {
  const std::string dir = TempDir("list");
  std::string old_id;
  {
    auto c = SweepCoordinator::Open(dir);
    ASSERT_TRUE(c.ok());
    SweepPlan plan;
    RunSweep(**c, Parse(kSmall), 2, &plan);
    old_id = plan.id;
  }
  auto c = SweepCoordinator::Open(dir);
  ASSERT_TRUE(c.ok());
  auto plan = (*c)->Submit(Parse(R"(
model = "coupled"
[axes]
alpha = { linspace = [0.3, 1.1, 4] }
omega = [0.9, 1.3, 1.7, 2.1]
)"),
                           4);
  ASSERT_TRUE(plan.ok());
  auto a = (*c)->Lease("w1");
  auto b = (*c)->Lease("w2");
  auto a2 = (*c)->Lease("w1");
  ASSERT_TRUE(a && b && a2);
  auto list = (*c)->ListSweeps();
  ASSERT_TRUE(list.ok()) << list.status().ToString();
  ASSERT_EQ(list->size(), 2u);
  for (const SweepInfo& s : *list) {
    auto one = (*c)->Info(s.id);
    ASSERT_TRUE(one.ok());
    EXPECT_EQ(s.name, one->name);
    EXPECT_EQ(s.state, one->state) << s.id;
    EXPECT_EQ(s.items_total, one->items_total);
    EXPECT_EQ(s.items_done, one->items_done);
    EXPECT_EQ(s.items_cached, one->items_cached);
    EXPECT_EQ(s.workers, one->workers);
    EXPECT_EQ(s.file, one->file);
  }
  const SweepInfo& old = (*list)[0].id == old_id ? (*list)[0] : (*list)[1];
  const SweepInfo& now = (*list)[0].id == old_id ? (*list)[1] : (*list)[0];
  EXPECT_EQ(old.state, SweepState::kDone);
  EXPECT_EQ(old.items_done, 15);
  EXPECT_FALSE(old.file.empty());
  EXPECT_EQ(now.id, plan->id);
  EXPECT_EQ(now.state, SweepState::kRunning);
  EXPECT_EQ(now.workers, 2);  // w1 holds two leases
  std::filesystem::remove_all(dir);
}

// Group commit: concurrent reports share transactions; every job is stored and counted exactly once
// and the published map equals the one computed by a single reporter.
TEST(SweepEngine, ConcurrentReportsAreStoredOnceAndGiveTheSameMap) {
  const SweepSpec spec = Parse(kSmall);
  std::vector<std::string> files;
  for (int threads : {1, 6}) {
    const std::string dir = TempDir("group_commit_" + std::to_string(threads));
    {
      auto c = SweepCoordinator::Open(dir);
      ASSERT_TRUE(c.ok());
      auto plan = (*c)->Submit(spec, 1);  // 15 jobs of one item
      ASSERT_TRUE(plan.ok());
      ASSERT_EQ(plan->jobs, 15);
      std::atomic<int> reports{0};
      std::vector<std::thread> pool;
      for (int t = 0; t < threads; ++t)
        pool.emplace_back([&] {
          while (auto lease = (*c)->Lease("w")) {
            const auto records = ComputeItems(spec, lease->items);
            EXPECT_TRUE((*c)->Report(lease->lease_id, records).ok());
            EXPECT_TRUE((*c)->Report(lease->lease_id, records).ok());  // a retry: acknowledged, not stored again
            ++reports;
          }
        });
      for (auto& th : pool) th.join();
      EXPECT_EQ(reports.load(), 15);
      auto info = AwaitFinalState(**c, plan->id);
      ASSERT_TRUE(info.ok());
      EXPECT_EQ(info->state, SweepState::kDone);
      EXPECT_EQ(info->items_done, 15);
    }
    auto db = IndexDb::Open(dir + "/index.sqlite");
    ASSERT_TRUE(db.ok());
    std::unordered_map<std::string, std::vector<double>> left;
    ASSERT_TRUE((*db)->FoldResults(&left).ok());
    EXPECT_TRUE(left.empty()) << "publication folds the staged records (beside the map's writing) before its index row";
    EXPECT_EQ((*db)->CachedPointCount(), 15);
    files.push_back(dir + "/sweeps/" + spec.Id() + ".h5");
  }
  bistable_test::ExpectSameMaps(files[0], files[1]);
}

TEST(SweepEngine, ExpiredLeasesAreRequeuedAndRejected) {
  const std::string dir = TempDir("lease");
  auto c = SweepCoordinator::Open(dir, {.lease_seconds = 0.05, .resume = true});
  ASSERT_TRUE(c.ok());
  const SweepSpec spec = Parse(kSmall);
  auto plan = (*c)->Submit(spec, 16);  // one job
  ASSERT_TRUE(plan.ok());
  ASSERT_EQ(plan->jobs, 1);
  auto first = (*c)->Lease("slow");
  ASSERT_TRUE(first.has_value());
  EXPECT_FALSE((*c)->Lease("fast").has_value());  // the only job is out
  std::this_thread::sleep_for(std::chrono::milliseconds(120));
  EXPECT_EQ((*c)->Extend(first->lease_id).code(), Status::Code::kFailedPrecondition);
  auto second = (*c)->Lease("fast");  // the expired lease's job came back
  ASSERT_TRUE(second.has_value());
  EXPECT_EQ(second->job_id, first->job_id);
  const auto records = ComputeItems(spec, second->items);
  EXPECT_EQ((*c)->Report(first->lease_id, records).code(), Status::Code::kNotFound);  // requeued: gone
  ASSERT_TRUE((*c)->Report(second->lease_id, records).ok());
  auto info = AwaitFinalState(**c, plan->id);
  ASSERT_TRUE(info.ok());
  EXPECT_EQ(info->state, SweepState::kDone);  // the last report queued the publication
  EXPECT_TRUE(std::filesystem::exists((*c)->MapPath(plan->id)));
  std::filesystem::remove_all(dir);
}

// Lease deadlines follow the monotonic clock: the wall clock stepping an hour forward (NTP, a resumed VM)
// expires nothing — the report is stored and the job is not leased twice — while the monotonic clock passing
// the deadline does. The lease's deadline on the wire stays wall time.
TEST(SweepEngine, LeasesExpireByTheMonotonicClockNotTheWallClock) {
  const std::string dir = TempDir("clockjump");
  double wall = 1e9, mono = 100;
  auto c = SweepCoordinator::Open(
      dir,
      {.lease_seconds = 10, .resume = true, .clock = [&wall] { return wall; }, .monotonic = [&mono] { return mono; }});
  ASSERT_TRUE(c.ok());
  const SweepSpec spec = Parse(kSmall);  // 15 items
  auto plan = (*c)->Submit(spec, 8);     // jobs of 8 and 7
  ASSERT_TRUE(plan.ok());
  auto first = (*c)->Lease("w1");
  ASSERT_TRUE(first.has_value());
  EXPECT_DOUBLE_EQ(first->deadline, wall + 10);
  wall += 3600;  // the wall clock jumps; no time passes
  auto second = (*c)->Lease("w2");
  ASSERT_TRUE(second.has_value());
  EXPECT_NE(second->job_id, first->job_id);  // the first lease was not expired and requeued
  EXPECT_TRUE((*c)->Extend(first->lease_id).ok());
  ASSERT_TRUE((*c)->Report(first->lease_id, ComputeItems(spec, first->items)).ok());
  mono += 11;  // now the second lease's deadline passes
  EXPECT_EQ((*c)->Report(second->lease_id, ComputeItems(spec, second->items)).code(),
            Status::Code::kFailedPrecondition);
  auto again = (*c)->Lease("w3");
  ASSERT_TRUE(again.has_value());
  EXPECT_EQ(again->job_id, second->job_id);
  ASSERT_TRUE((*c)->Report(again->lease_id, ComputeItems(spec, again->items)).ok());
  auto info = AwaitFinalState(**c, plan->id);
  ASSERT_TRUE(info.ok());
  EXPECT_EQ(info->state, SweepState::kDone);
  EXPECT_EQ(info->items_done, 15);
  std::filesystem::remove_all(dir);
}

// Issue 40: a lease carries its spec's key (SHA-256 of the text, computed once per plan), not the text;
// the text is asked for once, by key, by whoever lacks it.
TEST(SweepEngine, ALeaseCarriesItsSpecsKey) {
  const std::string dir = TempDir("spec_key");
  auto c = SweepCoordinator::Open(dir);
  ASSERT_TRUE(c.ok());
  const SweepSpec spec = Parse(kSmall);
  ASSERT_TRUE((*c)->Submit(spec, 8).ok());
  auto lease = (*c)->Lease("w");
  ASSERT_TRUE(lease.has_value());
  EXPECT_EQ(lease->spec_key, Sha256Hex(spec.source));
  std::string key;
  auto text = (*c)->SpecText(spec.Id(), &key);
  ASSERT_TRUE(text.ok());
  EXPECT_EQ(*text, spec.source);
  EXPECT_EQ(key, lease->spec_key);
  std::filesystem::remove_all(dir);
}

// Issue 40: a publication starts in one place, the publisher's thread: Publish (the embedded run's, a
// submit of a sweep found wholly stored) asks it and waits; it never writes the map on the caller's thread.
TEST(SweepEngine, PublicationRunsOnThePublishersThreadOnly) {
  const std::string dir = TempDir("publisher_thread");
  const SweepSpec spec = Parse(kSmall);
  std::mutex mu;
  std::vector<std::thread::id> writers;  // the threads that reached a map's index row
  SweepCoordinator::Options opt;
  opt.before_index_row = [&] {
    std::lock_guard<std::mutex> lock(mu);
    writers.push_back(std::this_thread::get_id());
  };
  {
    auto c = SweepCoordinator::Open(dir, opt);
    ASSERT_TRUE(c.ok());
    SweepPlan plan;
    RunSweep(**c, spec, 1, &plan);
  }
  // The map goes missing: a submit finds every item stored and publishes at once (before issue 40, inline
  // on the submitting thread).
  ASSERT_TRUE(std::filesystem::remove(std::filesystem::path(dir) / "sweeps" / (spec.Id() + ".h5")));
  auto c = SweepCoordinator::Open(dir, opt);
  ASSERT_TRUE(c.ok());
  auto plan = (*c)->Submit(spec, 8);
  ASSERT_TRUE(plan.ok()) << plan.status().ToString();
  EXPECT_EQ(plan->jobs, 0);
  auto info = (*c)->Info(spec.Id());
  ASSERT_TRUE(info.ok());
  EXPECT_EQ(info->state, SweepState::kDone) << "published before Submit returned";
  std::lock_guard<std::mutex> lock(mu);
  ASSERT_EQ(writers.size(), 2u);
  for (const std::thread::id& t : writers) EXPECT_NE(t, std::this_thread::get_id());
  std::filesystem::remove_all(dir);
}

// A cancel that arrives while the complete sweep's map is being published is refused: before, it was
// acknowledged and then the index row said "done" (the publication wrote it after the cancel).
TEST(SweepEngine, CancelDuringPublicationIsRefused) {
  const std::string dir = TempDir("cancel_publish");
  std::promise<void> reached, release;
  std::shared_future<void> go = release.get_future().share();
  std::atomic<bool> first{true};
  auto c = SweepCoordinator::Open(dir, {.before_index_row = [&] {
                                    if (first.exchange(false)) reached.set_value(), go.wait();
                                  }});
  ASSERT_TRUE(c.ok());
  const SweepSpec spec = Parse(kSmall);
  auto plan = (*c)->Submit(spec, 16);  // one job
  ASSERT_TRUE(plan.ok());
  auto lease = (*c)->Lease("w");
  ASSERT_TRUE(lease.has_value());
  ASSERT_TRUE((*c)->Report(lease->lease_id, ComputeItems(spec, lease->items)).ok());  // queues the publication
  reached.get_future().wait();  // the map file is written; its index row is not
  const Status cancel = (*c)->Cancel(plan->id);
  EXPECT_EQ(cancel.code(), Status::Code::kFailedPrecondition) << cancel.ToString();
  EXPECT_NE(cancel.ToString().find("being published"), std::string::npos) << cancel.ToString();
  release.set_value();
  auto info = AwaitFinalState(**c, plan->id);
  ASSERT_TRUE(info.ok());
  EXPECT_EQ(info->state, SweepState::kDone);
  EXPECT_TRUE(std::filesystem::exists((*c)->MapPath(plan->id)));
  EXPECT_EQ((*c)->Cancel(plan->id).code(), Status::Code::kFailedPrecondition);  // done now
  std::filesystem::remove_all(dir);
}

// --jobs-per-lease: queued jobs of one sweep merged into one lease (at most 4096 items), reported
// as one, requeued together in their order when the lease expires, and the map is the same.
TEST(SweepEngine, MergedLeasesCoverSeveralJobsAndRequeueTogether) {
  const std::string dir = TempDir("merged");
  double now = 1e9;
  auto c = SweepCoordinator::Open(dir, {.lease_seconds = 10, .resume = true, .clock = [&now] { return now; }});
  ASSERT_TRUE(c.ok());
  const SweepSpec spec = Parse(kSmall);  // 15 items
  auto plan = (*c)->Submit(spec, 4);     // jobs of 4, 4, 4, 3
  ASSERT_TRUE(plan.ok());
  ASSERT_EQ(plan->jobs, 4);
  auto merged = (*c)->Lease("far", "", 3);
  ASSERT_TRUE(merged.has_value());
  EXPECT_EQ(merged->jobs, 3);
  EXPECT_EQ(merged->items.size(), 12u);
  // A report must cover every merged item: one job's worth is refused, nothing stored.
  const auto part = ComputeItems(spec, std::vector<WorkItem>(merged->items.begin(), merged->items.begin() + 4));
  EXPECT_EQ((*c)->Report(merged->lease_id, part).code(), Status::Code::kInvalidArgument);
  // Expiry gives all three jobs back, first in line and in order: a single lease now gets the first.
  now += 11;
  auto again = (*c)->Lease("near", "", 1);
  ASSERT_TRUE(again.has_value());
  EXPECT_EQ(again->job_id, merged->job_id);
  ASSERT_EQ(again->items.size(), 4u);
  for (size_t i = 0; i < 4; ++i)
    EXPECT_TRUE(again->items[i].point == merged->items[i].point && again->items[i].ic == merged->items[i].ic) << i;
  EXPECT_EQ((*c)->Report(merged->lease_id, ComputeItems(spec, merged->items)).code(), Status::Code::kNotFound);
  ASSERT_TRUE((*c)->Report(again->lease_id, ComputeItems(spec, again->items)).ok());
  // The rest in one lease of up to 16 jobs: three jobs, 11 items.
  auto rest = (*c)->Lease("far", "", 16);
  ASSERT_TRUE(rest.has_value());
  EXPECT_EQ(rest->jobs, 3);
  EXPECT_EQ(rest->items.size(), 11u);
  EXPECT_FALSE((*c)->Lease("near").has_value());
  ASSERT_TRUE((*c)->Report(rest->lease_id, ComputeItems(spec, rest->items)).ok());
  auto info = AwaitFinalState(**c, plan->id);
  ASSERT_TRUE(info.ok());
  EXPECT_EQ(info->state, SweepState::kDone);
  EXPECT_EQ(info->items_done, 15);
  // The same map as single-job leases give.
  const std::string ref_dir = TempDir("merged_ref");
  auto r = SweepCoordinator::Open(ref_dir);
  ASSERT_TRUE(r.ok());
  SweepPlan ref_plan;
  const std::string ref = RunSweep(**r, spec, 1, &ref_plan);
  bistable_test::ExpectSameMaps((*c)->MapPath(plan->id), ref);
  std::filesystem::remove_all(dir);
  std::filesystem::remove_all(ref_dir);
}

// A lookup that leaves the staged records staged (publication folds them on another thread while it
// writes the map) finds what a folding lookup finds, skips a corrupt staged row the same way, and
// leaves the rows for the fold, which then hands back the same records.
TEST(SweepEngine, LookupWithoutFoldingFindsWhatFoldingFinds) {
  const SweepSpec spec = Parse(kSmall);
  std::vector<WorkItem> all;
  for (long p = 0; p < spec.points(); ++p) all.push_back({p, 0});
  const auto rec = ComputeItems(spec, all);
  std::vector<std::string> keys;
  std::vector<IndexDb::JobResults> jobs;
  for (size_t i = 0; i < all.size(); ++i) {
    if (i % 4 == 0) jobs.push_back({spec.Id(), rec[0].v.size(), "", {}});
    keys.push_back(spec.ItemKey(all[i].point, 0));
    jobs.back().keys += keys.back() + "\n";
    jobs.back().values.insert(jobs.back().values.end(), rec[i].v.begin(), rec[i].v.end());
  }
  ASSERT_GE(jobs.size(), 3u);
  const std::string dir = TempDir("lookup_later");
  std::filesystem::create_directories(dir);
  std::unordered_map<std::string, std::vector<double>> by_fold;
  std::unordered_map<std::string, PointRecord> folded_lookup;
  auto same_bits = [](const std::vector<double>& a, const std::vector<double>& b) {  // NaN metrics included
    return a.size() == b.size() && std::memcmp(a.data(), b.data(), a.size() * sizeof(double)) == 0;
  };
  for (int variant = 0; variant < 2; ++variant) {
    const std::string path = dir + "/index" + std::to_string(variant) + ".sqlite";
    auto db = IndexDb::Open(path);
    ASSERT_TRUE(db.ok());
    ASSERT_TRUE((*db)->PutPoints(jobs).ok());
    {  // corrupt the second staged row's records: its four points go missing either way
      sqlite3* raw = nullptr;
      ASSERT_EQ(sqlite3_open(path.c_str(), &raw), SQLITE_OK);
      ASSERT_EQ(
          sqlite3_exec(
              raw,
              "UPDATE results SET records = zeroblob(length(records)) WHERE seq = (SELECT min(seq) + 1 FROM results)",
              nullptr, nullptr, nullptr),
          SQLITE_OK);
      sqlite3_close(raw);
    }
    long corrupt = -1;
    auto found =
        (*db)->LookupPoints(keys, rec[0].v.size(), &corrupt, variant ? IndexDb::Fold::kLater : IndexDb::Fold::kNow);
    ASSERT_TRUE(found.ok());
    EXPECT_EQ(corrupt, 0) << "the corrupt row is a staged one, not a cached record";
    EXPECT_EQ(found->size(), keys.size() - 4);
    for (size_t i = 4; i < 8; ++i) EXPECT_EQ(found->count(keys[i]), 0u) << "the corrupt row's point " << i;
    if (variant == 0) {
      folded_lookup = *found;
      EXPECT_EQ((*db)->corrupt_rows(), 1);
      std::unordered_map<std::string, std::vector<double>> left;
      ASSERT_TRUE((*db)->FoldResults(&left).ok());
      EXPECT_TRUE(left.empty()) << "kNow folded everything";
      continue;
    }
    ASSERT_EQ(found->size(), folded_lookup.size());
    for (const auto& [k, r] : *found) EXPECT_TRUE(same_bits(r.v, folded_lookup.at(k).v)) << k;
    EXPECT_EQ((*db)->corrupt_rows(), 0) << "counted by the fold, not by the read";
    ASSERT_TRUE((*db)->FoldResults(&by_fold).ok());
    EXPECT_EQ((*db)->corrupt_rows(), 1);
    EXPECT_EQ(by_fold.size(), found->size()) << "the rows were left staged for the fold";
    for (const auto& [k, r] : *found) EXPECT_TRUE(same_bits(by_fold.at(k), r.v)) << k;
    EXPECT_EQ((*db)->CachedPointCount(), static_cast<long>(found->size()));
  }
  std::filesystem::remove_all(dir);
}

// Staged records override the point cache and, where a key repeats among them, the later report wins —
// with and without folding; and a lookup that does not fold pages through more staged rows than one read.
TEST(SweepEngine, StagedRecordsOverrideTheCacheAndTheLaterReportWins) {
  const std::string dir = TempDir("lookup_order");
  std::filesystem::create_directories(dir);
  auto job = [](const std::vector<std::string>& keys, double value) {
    IndexDb::JobResults j{"s", 2, "", {}};
    for (const std::string& k : keys) j.keys += k + "\n", j.values.push_back(value), j.values.push_back(-value);
    return j;
  };
  for (IndexDb::Fold fold : {IndexDb::Fold::kNow, IndexDb::Fold::kLater}) {
    auto db = IndexDb::Open(dir + (fold == IndexDb::Fold::kNow ? "/now.sqlite" : "/later.sqlite"));
    ASSERT_TRUE(db.ok());
    ASSERT_TRUE((*db)->PutPoints({job({"a", "b"}, 1.0)}).ok());
    ASSERT_EQ((*db)->CachedPointCount(), 2);  // folded: a and b are in the point cache with 1
    std::vector<IndexDb::JobResults> staged;
    for (int i = 0; i < 5000; ++i)
      staged.push_back(job({std::string("k").append(std::to_string(i))}, i));  // more rows than one page of reads
    staged.push_back(job({"a"}, 2.0));
    staged.push_back(job({"a"}, 3.0));  // the later report of a
    ASSERT_TRUE((*db)->PutPoints(staged).ok());
    long corrupt = -1;
    auto found = (*db)->LookupPoints({"a", "b", "k0", "k4999", "missing"}, 2, &corrupt, fold);
    ASSERT_TRUE(found.ok());
    EXPECT_EQ(corrupt, 0);
    EXPECT_EQ(found->size(), 4u);
    EXPECT_EQ(found->at("a").v, (std::vector<double>{3.0, -3.0})) << "staged over cached, the later over the earlier";
    EXPECT_EQ(found->at("b").v, (std::vector<double>{1.0, -1.0}));
    EXPECT_EQ(found->at("k4999").v, (std::vector<double>{4999.0, -4999.0}));
    EXPECT_EQ((*db)->CachedPointCount(), 5002);
    auto again = (*db)->LookupPoints({"a"}, 2, nullptr);
    ASSERT_TRUE(again.ok());
    EXPECT_EQ(again->at("a").v, (std::vector<double>{3.0, -3.0})) << "and so folded";
  }
  std::filesystem::remove_all(dir);
}

// Found by bench/fault_run.sh: a coordinator killed after storing the last report but before
// publishing came back with nothing to compute and waited forever for a report.
TEST(SweepEngine, ReopenedCoordinatorPublishesASweepWhoseItemsAreAllStored) {
  const std::string dir = TempDir("allstored");
  const SweepSpec spec = Parse(kSmall);
  {
    auto c = SweepCoordinator::Open(dir);
    ASSERT_TRUE(c.ok());
    auto plan = (*c)->Submit(spec, 64);
    ASSERT_TRUE(plan.ok());
  }
  {  // Store every item directly, as if the last report landed and the process died before publishing.
    auto db = IndexDb::Open(dir + "/index.sqlite");
    ASSERT_TRUE(db.ok());
    std::vector<WorkItem> all;
    for (long p = 0; p < spec.points(); ++p) all.push_back({p, 0});
    const auto rec = ComputeItems(spec, all);
    IndexDb::JobResults rows{spec.Id(), rec[0].v.size(), "", {}};
    for (size_t i = 0; i < all.size(); ++i) {
      rows.keys += spec.ItemKey(all[i].point, 0) + "\n";
      rows.values.insert(rows.values.end(), rec[i].v.begin(), rec[i].v.end());
    }
    ASSERT_TRUE((*db)->PutPoints({rows}).ok());
  }
  auto c = SweepCoordinator::Open(dir);
  ASSERT_TRUE(c.ok());
  auto info = (*c)->Info(spec.Id());
  ASSERT_TRUE(info.ok());
  EXPECT_EQ(info->state, SweepState::kDone);
  EXPECT_TRUE(std::filesystem::exists((*c)->MapPath(spec.Id())));
  std::filesystem::remove_all(dir);
}

TEST(SweepEngine, ReopenedCoordinatorResumesUnfinishedSweeps) {
  const std::string dir = TempDir("resume");
  const SweepSpec spec = Parse(kSmall);
  std::string id;
  {
    auto c = SweepCoordinator::Open(dir);
    ASSERT_TRUE(c.ok());
    auto plan = (*c)->Submit(spec, 8);
    ASSERT_TRUE(plan.ok());
    id = plan->id;
    auto lease = (*c)->Lease("w");
    ASSERT_TRUE((*c)->Report(lease->lease_id, ComputeItems(spec, lease->items)).ok());
    (*c)->Lease("w");  // leased, never reported: lost with the "crash" below
  }
  auto c = SweepCoordinator::Open(dir);
  ASSERT_TRUE(c.ok());
  auto info = (*c)->Info(id);
  ASSERT_TRUE(info.ok());
  EXPECT_EQ(info->items_done, 8);  // the acknowledged job is still there
  int jobs = 0;
  while (auto lease = (*c)->Lease("w")) {
    ASSERT_TRUE((*c)->Report(lease->lease_id, ComputeItems(spec, lease->items)).ok());
    ++jobs;
  }
  EXPECT_GE(jobs, 1);
  EXPECT_EQ(AwaitFinalState(**c, id)->state, SweepState::kDone);
  std::filesystem::remove_all(dir);
}

TEST(SweepEngine, SeveralInitialConditionsGiveMotionFractions) {
  const std::string dir = TempDir("ic");
  auto c = SweepCoordinator::Open(dir);
  ASSERT_TRUE(c.ok());
  const SweepSpec spec = Parse(R"(
model = "standalone"
[axes]
alpha = [0.1, 0.3]
omega = [0.8, 1.2]
[initial_conditions]
states = [[1, 0], [-1, 0], [0.0, 1.0]]
)");
  SweepPlan plan;
  const std::string path = RunSweep(**c, spec, 1, &plan);
  EXPECT_EQ(plan.items_total, 12);
  auto motion = ReadMapMetric(path, "motion");
  auto fi = ReadMapMetric(path, "frac_intrawell");
  auto fw = ReadMapMetric(path, "frac_interwell");
  auto fc = ReadMapMetric(path, "frac_chaotic");
  ASSERT_TRUE(motion.ok() && fi.ok() && fw.ok() && fc.ok());
  EXPECT_EQ(motion->dims, (std::vector<size_t>{2, 2, 3}));
  EXPECT_EQ(motion->dim_names.back(), "ic");
  for (size_t p = 0; p < 4; ++p) {
    EXPECT_NEAR(fi->values[p] + fw->values[p] + fc->values[p], 1.0, 1e-12);
    int intra = 0;
    for (int i = 0; i < 3; ++i) intra += motion->values[p * 3 + i] == 0;
    EXPECT_DOUBLE_EQ(fi->values[p], intra / 3.0);
  }
  std::filesystem::remove_all(dir);
}

// A basin map against brute force: every start integrated on its own by Dormand–Prince (rtol 1e-10,
// an integrator the sweep does not use) and classified by the well its orbit ends in. The double-well
// Duffing at gamma 0.2 has two period-1 attractors, one per well, with intertwined basins.
TEST(SweepEngine, BasinMapAgreesWithBruteForceClassification) {
  const std::string dir = TempDir("basins");
  auto c = SweepCoordinator::Open(dir);
  ASSERT_TRUE(c.ok());
  const SweepSpec spec = Parse(R"(
model = "standalone"
[params]
eta = 0.3
omega = 1.2
alpha = 0.1388888888888889
[axes]
ym0 = { linspace = [-2.0, 2.0, 31] }
vm0 = { linspace = [-2.0, 2.0, 31] }
[metrics]
store = ["motion", "period", "y_min", "y_max", "strobe_y", "strobe_v"]
)");
  ASSERT_TRUE(spec.IsBasinSweep());
  SweepPlan plan;
  const std::string path = RunSweep(**c, spec, 2, &plan);
  auto ids = ReadMapMetric(path, "attractor");
  ASSERT_TRUE(ids.ok()) << ids.status().ToString();
  EXPECT_EQ(ids->dim_names, (std::vector<std::string>{"vm0", "ym0"}));
  ASSERT_EQ(ids->categories.size(), 2u);  // one attractor per well
  const std::string a0 = ids->categories[0].second, a1 = ids->categories[1].second;
  EXPECT_NE(a0.find("P1"), std::string::npos) << a0;
  EXPECT_NE(a1.find("P1"), std::string::npos) << a1;
  // Which id is the +well orbit.
  const int plus_id = a0.find("+well") != std::string::npos ? 0 : 1;
  NondimSystem<SingleModel> sys(LaneFor(spec.PointAt(0, 0)).coeffs, spec.base.alpha, spec.base.omega);
  AdaptiveOptions ao;
  ao.rtol = ao.atol = 1e-10;
  int agree = 0, total = 0;
  for (size_t i = 0; i < ids->dims[0]; ++i)
    for (size_t j = 0; j < ids->dims[1]; ++j) {
      Eigen::Vector2d x(ids->axes[1].values[j], ids->axes[0].values[i]);  // (ym0, vm0)
      Dopri5<NondimSystem<SingleModel>>(sys, ao).Integrate(0.0, x, 500.0);
      const int brute = x[0] > 0 ? plus_id : 1 - plus_id;  // both orbits stay inside their well
      agree += brute == static_cast<int>(ids->values[i * ids->dims[1] + j]);
      ++total;
    }
  // Starts on a basin boundary may go either way under a different integrator; all others agree.
  EXPECT_GE(agree, total - total / 50) << agree << " of " << total;
  // Basin fractions sum to 1 and match the map.
  long plus = 0;
  for (double v : ids->values) plus += v == plus_id;
  const BasinMap again = [&] {
    std::vector<PointRecord> records;
    for (long p = 0; p < spec.points(); ++p) records.push_back(PointRecord::From(EvaluateItem(spec, p, 0)));
    return ClassifyAttractors(spec, records, 10 * spec.base.metrics.period_tol);
  }();
  ASSERT_EQ(again.attractors.size(), 2u);
  EXPECT_DOUBLE_EQ(again.attractors[plus_id].basin_fraction, static_cast<double>(plus) / total);
  EXPECT_NEAR(again.attractors[0].basin_fraction + again.attractors[1].basin_fraction, 1.0, 1e-12);
  EXPECT_GT(again.boundary_fraction, 0.0);
  EXPECT_LT(again.boundary_fraction, 0.5);
  std::filesystem::remove_all(dir);
}

// A map whose starts end on more kinds than the limit (here: 400 distinct period-1 fingerprints) keeps
// the classification bounded: the 255 first kinds, then one "other" class for the rest.
TEST(Basins, KindsPastTheLimitShareOneClass) {
  const SweepSpec spec = Parse("model = \"standalone\"\n[axes]\nym0 = { linspace = [-2.0, 2.0, 400] }\n");
  ASSERT_TRUE(spec.IsBasinSweep());
  std::vector<PointRecord> records(400);
  for (int i = 0; i < 400; ++i) {
    records[i].v.assign(PointRecord::Size(), 0.0);
    records[i].v[MetricIndex("motion")] = 0;
    records[i].v[MetricIndex("period")] = 1;
    records[i].v[MetricIndex("y_min")] = 0.5;
    records[i].v[MetricIndex("y_max")] = 1.5;
    records[i].v[MetricIndex("strobe_y")] = i;  // 400 different orbits
    records[i].v[MetricIndex("strobe_v")] = 0;
  }
  const BasinMap b = ClassifyAttractors(spec, records, 0.01);
  ASSERT_EQ(b.attractors.size(), 256u);
  const Attractor& other = b.attractors[0];  // the largest class: 400 - 255 starts
  EXPECT_EQ(other.cells, 400 - 255);
  EXPECT_NE(other.label.find("other"), std::string::npos) << other.label;
  long total = 0;
  for (const Attractor& a : b.attractors) total += a.cells;
  EXPECT_EQ(total, 400);
}

// Robustness maps: with no tolerance every sample is the same point, so every probability is 0 or 1;
// with tolerances a band of intermediate probabilities appears at the regime boundaries and widens
// with the tolerance, while points far from any boundary stay 0 or 1. Samples are seeded: the same
// seed gives the same map, another seed another sample set.
TEST(SweepEngine, RobustnessBandWidensWithTheTolerance) {
  const std::string dir = TempDir("robust");
  auto c = SweepCoordinator::Open(dir);
  ASSERT_TRUE(c.ok());
  auto spec_for = [](double tol, int seed) {
    char t[640];
    std::snprintf(t, sizeof t, R"(
model = "coupled"
[params]
alpha = 0.5
[axes]
omega = { linspace = [0.3, 2.5, 45] }
[metrics]
store = ["motion", "lle"]
[robustness]
samples = 16
seed = %d
tolerance = { eta = %g, lambda = %g, eps = %g }
ic_radius = %g
)",
                  seed, 4 * tol, tol, tol, tol);
    return Parse(t);
  };
  auto band = [&](const SweepSpec& spec, std::vector<double>* chaotic) {
    SweepPlan plan;
    const std::string path = RunSweep(**c, spec, 2, &plan);
    EXPECT_EQ(plan.items_total, 45 * 16);
    auto fc = ReadMapMetric(path, "frac_chaotic");
    auto fw = ReadMapMetric(path, "frac_interwell");
    auto se = ReadMapMetric(path, "frac_chaotic_stderr");
    EXPECT_TRUE(fc.ok() && fw.ok() && se.ok());
    if (!fc.ok() || !fw.ok() || !se.ok()) return -1;
    int mid = 0;
    for (size_t i = 0; i < fc->values.size(); ++i) {
      const double p = fc->values[i], q = fw->values[i];
      mid += (p > 0 && p < 1) || (q > 0 && q < 1);
      EXPECT_DOUBLE_EQ(se->values[i], std::sqrt(p * (1 - p) / 16));
    }
    *chaotic = fc->values;
    return mid;
  };
  std::vector<double> c0, c1, c5, c5b, c5s;
  const int none = band(spec_for(0.0, 7), &c0), small = band(spec_for(0.01, 7), &c1),
            wide = band(spec_for(0.05, 7), &c5);
  EXPECT_EQ(none, 0);  // identical samples: 0 or 1 everywhere
  EXPECT_GT(small, 0);
  EXPECT_GT(wide, small) << "the band widens with the tolerance";
  // Far from any boundary (Omega 1.2-1.45 is periodic intrawell for every sample): probability 0.
  for (size_t i = 18; i <= 23; ++i) EXPECT_EQ(c5[i], 0.0) << "omega index " << i;
  band(spec_for(0.05, 7), &c5b);
  EXPECT_EQ(c5, c5b);  // reproducible
  band(spec_for(0.05, 8), &c5s);
  EXPECT_NE(c5, c5s);  // another seed, another sample set
  std::filesystem::remove_all(dir);
}

// A refined sweep ([refine]) through the coordinator: lease and report until no work is left, publish
// (which plans the next level while one is left), round after round.
std::string RunRefined(SweepCoordinator& c, const SweepSpec& spec, SweepPlan* plan, int* rounds) {
  auto p = c.Submit(spec, 64);
  EXPECT_TRUE(p.ok()) << p.status().ToString();
  if (!p.ok()) return "";
  *plan = *p;
  for (*rounds = 1; *rounds <= 1000; ++*rounds) {
    while (auto lease = c.Lease("test")) EXPECT_TRUE(c.Report(lease->lease_id, ComputeItems(spec, lease->items)).ok());
    auto path = c.Publish(p->id);
    if (path.ok()) return *path;
    EXPECT_EQ(path.status().code(), Status::Code::kFailedPrecondition) << path.status().ToString();
  }
  ADD_FAILURE() << "refinement did not finish";
  return "";
}

std::string RefineSpec(const char* criterion, int mixed_after, double t_end = 200) {
  char t[900];
  std::snprintf(t, sizeof t, R"(
name = "refined"
model = "coupled"
[axes]
alpha = { linspace = [0.015, 1.2, 65] }
omega = { linspace = [0.3, 3.0, 65] }
[integration]
t_end = %g
t_keep = %g
[metrics]
store = ["frf_db", "lle", "motion", "period", "y_max"]
[refine]
levels = 3
criterion = "%s"
mixed_after = %d
)",
                t_end, t_end / 2, criterion, mixed_after);
  return t;
}

TEST(SweepEngine, RefinedMapEqualsTheUniformMapWhereComputedAndCostsLess) {
  const std::string dir_r = TempDir("refined"), dir_u = TempDir("uniform");
  for (const char* criterion : {"frf_0db", "motion"}) {
    SCOPED_TRACE(criterion);
    const SweepSpec refined = Parse(RefineSpec(criterion, 2));
    std::string uniform_text = RefineSpec(criterion, 2);
    uniform_text = uniform_text.substr(0, uniform_text.find("[refine]"));
    const SweepSpec uniform = Parse(uniform_text);
    auto cr = SweepCoordinator::Open(dir_r);
    auto cu = SweepCoordinator::Open(dir_u);  // its own cache: nothing is shared with the refined run
    ASSERT_TRUE(cr.ok() && cu.ok());
    SweepPlan pr, pu;
    int rounds = 0;
    const std::string path_r = RunRefined(**cr, refined, &pr, &rounds);
    const std::string path_u = RunSweep(**cu, uniform, 2, &pu);
    ASSERT_FALSE(path_r.empty());
    auto fill = ReadMapMetric(path_r, "refine_fill");
    auto level = ReadMapMetric(path_r, "refine_level");
    ASSERT_TRUE(fill.ok() && level.ok());
    EXPECT_EQ(fill->categories.size(), 3u);
    long computed = 0, boundary_points = 0;
    for (size_t i = 0; i < fill->values.size(); ++i)
      computed += fill->values[i] == 0, boundary_points += level->values[i] == 3;
    EXPECT_LT(computed, 65 * 65 / 2) << "refinement computes a fraction of the uniform grid";
    EXPECT_GT(boundary_points, 0) << "some cells were refined to the finest spacing";
    auto attr = ReadMapAttribute(path_r, "refine_criterion");
    EXPECT_TRUE(attr.ok() && *attr == criterion);
    // Every computed point equals the uniform map's value bit for bit (every stored metric).
    for (const char* metric : {"frf_db", "lle", "motion", "period", "y_max"}) {
      auto a = ReadMapMetric(path_r, metric);
      auto b = ReadMapMetric(path_u, metric);
      ASSERT_TRUE(a.ok() && b.ok());
      ASSERT_EQ(a->values.size(), b->values.size());
      long differ = 0;
      for (size_t i = 0; i < a->values.size(); ++i)
        if (fill->values[i] == 0 && std::memcmp(&a->values[i], &b->values[i], sizeof(double)) != 0) ++differ;
      EXPECT_EQ(differ, 0) << metric;
    }
    // Interpolated points: the criterion agrees with the uniform map almost everywhere (an island
    // smaller than a coarse cell between agreeing corners is missed: that is the method's bet).
    auto crit = ReadMapMetric(path_r, std::string(criterion) == "motion" ? "motion" : "frf_db");
    auto crit_u = ReadMapMetric(path_u, std::string(criterion) == "motion" ? "motion" : "frf_db");
    long filled = 0, agree = 0;
    for (size_t i = 0; i < fill->values.size(); ++i) {
      if (fill->values[i] != 1) continue;
      ++filled;
      const bool same = std::string(criterion) == "motion" ? crit->values[i] == crit_u->values[i]
                                                           : (crit->values[i] >= 0) == (crit_u->values[i] >= 0);
      agree += same;
    }
    EXPECT_GT(filled, 0);
    EXPECT_GE(static_cast<double>(agree), 0.95 * static_cast<double>(filled));
    // Published like any map: the index row counts the computed points.
    auto info = (*cr)->Info(pr.id);
    ASSERT_TRUE(info.ok());
    EXPECT_EQ(info->state, SweepState::kDone);
    EXPECT_EQ(info->items_done, computed);
  }
  std::filesystem::remove_all(dir_r);
  std::filesystem::remove_all(dir_u);
}

TEST(SweepEngine, RefinedSweepResumesFromItsStoredLevels) {
  const std::string dir = TempDir("refine_resume"), fresh = TempDir("refine_fresh");
  const SweepSpec spec = Parse(RefineSpec("frf_0db", 2, 120));
  long level0 = 0;
  {
    auto c = SweepCoordinator::Open(dir);
    ASSERT_TRUE(c.ok());
    auto plan = (*c)->Submit(spec, 64);
    ASSERT_TRUE(plan.ok());
    level0 = plan->items_total;
    EXPECT_EQ(level0, 9 * 9);  // the coarse grid: every 8th value of 65
    EXPECT_EQ((*c)->progress(spec.Id()).refine_round, 0) << "round 0: the coarse grid";
    // Round 0 only: the report completing it has the publisher thread plan round 1, and a loop leasing
    // "until nothing is queued" raced it (1 run in ~60: the loop went on through every round and the sweep
    // was published before the "crash", so the resumed coordinator held no plan: round -1).
    long reported = 0;
    while (reported < level0) {
      auto lease = (*c)->Lease("w");
      ASSERT_TRUE(lease.has_value()) << reported << " of " << level0 << " items reported";
      ASSERT_TRUE((*c)->Report(lease->lease_id, ComputeItems(spec, lease->items)).ok());
      reported += static_cast<long>(lease->items.size());
    }
    ASSERT_EQ(reported, level0) << "leases of round 0 hold round 0's items only";
    // "crash" here: the next level may or may not have been planned
  }
  auto c = SweepCoordinator::Open(dir);  // resumes: plans again from the stored levels
  ASSERT_TRUE(c.ok());
  auto info = (*c)->Info(spec.Id());
  ASSERT_TRUE(info.ok());
  EXPECT_GE(info->items_done, level0) << "the coarse level is not computed again";
  EXPECT_GE((*c)->progress(spec.Id()).refine_round, 1) << "the resumed plan names the round it resumes, not 0";
  SweepPlan plan;
  int rounds = 0;
  const std::string resumed = RunRefined(**c, spec, &plan, &rounds);
  auto f = SweepCoordinator::Open(fresh);
  ASSERT_TRUE(f.ok());
  SweepPlan plan_f;
  const std::string once = RunRefined(**f, spec, &plan_f, &rounds);
  for (const char* metric : {"frf_db", "motion", "refine_level", "refine_fill"}) {
    auto a = ReadMapMetric(resumed, metric);
    auto b = ReadMapMetric(once, metric);
    ASSERT_TRUE(a.ok() && b.ok());
    EXPECT_EQ(std::memcmp(a->values.data(), b->values.data(), a->values.size() * sizeof(double)), 0) << metric;
  }
  std::filesystem::remove_all(dir);
  std::filesystem::remove_all(fresh);
}

TEST(Refine, SpeckledRegionsStopRefiningAndBoundaryLinesDoNot) {
  // Classes from a rule on the grid: a straight boundary (class by the sign of i + j - 40) everywhere
  // except a speckled square (pseudo-random classes) at the top: the line is refined to the end,
  // the square stops after mixed_after levels of all-mixed children.
  SweepSpec spec = Parse(R"(
model = "coupled"
[axes]
alpha = { linspace = [0.1, 1.0, 65] }
omega = { linspace = [0.1, 1.0, 65] }
[refine]
levels = 4
criterion = "motion"
mixed_after = 2
)");
  auto cls = [](long p) -> int64_t {
    const long i = p / 65, j = p % 65;
    if (i >= 48 && (j >= 48 || j < 16)) return static_cast<int64_t>((i * 7919 + j * 104729) % 3);
    return i + j >= 40 ? 1 : 0;
  };
  std::vector<long> all;
  auto step = PlanRefinement(spec, [&](const std::vector<long>& pts, std::vector<std::optional<RefineMark>>* out) {
    out->clear();
    // The speckled square is chaotic; the line's two sides are regular motion.
    for (long p : pts) out->push_back(RefineMark{cls(p), p / 65 >= 48 && p % 65 >= 48}), all.push_back(p);
    return Status::Ok();
  });
  ASSERT_TRUE(step.ok());
  ASSERT_TRUE(step->complete);
  EXPECT_GT(step->cells_mixed, 0);
  // A second speckled square (i >= 48, j < 16) has no chaotic point: like a triple junction or a thin
  // stripe of regular motion, it is refined to the end.
  int finest_mixed_on_line = 0, finest_in_square = 0, finest_in_regular_square = 0;
  for (const RefineCell& c : step->cells) {
    const long i = c.origin / 65, j = c.origin % 65;
    if (c.level == 4 && c.mixed)
      (i >= 48 && j >= 48  ? finest_in_square
       : i >= 48 && j < 16 ? finest_in_regular_square
                           : finest_mixed_on_line) += 1;
  }
  EXPECT_GT(finest_mixed_on_line, 20) << "the boundary line is refined to the finest spacing";
  EXPECT_EQ(finest_in_square, 0) << "the chaotic speckled square is not";
  EXPECT_GT(finest_in_regular_square, 100) << "speckle without chaos is";
  // Every finest cell on the line has its corners computed on both sides of the line.
  std::sort(all.begin(), all.end());
  for (long d = 0; d <= 40; ++d) {
    const long p = d * 65 + (40 - d);  // on the line i + j = 40
    if (40 - d < 0 || 40 - d > 64) continue;
    EXPECT_TRUE(std::binary_search(all.begin(), all.end(), p)) << "point on the boundary line " << d;
  }
  EXPECT_LT(all.size(), 65u * 65u / 2);
}

TEST(SweepSpec, RefineIsCheckedByName) {
  for (const auto& [toml, field] : std::vector<std::pair<std::string, std::string>>{
           {"[refine]\ncriterion = \"motion\"\n", "refine.levels"},
           {"[refine]\nlevels = 11\n", "refine.levels"},
           {"[refine]\nlevels = 2\ncriterion = \"chaos\"\n", "refine.criterion"},
           {"[refine]\nlevels = 2\nmixed_after = -1\n", "refine.mixed_after"},
           {"[refine]\nlevels = 2\nlevel = 3\n", "refine.level"},
           {"[refine]\nlevels = 3\n", "axes.omega"},  // 5 values do not split into 8 steps
           {"[refine]\nlevels = 2\n[initial_conditions]\nstates = [[1, 0], [-1, 0]]\n", "refine"}}) {
    auto s = ParseSweepSpec("model = \"coupled\"\n[axes]\nomega = { linspace = [1.0, 2.0, 5] }\n" + toml, "test.toml");
    ASSERT_FALSE(s.ok()) << toml;
    EXPECT_EQ(s.status().field(), field) << s.status().ToString();
  }
  auto ok = ParseSweepSpec("model = \"coupled\"\n[axes]\nomega = { linspace = [1.0, 2.0, 5] }\n[refine]\nlevels = 2\n",
                           "t.toml");
  ASSERT_TRUE(ok.ok()) << ok.status().ToString();
  auto plain = ParseSweepSpec("model = \"coupled\"\n[axes]\nomega = { linspace = [1.0, 2.0, 5] }\n", "t.toml");
  EXPECT_NE(ok->Id(), plain->Id()) << "refinement is part of the sweep's identity";
  EXPECT_EQ(ok->ItemKey(2, 0), plain->ItemKey(2, 0)) << "but its points share the cache with the uniform sweep";
}

TEST(SweepSpec, RobustnessIsCheckedByName) {
  for (const auto& [toml, field] : std::vector<std::pair<std::string, std::string>>{
           {"[robustness]\nsamples = 0\n", "robustness.samples"},
           {"[robustness]\nsamples = 5000\n", "robustness.samples"},
           {"[robustness]\nseed = 3\n", "robustness.samples"},
           {"[robustness]\nsamples = 8\ntolerance = { eta = 0.7 }\n", "robustness.tolerance.eta"},
           {"[robustness]\nsamples = 8\ntolerance = { etta = 0.1 }\n", "robustness.tolerance.etta"},
           {"[robustness]\nsamples = 8\nic_radius = -1\n", "robustness.ic_radius"},
           {"[robustness]\nsamples = 8\n[initial_conditions]\nstates = [[1, 0], [-1, 0]]\n",
            "initial_conditions.states"}}) {
    auto s = ParseSweepSpec("model = \"coupled\"\n[axes]\nomega = [1.0, 2.0]\n" + toml, "test.toml");
    ASSERT_FALSE(s.ok()) << toml;
    EXPECT_EQ(s.status().field(), field) << s.status().ToString();
  }
}

TEST(SweepSpec, InitialStateAxesAreCheckedByName) {
  for (const auto& [toml, field] : std::vector<std::pair<std::string, std::string>>{
           {"model = \"standalone\"\n[axes]\nyr0 = [0.0, 1.0]\n", "axes.yr0"},
           {"model = \"coupled\"\n[axes]\nym0 = [0.0, 1.0]\n[initial_conditions]\nstates = [[1, 0], [-1, 0]]\n",
            "initial_conditions.states"},
           {"model = \"coupled\"\n[axes]\nym0 = [0.0, 1.0]\nalpha = [0.1, 0.2]\n[continuation]\naxis = \"alpha\"\n",
            "continuation"}}) {
    auto s = ParseSweepSpec(toml, "test.toml");
    ASSERT_FALSE(s.ok()) << toml;
    EXPECT_EQ(s.status().field(), field) << s.status().ToString();
  }
  // With parameter axes too, initial-state axes give maps over both, but no basin map.
  auto mixed = ParseSweepSpec("model = \"coupled\"\n[axes]\nym0 = [0.0, 1.0]\nalpha = [0.1, 0.2]\n", "test.toml");
  ASSERT_TRUE(mixed.ok()) << mixed.status().ToString();
  EXPECT_FALSE(mixed->IsBasinSweep());
  EXPECT_EQ(mixed->PointAt(1, 0).ic[0], 1.0);  // the last axis fastest: (alpha 0.1, ym0 1)
  EXPECT_EQ(mixed->PointAt(1, 0).ic[2], 1.0);  // unswept components: the default start (resonator at +1)
}

TEST(SweepEngine, UnwritableDataDirectoryIsAClearError) {
  auto c = SweepCoordinator::Open("/proc/bistable-cannot-exist/data");
  ASSERT_FALSE(c.ok());
  EXPECT_EQ(c.status().field(), "data");
  EXPECT_NE(c.status().message().find("/proc/bistable-cannot-exist/data"), std::string::npos);
}

}  // namespace
}  // namespace bistable

namespace bistable {
namespace {

// A one-cell chain through the generic path reproduces the coupled model through the kernel.
TEST(SweepModels, OneCellSeriesEqualsTheCoupledModel) {
  const SweepSpec series = Parse(R"(
model = "series"
[series]
cells = 1
[axes]
alpha = [0.1, 1.0]
omega = [0.3, 1.2]
)");
  EXPECT_EQ(series.ModelLabel(), "series");
  for (long p = 0; p < 3; ++p) {  // the periodic points of this grid
    const PointResult a = EvaluateItem(series, p, 0);
    PointSpec ps = series.PointAt(p, 0);
    ps.model = ModelKind::kCoupled;
    auto b = EvaluatePoint(ps);
    ASSERT_TRUE(b.ok());
    EXPECT_NEAR(a.frf_db, b->frf_db, 1e-6) << p;  // same RK4 steps, same samples
    // The tangent starts along another direction; over a 250-τ window the estimates agree to a few 1e-3.
    EXPECT_NEAR(a.lle, b->lle, 0.006) << p;
    EXPECT_EQ(a.motion, b->motion) << p;
    EXPECT_EQ(a.period, b->period) << p;
  }
  EXPECT_NE(series.ItemKey(0, 0), PointKey(series.PointAt(0, 0)));  // model configuration is part of the key
}

// Without friction and c2, the dimensional model is the non-dimensional one in SI units: a periodic
// point at (α 0.4, Ω 0.9) has the same transmissibility at A0 = α δs, f0 = Ω ωn / 2π (model.md §5).
TEST(SweepModels, DimensionalSweepInPhysicalUnitsMatchesTheNondimensionalModel) {
  const DimensionalParams t2 = DimensionalParams::BistableTable2();
  const double delta_s = std::sqrt(-t2.k_lin / t2.k3), wn = std::sqrt(-t2.k_lin / t2.m_m);
  const double alpha = 0.4, omega = 0.9;
  char toml[1024];
  std::snprintf(toml, sizeof toml, R"(
model = "dimensional"
[dimensional]
preset = "bistable"
c2_m = 0
c2_r = 0
fs_m = 0
fc_m = 0
fs_r = 0
fc_r = 0
[params]
a0_mm = %.17g
f0_hz = %.17g
[integration]
t_end = 8.0
t_keep = 4.0
dt = 0.0005
rtol = 1e-10
atol = 1e-13
)",
                alpha * delta_s * 1e3, omega * wn / (2 * M_PI));
  const SweepSpec dim = Parse(toml);
  ASSERT_EQ(dim.axes.size(), 0u);
  const PointResult d = EvaluateItem(dim, 0, 0);
  PointSpec nd;
  nd.model = ModelKind::kCoupled;
  nd.alpha = alpha;
  nd.omega = omega;
  nd.params = {1.0, t2.c0_m / (t2.m_m * wn), t2.c0_r / (t2.m_r * wn), t2.m_r / t2.m_m, std::sqrt(t2.k_r / t2.m_r) / wn};
  nd.integration.integrator = IntegratorKind::kAdaptive;
  auto n = EvaluatePoint(nd);
  ASSERT_TRUE(n.ok());
  ASSERT_EQ(n->period, 1);
  EXPECT_EQ(d.period, 1);
  EXPECT_EQ(d.motion, n->motion);
  EXPECT_NEAR(d.frf_db, n->frf_db, 0.01);
  EXPECT_NEAR(d.lle / wn, n->lle, 0.01);  // per second → per unit τ
  ASSERT_FALSE(d.hd_peaks.empty());
  EXPECT_NEAR(d.hd_peaks[0].freq, 2 * M_PI * omega * wn / (2 * M_PI), 0.5);  // rad/s
}

TEST(SweepModels, DimensionalMassSticksAtSmallAmplitude) {
  // A0 2 mm at 2 Hz: the base's inertial force on the mass, m A0 ω² ≈ 0.09 N, is far below static
  // friction F_s = 1.2 N, so the mass rides with the table: transmissibility 0 dB, no relative motion.
  const SweepSpec dim = Parse(R"(
model = "dimensional"
[params]
a0_mm = 2.0
f0_hz = 2.0
[integration]
t_end = 6.0
t_keep = 3.0
)");
  const PointResult r = EvaluateItem(dim, 0, 0);
  EXPECT_EQ(r.termination, Termination::kOk);
  EXPECT_NEAR(r.frf_db, 0.0, 0.1);
  EXPECT_LT(r.y_max - r.y_min, 1e-4);  // metres
  EXPECT_EQ(r.motion, Motion::kIntrawell);
}

TEST(SweepModels, SeriesAndDimensionalSpecErrorsNameTheirFields) {
  for (auto [toml, field] : std::vector<std::pair<std::string, std::string>>{
           {"model = \"series\"\n[series]\ncells = 0", "series.cells"},
           {"model = \"series\"\n[series]\ncells = 2\ncell = [{eta = -1}]", "series.cells[0].eta"},
           {"model = \"series\"\n[series]\ncells = 2\ncell = [{etta = 1}]", "series.cell[0].etta"},
           {"model = \"coupled\"\n[series]\ncells = 2", "series"},
           {"model = \"dimensional\"\n[dimensional]\npreset = \"stiff\"", "dimensional.preset"},
           {"model = \"dimensional\"\n[dimensional]\nv_t = 0", "dimensional.v_t_m"},
           {"model = \"dimensional\"\n[axes]\nalpha = [1]", "axes.alpha"},
           {"model = \"dimensional\"\n[axes]\na0_mm = [0, 1]", "axes.a0_mm[0]"},
           {"model = \"series\"\n[initial_conditions]\nstates = [[1, 0]]", "initial_conditions"},
       }) {
    auto s = ParseSweepSpec(toml, "t.toml");
    ASSERT_FALSE(s.ok()) << toml;
    EXPECT_EQ(s.status().field(), field) << toml << "\n" << s.status().ToString();
  }
}

}  // namespace
}  // namespace bistable

namespace bistable {
namespace {

constexpr const char* kHysteresis = R"(
model = "standalone"
[axes]
alpha = [0.1]
omega = { linspace = [0.5, 1.3, 21] }
[continuation]
axis = "omega"
direction = "both"
[metrics]
store = ["y_max", "y_min", "motion", "turning_points", "frf_db"]
)";

// Each chained point starts from the previous point's final state: the map equals running the chain
// by hand with `bistable point --ic`, bit for bit, upward and downward.
TEST(Continuation, ChainedPointsStartFromThePreviousFinalState) {
  const SweepSpec spec = Parse(kHysteresis);
  ASSERT_TRUE(spec.continuation.enabled());
  EXPECT_EQ(spec.ic_count(), 2);
  const auto chains = KindOf(spec).Chains(spec);
  ASSERT_EQ(chains.size(), 2u);
  EXPECT_EQ(chains[0].front().point, 0);
  EXPECT_EQ(chains[1].front().point, 20);  // the downward chain starts at the top of the axis
  for (const auto& chain : chains) {
    const std::vector<PointRecord> rec = ComputeItems(spec, chain);
    std::array<double, 4> state{};
    for (size_t i = 0; i < chain.size(); ++i) {
      PointSpec p = spec.PointAt(chain[i].point, chain[i].ic);
      if (i > 0) p.ic_given = true, p.ic = state;
      auto r = EvaluatePoint(p);
      ASSERT_TRUE(r.ok());
      state = r->final_state;
      EXPECT_EQ(std::memcmp(&r->frf_db, &rec[i].v[0], sizeof(double)), 0) << "chain point " << i;
    }
  }
}

// Sweeping Ω up keeps the oscillator in its positive well; sweeping down it crosses the softening
// intrawell resonance from above, snaps through and settles in the other well: the two maps differ.
TEST(Continuation, UpAndDownSweepsShowHysteresisAndTurningPoints) {
  const std::string dir = TempDir("hyst");
  auto c = SweepCoordinator::Open(dir);
  ASSERT_TRUE(c.ok());
  const SweepSpec spec = Parse(kHysteresis);
  SweepPlan plan;
  const std::string path = RunSweep(**c, spec, 2, &plan);
  EXPECT_EQ(plan.items_total, 42);
  auto ymax = ReadMapMetric(path, "y_max");
  auto tp = ReadMapMetric(path, "turning_points");
  ASSERT_TRUE(ymax.ok() && tp.ok());
  EXPECT_EQ(ymax->dims, (std::vector<size_t>{1, 21, 2}));
  EXPECT_EQ(ymax->dim_names.back(), "direction");
  int differ = 0;
  for (size_t i = 0; i < 21; ++i) differ += std::fabs(ymax->values[i * 2] - ymax->values[i * 2 + 1]) > 0.1;
  EXPECT_GE(differ, 3) << "no hysteresis between the upward and downward sweeps";
  // Turning points of a periodic intrawell orbit: alternating maxima and minima within [y_min, y_max].
  const size_t k = 64, first = 0;  // Ω = 0.5, upward
  int finite = 0;
  for (size_t j = 0; j < k; ++j) {
    const double y = tp->values[first * k + j];
    if (!std::isfinite(y)) continue;
    ++finite;
    EXPECT_LE(y, ymax->values[0] + 1e-6);
  }
  EXPECT_GE(finite, 30);  // 250 τ at Ω = 0.5: ~20 periods, 2 turning points each, last 64 kept
  std::filesystem::remove_all(dir);
}

TEST(Continuation, SpecErrorsNameTheirFields) {
  for (auto [toml, field] : std::vector<std::pair<std::string, std::string>>{
           {"model = \"coupled\"\n[axes]\nalpha = [1, 2]\n[continuation]\naxis = \"omega\"", "continuation.axis"},
           {"model = \"coupled\"\n[axes]\nalpha = [1, 2]\n[continuation]\naxis = \"alpha\"\ndirection = \"sideways\"",
            "continuation.direction"},
           {"model = \"series\"\n[axes]\nalpha = [1, 2]\n[continuation]\naxis = \"alpha\"", "continuation"},
       }) {
    auto s = ParseSweepSpec(toml, "t.toml");
    ASSERT_FALSE(s.ok()) << toml;
    EXPECT_EQ(s.status().field(), field) << s.status().ToString();
  }
}

}  // namespace
}  // namespace bistable
