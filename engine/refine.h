// Adaptive maps ([refine], issue 17): which grid points a refined sweep computes, level by level, and
// how the map at the finest grid is completed from them.
//
// The axes give the finest grid; level 0 is the coarse grid of every 2^L-th value along each axis
// (L = refine.levels), cut into cells of 2^d corners. At level k the cells have index stride
// s = 2^(L-k). A cell whose corners agree on the criterion class (RefineClass) is resolved; a mixed
// cell is split into 2^d children at stride s/2, whose new corners are level k+1's points; a mixed cell
// at stride 1 is a boundary cell (every point of it computed). A mixed cell whose siblings were all
// mixed for `mixed_after` levels in a row (speckle: chaos, fractal basin boundaries — a boundary
// line crosses at most 2^d - 1 children of a cell) stops refining and is marked chaotic-mixed: it
// keeps the samples it has.
//
// Everything here is a function of the stored records, so a refined sweep resumes by planning again:
// the levels already stored are read back and the first level with missing points is computed.
#ifndef BISTABLE_ENGINE_REFINE_H_
#define BISTABLE_ENGINE_REFINE_H_

#include <cstdint>
#include <functional>
#include <vector>

#include "base/status.h"
#include "engine/metric_catalog.h"
#include "engine/sweep_spec.h"

namespace bistable {

// The class of a computed point under the criterion: frf_0db (frf_db >= 0), motion code, lle_sign
// (lle > chaos_threshold), period. Non-finite values are a class of their own.
int64_t RefineClass(const RefineConfig& r, const MetricSettings& m, const PointRecord& rec);

// How a grid point of a refined map got its values (the refine_fill dataset; CF flag_meanings).
enum class RefineFill : int { kComputed = 0, kInterpolated = 1, kChaoticMixed = 2 };
const std::vector<Category>& RefineFillCategories();

struct RefineCell {
  long origin = 0;  // grid index of the corner with the smallest indices
  int level = 0;    // stride 2^(levels - level)
  bool mixed = false;  // corners disagree (a boundary cell at the finest level, else chaotic-mixed)
};

struct RefineStep {
  std::vector<long> points;   // every point planned so far (levels 0..level), ascending
  std::vector<long> missing;  // those of `points` not stored yet (all of them at `level`), ascending
  int level = 0;              // the level being computed (== levels when complete)
  bool complete = false;      // every level stored: the map can be published
  std::vector<RefineCell> cells;  // when complete: the cells that resolved the grid, coarse to fine
  long cells_mixed = 0;           // chaotic-mixed cells (stopped refining), when complete
};

// The classes of `points` (ascending): class per point, or nullopt where no valid record is stored.
using RefineLookup = std::function<Status(const std::vector<long>& points, std::vector<std::optional<int64_t>>* classes)>;

// Plans a refined sweep against what is stored: walks the levels while every point of a level is
// stored and stops at the first level with missing points (or completes).
StatusOr<RefineStep> PlanRefinement(const SweepSpec& spec, const RefineLookup& lookup);

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
