// bistable-worker: pulls jobs from a coordinator, computes them with the same code as the embedded
// `bistable run` (ComputeItems), and reports. One pull loop per thread; while a job computes, a
// heartbeat extends its lease; RPC failures back off exponentially (0.1 s → 5 s) and retry, so a
// restarted coordinator is picked up again. SIGTERM/SIGINT (dynamics/cancel.h): the jobs in hand stop
// computing within a few milliseconds, their leases are released unreported (the coordinator requeues
// them), and the worker exits; a second signal ends it at once.
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <future>
#include <iostream>
#include <map>
#include <mutex>
#include <thread>

#include <CLI/CLI.hpp>
#include <grpcpp/grpcpp.h>

#include "bistable.grpc.pb.h"
#include "dynamics/cancel.h"
#include "proto/channel.h"
#include "proto/status_convert.h"
#include "worker/block_worker.h"

namespace {

using bistable::v1::Coordinator;
using bistable::CancelRequested;

// Sleeps up to `seconds`, waking early when cancellation is requested.
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

class Backoff {
 public:
  void Wait() {
    SleepUnlessCancelled(delay_);
    delay_ = std::min(5.0, delay_ * 2);
  }
  void Reset() { delay_ = 0.1; }

 private:
  double delay_ = 0.1;
};

bool Retryable(const grpc::Status& s) {
  return s.error_code() == grpc::StatusCode::UNAVAILABLE || s.error_code() == grpc::StatusCode::DEADLINE_EXCEEDED;
}

bistable::ConnectOptions g_conn;
std::unique_ptr<grpc::ClientContext> Context(double seconds) { return bistable::CallContext(g_conn, seconds); }

struct SpecCache {
  std::mutex mu;
  std::map<std::string, std::shared_ptr<bistable::SweepSpec>> by_id;
  std::shared_ptr<bistable::SweepSpec> Get(const std::string& id, const std::string& toml) {
    std::lock_guard<std::mutex> lock(mu);
    auto it = by_id.find(id);
    if (it != by_id.end()) return it->second;
    auto spec = bistable::ParseSweepSpec(toml, "sweep " + id);
    if (!spec.ok()) return nullptr;
    return by_id[id] = std::make_shared<bistable::SweepSpec>(std::move(*spec));
  }
};

void PullLoop(Coordinator::Stub* stub, const std::string& name, double lease_seconds, SpecCache* cache, std::atomic<long>* done) {
  Backoff backoff;
  bistable::v1::LeaseReply lease;  // the next job, from a Lease call or from the previous report's reply
  auto release = [&](const std::string& lease_id) {
    bistable::v1::ReleaseRequest rr;
    rr.set_lease_id(lease_id);
    bistable::v1::ReleaseReply rel;
    return stub->Release(Context(5).get(), rr, &rel);
  };
  while (!CancelRequested()) {
    if (!lease.has_job()) {
      bistable::v1::LeaseRequest lreq;
      lreq.set_worker(name);
      const grpc::Status ls = stub->Lease(Context(10).get(), lreq, &lease);
      if (!ls.ok()) {
        if (!Retryable(ls)) std::cerr << "worker " << name << ": lease refused: " << ls.error_message() << "\n";
        lease.Clear();
        backoff.Wait();
        continue;
      }
    }
    backoff.Reset();
    if (!lease.has_job()) {
      SleepUnlessCancelled(0.05);
      continue;
    }
    const bistable::v1::LeaseReply job = std::exchange(lease, {});
    auto spec = cache->Get(job.sweep_id(), job.spec_toml());
    if (!spec) {
      std::cerr << "worker " << name << ": cannot parse the spec of sweep " << job.sweep_id() << "; releasing\n";
      release(job.lease_id());
      continue;
    }
    std::vector<bistable::WorkItem> items(job.points_size());
    for (int i = 0; i < job.points_size(); ++i) items[i] = {job.points(i), job.ics(i)};
    auto work = std::async(std::launch::async, [&] { return bistable::ComputeItemsUnlessCancelled(*spec, items); });
    // Heartbeat a third of the lease period while computing (the computation itself stops within a
    // few milliseconds of a cancellation, so waiting for it is short then).
    while (work.wait_for(std::chrono::duration<double>(lease_seconds / 3)) != std::future_status::ready) {
      bistable::v1::HeartbeatRequest hb;
      hb.set_lease_id(job.lease_id());
      bistable::v1::HeartbeatReply hr;
      stub->Heartbeat(Context(5).get(), hb, &hr);
    }
    const std::optional<std::vector<bistable::PointRecord>> computed = work.get();
    if (!computed) {  // cancelled mid-job: report nothing of it, give the job back now
      const grpc::Status rs = release(job.lease_id());
      std::cerr << "worker " << name << ": stopped computing " << job.lease_id() << " ("
                << (rs.ok() ? "released" : "release failed: " + rs.error_message() + "; it requeues when the lease expires")
                << ")\n";
      break;
    }
    const std::vector<bistable::PointRecord>& records = *computed;
    bistable::v1::ReportRequest rep;
    rep.set_lease_id(job.lease_id());
    rep.set_record_width(records.empty() ? 0 : static_cast<unsigned>(records[0].v.size()));
    if (!CancelRequested()) rep.set_lease_next_for(name);  // on SIGTERM, take nothing new
    for (const auto& r : records) rep.mutable_values()->Add(r.v.begin(), r.v.end());
    for (int attempt = 0;; ++attempt) {  // reports are idempotent: retry until answered
      bistable::v1::ReportReply rr;
      const grpc::Status s = stub->Report(Context(30).get(), rep, &rr);
      if (s.ok()) {
        *done += static_cast<long>(records.size());
        if (rr.has_next()) lease = rr.next();
        break;
      }
      if (!Retryable(s) || attempt > 50 || CancelRequested()) {
        std::cerr << "worker " << name << ": report of " << job.lease_id() << (Retryable(s) ? " not answered: " : " refused: ")
                  << s.error_message() << (Retryable(s) ? " (its job requeues when the lease expires)" : "") << "\n";
        break;
      }
      backoff.Wait();
    }
    backoff.Reset();
  }
  if (lease.has_job()) release(lease.lease_id());  // stopping with a job leased by the last report: give it back
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
    return 2;
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
    return 2;
  }
  g_conn = {coordinator, tls_ca, *token};
  auto channel = bistable::MakeChannel(g_conn);
  if (!channel.ok()) {
    std::cerr << "error: " << channel.status().ToString() << "\n";
    return 2;
  }
  auto stub = Coordinator::NewStub(*channel);
  bistable::InstallCancelSignalHandlers();
  double lease_seconds = 60;
  Backoff backoff;
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
      return 2;
    }
    backoff.Wait();
  }
  SpecCache cache;
  std::atomic<long> done{0};
  std::vector<std::thread> pool;
  for (int t = 0; t < threads; ++t)
    pool.emplace_back(PullLoop, stub.get(), name, lease_seconds, &cache, &done);
  for (auto& th : pool) th.join();
  std::cerr << "worker " << name << ": stopped after " << done.load() << " items\n";
  return 0;
}
