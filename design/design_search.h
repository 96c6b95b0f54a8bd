// The design search (issue 17, `bistable design`): a global optimiser (NLopt) proposes resonator
// designs (lambda, phi, eta_r) within bounds; each is scored from its sub-sweep over Ω (an ordinary
// sweep run by the caller's evaluator: embedded or through a coordinator); the Pareto front over
// (band width up, unsafe share in the band down, cost down) is taken over every evaluated candidate.
// Definitions (docs/design-search.md):
//   g(Ω_i)     = max over the design's alphas of frf_db(alpha, Ω_i) (NaN: not attenuated);
//   chaotic_i  = at some alpha, motion == chaotic or lle > chaos_threshold; unsafe_i = chaotic_i or
//                motion undefined (the run diverged);
//   band       = {Ω in [Ω_0, Ω_n-1] : G(Ω) < 0}, G the piecewise-linear interpolant of g over the Ω line;
//   band_width = its measure (a zero crossing inside a cell is found by linear interpolation);
//   band points = {i : g_i < 0}; chaotic_share_band = chaotic band points / band points (0 with none);
//   unsafe_share_band = unsafe band points / band points (0 with none): chaotic or diverged, the front's
//                second objective (a diverged band point is as unusable as a chaotic one);
//   chaotic_share = chaotic points / all points of the Ω line;
//   safe_band_width = band_width without the cells that have an unsafe band point at either end;
//   feasible   = at least one band point and no unsafe band point (then safe_band_width == band_width).
// The optimiser maximises safe_band_width; the best design is the feasible candidate with the widest
// band (ties: lower cost, then earlier).
#ifndef BISTABLE_DESIGN_DESIGN_SEARCH_H_
#define BISTABLE_DESIGN_DESIGN_SEARCH_H_

#include <functional>
#include <string>
#include <vector>

#include "base/status.h"
#include "design/design_spec.h"

namespace bistable {

struct DesignScore {
  double band_width = 0, safe_band_width = 0;
  double chaotic_share_band = 0, unsafe_share_band = 0, chaotic_share = 0;
  long band_points = 0, chaotic_in_band = 0, unsafe_in_band = 0;
  double band_lo = NAN, band_hi = NAN;  // the smallest and largest Ω of the band (NaN: empty)
  bool feasible() const { return band_points > 0 && unsafe_in_band == 0; }
};

// frf_db, motion, lle: row-major [alpha][omega] with n_alpha rows over the Ω line `omega`.
DesignScore ScoreDesign(const std::vector<double>& omega, size_t n_alpha, const std::vector<double>& frf_db,
                        const std::vector<double>& motion, const std::vector<double>& lle, double chaos_threshold);

// What running one candidate's sweep gave: its id, cost and the metrics the score reads.
struct SweepOutcome {
  std::string sweep_id, map_path;  // map_path: local file ("" through a coordinator)
  long items = 0, cached = 0;      // items of the sweep, of which reused from the cache
  double seconds = 0;
  std::vector<double> frf_db, motion, lle;  // row-major over dims ([alpha][omega] for a candidate)
  std::vector<std::string> dim_names;       // the map's dimensions and their coordinates
  std::vector<size_t> dims;
  std::vector<std::vector<double>> axis_values;
};
// Runs one sweep spec (TOML) to completion and reads its metrics back.
using SweepRunner = std::function<StatusOr<SweepOutcome>(const std::string& spec_toml)>;

struct Candidate {
  int index = 0;
  DesignPoint x{};
  double cost = 0;
  DesignScore score;
  std::string sweep_id;
  long items = 0, computed = 0;
  double seconds = 0;
};

// Non-dominated candidates (maximise band_width, minimise unsafe_share_band and cost): indices in
// descending band width. Distinct designs with equal objectives are all kept; a design evaluated twice
// appears once.
std::vector<int> ParetoFront(const std::vector<Candidate>& c);
// Whether a dominates b (at least as good in all three, better in one).
bool Dominates(const Candidate& a, const Candidate& b);
// The best feasible candidate (widest band; ties: lower cost, then lower index), -1 when none is.
int BestCandidate(const std::vector<Candidate>& c);
// The best k distinct feasible candidates, best first.
std::vector<int> BestCandidates(const std::vector<Candidate>& c, int k);

struct SearchResult {
  std::vector<Candidate> candidates;
  std::vector<int> front;
  int best = -1;
  long items = 0, computed = 0;
  double seconds = 0;
  bool interrupted = false;  // cancellation stopped the optimiser (what ran is in the cache)
};

// Runs the optimiser for at most spec.budget candidates; on_candidate (may be empty) is called after
// each. An error of the runner stops the search and is returned; cancellation (dynamics/cancel.h)
// stops it with interrupted = true and what was evaluated.
StatusOr<SearchResult> RunDesignSearch(const DesignSpec& spec, const SweepRunner& run,
                                       const std::function<void(const Candidate&)>& on_candidate);

// Scores every design of a brute-force sweep (DesignSpec::BruteForceToml) read back as full arrays:
// `dims`/`dim_names` the map's shape (lambda, phi, eta_r, alpha, omega in any subset, canonical order).
std::vector<Candidate> ScoreBruteForce(const DesignSpec& spec, const std::vector<std::string>& dim_names,
                                       const std::vector<size_t>& dims, const std::vector<double>& frf_db,
                                       const std::vector<double>& motion, const std::vector<double>& lle,
                                       const std::vector<std::vector<double>>& axis_values);

}  // namespace bistable

#endif  // BISTABLE_DESIGN_DESIGN_SEARCH_H_
