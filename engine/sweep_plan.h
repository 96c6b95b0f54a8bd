// A sweep's plan: which items are left to compute, cut into jobs, and what comes next (compute, the next
// round of a refined sweep, publication). Pure: no locks and no I/O. The point cache is reached through a
// lookup the caller passes (the coordinator's reads the SQLite index in batches; tests pass a map), and a
// plan is used under its owner's lock (server/sweep_coordinator.h). Issue 40: the coordinator's "what
// next", as leveldb's VersionSet::PickCompaction is DBImpl's.
#ifndef BISTABLE_ENGINE_SWEEP_PLAN_H_
#define BISTABLE_ENGINE_SWEEP_PLAN_H_

#include <deque>
#include <functional>
#include <memory>
#include <string>
#include <unordered_map>
#include <vector>

#include "base/status.h"
#include "engine/metric_catalog.h"
#include "engine/refine.h"
#include "engine/sweep_spec.h"

namespace bistable {

struct Job {
  long id = 0;
  std::vector<WorkItem> items;
};

// The records stored under some of `keys` (at most kPlanLookupBatch of them per call), by key: the
// point cache as the plan sees it.
using PointLookup =
    std::function<StatusOr<std::unordered_map<std::string, PointRecord>>(const std::vector<std::string>& keys)>;
inline constexpr size_t kPlanLookupBatch = 65536;  // keys per lookup: each batch its own read of the index

class RefinePlanner;

// A deterministic slice of a sweep, for a batch system's job array (issue 43: `bistable run --shard I/N`,
// merged by `bistable merge`). The sweep's units — its items, or its continuation chains whole (a chain
// runs in order from its first point) — are dealt round-robin: unit u is shard u mod count's. The shards
// partition the sweep, and each item is computed exactly as in the whole sweep (same item, same code), so
// the merged map is the embedded run's bit for bit. Round-robin rather than blocks: neighbouring grid
// points cost alike (chaotic regions, adaptive steps), so every shard gets a share of the dear ones.
struct Shard {
  int index = 0;  // I: 0 <= index < count
  int count = 1;  // N
  std::string Label() const { return std::to_string(index) + "/" + std::to_string(count); }
};
// "I/N" (decimal, 0 <= I < N <= limits::kMaxShards) as a Shard; InvalidArgument naming `shard` and the
// bound otherwise.
StatusOr<Shard> ParseShard(const std::string& text);
// Whether `spec` can be cut into independent shards. A refined sweep ([refine]) cannot: each round is
// planned from the whole previous round's results (FailedPrecondition saying so). Plain grids, several
// initial conditions, robustness samples, basin sweeps (attractors are classified from all records when
// the map is written) and continuation chains (whole chains per shard) can.
Status CheckShardable(const SweepSpec& spec);
// The items of `shard` of `spec`, as item indices (point · ic_count + ic), ascending.
std::vector<long> ShardItemIndices(const SweepSpec& spec, const Shard& shard);
// The content key of every item of `spec`, in item order (point · ic_count + ic).
std::vector<std::string> ItemKeys(const SweepSpec& spec);

// A refined sweep's walk and keys carried from its last plan into the next round.
struct RefineCarry {
  std::shared_ptr<RefinePlanner> planner;
  std::vector<long> points;
  std::vector<std::string> keys;
  bool continued = false;  // the sweep's last plan is continued (else a walk from the start)
  long cached = 0;         // items the last plan counted as reused from the cache
  long computed = 0;       // items the last plan queued (computed by the plan's owner since)
};

class JobPlan {
 public:
  enum class JobState { kQueued, kLeased, kDone };
  // What the plan's owner does next.
  enum class Next {
    kCompute,    // items are left to compute (queued or leased)
    kNextRound,  // a refined sweep's round is stored and rounds are left: plan the next one
    kPublish,    // everything is stored: write the map
  };

  // Plans `spec` against the point cache: every item's content key, the missing items cut into jobs of
  // about `job_items` (a continuation chain is never split, and one with any missing item is computed
  // whole). A refined sweep walks its rounds (engine/refine.h) from `carry` (or from the start) and
  // queues the first round's missing points. A result the lookup does not return (absent, or failing its
  // checksum: the lookup's to count) is missing.
  static StatusOr<JobPlan> Build(const SweepSpec& spec, long job_items, const PointLookup& lookup,
                                 RefineCarry carry = {});
  // The plan of one shard of a sweep (CheckShardable): only the shard's items are looked up, counted and
  // queued (items_total is the shard's); keys() still holds every item's key, in item order.
  static StatusOr<JobPlan> BuildShard(const SweepSpec& spec, long job_items, const PointLookup& lookup,
                                      const Shard& shard);
  // The plan of a published sweep: every item stored, nothing to compute.
  static JobPlan Published(long items_total);

  long items_total() const { return items_total_; }  // a refined sweep: the grid points planned so far
  long items_done() const { return items_done_; }    // stored (cached or reported to this plan)
  long items_cached() const { return items_cached_; }
  long jobs() const { return static_cast<long>(jobs_.size()); }
  size_t queued() const { return queue_.size(); }
  bool refined() const { return refined_; }
  int refine_round() const { return refine_round_; }
  bool refine_complete() const { return refine_complete_; }
  const std::vector<std::string>& keys() const { return keys_; }  // item point·ic_count + ic; refined: of points()
  const std::vector<long>& points() const { return points_; }     // refined: the grid points planned, ascending
  Next next() const;
  // The walk and keys to continue from in the next round (a refined sweep whose walk is not complete).
  RefineCarry Carry() const;

  // Up to `max_jobs` queued jobs (at least one), oldest first, whose items total at most `max_items`
  // (the first is always taken): now leased. Empty when nothing is queued.
  std::vector<long> Take(int max_jobs, long max_items);
  // Leased jobs of `job_ids` back at the front of the queue, in their order (an expired or released lease).
  void Requeue(const std::vector<long>& job_ids);
  // Every id names a job of this plan.
  bool Holds(const std::vector<long>& job_ids) const;
  bool AllDone(const std::vector<long>& job_ids) const;
  long ItemsOf(const std::vector<long>& job_ids) const;
  // The items of `job_ids` in order (what a lease carries).
  std::vector<WorkItem> ItemsFor(const std::vector<long>& job_ids) const;
  // The content keys of the jobs' items in order, each ended by '\n' (the stored rows' keys).
  std::string KeysFor(const std::vector<long>& job_ids) const;
  // Marks the jobs done; returns the items newly done (a job done before counts once).
  long Complete(const std::vector<long>& job_ids);
  // Nothing is left to lease (a replan underway, a cancel).
  void ClearQueue() { queue_.clear(); }
  // Frees the keys, jobs and walk of a published or cancelled plan (their memory given back); the
  // counters and the round stay, for status.
  void Free();

 private:
  const std::string& KeyOf(const WorkItem& w) const;
  // A grid sweep's plan (not refined); with `shard`, of that shard's items only.
  static StatusOr<JobPlan> BuildGrid(const SweepSpec& spec, long job_items, const PointLookup& lookup,
                                     const Shard* shard);
  void QueueAllJobs();  // every job queued, in order

  int ic_count_ = 1;
  bool refined_ = false;
  std::vector<std::string> keys_;
  std::vector<long> points_;
  std::vector<Job> jobs_;
  std::vector<JobState> job_state_;
  std::deque<long> queue_;
  long items_total_ = 0, items_done_ = 0, items_cached_ = 0;
  std::shared_ptr<RefinePlanner> refiner_;  // refined sweeps: the walk so far
  int refine_round_ = 0;                    // refined sweeps: the round being computed
  long refine_queued_ = 0;                  // refined sweeps: items this round queued (not found stored)
  bool refine_complete_ = false;            // refined sweeps: every level stored, ready to publish
};

}  // namespace bistable

#endif  // BISTABLE_ENGINE_SWEEP_PLAN_H_
