// End-to-end tests of the distributed service with real processes on loopback: a coordinator, worker
// processes and the client; maps compared bit for bit with the embedded `bistable run`.
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <thread>

#include <grpcpp/grpcpp.h>
#include <gtest/gtest.h>

#include <nlohmann/json.hpp>
#include "engine/metric_catalog.h"

#include "bistable.grpc.pb.h"
#include "storage/map_file.h"
#include "tests/iso_time_parse.h"
#include "tests/map_compare.h"
#include "tests/process_util.h"

namespace {

namespace fs = std::filesystem;
using bistable_test::Bistable;
using bistable_test::ProcessResult;

std::string Dir(const std::string& name) { return bistable_test::FreshDir("bistable_dist", name); }

pid_t Spawn(const std::vector<std::string>& argv, const std::string& out_file) {
  return bistable_test::SpawnLogged(argv, out_file);
}

void Kill(pid_t pid, int sig) {
  ::kill(pid, sig);
  int status = 0;
  ::waitpid(pid, &status, 0);
}

// Starts a coordinator on a free loopback port; returns its pid and address.
std::pair<pid_t, std::string> StartCoordinator(const std::string& data, const std::string& log, double lease = 1.0,
                                               const std::string& listen = "127.0.0.1:0") {
  const pid_t pid = Spawn({BISTABLE_COORDINATOR, "--listen", listen, "--data", data, "--lease-seconds",
                           std::to_string(lease), "--job-seconds", "0.01"},
                          log);
  for (int i = 0; i < 200; ++i) {
    std::ifstream in(log);
    std::string line;
    if (std::getline(in, line) && line.rfind("listening on ", 0) == 0) return {pid, line.substr(13)};
    std::this_thread::sleep_for(std::chrono::milliseconds(25));
  }
  return {pid, ""};
}

pid_t StartWorker(const std::string& addr, const std::string& name, const std::string& log) {
  return Spawn({BISTABLE_WORKER, "--coordinator", addr, "--threads", "1", "--name", name}, log);
}

nlohmann::json Status(const std::string& id, const std::string& addr) {
  const ProcessResult r = Bistable("status " + id + " --json --coordinator " + addr);
  return r.exit_code <= 1 && !r.out.empty() ? nlohmann::json::parse(r.out) : nlohmann::json{{"state", "unreachable"}};
}

bool WaitDone(const std::string& id, const std::string& addr, double seconds) {
  const auto end = std::chrono::steady_clock::now() + std::chrono::duration<double>(seconds);
  while (std::chrono::steady_clock::now() < end) {
    if (Status(id, addr)["state"] == "done") return true;
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
  }
  return false;
}

using bistable_test::ExpectSameMaps;

constexpr const char* kSpec = R"(
name = "distributed test"
model = "coupled"
[axes]
alpha = { linspace = [0.1, 3.0, 30] }
omega = { linspace = [0.1, 3.0, 30] }
[integration]
t_end = 200.0
t_keep = 100.0
)";

// The embedded reference map of kSpec.
std::string Embedded(const std::string& dir, const std::string& spec) {
  const ProcessResult r = Bistable("run " + spec + " --data " + dir + "/embedded --json --no-plots --quiet");
  EXPECT_EQ(r.exit_code, 0) << r.err;
  return nlohmann::json::parse(r.out)["files"][0];
}

TEST(Distributed, ThreeWorkersGiveTheEmbeddedMapBitForBit) {
  const std::string dir = Dir("three");
  const std::string spec = dir + "/spec.toml";
  std::ofstream(spec) << kSpec;
  auto [coord, addr] = StartCoordinator(dir + "/data", dir + "/coord.log");
  ASSERT_FALSE(addr.empty()) << "coordinator did not start";
  std::vector<pid_t> workers;
  for (int i = 0; i < 3; ++i)
    workers.push_back(StartWorker(addr, "w" + std::to_string(i), dir + "/w" + std::to_string(i) + ".log"));
  const ProcessResult sub = Bistable("submit " + spec + " --json --coordinator " + addr);
  ASSERT_EQ(sub.exit_code, 0) << sub.err;
  const std::string id = nlohmann::json::parse(sub.out)["id"];
  ASSERT_TRUE(WaitDone(id, addr, 120));
  const auto st = Status(id, addr);
  EXPECT_EQ(st["items_done"], 900);
  EXPECT_EQ(st["items_total"], 900);
  // Work was shared.
  const auto ws = nlohmann::json::parse(Bistable("workers --json --coordinator " + addr).out);
  int busy = 0;
  const double now = std::chrono::duration<double>(std::chrono::system_clock::now().time_since_epoch()).count();
  for (const auto& w : ws) {
    busy += w["items_done"].get<long>() > 0;
    // last_seen is ISO 8601 UTC, within this test's run.
    const double seen = bistable_test::ParseIsoTimeUtc(w["last_seen"].get<std::string>());
    EXPECT_GT(seen, now - 300) << w.dump();
    EXPECT_LE(seen, now + 1) << w.dump();
  }
  EXPECT_GE(busy, 2);
  // map and query answer the same through the coordinator as from the data directory.
  for (const std::string& args :
       {"map " + id + " --metric frf_db --format json", "map " + id + " --metric lle --at alpha=3 --format csv",
        "map " + id + " --metric motion --format json --out -",
        "query " + id + " \"lle > 0.01 and frf_db < 5\" --json"}) {
    const ProcessResult remote = Bistable(args + " --coordinator " + addr);
    const ProcessResult local = Bistable(args + " --data " + dir + "/data");
    ASSERT_EQ(remote.exit_code, 0) << args << ": " << remote.err;
    EXPECT_EQ(remote.out, local.out) << args;
  }
  for (pid_t w : workers) Kill(w, SIGTERM);
  Kill(coord, SIGTERM);
  ExpectSameMaps(dir + "/data/" + st["file"].get<std::string>(), Embedded(dir, spec));
  fs::remove_all(dir);
}

TEST(Distributed, KilledWorkerAndRestartedCoordinatorLoseNothing) {
  const std::string dir = Dir("faults");
  const std::string spec = dir + "/spec.toml";
  std::ofstream(spec) << kSpec;
  auto [coord, addr] = StartCoordinator(dir + "/data", dir + "/coord.log", 1.0);
  ASSERT_FALSE(addr.empty());
  std::vector<pid_t> workers;
  for (int i = 0; i < 3; ++i)
    workers.push_back(StartWorker(addr, "w" + std::to_string(i), dir + "/w" + std::to_string(i) + ".log"));
  const std::string id = nlohmann::json::parse(Bistable("submit " + spec + " --json --coordinator " + addr).out)["id"];
  auto progress = [&] { return Status(id, addr)["items_done"].get<long>(); };
  while (progress() < 150) std::this_thread::sleep_for(std::chrono::milliseconds(20));
  Kill(workers[0], SIGKILL);  // mid-job: its lease expires after 1 s and the job is requeued
  while (progress() < 400) std::this_thread::sleep_for(std::chrono::milliseconds(20));
  const long before = progress();
  Kill(coord, SIGKILL);  // coordinator dies; workers back off and retry
  auto [coord2, addr2] = StartCoordinator(dir + "/data", dir + "/coord2.log", 1.0, addr);  // same port
  ASSERT_EQ(addr2, addr);
  EXPECT_GE(Status(id, addr)["items_done"].get<long>(), before) << "results acknowledged before the kill are kept";
  workers[0] = StartWorker(addr, "w0b", dir + "/w0b.log");
  ASSERT_TRUE(WaitDone(id, addr, 120));
  const auto st = Status(id, addr);
  EXPECT_EQ(st["items_done"], 900);  // each item stored once into the map
  for (pid_t w : workers) Kill(w, SIGTERM);
  Kill(coord2, SIGTERM);
  ExpectSameMaps(dir + "/data/" + st["file"].get<std::string>(), Embedded(dir, spec));
  fs::remove_all(dir);
}

// Bad input over the wire: each answered with its status code while the coordinator stays up.
TEST(Distributed, BadInputOverTheWireGetsTheRightStatusCode) {
  const std::string dir = Dir("bad");
  auto [coord, addr] = StartCoordinator(dir + "/data", dir + "/coord.log", 0.3);
  ASSERT_FALSE(addr.empty());
  auto stub = bistable::v1::Coordinator::NewStub(grpc::CreateChannel(addr, grpc::InsecureChannelCredentials()));
  auto submit = [&](const std::string& toml) {
    grpc::ClientContext ctx;
    bistable::v1::SubmitRequest req;
    req.set_spec_toml(toml);
    bistable::v1::SubmitReply rep;
    return stub->Submit(&ctx, req, &rep).error_code();
  };
  auto report = [&](const std::string& lease, unsigned width, std::vector<double> values) {
    grpc::ClientContext ctx;
    bistable::v1::ReportRequest req;
    req.set_lease_id(lease);
    req.set_record_width(width);
    req.set_catalog_hash(bistable::CatalogHash());
    for (double v : values) req.add_values(v);
    bistable::v1::ReportReply rep;
    return stub->Report(&ctx, req, &rep).error_code();
  };
  // A valid sweep and two leases to misuse.
  ASSERT_EQ(submit("model = \"coupled\"\n[axes]\nalpha = [0.5, 1.0]\nomega = [0.5, 1.0]\n[integration]\nt_end = "
                   "50.0\nt_keep = 25.0\n"),
            grpc::StatusCode::OK);
  auto lease = [&] {
    grpc::ClientContext ctx;
    bistable::v1::LeaseRequest req;
    req.set_worker("tester");
    bistable::v1::LeaseReply rep;
    stub->Lease(&ctx, req, &rep);
    return rep;
  };
  const auto l1 = lease();
  ASSERT_TRUE(l1.has_job());
  const size_t items = l1.points_size();
  const int width = static_cast<int>(bistable::PointRecord::Size());  // the record layout (engine/metric_catalog.h)
  const std::vector<double> good(items * width, 0.0);
  std::vector<double> with_inf = good;
  with_inf[3] = INFINITY;
  struct Case {
    const char* what;
    std::function<grpc::StatusCode()> call;
    grpc::StatusCode expect;
  };
  const Case cases[] = {
      {"malformed spec", [&] { return submit("model = \"coupled\"\n[axes\n"); }, grpc::StatusCode::INVALID_ARGUMENT},
      {"oversized spec", [&] { return submit(std::string(2 << 20, '#')); }, grpc::StatusCode::INVALID_ARGUMENT},
      {"grid above the limit",
       [&] {
         return submit(
             "model = \"coupled\"\n[axes]\nalpha = { linspace = [0.1, 3, 10000] }\nomega = { linspace = [0.1, 3, "
             "10000] }\n");
       },
       grpc::StatusCode::INVALID_ARGUMENT},
      {"unknown key", [&] { return submit("model = \"coupled\"\n[axes]\nalpah = [1]\n"); },
       grpc::StatusCode::INVALID_ARGUMENT},
      {"result for an unknown lease", [&] { return report("no-such-lease", width, good); },
       grpc::StatusCode::NOT_FOUND},
      {"result of the wrong shape", [&] { return report(l1.lease_id(), width, std::vector<double>(width, 0.0)); },
       grpc::StatusCode::INVALID_ARGUMENT},
      {"values not a whole number of records",
       [&] { return report(l1.lease_id(), width, std::vector<double>(width + 7, 0.0)); },
       grpc::StatusCode::INVALID_ARGUMENT},
      {"infinity in a result", [&] { return report(l1.lease_id(), width, with_inf); },
       grpc::StatusCode::INVALID_ARGUMENT},
      {"result for an expired lease",
       [&] {
         std::this_thread::sleep_for(std::chrono::milliseconds(400));  // lease period 0.3 s
         return report(l1.lease_id(), width, good);
       },
       grpc::StatusCode::FAILED_PRECONDITION},
      {"status of an unknown sweep",
       [&] {
         grpc::ClientContext ctx;
         bistable::v1::StatusRequest req;
         req.set_id("ffffffffffff");
         bistable::v1::SweepStatus rep;
         return stub->GetStatus(&ctx, req, &rep).error_code();
       },
       grpc::StatusCode::NOT_FOUND},
  };
  for (const Case& c : cases) EXPECT_EQ(c.call(), c.expect) << c.what;
  // Still up and answering.
  grpc::ClientContext ctx;
  bistable::v1::ListSweepsRequest req;
  bistable::v1::ListSweepsReply rep;
  EXPECT_TRUE(stub->ListSweeps(&ctx, req, &rep).ok());
  EXPECT_EQ(rep.sweeps_size(), 1);
  Kill(coord, SIGTERM);
  fs::remove_all(dir);
}

// Mints a token with `bistable token`; returns {token, tokens-file line}.
std::pair<std::string, std::string> MintToken(const std::string& role, const std::string& name) {
  const ProcessResult r = Bistable("token --role " + role + " --name " + name);
  const size_t a = r.out.find("token: ") + 7, b = r.out.find('\n', a);
  const size_t c = r.out.find("tokens-file line: ") + 18, d = r.out.find('\n', c);
  return {r.out.substr(a, b - a), r.out.substr(c, d - c)};
}

grpc::StatusCode CallWith(const std::string& token, const std::function<grpc::Status(grpc::ClientContext*)>& call) {
  grpc::ClientContext ctx;
  if (!token.empty()) ctx.AddMetadata("authorization", "Bearer " + token);
  return call(&ctx).error_code();
}

TEST(Distributed, TokensAndRolesAreEnforcedAndNeverLogged) {
  const std::string dir = Dir("auth");
  auto [alice, alice_line] = MintToken("client", "alice");
  auto [bob, bob_line] = MintToken("client", "bob");
  auto [worker, worker_line] = MintToken("worker", "w");
  auto [admin, admin_line] = MintToken("admin", "root");
  std::ofstream(dir + "/tokens") << "# role sha256 name\n"
                                 << alice_line << "\n"
                                 << bob_line << "\n"
                                 << worker_line << "\n"
                                 << admin_line << "\n";
  const pid_t coord =
      Spawn({BISTABLE_COORDINATOR, "--listen", "127.0.0.1:0", "--data", dir + "/data", "--tokens", dir + "/tokens"},
            dir + "/coord.log");
  std::string addr;
  for (int i = 0; i < 200 && addr.empty(); ++i) {
    std::ifstream in(dir + "/coord.log");
    std::string line;
    if (std::getline(in, line) && line.rfind("listening on ", 0) == 0)
      addr = line.substr(13);
    else
      std::this_thread::sleep_for(std::chrono::milliseconds(25));
  }
  ASSERT_FALSE(addr.empty());
  auto stub = bistable::v1::Coordinator::NewStub(grpc::CreateChannel(addr, grpc::InsecureChannelCredentials()));
  const std::string spec =
      "model = \"coupled\"\n[axes]\nalpha = [0.5]\nomega = [1.0]\n[integration]\nt_end = 50.0\nt_keep = 25.0\n";
  auto submit = [&](grpc::ClientContext* c) {
    bistable::v1::SubmitRequest req;
    req.set_spec_toml(spec);
    bistable::v1::SubmitReply rep;
    return stub->Submit(c, req, &rep);
  };
  auto lease = [&](grpc::ClientContext* c) {
    bistable::v1::LeaseRequest req;
    req.set_worker("w");
    bistable::v1::LeaseReply rep;
    return stub->Lease(c, req, &rep);
  };
  std::string id;
  auto cancel = [&](grpc::ClientContext* c) {
    bistable::v1::CancelRequest req;
    req.set_id(id);
    bistable::v1::CancelReply rep;
    return stub->Cancel(c, req, &rep);
  };
  auto status = [&](grpc::ClientContext* c) {
    bistable::v1::StatusRequest req;
    req.set_id(id);
    bistable::v1::SweepStatus rep;
    return stub->GetStatus(c, req, &rep);
  };
  {
    grpc::ClientContext ctx;
    ctx.AddMetadata("authorization", "Bearer " + alice);
    bistable::v1::SubmitRequest req;
    req.set_spec_toml(spec);
    bistable::v1::SubmitReply rep;
    ASSERT_TRUE(stub->Submit(&ctx, req, &rep).ok());
    id = rep.id();
  }
  struct Case {
    const char* what;
    std::string token;
    std::function<grpc::Status(grpc::ClientContext*)> call;
    grpc::StatusCode expect;
  };
  const Case cases[] = {
      {"no token", "", submit, grpc::StatusCode::UNAUTHENTICATED},
      {"wrong token", "0123456789abcdef", submit, grpc::StatusCode::UNAUTHENTICATED},
      {"worker token calling submit", worker, submit, grpc::StatusCode::PERMISSION_DENIED},
      {"client token calling lease", alice, lease, grpc::StatusCode::PERMISSION_DENIED},
      {"worker token calling lease", worker, lease, grpc::StatusCode::OK},
      {"client reading status", bob, status, grpc::StatusCode::OK},
      {"client cancelling another's sweep", bob, cancel, grpc::StatusCode::PERMISSION_DENIED},
      {"client cancelling its own sweep", alice, cancel, grpc::StatusCode::OK},
      {"admin reading status", admin, status, grpc::StatusCode::OK},
  };
  for (const Case& c : cases) EXPECT_EQ(CallWith(c.token, c.call), c.expect) << c.what;
  Kill(coord, SIGTERM);
  std::ifstream log(dir + "/coord.log"), err(dir + "/coord.log.err");
  const std::string text =
      std::string(std::istreambuf_iterator<char>(log), {}) + std::string(std::istreambuf_iterator<char>(err), {});
  for (const std::string& t : {alice, bob, worker, admin})
    EXPECT_EQ(text.find(t), std::string::npos) << "a token was logged";
  std::ifstream tf(dir + "/tokens");
  const std::string tokens_text((std::istreambuf_iterator<char>(tf)), {});
  EXPECT_EQ(tokens_text.find(alice), std::string::npos) << "the tokens file must hold hashes only";
  fs::remove_all(dir);
}

// Multi-host path: coordinator and worker in separate network namespaces joined by a veth pair, over
// TLS with tokens. Needs root and `ip netns`; skipped with a message elsewhere.
TEST(Distributed, TlsAndTokensAcrossNetworkNamespaces) {
  if (::geteuid() != 0) GTEST_SKIP() << "needs root for ip netns";
  const std::string ip = fs::exists("/usr/sbin/ip") ? "/usr/sbin/ip" : "/sbin/ip";
  const std::string a = "bsA" + std::to_string(::getpid() % 10000), b = "bsB" + std::to_string(::getpid() % 10000);
  auto sh = [](const std::string& cmd) { return std::system((cmd + " >/dev/null 2>&1").c_str()); };
  if (sh(ip + " netns add " + a) != 0) GTEST_SKIP() << "network namespaces are not available here";
  sh(ip + " netns add " + b);
  const std::string va = "vA" + std::to_string(::getpid() % 10000), vb = "vB" + std::to_string(::getpid() % 10000);
  const bool net_ok =
      sh(ip + " link add " + va + " type veth peer name " + vb) == 0 &&
      sh(ip + " link set " + va + " netns " + a) == 0 && sh(ip + " link set " + vb + " netns " + b) == 0 &&
      sh(ip + " -n " + a + " addr add 10.77.0.1/24 dev " + va) == 0 &&
      sh(ip + " -n " + b + " addr add 10.77.0.2/24 dev " + vb) == 0 &&
      sh(ip + " -n " + a + " link set " + va + " up") == 0 && sh(ip + " -n " + b + " link set " + vb + " up") == 0 &&
      sh(ip + " -n " + a + " link set lo up") == 0 && sh(ip + " -n " + b + " link set lo up") == 0;
  auto cleanup = [&] {
    sh(ip + " netns del " + a);
    sh(ip + " netns del " + b);
  };
  if (!net_ok) {
    cleanup();
    GTEST_SKIP() << "cannot create a veth pair between namespaces here";
  }
  const std::string dir = Dir("netns");
  ASSERT_EQ(std::system((std::string(BISTABLE_TESTS_DIR) + "/make_test_certs.sh " + dir + "/tls 10.77.0.1").c_str()),
            0);
  auto [client, client_line] = MintToken("client", "alice");
  auto [worker, worker_line] = MintToken("worker", "w");
  std::ofstream(dir + "/tokens") << client_line << "\n" << worker_line << "\n";
  std::ofstream(dir + "/client.tok") << client << "\n";
  std::ofstream(dir + "/worker.tok") << worker << "\n";
  const std::string addr = "10.77.0.1:50077";
  const pid_t coord = Spawn({ip, "netns", "exec", a, BISTABLE_COORDINATOR, "--listen", addr, "--data", dir + "/data",
                             "--tls-cert", dir + "/tls/server.pem", "--tls-key", dir + "/tls/server.key", "--tokens",
                             dir + "/tokens", "--job-seconds", "0.01"},
                            dir + "/coord.log");
  const pid_t work = Spawn({ip, "netns", "exec", b, BISTABLE_WORKER, "--coordinator", addr, "--tls-ca",
                            dir + "/tls/ca.pem", "--token-file", dir + "/worker.tok", "--threads", "2"},
                           dir + "/worker.log");
  const std::string spec = dir + "/spec.toml";
  std::ofstream(spec)
      << "model = \"coupled\"\n[axes]\nalpha = { linspace = [0.2, 2.0, 8] }\nomega = { linspace = [0.4, 2.4, 8] }\n"
         "[integration]\nt_end = 100.0\nt_keep = 50.0\n";
  const std::string remote =
      " --coordinator " + addr + " --tls-ca " + dir + "/tls/ca.pem --token-file " + dir + "/client.tok";
  // The client runs in namespace b (the worker's host) and reaches the coordinator over the veth link.
  auto in_b = [&](const std::string& args) {
    const std::string cmd = ip + " netns exec " + b + " " + BISTABLE_CLI + " " + args + remote + " 2>/dev/null";
    FILE* p = ::popen(cmd.c_str(), "r");
    char buf[1024];
    std::string out;
    size_t n;
    while ((n = std::fread(buf, 1, sizeof buf, p)) > 0) out.append(buf, n);
    const int rc = ::pclose(p);
    return ProcessResult{WEXITSTATUS(rc), out, ""};
  };
  ProcessResult sub{1, "", ""};
  for (int i = 0; i < 100 && sub.exit_code != 0; ++i) {  // the coordinator may still be starting
    sub = in_b("submit " + spec + " --json");
    if (sub.exit_code != 0) std::this_thread::sleep_for(std::chrono::milliseconds(100));
  }
  ASSERT_EQ(sub.exit_code, 0) << "submit over TLS from the other namespace failed";
  const std::string id = nlohmann::json::parse(sub.out)["id"];
  bool done = false;
  for (int i = 0; i < 600 && !done; ++i) {
    done = in_b("status " + id + " --json").out.find("\"state\":\"done\"") != std::string::npos;
    if (!done) std::this_thread::sleep_for(std::chrono::milliseconds(100));
  }
  EXPECT_TRUE(done) << "the sweep did not finish across namespaces";
  // Plaintext to the TLS coordinator fails.
  const int plain = std::system((ip + " netns exec " + b + " " + BISTABLE_CLI + " status " + id + " --coordinator " +
                                 addr + " --token-file " + dir + "/client.tok >/dev/null 2>&1")
                                    .c_str());
  EXPECT_NE(WEXITSTATUS(plain), 0);
  Kill(work, SIGTERM);
  Kill(coord, SIGTERM);
  cleanup();
  if (done) {
    const std::string emb = dir + "/emb";
    const ProcessResult r = Bistable("run " + spec + " --data " + emb + " --json --no-plots --quiet");
    ASSERT_EQ(r.exit_code, 0);
    ExpectSameMaps(dir + "/data/sweeps/" + id + ".h5", nlohmann::json::parse(r.out)["files"][0]);
  }
  fs::remove_all(dir);
}

TEST(Distributed, CoordinatorRefusesNonLoopbackWithoutTls) {
  const ProcessResult r{[] {
    const std::string out = ::testing::TempDir() + "/coord_nl.txt";
    const int rc =
        std::system((std::string(BISTABLE_COORDINATOR) + " --listen 0.0.0.0:0 --data /tmp/x 2>" + out).c_str());
    std::ifstream in(out);
    return ProcessResult{WEXITSTATUS(rc), "", std::string(std::istreambuf_iterator<char>(in), {})};
  }()};
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.err.find("is not a loopback address"), std::string::npos) << r.err;
}

}  // namespace
