// `bistable hbm`: harmonic balance with continuation and stability.
#ifndef BISTABLE_CLIENT_HBM_COMMAND_H_
#define BISTABLE_CLIENT_HBM_COMMAND_H_

#include <CLI/CLI.hpp>

namespace bistable {
void AddHbmCommand(CLI::App& app, int* exit_code);
}  // namespace bistable

#endif  // BISTABLE_CLIENT_HBM_COMMAND_H_
