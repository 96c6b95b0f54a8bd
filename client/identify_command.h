// `bistable identify`: fit measured records, trace the residual, add the missing effect, report.
#ifndef BISTABLE_CLIENT_IDENTIFY_COMMAND_H_
#define BISTABLE_CLIENT_IDENTIFY_COMMAND_H_

#include <string>
#include <vector>

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include "base/status.h"
#include "client/identify_predict.h"
#include "identify/options.h"
#include "identify/synthetic.h"

namespace bistable {
void AddIdentifyCommand(CLI::App& app, int* exit_code);

// --make-synthetic for a program (the CLI and the Python module): the records (and, for the snap-through family,
// truth.json) written into options.dir; returns what --json prints ({"files"[, "truth"]}). Invalid options
// (identify::Validate) are InvalidArgument naming the option, before anything is written.
StatusOr<nlohmann::json> SyntheticJson(const identify::MakeSyntheticOptions& options);

// --predict for a program (the CLI and the Python module): returns what --json prints ({"prediction": ...}).
// Invalid options (Validate(PredictOptions)) are InvalidArgument naming the option.
StatusOr<nlohmann::json> PredictJson(const PredictOptions& options);

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
