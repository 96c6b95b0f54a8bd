// The gRPC face of SweepCoordinator. Handlers decode the request, call the coordinator, convert the
// Status (proto/status_convert.h) — nothing else. Thread-safe (the coordinator is).
#ifndef BISTABLE_SERVER_COORDINATOR_SERVICE_H_
#define BISTABLE_SERVER_COORDINATOR_SERVICE_H_

#include <atomic>
#include <mutex>

#include "bistable.grpc.pb.h"
#include "server/auth.h"
#include "server/metrics.h"
#include "server/sweep_coordinator.h"

namespace bistable {

// Server settings shared by bistable-coordinator and the benchmarks: message limits and a steady pool
// of polling threads (gRPC's default of at most 2 pollers makes the sync server create and destroy a
// thread for many calls under load: 9,300 clone3 calls in 40,000 calls, measured).
void ConfigureServerBuilder(grpc::ServerBuilder& builder);

class CoordinatorService final : public v1::Coordinator::Service {
 public:
  // job_seconds: target work per job on one core (jobs are blocks of points sized to it).
  CoordinatorService(SweepCoordinator* c, double lease_seconds, double job_seconds = 2.0, TokenStore tokens = {})
      : c_(c), lease_seconds_(lease_seconds), job_seconds_(job_seconds), tokens_(std::move(tokens)) {}
  void Shutdown() { shutting_down_ = true; }
  // Metrics to feed (report latency, refusals); optional, not owned.
  void SetMetrics(CoordinatorMetrics* m) { metrics_ = m; }

  grpc::Status Submit(grpc::ServerContext*, const v1::SubmitRequest*, v1::SubmitReply*) override;
  grpc::Status GetStatus(grpc::ServerContext*, const v1::StatusRequest*, v1::SweepStatus*) override;
  grpc::Status WatchStatus(grpc::ServerContext*, const v1::StatusRequest*, grpc::ServerWriter<v1::SweepStatus>*) override;
  grpc::Status Cancel(grpc::ServerContext*, const v1::CancelRequest*, v1::CancelReply*) override;
  grpc::Status ListSweeps(grpc::ServerContext*, const v1::ListSweepsRequest*, v1::ListSweepsReply*) override;
  grpc::Status GetMap(grpc::ServerContext*, const v1::MapRequest*, v1::MapReply*) override;
  grpc::Status ListMetrics(grpc::ServerContext*, const v1::MapRequest*, v1::MetricsReply*) override;
  grpc::Status RegisterWorker(grpc::ServerContext*, const v1::RegisterRequest*, v1::RegisterReply*) override;
  grpc::Status Lease(grpc::ServerContext*, const v1::LeaseRequest*, v1::LeaseReply*) override;
  grpc::Status Heartbeat(grpc::ServerContext*, const v1::HeartbeatRequest*, v1::HeartbeatReply*) override;
  grpc::Status Report(grpc::ServerContext*, const v1::ReportRequest*, v1::ReportReply*) override;
  grpc::Status Release(grpc::ServerContext*, const v1::ReleaseRequest*, v1::ReleaseReply*) override;
  grpc::Status ListWorkers(grpc::ServerContext*, const v1::ListWorkersRequest*, v1::ListWorkersReply*) override;
  grpc::Status FetchMap(grpc::ServerContext*, const v1::FetchMapRequest*, grpc::ServerWriter<v1::FileChunk>*) override;

 private:
  // The answer for a handler's Status: refusals are counted and logged (rate-limited) with the method,
  // code, peer and reason.
  grpc::Status Answer(const grpc::ServerContext* ctx, const char* method, const Status& st);
  // Leases the next job for `worker` into `rep` (has_job false when there is none), up to max_jobs
  // (0: 1) queued jobs merged into it.
  Status LeaseInto(const std::string& worker, const std::string& who, v1::LeaseReply* rep, int max_jobs);  // bound to who
  StatusOr<std::pair<std::string, std::string>> PublishedMap(const std::string& id_or_prefix) const;
  SweepCoordinator* c_;
  double lease_seconds_, job_seconds_;
  TokenStore tokens_;
  std::atomic<bool> shutting_down_{false};
  CoordinatorMetrics* metrics_ = nullptr;
  std::mutex refusal_log_mu_;
  long long refusal_log_second_ = 0, refusal_logs_this_second_ = 0, refusals_suppressed_ = 0;
};

}  // namespace bistable

#endif  // BISTABLE_SERVER_COORDINATOR_SERVICE_H_
