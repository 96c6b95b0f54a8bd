// Coordinator overhead: lease + report round trips per second with no-op jobs (records of zeros of
// the right shape, stored durably like real ones), through gRPC on loopback with 1, 2, 4, 8
// concurrent workers, against direct in-process calls in the same run. Prints a table and ratios.
// The rate counts until the last report is acknowledged; the sweep's publication (fold into the
// point cache, HDF5 map, index rows: a background thread) is timed separately.
// The first line says the CPU and the build's lanes (dynamics/host_lanes.h); no job computes here.
//   build/bench/bench_coordinator [JOBS=4000]
#include <atomic>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <thread>

#include <grpcpp/grpcpp.h>

#include "bistable.grpc.pb.h"
#include "dynamics/host_lanes.h"
#include "server/coordinator_service.h"

namespace {

using namespace bistable;
namespace fs = std::filesystem;

// A sweep of `jobs` jobs of 8 items (a 1-D grid along alpha).
SweepSpec NoOpSpec(long jobs, int salt) {
  const std::string toml = "name = \"noop " + std::to_string(salt) +
                           "\"\nmodel = \"coupled\"\n[axes]\nalpha = { linspace = [0.01, " +
                           std::to_string(1.0 + salt * 0.001) + ", " + std::to_string(jobs * 8) +
                           "] }\n[integration]\nt_end = 20.0\nt_keep = 10.0\n";
  return *ParseSweepSpec(toml, "noop");
}

// Seconds until the sweep's map is published, from now.
double AwaitPublished(SweepCoordinator& c, const std::string& id) {
  const auto t0 = std::chrono::steady_clock::now();
  while (true) {
    auto info = c.Info(id);
    if (!info.ok() || IsFinal(info->state)) break;
    std::this_thread::sleep_for(std::chrono::milliseconds(2));
  }
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

double g_publish_seconds = 0;

double Direct(const std::string& dir, long jobs) {
  auto c = SweepCoordinator::Open(dir + "/direct");
  const SweepSpec spec = NoOpSpec(jobs, 0);
  (*c)->Submit(spec, 8);
  const std::vector<PointRecord> zeros(8, PointRecord{std::vector<double>(PointRecord::Size(), 0.0)});
  const auto t0 = std::chrono::steady_clock::now();
  long n = 0;
  while (auto l = (*c)->Lease("w")) (*c)->Report(l->lease_id, zeros), ++n;
  const double rate = n / std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  g_publish_seconds = AwaitPublished(**c, spec.Id());
  return rate;
}

// A coordinator on a fresh data dir served on a loopback port, with a channel to it.
struct LoopbackServer {
  std::unique_ptr<SweepCoordinator> coordinator;
  std::unique_ptr<CoordinatorService> service;
  std::unique_ptr<grpc::Server> server;
  std::shared_ptr<grpc::Channel> channel;
  explicit LoopbackServer(const std::string& data) {
    coordinator = std::move(SweepCoordinator::Open(data).value());
    service = std::make_unique<CoordinatorService>(coordinator.get(), 60);
    grpc::ServerBuilder b;
    int port = 0;
    b.AddListeningPort("127.0.0.1:0", grpc::InsecureServerCredentials(), &port);
    b.RegisterService(service.get());
    ConfigureServerBuilder(b);
    server = b.BuildAndStart();
    channel = grpc::CreateChannel("127.0.0.1:" + std::to_string(port), grpc::InsecureChannelCredentials());
  }
  ~LoopbackServer() { server->Shutdown(); }
};

// The transport's floor: pairs of near-empty calls (ListWorkers) through the same server and channel.
double EmptyPairs(const std::string& dir, long pairs, int clients) {
  LoopbackServer srv(dir + "/empty");
  const auto& channel = srv.channel;
  std::atomic<long> n{0};
  const auto t0 = std::chrono::steady_clock::now();
  std::vector<std::thread> pool;
  for (int k = 0; k < clients; ++k)
    pool.emplace_back([&] {
      auto stub = v1::Coordinator::NewStub(channel);
      while (n.fetch_add(1) < pairs)
        for (int call = 0; call < 2; ++call) {
          grpc::ClientContext ctx;
          v1::ListWorkersReply r;
          stub->ListWorkers(&ctx, v1::ListWorkersRequest(), &r);
        }
    });
  for (auto& t : pool) t.join();
  return pairs / std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

double OverGrpc(const std::string& dir, long jobs, int clients, int salt, bool combined) {
  LoopbackServer srv(dir + "/grpc" + std::to_string(salt));
  const SweepSpec spec = NoOpSpec(jobs, salt);
  srv.coordinator->Submit(spec, 8);
  const auto& channel = srv.channel;
  std::atomic<long> n{0};
  const auto t0 = std::chrono::steady_clock::now();
  std::vector<std::thread> pool;
  for (int k = 0; k < clients; ++k)
    pool.emplace_back([&, k] {
      auto stub = v1::Coordinator::NewStub(channel);
      const std::string worker =
          std::string("w").append(std::to_string(k));  // not "w" + ...: a GCC 12 -Wrestrict false positive
      v1::ReportRequest rep;
      rep.set_record_width(static_cast<unsigned>(PointRecord::Size()));
      rep.set_catalog_hash(CatalogHash());
      for (size_t i = 0; i < 8 * PointRecord::Size(); ++i) rep.add_values(0.0);
      if (combined) rep.set_lease_next_for(worker);
      v1::LeaseReply lease;
      while (true) {
        if (!lease.has_job()) {  // the worker's loop: lease only when the last report brought nothing
          grpc::ClientContext lc;
          v1::LeaseRequest lr;
          lr.set_worker(worker);
          if (!stub->Lease(&lc, lr, &lease).ok() || !lease.has_job()) break;
        }
        grpc::ClientContext rc;
        rep.set_lease_id(lease.lease_id());
        v1::ReportReply rr;
        if (stub->Report(&rc, rep, &rr).ok()) ++n;
        lease = rr.next();
      }
    });
  for (auto& t : pool) t.join();
  const double rate = n / std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  g_publish_seconds = AwaitPublished(*srv.coordinator, spec.Id());
  return rate;
}

}  // namespace

int main(int argc, char** argv) {
  const long jobs = argc > 1 ? std::atol(argv[1]) : 4000;
  std::printf("%s\n", HostLanesLine().c_str());
  std::fflush(stdout);
  const std::string dir = (fs::temp_directory_path() / ("bench_coord_" + std::to_string(::getpid()))).string();
  fs::remove_all(dir);
  const double direct = Direct(dir, jobs);
  std::printf("coordinator overhead, no-op jobs of 8 items (%ld jobs per run), lease + durable report round trips/s\n",
              jobs);
  std::printf("  direct in-process calls           %8.0f /s   (then %.2f s to publish the %ld-item map)\n", direct,
              g_publish_seconds, jobs * 8);
  if (argc > 2 && std::string(argv[2]) == "--direct-only") return fs::remove_all(dir), 0;
  for (int clients : {1, 8})
    std::printf("  gRPC floor: 2 empty calls, %d in flight %8.0f /s\n", clients, EmptyPairs(dir, jobs, clients));
  int salt = 1;
  for (bool combined : {false, true})
    for (int clients : {1, 2, 4, 8}) {
      const double r = OverGrpc(dir, jobs, clients, salt++, combined);
      std::printf("  gRPC loopback, %-22s %d worker(s) in flight %8.0f /s   (%.2f of direct; publication %.2f s)\n",
                  combined ? "report+lease in 1 call," : "lease, report: 2 calls,", clients, r, r / direct,
                  g_publish_seconds);
    }
  fs::remove_all(dir);
  return 0;
}
