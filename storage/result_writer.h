// The index's one writing connection, shared by its users under one lock, with the two things that keep
// reports fast: group commit (concurrent reports queue their rows; whichever reporter holds the connection
// next stores every queued job in one transaction) and WAL checkpoints on a connection of their own in a
// background thread, so no report waits for a checkpoint (measured: docs/scaling.md). Issue 40: the
// coordinator's writer, as leveldb's DBImpl keeps its writers' group commit.
#ifndef BISTABLE_STORAGE_RESULT_WRITER_H_
#define BISTABLE_STORAGE_RESULT_WRITER_H_

#include <condition_variable>
#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "base/status.h"
#include "storage/index_db.h"

namespace bistable {

class ResultWriter {
 public:
  struct Options {
    // Seconds between PASSIVE checkpoints of the checkpointing connection; 0: no checkpointer (the
    // writer's own automatic checkpoint then does the work).
    double checkpoint_seconds = 0.25;
  };
  // Takes `db`, the index at `path` opened for writing. With checkpoint_seconds > 0 it opens a second
  // connection on `path` for checkpoints and raises the writer's automatic checkpoint to a safety net at
  // ~400 MB of WAL; if that connection cannot be had, the writer checkpoints by itself as before.
  ResultWriter(std::unique_ptr<IndexDb> db, const std::string& path, Options opt);
  // Stops the checkpointer.
  ~ResultWriter();
  ResultWriter(const ResultWriter&) = delete;
  ResultWriter& operator=(const ResultWriter&) = delete;

  // The connection under the writer's lock, for one call or a few (lookups, sweep rows, publication).
  struct Locked {
    std::unique_lock<std::mutex> lock;
    IndexDb* db;
    IndexDb* operator->() const { return db; }
  };
  Locked Db() const { return {std::unique_lock<std::mutex>(mu_), db_.get()}; }

  // Stores one job's rows durably (IndexDb::PutPoints), in one transaction with every job queued beside
  // it; returns once they are committed, or with the transaction's error.
  Status Commit(IndexDb::JobResults rows);

  long transactions() const;  // PutPoints transactions run (tests: several commits, one transaction)
  long checkpoints() const;   // checkpoints the background connection ran
  size_t queued() const;      // jobs queued for the next transaction (tests)
  bool checkpointing() const { return checkpointer_.joinable(); }

 private:
  unsigned long long Enqueue(IndexDb::JobResults rows);
  Status AwaitCommit(unsigned long long ticket);

  std::unique_ptr<IndexDb> db_;
  mutable std::mutex mu_;                                 // the connection (lock order: a caller's locks, then mu_)
  unsigned long long committed_through_ = 0;              // under mu_
  std::map<unsigned long long, Status> commit_failures_;  // under mu_: ticket → why
  long transactions_ = 0;                                 // under mu_
  mutable std::mutex batch_mu_;                           // a leaf
  std::vector<IndexDb::JobResults> batch_;                // under batch_mu_
  unsigned long long last_ticket_ = 0;                    // under batch_mu_
  std::unique_ptr<IndexDb> checkpoint_db_;
  mutable std::mutex checkpoint_mu_;
  std::condition_variable checkpoint_cv_;
  bool checkpoint_stop_ = false;  // under checkpoint_mu_
  long checkpoints_ = 0;          // under checkpoint_mu_
  std::thread checkpointer_;      // last: started after, and joined before, what it uses
};

}  // namespace bistable

#endif  // BISTABLE_STORAGE_RESULT_WRITER_H_
