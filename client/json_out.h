// JSON shapes of the CLI (scripts depend on them; see README "JSON output").
#ifndef BISTABLE_CLIENT_JSON_OUT_H_
#define BISTABLE_CLIENT_JSON_OUT_H_

#include <nlohmann/json.hpp>

#include "dynamics/point_spec.h"

namespace bistable {

// Everything needed to reproduce a point run.
nlohmann::json SettingsJson(const PointSpec& spec);
// The `bistable point --json` object: frf_db, lle, lle_rosenstein, motion, period, hd_index, hd_peaks,
// edr_b, edr_r, edr_t, energy_balance_residual, energies, termination, settings. NaN prints as null.
nlohmann::json PointJson(const PointSpec& spec, const PointResult& r);

}  // namespace bistable

#endif  // BISTABLE_CLIENT_JSON_OUT_H_
