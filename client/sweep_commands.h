// `bistable run | sweeps | map | query | info`: the sweep engine embedded in one process, and reading maps.
#ifndef BISTABLE_CLIENT_SWEEP_COMMANDS_H_
#define BISTABLE_CLIENT_SWEEP_COMMANDS_H_

#include <CLI/CLI.hpp>

namespace bistable {

void AddRunCommand(CLI::App& app, int* exit_code);
void AddMergeCommand(CLI::App& app, int* exit_code);
void AddSweepsCommand(CLI::App& app, int* exit_code);
void AddMapCommand(CLI::App& app, int* exit_code);
void AddQueryCommand(CLI::App& app, int* exit_code);
void AddInfoCommand(CLI::App& app, int* exit_code);

}  // namespace bistable

#endif  // BISTABLE_CLIENT_SWEEP_COMMANDS_H_
