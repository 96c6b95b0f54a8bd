// The Poincaré (stroboscopic) section of one point as `bistable point --poincare` and the Python
// module's point(poincare=True) give it: one home for its window, columns, rows and JSON.
#ifndef BISTABLE_CLIENT_POINCARE_SECTION_H_
#define BISTABLE_CLIENT_POINCARE_SECTION_H_

#include <cstddef>
#include <string>
#include <utility>
#include <vector>

#include <nlohmann/json.hpp>

#include "base/status.h"
#include "dynamics/point_spec.h"

namespace bistable {

// `poincare_periods` N: the window [t_keep, t_end] is made N + 1 forcing periods long (rounded up to
// whole steps), so it holds at least N strobes whatever the phase; the section keeps the first N.
// N in [1, limits::kMaxPoincarePeriods] and within the steps-per-point limit; errors name `field`
// ("--poincare-periods" in the CLI, "poincare_periods" in Python) and the bound.
Status SetPoincareWindow(long n, const std::string& field, PointSpec* spec);

// The section's columns (strobe index k, its time, the state there) and their units: τ = ωn t,
// lengths in δs, velocities d/dτ in δs ωn. k, tau, y_m, dy_m, and y_r, dy_r for models with a resonator.
std::vector<std::pair<std::string, std::string>> SectionColumns(const PointSpec& spec);

// Points of the section given out (the first `limit` when > 0).
size_t SectionCount(const PointResult& r, long limit);

// Row i, one value per SectionColumns: k, τ_k = (φ + 2πk)/Ω as the recorder computes it, y_m, y_m'
// (, y_r, y_r').
std::vector<double> SectionRow(const PointSpec& spec, const PointResult& r, size_t i);

// What `point --json` says about the section: phase, count, k0, columns, units; its points (rows)
// when `file` is "-", the file's name when it is another non-empty string.
nlohmann::json SectionJson(const PointSpec& spec, const PointResult& r, long limit, const std::string& file);

}  // namespace bistable

#endif  // BISTABLE_CLIENT_POINCARE_SECTION_H_
