// The coordinator of sweeps over one data directory. It plans each sweep against the point cache,
// queues the missing items as jobs, leases jobs to workers with deadlines (an expired lease returns its
// job to the queue), stores each reported job durably in one transaction before acknowledging it,
// and publishes a sweep's HDF5 map when its last job is stored. The embedded `bistable run` drives
// it with in-process worker threads; `bistable-coordinator` drives the same class over gRPC.
//
// It is the composition of four parts (issue 40; docs/architecture.md, "The coordinator's parts"):
// each sweep's plan (engine/sweep_plan.h: jobs, what next; no locks, no I/O), the lease table
// (server/lease_table.h, on the injected clock), the result writer (storage/result_writer.h: the index
// connection, group commit, checkpoints) and the publisher (server/publisher.h: the one thread that
// publishes maps and plans refined sweeps' next rounds). The coordinator holds the plans and the lease
// table under its lock and decides; the parts do not call each other.
//
// Durability: sweeps (spec, status) and every acknowledged result live in SQLite (WAL). Jobs and
// leases are derived state: on Open, every unfinished sweep is planned again against the point
// cache, so a restarted coordinator continues each sweep and recomputes only unacknowledged work.
// Every lease belongs to one plan of its sweep (a generation): cancelling or replanning a sweep revokes
// its leases, and a report is checked against its lease's own job (item count, record layout, every
// value in its metric's domain) before anything is stored. Limits: base/limits.h.
// Thread-safe: every public method may be called from any thread; planning runs outside the main
// lock, so a big submit does not hold up leases, reports or status calls.
#ifndef BISTABLE_SERVER_SWEEP_COORDINATOR_H_
#define BISTABLE_SERVER_SWEEP_COORDINATOR_H_

#include <array>
#include <condition_variable>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include "base/log.h"
#include "engine/metric_catalog.h"
#include "engine/sweep_plan.h"
#include "engine/sweep_spec.h"
#include "server/lease_table.h"
#include "server/publisher.h"
#include "storage/index_db.h"
#include "storage/result_writer.h"

namespace bistable {

struct SweepPlan {
  std::string id;
  long items_total = 0;   // grid points × initial conditions
  long items_cached = 0;  // already stored under their content key (reused, not recomputed)
  long jobs = 0;
  bool already_published = false;  // done before, map file present: nothing to do
};

struct SweepProgress {
  long items_total = 0, items_done = 0, items_cached = 0;
  int refine_round = -1;  // a refined sweep's round being computed (0: the coarse grid); -1 for any other sweep
};

// A granted lease: the job's items of one sweep, to be reported before `deadline`.
struct LeaseGrant {
  std::string lease_id;  // opaque, unique, unguessable: the sweep id and 128 random bits
  std::string sweep_id;
  std::string spec_key;  // SHA-256 of the sweep's spec text (proto/convert.h's SpecKey): the text itself is
                         // the coordinator's SpecText, fetched once per sweep by whoever lacks it
  long job_id = 0;       // the first job of the lease
  int jobs = 1;          // jobs merged into this lease
  std::vector<WorkItem> items;
  double deadline = 0;  // unix seconds (the wire's; the coordinator keeps its own on the monotonic clock)
};

// Counters since this process started and gauges now, for metrics (server/metrics.h).
struct CoordinatorStats {
  long leases_granted = 0, leases_expired = 0, leases_released = 0;
  long reports_stored = 0, reports_duplicate = 0, reports_failed = 0;
  long items_stored = 0;  // items of stored reports (counted once per job)
  long leases_outstanding = 0, jobs_queued = 0, items_pending = 0, workers_active = 0;
  std::array<long, 6> sweeps_by_state{};  // indexed by SweepState
  std::vector<WorkerInfo> workers;
};

class SweepCoordinator {
 public:
  struct Options {
    double lease_seconds = 60;  // a lease not reported or extended within this is requeued
    bool resume = true;         // on Open, plan every unfinished sweep of the index again (the service);
                                // the embedded `bistable run` handles only the sweep it submits
    bool log = true;            // events (storage failures, corrupt results, replans) to stderr; the
                                // embedded run turns it off and reports through its Status instead
    // Seconds: unix time for timestamps and, when set, also the clock of lease deadlines (tests step it);
    // empty: the system clock for timestamps and the monotonic clock for deadlines, so a stepped wall clock
    // (NTP, a resumed VM) neither expires every lease at once nor keeps a dead worker's job.
    std::function<double()> clock = nullptr;
    std::function<double()> monotonic = nullptr;       // the deadlines' clock when set (tests: a wall clock that jumps)
    std::function<void()> before_index_row = nullptr;  // tests: runs when a map file is written, before its index row
    // Repairs of the data directory, one sentence each naming the files (a damaged index or map moved aside
    // and made again, map files indexed again, stored points that failed their checksum): also logged as
    // warn events when `log` is on; the embedded run prints them as warnings (its log is off).
    std::function<void(const std::string&)> warn = nullptr;
  };

  // Opens <data>/index.sqlite and <data>/sweeps/ (creating them; repairing a damaged index and indexing
  // map files it has no row for: storage/data_dir.h, OpenDataIndex) and resumes unfinished sweeps.
  static StatusOr<std::unique_ptr<SweepCoordinator>> Open(const std::string& data_dir, Options opt);
  static StatusOr<std::unique_ptr<SweepCoordinator>> Open(const std::string& data_dir) {
    return Open(data_dir, Options{});
  }
  // Finishes queued publications, then stops the publisher thread.
  ~SweepCoordinator();

  // Registers the sweep (id = hash of its canonical spec), looks its items up in the point cache and
  // queues the missing ones as jobs of about `job_items` items. Submitting a running sweep again is
  // harmless (its plan is returned). `owner` is the submitter's identity; each owner may have
  // limits::kMaxActiveSweepsPerOwner sweeps queued or running (limits::kMaxActiveSweeps in all).
  StatusOr<SweepPlan> Submit(const SweepSpec& spec, long job_items, const std::string& owner = "local") {
    return SubmitImpl(spec, job_items, owner, true);
  }
  // The next queued job of the oldest running sweep, after requeueing expired leases; nullopt when
  // there is none (or after Stop()).
  // `only_sweep` restricts the lease to one sweep (the embedded run).
  // `max_jobs` > 1 merges up to that many queued jobs of the sweep into one lease (a larger job for a
  // worker far away or with many cores: one round trip and one stored report for all of them) while
  // their items total at most limits::kMaxJobItems; the lease stands or falls as a whole.
  // `identity` is the caller's authenticated identity (a token's; "" in the embedded run): the lease is
  // bound to it, and Extend, Report and Release of it by any other identity are PermissionDenied.
  std::optional<LeaseGrant> Lease(const std::string& worker, const std::string& only_sweep = "", int max_jobs = 1,
                                  const std::string& identity = "");
  // Pushes a lease's deadline back by lease_seconds. NotFound for an unknown lease, FailedPrecondition
  // for an expired one.
  Status Extend(const std::string& lease_id, const std::string& identity = "");
  // Stores a lease's records (one transaction) and acknowledges; publishes the sweep when complete.
  // A lease reported again after success is acknowledged without storing anything twice. `values`
  // holds the job's items × `width` doubles in the lease's item order; the lease, its plan, the
  // count, the width and every value's domain are checked before anything is stored.
  Status Report(const std::string& lease_id, size_t width, const double* values, size_t n_values,
                const std::string& identity = "");
  Status Report(const std::string& lease_id, const std::vector<PointRecord>& records, const std::string& identity = "");
  // Gives a lease's job back to the queue (a worker shutting down).
  Status Release(const std::string& lease_id, const std::string& identity = "");
  Status Cancel(const std::string& sweep_id);
  // Asks the publisher (the one place a publication starts) for the sweep's next step and waits for it:
  // a sweep whose items are all stored has its records gathered from the cache, its map written
  // atomically and is marked done (idempotent); a refined sweep whose round is stored has its next round
  // planned instead (FailedPrecondition "refining": compute that round, then ask again). A write failure
  // marks the sweep failed. The last report of a sweep or round asks for this without waiting; clients
  // wait for state "done".
  StatusOr<std::string> Publish(const std::string& sweep_id) { return publisher_->Run(sweep_id); }
  Status MarkInterrupted(const std::string& sweep_id);
  void Stop();

  StatusOr<SweepInfo> Info(const std::string& sweep_id) const;
  // Waits up to `seconds` for the sweep to reach a final state (done, failed, cancelled) and returns
  // its info then or at the timeout: watchers learn of completion at once, not at their next poll.
  StatusOr<SweepInfo> AwaitFinal(const std::string& sweep_id, double seconds) const;
  std::vector<WorkerInfo> Workers() const;
  CoordinatorStats Stats() const;
  // A sweep id from an id or a unique prefix (hex digits only, at most limits::kMaxIdBytes).
  StatusOr<std::string> ResolveId(const std::string& id_or_prefix) const;
  // Every sweep of the index, oldest first, as Info reports it.
  StatusOr<std::vector<SweepInfo>> ListSweeps() const;
  // The spec text (TOML) of a sweep, for workers that parse it themselves and the dashboard: the plan's
  // in memory, else the index row's (a sweep finished before this process started). With `spec_key`, also
  // the text's key (SHA-256, proto/convert.h's SpecKey; the plan's is computed once per plan).
  StatusOr<std::string> SpecText(const std::string& sweep_id, std::string* spec_key = nullptr) const;
  // The result writer's counters (tests: group commit, checkpoints).
  const ResultWriter& writer() const { return *writer_; }
  SweepProgress progress(const std::string& sweep_id) const;
  // What is stored so far of a planned (queued or running) sweep: scalar metric `metric` (a catalog
  // name) for every item in grid order (point · ic_count + ic; a refined sweep: every grid point), NaN where nothing is
  // stored yet, looked up by content key in the point cache (read transactions of at most 16,384 keys each). NotFound
  // when the sweep has no plan in memory (published, cancelled or unknown: read its map file instead). For live views.
  StatusOr<std::vector<double>> StoredValues(const std::string& sweep_id, const std::string& metric) const;
  const std::string& data_dir() const { return data_dir_; }
  std::string MapPath(const std::string& id) const;

 private:
  struct Sweep {
    SweepSpec spec;
    std::string spec_key;  // SHA-256 of spec.source, computed once per plan: what each lease carries
    SweepRow row;
    unsigned long long generation = 0;  // this plan's number: leases of other plans are void
    JobPlan plan;                       // the items, jobs and what next (engine/sweep_plan.h)
    long job_items = 0;                 // items per job as submitted (replans and refinement rounds keep it)
    long seq = 0;                       // submission order
    bool cancelled = false, any_leased = false;
    bool publishing = false;  // its map is being written and indexed: a cancel now is refused
    std::string error;        // last storage / publication failure, for status
    double started = 0;
  };
  // A plan built outside mu_: the sweep's keys, its jobs against the point cache.
  struct Planned {
    Sweep sweep;
    SweepPlan plan;
  };

  SweepCoordinator(std::string dir, std::unique_ptr<IndexDb> db, Options opt);
  // Submit; `limits` false when Open resumes sweeps the index already holds (accepted before: a restart
  // must not fail the ninth interrupted sweep of an owner).
  StatusOr<SweepPlan> SubmitImpl(const SweepSpec& spec, long job_items, const std::string& owner, bool limits);
  // Plans a sweep against the point cache (JobPlan::Build with lookups in bounded batches; a published
  // sweep's map checked). Without mu_.
  StatusOr<Planned> BuildPlan(const SweepSpec& spec, long job_items, RefineCarry carry = {});
  // Makes a built plan the sweep's current one (a new generation) and persists its row. Under mu_.
  StatusOr<SweepPlan> InstallLocked(Planned p, const std::string& owner);
  // The plan of an active (not cancelled) sweep, if any. Under mu_.
  std::optional<SweepPlan> ActivePlanLocked(const std::string& id) const;
  // Plans the sweep again (stored items that went missing or failed their checksum are recomputed; a
  // refined sweep's next round).
  Status Replan(const std::string& id);
  // The publisher's step (its thread only): publishes the sweep, or plans a refined sweep's next round.
  StatusOr<std::string> PublishStep(const std::string& sweep_id);
  // Drops every lease of a sweep (cancel, replan). Under mu_.
  void RevokeLeasesLocked(const std::string& sweep_id);
  // Frees a finished or cancelled sweep's plan (keys, jobs) and returns the memory to the system.
  static void FreePlan(Sweep& s);
  void TouchWorkerLocked(const std::string& worker, double now);
  void LeaseEndedLocked(const std::string& worker);  // the worker holds one lease fewer
  void RequeueExpiredLocked();
  double Clock() const;      // unix seconds (timestamps)
  double Monotonic() const;  // seconds of the monotonic clock (lease deadlines)
  // A structured event (base/log.h), unless Options::log is off.
  void Log(log::Level level, std::string_view event, std::initializer_list<log::Field> fields) const;
  // A repair of the data directory: a warn event with the sentence (unless Options::log is off), and the
  // sentence to Options::warn.
  void Repaired(std::string_view event, const std::string& message) const;
  // `items` stored results of `sweep` failed their checksum: recomputed (`action`); logged and said.
  void ChecksumFailed(const std::string& sweep, long items, const char* action) const;
  // Gives a lease's jobs back to their queue (if the lease's plan is still current). Under mu_.
  void RequeueLocked(const LeaseState& l);
  Status MarkLocked(Sweep& s, SweepState state);
  // Info of an active sweep (mu_ held), its worker count from LeaseTable::HoldersBySweep.
  SweepInfo InfoLocked(const Sweep& s, const std::map<std::string, int>& holders) const;
  // The index connection under the writer's lock (lock order: mu_ before it).
  ResultWriter::Locked Db() const { return writer_->Db(); }

  mutable std::mutex mu_;
  mutable std::condition_variable final_cv_;  // with mu_: a sweep became done, failed or cancelled
  std::string data_dir_;
  Options opt_;
  std::unique_ptr<ResultWriter> writer_;  // the index: group commit and checkpoints
  LeaseTable leases_;                     // under mu_
  std::map<std::string, Sweep> sweeps_;   // under mu_
  struct Planning {
    std::string owner;
    bool reserves_slot = false;  // a submit's reservation of an active-sweep slot (a replan's sweep is counted already)
  };
  std::map<std::string, Planning> planning_;  // sweep ids being planned (outside mu_)
  std::condition_variable plan_cv_;           // with mu_: a planning finished
  unsigned long long generation_counter_ = 0;
  std::map<std::string, WorkerInfo> workers_;
  CoordinatorStats stats_;  // counters, under mu_
  long next_seq_ = 0;
  bool stopped_ = false;
  std::unique_ptr<Publisher> publisher_;  // last member: started after, and closed before, everything it uses
};

}  // namespace bistable

#endif  // BISTABLE_SERVER_SWEEP_COORDINATOR_H_
