// The publisher on its own (server/publisher.h, issue 40): one thread runs the steps, in order; a sweep
// asked for again while its step waits is stepped once; callers that wait share the step's outcome; a close
// runs what is queued.
#include "server/publisher.h"

#include <chrono>
#include <future>
#include <mutex>
#include <thread>
#include <vector>

#include <gtest/gtest.h>

#include "engine/evaluate.h"
#include "storage/map_file.h"
#include "tests/process_util.h"
#include "tests/spec_fixture.h"

namespace bistable {
namespace {

// A step that records what it ran and on which thread, and can be held until the test lets it go.
struct Steps {
  std::mutex mu;
  std::condition_variable cv;
  bool hold = false;
  std::vector<std::string> ran;
  std::vector<std::thread::id> threads;
  std::vector<std::pair<std::string, Status>> failures;
  StatusOr<std::string> Run(const std::string& id) {
    std::unique_lock<std::mutex> lock(mu);
    ran.push_back(id);
    threads.push_back(std::this_thread::get_id());
    cv.notify_all();
    cv.wait(lock, [&] { return !hold; });
    if (id == "broken") return Status::IoError("map", "disk full");
    if (id == "refining") return Status::FailedPrecondition("refining");
    return "maps/" + id + ".h5";
  }
  void Release() {
    std::lock_guard<std::mutex> lock(mu);
    hold = false;
    cv.notify_all();
  }
  // Waits until `n` steps have started.
  void AwaitStarted(size_t n) {
    std::unique_lock<std::mutex> lock(mu);
    cv.wait_for(lock, std::chrono::seconds(10), [&] { return ran.size() >= n; });
  }
  std::unique_ptr<Publisher> Make() {
    return std::make_unique<Publisher>([this](const std::string& id) { return Run(id); },
                                       [this](const std::string& id, const Status& st) {
                                         std::lock_guard<std::mutex> lock(mu);
                                         failures.emplace_back(id, st);
                                       });
  }
};

TEST(Publisher, RunWaitsForTheStepOnThePublishersOwnThread) {
  Steps steps;
  auto p = steps.Make();
  auto path = p->Run("a");
  ASSERT_TRUE(path.ok());
  EXPECT_EQ(*path, "maps/a.h5");
  ASSERT_EQ(steps.threads.size(), 1u);
  EXPECT_NE(steps.threads[0], std::this_thread::get_id()) << "a caller never publishes on its own thread";
  EXPECT_EQ(p->Run("broken").status().code(), Status::Code::kIoError);
  EXPECT_TRUE(steps.failures.empty()) << "a failure someone waited for is theirs to report";
}

TEST(Publisher, ASweepAskedForAgainWhileItsStepWaitsIsSteppedOnce) {
  Steps steps;
  steps.hold = true;
  auto p = steps.Make();
  p->Post("a");
  steps.AwaitStarted(1);  // a's step runs (held): b is queued behind it
  p->Post("b");
  p->Post("b");
  auto waiter = std::async(std::launch::async, [&] { return p->Run("b"); });  // joins the queued step
  for (int i = 0; i < 2000 && p->waiting() < 1; ++i) std::this_thread::sleep_for(std::chrono::milliseconds(5));
  ASSERT_EQ(p->waiting(), 1);
  steps.Release();
  auto b = waiter.get();
  ASSERT_TRUE(b.ok());
  EXPECT_EQ(*b, "maps/b.h5");
  p->Close();
  EXPECT_EQ(steps.ran, (std::vector<std::string>{"a", "b"}));
  EXPECT_EQ(p->steps(), 2);
}

TEST(Publisher, ASweepAskedForWhileItsStepRunsIsSteppedAgain) {
  Steps steps;
  steps.hold = true;
  auto p = steps.Make();
  p->Post("a");
  steps.AwaitStarted(1);
  p->Post("a");  // the running step may have read the sweep before what this caller saw
  steps.Release();
  p->Close();
  EXPECT_EQ(steps.ran, (std::vector<std::string>{"a", "a"}));
}

TEST(Publisher, CloseRunsWhatIsQueuedThenRefusesMore) {
  Steps steps;
  steps.hold = true;
  auto p = steps.Make();
  p->Post("x");
  steps.AwaitStarted(1);
  p->Post("y");
  p->Post("broken");
  p->Post("refining");
  auto closing = std::async(std::launch::async, [&] { p->Close(); });
  std::this_thread::sleep_for(std::chrono::milliseconds(50));
  steps.Release();
  closing.get();
  EXPECT_EQ(steps.ran, (std::vector<std::string>{"x", "y", "broken", "refining"}));
  // Unwaited failures are said, except FailedPrecondition (cancelled or refining meanwhile).
  ASSERT_EQ(steps.failures.size(), 1u);
  EXPECT_EQ(steps.failures[0].first, "broken");
  EXPECT_EQ(p->Run("z").status().code(), Status::Code::kFailedPrecondition);
  p->Post("z");
  EXPECT_EQ(steps.ran.size(), 4u);
}

// PublishMap, the publication itself, on a real SQLite index and a real HDF5 map file: the records as the
// writer stored them, checked, gathered and written; a sweep with an item not stored is not published.
TEST(Publisher, PublishMapWritesTheStoredRecordsAndIndexesTheMapOnlyWhenEveryItemIsStored) {
  const std::string dir = bistable_test::FreshDir("bistable_publish_map", "real");
  std::filesystem::create_directories(std::filesystem::path(dir) / "sweeps");
  const std::string index = dir + "/index.sqlite";
  auto db = IndexDb::Open(index);
  ASSERT_TRUE(db.ok()) << db.status().ToString();
  ResultWriter writer(std::move(db).value(), index, ResultWriter::Options{.checkpoint_seconds = 0});
  const SweepSpec spec = bistable_test::ParsedSpec(R"(
model = "coupled"
[axes]
alpha = { linspace = [0.2, 1.4, 5] }
omega = [0.8, 1.2, 2.0]
)");
  std::vector<WorkItem> items;
  std::vector<std::string> keys;
  for (long p = 0; p < spec.points(); ++p) items.push_back({p, 0}), keys.push_back(spec.ItemKey(p, 0));
  const std::vector<PointRecord> records = ComputeItems(spec, items);
  ASSERT_EQ(records.size(), items.size());
  SweepRow row;
  row.id = spec.Id();
  row.spec = spec.source;
  row.state = SweepState::kRunning;
  row.items_total = static_cast<long>(items.size());
  ASSERT_TRUE(writer.Db()->UpsertSweep(row).ok());
  auto store = [&](size_t from, size_t to) {
    IndexDb::JobResults rows;
    rows.sweep_id = row.id;
    rows.width = records[0].v.size();
    for (size_t i = from; i < to; ++i) {
      rows.keys += keys[i] + "\n";
      rows.values.insert(rows.values.end(), records[i].v.begin(), records[i].v.end());
    }
    return writer.Commit(std::move(rows));
  };
  ASSERT_TRUE(store(0, items.size() - 1).ok());  // all but the last item
  const std::string path = dir + "/sweeps/" + row.id + ".h5";
  const MapPublication m{spec, keys, {}, row, 100.0, path, dir};
  MapPublication::Outcome said;
  bool indexed = false;
  auto early = PublishMap(
      m, writer, [] { return 160.0; }, [&] { indexed = true; }, &said);
  ASSERT_FALSE(early.ok());
  EXPECT_TRUE(said.incomplete) << early.status().ToString();
  EXPECT_FALSE(indexed);
  EXPECT_FALSE(std::filesystem::exists(path));
  ASSERT_TRUE(store(items.size() - 1, items.size()).ok());
  said = {};
  auto done = PublishMap(
      m, writer, [] { return 160.0; }, [&] { indexed = true; }, &said);
  ASSERT_TRUE(done.ok()) << done.status().ToString();
  EXPECT_FALSE(said.incomplete);
  EXPECT_EQ(said.corrupt, 0);
  EXPECT_TRUE(said.folded.ok());
  EXPECT_TRUE(indexed);
  EXPECT_EQ(done->state, SweepState::kDone);
  EXPECT_EQ(done->file, "sweeps/" + row.id + ".h5");
  EXPECT_EQ(done->seconds, 60.0);
  EXPECT_EQ(done->items_done, static_cast<long>(items.size()));
  // The index says published, and the file holds the records as computed, in grid order.
  auto stored_row = writer.Db()->GetSweep(row.id);
  ASSERT_TRUE(stored_row.ok() && stored_row.value());
  EXPECT_EQ(stored_row.value()->state, SweepState::kDone);
  auto maps = writer.Db()->ListMaps(row.id);
  ASSERT_TRUE(maps.ok());
  EXPECT_FALSE(maps->empty());
  auto y_max = ReadMapMetric(path, "y_max");
  ASSERT_TRUE(y_max.ok()) << y_max.status().ToString();
  ASSERT_EQ(y_max->values.size(), items.size());
  const size_t mi = MetricIndex("y_max");
  for (size_t i = 0; i < items.size(); ++i) EXPECT_EQ(y_max->values[i], records[i].v[mi]) << "item " << i;
}

}  // namespace
}  // namespace bistable
