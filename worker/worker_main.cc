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
#include <grpcpp/grpcpp.h>

#include "base/exit_codes.h"
#include "bistable.grpc.pb.h"
#include "dynamics/cancel.h"
#include "proto/channel.h"
#include "proto/status_convert.h"
#include "worker/pull_loop.h"

namespace {

using bistable::v1::Coordinator;
using bistable::CancelRequested;

bistable::ConnectOptions g_conn;
std::unique_ptr<grpc::ClientContext> Context(double seconds) { return bistable::CallContext(g_conn, seconds); }

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

// Jobs from a coordinator over gRPC (the wire side of worker/pull_loop.h).
class GrpcJobSource : public bistable::JobSource {
 public:
  GrpcJobSource(Coordinator::Stub* stub, std::string name, SpecCache* cache) : stub_(stub), name_(std::move(name)), cache_(cache) {}

  bistable::StatusOr<std::optional<bistable::LeasedJob>> Lease() override {
    bistable::v1::LeaseRequest req;
    req.set_worker(name_);
    bistable::v1::LeaseReply rep;
    const grpc::Status s = stub_->Lease(Context(10).get(), req, &rep);
    if (!s.ok()) return bistable::FromGrpcStatus(s);
    return FromReply(rep);
  }
  void Heartbeat(const bistable::LeasedJob& job) override {
    bistable::v1::HeartbeatRequest hb;
    hb.set_lease_id(job.lease_id);
    bistable::v1::HeartbeatReply hr;
    stub_->Heartbeat(Context(5).get(), hb, &hr);
  }
  bistable::Status Report(const bistable::LeasedJob& job, const std::vector<bistable::PointRecord>& records,
                          std::optional<bistable::LeasedJob>* next) override {
    bistable::v1::ReportRequest req;
    req.set_lease_id(job.lease_id);
    req.set_record_width(records.empty() ? 0 : static_cast<unsigned>(records[0].v.size()));
    req.set_catalog_hash(bistable::CatalogHash());
    if (next) req.set_lease_next_for(name_);
    for (const auto& r : records) req.mutable_values()->Add(r.v.begin(), r.v.end());
    bistable::v1::ReportReply rep;
    const grpc::Status s = stub_->Report(Context(30).get(), req, &rep);
    if (!s.ok()) return bistable::FromGrpcStatus(s);
    if (next && rep.has_next()) {
      auto job_next = FromReply(rep.next());
      if (job_next.ok()) *next = std::move(*job_next);
    }
    return bistable::Status::Ok();
  }
  bistable::Status Release(const bistable::LeasedJob& job) override { return ReleaseId(job.lease_id); }

 private:
  bistable::Status ReleaseId(const std::string& lease_id) {
    bistable::v1::ReleaseRequest req;
    req.set_lease_id(lease_id);
    bistable::v1::ReleaseReply rep;
    return bistable::FromGrpcStatus(stub_->Release(Context(5).get(), req, &rep));
  }
  // A lease reply as a job; a spec this build cannot parse is released and refused.
  bistable::StatusOr<std::optional<bistable::LeasedJob>> FromReply(const bistable::v1::LeaseReply& rep) {
    if (!rep.has_job()) return std::optional<bistable::LeasedJob>();
    auto spec = cache_->Get(rep.sweep_id(), rep.spec_toml());
    if (!spec.ok()) {
      ReleaseId(rep.lease_id());
      return bistable::Status::FailedPrecondition("cannot parse the spec of sweep " + rep.sweep_id() + " (released): " +
                                                  spec.status().ToString());
    }
    if (rep.points_size() != rep.ics_size()) {
      ReleaseId(rep.lease_id());
      return bistable::Status::FailedPrecondition("malformed lease of sweep " + rep.sweep_id() + " (released)");
    }
    bistable::LeasedJob job{rep.lease_id(), *spec, {}};
    job.items.resize(rep.points_size());
    for (int i = 0; i < rep.points_size(); ++i) job.items[i] = {rep.points(i), rep.ics(i)};
    return std::optional<bistable::LeasedJob>(std::move(job));
  }

  Coordinator::Stub* stub_;
  std::string name_;
  SpecCache* cache_;
};

bool Retryable(const grpc::Status& s) {
  return s.error_code() == grpc::StatusCode::UNAVAILABLE || s.error_code() == grpc::StatusCode::DEADLINE_EXCEEDED;
}

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
  g_conn = {coordinator, tls_ca, *token};
  auto channel = bistable::MakeChannel(g_conn);
  if (!channel.ok()) {
    std::cerr << "error: " << channel.status().ToString() << "\n";
    return bistable::kExitError;
  }
  auto stub = Coordinator::NewStub(*channel);
  bistable::InstallCancelSignalHandlers();
  double lease_seconds = 60;
  bistable::Backoff backoff;
  while (!CancelRequested()) {  // register (waits for the coordinator to come up)
    bistable::v1::RegisterRequest req;
    req.set_name(name);
    req.set_threads(threads);
    bistable::v1::RegisterReply rep;
    const grpc::Status s = stub->RegisterWorker(Context(5).get(), req, &rep);
    if (s.ok()) {
      lease_seconds = rep.lease_seconds();
      break;
    }
    if (!Retryable(s)) {
      std::cerr << "error: " << bistable::FromGrpcStatus(s).ToString() << "\n";
      return bistable::kExitError;
    }
    backoff.Wait();
  }
  SpecCache cache;
  std::atomic<long> done{0};
  std::vector<std::thread> pool;
  for (int t = 0; t < threads; ++t)
    pool.emplace_back([&] {
      GrpcJobSource source(stub.get(), name, &cache);
      bistable::PullLoopOptions opt;
      opt.name = "worker " + name;
      opt.heartbeat_seconds = lease_seconds / 3;
      done += bistable::RunPullLoop(source, opt).items;
    });
  for (auto& th : pool) th.join();
  std::cerr << "worker " << name << ": stopped after " << done.load() << " items\n";
  return 0;
}
