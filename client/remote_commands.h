// `bistable submit | status | cancel | workers` against a coordinator.
#ifndef BISTABLE_CLIENT_REMOTE_COMMANDS_H_
#define BISTABLE_CLIENT_REMOTE_COMMANDS_H_

#include <CLI/CLI.hpp>

namespace bistable {
void AddRemoteCommands(CLI::App& app, int* exit_code);
}  // namespace bistable

#endif  // BISTABLE_CLIENT_REMOTE_COMMANDS_H_
