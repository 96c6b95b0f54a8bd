// `bistable identify --report DIR` and the text summary: report.md, report.json and the figures of a fit
// (identify/identify.h's Summary), and what the command prints without --json.
#ifndef BISTABLE_CLIENT_IDENTIFY_REPORT_H_
#define BISTABLE_CLIENT_IDENTIFY_REPORT_H_

#include <string>

#include <nlohmann/json.hpp>

#include "base/status.h"
#include "identify/identify.h"

namespace bistable {

// --report DIR: the figures, report.md and report.json (the result `j`, as --json prints it); `declared`:
// the declared terms as given.
Status WriteReport(const std::string& report, const std::string& declared, const identify::Summary& s,
                   const nlohmann::json& j);

// The human-readable result on stdout (identify::Summary::FullReport); `report`: the report directory ("" none).
void PrintSummary(const std::string& report, const identify::Summary& s);

}  // namespace bistable

#endif  // BISTABLE_CLIENT_IDENTIFY_REPORT_H_
