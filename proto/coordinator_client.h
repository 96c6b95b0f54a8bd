// The client side of the wire in one class: every call the CLI and the worker make to a coordinator,
// with the project's types in and out (conversions in proto/convert.h) and errors as Status — a
// coordinator that cannot be reached is an IoError naming its address (callers retry those).
#ifndef BISTABLE_PROTO_COORDINATOR_CLIENT_H_
#define BISTABLE_PROTO_COORDINATOR_CLIENT_H_

#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "base/status.h"
#include "engine/map_array.h"
#include "engine/metric_catalog.h"
#include "engine/sweep_spec.h"
#include "engine/sweep_state.h"
#include "proto/channel.h"
#include "proto/convert.h"

namespace bistable {

class CoordinatorClient {
 public:
  // A client over one channel (plaintext on loopback, TLS with o.tls_ca); the token rides on every call.
  static StatusOr<std::unique_ptr<CoordinatorClient>> Connect(const ConnectOptions& o);
  ~CoordinatorClient();

  // --- clients ---
  using Submitted = SubmitResult;  // proto/convert.h, like every reply
  StatusOr<Submitted> Submit(const std::string& spec_toml, const std::string& origin);
  StatusOr<SweepInfo> GetStatus(const std::string& id);
  // Streams the sweep's status until it is final (or `on_status` returns false); the last one seen.
  StatusOr<SweepInfo> Watch(const std::string& id, const std::function<bool(const SweepInfo&)>& on_status);
  Status Cancel(const std::string& id);
  StatusOr<std::vector<WorkerInfo>> Workers();
  using MetricList = ::bistable::MetricList;
  StatusOr<MetricList> ListMetrics(const std::string& id);
  StatusOr<MapArray> GetMap(const std::string& id, const std::string& metric);
  StatusOr<std::vector<SweepInfo>> ListSweeps();
  // Streams a published map file into `sink` (chunks in order). Checked as it arrives: the id is a
  // sweep id, offsets follow each other, the size is the one announced and at most
  // limits::kMaxFetchBytes, and the SHA-256 of what was received equals the coordinator's. The sink's
  // error stops the transfer.
  struct Fetched {
    std::string id, sha256;
    uint64_t bytes = 0;
  };
  StatusOr<Fetched> FetchMap(const std::string& id, const std::function<Status(std::string_view data)>& sink);

  // --- workers ---
  // Registers; the lease period in seconds.
  StatusOr<double> Register(const std::string& name, int threads);
  // A lease; its spec_toml is "" when `known_specs` named its spec_key (the caller holds that spec).
  using Lease = LeasedWork;
  // max_jobs > 1: up to that many queued jobs merged into one lease (SweepCoordinator::Lease).
  // known_specs: the spec keys (SpecKey) whose text the caller holds, at most limits::kMaxKnownSpecs.
  StatusOr<std::optional<Lease>> LeaseJob(const std::string& worker, int max_jobs = 1,
                                          const std::vector<std::string>& known_specs = {});
  Status Heartbeat(const std::string& lease_id);
  // Reports; with `lease_next_for` non-empty the reply may carry the worker's next job (into *next).
  Status Report(const std::string& lease_id, const std::vector<PointRecord>& records, const std::string& lease_next_for,
                std::optional<Lease>* next, int next_max_jobs = 1,
                const std::vector<std::string>& next_known_specs = {});
  // A sweep's spec text and key (a lease that came without it); the key is checked to be the text's.
  StatusOr<SpecText> GetSpec(const std::string& sweep_id);
  Status Release(const std::string& lease_id);

  const std::string& address() const { return o_.address; }

 private:
  struct Impl;
  CoordinatorClient(ConnectOptions o, std::unique_ptr<Impl> impl);
  ConnectOptions o_;
  std::unique_ptr<Impl> impl_;
};

}  // namespace bistable

#endif  // BISTABLE_PROTO_COORDINATOR_CLIENT_H_
