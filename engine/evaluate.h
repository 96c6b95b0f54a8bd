// How a sweep's items become records — the one place: the SIMD ensemble kernel for RK4 cell models
// (kSweepLanes lanes per call), the lane kernel for RK4 series chains and the dimensional model
// (kSweepLanes lanes), the generic per-point path for adaptive integration, continuation chains in
// order, and the size of the jobs they are cut into.
// Each item's record equals what `bistable point` prints for the same settings, bit for bit.
// Used by the worker process and the embedded `bistable run` (through worker/pull_loop.h) alike.
// Thread-safe: no shared state; run one job per thread.
#ifndef BISTABLE_ENGINE_EVALUATE_H_
#define BISTABLE_ENGINE_EVALUATE_H_

#include <optional>
#include <vector>

#include "dynamics/lanes.h"
#include "engine/metric_catalog.h"
#include "engine/sweep_spec.h"

namespace bistable {

// Lanes per kernel call in sweeps: kSweepLanes (dynamics/lanes.h) — 8 on AVX-512, 4 on AVX2, fixed
// by the build's -march. Results do not depend on it: a lane's bits are the same at every width.

// Checks a job's items against its spec before anything is computed — a lease may come from a
// coordinator the worker does not control: 1 to limits::kMaxLeaseItems items, every point in
// [0, spec.points()), every slot in [0, spec.ic_count()). InvalidArgument naming the item, the value and
// the bound (`field` prefixes it, e.g. "lease").
Status CheckItems(const SweepSpec& spec, const std::vector<WorkItem>& items, const std::string& field);

// The job's records, or nullopt when cancellation (dynamics/cancel.h) was requested before the job
// finished: an integration may have stopped early, so no record of the job may be reported or stored
// — give the lease back instead. Records returned are complete (the flag was still clear at the end).
std::optional<std::vector<PointRecord>> ComputeItemsUnlessCancelled(const SweepSpec& spec,
                                                                    const std::vector<WorkItem>& items);

// ComputeItemsUnlessCancelled for callers that never cancel (tests, benches): an empty vector when
// cancelled, which no coordinator accepts as a job's report.
std::vector<PointRecord> ComputeItems(const SweepSpec& spec, const std::vector<WorkItem>& items);

// One item outside the cell kernel (series, dimensional, adaptive cell models). An evaluation error is
// returned as a diverged result (termination 1) and reported on stderr with its reason — the spec was
// validated, so only a degenerate run gets there. Series and dimensional RK4 items run in the lane
// kernel at width 1, so a sweep's record of the item has the same bits.
PointResult EvaluateItem(const SweepSpec& spec, long index, int ic);

// Items of a series or dimensional RK4 sweep (spec.UsesGenericLanes()) through the lane kernel,
// `width` side by side (1, 4 or kSweepLanes); nullopt when cancelled. Results do not depend on width.
std::optional<std::vector<PointResult>> EvaluateItemsInLanes(const SweepSpec& spec, const std::vector<WorkItem>& items,
                                                             int width);

// Items per job: about `seconds` of work on one core (≈ 1.5e7 lane-steps/s with metrics; points off
// the kernel count 8 times as much), but at least `min_jobs` jobs where the sweep has the items (so
// the last jobs balance across workers); a multiple of kSweepLanes in [kSweepLanes, limits::kMaxJobItems].
long JobItems(const SweepSpec& spec, double seconds, long min_jobs = 0);

}  // namespace bistable

#endif  // BISTABLE_ENGINE_EVALUATE_H_
