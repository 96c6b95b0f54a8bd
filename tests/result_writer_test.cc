// The result writer on its own (storage/result_writer.h, issue 40): group commit and the background
// checkpointer, on a real SQLite index in a temporary directory.
#include "storage/result_writer.h"

#include <chrono>
#include <filesystem>
#include <thread>
#include <vector>

#include <gtest/gtest.h>

#include "tests/process_util.h"

namespace bistable {
namespace {

std::string TempDir(const std::string& name) { return bistable_test::FreshDir("bistable_writer", name); }

constexpr size_t kWidth = 8;

// One job's rows: `n` records under keys "<prefix>-<i>", values i + 0.5.
IndexDb::JobResults Rows(const std::string& prefix, int n) {
  IndexDb::JobResults rows;
  rows.sweep_id = "s";
  rows.width = kWidth;
  for (int i = 0; i < n; ++i) {
    rows.keys += prefix + "-" + std::to_string(i) + "\n";
    for (size_t k = 0; k < kWidth; ++k) rows.values.push_back(i + 0.5);
  }
  return rows;
}

std::unique_ptr<IndexDb> OpenIndex(const std::string& path) {
  auto db = IndexDb::Open(path);
  EXPECT_TRUE(db.ok()) << db.status().ToString();
  return db.ok() ? std::move(db).value() : nullptr;
}

TEST(ResultWriter, ConcurrentCommitsShareOneTransactionAndAreDurable) {
  const std::string path = TempDir("writer_group") + "/index.sqlite";
  ResultWriter w(OpenIndex(path), path, ResultWriter::Options{.checkpoint_seconds = 0});
  ASSERT_FALSE(w.checkpointing());
  constexpr int kReporters = 4;
  std::vector<std::thread> reporters;
  std::vector<Status> results(kReporters, Status::IoError("test", "not run"));
  {
    // The connection is busy (a transaction of someone else's): the reports queue up behind it.
    ResultWriter::Locked busy = w.Db();
    for (int r = 0; r < kReporters; ++r)
      reporters.emplace_back([&, r] { results[r] = w.Commit(Rows("job" + std::to_string(r), 10)); });
    for (int i = 0; i < 2000 && w.queued() < kReporters; ++i) std::this_thread::sleep_for(std::chrono::milliseconds(5));
    ASSERT_EQ(w.queued(), static_cast<size_t>(kReporters));
  }
  for (auto& t : reporters) t.join();
  for (const Status& st : results) EXPECT_TRUE(st.ok()) << st.ToString();
  EXPECT_EQ(w.transactions(), 1) << "the first reporter to hold the connection stores every queued job";
  EXPECT_EQ(w.queued(), 0u);
  // Durable: a second connection on the file reads every record back.
  auto reader = OpenIndex(path);
  std::vector<std::string> keys;
  for (int r = 0; r < kReporters; ++r)
    for (int i = 0; i < 10; ++i) keys.push_back("job" + std::to_string(r) + "-" + std::to_string(i));
  auto found = reader->LookupPoints(keys, kWidth);
  ASSERT_TRUE(found.ok()) << found.status().ToString();
  EXPECT_EQ(found->size(), keys.size());
  EXPECT_EQ(found->at("job3-7").v[0], 7.5);
  // A commit alone is a transaction of its own.
  ASSERT_TRUE(w.Commit(Rows("alone", 1)).ok());
  EXPECT_EQ(w.transactions(), 2);
}

TEST(ResultWriter, TheCheckpointerCopiesCommittedPagesIntoTheIndexFile) {
  const std::string dir = TempDir("writer_checkpoint"), path = dir + "/index.sqlite";
  ResultWriter w(OpenIndex(path), path, ResultWriter::Options{.checkpoint_seconds = 0.01});
  ASSERT_TRUE(w.checkpointing());
  const auto before = std::filesystem::file_size(path);
  // About 2 MB of records: half the writer's default automatic checkpoint (4 MB), which the writer raised to
  // ~400 MB; only the checkpointer moves them into the index file.
  ASSERT_TRUE(w.Commit(Rows("big", 32768)).ok());
  const long seen = w.checkpoints();
  for (int i = 0; i < 1000 && w.checkpoints() < seen + 2; ++i)
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  ASSERT_GE(w.checkpoints(), seen + 2);
  EXPECT_GT(std::filesystem::file_size(path), before + 1'000'000)
      << "the WAL's frames were not copied into the index file";
}

TEST(ResultWriter, WithoutTheCheckpointerTheWalKeepsTheRecords) {
  // The control of the test above: no checkpointer, the same commit stays in the WAL.
  const std::string dir = TempDir("writer_no_checkpoint"), path = dir + "/index.sqlite";
  ResultWriter w(OpenIndex(path), path, ResultWriter::Options{.checkpoint_seconds = 0});
  const auto before = std::filesystem::file_size(path);
  ASSERT_TRUE(w.Commit(Rows("big", 32768)).ok());
  std::this_thread::sleep_for(std::chrono::milliseconds(50));
  EXPECT_EQ(w.checkpoints(), 0);
  EXPECT_LT(std::filesystem::file_size(path), before + 1'000'000);
  EXPECT_GT(std::filesystem::file_size(path + "-wal"), 1'000'000u);
}

}  // namespace
}  // namespace bistable
