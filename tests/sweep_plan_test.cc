// The sweep plan on its own (engine/sweep_plan.h, issue 40): no locks, no I/O. The point cache is a map
// in the test; a refined sweep's records are computed for real (engine/evaluate.h) and "stored" in it.
#include "engine/sweep_plan.h"

#include <string>
#include <unordered_map>
#include <vector>

#include <gtest/gtest.h>

#include "engine/evaluate.h"
#include "engine/sweep_kind.h"
#include "tests/spec_fixture.h"

namespace bistable {
namespace {

// The point cache of a test: content key → record, with every lookup's batch size seen.
struct FakeCache {
  std::unordered_map<std::string, PointRecord> stored;
  std::vector<size_t> batches;
  PointLookup Lookup() {
    return [this](const std::vector<std::string>& keys) -> StatusOr<std::unordered_map<std::string, PointRecord>> {
      batches.push_back(keys.size());
      std::unordered_map<std::string, PointRecord> out;
      for (const std::string& k : keys)
        if (auto it = stored.find(k); it != stored.end()) out.emplace(k, it->second);
      return out;
    };
  }
};

// The built plan (the test fails with the plan's error if it has one).
JobPlan Planned(StatusOr<JobPlan> built) {
  EXPECT_TRUE(built.ok()) << built.status().ToString();
  return built.ok() ? std::move(built).value() : JobPlan{};
}

constexpr const char* kGrid = R"(
model = "coupled"
[axes]
alpha = { linspace = [0.2, 1.4, 5] }
omega = [0.8, 1.2, 2.0]
)";  // 15 points, one initial condition

// A refined sweep: 17 x 17, 2 levels, short integration.
constexpr const char* kRefined = R"(
model = "coupled"
[axes]
alpha = { linspace = [0.015, 1.2, 17] }
omega = { linspace = [0.3, 3.0, 17] }
[integration]
t_end = 120
t_keep = 60
[metrics]
store = ["frf_db", "motion"]
[refine]
levels = 2
criterion = "frf_0db"
)";

// Continuation over omega on 3 lines of 5 points, `direction` "up", "down" or "both".
std::string ChainSpec(const std::string& direction) {
  return "model = \"coupled\"\n[axes]\nalpha = [0.2, 0.6, 1.0]\nomega = { linspace = [0.8, 1.6, 5] }\n"
         "[continuation]\naxis = \"omega\"\ndirection = \"" +
         direction + "\"\n";
}

TEST(SweepPlan, QueuesOnlyTheMissingItemsInJobsOfTheAskedSize) {
  const SweepSpec spec = bistable_test::ParsedSpec(kGrid);
  FakeCache cache;
  for (long p = 0; p < 15; p += 2) cache.stored[spec.ItemKey(p, 0)] = PointRecord{};  // 8 stored, 7 missing
  JobPlan plan = Planned(JobPlan::Build(spec, 3, cache.Lookup()));
  EXPECT_EQ(plan.items_total(), 15);
  EXPECT_EQ(plan.items_cached(), 8);
  EXPECT_EQ(plan.items_done(), 8);
  EXPECT_EQ(plan.jobs(), 3);  // 3 + 3 + 1
  EXPECT_EQ(plan.queued(), 3u);
  ASSERT_EQ(plan.keys().size(), 15u);
  EXPECT_EQ(plan.keys()[4], spec.ItemKey(4, 0));
  std::vector<long> missing;
  for (const WorkItem& w : plan.ItemsFor({0, 1, 2})) missing.push_back(w.point);
  EXPECT_EQ(missing, (std::vector<long>{1, 3, 5, 7, 9, 11, 13}));
  // The keys a job's rows are stored under, in its items' order.
  EXPECT_EQ(plan.KeysFor({2}), spec.ItemKey(13, 0) + "\n");
  EXPECT_EQ(plan.next(), JobPlan::Next::kCompute);
  EXPECT_EQ(cache.batches, std::vector<size_t>{15});
}

TEST(SweepPlan, EverythingStoredIsPublishedAtOnce) {
  const SweepSpec spec = bistable_test::ParsedSpec(kGrid);
  FakeCache cache;
  for (long p = 0; p < 15; ++p) cache.stored[spec.ItemKey(p, 0)] = PointRecord{};
  JobPlan plan = Planned(JobPlan::Build(spec, 4, cache.Lookup()));
  EXPECT_EQ(plan.jobs(), 0);
  EXPECT_EQ(plan.next(), JobPlan::Next::kPublish);
  EXPECT_TRUE(plan.Take(1, 100).empty());
}

TEST(SweepPlan, TakeMergesJobsWithinTheItemBoundAndRequeueKeepsTheirOrder) {
  const SweepSpec spec = bistable_test::ParsedSpec(kGrid);
  FakeCache cache;
  JobPlan plan = Planned(JobPlan::Build(spec, 2, cache.Lookup()));  // 8 jobs: 7 of two items, one of one
  ASSERT_EQ(plan.jobs(), 8);
  EXPECT_EQ(plan.Take(3, 100), (std::vector<long>{0, 1, 2}));
  EXPECT_EQ(plan.Take(3, 5), (std::vector<long>{3, 4}));  // a third job would make 6 items
  EXPECT_EQ(plan.Take(1, 1), (std::vector<long>{5}));     // the first job is taken whatever its size
  EXPECT_EQ(plan.queued(), 2u);
  plan.Requeue({3, 4});  // an expired merged lease: back at the front, in order
  EXPECT_EQ(plan.Take(1, 100), (std::vector<long>{3}));
  EXPECT_EQ(plan.Take(1, 100), (std::vector<long>{4}));
  plan.Requeue({7});  // not leased (queued): nothing moves
  EXPECT_EQ(plan.queued(), 2u);
  EXPECT_TRUE(plan.Holds({0, 7}));
  EXPECT_FALSE(plan.Holds({0, 8}));
  EXPECT_FALSE(plan.Holds({-1}));
}

TEST(SweepPlan, AJobCountsOnceAndTheLastOneMakesThePlanPublishable) {
  const SweepSpec spec = bistable_test::ParsedSpec(kGrid);
  FakeCache cache;
  JobPlan plan = Planned(JobPlan::Build(spec, 8, cache.Lookup()));  // jobs of 8 and 7 items
  const std::vector<long> first = plan.Take(1, 100), second = plan.Take(1, 100);
  EXPECT_EQ(plan.Complete(first), 8);
  EXPECT_EQ(plan.Complete(first), 0);  // a second lease of the job stored too: counted once
  EXPECT_TRUE(plan.AllDone(first));
  EXPECT_FALSE(plan.AllDone({0, 1}));
  EXPECT_EQ(plan.items_done(), 8);
  EXPECT_EQ(plan.next(), JobPlan::Next::kCompute);
  EXPECT_EQ(plan.Complete(second), 7);
  EXPECT_EQ(plan.items_done(), 15);
  EXPECT_EQ(plan.next(), JobPlan::Next::kPublish);
  plan.Free();  // published: the memory goes, the counters stay for status
  EXPECT_TRUE(plan.keys().empty());
  EXPECT_EQ(plan.items_done(), 15);
}

TEST(SweepPlan, AContinuationChainWithAnyMissingItemIsQueuedWholeInOneJob) {
  const SweepSpec spec = bistable_test::ParsedSpec(ChainSpec("up"));
  const auto chains = KindOf(spec).Chains(spec);
  ASSERT_EQ(chains.size(), 3u);
  FakeCache cache;
  for (const auto& chain : chains)
    for (const WorkItem& w : chain) cache.stored[spec.ItemKey(w.point, w.ic)] = PointRecord{};
  cache.stored.erase(spec.ItemKey(chains[1][2].point, chains[1][2].ic));  // one item of the middle chain
  JobPlan plan = Planned(JobPlan::Build(spec, 2, cache.Lookup()));        // jobs of 2 would cut a chain of 5
  ASSERT_EQ(plan.jobs(), 1);
  const std::vector<WorkItem> items = plan.ItemsFor({0});
  ASSERT_EQ(items.size(), chains[1].size());
  for (size_t i = 0; i < items.size(); ++i) EXPECT_EQ(items[i].point, chains[1][i].point);
  EXPECT_EQ(plan.items_cached(), 15 - static_cast<long>(chains[1].size()));  // its stored items are recomputed
}

TEST(SweepPlan, ALookupFailureIsThePlansError) {
  const SweepSpec spec = bistable_test::ParsedSpec(kGrid);
  auto failed = JobPlan::Build(spec, 4, [](const std::vector<std::string>&) {
    return StatusOr<std::unordered_map<std::string, PointRecord>>(Status::IoError("index", "disk gone"));
  });
  ASSERT_FALSE(failed.ok());
  EXPECT_NE(failed.status().message().find("disk gone"), std::string::npos);
}

TEST(SweepPlan, ARefinedSweepPlansRoundAfterRoundUntilItPublishes) {
  const SweepSpec spec = bistable_test::ParsedSpec(kRefined);
  FakeCache cache;
  JobPlan plan = Planned(JobPlan::Build(spec, 64, cache.Lookup()));
  EXPECT_TRUE(plan.refined());
  EXPECT_EQ(plan.refine_round(), 0);
  EXPECT_EQ(plan.items_total(), 5 * 5);  // the coarse grid: every 4th value of 17
  int rounds = 0;
  long computed = 0;
  while (plan.next() != JobPlan::Next::kPublish) {
    ASSERT_LT(++rounds, 10) << "the walk does not end";
    // Compute and "store" every queued job, as workers and the writer would.
    for (std::vector<long> jobs = plan.Take(1, 1000); !jobs.empty(); jobs = plan.Take(1, 1000)) {
      const std::vector<WorkItem> items = plan.ItemsFor(jobs);
      const std::vector<PointRecord> records = ComputeItems(spec, items);
      ASSERT_EQ(records.size(), items.size());
      for (size_t i = 0; i < items.size(); ++i) cache.stored[spec.ItemKey(items[i].point, 0)] = records[i];
      computed += static_cast<long>(items.size());
      plan.Complete(jobs);
    }
    if (plan.next() == JobPlan::Next::kPublish) break;
    ASSERT_EQ(plan.next(), JobPlan::Next::kNextRound) << "a stored round of an unfinished walk";
    const int round = plan.refine_round();
    const long planned = plan.items_total();
    auto next = JobPlan::Build(spec, 64, cache.Lookup(), plan.Carry());
    ASSERT_TRUE(next.ok()) << next.status().ToString();
    EXPECT_EQ(next->refine_round(), round + 1);
    EXPECT_GE(next->items_total(), planned) << "planned points only grow";
    plan = std::move(next).value();
  }
  EXPECT_GE(rounds, 1);
  EXPECT_TRUE(plan.refine_complete());
  EXPECT_LT(computed, 17 * 17) << "refinement computes fewer points than the full grid";
  EXPECT_EQ(plan.items_done(), plan.items_total());
  // A walk from the start (a restarted coordinator) over the same cache needs nothing more.
  auto again = JobPlan::Build(spec, 64, cache.Lookup());
  ASSERT_TRUE(again.ok());
  EXPECT_TRUE(again->refine_complete());
  EXPECT_EQ(again->jobs(), 0);
  EXPECT_EQ(again->points(), plan.points());
  EXPECT_EQ(again->keys(), plan.keys());
}

// Shards (issue 43): `bistable run --shard I/N` plans one slice of a sweep.
TEST(SweepPlan, ShardTextIsIOverNWithItsBoundsNamed) {
  auto s = ParseShard("3/8");
  ASSERT_TRUE(s.ok()) << s.status().ToString();
  EXPECT_EQ(s->index, 3);
  EXPECT_EQ(s->count, 8);
  EXPECT_EQ(s->Label(), "3/8");
  for (const char* bad : {"8/8", "9/8", "0/0", "-1/4", "1/", "/4", "a/b", "3", "3/8/1", "1/100001", " 1/4"}) {
    auto r = ParseShard(bad);
    ASSERT_FALSE(r.ok()) << bad;
    EXPECT_EQ(r.status().field(), "shard") << bad;
  }
  EXPECT_NE(ParseShard("8/8").status().message().find("0 <= I < N = 8"), std::string::npos);
  EXPECT_NE(ParseShard("0/0").status().message().find("1 <= N <= 100000"), std::string::npos);
}

TEST(SweepPlan, ShardsPartitionTheItemsRoundRobinAndQueueOnlyTheirMissingOnes) {
  const SweepSpec spec = bistable_test::ParsedSpec(kGrid);  // 15 items
  FakeCache cache;
  cache.stored[spec.ItemKey(4, 0)] = PointRecord{};  // shard 1/3's (4 mod 3 = 1)
  std::vector<int> owner(15, -1);
  long total = 0;
  for (int i = 0; i < 3; ++i) {
    const Shard shard{i, 3};
    JobPlan plan = Planned(JobPlan::BuildShard(spec, 2, cache.Lookup(), shard));
    EXPECT_EQ(plan.keys().size(), 15u) << "every item's key, in item order";
    EXPECT_EQ(plan.items_total(), 5);
    EXPECT_EQ(plan.items_cached(), i == 1 ? 1 : 0);
    total += plan.items_total();
    std::vector<long> jobs;
    for (long j = 0; j < plan.jobs(); ++j) jobs.push_back(j);
    for (const WorkItem& w : plan.ItemsFor(jobs)) {
      EXPECT_EQ(owner[w.point], -1) << "item " << w.point << " in two shards";
      owner[w.point] = i;
      EXPECT_EQ(w.point % 3, i);
    }
    EXPECT_EQ(ShardItemIndices(spec, shard).size(), 5u);
  }
  EXPECT_EQ(total, 15);
  for (long p = 0; p < 15; ++p) EXPECT_EQ(owner[p], p == 4 ? -1 : p % 3) << p;  // item 4: stored, not queued
  // More shards than items: the last ones are empty, and done.
  JobPlan empty = Planned(JobPlan::BuildShard(spec, 2, cache.Lookup(), Shard{16, 20}));
  EXPECT_EQ(empty.items_total(), 0);
  EXPECT_EQ(empty.next(), JobPlan::Next::kPublish);
}

TEST(SweepPlan, AContinuationShardHoldsWholeChains) {
  const SweepSpec spec = bistable_test::ParsedSpec(ChainSpec("both"));
  const auto chains = KindOf(spec).Chains(spec);
  ASSERT_EQ(chains.size(), 6u);  // 3 lines x 2 directions
  FakeCache cache;
  long total = 0;
  for (int i = 0; i < 4; ++i) {
    JobPlan plan = Planned(JobPlan::BuildShard(spec, 2, cache.Lookup(), Shard{i, 4}));
    std::vector<long> jobs;
    for (long j = 0; j < plan.jobs(); ++j) jobs.push_back(j);
    const std::vector<WorkItem> items = plan.ItemsFor(jobs);
    std::vector<WorkItem> expected;  // chains i and i + 4, whole and in their order
    for (size_t c = static_cast<size_t>(i); c < chains.size(); c += 4)
      expected.insert(expected.end(), chains[c].begin(), chains[c].end());
    ASSERT_EQ(items.size(), expected.size()) << "shard " << i;
    for (size_t k = 0; k < items.size(); ++k) {
      EXPECT_EQ(items[k].point, expected[k].point);
      EXPECT_EQ(items[k].ic, expected[k].ic);
    }
    total += plan.items_total();
  }
  EXPECT_EQ(total, 30);
}

TEST(SweepPlan, ARefinedSweepCannotBeSharded) {
  const SweepSpec spec = bistable_test::ParsedSpec(kRefined);
  FakeCache cache;
  auto plan = JobPlan::BuildShard(spec, 8, cache.Lookup(), Shard{0, 2});
  ASSERT_FALSE(plan.ok());
  EXPECT_EQ(plan.status().field(), "shard");
  EXPECT_NE(plan.status().message().find("refined"), std::string::npos) << plan.status().message();
}

}  // namespace
}  // namespace bistable
