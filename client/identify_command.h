// `bistable identify`: fit measured records, trace the residual, add the missing effect, report.
#ifndef BISTABLE_CLIENT_IDENTIFY_COMMAND_H_
#define BISTABLE_CLIENT_IDENTIFY_COMMAND_H_

#include <CLI/CLI.hpp>

namespace bistable {
void AddIdentifyCommand(CLI::App& app, int* exit_code);
}  // namespace bistable

#endif  // BISTABLE_CLIENT_IDENTIFY_COMMAND_H_
