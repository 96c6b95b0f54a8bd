// Seeing into the service (issue 12): structured logs, Prometheus metrics over the project's HTTP
// server, grpc.health.v1, the CPUs a process may use, and `bistable sweeps/fetch --coordinator`.
// Real processes on loopback, scraped by a real HTTP client (Boost.Beast), checked against the sweep.
#include <sched.h>
#include <sys/socket.h>

#include <atomic>
#include <ctime>
#include <functional>
#include <future>
#include <mutex>

#include <boost/asio/connect.hpp>
#include <boost/asio/ip/tcp.hpp>
#include <boost/beast/core.hpp>
#include <boost/beast/http.hpp>
#include <nlohmann/json.hpp>

#include "base/cpus.h"
#include "base/log.h"
#include "base/sha256.h"
#include "net/http_server.h"
#include "proto/health.h"
#include "tests/http_client.h"
#include "tests/iso_time_parse.h"
#include "tests/process_util.h"

namespace {

namespace fs = std::filesystem;
namespace beast = boost::beast;
namespace http = beast::http;
namespace asio = boost::asio;
using asio::ip::tcp;
using bistable_test::ExecResult;
using bistable_test::HttpReply;
using bistable_test::HttpRequest;
using bistable_test::ParseMetrics;
using bistable_test::RunArgv;

double SumOf(const std::map<std::string, double>& m, const std::string& prefix) {
  double s = 0;
  for (const auto& [k, v] : m)
    if (k.rfind(prefix, 0) == 0) s += v;
  return s;
}

std::string Dir(const std::string& name) { return bistable_test::FreshDir("bistable_obs", name); }

// The "<what> on HOST:PORT" line a process printed; its port (0 while not yet printed).
int PortFrom(const std::string& log, const std::string& what) {
  std::istringstream in(bistable_test::ReadText(log));
  for (std::string line; std::getline(in, line);)
    if (line.rfind(what + " on ", 0) == 0) return std::stoi(line.substr(line.rfind(':') + 1));
  return 0;
}

int AwaitPort(const std::string& log, const std::string& what) {
  for (int i = 0; i < 400; ++i) {
    if (int p = PortFrom(log, what)) return p;
    std::this_thread::sleep_for(std::chrono::milliseconds(25));
  }
  return 0;
}

// A field of a JSON log line of `stderr_log` whose "event" is `event` ({} when there is none).
std::vector<nlohmann::json> Events(const std::string& stderr_log, const std::string& event) {
  std::vector<nlohmann::json> out;
  std::istringstream in(bistable_test::ReadText(stderr_log));
  for (std::string line; std::getline(in, line);) {
    auto j = nlohmann::json::parse(line, nullptr, false);
    if (!j.is_discarded() && j.value("event", "") == event) out.push_back(j);
  }
  return out;
}

std::pair<std::string, std::string> MintToken(const std::string& role, const std::string& name) {
  const ExecResult r = RunArgv({BISTABLE_CLI, "token", "--role", role, "--name", name});
  const size_t a = r.out.find("token: ") + 7, b = r.out.find('\n', a);
  const size_t c = r.out.find("tokens-file line: ") + 18, d = r.out.find('\n', c);
  return {r.out.substr(a, b - a), r.out.substr(c, d - c)};
}

constexpr const char* kSpec = R"(
name = "observability test"
model = "coupled"
[axes]
alpha = { linspace = [0.2, 2.0, 20] }
omega = { linspace = [0.2, 2.0, 20] }
[integration]
t_end = 200.0
t_keep = 100.0
)";

struct Service {
  std::string dir, addr, client_token, worker_token, admin_token;
  pid_t coord = -1;
  std::vector<pid_t> workers;
  int metrics = 0, health = 0;
  std::vector<int> worker_metrics, worker_health;

  // A coordinator with tokens, JSON logs, metrics and a health port; two workers with metrics and health.
  explicit Service(const std::string& name) : dir(Dir(name)) {
    auto [ct, cl] = MintToken("client", "alice");
    auto [wt, wl] = MintToken("worker", "pool");
    auto [at, al] = MintToken("admin", "ops");
    client_token = ct, worker_token = wt, admin_token = at;
    std::ofstream(dir + "/tokens") << cl << "\n" << wl << "\n" << al << "\n";
    std::ofstream(dir + "/client.token") << client_token << "\n";
    std::ofstream(dir + "/worker.token") << worker_token << "\n";
    coord = bistable_test::SpawnLogged(
        {BISTABLE_COORDINATOR, "--listen", "127.0.0.1:0", "--data", dir + "/data", "--tokens", dir + "/tokens",
         "--job-seconds", "0.02", "--log-format", "json", "--metrics", "127.0.0.1:0", "--health", "127.0.0.1:0"},
        dir + "/coord.log");
    const int port = AwaitPort(dir + "/coord.log", "listening");
    addr = "127.0.0.1:" + std::to_string(port);
    metrics = AwaitPort(dir + "/coord.log", "metrics");
    health = AwaitPort(dir + "/coord.log", "health");
    for (int i = 0; i < 2; ++i) {
      const std::string log = dir + "/w" + std::to_string(i) + ".log";
      workers.push_back(bistable_test::SpawnLogged(
          {BISTABLE_WORKER, "--coordinator", addr, "--threads", "1", "--name", "w" + std::to_string(i), "--token-file",
           dir + "/worker.token", "--log-format", "json", "--metrics", "127.0.0.1:0", "--health", "127.0.0.1:0"},
          log));
    }
    for (int i = 0; i < 2; ++i) {
      // The worker prints no "on" lines; its ports are in its worker.started event.
      for (int t = 0; t < 400; ++t) {
        auto ev = Events(dir + "/w" + std::to_string(i) + ".log.err", "worker.started");
        if (!ev.empty()) {
          worker_metrics.push_back(std::stoi(ev[0]["metrics"].get<std::string>()));
          worker_health.push_back(std::stoi(ev[0]["health"].get<std::string>()));
          break;
        }
        std::this_thread::sleep_for(std::chrono::milliseconds(25));
      }
    }
  }
  ~Service() {
    for (pid_t w : workers) ::kill(w, SIGTERM), bistable_test::WaitExitFor(w, 10);
    if (coord > 0) ::kill(coord, SIGTERM), bistable_test::WaitExitFor(coord, 10);
    if (!::testing::Test::HasFailure()) fs::remove_all(dir);
  }
  std::vector<std::string> Remote() const { return {"--coordinator", addr, "--token-file", dir + "/client.token"}; }
  ExecResult Cli(std::vector<std::string> args) const {
    args.insert(args.begin(), BISTABLE_CLI);
    auto r = Remote();
    args.insert(args.end(), r.begin(), r.end());
    return RunArgv(args, dir);
  }
  // Submits kSpec and waits for it; the submit reply.
  nlohmann::json RunSweep() const {
    std::ofstream(dir + "/spec.toml") << kSpec;
    submitted_at = static_cast<double>(std::time(nullptr));
    const ExecResult sub = Cli({"submit", dir + "/spec.toml", "--json"});
    EXPECT_EQ(sub.exit_code, 0) << sub.err;
    const nlohmann::json j = nlohmann::json::parse(sub.out);
    const ExecResult w = Cli({"status", j["id"], "--watch", "--json"});
    EXPECT_EQ(w.exit_code, 0) << w.err;
    done_at = static_cast<double>(std::time(nullptr));
    return j;
  }
  mutable double submitted_at = 0, done_at = 0;  // unix seconds, whole (the CLI's times have whole seconds)
};

TEST(Observability, MetricsLogsAndHealthAgreeWithTheSweep) {
  Service s("metrics");
  ASSERT_GT(s.metrics, 0);
  ASSERT_GT(s.health, 0);
  ASSERT_EQ(s.worker_metrics.size(), 2u);
  const nlohmann::json sub = s.RunSweep();
  const long items = sub["items_total"], jobs = sub["jobs"];
  ASSERT_EQ(items, 400);

  // A caller with a token the coordinator does not know: refused, counted, logged without the token.
  const std::string forged(64, 'f');
  std::ofstream(s.dir + "/forged.token") << forged << "\n";
  const ExecResult bad = RunArgv(
      {BISTABLE_CLI, "submit", s.dir + "/spec.toml", "--coordinator", s.addr, "--token-file", s.dir + "/forged.token"});
  EXPECT_NE(bad.exit_code, 0);

  const HttpReply scrape = HttpRequest(s.metrics, "/metrics");
  ASSERT_EQ(scrape.status, 200) << scrape.body;
  EXPECT_NE(scrape.content_type.find("text/plain; version=0.0.4"), std::string::npos);
  const auto m = ParseMetrics(scrape.body);
  EXPECT_EQ(m.at("bistable_items_done_total"), items);
  EXPECT_EQ(m.at("bistable_reports_total{outcome=\"stored\"}"), jobs);
  EXPECT_GE(m.at("bistable_leases_granted_total"), jobs);
  EXPECT_EQ(m.at("bistable_leases_outstanding"), 0);
  EXPECT_EQ(m.at("bistable_jobs_queued"), 0);
  EXPECT_EQ(m.at("bistable_items_pending"), 0);
  EXPECT_EQ(m.at("bistable_workers"), 2);
  EXPECT_EQ(m.at("bistable_sweeps{state=\"done\"}"), 1);
  EXPECT_EQ(SumOf(m, "bistable_worker_items_total{"), items);
  EXPECT_EQ(m.at("bistable_report_seconds_count"),
            m.at("bistable_reports_total{outcome=\"stored\"}") + m.at("bistable_reports_total{outcome=\"duplicate\"}"));
  EXPECT_EQ(m.at("bistable_calls_refused_total{code=\"UNAUTHENTICATED\",method=\"Submit\"}"), 1);
  // Each worker's own counters: together they computed every item once.
  double computed = 0, reports = 0;
  for (int port : s.worker_metrics) {
    const auto wm = ParseMetrics(HttpRequest(port, "/metrics").body);
    computed += wm.at("bistable_worker_items_computed_total");
    reports += wm.at("bistable_worker_rpcs_total{method=\"Report\",outcome=\"ok\"}");
    EXPECT_EQ(wm.at("bistable_worker_threads"), 1);
  }
  EXPECT_EQ(computed, items);
  EXPECT_EQ(reports, jobs);
  EXPECT_EQ(HttpRequest(s.metrics, "/healthz").body, "ok\n");

  // grpc.health.v1 on the TLS-less health port and on the main port (with or without a token).
  for (const std::string& a : {s.addr, "127.0.0.1:" + std::to_string(s.health)}) {
    EXPECT_EQ(*bistable::CheckHealth({a, "", ""}, "", 5), "SERVING") << a;
    EXPECT_EQ(*bistable::CheckHealth({a, "", ""}, "bistable.v1.Coordinator", 5), "SERVING") << a;
    EXPECT_EQ(*bistable::CheckHealth({a, "", ""}, "no.such.Service", 5), "SERVICE_UNKNOWN") << a;
  }
  for (int p : s.worker_health)
    EXPECT_EQ(*bistable::CheckHealth({"127.0.0.1:" + std::to_string(p), "", ""}, "bistable.v1.Worker", 5), "SERVING");
  const ExecResult h =
      RunArgv({BISTABLE_CLI, "health", "--coordinator", "127.0.0.1:" + std::to_string(s.health), "--json"});
  EXPECT_EQ(h.exit_code, 0) << h.err;
  EXPECT_EQ(nlohmann::json::parse(h.out)["status"], "SERVING");

  // Logs: every line one JSON object with ts, level and event; the sweep's story is there; no token.
  ::kill(s.coord, SIGTERM);
  EXPECT_EQ(bistable_test::WaitExitFor(s.coord, 10), 0);
  s.coord = -1;
  const std::string log = bistable_test::ReadText(s.dir + "/coord.log.err");
  std::istringstream in(log);
  int lines = 0;
  for (std::string line; std::getline(in, line); ++lines) {
    auto j = nlohmann::json::parse(line, nullptr, false);
    ASSERT_FALSE(j.is_discarded()) << "not JSON: " << line;
    EXPECT_TRUE(j.contains("ts") && j.contains("level") && j.contains("event")) << line;
  }
  EXPECT_GT(lines, 5);
  const std::string err = s.dir + "/coord.log.err";
  EXPECT_EQ(Events(err, "coordinator.started").size(), 1u);
  ASSERT_EQ(Events(err, "sweep.planned").size(), 1u);
  EXPECT_EQ(Events(err, "sweep.planned")[0]["items"], items);
  EXPECT_EQ(Events(err, "sweep.planned")[0]["owner"], "alice");
  EXPECT_EQ(Events(err, "sweep.published").size(), 1u);
  EXPECT_EQ(Events(err, "worker.joined").size(), 2u);
  EXPECT_EQ(Events(err, "worker.registered").size(), 2u);
  EXPECT_EQ(Events(err, "coordinator.stopping").size(), 1u);
  // The forged token's refusal (workers polling while the coordinator stops may add UNAVAILABLE ones).
  std::vector<nlohmann::json> refused;
  for (const auto& e : Events(err, "call.refused"))
    if (e["code"] != "UNAVAILABLE") refused.push_back(e);
  ASSERT_EQ(refused.size(), 1u);
  EXPECT_EQ(refused[0]["code"], "UNAUTHENTICATED");
  EXPECT_EQ(refused[0]["method"], "Submit");
  EXPECT_EQ(refused[0]["level"], "warning");
  for (const std::string& t : {s.client_token, s.worker_token, s.admin_token, forged})
    EXPECT_EQ(log.find(t), std::string::npos);
  for (int i = 0; i < 2; ++i) {
    const std::string wlog = bistable_test::ReadText(s.dir + "/w" + std::to_string(i) + ".log.err");
    EXPECT_EQ(wlog.find(s.worker_token), std::string::npos);
  }
}

TEST(Observability, SweepsAndFetchOverTheWire) {
  Service s("fetch");
  const nlohmann::json sub = s.RunSweep();
  const std::string id = sub["id"];
  const ExecResult list = s.Cli({"sweeps", "--json"});
  ASSERT_EQ(list.exit_code, 0) << list.err;
  const auto sweeps = nlohmann::json::parse(list.out);
  ASSERT_EQ(sweeps.size(), 1u);
  EXPECT_EQ(sweeps[0]["id"], id);
  EXPECT_EQ(sweeps[0]["status"], "done");
  EXPECT_EQ(sweeps[0]["owner"], "alice");
  EXPECT_EQ(sweeps[0]["items_done"], 400);
  // Submission and publication times (ISO 8601 UTC), in `sweeps --json` and `status --json`.
  for (const nlohmann::json& row : {sweeps[0], nlohmann::json::parse(s.Cli({"status", id, "--json"}).out)}) {
    ASSERT_TRUE(row["created"].is_string() && row["finished"].is_string()) << row.dump();
    const double created = bistable_test::ParseIsoTimeUtc(row["created"]),
                 finished = bistable_test::ParseIsoTimeUtc(row["finished"]);
    EXPECT_GE(created, s.submitted_at - 1) << row.dump();
    EXPECT_LE(created, finished) << row.dump();
    EXPECT_LE(finished, s.done_at + 1) << row.dump();
  }

  // By prefix, default name <id>.h5, byte-identical to the coordinator's file, checksum reported.
  const ExecResult f = s.Cli({"fetch", id.substr(0, 6), "--json"});
  ASSERT_EQ(f.exit_code, 0) << f.err;
  const auto fj = nlohmann::json::parse(f.out);
  const std::string got = bistable_test::ReadText(s.dir + "/" + id + ".h5");
  const std::string orig = bistable_test::ReadText(s.dir + "/data/sweeps/" + id + ".h5");
  ASSERT_FALSE(orig.empty());
  EXPECT_EQ(got, orig);
  EXPECT_EQ(fj["bytes"], orig.size());
  EXPECT_EQ(fj["sha256"], bistable::Sha256Hex(orig));

  // Refusals leave nothing behind: an unknown sweep, a missing directory, a client without a token.
  fs::create_directories(s.dir + "/out");
  const ExecResult unknown = s.Cli({"fetch", "abcdef", "--out", s.dir + "/out/x.h5"});
  EXPECT_NE(unknown.exit_code, 0);
  EXPECT_NE(unknown.err.find("abcdef"), std::string::npos) << unknown.err;
  const ExecResult nodir = s.Cli({"fetch", id, "--out", s.dir + "/missing/x.h5"});
  EXPECT_NE(nodir.exit_code, 0);
  EXPECT_NE(nodir.err.find("out"), std::string::npos) << nodir.err;
  const ExecResult anon = RunArgv({BISTABLE_CLI, "fetch", id, "--coordinator", s.addr, "--out", s.dir + "/out/y.h5"});
  EXPECT_NE(anon.exit_code, 0);
  EXPECT_NE(anon.err.find("unauthenticated"), std::string::npos) << anon.err;
  EXPECT_TRUE(fs::is_empty(s.dir + "/out"));
  EXPECT_FALSE(fs::exists(s.dir + "/missing"));
}

TEST(Observability, APortInUseIsAnErrorNotShared) {
  Service s("port");
  ASSERT_FALSE(s.addr.empty());
  // A second coordinator on the first one's port, metrics port and health port: each refused.
  for (const std::vector<std::string>& extra :
       {std::vector<std::string>{"--listen", s.addr},
        {"--listen", "127.0.0.1:0", "--metrics", "127.0.0.1:" + std::to_string(s.metrics)},
        {"--listen", "127.0.0.1:0", "--health", "127.0.0.1:" + std::to_string(s.health)}}) {
    std::vector<std::string> argv = {BISTABLE_COORDINATOR, "--data", s.dir + "/data2"};
    argv.insert(argv.end(), extra.begin(), extra.end());
    const ExecResult r = RunArgv(argv, "", {}, 20);
    EXPECT_EQ(r.exit_code, 2) << extra[1] << ": " << r.out << r.err;
    EXPECT_NE(r.err.find("listen"), std::string::npos) << r.err;
  }
}

// gRPC's own messages (here a TLS handshake a plaintext client fails) are events of the structured log: with
// --log-format json every line the coordinator writes on stderr is a JSON object, one of them "grpc.log".
TEST(Observability, GrpcMessagesAreEventsOfTheLog) {
  const std::string dir = Dir("grpc_log");
  ASSERT_EQ(
      std::system(
          (std::string(BISTABLE_TESTS_DIR) + "/make_test_certs.sh " + dir + "/tls 127.0.0.1 >/dev/null 2>&1").c_str()),
      0);
  auto [ct, cl] = MintToken("client", "alice");
  std::ofstream(dir + "/tokens") << cl << "\n";
  const pid_t coord = bistable_test::SpawnLogged(
      {BISTABLE_COORDINATOR, "--listen", "127.0.0.1:0", "--data", dir + "/data", "--tokens", dir + "/tokens",
       "--tls-cert", dir + "/tls/server.pem", "--tls-key", dir + "/tls/server.key", "--log-format", "json"},
      dir + "/coord.log");
  const int port = AwaitPort(dir + "/coord.log", "listening");
  ASSERT_GT(port, 0) << bistable_test::ReadText(dir + "/coord.log.err");
  // A client without --tls-ca speaks plaintext to the TLS port: its call fails, the server's handshake too.
  std::ofstream(dir + "/client.token") << ct << "\n";
  const ExecResult r = RunArgv({BISTABLE_CLI, "sweeps", "--coordinator", "127.0.0.1:" + std::to_string(port),
                                "--token-file", dir + "/client.token"},
                               "", {}, 20);
  EXPECT_NE(r.exit_code, 0);
  std::vector<nlohmann::json> grpc;
  for (int i = 0; i < 200 && grpc.empty(); ++i) {
    std::this_thread::sleep_for(std::chrono::milliseconds(25));
    grpc = Events(dir + "/coord.log.err", "grpc.log");
  }
  ::kill(coord, SIGTERM);
  bistable_test::WaitExitFor(coord, 10);
  const std::string err = bistable_test::ReadText(dir + "/coord.log.err");
  ASSERT_FALSE(grpc.empty()) << "no grpc.log event: " << err;
  EXPECT_EQ(grpc[0]["level"], "error") << grpc[0];
  EXPECT_FALSE(grpc[0]["message"].get<std::string>().empty()) << grpc[0];
  std::istringstream lines(err);
  for (std::string line; std::getline(lines, line);)
    EXPECT_FALSE(nlohmann::json::parse(line, nullptr, false).is_discarded()) << "not a JSON line: " << line;
}

// A status watch that the coordinator's shutdown ends is an error (UNAVAILABLE, "shutting down"), not a
// last status taken for the end: the sweep is still running (it has no workers here).
TEST(Observability, AWatchEndedByShutdownIsAnError) {
  const std::string dir = Dir("watch_shutdown");
  const pid_t coord = bistable_test::SpawnLogged(
      {BISTABLE_COORDINATOR, "--listen", "127.0.0.1:0", "--data", dir + "/data"}, dir + "/coord.log");
  const int port = AwaitPort(dir + "/coord.log", "listening");
  ASSERT_GT(port, 0) << bistable_test::ReadText(dir + "/coord.log.err");
  const std::string addr = "127.0.0.1:" + std::to_string(port);
  std::ofstream(dir + "/spec.toml") << kSpec;
  const ExecResult sub = RunArgv({BISTABLE_CLI, "submit", dir + "/spec.toml", "--coordinator", addr, "--json"});
  ASSERT_EQ(sub.exit_code, 0) << sub.err;
  const std::string id = nlohmann::json::parse(sub.out)["id"];
  const pid_t watch =
      bistable_test::SpawnLogged({BISTABLE_CLI, "status", id, "--watch", "--coordinator", addr}, dir + "/watch.log");
  std::this_thread::sleep_for(std::chrono::milliseconds(800));  // the stream is open and has sent a status
  ::kill(coord, SIGTERM);
  const int code = bistable_test::WaitExitFor(watch, 20);
  bistable_test::WaitExitFor(coord, 10);
  const std::string err = bistable_test::ReadText(dir + "/watch.log.err");
  EXPECT_NE(code, 0) << "the watch ended as if the sweep had: " << bistable_test::ReadText(dir + "/watch.log");
  EXPECT_NE(code, -2) << "the watch hung";
  EXPECT_NE(err.find("shutting down"), std::string::npos) << err;
}

// ---- the HTTP server itself ----

TEST(HttpServer, RoutesMethodsAndBounds) {
  auto server = bistable::HttpServer::Start(
      "127.0.0.1:0",
      {{"/x",
        [](const bistable::HttpRequest&) {
          return bistable::HttpResponse{200, "text/plain", "hello\n", {}};
        }},
       {"/boom", [](const bistable::HttpRequest&) -> bistable::HttpResponse { throw std::runtime_error("no"); }}});
  ASSERT_TRUE(server.ok()) << server.status().ToString();
  const int port = (*server)->port();
  EXPECT_EQ(HttpRequest(port, "/x").body, "hello\n");
  EXPECT_EQ(HttpRequest(port, "/x?since=3").status, 200);
  const HttpReply head = HttpRequest(port, "/x", http::verb::head);
  EXPECT_EQ(head.status, 200);
  EXPECT_EQ(head.body, "");
  EXPECT_EQ(HttpRequest(port, "/nope").status, 404);
  EXPECT_EQ(HttpRequest(port, "/x", http::verb::post).status, 405);
  EXPECT_EQ(HttpRequest(port, "/boom").status, 500);
  // A header over 8 KiB is refused (400 or closed), and the server answers the next caller.
  const HttpReply big = HttpRequest(port, "/x", http::verb::get, std::string(9000, 'a'));
  EXPECT_TRUE(big.status == 400 || big.status == -1) << big.status;
  // 80 idle connections: at most 64 are kept; the server still answers.
  asio::io_context io;
  std::vector<std::unique_ptr<tcp::socket>> idle;
  for (int i = 0; i < 80; ++i) {
    idle.push_back(std::make_unique<tcp::socket>(io));
    idle.back()->connect(tcp::endpoint(asio::ip::make_address("127.0.0.1"), static_cast<unsigned short>(port)));
  }
  std::this_thread::sleep_for(std::chrono::milliseconds(200));
  idle.resize(10);  // free some slots
  std::this_thread::sleep_for(std::chrono::milliseconds(200));
  EXPECT_EQ(HttpRequest(port, "/x").status, 200);
  EXPECT_FALSE(bistable::HttpServer::Start("127.0.0.1:99999", {}).ok());
  EXPECT_FALSE(bistable::HttpServer::Start("example.com:80", {}).ok());
}

// Slow routes (a dashboard cell integrates a point) run on the server's pool: /healthz answers while both
// pool threads are busy, further slow requests wait for a free thread up to 4 · kSlowThreads at once and the
// next is answered 503 at once, and stopping the server waits for the running handlers and drops the queued.
TEST(HttpServer, SlowRoutesRunBesideTheOthers) {
  // The handlers block until released; every way out of this test releases them (a failed ASSERT included),
  // or the server's stop and the clients' futures would wait for ever.
  std::mutex mu;
  std::vector<std::promise<void>> releases(2);
  std::shared_future<void> released = releases[0].get_future().share();
  std::vector<bool> done(2, false);
  auto release = [&](size_t k) {
    std::lock_guard<std::mutex> lock(mu);
    if (!done[k]) releases[k].set_value(), done[k] = true;
  };
  std::atomic<int> started{0};
  bistable::HttpServer::Options options;
  options.slow_routes = {"/slow", "/slow-boom"};
  auto server = bistable::HttpServer::Start(
      "127.0.0.1:0",
      {{"/slow",
        [&](const bistable::HttpRequest&) {
          ++started;
          std::shared_future<void> r;
          {
            std::lock_guard<std::mutex> lock(mu);
            r = released;
          }
          r.wait();
          return bistable::HttpResponse{200, "text/plain", "slow\n", {}};
        }},
       {"/slow-boom", [](const bistable::HttpRequest&) -> bistable::HttpResponse { throw 42; }},
       {"/healthz",
        [](const bistable::HttpRequest&) {
          return bistable::HttpResponse{200, "text/plain", "ok\n", {}};
        }}},
      options);
  ASSERT_TRUE(server.ok()) << server.status().ToString();
  std::unique_ptr<bistable::HttpServer> srv = std::move(server).value();
  const int port = srv->port();
  struct Guard {
    std::function<void()> f;
    ~Guard() { f(); }
  } guard{[&] { release(0), release(1); }};                // destroyed before srv
  EXPECT_EQ(HttpRequest(port, "/slow-boom").status, 500);  // not even a non-std exception ends the process
  auto wait_for = [](auto pred) {
    for (int i = 0; i < 500 && !pred(); ++i) std::this_thread::sleep_for(std::chrono::milliseconds(10));
    return pred();
  };
  constexpr int kLimit = 4 * bistable::HttpServer::kSlowThreads;
  std::vector<std::future<HttpReply>> slow;
  for (int i = 0; i < 2; ++i)
    slow.push_back(std::async(std::launch::async, [port] { return HttpRequest(port, "/slow"); }));
  if (!wait_for([&] { return started.load() == 2; })) {
    release(0);
    FAIL() << "slow handlers started: " << started.load();
  }
  auto health = std::async(std::launch::async, [port] { return HttpRequest(port, "/healthz"); });
  const bool answered = health.wait_for(std::chrono::seconds(5)) == std::future_status::ready;
  EXPECT_TRUE(answered) << "/healthz waited for the slow handlers";
  for (int i = 2; i < kLimit; ++i)
    slow.push_back(std::async(std::launch::async, [port] { return HttpRequest(port, "/slow"); }));
  std::this_thread::sleep_for(std::chrono::milliseconds(300));
  EXPECT_EQ(started.load(), 2);  // the others wait for a pool thread
  auto busy = std::async(std::launch::async, [port] { return HttpRequest(port, "/slow"); });  // one past the limit
  const bool refused_at_once = busy.wait_for(std::chrono::seconds(2)) == std::future_status::ready;
  EXPECT_TRUE(refused_at_once) << "the request past the limit was queued";
  release(0);
  const HttpReply b = busy.get();
  if (refused_at_once) {
    EXPECT_EQ(b.status, 503) << b.body;
  }
  if (answered) {
    EXPECT_EQ(health.get().body, "ok\n");
  }
  for (auto& f : slow) {
    const HttpReply r = f.get();
    EXPECT_EQ(r.status, 200);
    EXPECT_EQ(r.body, "slow\n");
  }
  EXPECT_EQ(started.load(), kLimit);
  EXPECT_EQ(HttpRequest(port, "/slow").status, 200);  // the count went back down

  // Stopping: the two running handlers finish, the queued one never starts.
  {
    std::lock_guard<std::mutex> lock(mu);
    released = releases[1].get_future().share();
  }
  started = 0;
  std::vector<std::future<HttpReply>> more;
  for (int i = 0; i < 3; ++i)
    more.push_back(std::async(std::launch::async, [port] { return HttpRequest(port, "/slow"); }));
  if (!wait_for([&] { return started.load() == 2; })) {
    release(1);
    FAIL() << "slow handlers started: " << started.load();
  }
  std::this_thread::sleep_for(std::chrono::milliseconds(300));  // the third is queued by now
  auto stopped = std::async(std::launch::async, [&] { srv.reset(); });
  EXPECT_EQ(stopped.wait_for(std::chrono::milliseconds(200)),
            std::future_status::timeout);  // waits for the running two
  release(1);
  stopped.get();
  EXPECT_EQ(started.load(), 2);
  for (auto& f : more) EXPECT_EQ(f.get().status, -1);  // closed without an answer
}

// Heavy routes (a dashboard cell): at most kSlowThreads - 1 run at once, so a light slow route (a map) still
// has a thread; a client holds at most kMaxHeavyPerClient (more: 503 at once, to it alone), another client's
// request waits its turn instead of being refused.
TEST(HttpServer, HeavyRoutesLeaveAThreadAndBoundEachClient) {
  std::mutex mu;
  std::promise<void> release;
  std::shared_future<void> released = release.get_future().share();
  bool done = false;
  auto let_go = [&] {
    std::lock_guard<std::mutex> lock(mu);
    if (!done) release.set_value(), done = true;
  };
  std::atomic<int> running{0}, most{0}, started{0};
  bistable::HttpServer::Options options;
  options.slow_routes = {"/heavy", "/light"};
  options.heavy_routes = {"/heavy"};
  auto server =
      bistable::HttpServer::Start("127.0.0.1:0",
                                  {{"/heavy",
                                    [&](const bistable::HttpRequest&) {
                                      ++started;
                                      const int now = ++running;
                                      for (int m = most.load(); now > m && !most.compare_exchange_weak(m, now);) {
                                      }
                                      released.wait();
                                      --running;
                                      return bistable::HttpResponse{200, "text/plain", "cell\n", {}};
                                    }},
                                   {"/light",
                                    [](const bistable::HttpRequest&) {
                                      return bistable::HttpResponse{200, "text/plain", "map\n", {}};
                                    }}},
                                  options);
  ASSERT_TRUE(server.ok()) << server.status().ToString();
  std::unique_ptr<bistable::HttpServer> srv = std::move(server).value();
  struct Guard {
    std::function<void()> f;
    ~Guard() { f(); }
  } guard{let_go};  // destroyed before srv: the handlers are released on every way out
  const int port = srv->port();
  const auto as = [port](const std::string& who, const std::string& target) {
    return bistable_test::HttpExchange(port, target, http::verb::get,
                                       {{"Host", "127.0.0.1"}, {"Authorization", "Bearer " + who}});
  };
  std::vector<std::future<HttpReply>> a;
  for (int i = 0; i < 2; ++i) a.push_back(std::async(std::launch::async, [&] { return as("alice", "/heavy"); }));
  for (int i = 0; i < 500 && started.load() < 1; ++i) std::this_thread::sleep_for(std::chrono::milliseconds(10));
  std::this_thread::sleep_for(std::chrono::milliseconds(200));  // both of alice's are in: one runs, one waits
  const HttpReply third = as("alice", "/heavy");
  EXPECT_EQ(third.status, 503) << third.body;
  EXPECT_NE(third.body.find("at most 2 per client"), std::string::npos) << third.body;
  auto b = std::async(std::launch::async, [&] { return as("bob", "/heavy"); });
  auto map = std::async(std::launch::async, [&] { return as("bob", "/light"); });
  const bool map_answered = map.wait_for(std::chrono::seconds(5)) == std::future_status::ready;
  EXPECT_TRUE(map_answered) << "a light slow route waited for the heavy ones";
  if (map_answered) {
    EXPECT_EQ(map.get().status, 200);
  }
  std::this_thread::sleep_for(std::chrono::milliseconds(200));
  EXPECT_EQ(started.load(), 1) << "a second heavy handler took the other thread";
  let_go();
  for (auto& f : a) EXPECT_EQ(f.get().status, 200);
  EXPECT_EQ(b.get().status, 200) << "another client's request was refused";
  EXPECT_EQ(most.load(), 1);
  EXPECT_EQ(as("alice", "/heavy").status, 200);  // the counts went back down
}

// Query strings and cookies as the dashboard reads them: decoded, bounded, hostile forms refused.
TEST(HttpServer, QueryStringsAndCookies) {
  auto q = bistable::ParseQueryString("id=ab12&q=frf_db%20%3C%20-3+and+lle%3E0&x=");
  ASSERT_TRUE(q.ok());
  EXPECT_EQ(q->at("id"), "ab12");
  EXPECT_EQ(q->at("q"), "frf_db < -3 and lle>0");
  EXPECT_EQ(q->at("x"), "");
  EXPECT_FALSE(bistable::ParseQueryString("a=1&a=2").ok());  // repeated
  EXPECT_FALSE(bistable::ParseQueryString("a=%zz").ok());    // malformed escape
  EXPECT_FALSE(bistable::ParseQueryString("a=%0a").ok());    // control character
  EXPECT_FALSE(bistable::ParseQueryString("=1").ok());       // no name
  std::string many;
  for (int i = 0; i < 17; ++i) many += "p" + std::to_string(i) + "=1&";
  EXPECT_FALSE(bistable::ParseQueryString(many).ok());  // more than 16
  EXPECT_EQ(bistable::CookieValue("a=1; bistable_token=t0k; b=2", "bistable_token"), "t0k");
  EXPECT_EQ(bistable::CookieValue("xbistable_token=no", "bistable_token"), "");
  EXPECT_EQ(bistable::CookieValue("", "bistable_token"), "");
}

// The Host rule of every listener that serves data without a token (DNS rebinding: a page elsewhere sends
// its own host name; an IP literal is no name an attacker controls).
TEST(HttpServer, HostRuleAnswersIpLiteralsLocalhostAndAllowedNamesOnly) {
  const std::vector<std::string> allowed = {"bistable-coordinator", "Metrics.Internal"};
  for (const char* ok : {"localhost", "LocalHost:8080", "127.0.0.1", "127.0.0.1:65535", "[::1]", "[::1]:80",
                         "127.0.0.2", "0.0.0.0", "10.1.2.3:9090", "[::2]:80", "[2001:db8::7]", "bistable-coordinator",
                         "BISTABLE-COORDINATOR:9090", "metrics.internal"})
    EXPECT_TRUE(bistable::HostAllowed(ok, allowed)) << ok;
  for (const char* bad : {"",
                          "evil.example",
                          "evil.example:8080",
                          "localhost.evil.example",
                          "127.0.0.1.nip.io",
                          "localhost:",
                          "localhost:80x",
                          "localhost:123456",
                          "[::1",
                          "[::1]x",
                          "[::1]:",
                          "::1",
                          "[evil.example]",
                          "[127.0.0.1]",
                          "localhost.",
                          " localhost",
                          "127.0.0.1:80:80",
                          "127.1",
                          "0x7f000001",
                          "bistable-coordinator.evil.example",
                          "metrics"})
    EXPECT_FALSE(bistable::HostAllowed(bad, allowed)) << bad;
  EXPECT_FALSE(bistable::HostAllowed("bistable-coordinator", {}));  // only when allowed
  EXPECT_TRUE(bistable::CheckAllowedHostName("bistable-coordinator.bistable.svc", "http-allowed-host").ok());
  for (const std::string& bad : std::vector<std::string>{"", "a:80", "*.example", "a b", std::string(254, 'a'), "a\nb"})
    EXPECT_FALSE(bistable::CheckAllowedHostName(bad, "http-allowed-host").ok()) << bad;
}

// ---- structured logs ----

TEST(Log, FieldsFromHostileInputCannotForgeLines) {
  using bistable::log::Field;
  using bistable::log::Format;
  const std::string evil = "w1\n2026-01-01T00:00:00Z info sweep.published sweep=x\"} {\"a\":1\x01\xff";
  const std::string text =
      bistable::log::Render(Format::kText, "worker.joined", {{"worker", evil}, {"n", 3}, {"ok", true}});
  EXPECT_EQ(text.find('\n'), std::string::npos) << text;
  EXPECT_NE(text.find("worker=\"w1\\x0a"), std::string::npos) << text;
  EXPECT_NE(text.find(" n=3 ok=true"), std::string::npos) << text;
  const std::string json =
      "{" + bistable::log::Render(Format::kJson, "worker.joined", {{"worker", evil}, {"x", 0.5}}) + "}";
  auto j = nlohmann::json::parse(json, nullptr, false);
  ASSERT_FALSE(j.is_discarded()) << json;
  EXPECT_EQ(j["event"], "worker.joined");
  EXPECT_EQ(j["worker"].get<std::string>().substr(0, 3), "w1\n");
  EXPECT_EQ(j["x"], 0.5);
  EXPECT_EQ(json.find('\n'), std::string::npos);
  // Bounded: a megabyte of name becomes 512 bytes and "...".
  const std::string big = bistable::log::Render(Format::kJson, "e", {{"v", std::string(1 << 20, 'a')}});
  EXPECT_LT(big.size(), 600u);
  EXPECT_TRUE(nlohmann::json::parse("{" + big + "}", nullptr, false).is_object());
  // Non-finite numbers stay valid JSON.
  EXPECT_TRUE(nlohmann::json::parse("{" + bistable::log::Render(Format::kJson, "e", {{"v", NAN}}) + "}", nullptr, false)
                  .is_object());
  EXPECT_FALSE(bistable::log::ParseLevel("verbose").ok());
  EXPECT_FALSE(bistable::log::ParseFormat("xml").ok());
}

// ---- CPUs ----

TEST(Cpus, QuotasFromCgroupFiles) {
  EXPECT_FALSE(bistable::CpuQuotaFromCpuMax("max 100000").has_value());
  EXPECT_DOUBLE_EQ(*bistable::CpuQuotaFromCpuMax("150000 100000"), 1.5);
  EXPECT_FALSE(bistable::CpuQuotaFromCfs("-1", "100000").has_value());
  EXPECT_DOUBLE_EQ(*bistable::CpuQuotaFromCfs("200000", "100000"), 2.0);
  EXPECT_FALSE(bistable::CpuQuotaFromCpuMax("garbage").has_value());
  // A fake v2 hierarchy: the pod limits to 3 CPUs, the container to 2: the tightest wins.
  const std::string root = Dir("cgroup");
  fs::create_directories(root + "/kubepods/pod1/ctr");
  std::ofstream(root + "/kubepods/pod1/cpu.max") << "300000 100000\n";
  std::ofstream(root + "/kubepods/pod1/ctr/cpu.max") << "200000 100000\n";
  std::ofstream(root + "/cpu.max") << "max 100000\n";
  EXPECT_DOUBLE_EQ(*bistable::CgroupCpuQuota("0::/kubepods/pod1/ctr\n", root), 2.0);
  // Inside a cgroup namespace the path is "/": the root's file counts.
  const std::string ns = Dir("cgroupns");
  std::ofstream(ns + "/cpu.max") << "50000 100000\n";
  EXPECT_DOUBLE_EQ(*bistable::CgroupCpuQuota("0::/\n", ns), 0.5);
  // v1: cpu,cpuacct controller.
  const std::string v1 = Dir("cgroupv1");
  fs::create_directories(v1 + "/cpu,cpuacct/docker/abc");
  std::ofstream(v1 + "/cpu,cpuacct/docker/abc/cpu.cfs_quota_us") << "400000\n";
  std::ofstream(v1 + "/cpu,cpuacct/docker/abc/cpu.cfs_period_us") << "100000\n";
  EXPECT_DOUBLE_EQ(*bistable::CgroupCpuQuota("12:memory:/docker/abc\n4:cpu,cpuacct:/docker/abc\n", v1), 4.0);
  EXPECT_FALSE(bistable::CgroupCpuQuota("0::/nothing\n", Dir("empty")).has_value());
}

TEST(Cpus, AffinityLimitsTheDefaultThreadsOfAWorker) {
  cpu_set_t before;
  ASSERT_EQ(sched_getaffinity(0, sizeof before, &before), 0);
  cpu_set_t one;
  CPU_ZERO(&one);
  for (int c = 0; c < CPU_SETSIZE; ++c)
    if (CPU_ISSET(c, &before)) {
      CPU_SET(c, &one);
      break;
    }
  ASSERT_EQ(sched_setaffinity(0, sizeof one, &one), 0);
  EXPECT_EQ(bistable::UsableCpus(), 1);
  // A worker started under that mask (children inherit it) defaults to one pull loop.
  const std::string dir = Dir("affinity");
  const pid_t w = bistable_test::SpawnLogged(
      {BISTABLE_WORKER, "--coordinator", "127.0.0.1:1", "--log-format", "json", "--name", "pinned"}, dir + "/w.log");
  ASSERT_EQ(sched_setaffinity(0, sizeof before, &before), 0);
  std::vector<nlohmann::json> ev;
  for (int i = 0; i < 200 && ev.empty(); ++i) {
    std::this_thread::sleep_for(std::chrono::milliseconds(25));
    ev = Events(dir + "/w.log.err", "worker.started");
  }
  ::kill(w, SIGTERM);
  EXPECT_EQ(bistable_test::WaitExitFor(w, 10), 0);
  ASSERT_EQ(ev.size(), 1u);
  EXPECT_EQ(ev[0]["threads"], 1);
  EXPECT_GE(bistable::UsableCpus(), 1);
  EXPECT_LE(bistable::UsableCpus(), CPU_COUNT(&before));
}

}  // namespace
