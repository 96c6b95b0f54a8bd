// Hostile input over the wire (issue 10): one real coordinator process on loopback, attacked through
// a real gRPC client, one case per row. Every row must get its refusal (status code and the field or
// bound named) while the coordinator stays up; the last rows check that it is still up, that its
// memory is back within 20 % of where it was before the attacks, and that a sweep run through the
// storm (cancel, resubmit, stale and forged reports) publishes the embedded map bit for bit.
// The whole table runs in one process against one coordinator (one ctest entry).
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <functional>
#include <mutex>
#include <set>
#include <sstream>
#include <thread>

#include <grpcpp/grpcpp.h>
#include <gtest/gtest.h>

#include "base/limits.h"
#include "bistable.grpc.pb.h"
#include "engine/evaluate.h"
#include "engine/sweep_spec.h"
#include "storage/index_db.h"
#include "storage/map_file.h"
#include "tests/http_client.h"
#include "tests/map_compare.h"
#include "tests/process_util.h"

namespace {

namespace fs = std::filesystem;
namespace v1 = bistable::v1;
using Clock = std::chrono::steady_clock;

using bistable_test::ReadText;
pid_t Spawn(const std::vector<std::string>& argv, const std::string& out_file) {
  return bistable_test::SpawnLogged(argv, out_file);
}
int Wait(pid_t pid, double seconds) { return bistable_test::WaitExitFor(pid, seconds); }
std::string ReadFile(const std::string& path) { return ReadText(path); }

std::pair<pid_t, std::string> StartCoordinator(const std::string& data, const std::string& log,
                                               const std::vector<std::string>& extra = {}) {
  std::vector<std::string> argv = {BISTABLE_COORDINATOR, "--listen", "127.0.0.1:0",   "--data", data,
                                   "--lease-seconds",    "5",        "--job-seconds", "0.01"};
  argv.insert(argv.end(), extra.begin(), extra.end());
  fs::remove(log);  // a previous run's "listening on" must not be read
  const pid_t pid = Spawn(argv, log);
  for (int i = 0; i < 400; ++i) {
    std::istringstream in(ReadFile(log));
    std::string line;
    if (std::getline(in, line) && line.rfind("listening on ", 0) == 0) return {pid, line.substr(13)};
    std::this_thread::sleep_for(std::chrono::milliseconds(25));
  }
  return {pid, ""};
}

long RssKb(pid_t pid) {
  std::istringstream in(ReadFile("/proc/" + std::to_string(pid) + "/status"));
  std::string line;
  while (std::getline(in, line))
    if (line.rfind("VmRSS:", 0) == 0) return std::stol(line.substr(6));
  return -1;
}

bool Alive(pid_t pid) { return ::kill(pid, 0) == 0 && ::waitpid(pid, nullptr, WNOHANG) == 0; }

std::string Spec(const std::string& axes, const std::string& extra = "") {
  return "model = \"coupled\"\n" + extra + "\n[axes]\n" + axes + "\n[integration]\nt_end = 40.0\nt_keep = 20.0\n";
}

// The suite's shared state: one coordinator for every row.
struct World {
  std::string dir, data, addr;
  pid_t coord = -1;
  long rss_before = 0;
  int metrics_port = -1;     // the coordinator's --metrics port
  double heap_before = 0;    // its bistable_heap_in_use_bytes after the warm-up
  std::string unheld_id;     // a sweep in the index that this coordinator does not hold
  std::string published_id;  // the warm-up sweep: done, with a map
  std::unique_ptr<v1::Coordinator::Stub> stub;
};
World* g = nullptr;

std::unique_ptr<grpc::ClientContext> Ctx(double seconds = 30) {
  auto c = std::make_unique<grpc::ClientContext>();
  c->set_deadline(std::chrono::system_clock::now() + std::chrono::milliseconds(static_cast<long>(seconds * 1000)));
  return c;
}

grpc::Status Submit(const std::string& toml, v1::SubmitReply* rep = nullptr, const std::string& origin = "") {
  v1::SubmitRequest req;
  req.set_spec_toml(toml);
  req.set_origin(origin);
  v1::SubmitReply r;
  return g->stub->Submit(Ctx().get(), req, rep ? rep : &r);
}

grpc::Status Cancel(const std::string& id) {
  v1::CancelRequest req;
  req.set_id(id);
  v1::CancelReply rep;
  return g->stub->Cancel(Ctx().get(), req, &rep);
}

grpc::Status GetStatus(const std::string& id, v1::SweepStatus* rep = nullptr) {
  v1::StatusRequest req;
  req.set_id(id);
  v1::SweepStatus r;
  return g->stub->GetStatus(Ctx().get(), req, rep ? rep : &r);
}

v1::LeaseReply Lease(const std::string& worker = "hostile-test") {
  v1::LeaseRequest req;
  req.set_worker(worker);
  v1::LeaseReply rep;
  EXPECT_TRUE(g->stub->Lease(Ctx().get(), req, &rep).ok());
  return rep;
}

grpc::Status Report(const std::string& lease, uint32_t width, const std::vector<double>& values,
                    uint64_t catalog_hash = bistable::CatalogHash()) {
  v1::ReportRequest req;
  req.set_lease_id(lease);
  req.set_record_width(width);
  req.set_catalog_hash(catalog_hash);
  req.mutable_values()->Add(values.begin(), values.end());
  v1::ReportReply rep;
  return g->stub->Report(Ctx().get(), req, &rep);
}

// The true records of a lease (this test computes them like a worker would).
std::vector<double> Honest(const v1::LeaseReply& l) {
  auto spec = bistable::ParseSweepSpec(l.spec_toml(), "lease");
  EXPECT_TRUE(spec.ok());
  std::vector<bistable::WorkItem> items;
  for (int i = 0; i < l.points_size(); ++i) items.push_back({l.points(i), l.ics(i)});
  std::vector<double> flat;
  for (const auto& r : bistable::ComputeItems(*spec, items)) flat.insert(flat.end(), r.v.begin(), r.v.end());
  return flat;
}

const uint32_t kWidth =
    static_cast<uint32_t>(bistable::PointRecord::Size(false));  // metrics + 10 peak frequencies + 10 amplitudes

// A row: what is sent and what must come back. Returns "" when the row holds, else what went wrong.
struct Row {
  const char* name;
  std::function<std::string()> run;
};

std::string Expect(const grpc::Status& st, grpc::StatusCode code, const std::string& fragment = "") {
  std::ostringstream os;
  if (st.error_code() != code)
    os << "status " << st.error_code() << " (want " << code << "): " << st.error_message();
  else if (!fragment.empty() && st.error_message().find(fragment) == std::string::npos)
    os << "message lacks '" << fragment << "': " << st.error_message();
  return os.str();
}

template <class F>
std::string Within(double seconds, F f) {
  const auto t0 = Clock::now();
  std::string r = f();
  const double took = std::chrono::duration<double>(Clock::now() - t0).count();
  if (r.empty() && took > seconds) r = "took " + std::to_string(took) + " s (bound " + std::to_string(seconds) + " s)";
  return r;
}

std::string Lin(const char* axis, const std::string& count) {
  return std::string(axis) + " = { linspace = [0.1, 3.0, " + count + "] }\n";
}

// After every row: up, answering, memory back within 20 % of the baseline, and a sweep run through
// the coordinator by a real worker process equals the embedded run bit for bit. (The last row.)
void AfterTheStorm() {
  ASSERT_TRUE(Alive(g->coord));
  ASSERT_TRUE(GetStatus(g->unheld_id).ok());
  // Two questions. Did anything leak? The heap in use (malloc's own count, scraped from /metrics) must
  // come back within 20 % + 512 KiB of the baseline once the rows' connection is closed. Does the
  // process keep what the storm made it allocate? RSS must come back within 24 MB of the baseline —
  // below any one of the storm's 60 MB requests. RSS alone cannot answer the first: freed fragments
  // malloc keeps in its arenas (malloc_trim every few seconds gives back what it can) stay in RSS, and
  // how many depends on how the threads interleaved. Measured (2026-11-23): with the connection open,
  // heap in use after the rows was 2.6–7.8 MB against 1.85 MB (the connection's buffers, sized by the
  // largest messages: +27 % RSS once, which failed the old RSS-only check); closed, 2.04–2.12 MB.
  const auto heap = [] {
    const auto m = bistable_test::ParseMetrics(bistable_test::HttpRequest(g->metrics_port, "/metrics").body);
    const auto it = m.find("bistable_heap_in_use_bytes");
    return it == m.end() ? -1.0 : it->second;
  };
  // The rows' connection goes first: what the server holds for a connection (HTTP/2 and TCP read
  // buffers grown for the largest messages it carried) is freed with it.
  g->stub.reset();
  std::this_thread::sleep_for(std::chrono::milliseconds(500));
  g->stub = v1::Coordinator::NewStub(grpc::CreateChannel(g->addr, grpc::InsecureChannelCredentials()));
  const double heap_bound = g->heap_before * 1.2 + (512 << 10);
  const long rss_bound = g->rss_before + 24 * 1024;
  long rss = RssKb(g->coord);
  double in_use = heap();
  for (int i = 0; i < 150 && (rss > rss_bound || in_use > heap_bound); ++i) {
    std::this_thread::sleep_for(std::chrono::milliseconds(200));
    rss = RssKb(g->coord), in_use = heap();
  }
  std::printf(
      "  coordinator memory: RSS %ld kB before the rows, %ld kB after; heap in use %.0f kB before, %.0f kB after\n",
      g->rss_before, rss, g->heap_before / 1024, in_use / 1024);
  if (std::getenv("HOSTILE_DEBUG"))
    std::printf("%s\n%s\n", ReadFile("/proc/" + std::to_string(g->coord) + "/status").c_str(),
                ReadFile("/proc/" + std::to_string(g->coord) + "/smaps_rollup").c_str());
  EXPECT_GT(in_use, 0) << "no bistable_heap_in_use_bytes on /metrics";
  EXPECT_LE(in_use, heap_bound) << "heap in use grew by more than 20 % + 512 KiB: a leak";
  EXPECT_LE(rss, rss_bound) << "RSS stayed more than 24 MB above the baseline";
  // A sweep through the service, drained by a real worker.
  const std::string toml = Spec("alpha = { linspace = [0.2, 2.6, 7] }\nomega = { linspace = [0.4, 2.0, 6] }\n",
                                "name = \"after the storm\"");
  std::ofstream(g->dir + "/after.toml") << toml;
  v1::SubmitReply sub;
  ASSERT_TRUE(Submit(toml, &sub).ok());
  const pid_t worker =
      Spawn({BISTABLE_WORKER, "--coordinator", g->addr, "--threads", "1", "--name", "honest"}, g->dir + "/worker.log");
  v1::SweepStatus st;
  for (int i = 0; i < 600 && !(GetStatus(sub.id(), &st).ok() && st.state() == "done"); ++i)
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
  ::kill(worker, SIGTERM);
  Wait(worker, 20);
  ASSERT_EQ(st.state(), "done");
  const pid_t run =
      Spawn({BISTABLE_CLI, "run", g->dir + "/after.toml", "--data", g->dir + "/embedded", "--no-plots", "--quiet"},
            g->dir + "/run.log");
  ASSERT_EQ(Wait(run, 120), 0) << ReadFile(g->dir + "/run.log.err");
  bistable_test::ExpectSameMaps(g->data + "/" + st.file(), g->dir + "/embedded/sweeps/" + sub.id() + ".h5");
}

std::string AfterTheStormRow() {
  AfterTheStorm();
  return ::testing::Test::HasFailure() ? "see the failures above" : "";
}

const std::vector<Row>& Rows() {
  static const std::vector<Row> kRows = {
      // --- Checked arithmetic and limits in specs --------------------------------------------------
      {"GridProductOverflow_2e22x2e22x2e20",
       [] {
         return Within(2, [] {
           return Expect(Submit(Spec(Lin("alpha", "4194304") + Lin("omega", "4194304") + Lin("eta", "1048576"))),
                         grpc::StatusCode::INVALID_ARGUMENT, "axes");
         });
       }},
      {"AxisCount2e63",
       [] {
         return Expect(Submit(Spec(Lin("alpha", "9223372036854775807"))), grpc::StatusCode::INVALID_ARGUMENT, "count");
       }},
      {"SevenAxesOf1e7ValuesFailFast",
       [] {
         std::string axes;
         for (const char* a : {"alpha", "omega", "eta", "eta_r", "lambda", "phi", "eps"}) axes += Lin(a, "10000000");
         return Within(2, [&] { return Expect(Submit(Spec(axes)), grpc::StatusCode::INVALID_ARGUMENT, "1048576"); });
       }},
      {"GridJustOverTheItemLimit",
       [] {
         return Expect(Submit(Spec(Lin("alpha", "2049") + Lin("omega", "2048"))), grpc::StatusCode::INVALID_ARGUMENT,
                       "4194304");
       }},
      {"IntegerNotNarrowed_max_period_4294967297",
       [] {
         return Expect(Submit(Spec("alpha = [1.0]\n", "[metrics]\nmax_period = 4294967297\n")),
                       grpc::StatusCode::INVALID_ARGUMENT, "metrics.max_period");
       }},
      {"IntegerNotNarrowed_sample_every_2e32",
       [] {
         return Expect(Submit(Spec("alpha = [1.0]\n", "[metrics]\nsample_every = 4294967301\n")),
                       grpc::StatusCode::INVALID_ARGUMENT, "metrics.sample_every");
       }},
      {"BillionStepsPerPoint",
       [] {
         return Expect(Submit("model = \"coupled\"\n[integration]\nt_end = 1e7\nt_keep = 9999000.0\ndt = 0.01\n"),
                       grpc::StatusCode::INVALID_ARGUMENT, "steps per point");
       }},
      {"WindowSamplesUnbounded",
       [] {
         return Expect(Submit("model = \"coupled\"\n[integration]\nt_end = 500000.0\nt_keep = 0.0\ndt = 0.01\n"),
                       grpc::StatusCode::INVALID_ARGUMENT, "window samples");
       }},
      {"SpecOverOneMiB",
       [] { return Expect(Submit(std::string((1 << 20) + 1, '#')), grpc::StatusCode::INVALID_ARGUMENT, "1048576"); }},
      {"MessageOverTheRpcLimit",
       [] { return Expect(Submit(std::string(9 << 20, '#')), grpc::StatusCode::RESOURCE_EXHAUSTED); }},
      {"NameWithControlCharacters",
       [] {
         return Expect(Submit(Spec("alpha = [1.0]\n", "name = \"a\\u001b]0;owned\\u0007\\nb\"\n")),
                       grpc::StatusCode::INVALID_ARGUMENT, "name");
       }},
      {"NameOverTheLimit",
       [] {
         return Expect(Submit(Spec("alpha = [1.0]\n", "name = \"" + std::string(300, 'x') + "\"\n")),
                       grpc::StatusCode::INVALID_ARGUMENT, "200");
       }},
      {"HugeOriginIsBoundedInMessages",
       [] {
         const grpc::Status st =
             Submit("model = \"coupled\"\n[axes\n", nullptr, std::string(100000, 'o') + "\n\x1b[2J");
         std::string r = Expect(st, grpc::StatusCode::INVALID_ARGUMENT);
         if (r.empty() && st.error_message().size() > 2000)
           r = "message of " + std::to_string(st.error_message().size()) + " bytes";
         if (r.empty() && st.error_message().find('\x1b') != std::string::npos) r = "control character echoed";
         return r;
       }},
      {"ContinuationChainLongerThanAJob",
       [] {
         return Expect(Submit(Spec(Lin("alpha", "5000"), "[continuation]\naxis = \"alpha\"\n")),
                       grpc::StatusCode::INVALID_ARGUMENT, "continuation");
       }},
      // --- Ids and names ---------------------------------------------------------------------------
      {"StatusIdWithLikeWildcard", [] { return Expect(GetStatus("%"), grpc::StatusCode::INVALID_ARGUMENT, "id"); }},
      {"StatusIdUnderscoreWildcard",
       [] { return Expect(GetStatus("____"), grpc::StatusCode::INVALID_ARGUMENT, "id"); }},
      {"StatusIdTenKilobytes",
       [] { return Expect(GetStatus(std::string(10000, 'a')), grpc::StatusCode::INVALID_ARGUMENT, "64"); }},
      {"StatusIdEmpty", [] { return Expect(GetStatus(""), grpc::StatusCode::INVALID_ARGUMENT, "empty"); }},
      {"CancelIdWithQuote", [] { return Expect(Cancel("' OR 1=1 --"), grpc::StatusCode::INVALID_ARGUMENT, "hex"); }},
      {"WatchOfASweepTheCoordinatorDoesNotHoldIsRateLimited",
       [] {
         v1::StatusRequest req;
         req.set_id(g->unheld_id);
         auto ctx = Ctx(2.0);
         auto reader = g->stub->WatchStatus(ctx.get(), req);
         v1::SweepStatus s;
         int n = 0;
         while (reader->Read(&s)) ++n;
         reader->Finish();
         return n <= 12 ? std::string() : std::to_string(n) + " messages in 2 s (bound 12)";
       }},
      {"MapMetricsThatAreHdf5PathsOnAPublishedMap",
       [] {
         // A published map: the name itself must be refused (naming the field), not the sweep's state.
         for (const std::string& metric : std::vector<std::string>{"/", "", ".", "..", "/axes/alpha", "alpha",
                                                                   "frf_db/../lle", std::string("frf_db\0x", 8)}) {
           v1::MapRequest req;
           req.set_id(g->published_id);
           req.set_metric(metric);
           v1::MapReply rep;
           const std::string r =
               Expect(g->stub->GetMap(Ctx().get(), req, &rep), grpc::StatusCode::INVALID_ARGUMENT, "metric");
           if (!r.empty()) return "'" + metric + "': " + r;
         }
         return std::string();
       }},
      {"RegisterWorkerNameOfThreeMegabytes",
       [] {
         std::string r;
         for (int i = 0; i < 90 && r.empty(); ++i) {
           v1::RegisterRequest req;
           req.set_name(std::string(3 << 20, static_cast<char>('a' + i % 26)));
           v1::RegisterReply rep;
           r = Expect(g->stub->RegisterWorker(Ctx().get(), req, &rep), grpc::StatusCode::INVALID_ARGUMENT, "128");
         }
         v1::ListWorkersRequest lreq;
         v1::ListWorkersReply lrep;
         if (r.empty()) r = Expect(g->stub->ListWorkers(Ctx().get(), lreq, &lrep), grpc::StatusCode::OK);
         if (r.empty() && lrep.ByteSizeLong() > 100000)
           r = "workers list is " + std::to_string(lrep.ByteSizeLong()) + " bytes";
         return r;
       }},
      {"LeaseWorkerNameWithNewline",
       [] {
         v1::LeaseRequest req;
         req.set_worker("evil\nworker");
         v1::LeaseReply rep;
         return Expect(g->stub->Lease(Ctx().get(), req, &rep), grpc::StatusCode::INVALID_ARGUMENT, "worker");
       }},
      {"HeartbeatLeaseIdOfOneMegabyte",
       [] {
         v1::HeartbeatRequest req;
         req.set_lease_id(std::string(1 << 20, 'x'));
         v1::HeartbeatReply rep;
         return Expect(g->stub->Heartbeat(Ctx().get(), req, &rep), grpc::StatusCode::INVALID_ARGUMENT, "lease_id");
       }},
      // --- Reports ---------------------------------------------------------------------------------
      {"SixtyMegabyteReportWithAForgedLease",
       [] {
         return Expect(Report("forged", kWidth, std::vector<double>(60 << 17, 0.0)),
                       grpc::StatusCode::RESOURCE_EXHAUSTED);
       }},
      {"FourConcurrentOversizedReports",
       [] {
         std::vector<std::thread> ts;
         std::vector<grpc::Status> sts(4);
         for (int i = 0; i < 4; ++i)
           ts.emplace_back([&, i] { sts[i] = Report("forged", kWidth, std::vector<double>(60 << 17, 0.0)); });
         for (auto& t : ts) t.join();
         std::string r;
         for (const auto& st : sts)
           if (r.empty()) r = Expect(st, grpc::StatusCode::RESOURCE_EXHAUSTED);
         return r;
       }},
      {"ReportForForgedLease",
       [] {
         return Expect(Report("forged-lease", kWidth, std::vector<double>(kWidth, 0.0)), grpc::StatusCode::NOT_FOUND);
       }},
      {"ReportGarbageWidth",
       [] {
         return Expect(Report("forged-lease", 0xffffffffu, std::vector<double>(8, 0.0)),
                       grpc::StatusCode::INVALID_ARGUMENT, "record_width");
       }},
      {"ReportWidthZero",
       [] { return Expect(Report("forged-lease", 0, {}), grpc::StatusCode::INVALID_ARGUMENT, "record_width"); }},
      {"ForgedValuesOnARealLeaseAreRefusedAndTheHonestReportThenStored",
       [] {
         v1::SubmitReply sub;
         std::string r =
             Expect(Submit(Spec("alpha = [0.5, 1.0]\nomega = [0.7, 1.3]\n", "name = \"forgery target\""), &sub),
                    grpc::StatusCode::OK);
         if (!r.empty()) return r;
         const v1::LeaseReply l = Lease();
         if (!l.has_job()) return std::string("no job leased");
         const std::vector<double> honest = Honest(l);
         struct Forgery {
           const char* what;
           size_t index;
           double value;
         };
         for (const Forgery& f :
              {Forgery{"frf_db = 1e300", 0, 1e300}, Forgery{"motion = 1e300", 3, 1e300}, Forgery{"motion = 7", 3, 7},
               Forgery{"motion = NaN", 3, NAN}, Forgery{"period = -1", 4, -1}, Forgery{"lle = inf", 1, INFINITY},
               Forgery{"hd_index = 2", 5, 2}, Forgery{"termination = 0.5", 12, 0.5},
               Forgery{"peak amplitude < 0", 23, -1}}) {
           std::vector<double> bad = honest;
           bad[kWidth + f.index] = f.value;  // in the second record
           const grpc::Status st = Report(l.lease_id(), kWidth, bad);
           if (st.error_code() != grpc::StatusCode::INVALID_ARGUMENT) return std::string(f.what) + " was not refused";
         }
         r = Expect(Report(l.lease_id(), kWidth, honest, bistable::CatalogHash() ^ 1),
                    grpc::StatusCode::FAILED_PRECONDITION, "metric catalog");
         if (!r.empty()) return r;
         std::vector<double> extra = honest;
         extra.insert(extra.end(), honest.begin(), honest.begin() + kWidth);
         r = Expect(Report(l.lease_id(), kWidth, extra), grpc::StatusCode::INVALID_ARGUMENT, "items");
         if (r.empty()) r = Expect(Report(l.lease_id(), kWidth, honest), grpc::StatusCode::OK);
         // Clean-up only (frees the owner's active-sweep slot): the honest report may have completed the
         // sweep, and then its publication may already be done ("already done") — both are fine.
         if (r.empty()) {
           const grpc::Status c = Cancel(sub.id());
           if (!c.ok() && c.error_code() != grpc::StatusCode::FAILED_PRECONDITION) r = Expect(c, grpc::StatusCode::OK);
         }
         return r;
       }},
      {"StaleLeaseAfterCancelAndResubmitIsRefused",
       [] {
         const std::string toml = Spec("alpha = [0.4, 0.8, 1.2]\nomega = [0.6, 1.0, 1.4]\n", "name = \"stale target\"");
         v1::SubmitReply sub;
         std::string r = Expect(Submit(toml, &sub), grpc::StatusCode::OK);
         const v1::LeaseReply a = Lease(), b = Lease();
         if (r.empty() && (!a.has_job() || !b.has_job())) r = "no jobs leased";
         if (r.empty()) r = Expect(Cancel(sub.id()), grpc::StatusCode::OK);
         if (r.empty()) r = Expect(Submit(toml), grpc::StatusCode::OK);
         if (!r.empty()) return r;
         const grpc::Status st = Report(b.lease_id(), kWidth, Honest(b));
         if (st.ok()) return std::string("a lease of the cancelled plan was accepted");
         return Expect(Cancel(sub.id()), grpc::StatusCode::OK);
       }},
      {"SubmitsPerOwnerAreLimited",
       [] {
         std::vector<std::string> ids;
         std::string r;
         grpc::Status last;
         for (int i = 0; i < 12 && r.empty(); ++i) {
           v1::SubmitReply rep;
           last = Submit(Spec("alpha = [" + std::to_string(0.61 + 0.01 * i) + "]\n"), &rep);  // nothing cached
           if (!last.ok()) break;
           ids.push_back(rep.id());
         }
         r = Expect(last, grpc::StatusCode::FAILED_PRECONDITION, "limit per owner");
         if (r.empty() && ids.size() > 8) r = std::to_string(ids.size()) + " sweeps accepted";
         for (const auto& id : ids) Cancel(id);
         return r;
       }},
      {"BigSubmitDoesNotBlockOtherCallsAndIsFreedOnCancel",
       [] {
         const long rss0 = RssKb(g->coord);
         std::string r;
         v1::SubmitReply sub;
         grpc::Status st;
         std::thread big(
             [&] { st = Submit(Spec(Lin("alpha", "2048") + Lin("omega", "2048"), "name = \"big\""), &sub); });
         std::this_thread::sleep_for(std::chrono::milliseconds(300));
         double worst = 0;
         for (int i = 0; i < 10; ++i) {  // while the plan is built: status and listing answer at once
           const auto t0 = Clock::now();
           v1::ListSweepsRequest lreq;
           v1::ListSweepsReply lrep;
           if (!g->stub->ListSweeps(Ctx().get(), lreq, &lrep).ok()) r = "ListSweeps failed during planning";
           worst = std::max(worst, std::chrono::duration<double>(Clock::now() - t0).count());
           std::this_thread::sleep_for(std::chrono::milliseconds(100));
         }
         big.join();
         if (r.empty()) r = Expect(st, grpc::StatusCode::OK);
         if (r.empty() && worst > 1.0) r = "a call took " + std::to_string(worst) + " s while a big sweep was planned";
         if (r.empty()) r = Expect(Cancel(sub.id()), grpc::StatusCode::OK);
         const long rss1 = RssKb(g->coord);
         std::printf("  big submit: %ld -> %ld kB after cancel; slowest call while planning %.3f s\n", rss0, rss1,
                     worst);
         if (r.empty() && rss1 > rss0 * 1.2 + 20000)
           r = "memory " + std::to_string(rss0) + " -> " + std::to_string(rss1) + " kB after cancel";
         return r;
       }},
      {"ZZ_AfterTheStormTheCoordinatorIsUpItsMemoryBackAndItsMapsExact", [] { return AfterTheStormRow(); }},
  };
  return kRows;
}

class Hostile : public ::testing::TestWithParam<size_t> {
 public:
  static void SetUpTestSuite() {
    g = new World;
    g->dir = (fs::path(::testing::TempDir()) / ("hostile_wire_" + std::to_string(::getpid()))).string();
    fs::remove_all(g->dir);
    fs::create_directories(g->dir);
    bistable_test::RemoveWhenAllPass(g->dir);
    g->data = g->dir + "/data";
    // A sweep the next coordinator will not hold: submitted and cancelled under an earlier one.
    {
      auto [pid, addr] = StartCoordinator(g->data, g->dir + "/first.log");
      ASSERT_FALSE(addr.empty());
      g->stub = v1::Coordinator::NewStub(grpc::CreateChannel(addr, grpc::InsecureChannelCredentials()));
      v1::SubmitReply rep;
      ASSERT_TRUE(Submit(Spec("alpha = [0.3, 0.9]\n", "name = \"unheld\""), &rep).ok());
      g->unheld_id = rep.id();
      ASSERT_TRUE(Cancel(rep.id()).ok());
      ::kill(pid, SIGTERM);
      Wait(pid, 10);
    }
    auto [pid, addr] = StartCoordinator(g->data, g->dir + "/coord.log", {"--metrics", "127.0.0.1:0"});
    ASSERT_FALSE(addr.empty()) << ReadFile(g->dir + "/coord.log.err");
    for (int i = 0; i < 80 && g->metrics_port < 0; ++i) {  // printed right after "listening on"
      std::istringstream in(ReadFile(g->dir + "/coord.log"));
      for (std::string line; std::getline(in, line);)
        if (line.rfind("metrics on ", 0) == 0) g->metrics_port = std::stoi(line.substr(line.rfind(':') + 1));
      if (g->metrics_port < 0) std::this_thread::sleep_for(std::chrono::milliseconds(25));
    }
    ASSERT_GT(g->metrics_port, 0) << "no 'metrics on' line";
    g->coord = pid;
    g->addr = addr;
    g->stub = v1::Coordinator::NewStub(grpc::CreateChannel(addr, grpc::InsecureChannelCredentials()));
    // Warm up with ordinary work (a small sweep leased, reported, published and read back, status
    // calls), then take the memory baseline: "before" is a coordinator that has served a sweep.
    v1::SubmitReply warm;
    ASSERT_TRUE(Submit(Spec("alpha = [0.5, 1.5]\nomega = [0.5, 1.0, 1.5]\n", "name = \"warm-up\""), &warm).ok());
    for (v1::LeaseReply l = Lease(); l.has_job(); l = Lease())
      ASSERT_TRUE(Report(l.lease_id(), kWidth, Honest(l)).ok());
    v1::SweepStatus st;
    for (int i = 0; i < 100 && !(GetStatus(warm.id(), &st).ok() && st.state() == "done"); ++i)
      std::this_thread::sleep_for(std::chrono::milliseconds(50));
    ASSERT_EQ(st.state(), "done");
    g->published_id = warm.id();
    v1::MapRequest mreq;
    mreq.set_id(warm.id());
    mreq.set_metric("frf_db");
    v1::MapReply mrep;
    ASSERT_TRUE(g->stub->GetMap(Ctx().get(), mreq, &mrep).ok());
    for (int i = 0; i < 20; ++i) GetStatus(g->unheld_id);
    g->rss_before = RssKb(pid);
    g->heap_before = bistable_test::ParseMetrics(
        bistable_test::HttpRequest(g->metrics_port, "/metrics").body)["bistable_heap_in_use_bytes"];
  }
  static void TearDownTestSuite() {
    if (g->coord > 0) {
      ::kill(g->coord, SIGTERM);
      Wait(g->coord, 10);
    }
    fs::remove_all(g->dir);
    delete g;
  }
};

TEST_P(Hostile, Row) {
  ASSERT_TRUE(Alive(g->coord)) << "the coordinator died before this row";
  const Row& row = Rows()[GetParam()];
  const std::string failure = row.run();
  EXPECT_EQ(failure, "") << row.name;
  const auto m = bistable_test::ParseMetrics(bistable_test::HttpRequest(g->metrics_port, "/metrics").body);
  const auto heap = m.find("bistable_heap_in_use_bytes");
  std::printf("  %-70s %s  (coordinator RSS %ld kB, heap in use %.0f kB)\n", row.name,
              failure.empty() ? "held" : "FAILED", RssKb(g->coord), heap == m.end() ? -1.0 : heap->second / 1024);
  EXPECT_TRUE(Alive(g->coord)) << "the coordinator died in row " << row.name << ": "
                               << ReadFile(g->dir + "/coord.log.err");
}

INSTANTIATE_TEST_SUITE_P(Wire, Hostile, ::testing::Range<size_t>(0, Rows().size()),
                         [](const ::testing::TestParamInfo<size_t>& i) { return std::string(Rows()[i.param].name); });

// Outside the shared coordinator: the exposure guard decides by address, and owners are identities
// that survive a restart.
TEST(HostileStartup, ListenOnANameThatStartsWith127IsNotLoopback) {
  const std::string dir = (fs::path(::testing::TempDir()) / ("hostile_listen_" + std::to_string(::getpid()))).string();
  bistable_test::RemoveWhenAllPass(dir);
  fs::create_directories(dir);
  for (const char* addr : {"127.attacker.example:0", "0.0.0.0:0", "localhost.attacker.example:0", "[::]:0"}) {
    const pid_t pid = Spawn({BISTABLE_COORDINATOR, "--listen", addr, "--data", dir + "/data"}, dir + "/log");
    EXPECT_EQ(Wait(pid, 10), 2) << addr;
    EXPECT_NE(ReadFile(dir + "/log.err").find("not a loopback address"), std::string::npos) << addr;
  }
  fs::remove_all(dir);
}

// A full disk in the service: the report is refused (not acknowledged), the sweep's status says why,
// the coordinator logs it, and once space is back the same report is stored.
TEST(HostileStartup, FullDiskIsReportedInStatusAndLoggedAndLosesNothing) {
  if (::geteuid() != 0) GTEST_SKIP() << "needs root to mount a small tmpfs";
  const std::string dir = (fs::path(::testing::TempDir()) / ("hostile_disk_" + std::to_string(::getpid()))).string();
  bistable_test::RemoveWhenAllPass(dir);
  fs::remove_all(dir);
  fs::create_directories(dir + "/mnt");
  const pid_t m = Spawn({"/bin/mount", "-t", "tmpfs", "-o", "size=3m", "tmpfs", dir + "/mnt"}, dir + "/mount.log");
  if (Wait(m, 10) != 0) GTEST_SKIP() << "cannot mount tmpfs here: " << ReadFile(dir + "/mount.log.err");
  World w;
  World* saved = g;
  g = &w;
  auto [pid, addr] = StartCoordinator(dir + "/mnt/data", dir + "/coord.log");
  ASSERT_FALSE(addr.empty()) << ReadFile(dir + "/coord.log.err");
  w.coord = pid;
  w.stub = v1::Coordinator::NewStub(grpc::CreateChannel(addr, grpc::InsecureChannelCredentials()));
  v1::SubmitReply sub;
  ASSERT_TRUE(Submit(Spec("alpha = [0.5, 1.0]\nomega = [0.5, 1.0]\n"), &sub).ok());
  const v1::LeaseReply l = Lease();
  ASSERT_TRUE(l.has_job());
  const std::vector<double> honest = Honest(l);
  {  // fill the disk
    std::ofstream fill(dir + "/mnt/filler", std::ios::binary);
    const std::string block(1 << 16, 'x');
    for (int i = 0; i < 64 && fill.write(block.data(), block.size()); ++i) {
    }
  }
  const grpc::Status full = Report(l.lease_id(), kWidth, honest);
  EXPECT_FALSE(full.ok()) << "a report was acknowledged on a full disk";
  v1::SweepStatus st;
  ASSERT_TRUE(GetStatus(sub.id(), &st).ok());
  EXPECT_NE(st.error().find("full"), std::string::npos) << "status error: '" << st.error() << "'";
  EXPECT_NE(ReadFile(dir + "/coord.log.err").find("report.store_failed"), std::string::npos);
  fs::remove(dir + "/mnt/filler");
  EXPECT_TRUE(Report(l.lease_id(), kWidth, honest).ok()) << "the same report once space is back";
  ASSERT_TRUE(GetStatus(sub.id(), &st).ok());
  EXPECT_EQ(st.error(), "");
  EXPECT_TRUE(Alive(pid));
  ::kill(pid, SIGTERM);
  Wait(pid, 10);
  g = saved;
  const pid_t u = Spawn({"/bin/umount", dir + "/mnt"}, dir + "/umount.log");
  Wait(u, 10);
  fs::remove_all(dir);
}

TEST(HostileStartup, UnnamedTokensAreDistinctOwnersAcrossRestarts) {
  const std::string dir = (fs::path(::testing::TempDir()) / ("hostile_owner_" + std::to_string(::getpid()))).string();
  bistable_test::RemoveWhenAllPass(dir);
  fs::remove_all(dir);
  fs::create_directories(dir);
  // Two unnamed client tokens.
  const std::string ta(64, 'a'), tb(64, 'b');
  auto hash = [&](const std::string& t) {
    std::ofstream(dir + "/t", std::ios::trunc) << t;
    const pid_t p = Spawn({"/usr/bin/sha256sum", dir + "/t"}, dir + "/sha.out");
    Wait(p, 10);
    return ReadFile(dir + "/sha.out").substr(0, 64);
  };
  std::ofstream(dir + "/tokens") << "client " << hash(ta) << "\nclient " << hash(tb) << "\n";
  auto run = [&](auto&& body) {
    auto [pid, addr] = StartCoordinator(dir + "/data", dir + "/coord.log", {"--tokens", dir + "/tokens"});
    ASSERT_FALSE(addr.empty()) << ReadFile(dir + "/coord.log.err");
    auto stub = v1::Coordinator::NewStub(grpc::CreateChannel(addr, grpc::InsecureChannelCredentials()));
    body(*stub);
    ::kill(pid, SIGTERM);
    Wait(pid, 10);
  };
  auto with = [](const std::string& token) {
    auto c = std::make_unique<grpc::ClientContext>();
    c->AddMetadata("authorization", "Bearer " + token);
    return c;
  };
  std::string id;
  run([&](v1::Coordinator::Stub& stub) {
    v1::SubmitRequest req;
    req.set_spec_toml(Spec("alpha = [0.6]\n"));
    v1::SubmitReply rep;
    ASSERT_TRUE(stub.Submit(with(ta).get(), req, &rep).ok());
    id = rep.id();
    v1::CancelRequest c;
    c.set_id(id);
    v1::CancelReply cr;
    EXPECT_EQ(stub.Cancel(with(tb).get(), c, &cr).error_code(), grpc::StatusCode::PERMISSION_DENIED)
        << "B cancelled A's sweep";
  });
  run([&](v1::Coordinator::Stub& stub) {  // restarted: ownership is stored with the sweep
    v1::CancelRequest c;
    c.set_id(id);
    v1::CancelReply cr;
    EXPECT_EQ(stub.Cancel(with(tb).get(), c, &cr).error_code(), grpc::StatusCode::PERMISSION_DENIED) << "after restart";
    EXPECT_TRUE(stub.Cancel(with(ta).get(), c, &cr).ok()) << "A cannot cancel its own sweep after a restart";
  });
  fs::remove_all(dir);
}

// ---- Issue 39 (hostile input, second round): their own ctest entries (HostileWire.<name>) -------------

std::string Round2Dir(const std::string& what) {
  const std::string dir =
      (fs::path(::testing::TempDir()) / ("hostile2_" + what + "_" + std::to_string(::getpid()))).string();
  fs::remove_all(dir);
  fs::create_directories(dir);
  bistable_test::RemoveWhenAllPass(dir);
  return dir;
}

std::string Sha256Of(const std::string& dir, const std::string& text) {
  std::ofstream(dir + "/sha.in", std::ios::trunc) << text;
  const pid_t p = Spawn({"/usr/bin/sha256sum", dir + "/sha.in"}, dir + "/sha.out");
  Wait(p, 10);
  return ReadFile(dir + "/sha.out").substr(0, 64);
}

// Fail 1: the per-owner limit counts sweeps being planned. `n` different specs submitted at once by one
// identity (a client token, or no token at all): at most kMaxActiveSweepsPerOwner accepted, the rest
// refused naming the limit. Each plan is big enough (65,536 items) that they overlap; before the fix,
// every one passed the check because none was installed yet.
void ConcurrentSubmitsStopAtTheLimit(bool with_token, int n) {
  const std::string dir = Round2Dir(with_token ? "limit_token" : "limit_anon");
  const std::string token(64, 'c');
  std::vector<std::string> extra;
  if (with_token) {
    std::ofstream(dir + "/tokens") << "client " << Sha256Of(dir, token) << " alice\n";
    extra = {"--tokens", dir + "/tokens"};
  }
  auto [pid, addr] = StartCoordinator(dir + "/data", dir + "/coord.log", extra);
  ASSERT_FALSE(addr.empty()) << ReadFile(dir + "/coord.log.err");
  auto stub = v1::Coordinator::NewStub(grpc::CreateChannel(addr, grpc::InsecureChannelCredentials()));
  std::vector<grpc::Status> got(n);
  std::vector<std::string> ids(n);
  std::atomic<int> ready{0};
  std::vector<std::thread> threads;
  for (int i = 0; i < n; ++i)
    threads.emplace_back([&, i] {
      v1::SubmitRequest req;
      req.set_spec_toml(Spec("alpha = { linspace = [0.1, 3.0, 256] }\nomega = { linspace = [0.1, " +
                             std::to_string(3.0 + 0.01 * i) + ", 256] }\n"));
      auto ctx = Ctx(120);
      if (with_token) ctx->AddMetadata("authorization", "Bearer " + token);
      ++ready;
      while (ready.load() < n) std::this_thread::yield();  // all at once
      v1::SubmitReply rep;
      got[i] = stub->Submit(ctx.get(), req, &rep);
      ids[i] = rep.id();
    });
  for (auto& t : threads) t.join();
  int accepted = 0, refused = 0;
  for (int i = 0; i < n; ++i) {
    if (got[i].ok())
      ++accepted;
    else if (got[i].error_code() == grpc::StatusCode::FAILED_PRECONDITION &&
             got[i].error_message().find("limit per owner is 8") != std::string::npos)
      ++refused;
    else
      ADD_FAILURE() << "submit " << i << ": " << got[i].error_code() << " " << got[i].error_message();
  }
  std::printf("  %d concurrent submits (%s): %d accepted, %d refused\n", n,
              with_token ? "one client token" : "no tokens", accepted, refused);
  EXPECT_EQ(accepted, bistable::limits::kMaxActiveSweepsPerOwner)
      << "the per-owner limit did not hold under concurrency";
  EXPECT_EQ(refused, n - bistable::limits::kMaxActiveSweepsPerOwner);
  // The slots are real: one more submit, now sequential, is refused too; a cancel frees one.
  v1::SubmitRequest more;
  more.set_spec_toml(Spec("alpha = [0.77]\n"));
  auto ctx = Ctx();
  if (with_token) ctx->AddMetadata("authorization", "Bearer " + token);
  v1::SubmitReply rep;
  EXPECT_EQ(stub->Submit(ctx.get(), more, &rep).error_code(), grpc::StatusCode::FAILED_PRECONDITION);
  for (int i = 0; i < n; ++i)
    if (got[i].ok()) {
      v1::CancelRequest c;
      c.set_id(ids[i]);
      v1::CancelReply cr;
      auto cctx = Ctx();
      if (with_token) cctx->AddMetadata("authorization", "Bearer " + token);
      EXPECT_TRUE(stub->Cancel(cctx.get(), c, &cr).ok());
    }
  EXPECT_TRUE(Alive(pid));
  ::kill(pid, SIGTERM);
  Wait(pid, 20);
}

TEST(HostileRound2, ConcurrentSubmitsOfOneTokenStopAtThePerOwnerLimit) { ConcurrentSubmitsStopAtTheLimit(true, 12); }
TEST(HostileRound2, ConcurrentSubmitsWithoutTokensStopAtThePerOwnerLimit) {
  ConcurrentSubmitsStopAtTheLimit(false, 20);
}

// Fail 2: a token with a newline, a control byte or a NUL is refused before it reaches gRPC (which logs
// the whole metadata and aborts), by every process that sends one, and never printed.
TEST(HostileRound2, ATokenWithAControlByteIsRefusedAndNeverPrinted) {
  const std::string dir = Round2Dir("token");
  auto [pid, addr] = StartCoordinator(dir + "/data", dir + "/coord.log");
  ASSERT_FALSE(addr.empty()) << ReadFile(dir + "/coord.log.err");
  const std::string secret_a = "SECRETA1b2c3", secret_b = "SECRETB4d5e6";
  for (const std::string& token : {secret_a + "\n" + secret_b, secret_a + std::string(1, '\0') + secret_b,
                                   secret_a + "\x01" + secret_b, secret_a + " " + secret_b, secret_a + "\x7f"}) {
    SCOPED_TRACE(std::to_string(token.size()) +
                 " bytes, byte 13 = " + std::to_string(static_cast<unsigned char>(token[12])));
    std::ofstream(dir + "/t", std::ios::binary | std::ios::trunc) << token;
    for (const std::vector<std::string>& argv :
         {std::vector<std::string>{BISTABLE_WORKER, "--coordinator", addr, "--threads", "1", "--token-file",
                                   dir + "/t"},
          std::vector<std::string>{BISTABLE_CLI, "status", "abc", "--coordinator", addr, "--token-file", dir + "/t"},
          std::vector<std::string>{BISTABLE_CLI, "sweeps", "--coordinator", addr, "--token-file", dir + "/t"}}) {
      const pid_t p = Spawn(argv, dir + "/out");
      const int code = Wait(p, 20);
      const std::string err = ReadFile(dir + "/out.err") + ReadFile(dir + "/out");
      EXPECT_EQ(code, 2) << argv[0] << " " << argv[1] << " (-1: killed by a signal, SIGABRT before the fix)\n" << err;
      EXPECT_NE(err.find("token-file"), std::string::npos) << err;
      EXPECT_NE(err.find("the token is not shown"), std::string::npos) << err;
      EXPECT_EQ(err.find("SECRET"), std::string::npos) << "the token was printed:\n" << err;
    }
  }
  // A good token in plaintext to an address that is not loopback: the worker refuses to start (exit 2).
  std::ofstream(dir + "/t", std::ios::trunc) << secret_a << "\n";
  const pid_t w = Spawn({BISTABLE_WORKER, "--coordinator", "0.0.0.0:1", "--threads", "1", "--token-file", dir + "/t"},
                        dir + "/plain");
  EXPECT_EQ(Wait(w, 20), 2) << ReadFile(dir + "/plain.err");
  EXPECT_NE(ReadFile(dir + "/plain.err").find("--insecure-remote"), std::string::npos) << ReadFile(dir + "/plain.err");
  EXPECT_TRUE(Alive(pid));
  ::kill(pid, SIGTERM);
  Wait(pid, 10);
}

// Minor: a lease is bound to the token that leased it, and its id cannot be guessed. Worker token B holds
// the id of A's lease (a leaked log line, a guess): its report of in-range values for A's job, its
// heartbeat and its release are refused; A's own report is stored. Lease ids carry 128 random bits.
TEST(HostileRound2, LeasesAreBoundToTheLeasingTokenAndTheirIdsAreUnguessable) {
  const std::string dir = Round2Dir("lease_identity");
  const std::string client(64, 'c'), worker_a(64, 'a'), worker_b(64, 'b');
  std::ofstream(dir + "/tokens") << "client " << Sha256Of(dir, client) << " alice\nworker " << Sha256Of(dir, worker_a)
                                 << " wa\nworker " << Sha256Of(dir, worker_b) << " wb\n";
  auto [pid, addr] = StartCoordinator(dir + "/data", dir + "/coord.log", {"--tokens", dir + "/tokens"});
  ASSERT_FALSE(addr.empty()) << ReadFile(dir + "/coord.log.err");
  World w;
  World* saved = g;
  g = &w;
  w.coord = pid;
  w.stub = v1::Coordinator::NewStub(grpc::CreateChannel(addr, grpc::InsecureChannelCredentials()));
  auto as = [](const std::string& token) {
    auto c = Ctx();
    c->AddMetadata("authorization", "Bearer " + token);
    return c;
  };
  v1::SubmitRequest sreq;
  sreq.set_spec_toml(Spec("alpha = { linspace = [0.2, 2.0, 20] }\nomega = [0.8, 1.2]\n"));  // several jobs
  v1::SubmitReply sub;
  ASSERT_TRUE(w.stub->Submit(as(client).get(), sreq, &sub).ok());
  v1::LeaseRequest lreq;
  lreq.set_worker("wa");
  v1::LeaseReply lease;
  ASSERT_TRUE(w.stub->Lease(as(worker_a).get(), lreq, &lease).ok());
  ASSERT_TRUE(lease.has_job());
  const std::vector<double> honest = Honest(lease);
  v1::ReportRequest rreq;
  rreq.set_lease_id(lease.lease_id());
  rreq.set_record_width(kWidth);
  rreq.set_catalog_hash(bistable::CatalogHash());
  rreq.mutable_values()->Add(honest.begin(), honest.end());
  v1::ReportReply rrep;
  EXPECT_EQ(w.stub->Report(as(worker_b).get(), rreq, &rrep).error_code(), grpc::StatusCode::PERMISSION_DENIED)
      << "worker B reported worker A's job";
  v1::HeartbeatRequest hreq;
  hreq.set_lease_id(lease.lease_id());
  v1::HeartbeatReply hrep;
  EXPECT_EQ(w.stub->Heartbeat(as(worker_b).get(), hreq, &hrep).error_code(), grpc::StatusCode::PERMISSION_DENIED);
  v1::ReleaseRequest relreq;
  relreq.set_lease_id(lease.lease_id());
  v1::ReleaseReply relrep;
  EXPECT_EQ(w.stub->Release(as(worker_b).get(), relreq, &relrep).error_code(), grpc::StatusCode::PERMISSION_DENIED);
  EXPECT_TRUE(w.stub->Heartbeat(as(worker_a).get(), hreq, &hrep).ok());
  EXPECT_TRUE(w.stub->Report(as(worker_a).get(), rreq, &rrep).ok()) << "the holder's own report";
  // Ids: the sweep id, '-', then 32 hex digits (128 bits from the kernel's CSPRNG), all different.
  std::set<std::string> ids = {lease.lease_id()};
  for (v1::LeaseReply l; w.stub->Lease(as(worker_a).get(), lreq, &l).ok() && l.has_job(); l.Clear())
    ids.insert(l.lease_id());
  EXPECT_GE(ids.size(), 2u);
  for (const std::string& id : ids) {
    const std::string rand = id.substr(id.find('-') + 1);
    EXPECT_EQ(id.substr(0, id.find('-')), sub.id()) << id;
    EXPECT_EQ(rand.size(), 32u) << id;
    EXPECT_EQ(rand.find_first_not_of("0123456789abcdef"), std::string::npos) << id;
  }
  EXPECT_TRUE(Alive(pid));
  ::kill(pid, SIGTERM);
  Wait(pid, 10);
  g = saved;
}

// Minor: numeric flags of the coordinator are bounded (NaN, negative and absurd values used to be accepted).
TEST(HostileRound2, CoordinatorRefusesBadNumericFlags) {
  const std::string dir = Round2Dir("flags");
  for (const auto& [flag, value] : std::vector<std::pair<std::string, std::string>>{{"--job-seconds", "-1"},
                                                                                    {"--job-seconds", "nan"},
                                                                                    {"--job-seconds", "0"},
                                                                                    {"--job-seconds", "1e300"},
                                                                                    {"--lease-seconds", "1e300"},
                                                                                    {"--lease-seconds", "nan"},
                                                                                    {"--lease-seconds", "-1"}}) {
    const pid_t p =
        Spawn({BISTABLE_COORDINATOR, "--listen", "127.0.0.1:0", "--data", dir + "/data", flag, value}, dir + "/log");
    const int code = Wait(p, 10);
    const std::string err = ReadFile(dir + "/log.err");
    EXPECT_EQ(code, 2) << flag << " " << value << "\n" << err;
    EXPECT_NE(err.find(flag.substr(2) + " = "), std::string::npos) << err;
    EXPECT_NE(err.find("violates " + flag.substr(2) + " in (0, "), std::string::npos) << err;
  }
}

// Minor: a restart resumes every unfinished sweep of the index, also beyond the per-owner limit (ten
// interrupted embedded runs of one data directory: two used to be marked failed at start).
TEST(HostileRound2, ARestartResumesEveryInterruptedSweepBeyondThePerOwnerLimit) {
  const std::string dir = Round2Dir("resume");
  fs::create_directories(dir + "/data");
  std::vector<std::string> ids;
  {
    auto db = bistable::IndexDb::Open(dir + "/data/index.sqlite");
    ASSERT_TRUE(db.ok()) << db.status().ToString();
    for (int i = 0; i < 10; ++i) {
      const std::string toml = Spec("alpha = [" + std::to_string(0.41 + 0.01 * i) + "]\n");
      auto spec = bistable::ParseSweepSpec(toml, "resume");
      ASSERT_TRUE(spec.ok());
      bistable::SweepRow row;
      row.id = spec->Id();
      row.name = "interrupted " + std::to_string(i);
      row.model = "coupled";
      row.spec = toml;
      row.state = bistable::SweepState::kInterrupted;
      row.items_total = 1;
      row.owner = "local";
      ASSERT_TRUE((*db)->UpsertSweep(row).ok());
      ids.push_back(row.id);
    }
  }
  auto [pid, addr] = StartCoordinator(dir + "/data", dir + "/coord.log");
  ASSERT_FALSE(addr.empty()) << ReadFile(dir + "/coord.log.err");
  auto stub = v1::Coordinator::NewStub(grpc::CreateChannel(addr, grpc::InsecureChannelCredentials()));
  int failed = 0;
  for (const std::string& id : ids) {
    v1::StatusRequest req;
    req.set_id(id);
    v1::SweepStatus st;
    ASSERT_TRUE(stub->GetStatus(Ctx().get(), req, &st).ok());
    if (st.state() == "failed") ++failed;
    EXPECT_NE(st.state(), "failed") << id << ": " << st.error();
  }
  std::printf("  10 interrupted sweeps of one owner at start: %d failed\n", failed);
  EXPECT_EQ(ReadFile(dir + "/coord.log.err").find("sweep.resume_failed"), std::string::npos)
      << ReadFile(dir + "/coord.log.err");
  ::kill(pid, SIGTERM);
  Wait(pid, 10);
}

// Stops a process the test started (SIGTERM, then a wait) on every way out of it, a failed ASSERT included.
struct Stopped {
  pid_t pid;
  ~Stopped() {
    if (pid > 0 && Alive(pid)) ::kill(pid, SIGTERM), Wait(pid, 20);
  }
};

// The "<what> on ...:PORT" line a process printed on stdout (`log`), waited for; 0 when it never came.
int AwaitPrintedPort(const std::string& log, const std::string& what) {
  for (int i = 0; i < 400; ++i) {
    std::istringstream in(ReadFile(log));
    for (std::string line; std::getline(in, line);)
      if (line.rfind(what + " on ", 0) == 0) return std::stoi(line.substr(line.rfind(':') + 1));
    std::this_thread::sleep_for(std::chrono::milliseconds(25));
  }
  return 0;
}

// Minor: --metrics had no Host check, so a web page that points a name of its own at the machine (DNS
// rebinding) read worker names off the coordinator's and the worker's metrics. One rule now for every
// listener without tokens (--metrics; --http without tokens): an IP literal, localhost or a name given with
// --http-allowed-host is answered, any other name gets 421 and nothing; /healthz answers anyone.
TEST(HostileRound2, MetricsListenersAnswerNoForeignHostName) {
  const std::string dir = Round2Dir("metrics_host");
  auto [pid, addr] = StartCoordinator(
      dir + "/data", dir + "/coord.log",
      {"--metrics", "127.0.0.1:0", "--http", "127.0.0.1:0", "--http-allowed-host", "bistable-coordinator"});
  const Stopped stop_coordinator{pid};
  ASSERT_FALSE(addr.empty()) << ReadFile(dir + "/coord.log.err");
  const int coord_metrics = AwaitPrintedPort(dir + "/coord.log", "metrics"),
            dashboard = AwaitPrintedPort(dir + "/coord.log", "dashboard");
  ASSERT_GT(coord_metrics, 0);
  ASSERT_GT(dashboard, 0);
  const pid_t w = Spawn({BISTABLE_WORKER, "--coordinator", addr, "--threads", "1", "--name", "victim-worker",
                         "--metrics", "127.0.0.1:0", "--http-allowed-host", "Metrics.Internal"},
                        dir + "/worker.log");
  const Stopped stop_worker{w};
  int worker_metrics = 0;
  for (int i = 0; i < 400 && !worker_metrics; ++i) {  // the worker says its port in its worker.started line
    const std::string log = ReadFile(dir + "/worker.log.err");
    if (const size_t at = log.find("metrics=");
        at != std::string::npos && std::isdigit(static_cast<unsigned char>(log[at + 8])))
      worker_metrics = std::stoi(log.substr(at + 8));
    else
      std::this_thread::sleep_for(std::chrono::milliseconds(25));
  }
  ASSERT_GT(worker_metrics, 0) << ReadFile(dir + "/worker.log.err");
  // A sweep computed by the worker: its name is in the coordinator's metrics.
  std::ofstream(dir + "/spec.toml") << Spec("alpha = [0.5, 1.0]\nomega = [0.8, 1.2]\n");
  ASSERT_EQ(Wait(Spawn({BISTABLE_CLI, "submit", dir + "/spec.toml", "--coordinator", addr}, dir + "/submit"), 30), 0);
  bool named = false;
  for (int i = 0; i < 400 && !named; ++i) {
    named = bistable_test::HttpRequest(coord_metrics, "/metrics").body.find("victim-worker") != std::string::npos;
    if (!named) std::this_thread::sleep_for(std::chrono::milliseconds(25));
  }
  ASSERT_TRUE(named) << "the worker's name never reached the metrics";
  const auto get = [](int port, const std::string& target, const std::string& host) {
    return bistable_test::HttpRequest(port, target, boost::beast::http::verb::get, "", host);
  };
  const std::string cp = std::to_string(coord_metrics);
  struct Listener {
    const char* what;
    int port;
    std::string target, data;  // a route and what only its answer holds
    std::vector<std::string> answered, refused;
  };
  const std::vector<std::string> foreign = {"evil.example",
                                            "evil.example:" + cp,
                                            "localhost.evil.example",
                                            "127.0.0.1.nip.io:" + cp,
                                            "bistable-coordinator.evil.example",
                                            "[::1",
                                            "localhost:80x",
                                            ""};
  auto with = [](std::vector<std::string> v, std::initializer_list<std::string> more) {
    v.insert(v.end(), more);
    return v;
  };
  const std::vector<Listener> listeners = {
      {"coordinator --metrics",
       coord_metrics,
       "/metrics",
       "victim-worker",
       {"127.0.0.1:" + cp, "10.0.0.5:9090", "[::1]:" + cp, "[2001:db8::7]", "localhost", "LOCALHOST:" + cp,
        "bistable-coordinator:9090", "Bistable-Coordinator"},
       with(foreign, {"metrics.internal"})},
      {"worker --metrics",
       worker_metrics,
       "/metrics",
       "bistable_worker_threads",
       {"127.0.0.1", "10.0.0.6:9090", "[::1]", "localhost:9090", "metrics.internal:9090"},
       with(foreign, {"bistable-coordinator"})},
      {"coordinator --http (no tokens)",
       dashboard,
       "/api/sweeps",
       "victim-worker",
       {"127.0.0.1", "192.168.1.20:8080", "localhost", "bistable-coordinator"},
       foreign},
      {"coordinator --http /metrics (no tokens)",
       dashboard,
       "/metrics",
       "victim-worker",
       {"127.0.0.1", "bistable-coordinator"},
       foreign},
  };
  for (const Listener& l : listeners) {
    SCOPED_TRACE(l.what);
    for (const std::string& host : l.answered) {
      const auto r = get(l.port, l.target, host);
      EXPECT_EQ(r.status, 200) << "Host '" << host << "': " << r.body.substr(0, 200);
      EXPECT_NE(r.body.find(l.data), std::string::npos) << "Host '" << host << "'";
    }
    for (const std::string& host : l.refused) {
      const auto r = get(l.port, l.target, host);
      EXPECT_EQ(r.status, 421) << "Host '" << host << "' was answered (DNS rebinding reads it):\n"
                               << r.body.substr(0, 300);
      EXPECT_EQ(r.body.find(l.data), std::string::npos) << "Host '" << host << "'";
      EXPECT_EQ(r.body.find("bistable_"), std::string::npos) << "Host '" << host << "'";
      EXPECT_NE(r.body.find("--http-allowed-host"), std::string::npos) << r.body;
      if (host.size() > 4) {
        EXPECT_EQ(r.body.find(host), std::string::npos) << "the Host header was echoed";
      }
    }
    EXPECT_EQ(get(l.port, "/healthz", "evil.example").status, 200);  // no data: open to any Host
  }
  // A bad --http-allowed-host is refused at start, by both programs.
  for (const std::vector<std::string>& argv :
       {std::vector<std::string>{BISTABLE_COORDINATOR, "--listen", "127.0.0.1:0", "--data", dir + "/d2",
                                 "--http-allowed-host", "host:80"},
        std::vector<std::string>{BISTABLE_WORKER, "--coordinator", addr, "--http-allowed-host", "*.example"}}) {
    const int code = Wait(Spawn(argv, dir + "/bad"), 10);
    EXPECT_EQ(code, 2) << argv[0] << "\n" << ReadFile(dir + "/bad.err");
    EXPECT_NE(ReadFile(dir + "/bad.err").find("http-allowed-host"), std::string::npos) << ReadFile(dir + "/bad.err");
  }
  ::kill(w, SIGTERM);
  Wait(w, 20);
  EXPECT_TRUE(Alive(pid));
  ::kill(pid, SIGTERM);
  Wait(pid, 10);
}

// Minor: a tokens file of mode 0666 was used without a word. Anyone who may write it may add an admin
// token: a file every user may write is refused at start (exit 2, the file, its mode and the fix named);
// one the group may write or every user may read (it holds hashes and names) is used with a warning naming
// the file and its mode; 0600 and 0640 start quietly.
TEST(HostileRound2, ATokensFileEveryoneMayWriteIsRefusedAndALaxOneIsWarnedOf) {
  const std::string dir = Round2Dir("tokens_mode");
  const std::string tokens = dir + "/tokens";
  std::ofstream(tokens) << "client " << Sha256Of(dir, std::string(64, 'c')) << " alice\n";
  const auto start = [&](mode_t mode) {
    fs::permissions(tokens, static_cast<fs::perms>(mode), fs::perm_options::replace);
    return StartCoordinator(dir + "/data", dir + "/coord.log", {"--tokens", tokens});
  };
  for (const auto& [mode, text] :
       std::vector<std::pair<mode_t, std::string>>{{0666, "0666"}, {0602, "0602"}, {0646, "0646"}}) {
    SCOPED_TRACE(text);
    fs::permissions(tokens, static_cast<fs::perms>(mode), fs::perm_options::replace);
    const int code =
        Wait(Spawn({BISTABLE_COORDINATOR, "--listen", "127.0.0.1:0", "--data", dir + "/data", "--tokens", tokens},
                   dir + "/coord.log"),
             10);
    const std::string err = ReadFile(dir + "/coord.log.err");
    EXPECT_EQ(code, 2) << "a tokens file every user may write was used (-2: still running)\n" << err;
    for (const std::string& want :
         std::vector<std::string>{"tokens", "'" + tokens + "'", "mode " + text, "every user may write it", "chmod 600"})
      EXPECT_NE(err.find(want), std::string::npos) << "lacks '" << want << "':\n" << err;
  }
  for (const auto& [mode, text] :
       std::vector<std::pair<mode_t, std::string>>{{0664, "0664"}, {0660, "0660"}, {0644, "0644"}, {0604, "0604"}}) {
    SCOPED_TRACE(text);
    auto [pid, addr] = start(mode);
    EXPECT_FALSE(addr.empty()) << ReadFile(dir + "/coord.log.err");
    const std::string err = ReadFile(dir + "/coord.log.err");
    for (const std::string& want : std::vector<std::string>{"warning tokens.mode", tokens, "mode=" + text, "may "})
      EXPECT_NE(err.find(want), std::string::npos) << "lacks '" << want << "':\n" << err;
    ::kill(pid, SIGTERM);
    Wait(pid, 10);
  }
  for (mode_t mode : {0600, 0640, 0400}) {
    auto [pid, addr] = start(mode);
    EXPECT_FALSE(addr.empty()) << ReadFile(dir + "/coord.log.err");
    EXPECT_EQ(ReadFile(dir + "/coord.log.err").find("tokens.mode"), std::string::npos)
        << std::oct << mode << "\n"
        << ReadFile(dir + "/coord.log.err");
    ::kill(pid, SIGTERM);
    Wait(pid, 10);
  }
}

// Minor: a zero-length index.sqlite orphaned every published map in silence. A coordinator started on
// such a directory indexes the map files again (a data.repaired warning naming the index and the maps) and
// serves their sweeps as published; the same map truncated is moved aside by a resubmit and written again.
TEST(HostileRound2, ACoordinatorStartingOnAnEmptyIndexServesItsMapsAgain) {
  const std::string dir = Round2Dir("empty_index");
  std::ofstream(dir + "/spec.toml") << Spec("alpha = [0.5, 1.0]\nomega = [0.8, 1.2]\n");
  ASSERT_EQ(Wait(Spawn({BISTABLE_CLI, "run", dir + "/spec.toml", "--data", dir + "/data", "--no-plots", "--quiet"},
                       dir + "/run"),
                 60),
            0)
      << ReadFile(dir + "/run.err");
  const std::string id = bistable::ParseSweepSpec(Spec("alpha = [0.5, 1.0]\nomega = [0.8, 1.2]\n"), "x")->Id();
  fs::resize_file(dir + "/data/index.sqlite", 0);
  auto [pid, addr] = StartCoordinator(dir + "/data", dir + "/coord.log");
  const Stopped stop_coordinator{pid};
  ASSERT_FALSE(addr.empty()) << ReadFile(dir + "/coord.log.err");
  const std::string log = ReadFile(dir + "/coord.log.err");
  EXPECT_NE(log.find("data.repaired"), std::string::npos) << log;
  EXPECT_NE(log.find("held no row for 1 map file(s)"), std::string::npos) << log;
  auto stub = v1::Coordinator::NewStub(grpc::CreateChannel(addr, grpc::InsecureChannelCredentials()));
  v1::StatusRequest req;
  req.set_id(id);
  v1::SweepStatus st;
  ASSERT_TRUE(stub->GetStatus(Ctx().get(), req, &st).ok());
  EXPECT_EQ(st.state(), "done") << "the published sweep was orphaned";
  // Its map truncated: a resubmit moves it aside (map.corrupt) and plans the sweep again (the emptied index
  // lost the stored points: a worker computes them) until its map is written anew.
  fs::resize_file(dir + "/data/sweeps/" + id + ".h5", 1000);
  v1::SubmitRequest sub;
  sub.set_spec_toml(ReadFile(dir + "/spec.toml"));
  v1::SubmitReply rep;
  ASSERT_TRUE(stub->Submit(Ctx().get(), sub, &rep).ok());
  EXPECT_GE(rep.jobs(), 1) << "a truncated map was served as published";
  const pid_t w = Spawn({BISTABLE_WORKER, "--coordinator", addr, "--threads", "1"}, dir + "/worker.log");
  const Stopped stop_worker{w};
  for (int i = 0; i < 400 && !(stub->GetStatus(Ctx().get(), req, &st).ok() && st.state() == "done"); ++i)
    std::this_thread::sleep_for(std::chrono::milliseconds(25));
  ::kill(w, SIGTERM);
  Wait(w, 20);
  EXPECT_EQ(st.state(), "done");
  EXPECT_NE(ReadFile(dir + "/coord.log.err").find("map.corrupt"), std::string::npos)
      << ReadFile(dir + "/coord.log.err");
  EXPECT_TRUE(bistable::ReadMapMetric(dir + "/data/sweeps/" + id + ".h5", "frf_db").ok())
      << "the map was not written again";
  ::kill(pid, SIGTERM);
  Wait(pid, 10);
}

// Minor: a viewer's /api/cell on a sweep of 10^8 steps per point took seconds and hundreds of MB on the
// coordinator, and twelve at once answered 503 to everyone's maps. A cell is bounded now (10^7 steps, 2^20
// window samples: a larger one is refused, 422, with the bound and the `bistable point` command), at most
// one computes at a time (maps and queries keep the other thread), a client holds at most two (more: 503
// to that client only, the others are served in turn), and a cell's memory is given back.
TEST(HostileRound2, DashboardCellsAreBoundedAndTakenInTurnByClient) {
  const std::string dir = Round2Dir("cells");
  const std::string client(64, 'c'), alice(64, 'a'), bob(64, 'b');
  std::ofstream(dir + "/tokens") << "client " << Sha256Of(dir, client) << " carol\nviewer " << Sha256Of(dir, alice)
                                 << " alice\nviewer " << Sha256Of(dir, bob) << " bob\n";
  auto [pid, addr] =
      StartCoordinator(dir + "/data", dir + "/coord.log", {"--tokens", dir + "/tokens", "--http", "127.0.0.1:0"});
  const Stopped stop_coordinator{pid};
  ASSERT_FALSE(addr.empty()) << ReadFile(dir + "/coord.log.err");
  const int http = AwaitPrintedPort(dir + "/coord.log", "dashboard");
  ASSERT_GT(http, 0);
  auto stub = v1::Coordinator::NewStub(grpc::CreateChannel(addr, grpc::InsecureChannelCredentials()));
  const auto submit = [&](const std::string& axes, const std::string& integration) {
    v1::SubmitRequest req;
    req.set_spec_toml("model = \"coupled\"\n[axes]\n" + axes + "\n[integration]\ndt = 0.01\n" + integration);
    auto ctx = Ctx();
    ctx->AddMetadata("authorization", "Bearer " + client);
    v1::SubmitReply rep;
    EXPECT_TRUE(stub->Submit(ctx.get(), req, &rep).ok());
    return rep.id();
  };
  // No worker: the sweeps stay queued; cells are computed on demand all the same.
  const std::string huge =
      submit("alpha = [0.5]\nomega = [1.0]", "t_end = 1000000.0\nt_keep = 500000.0\n[metrics]\nsample_every = 16\n");
  const std::string some = submit("alpha = [0.5, 0.6]\nomega = [0.9, 1.0]", "t_end = 30000.0\nt_keep = 25000.0\n");
  const std::string near = submit("alpha = [0.5, 0.6]\nomega = [1.0]", "t_end = 99000.0\nt_keep = 89000.0\n");
  const auto get = [&](const std::string& target, const std::string& token) {
    return bistable_test::HttpExchange(http, target, boost::beast::http::verb::get,
                                       {{"Host", "127.0.0.1"}, {"Authorization", "Bearer " + token}});
  };
  const auto cell = [&](const std::string& id, int point) {
    return "/api/cell?id=" + id + "&point=" + std::to_string(point) + "&ic=0";
  };
  ASSERT_EQ(get(cell(some, 0), alice).status, 200);  // warm: the code paths and the caches are in
  // The heap in use (malloc's own count, on /metrics: a viewer token reads it) and the RSS.
  const auto heap = [&] {
    const auto m = bistable_test::ParseMetrics(get("/metrics", alice).body);
    const auto it = m.find("bistable_heap_in_use_bytes");
    return it == m.end() ? -1.0 : it->second;
  };
  const double heap0 = heap();
  const long rss0 = RssKb(pid);
  // Cells near the bound: their memory (the window's rows, the transform's tables) is freed and given
  // back once they are answered.
  for (int p = 0; p < 2; ++p) EXPECT_EQ(get(cell(near, p), alice).status, 200);
  std::this_thread::sleep_for(std::chrono::milliseconds(300));
  const double heap1 = heap();
  const long rss1 = RssKb(pid);
  std::printf("  heap in use: %.1f MB, %.1f MB after two cells of 10^6 samples\n", heap0 / 1e6, heap1 / 1e6);
  EXPECT_LT(heap1 - heap0, 8e6) << "bytes still held after two cells near the bound";
  EXPECT_LT(rss1 - rss0, 32 * 1024) << "kB kept after two cells near the bound";
  // A cell of 10^8 steps: refused at once, naming the bound and the command that runs it.
  const auto t0 = Clock::now();
  const auto refused = get(cell(huge, 0), alice);
  const double took = std::chrono::duration<double>(Clock::now() - t0).count();
  EXPECT_EQ(refused.status, 422) << refused.body.substr(0, 300);
  EXPECT_LT(took, 2.0) << "the cell was computed";
  EXPECT_NE(refused.body.find("at most 10000000 steps"), std::string::npos) << refused.body.substr(0, 300);
  EXPECT_NE(refused.body.find("bistable point"), std::string::npos) << refused.body.substr(0, 300);
  EXPECT_LT(RssKb(pid) - rss1, 16 * 1024) << "kB grown for a refused cell";
  // Twelve cells of alice at once, then bob's cell and four maps: bob is answered, alice gets two.
  std::vector<bistable_test::HttpReply> storm(12), bobs(5);
  std::vector<std::thread> threads;
  for (int i = 0; i < 12; ++i) threads.emplace_back([&, i] { storm[i] = get(cell(some, i % 4), alice); });
  std::this_thread::sleep_for(std::chrono::milliseconds(50));
  threads.emplace_back([&] { bobs[0] = get(cell(some, 3), bob); });
  for (int i = 1; i < 5; ++i)
    threads.emplace_back([&, i] { bobs[i] = get("/api/map?id=" + some + "&metric=frf_db", bob); });
  for (auto& t : threads) t.join();
  int accepted = 0, busy = 0;
  for (const auto& r : storm) {
    if (r.status == 200)
      ++accepted;
    else if (r.status == 503 && r.body.find("at most 2 per client") != std::string::npos)
      ++busy;
    else
      ADD_FAILURE() << "alice: " << r.status << " " << r.body.substr(0, 200);
  }
  std::printf("  12 cells of one client at once: %d computed, %d refused to it\n", accepted, busy);
  EXPECT_GE(accepted, 1);
  EXPECT_LE(accepted, 4) << "one client held more than its share";
  for (size_t i = 0; i < bobs.size(); ++i)
    EXPECT_EQ(bobs[i].status, 200) << (i == 0 ? "bob's cell" : "bob's map") << ": " << bobs[i].body.substr(0, 200);
  std::printf("  RSS: %ld kB at first, %ld kB after two cells of 10^6 samples, %ld kB after the storm\n", rss0, rss1,
              RssKb(pid));
  EXPECT_TRUE(Alive(pid));
  ::kill(pid, SIGTERM);
  Wait(pid, 20);
}

// Fail 3: a coordinator the worker cannot trust. A fake one (the Coordinator service, in this test) hands
// the real bistable-worker one lease with hostile values, then nothing; the worker must refuse it (a
// log line naming the field and the bound, the lease released, nothing reported) and stop cleanly on
// SIGTERM — before the fix an ic slot of 10^6 or -10^8 segfaulted it, point -1 hung it and point 2^40 was
// computed and reported.
class FakeCoordinator final : public v1::Coordinator::Service {
 public:
  FakeCoordinator(v1::LeaseReply first, double lease_seconds)
      : first_(std::move(first)), lease_seconds_(lease_seconds) {}
  grpc::Status RegisterWorker(grpc::ServerContext*, const v1::RegisterRequest*, v1::RegisterReply* rep) override {
    rep->set_lease_seconds(lease_seconds_);
    return grpc::Status::OK;
  }
  grpc::Status Lease(grpc::ServerContext*, const v1::LeaseRequest*, v1::LeaseReply* rep) override {
    std::lock_guard<std::mutex> lock(mu_);
    if (leases_++ == 0) *rep = first_;
    return grpc::Status::OK;
  }
  grpc::Status Heartbeat(grpc::ServerContext*, const v1::HeartbeatRequest*, v1::HeartbeatReply* rep) override {
    rep->set_deadline(1e10);
    return grpc::Status::OK;
  }
  grpc::Status Report(grpc::ServerContext*, const v1::ReportRequest* req, v1::ReportReply*) override {
    std::lock_guard<std::mutex> lock(mu_);
    ++reports_;
    report_values_ = req->values_size();
    return grpc::Status::OK;
  }
  grpc::Status Release(grpc::ServerContext*, const v1::ReleaseRequest* req, v1::ReleaseReply*) override {
    std::lock_guard<std::mutex> lock(mu_);
    released_.push_back(req->lease_id());
    return grpc::Status::OK;
  }
  int leases() {
    std::lock_guard<std::mutex> l(mu_);
    return leases_;
  }
  int reports() {
    std::lock_guard<std::mutex> l(mu_);
    return reports_;
  }
  int report_values() {
    std::lock_guard<std::mutex> l(mu_);
    return report_values_;
  }
  std::vector<std::string> released() {
    std::lock_guard<std::mutex> l(mu_);
    return released_;
  }

 private:
  std::mutex mu_;
  v1::LeaseReply first_;
  double lease_seconds_;
  int leases_ = 0, reports_ = 0, report_values_ = 0;
  std::vector<std::string> released_;
};

struct FakeRun {
  int exit_code = -3;
  std::string log;
  int leases = 0, reports = 0, report_values = 0;
  std::vector<std::string> released;
};

// Runs the real worker against a fake coordinator serving `first` until `done(log)` or 15 s, then SIGTERM.
FakeRun RunWorkerAgainst(const std::string& dir, const v1::LeaseReply& first, double lease_seconds,
                         const std::function<bool(const std::string&, FakeCoordinator&)>& done) {
  FakeCoordinator fake(first, lease_seconds);
  grpc::ServerBuilder b;
  int port = 0;
  b.AddListeningPort("127.0.0.1:0", grpc::InsecureServerCredentials(), &port);
  b.RegisterService(&fake);
  auto server = b.BuildAndStart();
  FakeRun r;
  if (!server || port <= 0) return r;
  static int run = 0;
  const std::string log = dir + "/worker" + std::to_string(++run) + ".log";
  const pid_t w = Spawn(
      {BISTABLE_WORKER, "--coordinator", "127.0.0.1:" + std::to_string(port), "--threads", "1", "--name", "victim"},
      log);
  bool exited = false;
  for (int i = 0; i < 300; ++i) {
    int st = 0;
    if (::waitpid(w, &st, WNOHANG) == w) {
      r.exit_code = WIFEXITED(st) ? WEXITSTATUS(st) : -1;
      exited = true;
      break;
    }
    if (done(ReadFile(log + ".err"), fake)) break;
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  }
  if (!exited) {
    ::kill(w, SIGTERM);
    r.exit_code = Wait(w, 20);
  }
  r.log = ReadFile(log + ".err");
  r.leases = fake.leases(), r.reports = fake.reports(), r.report_values = fake.report_values(),
  r.released = fake.released();
  server->Shutdown(std::chrono::system_clock::now() + std::chrono::seconds(1));
  return r;
}

v1::LeaseReply HostileLease(const std::vector<int64_t>& points, const std::vector<int32_t>& ics) {
  v1::LeaseReply l;
  l.set_has_job(true);
  l.set_lease_id("fake-lease-1");
  l.set_sweep_id("0123456789ab");
  l.set_job_id(0);
  // 2 x 2 grid points, two initial states: points in [0, 3], ic slots in [0, 1].
  l.set_spec_toml(Spec("alpha = [0.5, 1.0]\nomega = [0.8, 1.2]\n",
                       "[initial_conditions]\nstates = [[1, 0, 1, 0], [-1, 0, -1, 0]]\n"));
  for (int64_t p : points) l.add_points(p);
  for (int32_t i : ics) l.add_ics(i);
  l.set_deadline(1e10);
  return l;
}

TEST(HostileRound2, WorkerRefusesAHostileLeaseFromAFakeCoordinator) {
  const std::string dir = Round2Dir("fake_coordinator");
  // The control: an honest lease of the fake is computed and reported (the harness works).
  {
    const FakeRun r = RunWorkerAgainst(dir, HostileLease({3, 0}, {0, 1}), 60,
                                       [](const std::string&, FakeCoordinator& f) { return f.reports() > 0; });
    EXPECT_EQ(r.exit_code, 0) << r.log;
    EXPECT_EQ(r.reports, 1) << r.log;
    EXPECT_EQ(r.report_values, static_cast<int>(2 * kWidth)) << r.log;
  }
  struct Case {
    const char* name;
    v1::LeaseReply lease;
    std::string says;  // in the worker's log
    bool released;     // given back (an item refused after the lease was read); else refused at the wire edge
  };
  std::vector<int64_t> million(1'000'000, 0);
  std::vector<int32_t> million_ics(1'000'000, 0);
  const std::vector<Case> cases = {
      {"ic 10^6", HostileLease({0}, {1'000'000}), "ic = 1000000 violates ic in [0, 1]", true},
      {"ic -10^8", HostileLease({1, 2}, {0, -100'000'000}), "lease.items[1]: ic = -100000000 violates ic in [0, 1]",
       true},
      {"point -1", HostileLease({-1}, {0}), "point = -1 violates point in [0, 3]", true},
      {"point 2^40", HostileLease({int64_t{1} << 40}, {0}), "point = 1099511627776 violates point in [0, 3]", true},
      {"point one past the grid", HostileLease({0, 4}, {0, 0}), "lease.items[1]: point = 4 violates point in [0, 3]",
       true},
      {"points and ics of different lengths", HostileLease({0, 1, 2}, {0, 0}), "3 points and 2 initial-condition slots",
       false},
      {"a million items", HostileLease(million, million_ics), "a lease of 1000000 items violates items <= 8192", false},
      {"no items", HostileLease({}, {}), "lease of 0 items violates items in [1, 8192]", true},
  };
  for (const Case& c : cases) {
    SCOPED_TRACE(c.name);
    const FakeRun r = RunWorkerAgainst(dir, c.lease, 60, [&](const std::string& log, FakeCoordinator&) {
      return log.find("lease.refused") != std::string::npos;
    });
    EXPECT_EQ(r.exit_code, 0) << "the worker did not stop cleanly (-1: killed by a signal)\n" << r.log;
    EXPECT_NE(r.log.find(c.says), std::string::npos) << r.log;
    EXPECT_EQ(r.reports, 0) << "a hostile lease was computed and reported";
    if (c.released) {
      EXPECT_EQ(r.released, std::vector<std::string>{"fake-lease-1"}) << r.log;
    }
  }
  // A lease period the worker cannot heartbeat by: refused at registration, exit 2, not slept on.
  for (double bad : {std::nan(""), -1.0, 0.0, 1e300}) {
    const FakeRun r =
        RunWorkerAgainst(dir, HostileLease({0}, {0}), bad, [](const std::string&, FakeCoordinator&) { return false; });
    EXPECT_EQ(r.exit_code, 2) << bad << "\n" << r.log;
    EXPECT_NE(r.log.find("lease_seconds"), std::string::npos) << bad << "\n" << r.log;
    EXPECT_EQ(r.leases, 0);
  }
}

}  // namespace
