#include "server/publisher.h"

namespace bistable {

Publisher::Publisher(Step step, std::function<void(const std::string&, const Status&)> failed)
    : step_(std::move(step)), failed_(std::move(failed)), thread_([this] { Loop(); }) {}

Publisher::~Publisher() { Close(); }

void Publisher::Close() {
  {
    std::lock_guard<std::mutex> lock(mu_);
    closing_ = true;
  }
  queued_cv_.notify_all();
  if (thread_.joinable() && thread_.get_id() != std::this_thread::get_id()) thread_.join();
}

std::shared_ptr<Publisher::Request> Publisher::QueueLocked(const std::string& sweep_id) {
  for (const auto& r : queue_)  // queued, not started: its step will see everything this caller would
    if (r->sweep_id == sweep_id) return r;
  auto r = std::make_shared<Request>();
  r->sweep_id = sweep_id;
  queue_.push_back(r);
  queued_cv_.notify_one();
  return r;
}

void Publisher::Post(const std::string& sweep_id) {
  std::lock_guard<std::mutex> lock(mu_);
  if (!closing_) QueueLocked(sweep_id);
}

StatusOr<std::string> Publisher::Run(const std::string& sweep_id) {
  std::unique_lock<std::mutex> lock(mu_);
  if (closing_) return Status::FailedPrecondition("the publisher is closing");
  std::shared_ptr<Request> r = QueueLocked(sweep_id);
  r->awaited = true;
  ++waiting_;
  done_cv_.wait(lock, [&] { return r->finished; });
  --waiting_;
  return r->outcome;
}

void Publisher::Loop() {
  std::unique_lock<std::mutex> lock(mu_);
  while (true) {
    queued_cv_.wait(lock, [&] { return closing_ || !queue_.empty(); });
    if (queue_.empty()) return;  // closing, nothing left
    std::shared_ptr<Request> r = queue_.front();
    queue_.pop_front();
    lock.unlock();
    StatusOr<std::string> outcome = step_(r->sweep_id);
    lock.lock();
    ++steps_;
    r->outcome = std::move(outcome);
    r->finished = true;
    const bool awaited = r->awaited;
    done_cv_.notify_all();
    if (!awaited && !r->outcome.ok() && r->outcome.status().code() != Status::Code::kFailedPrecondition && failed_) {
      const Status st = r->outcome.status();
      lock.unlock();
      failed_(r->sweep_id, st);
      lock.lock();
    }
  }
}

long Publisher::steps() const {
  std::lock_guard<std::mutex> lock(mu_);
  return steps_;
}

long Publisher::waiting() const {
  std::lock_guard<std::mutex> lock(mu_);
  return waiting_;
}

}  // namespace bistable
