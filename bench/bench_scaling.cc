// How far one coordinator goes (issue 12): many fake workers on loopback against one coordinator
// served over gRPC, each a pull loop that leases a job of the paper map's size, "computes" it by
// sleeping (no CPU), and reports records of that job's real size (one real job's records of the spec,
// computed once, stored durably like real ones), leasing its next job in the same call. The demand is N x job items /
// compute time items per second; the table shows what the coordinator delivers as N grows, and where it saturates.
//   build/bench/bench_scaling [SPEC=examples/paper_fig8_frf.toml] [--compute-ms 50] [--seconds 3]
//                             [--max-workers 256] [--lease-batch K] [--external build/server/bistable-coordinator]
// --external BIN: the real coordinator process, pinned to one CPU, the fake workers to the others.
// --lease-batch K: leases merge up to K queued jobs (one round trip and one stored report for all: the
// first step that lifts the ceiling, docs/scaling.md) and the same ladder runs again, so both ceilings
// come from one run. Ratios are within the run. The first line says the CPU and the build's lanes
// (dynamics/host_lanes.h): the payload job is computed, and sized, at that width (JobItems).
#include <sched.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <thread>

#include <grpcpp/grpcpp.h>

#include "base/file.h"
#include "base/limits.h"
#include "bistable.grpc.pb.h"
#include "dynamics/host_lanes.h"
#include "engine/evaluate.h"
#include "server/coordinator_service.h"

namespace {

using namespace bistable;
std::string g_spec_text;
// One real job's records of the spec (computed once): what every fake report carries, so the bytes
// stored (and how well they compress) are those of real results, not zeros.
std::vector<double> g_payload;
namespace fs = std::filesystem;

// --external BIN: the coordinator is the real bistable-coordinator process, pinned to the first CPU of
// this process's mask, and the fake workers (this process) to the others: the ceiling is then the
// coordinator's own, not shared with the fake workers' encoding.
std::string g_external;
cpu_set_t g_coordinator_cpus, g_worker_cpus;

struct Loopback {
  std::unique_ptr<SweepCoordinator> coordinator;
  std::unique_ptr<CoordinatorService> service;
  std::unique_ptr<grpc::Server> server;
  pid_t child = -1;
  std::vector<std::shared_ptr<grpc::Channel>> channels;
  Loopback(const std::string& data, int n_channels) {
    int port = 0;
    if (!g_external.empty()) {
      fs::create_directories(data);
      const std::string log = data + "/coordinator.out";
      std::fflush(nullptr);
      child = ::fork();
      if (child == 0) {
        sched_setaffinity(0, sizeof g_coordinator_cpus, &g_coordinator_cpus);
        if (!std::freopen(log.c_str(), "w", stdout) || !std::freopen((log + ".err").c_str(), "w", stderr)) ::_exit(126);
        const std::string d = data + "/data";
        ::execl(g_external.c_str(), g_external.c_str(), "--listen", "127.0.0.1:0", "--data", d.c_str(),
                "--lease-seconds", "600", "--log-level", "warn", static_cast<char*>(nullptr));
        ::_exit(127);
      }
      for (int i = 0; i < 400 && port == 0; ++i) {
        std::this_thread::sleep_for(std::chrono::milliseconds(25));
        std::ifstream in(log);
        std::string line;
        if (std::getline(in, line) && line.rfind("listening on ", 0) == 0)
          port = std::atoi(line.substr(line.rfind(':') + 1).c_str());
      }
      if (port == 0) {
        std::fprintf(stderr, "error: %s did not start\n", g_external.c_str());
        std::exit(3);
      }
    } else {
      coordinator =
          std::move(SweepCoordinator::Open(data, {.lease_seconds = 600, .resume = false, .log = false}).value());
      service = std::make_unique<CoordinatorService>(coordinator.get(), 600);
      grpc::ServerBuilder b;
      b.AddListeningPort("127.0.0.1:0", grpc::InsecureServerCredentials(), &port);
      b.RegisterService(service.get());
      ConfigureServerBuilder(b);
      server = b.BuildAndStart();
    }
    for (int i = 0; i < n_channels; ++i) {  // several connections, as separate worker hosts would have
      grpc::ChannelArguments args;
      args.SetInt("bistable.channel", i);  // distinct args: distinct subchannels
      args.SetMaxReceiveMessageSize(64 << 20);
      channels.push_back(
          grpc::CreateCustomChannel("127.0.0.1:" + std::to_string(port), grpc::InsecureChannelCredentials(), args));
    }
  }
  // Submits the sweep: in-process with `job_items` per job; external with the coordinator's own sizing.
  void Submit(const SweepSpec& spec, long job_items) {
    if (coordinator) {
      if (auto p = coordinator->Submit(spec, job_items); !p.ok()) std::exit(2);
      return;
    }
    auto stub = v1::Coordinator::NewStub(channels[0]);
    grpc::ClientContext ctx;
    ctx.set_deadline(std::chrono::system_clock::now() + std::chrono::seconds(600));
    v1::SubmitRequest req;
    req.set_spec_toml(spec.source);
    v1::SubmitReply rep;
    if (const grpc::Status st = stub->Submit(&ctx, req, &rep); !st.ok()) {
      std::fprintf(stderr, "error: submit: %s\n", st.error_message().c_str());
      std::exit(2);
    }
  }
  void Stop() {
    if (coordinator) coordinator->Stop();
  }
  ~Loopback() {
    if (server) server->Shutdown(std::chrono::system_clock::now() + std::chrono::seconds(1));
    if (child > 0) {
      ::kill(child, SIGTERM);
      int st = 0;
      ::waitpid(child, &st, 0);
    }
  }
};

struct Result {
  double reports_per_s = 0, items_per_s = 0, mean_report_ms = 0;
  long reports = 0;
};

// One rung of the ladder: `workers` fake pull loops for `seconds`.
Result Run(const std::string& dir, const std::string& tag, long job_items, bool turning_points, int workers,
           double compute_s, double seconds, int lease_batch) {
  Loopback lb(dir + "/" + tag, std::min(workers, 16));
  // A no-op sweep big enough not to run dry: job_items alphas x `jobs` omegas.
  // Sized to the demand (planning costs ~5 us per item): enough for `seconds` at full demand, at most
  // the sweep limit; a run that drains it says so.
  const double demand_items = workers * job_items / compute_s * seconds * 1.2;
  const long jobs =
      std::clamp<long>(static_cast<long>(demand_items / job_items) + 1, 64, limits::kMaxSweepItems / job_items);
  // External: the paper spec's own settings (the coordinator sizes its jobs from them) on a grid of
  // job_items x `jobs` points; in-process: a cheap spec with `job_items` given.
  std::string toml = "name = \"scaling " + tag + "\"\nmodel = \"coupled\"\n[axes]\nalpha = { linspace = [0.01, 2.0, " +
                     std::to_string(job_items) + "] }\nomega = { linspace = [0.1, 3.0, " + std::to_string(jobs) +
                     "] }\n[integration]\nt_end = 20.0\nt_keep = 10.0\n" +
                     (turning_points ? "[metrics]\nturning_points = true\n" : "");
  if (!g_external.empty()) {
    toml = g_spec_text;
    const size_t a = toml.find("\nalpha"), o = toml.find("\nomega");
    if (a == std::string::npos || o == std::string::npos) {
      std::fprintf(stderr, "error: --external needs a spec with alpha and omega axes\n");
      std::exit(1);
    }
    auto line_end = [&](size_t at) { return toml.find('\n', at + 1); };
    toml.replace(o, line_end(o) - o, "\nomega = { linspace = [0.015, 3.0, " + std::to_string(jobs) + "] }");
    toml.replace(a, line_end(a) - a, "\nalpha = { linspace = [0.015, 3.0, " + std::to_string(job_items) + "] }");
    if (const size_t nm = toml.find("\nname = "); nm != std::string::npos)  // a new sweep id per rung
      toml.replace(nm, line_end(nm) - nm, "\nname = \"scaling " + tag + "\"");
  }
  auto spec = ParseSweepSpec(toml, "scaling");
  if (!spec.ok()) {
    std::fprintf(stderr, "%s\n", spec.status().ToString().c_str());
    std::exit(1);
  }
  const auto plan0 = std::chrono::steady_clock::now();
  lb.Submit(*spec, job_items);
  std::fprintf(stderr, "planned %ld items in %.1f s; measuring\n", jobs * job_items,
               std::chrono::duration<double>(std::chrono::steady_clock::now() - plan0).count());
  const size_t width = PointRecord::Size(turning_points);
  std::atomic<long> reports{0}, items{0};
  std::atomic<double> report_ms{0};
  std::atomic<bool> stop{false}, dry{false};
  std::vector<std::thread> pool;
  const auto t0 = std::chrono::steady_clock::now();
  for (int k = 0; k < workers; ++k)
    pool.emplace_back([&, k] {
      auto stub = v1::Coordinator::NewStub(lb.channels[k % lb.channels.size()]);
      const std::string name = "fake" + std::to_string(k);
      v1::ReportRequest rep;
      rep.set_record_width(static_cast<unsigned>(width));
      rep.set_catalog_hash(CatalogHash());
      rep.set_lease_next_for(name);
      std::vector<v1::LeaseReply> held;  // jobs in hand, in order
      while (!stop) {
        if (held.empty()) {
          grpc::ClientContext lc;
          v1::LeaseRequest lr;
          lr.set_worker(name);
          lr.set_max_jobs(lease_batch);
          v1::LeaseReply lease;
          if (!stub->Lease(&lc, lr, &lease).ok() || !lease.has_job()) {
            if (!stop) dry = true;
            break;
          }
          held.push_back(lease);
        }
        v1::LeaseReply job = std::move(held.front());
        held.erase(held.begin());
        const long n = job.points_size();
        // The computation: compute_s per job's worth of items (a merged lease takes as long as its jobs).
        std::this_thread::sleep_for(std::chrono::duration<double>(compute_s * n / job_items));
        rep.set_lease_id(job.lease_id());
        rep.mutable_values()->Clear();
        for (long k = 0; k < n; ++k) {
          const double* rec = g_payload.data() + (k % (g_payload.size() / width)) * width;
          rep.mutable_values()->Add(rec, rec + width);
        }
        rep.set_lease_next_for(held.empty() ? name : "");  // ask for the next job only when out of work
        rep.set_next_max_jobs(lease_batch);
        grpc::ClientContext rc;
        v1::ReportReply rr;
        const auto r0 = std::chrono::steady_clock::now();
        const bool ok = stub->Report(&rc, rep, &rr).ok();
        const double ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - r0).count();
        if (!ok) break;
        if (std::chrono::steady_clock::now() - t0 < std::chrono::duration<double>(seconds)) {
          ++reports;
          items += n;
          report_ms = report_ms + ms;
        }
        if (rr.has_next() && rr.next().has_job()) {
          held.push_back(rr.next());
        }
      }
    });
  std::this_thread::sleep_for(std::chrono::duration<double>(seconds));
  stop = true;
  lb.Stop();
  for (auto& t : pool) t.join();
  Result r;
  r.reports = reports;
  r.reports_per_s = reports / seconds;
  r.items_per_s = items / seconds;
  r.mean_report_ms = reports ? report_ms / reports : 0;
  if (dry)
    std::fprintf(stderr, "warning: %d workers drained the sweep before %.1f s: the rate is a lower bound\n", workers,
                 seconds);
  return r;
}

}  // namespace

int main(int argc, char** argv) {
  std::string spec_path = "examples/paper_fig8_frf.toml";
  std::printf("%s\n", HostLanesLine().c_str());
  std::fflush(stdout);
  double compute_ms = 50, seconds = 3;
  int max_workers = 256, min_workers = 1, lease_batch = 0;
  long job_items_override = 0;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--compute-ms" && i + 1 < argc)
      compute_ms = std::atof(argv[++i]);
    else if (a == "--seconds" && i + 1 < argc)
      seconds = std::atof(argv[++i]);
    else if (a == "--max-workers" && i + 1 < argc)
      max_workers = std::atoi(argv[++i]);
    else if (a == "--lease-batch" && i + 1 < argc)
      lease_batch = std::atoi(argv[++i]);
    else if (a == "--min-workers" && i + 1 < argc)
      min_workers = std::atoi(argv[++i]);
    else if (a == "--job-items" && i + 1 < argc)
      job_items_override = std::atol(argv[++i]);
    else if (a == "--external" && i + 1 < argc)
      g_external = argv[++i];
    else
      spec_path = a;
  }
  auto text = ReadTextFile(spec_path, "spec");
  auto spec = text.ok() ? ParseSweepSpec(*text, spec_path) : StatusOr<SweepSpec>(text.status());
  if (text.ok()) g_spec_text = *text;
  if (!g_external.empty()) {  // the first CPU of our mask for the coordinator, the rest for the fake workers
    cpu_set_t mine;
    sched_getaffinity(0, sizeof mine, &mine);
    CPU_ZERO(&g_coordinator_cpus);
    g_worker_cpus = mine;
    for (int c = 0; c < CPU_SETSIZE; ++c)
      if (CPU_ISSET(c, &mine)) {
        CPU_SET(c, &g_coordinator_cpus);
        CPU_CLR(c, &g_worker_cpus);
        break;
      }
    if (CPU_COUNT(&g_worker_cpus) == 0) {
      std::fprintf(stderr, "error: --external needs at least 2 CPUs\n");
      return 1;
    }
    sched_setaffinity(0, sizeof g_worker_cpus, &g_worker_cpus);
    std::printf("coordinator process (%s) on 1 CPU, fake workers on %d\n", g_external.c_str(),
                CPU_COUNT(&g_worker_cpus));
  }
  if (!spec.ok()) {
    std::fprintf(stderr, "error: %s\n", spec.status().ToString().c_str());
    return 1;
  }
  constexpr double kJobSeconds = 2.0;  // the coordinator's default --job-seconds
  const long job_items = job_items_override > 0 ? job_items_override : JobItems(*spec, kJobSeconds, 64);
  const bool tp = spec->base.metrics.turning_points;
  const size_t width = PointRecord::Size(tp);
  {
    std::vector<WorkItem> items;
    for (long k = 0; k < std::min(job_items, spec->points()); ++k) items.push_back({(k * 7919) % spec->points(), 0});
    const auto t0 = std::chrono::steady_clock::now();
    for (const PointRecord& r : ComputeItems(*spec, items)) g_payload.insert(g_payload.end(), r.v.begin(), r.v.end());
    std::fprintf(stderr, "computed the payload (%zu real records) in %.1f s\n", items.size(),
                 std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());
  }
  std::printf(
      "one coordinator, fake workers on loopback: jobs of %s (%ld items, reports of %.0f kB), compute %.0f ms per "
      "job\n",
      spec_path.c_str(), job_items, job_items * width * 8 / 1024.0, compute_ms);
  const std::string dir = (fs::temp_directory_path() / ("bench_scaling_" + std::to_string(::getpid()))).string();
  fs::remove_all(dir);
  std::vector<int> batches = {1};
  if (lease_batch > 1) batches.push_back(lease_batch);
  double ceiling[2] = {0, 0}, ceiling_items[2] = {0, 0};
  int saturated_at[2] = {0, 0};
  for (size_t b = 0; b < batches.size(); ++b) {
    std::printf("\nleases of up to %d merged job(s)\n", batches[b]);
    std::printf(
        "| fake workers | demand items/s | delivered items/s | delivered/demand | reports/s | mean report ms "
        "|\n|---|---|---|---|---|---|\n");
    for (int w = min_workers; w <= max_workers; w *= 2) {
      const Result r = Run(dir, std::to_string(b) + "-" + std::to_string(w), job_items, tp, w, compute_ms / 1000,
                           seconds, batches[b]);
      const double demand = w * job_items / (compute_ms / 1000);
      std::printf("| %d | %.0f | %.0f | %.2f | %.0f | %.1f |\n", w, demand, r.items_per_s, r.items_per_s / demand,
                  r.reports_per_s, r.mean_report_ms);
      std::fflush(stdout);
      ceiling[b] = std::max(ceiling[b], r.reports_per_s);
      ceiling_items[b] = std::max(ceiling_items[b], r.items_per_s);
      if (!saturated_at[b] && r.items_per_s < 0.8 * demand) saturated_at[b] = w;
    }
    std::printf("ceiling %.0f reports/s, %.0f items/s; saturated (< 0.8 of demand) at %d fake workers\n", ceiling[b],
                ceiling_items[b], saturated_at[b]);
    std::printf("at %.0f s of compute per %ld-item job, one coordinator feeds about %.0f pull loops (cores)\n",
                kJobSeconds, job_items, ceiling_items[b] / job_items * kJobSeconds);
  }
  if (batches.size() == 2)
    std::printf("\nitems/s ceiling with leases of up to %d merged jobs / single-job leases: %.2f\n", batches[1],
                ceiling_items[1] / ceiling_items[0]);
  fs::remove_all(dir);
  return 0;
}
