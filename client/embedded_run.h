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

// Items per job: about `seconds` of work on one core, a multiple of the lane width.
long JobItems(const SweepSpec& spec, double seconds);

// Runs `threads` worker threads until the coordinator's queue is empty, *stop is set, or a report
// fails (that status is returned). Updates `bar` (may be null) about ten times a second.
Status ComputeEmbedded(SweepCoordinator& c, const SweepSpec& spec, int threads, bool any_work, std::atomic<bool>* stop,
                       ProgressBar* bar);

// Submit + compute + publish in one call (no signal handling): the map file's path.
StatusOr<std::string> RunEmbeddedSweep(const SweepSpec& spec, const std::string& data_dir, int threads, bool progress);

// The default figures of a published sweep (heatmaps, Fig. 6 scatter, bifurcation diagrams) into dir.
std::vector<std::string> RenderDefaultPlots(const SweepSpec& spec, const std::string& map_path, const std::string& dir);

}  // namespace bistable

#endif  // BISTABLE_CLIENT_EMBEDDED_RUN_H_
