// Coordinator overhead: lease + report round trips per second with no-op jobs (records of zeros of
// the right shape, stored durably like real ones), through gRPC on loopback with 1, 2, 4, 8
// concurrent workers, against direct in-process calls in the same run. Prints a table and ratios.
//   build/bench/bench_coordinator [JOBS=4000]
#include <atomic>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <thread>

#include <grpcpp/grpcpp.h>

#include "bistable.grpc.pb.h"
#include "server/coordinator_service.h"

namespace {

using namespace bistable;
namespace fs = std::filesystem;

// A sweep of `jobs` jobs of 8 items (a 1-D grid along alpha).
SweepSpec NoOpSpec(long jobs, int salt) {
  const std::string toml = "name = \"noop " + std::to_string(salt) + "\"\nmodel = \"coupled\"\n[axes]\nalpha = { linspace = [0.01, " +
                           std::to_string(1.0 + salt * 0.001) + ", " + std::to_string(jobs * 8) +
                           "] }\n[integration]\nt_end = 20.0\nt_keep = 10.0\n";
  return *ParseSweepSpec(toml, "noop");
}

double Direct(const std::string& dir, long jobs) {
  auto c = SweepCoordinator::Open(dir + "/direct");
  const SweepSpec spec = NoOpSpec(jobs, 0);
  (*c)->Submit(spec, 8);
  const std::vector<PointRecord> zeros(8, PointRecord{std::vector<double>(PointRecord::Size(), 0.0)});
  const auto t0 = std::chrono::steady_clock::now();
  long n = 0;
  while (auto l = (*c)->Lease("w")) (*c)->Report(l->lease_id, zeros), ++n;
  return n / std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

double OverGrpc(const std::string& dir, long jobs, int clients, int salt) {
  auto c = SweepCoordinator::Open(dir + "/grpc" + std::to_string(salt));
  CoordinatorService service(c->get(), 60);
  grpc::ServerBuilder b;
  int port = 0;
  b.AddListeningPort("127.0.0.1:0", grpc::InsecureServerCredentials(), &port);
  b.RegisterService(&service);
  auto server = b.BuildAndStart();
  (*c)->Submit(NoOpSpec(jobs, salt), 8);
  const auto channel = grpc::CreateChannel("127.0.0.1:" + std::to_string(port), grpc::InsecureChannelCredentials());
  std::atomic<long> n{0};
  const auto t0 = std::chrono::steady_clock::now();
  std::vector<std::thread> pool;
  for (int k = 0; k < clients; ++k)
    pool.emplace_back([&, k] {
      auto stub = v1::Coordinator::NewStub(channel);
      v1::ReportRequest rep;
      rep.set_record_width(static_cast<unsigned>(PointRecord::Size()));
      for (size_t i = 0; i < 8 * PointRecord::Size(); ++i) rep.add_values(0.0);
      while (true) {
        grpc::ClientContext lc;
        v1::LeaseRequest lr;
        lr.set_worker("w" + std::to_string(k));
        v1::LeaseReply lease;
        if (!stub->Lease(&lc, lr, &lease).ok() || !lease.has_job()) break;
        grpc::ClientContext rc;
        rep.set_lease_id(lease.lease_id());
        v1::ReportReply rr;
        if (stub->Report(&rc, rep, &rr).ok()) ++n;
      }
    });
  for (auto& t : pool) t.join();
  const double rate = n / std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  server->Shutdown();
  return rate;
}

}  // namespace

int main(int argc, char** argv) {
  const long jobs = argc > 1 ? std::atol(argv[1]) : 4000;
  const std::string dir = (fs::temp_directory_path() / ("bench_coord_" + std::to_string(::getpid()))).string();
  fs::remove_all(dir);
  const double direct = Direct(dir, jobs);
  std::printf("coordinator overhead, no-op jobs of 8 items (%ld jobs per run), lease + durable report round trips/s\n", jobs);
  std::printf("  direct in-process calls           %8.0f /s\n", direct);
  int salt = 1;
  for (int clients : {1, 2, 4, 8}) {
    const double r = OverGrpc(dir, jobs, clients, salt++);
    std::printf("  gRPC loopback, %d worker(s) in flight %8.0f /s   (%.2f of direct)\n", clients, r, r / direct);
  }
  fs::remove_all(dir);
  return 0;
}
