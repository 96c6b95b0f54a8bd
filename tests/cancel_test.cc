// Cooperative cancellation (dynamics/cancel.h): the integration loops stop soon after the flag is
// set and return "cancelled", never a result; with the flag clear nothing changes. And end to end,
// as real processes: Ctrl-C / SIGTERM stop `bistable point`, `bistable run` and `bistable-worker`
// within a second on long points, nothing partial is stored, and a rerun / another worker finishes
// the sweep to the same map bit for bit.
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <future>
#include <thread>
#include <vector>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "dynamics/cancel.h"
#include "dynamics/chirp.h"
#include "dynamics/generic_point.h"
#include "dynamics/hbm.h"
#include "dynamics/point.h"
#include "dynamics/series_model.h"
#include "engine/evaluate.h"
#include "engine/sweep_spec.h"
#include "storage/index_db.h"
#include "tests/map_compare.h"
#include "tests/process_util.h"

namespace bistable {
namespace {

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

double Since(Clock::time_point t0) { return std::chrono::duration<double>(Clock::now() - t0).count(); }

// A chaotic coupled point (any rounding difference would grow exponentially); the window is the last
// 250 time units however long the run.
PointSpec ChaoticPoint(double t_end) {
  PointSpec s;
  s.model = ModelKind::kCoupled;
  s.alpha = 2.0;
  s.omega = 1.2;
  s.integration.t_end = t_end;
  s.integration.t_keep = t_end - 250;
  s.metrics.rosenstein = false;
  return s;
}

bool SameBits(double a, double b) { return std::memcmp(&a, &b, sizeof a) == 0; }

void ExpectSameRaw(const RawLane& a, const RawLane& b) {
  EXPECT_TRUE(SameBits(a.vabs_max, b.vabs_max));
  EXPECT_TRUE(SameBits(a.log_growth, b.log_growth));
  EXPECT_TRUE(SameBits(a.y_min, b.y_min) && SameBits(a.y_max, b.y_max));
  EXPECT_TRUE(SameBits(a.q_p, b.q_p) && SameBits(a.q_in, b.q_in) && SameBits(a.q_m, b.q_m) && SameBits(a.q_r, b.q_r));
  EXPECT_TRUE(SameBits(a.e_start, b.e_start) && SameBits(a.e_end, b.e_end));
  for (int d = 0; d < 4; ++d) EXPECT_TRUE(SameBits(a.final_state[d], b.final_state[d])) << d;
  EXPECT_EQ(a.strobe_y, b.strobe_y);
  EXPECT_EQ(a.y_samples, b.y_samples);
  EXPECT_EQ(a.steps, b.steps);
  EXPECT_EQ(a.diverged, b.diverged);
}

TEST(Cancel, FlagIsStickyAndScopedResetClearsIt) {
  {
    ScopedCancelReset reset;
    EXPECT_FALSE(CancelRequested());
    RequestCancel();
    EXPECT_TRUE(CancelRequested());
    EXPECT_TRUE(CancelRequested());
    EXPECT_EQ(CancelSignal(), 0);
    EXPECT_EQ(CancelExitStatus(), 130);
  }
  EXPECT_FALSE(CancelRequested());
}

// The handlers: the first SIGINT/SIGTERM sets the flag and is remembered (exit status 128 + signal);
// a second one ends the process with the default action; a SIGINT ignored on entry stays ignored.
// Each case runs in a forked child so the test process keeps its own dispositions.
TEST(Cancel, SignalHandlersSetTheFlagOnceAndASecondSignalEndsTheProcess) {
  auto in_child = [](auto body) {
    std::fflush(nullptr);
    const pid_t pid = ::fork();
    if (pid == 0) ::_exit(body());
    int status = 0;
    ::waitpid(pid, &status, 0);
    return status;
  };
  for (int sig : {SIGINT, SIGTERM}) {
    const int first = in_child([sig] {
      ::signal(SIGINT, SIG_DFL);
      InstallCancelSignalHandlers();
      ::raise(sig);
      return CancelRequested() && CancelSignal() == sig && CancelExitStatus() == 128 + sig ? 0 : 1;
    });
    EXPECT_TRUE(WIFEXITED(first) && WEXITSTATUS(first) == 0) << strsignal(sig);
    const int second = in_child([sig] {
      ::signal(SIGINT, SIG_DFL);
      InstallCancelSignalHandlers();
      ::raise(sig);
      ::raise(sig);  // ends the process here
      return 0;
    });
    EXPECT_TRUE(WIFSIGNALED(second) && WTERMSIG(second) == sig) << strsignal(sig);
  }
  const int ignored = in_child([] {
    ::signal(SIGINT, SIG_IGN);
    InstallCancelSignalHandlers();
    ::raise(SIGINT);
    if (CancelRequested()) return 1;
    ::raise(SIGTERM);
    return CancelRequested() && CancelSignal() == SIGTERM ? 0 : 2;
  });
  EXPECT_TRUE(WIFEXITED(ignored) && WEXITSTATUS(ignored) == 0) << WEXITSTATUS(ignored);
}

// (3) The kernel with the flag set stops at its first poll (step kCancelCheckSteps) and says so.
TEST(Cancel, KernelWithTheFlagSetReturnsCancelledAtItsFirstPoll) {
  ScopedCancelReset reset;
  const PointSpec s = ChaoticPoint(1e6);  // 1e8 steps: minutes if it ran
  KernelSettings ks = KernelSettingsFor(s);
  std::vector<LaneInput> lanes(kSweepLanes, LaneFor(s));
  std::vector<RawLane> out(kSweepLanes);
  RequestCancel();
  const auto t0 = Clock::now();
  EXPECT_FALSE(RunKernel<kSweepLanes>(s.model, lanes.data(), kSweepLanes, ks, out.data()));
  EXPECT_FALSE(RunKernel<1>(s.model, lanes.data(), 1, ks, out.data()));
  EXPECT_LT(Since(t0), 0.1);
  for (const RawLane& r : out) {
    EXPECT_TRUE(r.diverged);  // no result: nothing that reads like a finished point
    EXPECT_EQ(r.steps, kCancelCheckSteps);
  }
  auto point = EvaluatePoint(s);
  ASSERT_FALSE(point.ok());
  EXPECT_NE(point.status().message().find("cancelled"), std::string::npos) << point.status().ToString();
}

// (3) With the flag clear the kernel runs to the end with the same bits as ever: a run after a
// cancelled one equals a run in a fresh state, at lane width 1 and 8, and EvaluatePoint (1 lane)
// equals lane 3 of an 8-lane block. (bench/bench_kernel and a same-process comparison against the
// pre-cancellation kernel were used when the poll was added; see the session report.)
TEST(Cancel, KernelWithTheFlagClearGivesTheSameBitsAsAFreshRun) {
  ScopedCancelReset reset;
  const PointSpec s = ChaoticPoint(3000);  // 300,000 steps: 292 polls
  const KernelSettings ks = KernelSettingsFor(s);
  std::vector<LaneInput> lanes(kSweepLanes, LaneFor(s));
  for (int l = 0; l < kSweepLanes; ++l) lanes[l].omega = 0.9 + 0.1 * l;
  lanes[3].omega = s.omega;
  std::vector<RawLane> first(kSweepLanes), again(kSweepLanes), one(1);
  ASSERT_TRUE(RunKernel<kSweepLanes>(s.model, lanes.data(), kSweepLanes, ks, first.data()));
  {
    RequestCancel();
    std::vector<RawLane> cut(kSweepLanes);
    EXPECT_FALSE(RunKernel<kSweepLanes>(s.model, lanes.data(), kSweepLanes, ks, cut.data()));
  }
  ScopedCancelReset clear;
  ASSERT_TRUE(RunKernel<kSweepLanes>(s.model, lanes.data(), kSweepLanes, ks, again.data()));
  for (int l = 0; l < kSweepLanes; ++l) ExpectSameRaw(first[l], again[l]);
  ASSERT_TRUE(RunKernel<1>(s.model, &lanes[3], 1, ks, one.data()));
  ExpectSameRaw(one[0], first[3]);
  EXPECT_EQ(first[3].steps, 300000);
  EXPECT_FALSE(first[3].diverged);
  auto point = EvaluatePoint(s);
  ASSERT_TRUE(point.ok()) << point.status().ToString();
  const PointResult direct = ComputePointMetrics(std::move(first[3]), s);
  EXPECT_TRUE(SameBits(point->frf_db, direct.frf_db));
  EXPECT_TRUE(SameBits(point->lle, direct.lle));
  EXPECT_GT(point->lle, 0.01) << "the point is meant to be chaotic";
}

// Set from another thread while a 1e8-step point runs: EvaluatePoint returns "cancelled" within
// milliseconds (one poll = 1024 steps ≈ 30 µs on one lane).
TEST(Cancel, RequestFromAnotherThreadStopsALongPointWithinMilliseconds) {
  ScopedCancelReset reset;
  const PointSpec s = ChaoticPoint(9e5);
  auto run = std::async(std::launch::async, [&] {
    auto r = EvaluatePoint(s);
    return std::make_pair(r.ok(), Clock::now());
  });
  std::this_thread::sleep_for(std::chrono::milliseconds(200));
  const auto t_request = Clock::now();
  RequestCancel();
  const auto [ok, t_done] = run.get();
  EXPECT_FALSE(ok);
  ASSERT_GT(t_done, t_request) << "the point did not run until the request";
  const double latency = std::chrono::duration<double>(t_done - t_request).count();
  EXPECT_LT(latency, 0.05);
  std::printf("in-process stop latency (1 lane, 9e7-step point): %.3f ms\n", 1e3 * latency);
}

TEST(Cancel, AdaptiveGenericChirpAndHbmStopToo) {
  ScopedCancelReset reset;
  RequestCancel();
  const auto t0 = Clock::now();
  PointSpec a = ChaoticPoint(1e5);
  a.integration.integrator = IntegratorKind::kAdaptive;
  EXPECT_FALSE(EvaluatePoint(a).ok());

  // The generic window (series chains, the dimensional model): RK4 and adaptive.
  const SeriesModel m = SeriesModel::Uniform(3, SeriesCell{}, 1.0, 1.2);
  GenericWindow w;
  w.t_end = 1e5;
  w.t_keep = 5e4;
  w.position = [](const Eigen::VectorXd& x) { return x[0]; };
  w.velocity = [](const Eigen::VectorXd& x) { return x[1]; };
  for (bool adaptive : {false, true}) {
    w.adaptive = adaptive;
    bool cancelled = false;
    const RawLane r = RunGenericWindow(m, m.WellState(), w, &cancelled);
    EXPECT_TRUE(cancelled) << adaptive;
    EXPECT_TRUE(r.diverged) << adaptive;
  }

  ChirpOptions c;
  c.duration = 4e5;
  auto chirp = RunChirp(c);
  ASSERT_FALSE(chirp.ok());
  EXPECT_NE(chirp.status().message().find("cancelled"), std::string::npos);

  HbmOptions h;
  auto hbm = ContinueBranches(h);
  ASSERT_FALSE(hbm.ok());
  EXPECT_NE(hbm.status().message().find("cancelled"), std::string::npos);
  EXPECT_LT(Since(t0), 0.5);
}

// A sweep job computed while cancellation is requested yields no records at all (kernel, adaptive
// and continuation paths); ComputeItems' empty answer is refused by any coordinator for its size.
TEST(Cancel, ASweepJobThatSawTheFlagHasNoRecords) {
  ScopedCancelReset reset;
  for (const char* extra : {"", "[integration]\nintegrator = \"adaptive\"\n", "[continuation]\naxis = \"omega\"\n"}) {
    const std::string toml =
        std::string("model = \"coupled\"\n[axes]\nalpha = [0.5, 1.0]\nomega = [1.0, 1.2, 1.4, 1.6]\n") + extra;
    auto spec = ParseSweepSpec(toml, "cancel");
    ASSERT_TRUE(spec.ok()) << extra << spec.status().ToString();
    std::vector<WorkItem> items;
    for (long p = 0; p < spec->points(); ++p) items.push_back({p, 0});
    ScopedCancelReset clear;
    auto whole = ComputeItemsUnlessCancelled(*spec, items);
    ASSERT_TRUE(whole.has_value()) << extra;
    EXPECT_EQ(whole->size(), items.size());
    RequestCancel();
    EXPECT_FALSE(ComputeItemsUnlessCancelled(*spec, items).has_value()) << extra;
    EXPECT_TRUE(ComputeItems(*spec, items).empty()) << extra;
  }
}

// ---- real processes ----

struct Child {
  pid_t pid = -1;
  std::string err_file;
};

Child Spawn(const std::vector<std::string>& argv, const std::string& log) {
  return {bistable_test::SpawnLogged(argv, log), log + ".err"};
}

int WaitFor(pid_t pid, double seconds) { return bistable_test::WaitStatusFor(pid, seconds); }

std::string Slurp(const std::string& path) { return bistable_test::ReadText(path); }

std::string Dir(const std::string& name) { return bistable_test::FreshDir("bistable_cancel", name); }

// Sends `sig` to `pid` and waits up to `wait_s` seconds for it to end: its wait status (-1: still
// running, or the signal could not be sent) and the seconds from the signal to the end.
struct Stopped {
  int status = -1;
  double latency = 0;
};
Stopped SignalAndWait(pid_t pid, int sig, double wait_s) {
  const auto t_signal = Clock::now();
  if (::kill(pid, sig) != 0) return {};
  const int status = WaitFor(pid, wait_s);
  return {status, Since(t_signal)};
}

// (1) `bistable point` of 9e7 steps (minutes to the end), signalled after 0.5 s: it stops within
// 1.5 s of the signal with 128 + signal and a message, printing no result.
void PointStopsOnSignal(int sig) {
  const std::string dir = Dir(sig == SIGINT ? "point_int" : "point_term");
  const Child c = Spawn({BISTABLE_CLI, "point", "--alpha", "1", "--omega", "1.2", "--t-end", "900000", "--t-keep",
                         "899000", "--no-rosenstein", "--json"},
                        dir + "/out.txt");
  std::this_thread::sleep_for(std::chrono::milliseconds(500));
  const auto [status, latency] = SignalAndWait(c.pid, sig, 10);
  ASSERT_NE(status, -1) << "bistable point did not stop within 10 s of " << strsignal(sig);
  std::printf("bistable point, %s after 0.5 s: stopped in %.3f s\n", strsignal(sig), latency);
  EXPECT_LT(latency, 1.5);
  ASSERT_TRUE(WIFEXITED(status)) << "killed by the signal instead of stopping cleanly";
  EXPECT_EQ(WEXITSTATUS(status), 128 + sig);
  EXPECT_NE(Slurp(c.err_file).find("interrupted"), std::string::npos) << Slurp(c.err_file);
  EXPECT_EQ(Slurp(dir + "/out.txt"), "") << "a cancelled point prints no result";
  fs::remove_all(dir);
}

TEST(CancelCli, PointStopsWithinASecondOfCtrlC) { PointStopsOnSignal(SIGINT); }
TEST(CancelCli, PointStopsWithinASecondOfSigterm) { PointStopsOnSignal(SIGTERM); }

// (1b) `bistable identify` (the synthetic records' friction loop, several seconds), Ctrl-C after 1.5 s: every
// simulation stops at its next sample and the loop ends — within 1.5 s, 130, nothing printed, no report.
TEST(CancelCli, IdentifyStopsWithinASecondOfCtrlCAndWritesNothing) {
  const std::string dir = Dir("identify");
  ASSERT_EQ(std::system((std::string(BISTABLE_CLI) + " identify --make-synthetic " + dir + "/syn > /dev/null").c_str()),
            0);
  const Child c = Spawn({BISTABLE_CLI, "identify", "--data", dir + "/syn/chirp_6mm.csv", "--data",
                         dir + "/syn/chirp_10mm.csv", "--data", dir + "/syn/chirp_14mm.csv", "--known", "m_main=0.282",
                         "--terms", "main.linear,main.viscous,main.damping_y2", "--report", dir + "/report", "--json"},
                        dir + "/out.txt");
  std::this_thread::sleep_for(std::chrono::milliseconds(1500));
  const auto [status, latency] = SignalAndWait(c.pid, SIGINT, 20);
  ASSERT_NE(status, -1) << "bistable identify did not stop within 20 s of SIGINT";
  std::printf("bistable identify, SIGINT after 1.5 s: stopped in %.3f s\n", latency);
  EXPECT_LT(latency, 1.5);
  ASSERT_TRUE(WIFEXITED(status)) << "killed by the signal instead of stopping cleanly";
  EXPECT_EQ(WEXITSTATUS(status), 130) << Slurp(c.err_file);
  EXPECT_NE(Slurp(c.err_file).find("interrupted"), std::string::npos) << Slurp(c.err_file);
  EXPECT_EQ(Slurp(dir + "/out.txt"), "") << "a cancelled identification prints no result";
  EXPECT_FALSE(fs::exists(dir + "/report")) << "nor writes a report";
  fs::remove_all(dir);
}

// Long points: 2e7 steps each (t_end 2e5), so one 8-item job is about a second of kernel work.
constexpr const char* kLongPoints = R"(
name = "cancel test"
model = "coupled"
[axes]
alpha = [0.5, 1.0, 1.5]
omega = [0.8, 1.0, 1.2, 1.4, 1.6, 1.8, 2.0, 2.2]
[integration]
t_end = 200000.0
t_keep = 199750.0
)";

long PointsDone(const std::string& data) {
  if (!fs::exists(data + "/index.sqlite")) return 0;
  auto db = IndexDb::Open(data + "/index.sqlite");
  if (!db.ok()) return 0;
  auto rows = (*db)->ListSweeps();
  return rows.ok() && !rows->empty() ? (*rows)[0].items_done : 0;
}

// (2) `bistable run` of long points, Ctrl-C once the first job is stored: it stops within 1.5 s with
// 130, stores nothing of the job in flight, and a rerun finishes to the uninterrupted run's map.
TEST(CancelCli, RunStopsWithinASecondOfCtrlCAndResumesToTheSameMap) {
  const std::string dir = Dir("run");
  const std::string spec = dir + "/spec.toml", data = dir + "/data";
  std::ofstream(spec) << kLongPoints;
  const Child c = Spawn({BISTABLE_CLI, "run", spec, "--data", data, "--threads", "1", "--job-items", "8", "--no-plots"},
                        dir + "/run.txt");
  const auto deadline = Clock::now() + std::chrono::seconds(120);
  while (PointsDone(data) < 8 && Clock::now() < deadline) std::this_thread::sleep_for(std::chrono::milliseconds(5));
  ASSERT_GE(PointsDone(data), 8) << Slurp(c.err_file);
  std::this_thread::sleep_for(std::chrono::milliseconds(200));  // well inside the second job
  const auto [status, latency] = SignalAndWait(c.pid, SIGINT, 30);
  ASSERT_NE(status, -1) << "bistable run did not stop within 30 s of SIGINT";
  std::printf("bistable run (8-lane jobs of 2e7-step points), SIGINT: stopped in %.3f s\n", latency);
  EXPECT_LT(latency, 1.5);
  ASSERT_TRUE(WIFEXITED(status));
  EXPECT_EQ(WEXITSTATUS(status), 130);
  const std::string err = Slurp(c.err_file);
  EXPECT_NE(err.find("interrupted"), std::string::npos) << err;
  const long stored = PointsDone(data);
  EXPECT_EQ(stored % 8, 0) << "only whole jobs are stored";
  ASSERT_LT(stored, 24) << "the run finished before it could be interrupted";
  {
    auto db = IndexDb::Open(data + "/index.sqlite");
    ASSERT_TRUE(db.ok());
    auto rows = (*db)->ListSweeps();
    ASSERT_TRUE(rows.ok() && rows->size() == 1u);
    EXPECT_EQ((*rows)[0].state, bistable::SweepState::kInterrupted);
    EXPECT_EQ((*rows)[0].file, "");
  }

  const auto resume = bistable_test::Bistable("run " + spec + " --data " + data + " --json --no-plots");
  ASSERT_EQ(resume.exit_code, 0) << resume.err;
  const auto j = nlohmann::json::parse(resume.out);
  EXPECT_EQ(j["cached"], stored) << "every stored job is reused";
  EXPECT_EQ(j["computed"].get<long>() + stored, 24);
  const auto clean = bistable_test::Bistable("run " + spec + " --data " + dir + "/clean --json --no-plots");
  ASSERT_EQ(clean.exit_code, 0) << clean.err;
  bistable_test::ExpectSameMaps(j["files"][0], nlohmann::json::parse(clean.out)["files"][0]);
  fs::remove_all(dir);
}

// bistable-worker on long points, SIGTERM mid-job: it stops within 1.5 s, exits 0, and releases its
// lease — the lease period is 60 s, so a second worker finishing the sweep well before that shows
// the job was given back, not left to expire. The map equals the embedded run's bit for bit.
TEST(CancelCli, WorkerStopsWithinASecondOfSigtermAndReleasesItsLease) {
  const std::string dir = Dir("worker");
  const std::string spec = dir + "/spec.toml";
  std::ofstream(spec) << kLongPoints;
  const std::string log = dir + "/coord.log";
  const Child coord = Spawn({BISTABLE_COORDINATOR, "--listen", "127.0.0.1:0", "--data", dir + "/data",
                             "--lease-seconds", "60", "--job-seconds", "0.01"},
                            log);
  std::string addr;
  for (int i = 0; i < 400 && addr.empty(); ++i) {
    std::ifstream in(log);
    std::string line;
    if (std::getline(in, line) && line.rfind("listening on ", 0) == 0)
      addr = line.substr(13);
    else
      std::this_thread::sleep_for(std::chrono::milliseconds(25));
  }
  ASSERT_FALSE(addr.empty()) << "coordinator did not start: " << Slurp(coord.err_file);
  const Child w1 = Spawn({BISTABLE_WORKER, "--coordinator", addr, "--threads", "1", "--name", "w1"}, dir + "/w1.log");
  const auto sub = bistable_test::Bistable("submit " + spec + " --json --coordinator " + addr);
  ASSERT_EQ(sub.exit_code, 0) << sub.err;
  const std::string id = nlohmann::json::parse(sub.out)["id"];
  auto leases_of = [&](const std::string& name) {
    const auto r = bistable_test::Bistable("workers --json --coordinator " + addr);
    if (r.exit_code != 0) return -1;
    for (const auto& w : nlohmann::json::parse(r.out))
      if (w["name"] == name) return w["leases"].get<int>();
    return -1;
  };
  const auto deadline = Clock::now() + std::chrono::seconds(60);
  while (leases_of("w1") < 1 && Clock::now() < deadline) std::this_thread::sleep_for(std::chrono::milliseconds(20));
  ASSERT_GE(leases_of("w1"), 1) << Slurp(w1.err_file);
  std::this_thread::sleep_for(std::chrono::milliseconds(300));
  const auto [status, latency] = SignalAndWait(w1.pid, SIGTERM, 30);
  ASSERT_NE(status, -1) << "bistable-worker did not stop within 30 s of SIGTERM";
  std::printf("bistable-worker (8-lane job of 2e7-step points), SIGTERM: stopped in %.3f s\n", latency);
  EXPECT_LT(latency, 1.5);
  ASSERT_TRUE(WIFEXITED(status));
  EXPECT_EQ(WEXITSTATUS(status), 0);
  EXPECT_NE(Slurp(w1.err_file).find("released"), std::string::npos) << Slurp(w1.err_file);
  EXPECT_EQ(leases_of("w1"), 0) << "the lease was given back";

  const auto t_second = Clock::now();
  const Child w2 = Spawn({BISTABLE_WORKER, "--coordinator", addr, "--threads", "2", "--name", "w2"}, dir + "/w2.log");
  nlohmann::json st;
  while (Since(t_second) < 45) {
    const auto r = bistable_test::Bistable("status " + id + " --json --coordinator " + addr);
    if (r.exit_code <= 1 && !r.out.empty()) st = nlohmann::json::parse(r.out);
    if (st.value("state", "") == "done") break;
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
  }
  ASSERT_EQ(st.value("state", ""), "done")
      << "the released job was not requeued (the lease would expire only after 60 s)";
  ::kill(w2.pid, SIGTERM);
  EXPECT_NE(WaitFor(w2.pid, 10), -1);
  ::kill(coord.pid, SIGTERM);
  WaitFor(coord.pid, 10);
  const auto embedded =
      bistable_test::Bistable("run " + spec + " --data " + dir + "/embedded --json --no-plots --quiet");
  ASSERT_EQ(embedded.exit_code, 0) << embedded.err;
  bistable_test::ExpectSameMaps(dir + "/data/" + st["file"].get<std::string>(),
                                nlohmann::json::parse(embedded.out)["files"][0]);
  fs::remove_all(dir);
}

}  // namespace
}  // namespace bistable
