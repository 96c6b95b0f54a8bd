// `bistable point`: integrate one (α, Ω) point and print every metric.
#ifndef BISTABLE_CLIENT_POINT_COMMAND_H_
#define BISTABLE_CLIENT_POINT_COMMAND_H_

#include <CLI/CLI.hpp>

namespace bistable {

// Registers the subcommand on `app`; its callback sets *exit_code.
void AddPointCommand(CLI::App& app, int* exit_code);

}  // namespace bistable

#endif  // BISTABLE_CLIENT_POINT_COMMAND_H_
