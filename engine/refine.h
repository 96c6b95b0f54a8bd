// Adaptive maps ([refine], issue 17): which grid points a refined sweep computes, round by round, and
// how the map at the finest grid is completed from them.
//
// The axes give the finest grid; level 0 is the coarse grid of every 2^L-th value along each axis
// (L = refine.levels), cut into cells of 2^d corners; a cell of level k has index stride s = 2^(L-k).
// Refinement goes in rounds: each round computes the new points of the cells split in the last one.
//   - A cell whose corners agree on the criterion class (RefineClass) is resolved — until a point
//     computed later on its faces (by a finer neighbour) disagrees: then it is split after all.
//   - A mixed cell is split into 2^d children at stride s/2; a mixed cell at stride 1 is a boundary cell
//     (every point of it computed).
//   - A mixed cell with a chaotic corner whose sibling group (itself and the other children of its
//     parent) was all mixed for `mixed_after` levels in a row stops refining and is chaotic-mixed: it
//     keeps the samples it has. (A boundary line crosses at most 2^d - 1 children of a cell; a
//     speckled chaotic region crosses them all, level after level. Triple junctions and thin stripes of
//     regular motion can do so too; they have no chaotic corner and are refined to the end.)
//
// Everything here is a function of the stored records, so a refined sweep resumes by planning again:
// the rounds already stored are read back and the first round with missing points is computed.
#ifndef BISTABLE_ENGINE_REFINE_H_
#define BISTABLE_ENGINE_REFINE_H_

#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <vector>

#include "base/status.h"
#include "engine/metric_catalog.h"
#include "engine/sweep_spec.h"

namespace bistable {

// What refinement needs of a computed point: its class under the criterion — frf_0db (frf_db >= 0),
// motion code, lle_sign (lle > chaos_threshold), period; non-finite values are a class of their own —
// and whether its motion is chaotic (only cells with a chaotic corner can be marked chaotic-mixed).
struct RefineMark {
  int64_t cls = 0;
  bool chaotic = false;
};
RefineMark RefineClass(const RefineConfig& r, const MetricSettings& m, const PointRecord& rec);

// How a grid point of a refined map got its values (the refine_fill dataset; CF flag_meanings).
enum class RefineFill : int { kComputed = 0, kInterpolated = 1, kChaoticMixed = 2 };
const std::vector<Category>& RefineFillCategories();

struct RefineCell {
  long origin = 0;     // grid index of the corner with the smallest indices
  int level = 0;       // stride 2^(levels - level)
  bool mixed = false;  // corners disagree (a boundary cell at the finest level, else chaotic-mixed)
};

struct RefineStep {
  std::vector<long> points;       // every point planned so far (rounds 0..round), ascending
  std::vector<long> missing;      // those of `points` not stored yet (all of them of `round`), ascending
  int round = 0;                  // the round being computed (round 0: the coarse grid; round k mostly level k)
  bool complete = false;          // every round stored: the map can be published
  std::vector<RefineCell> cells;  // when complete: the cells that resolved the grid, coarse to fine
  long cells_mixed = 0;           // chaotic-mixed cells (stopped refining), when complete
};

// The marks of `points` (ascending): one per point, or nullopt where no valid record is stored.
using RefineLookup =
    std::function<Status(const std::vector<long>& points, std::vector<std::optional<RefineMark>>* marks)>;

// Plans a refined sweep against what is stored: walks the rounds while every point of a round is
// stored and stops at the first round with missing points (or completes).
StatusOr<RefineStep> PlanRefinement(const SweepSpec& spec, const RefineLookup& lookup);

// The same walk, kept between calls: Advance looks up only the current round's points (the rounds
// before are remembered), so a coordinator planning round after round does not read everything back
// each time. A new planner (a restarted coordinator) walks from the start. Not thread-safe.
class RefinePlanner {
 public:
  explicit RefinePlanner(const SweepSpec& spec);  // spec.refine.enabled()
  ~RefinePlanner();
  StatusOr<RefineStep> Advance(const RefineLookup& lookup);

 private:
  struct State;
  std::unique_ptr<State> st_;
};

// The finest grid of a completed refinement: records[p] for every grid point p (computed points as
// stored; others multilinear in their resolving cell's corners for real-valued metrics, the nearest
// corner for codes, peaks, turning points and section points, and in chaotic-mixed cells), with
// refine_level (level of the smallest cell holding the point) and refine_fill (RefineFill) per point.
struct RefinedGrid {
  std::vector<PointRecord> records;
  std::vector<double> level, fill;
  long computed = 0;
};
// `computed` ascending, `stored[i]` the record of computed[i].
StatusOr<RefinedGrid> FillRefinedGrid(const SweepSpec& spec, const std::vector<long>& computed,
                                      const std::vector<PointRecord>& stored);

}  // namespace bistable

#endif  // BISTABLE_ENGINE_REFINE_H_
