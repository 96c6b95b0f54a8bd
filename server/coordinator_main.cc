// bistable-coordinator: serves sweeps of one data directory to clients and workers over gRPC.
#include <csignal>
#include <iostream>
#include <thread>

#include <CLI/CLI.hpp>
#include <grpcpp/grpcpp.h>

#include "server/coordinator_service.h"

namespace {

std::atomic<bool> g_stop{false};
extern "C" void OnSignal(int) { g_stop.store(true); }

bool IsLoopback(const std::string& addr) {
  return addr.rfind("127.", 0) == 0 || addr.rfind("localhost:", 0) == 0 || addr.rfind("[::1]:", 0) == 0 ||
         addr.rfind("unix:", 0) == 0;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"bistable-coordinator: serves sweeps to clients and workers over gRPC"};
  std::string listen = "127.0.0.1:50051", data = "bistable-data";
  double lease_seconds = 60, job_seconds = 2.0;
  app.add_option("--listen", listen, "address to listen on (loopback unless TLS and tokens are configured); port 0 picks one")
      ->capture_default_str();
  app.add_option("--data", data, "data directory (index.sqlite, sweeps/)")->capture_default_str();
  app.add_option("--lease-seconds", lease_seconds, "lease period: jobs not reported or extended within it are requeued")
      ->capture_default_str();
  app.add_option("--job-seconds", job_seconds, "work per job on one core, seconds (jobs are blocks of points)")
      ->capture_default_str();
  CLI11_PARSE(app, argc, argv);
  if (!IsLoopback(listen)) {
    std::cerr << "error: invalid argument (listen: " << listen
              << " is not a loopback address; serving other hosts requires TLS and tokens, which this build does not "
                 "offer yet)\n";
    return 2;
  }
  if (!(lease_seconds > 0)) {
    std::cerr << "error: invalid argument (lease-seconds: lease-seconds = " << lease_seconds << " violates lease-seconds > 0)\n";
    return 2;
  }
  auto coord = bistable::SweepCoordinator::Open(data, {.lease_seconds = lease_seconds, .resume = true});
  if (!coord.ok()) {
    std::cerr << "error: " << coord.status().ToString() << "\n";
    return 2;
  }
  bistable::CoordinatorService service(coord->get(), lease_seconds, job_seconds);
  grpc::ServerBuilder builder;
  int port = 0;
  builder.AddListeningPort(listen, grpc::InsecureServerCredentials(), &port);
  builder.RegisterService(&service);
  builder.SetMaxReceiveMessageSize(64 << 20);
  std::unique_ptr<grpc::Server> server = builder.BuildAndStart();
  if (!server || port == 0) {
    std::cerr << "error: i/o error (listen: cannot listen on " << listen << ")\n";
    return 2;
  }
  const std::string host = listen.substr(0, listen.rfind(':'));
  std::cout << "listening on " << host << ":" << port << std::endl;
  std::signal(SIGINT, OnSignal);
  std::signal(SIGTERM, OnSignal);
  while (!g_stop.load()) std::this_thread::sleep_for(std::chrono::milliseconds(100));
  service.Shutdown();
  server->Shutdown(std::chrono::system_clock::now() + std::chrono::seconds(2));
  return 0;
}
