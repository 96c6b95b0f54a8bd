// `bistable identify`: fit measured records, trace the residual, add the missing effect, report.
#ifndef BISTABLE_CLIENT_IDENTIFY_COMMAND_H_
#define BISTABLE_CLIENT_IDENTIFY_COMMAND_H_

#include <string>
#include <vector>

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include "base/status.h"
#include "identify/options.h"

namespace bistable {
void AddIdentifyCommand(CLI::App& app, int* exit_code);

// The same command for a program (the Python module): `args` are identify's flags as on the command
// line (without "identify"), parsed by the same options; returns what --json prints (--list-terms: the
// library; --make-synthetic DIR: {"files"}). A bad flag is InvalidArgument with CLI11's message.
StatusOr<nlohmann::json> IdentifyFromArgs(const std::vector<std::string>& args);

// The fit for a program (the Python module), with no command-line text: `options` as the library takes them
// (identify/options.h), the records of the files `data`, Identify (identify/identify.h); returns what
// `identify --json` prints. `report`: a directory for report.md, report.json and the figures ("": none);
// `full_report` (optional) receives the fit as text (identify::Summary::FullReport, what the command prints).
StatusOr<nlohmann::json> IdentifyFitJson(const identify::Options& options, const std::vector<std::string>& data,
                                         const std::string& report = "", std::string* full_report = nullptr);
// The effect library as `identify --list-terms --json` prints it.
nlohmann::json IdentifyTermsJson();
}  // namespace bistable

#endif  // BISTABLE_CLIENT_IDENTIFY_COMMAND_H_
