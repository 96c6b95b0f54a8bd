// The embedded deployment's pieces, shared by `bistable run` and `bistable reproduce`: worker
// threads draining a coordinator, job sizing, and the default figures of a published sweep.
#ifndef BISTABLE_CLIENT_EMBEDDED_RUN_H_
#define BISTABLE_CLIENT_EMBEDDED_RUN_H_

#include <atomic>
#include <functional>
#include <string>
#include <utility>
#include <vector>

#include "client/progress.h"
#include "server/sweep_coordinator.h"
#include "worker/pull_loop.h"

namespace bistable {

// The coordinator of an embedded run (`run`, `reproduce`, `design`, Python's run): no resumes, no log
// events, a long lease; repairs of the data directory (storage/data_dir.h) said on stderr as warnings.
SweepCoordinator::Options EmbeddedCoordinatorOptions();

// Runs `threads` pull loops (worker/pull_loop.h) over one thread-safe `source` until it has no job left,
// *stop is set, cancellation is requested (dynamics/cancel.h), or a report fails (that status is returned;
// `halt` is called then, and on a stop, so the source leases nothing more). done_of() says {items done, items
// total}: the loop ends when they meet, and `bar` (may be null) counts from the first. The embedded run's
// threads (ComputeEmbedded) and a shard's (client/shard_run.h) are both this.
Status RunPullThreads(JobSource& source, int threads, const std::function<std::pair<long, long>()>& done_of,
                      const std::function<void()>& halt, std::atomic<bool>* stop, ProgressBar* bar);

// Runs `threads` worker threads until the coordinator's queue is empty, *stop is set, cancellation is
// requested (dynamics/cancel.h), or a report fails (that status is returned). A job cut short by
// cancellation is released, never reported: every stored job is whole. Returns within about the
// kernel's polling interval after cancellation. Updates `bar` (may be null) several times a second.
Status ComputeEmbedded(SweepCoordinator& c, const SweepSpec& spec, int threads, bool any_work, std::atomic<bool>* stop,
                       ProgressBar* bar);

// Computes a submitted sweep's queued work on `threads` worker threads and publishes its map; a
// refined sweep ([refine]) goes level by level, one progress line (`label`) per level. Cancellation or
// a worker error marks the sweep interrupted (CancelledStatus() or that error); what was stored stays.
// *stats (may be null): what this call did.
struct EmbeddedRunStats {
  long computed = 0;           // items computed in this call
  long items = 0;              // items of the sweep (a refined sweep: the points it computed, cached or not)
  double publish_seconds = 0;  // writing the map (and planning refinement levels)
};
StatusOr<std::string> ComputeAndPublish(SweepCoordinator& c, const SweepSpec& spec, int threads, bool progress,
                                        const std::string& label, EmbeddedRunStats* stats);

// Submit + compute + publish in one call (no signal handling; callers install it): the map file's
// path, or CancelledStatus() when cancellation stopped it (the sweep is marked interrupted; what was
// stored stays in the cache).
StatusOr<std::string> RunEmbeddedSweep(const SweepSpec& spec, const std::string& data_dir, int threads, bool progress);

// The default figures of a published sweep (heatmaps, Fig. 6 scatter, bifurcation diagrams) into dir,
// as PNG, SVG or PDF files (format; docs/figures.md). Stops starting new figures once cancellation is
// requested. With `progress`, a line on stderr per figure as it is written, with its time.
std::vector<std::string> RenderDefaultPlots(const SweepSpec& spec, const std::string& map_path, const std::string& dir,
                                            const std::string& format = "png", bool progress = false);

}  // namespace bistable

#endif  // BISTABLE_CLIENT_EMBEDDED_RUN_H_
