// The embedded deployment's pieces, shared by `bistable run` and `bistable reproduce`: worker
// threads draining a coordinator, job sizing, and the default figures of a published sweep.
#ifndef BISTABLE_CLIENT_EMBEDDED_RUN_H_
#define BISTABLE_CLIENT_EMBEDDED_RUN_H_

#include <atomic>
#include <string>
#include <vector>

#include "client/progress.h"
#include "server/sweep_coordinator.h"

namespace bistable {

// Runs `threads` worker threads until the coordinator's queue is empty, *stop is set, cancellation is
// requested (dynamics/cancel.h), or a report fails (that status is returned). A job cut short by
// cancellation is released, never reported: every stored job is whole. Returns within about the
// kernel's polling interval after cancellation. Updates `bar` (may be null) several times a second.
Status ComputeEmbedded(SweepCoordinator& c, const SweepSpec& spec, int threads, bool any_work, std::atomic<bool>* stop,
                       ProgressBar* bar);

// Submit + compute + publish in one call (no signal handling; callers install it): the map file's
// path, or CancelledStatus() when cancellation stopped it (the sweep is marked interrupted; what was
// stored stays in the cache).
StatusOr<std::string> RunEmbeddedSweep(const SweepSpec& spec, const std::string& data_dir, int threads, bool progress);

// The default figures of a published sweep (heatmaps, Fig. 6 scatter, bifurcation diagrams) into dir.
// Stops starting new figures once cancellation is requested.
std::vector<std::string> RenderDefaultPlots(const SweepSpec& spec, const std::string& map_path, const std::string& dir);

}  // namespace bistable

#endif  // BISTABLE_CLIENT_EMBEDDED_RUN_H_
