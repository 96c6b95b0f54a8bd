// Computes a job: a list of (grid point, initial condition) items of one sweep, returning one
// PointRecord per item in the same order. RK4 items run through the SIMD ensemble kernel in blocks of
// kSweepLanes lanes; everything else (adaptive, series, dimensional) one item at a time. Either way each item's record equals what
// `bistable point` prints for the same settings, bit for bit (see EnsembleKernel tests).
// Thread-safe: no shared state; run one job per thread.
#ifndef BISTABLE_WORKER_BLOCK_WORKER_H_
#define BISTABLE_WORKER_BLOCK_WORKER_H_

#include <optional>
#include <vector>

#include "engine/metric_catalog.h"
#include "engine/sweep_spec.h"

namespace bistable {

// Lanes per kernel call in sweeps: 8 measured fastest on AVX-512 (docs/numerics.md).
inline constexpr int kSweepLanes = 8;

// The job's records, or nullopt when cancellation (dynamics/cancel.h) was requested before the job
// finished: an integration may have stopped early, so no record of the job may be reported or stored
// — give the lease back instead. Records returned are complete (the flag was still clear at the end).
std::optional<std::vector<PointRecord>> ComputeItemsUnlessCancelled(const SweepSpec& spec,
                                                                    const std::vector<WorkItem>& items);

// ComputeItemsUnlessCancelled for callers that never cancel (tests, benches): an empty vector when
// cancelled, which no coordinator accepts as a job's report.
std::vector<PointRecord> ComputeItems(const SweepSpec& spec, const std::vector<WorkItem>& items);

}  // namespace bistable

#endif  // BISTABLE_WORKER_BLOCK_WORKER_H_
