// bistable-coordinator: serves sweeps of one data directory to clients and workers over gRPC.
#include <malloc.h>

#include <csignal>
#include <iostream>
#include <thread>
#include <vector>

#include <grpcpp/grpcpp.h>
#include <CLI/CLI.hpp>

#include "base/exit_codes.h"
#include "base/file.h"
#include "base/limits.h"
#include "base/log.h"
#include "net/http_server.h"
#include "net/prometheus_text.h"
#include "proto/channel.h"
#include "proto/grpc_log.h"
#include "proto/health.h"
#include "server/coordinator_service.h"
#include "server/dashboard.h"
#include "server/map_cache.h"
#include "server/metrics.h"

namespace {

std::atomic<bool> g_stop{false};
extern "C" void OnSignal(int) { g_stop.store(true); }

// The command line of bistable-coordinator.
struct Flags {
  std::string listen = "127.0.0.1:50051", data = "bistable-data", tls_cert, tls_key, tokens_file;
  double lease_seconds = 60, job_seconds = 2.0;
  std::string log_level = "info", log_format = "text", metrics_addr, health_addr, http_addr;
  std::vector<std::string> allowed_hosts;
};

void AddFlags(CLI::App& app, Flags* f) {
  app.add_option("--listen", f->listen,
                 "address to listen on (loopback unless TLS and tokens are configured); port 0 picks one")
      ->capture_default_str();
  app.add_option("--data", f->data, "data directory (index.sqlite, sweeps/)")->capture_default_str();
  app.add_option("--lease-seconds", f->lease_seconds,
                 "lease period: jobs not reported or extended within it are requeued")
      ->capture_default_str();
  app.add_option("--tls-cert", f->tls_cert, "PEM certificate (chain) of this coordinator: serve over TLS");
  app.add_option("--tls-key", f->tls_key, "PEM private key of --tls-cert");
  app.add_option("--tokens", f->tokens_file,
                 "tokens file: '<role> <sha256-of-token> [name]' per line (see `bistable token`)");
  app.add_option("--job-seconds", f->job_seconds, "work per job on one core, seconds (jobs are blocks of points)")
      ->capture_default_str();
  app.add_option("--log-level", f->log_level, "debug (every lease and report), info, warn, error, off")
      ->capture_default_str();
  app.add_option("--log-format", f->log_format, "text or json (one object per line), on stderr")->capture_default_str();
  app.add_option("--metrics", f->metrics_addr,
                 "serve Prometheus metrics (/metrics) and /healthz over HTTP on HOST:PORT (e.g. 0.0.0.0:9090)");
  app.add_option(
      "--http", f->http_addr,
      "serve the dashboard (docs/dashboard.md) on HOST:PORT, with /metrics and /healthz; over TLS with "
      "--tls-cert/--tls-key, behind --tokens (viewer, client or admin tokens); loopback unless both are given");
  app.add_option(
      "--health", f->health_addr,
      "also serve grpc.health.v1 alone, plaintext, on HOST:PORT (Kubernetes gRPC probes); the main port serves it too");
  app.add_option(
      "--http-allowed-host", f->allowed_hosts,
      "a host name (e.g. a Service name) under which --metrics and a tokenless --http answer; repeatable. Without it "
      "they answer only a Host that is an IP address or localhost (DNS rebinding)");
}

int Fail(const bistable::Status& st) {
  std::cerr << "error: " << st.ToString() << "\n";
  return bistable::kExitError;
}

// The addresses: TLS certificate and key together, the allowed host names valid, and a listener off loopback only
// with TLS and tokens.
bistable::Status CheckAddresses(const Flags& f) {
  if (f.tls_cert.empty() != f.tls_key.empty())
    return bistable::Status::InvalidArgument("tls-cert", "--tls-cert and --tls-key go together");
  for (const std::string& h : f.allowed_hosts)
    if (auto st = bistable::CheckAllowedHostName(h, "http-allowed-host"); !st.ok()) return st;
  if (!bistable::IsLoopbackAddress(f.listen) && (f.tls_cert.empty() || f.tokens_file.empty()))
    return bistable::Status::InvalidArgument(
        "listen",
        f.listen + " is not a loopback address: serving other hosts requires --tls-cert/--tls-key and --tokens");
  if (!f.http_addr.empty() && !bistable::IsLoopbackAddress(f.http_addr) &&
      (f.tls_cert.empty() || f.tokens_file.empty()))
    return bistable::Status::InvalidArgument(
        "http", f.http_addr +
                    " is not a loopback address: serving the dashboard to other hosts requires "
                    "--tls-cert/--tls-key and --tokens");
  return bistable::Status::Ok();
}

// --tls-cert/--tls-key: the gRPC server's credentials (insecure without them) and the same pair for the dashboard.
bistable::Status LoadTls(const Flags& f, std::shared_ptr<grpc::ServerCredentials>* creds,
                         bistable::HttpServer::Options* http_tls) {
  *creds = grpc::InsecureServerCredentials();
  if (f.tls_cert.empty()) return bistable::Status::Ok();
  auto cert = bistable::ReadTextFile(f.tls_cert, "tls-cert", bistable::limits::kMaxPemFileBytes);
  auto key = bistable::ReadTextFile(f.tls_key, "tls-key", bistable::limits::kMaxPemFileBytes);
  if (!cert.ok()) return cert.status();
  if (!key.ok()) return key.status();
  grpc::SslServerCredentialsOptions ssl;
  ssl.pem_key_cert_pairs.push_back({*key, *cert});
  *creds = grpc::SslServerCredentials(ssl);
  *http_tls = {*cert, *key};
  return bistable::Status::Ok();
}

// --lease-seconds and --job-seconds within their bounds (NaN fails too); false after saying which is not.
bool DurationsValid(const Flags& f) {
  if (!(f.lease_seconds > 0 && f.lease_seconds <= bistable::limits::kMaxLeaseSeconds)) {  // workers refuse more
    std::cerr << "error: invalid argument (lease-seconds: lease-seconds = " << f.lease_seconds
              << " violates lease-seconds in (0, " << static_cast<long>(bistable::limits::kMaxLeaseSeconds) << "])\n";
    return false;
  }
  if (!(f.job_seconds > 0 && f.job_seconds <= 3600)) {
    std::cerr << "error: invalid argument (job-seconds: job-seconds = " << f.job_seconds
              << " violates job-seconds in (0, 3600])\n";
    return false;
  }
  return true;
}

// The HTTP listeners: --metrics (/metrics and /healthz, the metrics only for a Host that names this server:
// net/http_server.h HostChecked) and --http, a second listener of the same server class (TLS when the gRPC side
// has it): the dashboard, and /metrics and /healthz so that one port can serve everything.
bistable::Status StartHttpServers(const Flags& f, bistable::SweepCoordinator* coord,
                                  bistable::CoordinatorMetrics& metrics, const bistable::TokenStore& dashboard_tokens,
                                  const std::shared_ptr<bistable::MapCache>& maps,
                                  const bistable::HttpServer::Options& http_tls,
                                  std::unique_ptr<bistable::HttpServer>* http,
                                  std::unique_ptr<bistable::HttpServer>* dashboard) {
  const std::map<std::string, bistable::HttpHandler> metric_routes = bistable::HostChecked(
      {{"/metrics", [&metrics](const bistable::HttpRequest&) { return bistable::PrometheusText(metrics.Sources()); }},
       {"/healthz",
        [](const bistable::HttpRequest&) {
          return bistable::HttpResponse{200, "text/plain; charset=utf-8", "ok\n", {}};
        }}},
      f.allowed_hosts);
  if (!f.metrics_addr.empty()) {
    auto h = bistable::HttpServer::Start(f.metrics_addr, metric_routes);
    if (!h.ok()) return h.status();
    *http = std::move(h).value();
  }
  if (!f.http_addr.empty()) {
    auto routes = bistable::DashboardRoutes(coord, &dashboard_tokens, f.allowed_hosts, maps);
    routes.insert(metric_routes.begin(), metric_routes.end());
    if (dashboard_tokens.enabled())  // behind tokens, the metrics are data too (Prometheus sends a bearer token)
      routes["/metrics"] = [&metrics, &dashboard_tokens](const bistable::HttpRequest& req) {
        const std::string token = req.authorization.rfind("Bearer ", 0) == 0 ? req.authorization.substr(7) : "";
        if (!dashboard_tokens.CheckToken(token, bistable::Op::kStatus, nullptr).ok())
          return bistable::HttpResponse{
              401, "text/plain; charset=utf-8", "unauthenticated\n", {{"WWW-Authenticate", "Bearer"}}};
        return bistable::PrometheusText(metrics.Sources());
      };
    bistable::HttpServer::Options options = bistable::DashboardHttpOptions();
    options.tls_cert_pem = http_tls.tls_cert_pem, options.tls_key_pem = http_tls.tls_key_pem;
    auto h = bistable::HttpServer::Start(f.http_addr, std::move(routes), options);
    if (!h.ok()) return h.status();
    *dashboard = std::move(h).value();
  }
  return bistable::Status::Ok();
}

// "coordinator.started" in the log, and the addresses it serves on stdout.
void Announce(const Flags& f, const std::string& host, int port, const bistable::HttpServer* http,
              const bistable::HttpServer* dashboard, bool health, int health_port) {
  bistable::log::Event(
      bistable::log::Level::kInfo, "coordinator.started",
      {{"listen", host + ":" + std::to_string(port)},
       {"data", f.data},
       {"tls", !f.tls_cert.empty()},
       {"tokens", !f.tokens_file.empty()},
       {"lease_seconds", f.lease_seconds},
       {"metrics",
        http ? f.metrics_addr.substr(0, f.metrics_addr.rfind(':')) + ":" + std::to_string(http->port()) : ""},
       {"dashboard",
        dashboard ? f.http_addr.substr(0, f.http_addr.rfind(':')) + ":" + std::to_string(dashboard->port()) : ""},
       {"health",
        health ? f.health_addr.substr(0, f.health_addr.rfind(':')) + ":" + std::to_string(health_port) : ""}});
  std::cout << "listening on " << host << ":" << port << std::endl;
  if (dashboard)
    std::cout << "dashboard on " << (f.tls_cert.empty() ? "http://" : "https://")
              << f.http_addr.substr(0, f.http_addr.rfind(':')) << ":" << dashboard->port() << "/" << std::endl;
  if (http)
    std::cout << "metrics on " << f.metrics_addr.substr(0, f.metrics_addr.rfind(':')) << ":" << http->port()
              << std::endl;
  if (health)
    std::cout << "health on " << f.health_addr.substr(0, f.health_addr.rfind(':')) << ":" << health_port << std::endl;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"bistable-coordinator: serves sweeps to clients and workers over gRPC"};
  Flags f;
  AddFlags(app, &f);
  CLI11_PARSE(app, argc, argv);
  // Two malloc arenas: gRPC serves calls on a pool of threads, and one arena per thread would keep
  // each thread's high-water mark of (possibly hostile, oversized) requests resident for good.
  ::mallopt(M_ARENA_MAX, 2);
  {
    auto level = bistable::log::ParseLevel(f.log_level);
    if (!level.ok()) return Fail(level.status());
    auto format = bistable::log::ParseFormat(f.log_format);
    if (!format.ok()) return Fail(format.status());
    bistable::log::Configure(*level, *format);
    bistable::RouteGrpcLogsToTheLog();
  }
  if (auto st = CheckAddresses(f); !st.ok()) return Fail(st);
  bistable::TokenStore tokens;
  if (!f.tokens_file.empty()) {
    auto t = bistable::TokenStore::Load(f.tokens_file);
    if (!t.ok()) return Fail(t.status());
    if (!t->lax_mode().empty())
      bistable::log::Event(bistable::log::Level::kWarn, "tokens.mode",
                           {{"file", f.tokens_file}, {"mode", t->lax_mode()}, {"reason", t->lax_reason()}});
    tokens = std::move(*t);
  }
  std::shared_ptr<grpc::ServerCredentials> creds;
  bistable::HttpServer::Options http_tls;  // the dashboard takes the same certificate and key
  if (auto st = LoadTls(f, &creds, &http_tls); !st.ok()) return Fail(st);
  if (!DurationsValid(f)) return bistable::kExitError;
  auto coord = bistable::SweepCoordinator::Open(f.data, {.lease_seconds = f.lease_seconds, .resume = true});
  if (!coord.ok()) return Fail(coord.status());
  const bistable::TokenStore dashboard_tokens = tokens;
  // One cache of published maps for GetMap/ListMetrics and the dashboard (server/map_cache.h).
  auto maps = std::make_shared<bistable::MapCache>();
  bistable::CoordinatorService service(coord->get(), f.lease_seconds, f.job_seconds, std::move(tokens), maps);
  bistable::CoordinatorMetrics metrics(coord->get());
  service.SetMetrics(&metrics);
  std::unique_ptr<bistable::HttpServer> http, dashboard;
  if (auto st = StartHttpServers(f, coord->get(), metrics, dashboard_tokens, maps, http_tls, &http, &dashboard);
      !st.ok())
    return Fail(st);
  bistable::HealthService health_service;
  grpc::ServerBuilder builder;
  int port = 0;
  builder.AddListeningPort(f.listen, creds, &port);
  builder.RegisterService(&service);
  builder.RegisterService(&health_service);
  bistable::ConfigureServerBuilder(builder);
  std::unique_ptr<grpc::Server> server = builder.BuildAndStart();
  if (!server || port == 0) {
    std::cerr << "error: i/o error (listen: cannot listen on " << f.listen << ")\n";
    return bistable::kExitError;
  }
  const std::string host = f.listen.substr(0, f.listen.rfind(':'));
  health_service.Set("", true);
  health_service.Set("bistable.v1.Coordinator", true);
  std::unique_ptr<grpc::Server> health;
  int health_port = 0;
  if (!f.health_addr.empty()) {
    auto h = bistable::StartHealthServer(f.health_addr, &health_service, &health_port);
    if (!h.ok()) return Fail(h.status());
    health = std::move(h).value();
  }
  Announce(f, host, port, http.get(), dashboard.get(), health != nullptr, health_port);
  std::signal(SIGINT, OnSignal);
  std::signal(SIGTERM, OnSignal);
  // Housekeeping: every 5 s give freed heap back to the system (rejected oversized messages and
  // cancelled plans leave large free chunks that glibc would otherwise keep). Measured with the hostile
  // wire suite: without this and the arena limit, 1 of 3 runs ended 36 % above its memory baseline;
  // with them 3 of 3 stayed within 14 %.
  for (int tick = 1; !g_stop.load(); ++tick) {
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
    if (tick % 50 == 0) ::malloc_trim(0);
  }
  bistable::log::Event(bistable::log::Level::kInfo, "coordinator.stopping", {});
  health_service.Shutdown();
  service.Shutdown();
  if (health) health->Shutdown(std::chrono::system_clock::now() + std::chrono::seconds(1));
  server->Shutdown(std::chrono::system_clock::now() + std::chrono::seconds(2));
  return 0;
}
