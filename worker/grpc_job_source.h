// bistable-worker's side of worker/pull_loop.h: jobs leased from a coordinator over gRPC
// (proto/coordinator_client.h), and the parsed specs the pull loops of one process share.
//
// A spec travels once per sweep to a worker, not with every lease: the worker names the keys of the specs it
// holds (LeaseRequest.known_specs; a spec's key is the SHA-256 of its text, proto/convert.h SpecKey), and a
// lease of one of them comes without the text. Nothing of this is state on the coordinator, so every failure
// falls back to sending the text: a restarted worker holds nothing and names nothing (old workers name nothing
// either and get the text every time); a restarted coordinator answers what the request names; a lease that
// came without its text to a worker that no longer holds it (pushed out by another sweep's spec between the
// request and the reply) is completed by GetSpec, its key checked against the text. A coordinator before
// issue 40 ignores known_specs and always sends the text, which the worker keys itself.
#ifndef BISTABLE_WORKER_GRPC_JOB_SOURCE_H_
#define BISTABLE_WORKER_GRPC_JOB_SOURCE_H_

#include <cstddef>
#include <functional>
#include <list>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include "base/limits.h"
#include "base/status.h"
#include "engine/sweep_spec.h"
#include "proto/coordinator_client.h"
#include "worker/pull_loop.h"

namespace bistable {

// Parsed specs by spec key, at most `capacity` (least recently used out first). Thread-safe.
class SpecCache {
 public:
  explicit SpecCache(std::size_t capacity = limits::kMaxKnownSpecs) : capacity_(capacity) {}
  // The spec of `key`, or nullptr.
  std::shared_ptr<const SweepSpec> Find(const std::string& key);
  // Parses `toml` (named "sweep <sweep_id>" in errors) and keeps it under its own key (SpecKey(toml)),
  // which must equal `key` when `key` is given (InvalidArgument "spec" otherwise). Kept specs are not parsed
  // again.
  StatusOr<std::shared_ptr<const SweepSpec>> Put(const std::string& sweep_id, const std::string& toml,
                                                 const std::string& key = "");
  // The keys held, most recently used first: what a lease request names.
  std::vector<std::string> Keys() const;
  // Parses done so far (tests: a spec is parsed once per process).
  long parses() const;

 private:
  const std::size_t capacity_;
  mutable std::mutex mu_;
  std::list<std::pair<std::string, std::shared_ptr<const SweepSpec>>> lru_;  // most recently used first
  long parses_ = 0;
};

// The spec of a lease: its text when it came with one, else the cache's entry for its key, else the
// coordinator's answer to GetSpec.
StatusOr<std::shared_ptr<const SweepSpec>> SpecOfLease(CoordinatorClient* c, SpecCache* cache,
                                                       const CoordinatorClient::Lease& lease);

class GrpcJobSource : public JobSource {
 public:
  // on_rpc (optional): every call's method and outcome (the worker's metrics).
  GrpcJobSource(CoordinatorClient* c, std::string name, SpecCache* cache, int jobs_per_lease,
                std::function<void(const char* method, const Status&)> on_rpc = nullptr)
      : c_(c), name_(std::move(name)), cache_(cache), jobs_per_lease_(jobs_per_lease), on_rpc_(std::move(on_rpc)) {}

  StatusOr<std::optional<LeasedJob>> Lease() override;
  void Heartbeat(const LeasedJob& job) override;
  Status Report(const LeasedJob& job, const std::vector<PointRecord>& records, std::optional<LeasedJob>* next) override;
  Status Release(const LeasedJob& job) override;

 private:
  // A lease as a job; a lease whose spec cannot be had or parsed is released and refused.
  StatusOr<std::optional<LeasedJob>> ToJob(std::optional<CoordinatorClient::Lease> lease);
  void Count(const char* method, const Status& st) {
    if (on_rpc_) on_rpc_(method, st);
  }

  CoordinatorClient* c_;
  std::string name_;
  SpecCache* cache_;
  int jobs_per_lease_;
  std::function<void(const char*, const Status&)> on_rpc_;
};

}  // namespace bistable

#endif  // BISTABLE_WORKER_GRPC_JOB_SOURCE_H_
