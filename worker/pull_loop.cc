#include "worker/pull_loop.h"

#include <chrono>
#include <future>
#include <thread>

#include "base/log.h"
#include "dynamics/cancel.h"

namespace bistable {

void SleepUnlessCancelled(double seconds) {
  const auto end = std::chrono::steady_clock::now() + std::chrono::duration_cast<std::chrono::steady_clock::duration>(
                                                          std::chrono::duration<double>(seconds));
  const std::chrono::steady_clock::duration slice = std::chrono::milliseconds(20);
  while (!CancelRequested()) {
    const auto left = end - std::chrono::steady_clock::now();
    if (left <= std::chrono::steady_clock::duration::zero()) break;
    std::this_thread::sleep_for(left < slice ? left : slice);
  }
}

void Backoff::Wait() {
  SleepUnlessCancelled(delay_);
  delay_ = std::min(5.0, delay_ * 2);
}

namespace {

bool Transient(const Status& st) { return st.code() == Status::Code::kIoError; }

// Computes the job, heartbeating its lease meanwhile when asked to.
std::optional<std::vector<PointRecord>> Compute(JobSource& source, const LeasedJob& job, double heartbeat_seconds) {
  if (heartbeat_seconds <= 0) return ComputeItemsUnlessCancelled(*job.spec, job.items);
  auto work = std::async(std::launch::async, [&] { return ComputeItemsUnlessCancelled(*job.spec, job.items); });
  // The computation stops within milliseconds of a cancellation, so waiting for it is short then.
  while (work.wait_for(std::chrono::duration<double>(heartbeat_seconds)) != std::future_status::ready)
    source.Heartbeat(job);
  return work.get();
}

}  // namespace

PullLoopResult RunPullLoop(JobSource& source, const PullLoopOptions& opt) {
  PullLoopResult result;
  Backoff backoff;
  std::optional<LeasedJob> next;  // leased by the previous report
  auto stopping = [&] { return CancelRequested() || (opt.stop && opt.stop()); };
  auto fail = [&](const Status& st) {
    if (result.error.ok()) result.error = st;
  };
  while (!stopping()) {
    if (!next) {
      auto leased = source.Lease();
      if (!leased.ok()) {
        if (!Transient(leased.status()) && opt.log)
          log::Event(log::Level::kWarn, "lease.refused",
                     {{"worker", opt.name}, {"reason", leased.status().ToString()}});
        if (opt.stop_on_error && !Transient(leased.status())) {
          fail(leased.status());
          break;
        }
        backoff.Wait();
        continue;
      }
      next = std::move(*leased);
    }
    backoff.Reset();
    if (!next) {
      if (opt.until_idle) break;
      SleepUnlessCancelled(opt.idle_poll_seconds);
      continue;
    }
    const LeasedJob job = std::move(*next);
    next.reset();
    // The lease is checked against its spec before anything runs: a hostile or broken coordinator's
    // out-of-range point or slot would otherwise index past the grid (issue 39). Given back, refused.
    if (Status bad = CheckItems(*job.spec, job.items, "lease"); !bad.ok()) {
      const Status rs = source.Release(job);
      if (opt.log)
        log::Event(log::Level::kError, "lease.refused",
                   {{"worker", opt.name},
                    {"lease", job.lease_id},
                    {"reason", bad.ToString()},
                    {"action", rs.ok() ? "released, not computed" : "not computed; release failed"}});
      fail(bad);
      if (opt.stop_on_error) break;
      backoff.Wait();
      continue;
    }
    const auto t0 = std::chrono::steady_clock::now();
    const std::optional<std::vector<PointRecord>> records = Compute(source, job, opt.heartbeat_seconds);
    if (!records) {  // cancelled mid-job: report nothing of it, give the job back now
      const Status rs = source.Release(job);
      if (opt.log)
        log::Event(log::Level::kInfo, "job.stopped",
                   {{"worker", opt.name},
                    {"lease", job.lease_id},
                    {"outcome", rs.ok() ? "released" : "release failed; it requeues when the lease expires"},
                    {"reason", rs.ok() ? "" : rs.ToString()}});
      break;
    }
    if (opt.on_computed)
      opt.on_computed(static_cast<long>(records->size()),
                      std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());
    for (int attempt = 0;; ++attempt) {  // reports are idempotent: retry transient failures
      const Status st = source.Report(job, *records, stopping() ? nullptr : &next);
      if (st.ok()) {
        result.items += static_cast<long>(records->size());
        if (opt.on_items) opt.on_items(static_cast<long>(records->size()));
        break;
      }
      if (!Transient(st) || attempt >= opt.report_retries || CancelRequested()) {
        if (opt.log)
          log::Event(log::Level::kWarn, "report.failed",
                     {{"worker", opt.name},
                      {"lease", job.lease_id},
                      {"outcome", Transient(st) ? "not answered" : "refused"},
                      {"reason", st.ToString()},
                      {"action", opt.stop_on_error ? "stop" : "its job requeues when the lease expires"}});
        fail(st);
        break;
      }
      backoff.Wait();
    }
    backoff.Reset();
    if (opt.stop_on_error && !result.error.ok()) break;
  }
  if (next) source.Release(*next);  // stopping with a job leased by the last report: give it back
  return result;
}

}  // namespace bistable
