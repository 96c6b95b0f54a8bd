// The job-array path (issue 43), for clusters whose compute nodes may run neither a long-lived service nor
// open ports: `bistable run SPEC --shard I/N` computes one deterministic slice of a sweep (engine/sweep_plan.h,
// Shard) into a store of its own, and `bistable merge SPEC` assembles the N stores into the map the embedded
// `bistable run` writes, bit for bit (the same items computed by the same code, the map written by the same
// PublishMap). deploy/slurm/array.sbatch runs it as a Slurm job array.
//
// A shard store is a directory, by default <data>/shards/<sweep id>-<I>-of-<N>/: index.sqlite, the shard's
// point cache (content-keyed, checksummed records, group commit: a data directory's index), and shard.json,
// what it is a shard of (sweep id, I, N, numerics version, record layout, state). A shard rerun resumes from
// what its store holds, like every run. Refined sweeps cannot be sharded (engine/sweep_plan.h, CheckShardable).
#ifndef BISTABLE_CLIENT_SHARD_RUN_H_
#define BISTABLE_CLIENT_SHARD_RUN_H_

#include <string>
#include <vector>

#include "base/status.h"
#include "engine/sweep_plan.h"
#include "engine/sweep_spec.h"

namespace bistable {

// <data_dir>/shards/<sweep id>-<I>-of-<N>
std::string ShardStorePath(const std::string& data_dir, const std::string& sweep_id, const Shard& shard);

struct ShardRunResult {
  std::string store;  // the shard store's directory
  long items = 0;     // the shard's items
  long cached = 0;    // found in the store (a resumed shard)
  long computed = 0;  // computed by this call
};
// Computes the items of `shard` missing from its store on `threads` threads (jobs of about `job_items`; 0: about
// 0.25 s of work), then marks the store complete. CancelledStatus() when cancellation stopped it, or a worker's
// error: what was stored stays, and a rerun resumes from it. *result is filled either way.
Status RunShard(const SweepSpec& spec, const Shard& shard, const std::string& data_dir, int threads, long job_items,
                bool progress, ShardRunResult* result);

struct MergeResult {
  std::string id;
  std::string map;  // the map file written
  int shards = 0;
  long items = 0;
};
// Checks `stores` and writes the sweep's map into data_dir (sweeps/<id>.h5 and its index row, as `bistable run`
// publishes it; the records are also added to data_dir's point cache). `stores` empty: every
// <data_dir>/shards/<id>-* directory. Refused, naming the store and the problem, when a store is not a shard
// store, is of another spec, of another numerics version or record layout, when the stores disagree on N, when
// a shard is given twice or is missing, or when one is incomplete (not finished, or records missing or failing
// their checksums).
StatusOr<MergeResult> MergeShards(const SweepSpec& spec, std::vector<std::string> stores, const std::string& data_dir);

}  // namespace bistable

#endif  // BISTABLE_CLIENT_SHARD_RUN_H_
