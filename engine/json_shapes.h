// JSON shapes shared by the CLI (client/json_out.h adds the wire-only ones), the Python module and the
// dashboard (server/dashboard.h): a point (`bistable point --json`), stored metric values, a sweep's
// status and a worker, and the conventions every JSON output of the project follows. One builder each,
// so a point prints the same bits wherever it is computed.
#ifndef BISTABLE_ENGINE_JSON_SHAPES_H_
#define BISTABLE_ENGINE_JSON_SHAPES_H_

#include <string>

#include <nlohmann/json.hpp>

#include "dynamics/point.h"
#include "dynamics/point_spec.h"
#include "engine/sweep_state.h"

namespace bistable {

// Conventions of every JSON output: a non-finite number prints as null; a metric's category code
// (motion, termination) as its name; an integer metric (period, the codes) as an integer; a time as
// ISO 8601 UTC ("2026-11-22T21:04:05.123Z").

// JSON text of `j` (indent -1: one line). Strings that are not valid UTF-8 (a file name, a label read from
// a file) are written with U+FFFD in place of the bad bytes instead of throwing: every JSON the
// programs print or write goes through this.
std::string DumpJson(const nlohmann::json& j, int indent = -1);

// `v`, or null when it is not finite.
nlohmann::json JsonNumber(double v);
// A Unix time as ISO 8601 UTC (IsoTimeUtc); null for 0 (not set, e.g. an unfinished sweep's end) or a
// time that cannot be printed.
nlohmann::json JsonTime(double unix_seconds);
// A stored value of `metric` as a number: an integer for the catalog's integer metrics, else JsonNumber.
nlohmann::json MetricNumberJson(const std::string& metric, double v);
// A stored value of `metric` as JSON prints it: a category's name (CategoryName), else MetricNumberJson.
nlohmann::json MetricValueJson(const std::string& metric, double v);

// Everything needed to reproduce a point run.
nlohmann::json SettingsJson(const PointSpec& spec);
// The `bistable point --json` object: frf_db, lle, lle_rosenstein, motion, period, hd_index, hd_peaks,
// edr_b, edr_r, edr_t, energy_balance_residual, energies, termination, settings. NaN prints as null.
nlohmann::json PointJson(const PointSpec& spec, const PointResult& r);
// `point --spectrum`'s keys: lyapunov_spectrum, lyapunov_sum, divergence, kaplan_yorke (CLI and Python).
void AddSpectrumJson(const LyapunovSpectrum& sp, nlohmann::json* j);

// `status --json` of a sweep (SweepStatusJson) and a row of `workers --json` (WorkerJson).
nlohmann::json SweepStatusJson(const SweepInfo& s);
nlohmann::json WorkerJson(const WorkerInfo& w);

}  // namespace bistable

#endif  // BISTABLE_ENGINE_JSON_SHAPES_H_
