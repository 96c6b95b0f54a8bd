#include "storage/result_writer.h"

#include <chrono>

namespace bistable {

ResultWriter::ResultWriter(std::unique_ptr<IndexDb> db, const std::string& path, Options opt) : db_(std::move(db)) {
  if (opt.checkpoint_seconds <= 0) return;
  auto ck = IndexDb::Open(path);
  if (!ck.ok()) return;
  checkpoint_db_ = std::move(ck).value();
  (void)checkpoint_db_->SetCacheKib(64);  // it copies WAL frames; it caches nothing worth memory
  if (!db_->SetAutoCheckpoint(100000).ok()) return;
  const auto period = std::chrono::duration<double>(opt.checkpoint_seconds);
  checkpointer_ = std::thread([this, period] {
    std::unique_lock<std::mutex> lock(checkpoint_mu_);
    while (!checkpoint_cv_.wait_for(lock, period, [this] { return checkpoint_stop_; })) {
      lock.unlock();
      const bool ok = checkpoint_db_->CheckpointPassive().ok();
      lock.lock();
      if (ok) ++checkpoints_;
    }
  });
}

ResultWriter::~ResultWriter() {
  {
    std::lock_guard<std::mutex> lock(checkpoint_mu_);
    checkpoint_stop_ = true;
  }
  checkpoint_cv_.notify_all();
  if (checkpointer_.joinable()) checkpointer_.join();
}

unsigned long long ResultWriter::Enqueue(IndexDb::JobResults rows) {
  std::lock_guard<std::mutex> lock(batch_mu_);
  batch_.push_back(std::move(rows));
  return ++last_ticket_;
}

Status ResultWriter::AwaitCommit(unsigned long long ticket) {
  std::lock_guard<std::mutex> lock(mu_);
  if (ticket > committed_through_) {
    // Lead: store everything queued so far (this ticket and any that arrived while the previous
    // transaction ran) in one transaction.
    std::vector<IndexDb::JobResults> batch;
    unsigned long long last = 0;
    {
      std::lock_guard<std::mutex> b(batch_mu_);
      batch.swap(batch_);
      last = last_ticket_;
    }
    const Status st = db_->PutPoints(batch);
    ++transactions_;
    if (!st.ok())
      for (unsigned long long t = committed_through_ + 1; t <= last; ++t) commit_failures_[t] = st;
    committed_through_ = last;
  }
  auto failed = commit_failures_.find(ticket);
  if (failed == commit_failures_.end()) return Status::Ok();
  Status st = failed->second;
  commit_failures_.erase(failed);
  return st;
}

Status ResultWriter::Commit(IndexDb::JobResults rows) { return AwaitCommit(Enqueue(std::move(rows))); }

long ResultWriter::transactions() const {
  std::lock_guard<std::mutex> lock(mu_);
  return transactions_;
}

long ResultWriter::checkpoints() const {
  std::lock_guard<std::mutex> lock(checkpoint_mu_);
  return checkpoints_;
}

size_t ResultWriter::queued() const {
  std::lock_guard<std::mutex> lock(batch_mu_);
  return batch_.size();
}

}  // namespace bistable
