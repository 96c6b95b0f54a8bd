// Basins of attraction: the attractor each start of a basin sweep (every axis an initial-state axis,
// ym0/vm0/yr0/vr0) ends on, identified across the map, with each attractor's basin and boundary
// fraction. Built from stored records only (motion, period, y range, strobe_y/strobe_v), so a basin map
// is published like any map and recomputes nothing.
#ifndef BISTABLE_ENGINE_BASINS_H_
#define BISTABLE_ENGINE_BASINS_H_

#include <string>
#include <vector>

#include "engine/metric_catalog.h"
#include "engine/sweep_spec.h"

namespace bistable {

struct Attractor {
  int id = 0;                         // 0 = the largest basin
  int motion = 0;                     // motion code (0 intrawell, 1 interwell, 2 chaotic; −2 the "other" class)
  int period = 0;                     // forcing periods, 0 = none found (chaotic, quasi-periodic, unsettled)
  std::string well;                   // "+well", "-well" or "interwell" (from the window's y_m range)
  double strobe_y = 0, strobe_v = 0;  // the Poincaré fingerprint (NaN for non-periodic attractors)
  long cells = 0;                     // starts ending here
  double basin_fraction = 0;          // cells / starts
  double boundary_fraction = 0;       // of its cells, those with a grid neighbour ending elsewhere
  std::string label;                  // one word, e.g. "P1_+well_y1.226", "chaotic_interwell" (CF flag_meanings)
};

struct BasinMap {
  std::vector<int> ids;               // per start, in record order; -1 undefined (diverged)
  std::vector<Attractor> attractors;  // by id
  double boundary_fraction = 0;       // starts with a neighbour on another attractor, of all starts
};

// Periodic starts are one attractor when motion and period agree and their fingerprints lie within
// `tol` (in y_m and y_m'); non-periodic starts are grouped by motion and well. Past
// limits::kMaxAttractors kinds, further kinds share one "other" class. Neighbours: ±1 along each axis
// of the grid.
BasinMap ClassifyAttractors(const SweepSpec& spec, const std::vector<PointRecord>& records, double tol);

}  // namespace bistable

#endif  // BISTABLE_ENGINE_BASINS_H_
