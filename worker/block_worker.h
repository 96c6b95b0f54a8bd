// Computes a job: a list of (grid point, initial condition) items of one sweep, returning one
// PointRecord per item in the same order. RK4 items run through the SIMD ensemble kernel in blocks of
// kSweepLanes lanes; everything else (adaptive, series, dimensional) one item at a time. Either way each item's record equals what
// `bistable point` prints for the same settings, bit for bit (see EnsembleKernel tests).
// Thread-safe: no shared state; run one job per thread.
#ifndef BISTABLE_WORKER_BLOCK_WORKER_H_
#define BISTABLE_WORKER_BLOCK_WORKER_H_

#include <vector>

#include "engine/metric_catalog.h"
#include "engine/sweep_spec.h"

namespace bistable {

// Lanes per kernel call in sweeps: 8 measured fastest on AVX-512 (docs/numerics.md).
inline constexpr int kSweepLanes = 8;

std::vector<PointRecord> ComputeItems(const SweepSpec& spec, const std::vector<WorkItem>& items);

}  // namespace bistable

#endif  // BISTABLE_WORKER_BLOCK_WORKER_H_
