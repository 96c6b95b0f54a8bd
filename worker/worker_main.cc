// bistable-worker: pulls jobs from a coordinator and computes them with the same pull loop and the
// same evaluation as the embedded `bistable run` (worker/pull_loop.h, engine/evaluate.h), one loop per
// thread; while a job computes, a heartbeat extends its lease; RPC failures back off exponentially
// (0.1 s → 5 s) and retry, so a restarted coordinator is picked up again. SIGTERM/SIGINT (dynamics/cancel.h): the jobs
// in hand stop computing within a few milliseconds, their leases are released unreported (the coordinator requeues
// them), and the worker exits; a second signal ends it at once.
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <iostream>
#include <map>
#include <mutex>
#include <thread>
#include <vector>

#include <prometheus/counter.h>
#include <prometheus/gauge.h>
#include <prometheus/histogram.h>
#include <prometheus/registry.h>
#include <CLI/CLI.hpp>

#include "base/cpus.h"
#include "base/exit_codes.h"
#include "base/limits.h"
#include "base/log.h"
#include "dynamics/cancel.h"
#include "net/http_server.h"
#include "net/prometheus_text.h"
#include "proto/coordinator_client.h"
#include "proto/grpc_log.h"
#include "proto/health.h"
#include "worker/grpc_job_source.h"
#include "worker/pull_loop.h"

namespace {

using bistable::CancelRequested;
using bistable::CoordinatorClient;

// The worker's Prometheus metrics (--metrics ADDR).
struct WorkerMetrics {
  std::shared_ptr<prometheus::Registry> registry = std::make_shared<prometheus::Registry>();
  prometheus::Counter& items = prometheus::BuildCounter()
                                   .Name("bistable_worker_items_computed_total")
                                   .Help("Items computed and acknowledged by the coordinator")
                                   .Register(*registry)
                                   .Add({});
  prometheus::Family<prometheus::Counter>& rpcs = prometheus::BuildCounter()
                                                      .Name("bistable_worker_rpcs_total")
                                                      .Help("Calls to the coordinator by method and outcome")
                                                      .Register(*registry);
  prometheus::Histogram& job_seconds =
      prometheus::BuildHistogram()
          .Name("bistable_worker_job_seconds")
          .Help("Compute time of one job on one thread")
          .Register(*registry)
          .Add({}, prometheus::Histogram::BucketBoundaries{0.1, 0.25, 0.5, 1, 2, 4, 8, 16, 32, 64});
  prometheus::Counter& busy_seconds = prometheus::BuildCounter()
                                          .Name("bistable_worker_compute_seconds_total")
                                          .Help("Thread-seconds spent computing jobs")
                                          .Register(*registry)
                                          .Add({});
  prometheus::Gauge& threads = prometheus::BuildGauge()
                                   .Name("bistable_worker_threads")
                                   .Help("Pull loops (one per usable CPU unless --threads)")
                                   .Register(*registry)
                                   .Add({});
  void Rpc(const char* method, const bistable::Status& st) {
    rpcs.Add({{"method", method},
              {"outcome", st.ok()                                         ? "ok"
                          : st.code() == bistable::Status::Code::kIoError ? "unavailable"
                                                                          : "refused"}})
        .Increment();
  }
};

int Fail(const bistable::Status& st) {
  std::cerr << "error: " << st.ToString() << "\n";
  return bistable::kExitError;
}

// The command line of bistable-worker.
struct Flags {
  std::string coordinator = "127.0.0.1:50051", name, token_file, tls_ca;
  int threads = 0, jobs_per_lease = 1;
  std::string log_level = "info", log_format = "text", metrics_addr, health_addr;
  bool insecure_remote = false;
  std::vector<std::string> allowed_hosts;
};

void AddFlags(CLI::App& app, Flags* f) {
  app.add_option("--coordinator", f->coordinator, "coordinator address")->capture_default_str();
  app.add_option("--threads", f->threads,
                 "pull loops, one per core (0 = the CPUs this process may use: affinity and cgroup CPU quota)")
      ->capture_default_str();
  app.add_option("--name", f->name, "worker name (default host:pid)");
  app.add_option("--token-file", f->token_file, "file holding this worker's bearer token (else $BISTABLE_TOKEN)");
  app.add_option("--tls-ca", f->tls_ca, "PEM CA certificate to verify a TLS coordinator");
  app.add_flag("--insecure-remote", f->insecure_remote,
               "send the token in plaintext to an address that is not loopback (refused otherwise)");
  app.add_option("--jobs-per-lease", f->jobs_per_lease,
                 "merge up to this many queued jobs into one lease (at most 4096 items): fewer, larger round trips "
                 "for a worker far from the coordinator, or to lift a busy coordinator's ceiling (docs/scaling.md)")
      ->capture_default_str();
  app.add_option("--log-level", f->log_level, "debug, info, warn, error, off")->capture_default_str();
  app.add_option("--log-format", f->log_format, "text or json (one object per line), on stderr")->capture_default_str();
  app.add_option("--metrics", f->metrics_addr,
                 "serve Prometheus metrics (/metrics) and /healthz over HTTP on HOST:PORT");
  app.add_option("--health", f->health_addr, "serve grpc.health.v1 (plaintext) on HOST:PORT, for liveness probes");
  app.add_option(
      "--http-allowed-host", f->allowed_hosts,
      "a host name under which --metrics answers; repeatable. Without it, only a Host that is an IP address or "
      "localhost (DNS rebinding)");
}

// --metrics: /metrics and /healthz over HTTP, the metrics only for a Host that names this worker (DNS rebinding).
bistable::Status StartMetricsServer(const Flags& f, WorkerMetrics& metrics,
                                    std::unique_ptr<bistable::HttpServer>* http) {
  if (f.metrics_addr.empty()) return bistable::Status::Ok();
  auto h = bistable::HttpServer::Start(
      f.metrics_addr,
      bistable::HostChecked(
          {{"/metrics",
            [&metrics](const bistable::HttpRequest&) { return bistable::PrometheusText({metrics.registry}); }},
           {"/healthz",
            [](const bistable::HttpRequest&) {
              return bistable::HttpResponse{200, "text/plain; charset=utf-8", "ok\n"};
            }}},
          f.allowed_hosts));
  if (!h.ok()) return h.status();
  *http = std::move(h).value();
  return bistable::Status::Ok();
}

// Registers this worker (`name`, `threads` pull loops), waiting for the coordinator to come up (backing off while
// it is unavailable); *lease_seconds: the coordinator's lease period. Ok also when cancelled first; the
// coordinator's refusal otherwise.
bistable::Status RegisterWorker(CoordinatorClient& c, const Flags& f, const std::string& name, int threads,
                                WorkerMetrics& metrics, double* lease_seconds) {
  bistable::Backoff backoff;
  while (!CancelRequested()) {
    auto reg = c.Register(name, threads);
    if (reg.ok()) {
      *lease_seconds = *reg;
      metrics.Rpc("RegisterWorker", reg.status());
      bistable::log::Event(bistable::log::Level::kInfo, "worker.registered",
                           {{"worker", name}, {"coordinator", f.coordinator}, {"lease_seconds", *lease_seconds}});
      break;
    }
    metrics.Rpc("RegisterWorker", reg.status());
    if (reg.status().code() != bistable::Status::Code::kIoError) return reg.status();
    bistable::log::Event(bistable::log::Level::kWarn, "coordinator.unavailable",
                         {{"worker", name}, {"coordinator", f.coordinator}, {"reason", reg.status().ToString()}});
    backoff.Wait();
  }
  return bistable::Status::Ok();
}

// `threads` pull loops on the coordinator `c`, each with its own job source over the shared spec cache, until
// cancelled; the items computed.
long RunPullLoops(CoordinatorClient& c, const Flags& f, const std::string& name, int threads, double lease_seconds,
                  WorkerMetrics& metrics) {
  bistable::SpecCache cache;  // parsed specs by key, shared by the pull loops (worker/grpc_job_source.h)
  std::atomic<long> done{0};
  std::vector<std::thread> pool;
  for (int t = 0; t < threads; ++t)
    pool.emplace_back([&] {
      bistable::GrpcJobSource source(
          &c, name, &cache, f.jobs_per_lease,
          [&metrics](const char* method, const bistable::Status& st) { metrics.Rpc(method, st); });
      bistable::PullLoopOptions opt;
      opt.name = name;
      opt.heartbeat_seconds = lease_seconds / 3;
      opt.on_items = [&metrics](long n) { metrics.items.Increment(static_cast<double>(n)); };
      opt.on_computed = [&metrics](long, double seconds) {
        metrics.job_seconds.Observe(seconds);
        metrics.busy_seconds.Increment(seconds);
      };
      done += bistable::RunPullLoop(source, opt).items;
    });
  for (auto& th : pool) th.join();
  return done.load();
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"bistable-worker: computes sweep jobs pulled from a coordinator"};
  Flags f;
  AddFlags(app, &f);
  CLI11_PARSE(app, argc, argv);
  for (const std::string& h : f.allowed_hosts)
    if (auto st = bistable::CheckAllowedHostName(h, "http-allowed-host"); !st.ok()) return Fail(st);
  {
    auto level = bistable::log::ParseLevel(f.log_level);
    if (!level.ok()) return Fail(level.status());
    auto format = bistable::log::ParseFormat(f.log_format);
    if (!format.ok()) return Fail(format.status());
    bistable::log::Configure(*level, *format);
    bistable::RouteGrpcLogsToTheLog();
  }
  int threads = f.threads;
  if (threads < 0 || threads > 1024) {
    std::cerr << "error: invalid argument (threads: threads = " << threads << " violates threads in [0, 1024])\n";
    return bistable::kExitError;
  }
  if (threads == 0) threads = bistable::UsableCpus();
  if (f.jobs_per_lease < 1 || f.jobs_per_lease > static_cast<int>(bistable::limits::kMaxJobsPerLease))
    return Fail(bistable::Status::InvalidArgument(
        "jobs-per-lease", "jobs-per-lease = " + std::to_string(f.jobs_per_lease) + " violates jobs-per-lease in [1, " +
                              std::to_string(bistable::limits::kMaxJobsPerLease) + "]"));
  std::string name = f.name;
  if (name.empty()) {
    char host[256] = "host";
    ::gethostname(host, sizeof host - 1);
    name = std::string(host) + ":" + std::to_string(::getpid());
  }
  auto token = bistable::LoadToken(f.token_file);
  if (!token.ok()) return Fail(token.status());
  auto client = CoordinatorClient::Connect({f.coordinator, f.tls_ca, *token, f.insecure_remote});
  if (!client.ok()) return Fail(client.status());
  WorkerMetrics metrics;
  metrics.threads.Set(threads);
  std::unique_ptr<bistable::HttpServer> http;
  if (auto st = StartMetricsServer(f, metrics, &http); !st.ok()) return Fail(st);
  bistable::HealthService health_service;
  std::unique_ptr<grpc::Server> health;
  int health_port = 0;
  if (!f.health_addr.empty()) {
    auto h = bistable::StartHealthServer(f.health_addr, &health_service, &health_port);
    if (!h.ok()) return Fail(h.status());
    health = std::move(h).value();
    health_service.Set("", true);
    health_service.Set("bistable.v1.Worker", true);
  }
  bistable::log::Event(bistable::log::Level::kInfo, "worker.started",
                       {{"worker", name},
                        {"coordinator", f.coordinator},
                        {"threads", threads},
                        {"tls", !f.tls_ca.empty()},
                        {"metrics", http ? std::to_string(http->port()) : ""},
                        {"health", health ? std::to_string(health_port) : ""}});
  CoordinatorClient& c = **client;
  bistable::InstallCancelSignalHandlers();
  double lease_seconds = 60;
  if (auto st = RegisterWorker(c, f, name, threads, metrics, &lease_seconds); !st.ok()) return Fail(st);
  const long done = RunPullLoops(c, f, name, threads, lease_seconds, metrics);
  if (health) {
    health_service.Shutdown();
    health->Shutdown(std::chrono::system_clock::now() + std::chrono::seconds(1));
  }
  bistable::log::Event(bistable::log::Level::kInfo, "worker.stopped", {{"worker", name}, {"items", done}});
  return 0;
}
