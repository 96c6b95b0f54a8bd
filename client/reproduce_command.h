// `bistable reproduce paper`: regenerate the paper's simulated figures and check its claims.
#ifndef BISTABLE_CLIENT_REPRODUCE_COMMAND_H_
#define BISTABLE_CLIENT_REPRODUCE_COMMAND_H_

#include <CLI/CLI.hpp>

namespace bistable {
void AddReproduceCommand(CLI::App& app, int* exit_code);
}  // namespace bistable

#endif  // BISTABLE_CLIENT_REPRODUCE_COMMAND_H_
