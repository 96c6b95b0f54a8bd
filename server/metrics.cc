#include "server/metrics.h"

#include <malloc.h>

#include <chrono>
#include <deque>
#include <mutex>

#include <prometheus/client_metric.h>
#include <prometheus/metric_family.h>

namespace bistable {
namespace {

prometheus::MetricFamily Family(const char* name, const char* help, prometheus::MetricType type) {
  prometheus::MetricFamily f;
  f.name = name;
  f.help = help;
  f.type = type;
  return f;
}

void Add(prometheus::MetricFamily& f, double v, std::vector<prometheus::ClientMetric::Label> labels = {}) {
  prometheus::ClientMetric m;
  m.label = std::move(labels);
  if (f.type == prometheus::MetricType::Counter)
    m.counter.value = v;
  else
    m.gauge.value = v;
  f.metric.push_back(std::move(m));
}

// Reads the coordinator's counters and gauges at scrape time.
class StatsCollector : public prometheus::Collectable {
 public:
  explicit StatsCollector(const SweepCoordinator* c) : c_(c) {}

  std::vector<prometheus::MetricFamily> Collect() const override {
    using prometheus::MetricType;
    const CoordinatorStats s = c_->Stats();
    std::vector<prometheus::MetricFamily> out;
    auto one = [&](const char* name, const char* help, MetricType t, double v) {
      out.push_back(Family(name, help, t));
      Add(out.back(), v);
    };
    one("bistable_items_done_total", "Items (grid points x initial conditions) of stored reports since start",
        MetricType::Counter, static_cast<double>(s.items_stored));
    one("bistable_items_per_second", "Items stored per second over the last minute of scrapes", MetricType::Gauge,
        Rate(s.items_stored));
    one("bistable_jobs_queued", "Jobs waiting for a worker", MetricType::Gauge, static_cast<double>(s.jobs_queued));
    one("bistable_items_pending", "Items of running sweeps not yet stored", MetricType::Gauge,
        static_cast<double>(s.items_pending));
    one("bistable_leases_outstanding", "Leases held by workers now", MetricType::Gauge,
        static_cast<double>(s.leases_outstanding));
    one("bistable_leases_granted_total", "Leases granted", MetricType::Counter, static_cast<double>(s.leases_granted));
    one("bistable_leases_expired_total", "Leases expired without a report (their jobs were requeued)",
        MetricType::Counter, static_cast<double>(s.leases_expired));
    one("bistable_leases_released_total", "Leases given back by workers (their jobs were requeued)",
        MetricType::Counter, static_cast<double>(s.leases_released));
    out.push_back(Family("bistable_reports_total", "Reports by outcome", MetricType::Counter));
    Add(out.back(), static_cast<double>(s.reports_stored), {{"outcome", "stored"}});
    Add(out.back(), static_cast<double>(s.reports_duplicate), {{"outcome", "duplicate"}});
    Add(out.back(), static_cast<double>(s.reports_failed), {{"outcome", "failed"}});
    one("bistable_workers", "Workers holding a lease or seen within three lease periods", MetricType::Gauge,
        static_cast<double>(s.workers_active));
    out.push_back(Family("bistable_worker_items_total", "Items stored per worker", MetricType::Counter));
    for (const WorkerInfo& w : s.workers) Add(out.back(), static_cast<double>(w.items_done), {{"worker", w.name}});
    out.push_back(Family("bistable_sweeps", "Sweeps this coordinator holds, by state", MetricType::Gauge));
    for (int st = 0; st < static_cast<int>(s.sweeps_by_state.size()); ++st)
      Add(out.back(), static_cast<double>(s.sweeps_by_state[st]),
          {{"state", SweepStateName(static_cast<SweepState>(st))}});
    // The heap as malloc sees it: what is allocated now, and what is free but kept (fragments in the
    // arenas that malloc_trim cannot give back). RSS alone mixes the two with the mapped libraries.
    const struct mallinfo2 mi = ::mallinfo2();
    one("bistable_heap_in_use_bytes", "Heap bytes allocated now (malloc arenas and mmapped blocks)", MetricType::Gauge,
        static_cast<double>(mi.uordblks + mi.hblkhd));
    one("bistable_heap_free_retained_bytes", "Heap bytes free inside the malloc arenas, not yet returned to the system",
        MetricType::Gauge, static_cast<double>(mi.fordblks));
    return out;
  }

 private:
  // Items/s between the oldest sample of the last minute and now (0 until two scrapes a second apart).
  double Rate(long items) const {
    const double now = std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
    std::lock_guard<std::mutex> lock(mu_);
    samples_.push_back({now, items});
    while (samples_.size() > 2 && now - samples_[1].first > 60) samples_.pop_front();
    while (samples_.size() > 256) samples_.pop_front();
    const auto& [t0, n0] = samples_.front();
    return now - t0 >= 1 ? static_cast<double>(items - n0) / (now - t0) : 0;
  }

  const SweepCoordinator* c_;
  mutable std::mutex mu_;
  mutable std::deque<std::pair<double, long>> samples_;
};

}  // namespace

CoordinatorMetrics::CoordinatorMetrics(const SweepCoordinator* c)
    : registry_(std::make_shared<prometheus::Registry>()), stats_(std::make_shared<StatsCollector>(c)) {
  report_seconds_ = &prometheus::BuildHistogram()
                         .Name("bistable_report_seconds")
                         .Help("Report calls, from decode to answer (checks, durable store, next lease)")
                         .Register(*registry_)
                         .Add({}, prometheus::Histogram::BucketBoundaries{0.0005, 0.001, 0.002, 0.005, 0.01, 0.02, 0.05,
                                                                          0.1, 0.2, 0.5, 1, 2, 5});
  refused_ = &prometheus::BuildCounter()
                  .Name("bistable_calls_refused_total")
                  .Help("Calls answered with an error, by method and gRPC code")
                  .Register(*registry_);
}

void CoordinatorMetrics::CountRefusal(const std::string& method, const std::string& code) {
  refused_->Add({{"method", method}, {"code", code}}).Increment();
}

}  // namespace bistable
