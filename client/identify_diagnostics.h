// The loop's diagnostics (identify/diagnostics.h) in `bistable identify`'s JSON and report.md:
// invariants of chaotic records before/after every step, the residual's whiteness and what is left
// unexplained, parameter correlations, drift of the declared parameters per refit, separability hints.
#ifndef BISTABLE_CLIENT_IDENTIFY_DIAGNOSTICS_H_
#define BISTABLE_CLIENT_IDENTIFY_DIAGNOSTICS_H_

#include <ostream>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "identify/loop.h"

namespace bistable {

// One set of invariants as JSON (the keys of "invariants.before" / "after").
nlohmann::json InvariantsObject(const Invariants& v);

// Adds "chaos_check", "invariants" (null unless a record is chaotic), "whiteness", "unexplained"
// (null when the residual is white), "correlations", "separability", "refits" and every
// effects_added entry's "drift" to `j`.
void AddDiagnosticsJson(const IdentifyResult& r, const std::vector<PreparedRecord>& recs, nlohmann::json* j);

// report.md sections: invariants, residual whiteness / unexplained, correlations and drift.
void WriteDiagnosticsReport(std::ostream& md, const IdentifyResult& r);

}  // namespace bistable

#endif  // BISTABLE_CLIENT_IDENTIFY_DIAGNOSTICS_H_
