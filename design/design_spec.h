// A design search spec (issue 17, `bistable design`): a base sweep spec (model, [params], integration,
// metrics: docs/sweep-spec.md) plus a [design] table naming the resonator parameters searched within
// bounds (lambda, phi, eta_r), the forcing amplitude(s), the Ω line every candidate is evaluated on,
// the number of candidates and the optimiser. Each candidate design is an ordinary sweep over
// (alpha ×) omega, so it goes through the sweep engine, its items are cached by content key, and a
// search run again reuses every candidate computed before. Format and definitions: docs/design-search.md.
#ifndef BISTABLE_DESIGN_DESIGN_SPEC_H_
#define BISTABLE_DESIGN_DESIGN_SPEC_H_

#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include "base/status.h"
#include "engine/sweep_spec.h"

namespace bistable {

// The searched parameters, in this order everywhere (vectors x, JSON, CSV columns).
inline const std::array<std::string, 3> kDesignParameters = {"lambda", "phi", "eta_r"};
using DesignPoint = std::array<double, 3>;  // lambda, phi, eta_r

struct DesignSpec {
  std::string name;
  std::string origin;                  // file name, for messages
  std::string source;                  // the TOML as given
  DesignPoint lo{}, hi{};              // bounds; lo == hi fixes the parameter (at the [params] value when not bounded)
  std::vector<double> alphas;          // forcing amplitude(s): several → each candidate is an alpha × omega sweep
  std::vector<double> omega;           // the Ω line (as the engine computes it from design.omega)
  int budget = 60;                     // candidates the optimiser may evaluate
  uint64_t seed = 1;                   // crs2 only (direct-l is deterministic)
  std::string optimizer = "direct-l";  // direct-l (NLopt GN_DIRECT_L) | crs2 (NLopt GN_CRS2_LM)
  std::string cost = "phi";       // the device's cost on the Pareto front: phi (resonator mass) | lambda (stiffness)
  int maps = 2;                   // alpha x omega maps of the best designs (0 .. limits::kMaxDesignMaps)
  double chaos_threshold = 0.01;  // from [metrics]: lle above it is chaotic
  std::string id;  // 12 hex digits of the hash of CanonicalText(): the report directory DATA/designs/<id>

  bool Free(int k) const { return hi[k] > lo[k]; }
  int CostIndex() const { return cost == "lambda" ? 0 : 1; }
  // The sweep spec (TOML) of design x over alphas × omega (alpha a fixed parameter when there is one).
  std::string CandidateToml(const DesignPoint& x) const;
  // The regular map of design x over map_alpha × omega, with frf_db and motion plots ("" map_alpha: no maps).
  std::string MapToml(const DesignPoint& x, const std::string& title) const;
  // Everything that determines the search's result and report (base spec, Ω line, alphas, map_alpha,
  // bounds, optimizer, budget, seed, cost, maps), one named, unambiguous field a line: the id hashes it.
  std::string CanonicalText() const;
  // One sweep over every free parameter's grid (n values from lo to hi) × alphas × omega: the brute force.
  std::string BruteForceToml(int n) const;

  // internal: the base spec without [design] as TOML, and the map's alpha axis node as TOML text
  std::string base_toml, map_alpha_toml, omega_toml, alpha_toml;
};

// Parses and validates every field up front (errors name the field and the bound it violates: "design.budget =
// 0 violates design.budget in [1, 10000]"); the base spec is checked by the engine's own parser.
StatusOr<DesignSpec> ParseDesignSpec(const std::string& toml_text, const std::string& origin);

}  // namespace bistable

#endif  // BISTABLE_DESIGN_DESIGN_SPEC_H_
