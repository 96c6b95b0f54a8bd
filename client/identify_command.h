// `bistable identify`: fit measured records, trace the residual, add the missing effect, report.
#ifndef BISTABLE_CLIENT_IDENTIFY_COMMAND_H_
#define BISTABLE_CLIENT_IDENTIFY_COMMAND_H_

#include <string>
#include <vector>

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include "base/status.h"

namespace bistable {
void AddIdentifyCommand(CLI::App& app, int* exit_code);

// The same command for a program (the Python module): `args` are identify's flags as on the command
// line (without "identify"), parsed by the same options; returns what --json prints (--list-terms: the
// library; --make-synthetic DIR: {"files"}). A bad flag is InvalidArgument with CLI11's message.
StatusOr<nlohmann::json> IdentifyFromArgs(const std::vector<std::string>& args);
}  // namespace bistable

#endif  // BISTABLE_CLIENT_IDENTIFY_COMMAND_H_
