// The one pull loop: lease a job, compute it (engine/evaluate.h) while heartbeating its lease, report
// it, repeat. `bistable-worker` runs it against a coordinator over gRPC (worker/grpc_job_source.h) and
// the embedded `bistable run` against the coordinator in its own process (client/embedded_run.cc);
// both therefore compute, cancel and retry the same way.
//
// Cancellation (dynamics/cancel.h): a job cut short is released, never reported, and the loop ends.
// Thread-safe as far as the JobSource is: run one loop per thread.
#ifndef BISTABLE_WORKER_PULL_LOOP_H_
#define BISTABLE_WORKER_PULL_LOOP_H_

#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "base/status.h"
#include "engine/evaluate.h"

namespace bistable {

// A leased job: its items of one sweep, to be reported (or released) under `lease_id`.
struct LeasedJob {
  std::string lease_id;
  std::shared_ptr<const SweepSpec> spec;
  std::vector<WorkItem> items;
};

// Where jobs come from. Errors: an IoError is transient (the coordinator is away: retried with
// backoff); anything else is the coordinator's refusal.
class JobSource {
 public:
  virtual ~JobSource() = default;
  // The next job, or nullopt when there is none now.
  virtual StatusOr<std::optional<LeasedJob>> Lease() = 0;
  // Extends the lease while a long job computes (best effort).
  virtual void Heartbeat(const LeasedJob& job) = 0;
  // Stores the job's records. When `next` is not null the source may lease the following job in the
  // same call and put it there (one round trip per job instead of two).
  virtual Status Report(const LeasedJob& job, const std::vector<PointRecord>& records,
                        std::optional<LeasedJob>* next) = 0;
  // Gives the job back unreported (cancelled, or its spec could not be used).
  virtual Status Release(const LeasedJob& job) = 0;
};

struct PullLoopOptions {
  std::string name = "worker";   // the worker's name in log events
  double heartbeat_seconds = 0;  // while computing; 0 = never
  bool until_idle = false;       // end when the source has no job (the embedded run); else poll
  double idle_poll_seconds = 0.05;
  int report_retries = 50;             // transient report failures retried with backoff (0: fail at once)
  bool stop_on_error = false;          // end at the first report failure (the embedded run) instead of
                                       // logging it and going on (the job requeues when its lease expires)
  bool log = true;                     // refusals and stops as log events (base/log.h)
  std::function<bool()> stop;          // checked between jobs, besides cancellation
  std::function<void(long)> on_items;  // items reported (progress)
  std::function<void(long items, double seconds)> on_computed;  // a job computed (metrics)
};

struct PullLoopResult {
  long items = 0;  // items reported and acknowledged
  Status error;    // the first report refusal or non-transient failure with report_retries == 0
};

PullLoopResult RunPullLoop(JobSource& source, const PullLoopOptions& opt);

// Sleeps up to `seconds`, waking early when cancellation is requested.
void SleepUnlessCancelled(double seconds);

// Exponential backoff for a coordinator that is away: 0.1 s doubling to 5 s; wakes on cancellation.
class Backoff {
 public:
  void Wait();
  void Reset() { delay_ = 0.1; }

 private:
  double delay_ = 0.1;
};

}  // namespace bistable

#endif  // BISTABLE_WORKER_PULL_LOOP_H_
