// The gRPC face of SweepCoordinator. Every handler goes through Serve — the service's one middleware
// (Arrow Flight's server middleware, as a call): the token checked for the method's operation, the body run
// with the caller's identity and role, its Status converted (proto/status_convert.h), refusals counted and
// logged. Bodies decode the request, call the coordinator and build the reply with proto/convert.h, as the
// client reads it — nothing else. Published maps are read through a MapCache (server/map_cache.h), shared
// with the dashboard when the caller passes one. Thread-safe (the coordinator is).
#ifndef BISTABLE_SERVER_COORDINATOR_SERVICE_H_
#define BISTABLE_SERVER_COORDINATOR_SERVICE_H_

#include <atomic>
#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include "bistable.grpc.pb.h"
#include "proto/convert.h"
#include "server/auth.h"
#include "server/map_cache.h"
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
  // maps: the published maps' cache to share (with the dashboard); none: one of its own.
  CoordinatorService(SweepCoordinator* c, double lease_seconds, double job_seconds = 2.0, TokenStore tokens = {},
                     std::shared_ptr<MapCache> maps = nullptr)
      : c_(c),
        lease_seconds_(lease_seconds),
        job_seconds_(job_seconds),
        tokens_(std::move(tokens)),
        maps_(maps ? std::move(maps) : std::make_shared<MapCache>()) {}
  void Shutdown() { shutting_down_ = true; }
  // Metrics to feed (report latency, refusals); optional, not owned.
  void SetMetrics(CoordinatorMetrics* m) { metrics_ = m; }

  grpc::Status Submit(grpc::ServerContext*, const v1::SubmitRequest*, v1::SubmitReply*) override;
  grpc::Status GetStatus(grpc::ServerContext*, const v1::StatusRequest*, v1::SweepStatus*) override;
  grpc::Status WatchStatus(grpc::ServerContext*, const v1::StatusRequest*,
                           grpc::ServerWriter<v1::SweepStatus>*) override;
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
  grpc::Status GetSpec(grpc::ServerContext*, const v1::SpecRequest*, v1::SpecReply*) override;
  grpc::Status FetchMap(grpc::ServerContext*, const v1::FetchMapRequest*, grpc::ServerWriter<v1::FileChunk>*) override;

 private:
  // The authenticated caller of a call.
  struct Caller {
    std::string who;  // the token's identity ("local" without tokens)
    Role role = Role::kAdmin;
  };
  // Every handler's one entry: checks the call's token for `op`, then runs body(caller) — a Status, or a
  // grpc::Status passed through as it is (a stream's end) — and answers it.
  template <class Body>
  grpc::Status Serve(grpc::ServerContext* ctx, const char* method, Op op, Body&& body);
  // The answer for a handler's Status: refusals are counted and logged (rate-limited) with the method,
  // code, peer and reason.
  grpc::Status Answer(const grpc::ServerContext* ctx, const char* method, const Status& st);
  // Leases the next job for `worker` into `rep` (has_job false when there is none), up to max_jobs
  // (0: 1) queued jobs merged into it; the spec text is left out when `known_specs` names its key.
  Status LeaseInto(const std::string& worker, const std::string& who, v1::LeaseReply* rep,
                   int max_jobs,  // bound to who
                   const std::vector<std::string>& known_specs);
  StatusOr<std::pair<std::string, std::string>> PublishedMap(const std::string& id_or_prefix) const;
  // A sweep's spec text and its key (SpecKey): by `spec_key` (a lease's) from the texts kept (the last
  // kMaxKnownSpecs), else the coordinator's text and key.
  StatusOr<SpecText> KeyedSpec(const std::string& sweep_id, const std::string& spec_key);
  SweepCoordinator* c_;
  double lease_seconds_, job_seconds_;
  TokenStore tokens_;
  std::atomic<bool> shutting_down_{false};
  std::shared_ptr<MapCache> maps_;
  CoordinatorMetrics* metrics_ = nullptr;
  std::mutex spec_texts_mu_;
  std::map<std::string, std::string> spec_texts_;  // spec key → text
  std::mutex refusal_log_mu_;
  long long refusal_log_second_ = 0, refusal_logs_this_second_ = 0, refusals_suppressed_ = 0;
};

}  // namespace bistable

#endif  // BISTABLE_SERVER_COORDINATOR_SERVICE_H_
