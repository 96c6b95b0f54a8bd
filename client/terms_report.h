// A sweep of an identified model (issue 42): `[terms] report = "DIR/report.json"` in a spec names the result
// of `bistable identify --report DIR` (or a file of `bistable identify --json` output), and the client — the
// only side that may read the user's files — replaces it with the model inline before the spec is parsed,
// stored or sent: terms.list (the final model's force terms), terms.theta, m_main, m_res, v_sp, v_t, the
// drive (displacement or acceleration, from the fit's input), the covariance of those parameters, and
// terms.origin (the report's path). The spec a map stores is then self-contained. Output terms and per-record
// offsets are properties of the sensors, not of the dynamics, and are left out; a fit with the piezo's
// voltage state or with a force input is refused (the swept term model has neither yet).
#ifndef BISTABLE_CLIENT_TERMS_REPORT_H_
#define BISTABLE_CLIENT_TERMS_REPORT_H_

#include <string>

#include "base/status.h"
#include "engine/sweep_spec.h"

namespace bistable {

// `spec_text` with [terms] report resolved (relative to the directory of `spec_path`); unchanged when the
// spec names no report. Errors name the field: terms.report (a file that cannot be read, or is not an
// identify result), terms.report.<key> (a key of the result that is missing or out of its domain).
StatusOr<std::string> InlineTermsReport(const std::string& spec_text, const std::string& spec_path);

// LoadSweepSpec for a client: the file read, its report inlined, parsed.
StatusOr<SweepSpec> LoadClientSweepSpec(const std::string& path);

}  // namespace bistable

#endif  // BISTABLE_CLIENT_TERMS_REPORT_H_
