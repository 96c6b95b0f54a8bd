// A sweep: a model, fixed parameters, axes over (α, Ω, η, η_r, λ, φ, ε), integration and metric
// settings and one or several initial conditions per point. Parsed from TOML (see
// examples/*.toml and docs/sweep-spec.md); validated once, up front, with the offending field named.
#ifndef BISTABLE_ENGINE_SWEEP_SPEC_H_
#define BISTABLE_ENGINE_SWEEP_SPEC_H_

#include <array>
#include <string>
#include <vector>

#include "dynamics/point_spec.h"
#include "dynamics/status.h"

namespace bistable {

// Most grid points × initial conditions one sweep may hold (documented in docs/sweep-spec.md).
inline constexpr long kMaxSweepItems = 20'000'000;

struct Axis {
  std::string name;            // alpha | omega | eta | eta_r | lambda | phi | eps
  std::vector<double> values;  // strictly increasing
};

// Axis names in the canonical order used for enumeration and for the map datasets.
const std::vector<std::string>& CanonicalAxisNames();
// Unit and meaning of an axis ("alpha" → "A0/delta_s", ...).
std::string AxisUnit(const std::string& name);

// One unit of work in a sweep: a grid point with one of its initial conditions.
struct WorkItem {
  long point = 0;  // row-major grid index
  int ic = 0;      // index into the spec's initial states
};

struct SweepSpec {
  std::string name;                 // free text, for humans
  ModelKind model = ModelKind::kCoupled;
  PointSpec base;                   // fixed parameters and settings; alpha/omega used when not swept
  std::vector<Axis> axes;           // in canonical order, only the swept ones
  std::vector<std::array<double, 4>> initial_states;  // empty: the model's default start
  std::vector<std::string> metrics; // stored metrics (names from MetricCatalog)
  std::vector<std::string> plots;   // metrics rendered after `bistable run`
  std::string source;               // the TOML text as given (stored with the maps)

  long points() const;              // product of axis lengths (1 with no axes)
  int ic_count() const { return initial_states.empty() ? 1 : static_cast<int>(initial_states.size()); }
  // Canonical text of everything that determines the numbers (not name/plots/source): its hash is the sweep id.
  std::string CanonicalText() const;
  std::string Id() const;           // 12 hex digits of the canonical text's hash
  // The point spec of grid point `index` (row-major over axes, last axis fastest) with initial condition ic.
  PointSpec PointAt(long index, int ic) const;
  // Axis indices of a point.
  std::vector<int> AxisIndices(long index) const;
};

// Parses and validates. `origin` names the source in messages (a file name).
StatusOr<SweepSpec> ParseSweepSpec(const std::string& toml_text, const std::string& origin);
StatusOr<SweepSpec> LoadSweepSpec(const std::string& path);

// The candidate `word` most likely meant: the only one it is a prefix of, else the closest by edit
// distance within a third of the longer length (+1); "" when none is close.
std::string NearestName(const std::string& word, const std::vector<std::string>& candidates);

}  // namespace bistable

#endif  // BISTABLE_ENGINE_SWEEP_SPEC_H_
