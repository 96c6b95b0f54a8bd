// The coordinator's Prometheus metrics, served on `--metrics ADDR` (net/http_server.h). Gauges and
// per-worker counters are read from SweepCoordinator::Stats() at scrape time (nothing is counted twice);
// the report latency histogram and refusal counters are fed by the gRPC service.
//   bistable_items_done_total            items of stored reports since this process started
//   bistable_items_per_second            items stored per second over the last minute of scrapes
//   bistable_jobs_queued                 jobs waiting for a worker (all running sweeps)
//   bistable_items_pending               items of running sweeps not yet stored
//   bistable_leases_outstanding          leases held by workers now
//   bistable_leases_granted_total / _expired_total / _released_total
//   bistable_reports_total{outcome="stored|duplicate|failed"}
//   bistable_report_seconds              histogram: a Report call from decode to answer
//   bistable_calls_refused_total{method,code}
//   bistable_workers                     workers with a lease or seen within 3 lease periods
//   bistable_worker_items_total{worker}  items stored per worker
//   bistable_sweeps{state}               sweeps this process holds, by state
//   bistable_heap_in_use_bytes           heap allocated now (mallinfo2: arenas + mmapped blocks)
//   bistable_heap_free_retained_bytes    heap free inside the arenas, kept by malloc
#ifndef BISTABLE_SERVER_METRICS_H_
#define BISTABLE_SERVER_METRICS_H_

#include <memory>
#include <string>
#include <vector>

#include <prometheus/collectable.h>
#include <prometheus/counter.h>
#include <prometheus/family.h>
#include <prometheus/histogram.h>
#include <prometheus/registry.h>

#include "server/sweep_coordinator.h"

namespace bistable {

class CoordinatorMetrics {
 public:
  explicit CoordinatorMetrics(const SweepCoordinator* c);
  void ObserveReport(double seconds) { report_seconds_->Observe(seconds); }
  void CountRefusal(const std::string& method, const std::string& code);
  // What "/metrics" serializes.
  std::vector<std::shared_ptr<prometheus::Collectable>> Sources() const { return {registry_, stats_}; }

 private:
  std::shared_ptr<prometheus::Registry> registry_;
  prometheus::Histogram* report_seconds_;
  prometheus::Family<prometheus::Counter>* refused_;
  std::shared_ptr<prometheus::Collectable> stats_;
};

}  // namespace bistable

#endif  // BISTABLE_SERVER_METRICS_H_
