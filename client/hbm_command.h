// `bistable hbm`: harmonic balance with continuation and stability.
#ifndef BISTABLE_CLIENT_HBM_COMMAND_H_
#define BISTABLE_CLIENT_HBM_COMMAND_H_

#include <CLI/CLI.hpp>

#include "client/plot.h"
#include "dynamics/hbm.h"

namespace bistable {
void AddHbmCommand(CLI::App& app, int* exit_code);

// Continuation branches as a figure (amplitude max |y_m| against the continued parameter; converged
// points only): each branch cut into runs of one well (WellOf: "+well", "-well", "interwell"; one
// "periodic orbit" name for the linear models, which have one well), each run joined to the next.
// +well curves go first and wider (mirror images of the -well ones, which would hide them); the title
// then says so.
BranchPlot HbmBranchPlot(const HbmResult& r, ModelKind model, ContinuationParam param, const std::string& title);
}  // namespace bistable

#endif  // BISTABLE_CLIENT_HBM_COMMAND_H_
