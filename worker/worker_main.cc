// bistable-worker: pulls jobs from a coordinator and computes them with the same pull loop and the
// same evaluation as the embedded `bistable run` (worker/pull_loop.h, engine/evaluate.h), one loop per
// thread; while a job computes, a heartbeat extends its lease; RPC failures back off exponentially
// (0.1 s → 5 s) and retry, so a restarted coordinator is picked up again. SIGTERM/SIGINT (dynamics/cancel.h): the jobs in hand stop
// computing within a few milliseconds, their leases are released unreported (the coordinator requeues
// them), and the worker exits; a second signal ends it at once.
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <iostream>
#include <map>
#include <mutex>
#include <thread>

#include <CLI/CLI.hpp>

#include "base/exit_codes.h"
#include "dynamics/cancel.h"
#include "proto/coordinator_client.h"
#include "worker/pull_loop.h"

namespace {

using bistable::CancelRequested;
using bistable::CoordinatorClient;

// Parsed specs by sweep id, shared by the pull loops of this process.
struct SpecCache {
  std::mutex mu;
  std::map<std::string, std::shared_ptr<const bistable::SweepSpec>> by_id;
  bistable::StatusOr<std::shared_ptr<const bistable::SweepSpec>> Get(const std::string& id, const std::string& toml) {
    std::lock_guard<std::mutex> lock(mu);
    auto it = by_id.find(id);
    if (it != by_id.end()) return it->second;
    auto spec = bistable::ParseSweepSpec(toml, "sweep " + id);
    if (!spec.ok()) return spec.status();
    auto p = std::make_shared<const bistable::SweepSpec>(std::move(spec).value());
    by_id[id] = p;
    return p;
  }
};

// Jobs from a coordinator over gRPC: the worker's side of worker/pull_loop.h.
class GrpcJobSource : public bistable::JobSource {
 public:
  GrpcJobSource(CoordinatorClient* c, std::string name, SpecCache* cache) : c_(c), name_(std::move(name)), cache_(cache) {}

  bistable::StatusOr<std::optional<bistable::LeasedJob>> Lease() override {
    auto lease = c_->LeaseJob(name_);
    if (!lease.ok()) return lease.status();
    return ToJob(std::move(*lease));
  }
  void Heartbeat(const bistable::LeasedJob& job) override { (void)c_->Heartbeat(job.lease_id); }
  bistable::Status Report(const bistable::LeasedJob& job, const std::vector<bistable::PointRecord>& records,
                          std::optional<bistable::LeasedJob>* next) override {
    std::optional<CoordinatorClient::Lease> following;
    BISTABLE_RETURN_IF_ERROR(c_->Report(job.lease_id, records, next ? name_ : "", next ? &following : nullptr));
    if (next && following) {
      auto j = ToJob(std::move(following));
      if (j.ok()) *next = std::move(*j);
    }
    return bistable::Status::Ok();
  }
  bistable::Status Release(const bistable::LeasedJob& job) override { return c_->Release(job.lease_id); }

 private:
  // A lease as a job; a spec this build cannot parse is released and refused.
  bistable::StatusOr<std::optional<bistable::LeasedJob>> ToJob(std::optional<CoordinatorClient::Lease> lease) {
    if (!lease) return std::optional<bistable::LeasedJob>();
    auto spec = cache_->Get(lease->sweep_id, lease->spec_toml);
    if (!spec.ok()) {
      (void)c_->Release(lease->lease_id);
      return bistable::Status::FailedPrecondition("cannot parse the spec of sweep " + lease->sweep_id + " (released): " +
                                                  spec.status().ToString());
    }
    return std::optional<bistable::LeasedJob>(bistable::LeasedJob{lease->lease_id, *spec, std::move(lease->items)});
  }

  CoordinatorClient* c_;
  std::string name_;
  SpecCache* cache_;
};

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"bistable-worker: computes sweep jobs pulled from a coordinator"};
  std::string coordinator = "127.0.0.1:50051", name, token_file, tls_ca;
  int threads = 0;
  app.add_option("--coordinator", coordinator, "coordinator address")->capture_default_str();
  app.add_option("--threads", threads, "pull loops / cores (0 = all)")->capture_default_str();
  app.add_option("--name", name, "worker name (default host:pid)");
  app.add_option("--token-file", token_file, "file holding this worker's bearer token (else $BISTABLE_TOKEN)");
  app.add_option("--tls-ca", tls_ca, "PEM CA certificate to verify a TLS coordinator");
  CLI11_PARSE(app, argc, argv);
  if (threads < 0 || threads > 1024) {
    std::cerr << "error: invalid argument (threads: threads = " << threads << " violates threads in [0, 1024])\n";
    return bistable::kExitError;
  }
  if (threads == 0) threads = static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
  if (name.empty()) {
    char host[256] = "host";
    ::gethostname(host, sizeof host - 1);
    name = std::string(host) + ":" + std::to_string(::getpid());
  }
  auto token = bistable::LoadToken(token_file);
  if (!token.ok()) {
    std::cerr << "error: " << token.status().ToString() << "\n";
    return bistable::kExitError;
  }
  auto client = CoordinatorClient::Connect({coordinator, tls_ca, *token});
  if (!client.ok()) {
    std::cerr << "error: " << client.status().ToString() << "\n";
    return bistable::kExitError;
  }
  CoordinatorClient& c = **client;
  bistable::InstallCancelSignalHandlers();
  double lease_seconds = 60;
  bistable::Backoff backoff;
  while (!CancelRequested()) {  // register (waits for the coordinator to come up)
    auto reg = c.Register(name, threads);
    if (reg.ok()) {
      lease_seconds = *reg;
      break;
    }
    if (reg.status().code() != bistable::Status::Code::kIoError) {
      std::cerr << "error: " << reg.status().ToString() << "\n";
      return bistable::kExitError;
    }
    backoff.Wait();
  }
  SpecCache cache;
  std::atomic<long> done{0};
  std::vector<std::thread> pool;
  for (int t = 0; t < threads; ++t)
    pool.emplace_back([&] {
      GrpcJobSource source(&c, name, &cache);
      bistable::PullLoopOptions opt;
      opt.name = "worker " + name;
      opt.heartbeat_seconds = lease_seconds / 3;
      done += bistable::RunPullLoop(source, opt).items;
    });
  for (auto& th : pool) th.join();
  std::cerr << "worker " << name << ": stopped after " << done.load() << " items\n";
  return 0;
}
