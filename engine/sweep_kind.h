// Sweep kinds (issue 40): what a sweep does beyond "every grid point, integrated and measured". A spec's
// kind is one of five, decided by its tables (they exclude one another; engine/sweep_spec_read.cc says
// which combinations are refused):
//
//   grid          [initial_conditions] states (or one default start): one item per state and point;
//                 with several states, the map adds the fractions of each motion type per point
//   continuation  [continuation]: items are chains along one axis, each point starting from the
//                 previous point's end, up and/or down (bifurcation diagrams, hysteresis)
//   robustness    [robustness]: items are tolerance samples; the map adds motion fractions and their
//                 Monte-Carlo standard errors
//   basins        every axis an initial-state axis: the map adds the attractor of each start and the
//                 table of attractors (engine/basins.h)
//   refined       [refine]: the grid is computed in rounds, each planned from the last (engine/refine.h);
//                 the map adds how each point got its values
//
// The seam, after DifferentialEquations.jl's EnsembleProblem (prob_func, output_func, reduction) and
// Attractors.jl's mappers: the runner (the plan, the evaluation, the map writer, the dashboard) never asks
// which kind a sweep is; it asks the kind for
//   - its items: slots per point and what a slot is (an initial state, a direction, a sample), the start
//     and parameters of an item, and its content key;
//   - its chains: items that run in order, each from the previous one's end, and never apart;
//   - its rounds: whether the next items are planned from this round's results (and so no shards);
//   - its map layout: the slot dimension and the variables it adds beyond the stored metrics (computed
//     here, from the records; storage/map_file.cc writes whatever it is given).
// Adding a kind: a class below, a case in KindOf, its spec table in sweep_spec_read.cc, its canonical
// line (CanonicalLine: a new line, so no other sweep's id changes). docs/architecture.md, "Seams".
#ifndef BISTABLE_ENGINE_SWEEP_KIND_H_
#define BISTABLE_ENGINE_SWEEP_KIND_H_

#include <optional>
#include <ostream>
#include <string>
#include <utility>
#include <vector>

#include "base/status.h"
#include "engine/metric_catalog.h"
#include "engine/refine.h"
#include "engine/sweep_spec.h"

namespace bistable {

// The trailing map dimension a kind's slots make (present when a point has more than one slot).
struct SlotDimension {
  std::string name;                                 // "ic" | "direction"
  std::string long_name;                            // CF long_name
  std::vector<std::pair<int, std::string>> labels;  // named slots (up, down); empty: plain indices
};

// A variable a kind adds to the map (beyond the stored metrics), computed from the records.
struct KindVariable {
  enum class Over {
    kPoints,  // the grid's axes
    kItems,   // the axes and the slot dimension (when there is one)
    kTable,   // the one dimension of the kind's table (KindMapPart::table), inside its group
  };
  std::string name;
  Over over = Over::kPoints;
  std::vector<double> values;
  bool integer = false;
  std::string long_name, unit, definition;          // unit: the catalog's form ("delta_s", "fraction", "code")
  std::vector<std::pair<int, std::string>> labels;  // a flag variable's codes and names; empty: none
};

// A global attribute a kind adds (one of three types, as written).
struct KindAttribute {
  enum class Type { kDouble, kLong, kString };
  std::string name;
  Type type = Type::kDouble;
  double number = 0;
  long integer = 0;
  std::string text;
};

// What a kind adds to its map, written in this order: the variables (a table's variables after the
// table's dimension is made), then the attributes.
struct KindMapPart {
  struct Table {
    std::string group;      // a netCDF-4 group holding the table (xarray: open_dataset(path, group=...))
    std::string dimension;  // its one dimension, a coordinate 0..size-1
    std::string long_name;
    long size = 0;
    std::vector<std::pair<int, std::string>> labels;
  };
  std::vector<KindVariable> variables;  // kPoints / kItems variables, at the root
  std::optional<Table> table;
  std::vector<KindVariable> table_variables;  // kTable variables, in the table's group
  std::vector<KindAttribute> attributes;
};

class SweepKind {
 public:
  virtual ~SweepKind() = default;
  // "grid", "continuation", "robustness", "basins", "refined": the status and the dashboard show it.
  virtual const char* Name() const = 0;

  // Items: slots per grid point (the WorkItem's `ic`), ≥ 1.
  virtual int Slots(const SweepSpec& spec) const = 0;
  virtual SlotDimension Dimension(const SweepSpec& spec) const;
  // The point of an item: the start (an [initial_conditions] state, or the model's default start whose
  // components initial-state axes set), the axes' values, then the kind's own change of the slot.
  PointSpec PointAt(const SweepSpec& spec, long point, int slot) const;
  // The start alone: spec.base with the slot's initial state (before the axes and the kind's change).
  PointSpec Start(const SweepSpec& spec, int slot) const;
  // The content key of an item (the point cache's): by default the point's own parameters and settings.
  virtual std::string ItemKey(const SweepSpec& spec, long point, int slot) const;

  // Chains: the items that run in order, each starting from the previous one's end state, computed
  // and stored whole (a job never splits one, a shard takes one whole). Empty: every item alone.
  virtual std::vector<std::vector<WorkItem>> Chains(const SweepSpec& spec) const;
  // Whether item `next` starts from the end state of item `prev` (the item before it in a job).
  virtual bool Continues(const SweepSpec& spec, const WorkItem& prev, const WorkItem& next) const;
  // Whether the kind makes chains at all (cheap: the evaluation asks it per job).
  virtual bool Chained() const { return false; }

  // Rounds: whether the next items are planned from this round's results. Such a sweep cannot be cut
  // into shards (CheckShardable) and its map is filled in from what was computed (RefinedGrid).
  virtual bool InRounds() const { return false; }
  // A sweep in rounds, complete: its finest grid filled in from the points computed (`points`
  // ascending, `stored[i]` the record of points[i]). FailedPrecondition when a point it needs is missing.
  virtual StatusOr<RefinedGrid> Fill(const SweepSpec& spec, const std::vector<long>& points,
                                     const std::vector<PointRecord>& stored) const;

  // Map layout: what the kind adds to the map. `refined` is the filled grid of a sweep in rounds
  // (nullptr otherwise); records are in item order (point · Slots + slot).
  virtual KindMapPart MapPart(const SweepSpec& spec, const std::vector<PointRecord>& records,
                              const RefinedGrid* refined) const;
  // The kind's line of the canonical text (the sweep id hashes it); "" for a plain grid.
  virtual std::string CanonicalLine(const SweepSpec& spec) const;

 protected:
  // The [initial_conditions] state slot `slot` starts from.
  virtual size_t StateOf(int /*slot*/) const { return 0; }
  // The kind's change of an item's point after the axes apply (robustness: the tolerance sample).
  virtual void Vary(const SweepSpec& /*spec*/, int /*slot*/, PointSpec* /*p*/) const {}
};

// The kind of a spec (derived from its tables, so hand-built specs in tests have one too).
const SweepKind& KindOf(const SweepSpec& spec);

}  // namespace bistable

#endif  // BISTABLE_ENGINE_SWEEP_KIND_H_
