// bistable-coordinator: serves sweeps of one data directory to clients and workers over gRPC.
#include <malloc.h>

#include <csignal>
#include <iostream>
#include <thread>

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

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"bistable-coordinator: serves sweeps to clients and workers over gRPC"};
  std::string listen = "127.0.0.1:50051", data = "bistable-data", tls_cert, tls_key, tokens_file;
  double lease_seconds = 60, job_seconds = 2.0;
  std::string log_level = "info", log_format = "text", metrics_addr, health_addr, http_addr;
  app.add_option("--listen", listen,
                 "address to listen on (loopback unless TLS and tokens are configured); port 0 picks one")
      ->capture_default_str();
  app.add_option("--data", data, "data directory (index.sqlite, sweeps/)")->capture_default_str();
  app.add_option("--lease-seconds", lease_seconds, "lease period: jobs not reported or extended within it are requeued")
      ->capture_default_str();
  app.add_option("--tls-cert", tls_cert, "PEM certificate (chain) of this coordinator: serve over TLS");
  app.add_option("--tls-key", tls_key, "PEM private key of --tls-cert");
  app.add_option("--tokens", tokens_file,
                 "tokens file: '<role> <sha256-of-token> [name]' per line (see `bistable token`)");
  app.add_option("--job-seconds", job_seconds, "work per job on one core, seconds (jobs are blocks of points)")
      ->capture_default_str();
  app.add_option("--log-level", log_level, "debug (every lease and report), info, warn, error, off")
      ->capture_default_str();
  app.add_option("--log-format", log_format, "text or json (one object per line), on stderr")->capture_default_str();
  app.add_option("--metrics", metrics_addr,
                 "serve Prometheus metrics (/metrics) and /healthz over HTTP on HOST:PORT (e.g. 0.0.0.0:9090)");
  app.add_option(
      "--http", http_addr,
      "serve the dashboard (docs/dashboard.md) on HOST:PORT, with /metrics and /healthz; over TLS with "
      "--tls-cert/--tls-key, behind --tokens (viewer, client or admin tokens); loopback unless both are given");
  app.add_option(
      "--health", health_addr,
      "also serve grpc.health.v1 alone, plaintext, on HOST:PORT (Kubernetes gRPC probes); the main port serves it too");
  std::vector<std::string> allowed_hosts;
  app.add_option(
      "--http-allowed-host", allowed_hosts,
      "a host name (e.g. a Service name) under which --metrics and a tokenless --http answer; repeatable. Without it "
      "they answer only a Host that is an IP address or localhost (DNS rebinding)");
  CLI11_PARSE(app, argc, argv);
  // Two malloc arenas: gRPC serves calls on a pool of threads, and one arena per thread would keep
  // each thread's high-water mark of (possibly hostile, oversized) requests resident for good.
  ::mallopt(M_ARENA_MAX, 2);
  auto fail = [](const bistable::Status& st) {
    std::cerr << "error: " << st.ToString() << "\n";
    return bistable::kExitError;
  };
  {
    auto level = bistable::log::ParseLevel(log_level);
    if (!level.ok()) return fail(level.status());
    auto format = bistable::log::ParseFormat(log_format);
    if (!format.ok()) return fail(format.status());
    bistable::log::Configure(*level, *format);
    bistable::RouteGrpcLogsToTheLog();
  }
  if (tls_cert.empty() != tls_key.empty())
    return fail(bistable::Status::InvalidArgument("tls-cert", "--tls-cert and --tls-key go together"));
  for (const std::string& h : allowed_hosts)
    if (auto st = bistable::CheckAllowedHostName(h, "http-allowed-host"); !st.ok()) return fail(st);
  if (!bistable::IsLoopbackAddress(listen) && (tls_cert.empty() || tokens_file.empty()))
    return fail(bistable::Status::InvalidArgument(
        "listen",
        listen + " is not a loopback address: serving other hosts requires --tls-cert/--tls-key and --tokens"));
  if (!http_addr.empty() && !bistable::IsLoopbackAddress(http_addr) && (tls_cert.empty() || tokens_file.empty()))
    return fail(bistable::Status::InvalidArgument(
        "http", http_addr + " is not a loopback address: serving the dashboard to other hosts requires "
                            "--tls-cert/--tls-key and --tokens"));
  bistable::TokenStore tokens;
  if (!tokens_file.empty()) {
    auto t = bistable::TokenStore::Load(tokens_file);
    if (!t.ok()) return fail(t.status());
    if (!t->lax_mode().empty())
      bistable::log::Event(bistable::log::Level::kWarn, "tokens.mode",
                           {{"file", tokens_file}, {"mode", t->lax_mode()}, {"reason", t->lax_reason()}});
    tokens = std::move(*t);
  }
  std::shared_ptr<grpc::ServerCredentials> creds = grpc::InsecureServerCredentials();
  bistable::HttpServer::Options http_tls;  // the dashboard takes the same certificate and key
  if (!tls_cert.empty()) {
    auto cert = bistable::ReadTextFile(tls_cert, "tls-cert", bistable::limits::kMaxPemFileBytes);
    auto key = bistable::ReadTextFile(tls_key, "tls-key", bistable::limits::kMaxPemFileBytes);
    if (!cert.ok()) return fail(cert.status());
    if (!key.ok()) return fail(key.status());
    grpc::SslServerCredentialsOptions ssl;
    ssl.pem_key_cert_pairs.push_back({*key, *cert});
    creds = grpc::SslServerCredentials(ssl);
    http_tls = {*cert, *key};
  }
  if (!(lease_seconds > 0 &&
        lease_seconds <= bistable::limits::kMaxLeaseSeconds)) {  // NaN fails too; workers refuse more
    std::cerr << "error: invalid argument (lease-seconds: lease-seconds = " << lease_seconds
              << " violates lease-seconds in (0, " << static_cast<long>(bistable::limits::kMaxLeaseSeconds) << "])\n";
    return bistable::kExitError;
  }
  if (!(job_seconds > 0 && job_seconds <= 3600)) {  // NaN fails too
    std::cerr << "error: invalid argument (job-seconds: job-seconds = " << job_seconds
              << " violates job-seconds in (0, 3600])\n";
    return bistable::kExitError;
  }
  auto coord = bistable::SweepCoordinator::Open(data, {.lease_seconds = lease_seconds, .resume = true});
  if (!coord.ok()) {
    std::cerr << "error: " << coord.status().ToString() << "\n";
    return bistable::kExitError;
  }
  const bistable::TokenStore dashboard_tokens = tokens;
  // One cache of published maps for GetMap/ListMetrics and the dashboard (server/map_cache.h).
  auto maps = std::make_shared<bistable::MapCache>();
  bistable::CoordinatorService service(coord->get(), lease_seconds, job_seconds, std::move(tokens), maps);
  bistable::CoordinatorMetrics metrics(coord->get());
  service.SetMetrics(&metrics);
  // /metrics and /healthz; the metrics only for a Host that names this server (net/http_server.h: HostChecked).
  const std::map<std::string, bistable::HttpHandler> metric_routes = bistable::HostChecked(
      {{"/metrics", [&metrics](const bistable::HttpRequest&) { return bistable::PrometheusText(metrics.Sources()); }},
       {"/healthz",
        [](const bistable::HttpRequest&) {
          return bistable::HttpResponse{200, "text/plain; charset=utf-8", "ok\n", {}};
        }}},
      allowed_hosts);
  std::unique_ptr<bistable::HttpServer> http, dashboard;
  if (!metrics_addr.empty()) {
    auto h = bistable::HttpServer::Start(metrics_addr, metric_routes);
    if (!h.ok()) return fail(h.status());
    http = std::move(h).value();
  }
  // --http: a second listener of the same server class (TLS when the gRPC side has it): the dashboard,
  // and /metrics and /healthz so that one port can serve everything.
  if (!http_addr.empty()) {
    auto routes = bistable::DashboardRoutes(coord->get(), &dashboard_tokens, allowed_hosts, maps);
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
    auto h = bistable::HttpServer::Start(http_addr, std::move(routes), options);
    if (!h.ok()) return fail(h.status());
    dashboard = std::move(h).value();
  }
  bistable::HealthService health_service;
  grpc::ServerBuilder builder;
  int port = 0;
  builder.AddListeningPort(listen, creds, &port);
  builder.RegisterService(&service);
  builder.RegisterService(&health_service);
  bistable::ConfigureServerBuilder(builder);
  std::unique_ptr<grpc::Server> server = builder.BuildAndStart();
  if (!server || port == 0) {
    std::cerr << "error: i/o error (listen: cannot listen on " << listen << ")\n";
    return bistable::kExitError;
  }
  const std::string host = listen.substr(0, listen.rfind(':'));
  health_service.Set("", true);
  health_service.Set("bistable.v1.Coordinator", true);
  std::unique_ptr<grpc::Server> health;
  int health_port = 0;
  if (!health_addr.empty()) {
    auto h = bistable::StartHealthServer(health_addr, &health_service, &health_port);
    if (!h.ok()) return fail(h.status());
    health = std::move(h).value();
  }
  bistable::log::Event(
      bistable::log::Level::kInfo, "coordinator.started",
      {{"listen", host + ":" + std::to_string(port)},
       {"data", data},
       {"tls", !tls_cert.empty()},
       {"tokens", !tokens_file.empty()},
       {"lease_seconds", lease_seconds},
       {"metrics", http ? metrics_addr.substr(0, metrics_addr.rfind(':')) + ":" + std::to_string(http->port()) : ""},
       {"dashboard",
        dashboard ? http_addr.substr(0, http_addr.rfind(':')) + ":" + std::to_string(dashboard->port()) : ""},
       {"health", health ? health_addr.substr(0, health_addr.rfind(':')) + ":" + std::to_string(health_port) : ""}});
  std::cout << "listening on " << host << ":" << port << std::endl;
  if (dashboard)
    std::cout << "dashboard on " << (tls_cert.empty() ? "http://" : "https://")
              << http_addr.substr(0, http_addr.rfind(':')) << ":" << dashboard->port() << "/" << std::endl;
  if (http)
    std::cout << "metrics on " << metrics_addr.substr(0, metrics_addr.rfind(':')) << ":" << http->port() << std::endl;
  if (health)
    std::cout << "health on " << health_addr.substr(0, health_addr.rfind(':')) << ":" << health_port << std::endl;
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
