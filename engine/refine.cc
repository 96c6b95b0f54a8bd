#include "engine/refine.h"

#include <algorithm>
#include <climits>
#include <cmath>

namespace bistable {
namespace {

constexpr int64_t kNonFinite = INT64_MIN + 1;  // the class of a NaN/inf criterion value

// The grid of a refined sweep: axis sizes, row-major (last axis fastest).
struct Grid {
  std::vector<long> n, step;  // values per axis, index stride per axis
  long points = 1;
  int d = 0;
  explicit Grid(const SweepSpec& spec) : d(static_cast<int>(spec.axes.size())) {
    n.resize(d), step.resize(d);
    for (int k = d - 1; k >= 0; --k) {
      n[k] = static_cast<long>(spec.axes[k].values.size());
      step[k] = points;
      points *= n[k];
    }
  }
  long Coord(long p, int k) const { return (p / step[k]) % n[k]; }
};

// Calls f(point) for every point origin + s * c, c in {0..m}^d (row-major order, ascending).
template <class F>
void ForBox(const Grid& g, long origin, long s, long m, F&& f) {
  std::vector<long> c(g.d, 0);
  while (true) {
    long p = origin;
    for (int k = 0; k < g.d; ++k) p += c[k] * s * g.step[k];
    f(p, c);
    int k = g.d - 1;
    while (k >= 0 && c[k] == m) c[k--] = 0;
    if (k < 0) return;
    ++c[k];
  }
}

struct Active {
  long origin;
  int run;  // levels in a row the parent's sibling group was all mixed
};

}  // namespace

const std::vector<Category>& RefineFillCategories() {
  static const std::vector<Category> kFill = {{0, "computed"}, {1, "interpolated"}, {2, "chaotic_mixed"}};
  return kFill;
}

int64_t RefineClass(const RefineConfig& r, const MetricSettings& m, const PointRecord& rec) {
  switch (r.criterion) {
    case RefineCriterion::kFrf0db: {
      const double v = rec.Get("frf_db");
      return !std::isfinite(v) ? kNonFinite : v >= 0 ? 1 : 0;
    }
    case RefineCriterion::kLleSign: {
      const double v = rec.Get("lle");
      return !std::isfinite(v) ? kNonFinite : v > m.chaos_threshold ? 1 : 0;
    }
    case RefineCriterion::kMotion:
    case RefineCriterion::kPeriod: {
      const double v = rec.Get(r.criterion == RefineCriterion::kMotion ? "motion" : "period");
      return !std::isfinite(v) ? kNonFinite : static_cast<int64_t>(std::llround(v));
    }
  }
  return kNonFinite;
}

StatusOr<RefineStep> PlanRefinement(const SweepSpec& spec, const RefineLookup& lookup) {
  const RefineConfig& r = spec.refine;
  if (!r.enabled()) return Status::Internal("PlanRefinement on a sweep without [refine]");
  const Grid g(spec);
  const int L = r.levels;
  const long group = 1L << g.d;  // children of a split cell
  std::vector<int64_t> cls(g.points, INT64_MIN);  // INT64_MIN: not planned
  RefineStep out;
  // Level 0: the coarse grid, and its cells.
  std::vector<long> level_points;
  std::vector<Active> active;
  {
    const long s0 = 1L << L;
    // Every point with each index a multiple of s0; cells at those with room for one more step.
    std::vector<long> c(g.d, 0);
    while (true) {
      long p = 0;
      bool origin = true;
      for (int k = 0; k < g.d; ++k) p += c[k] * s0 * g.step[k], origin = origin && (c[k] + 1) * s0 <= g.n[k] - 1;
      level_points.push_back(p);
      if (origin) active.push_back({p, 0});
      int k = g.d - 1;
      while (k >= 0 && (c[k] + 1) * s0 > g.n[k] - 1) c[k--] = 0;
      if (k < 0) break;
      ++c[k];
    }
  }
  long group_size = 1;  // level 0 cells have no siblings
  for (int level = 0;; ++level) {
    std::vector<std::optional<int64_t>> got;
    BISTABLE_RETURN_IF_ERROR(lookup(level_points, &got));
    if (got.size() != level_points.size()) return Status::Internal("refine lookup returned a wrong count");
    for (size_t i = 0; i < level_points.size(); ++i) {
      out.points.push_back(level_points[i]);
      if (got[i]) {
        cls[level_points[i]] = *got[i];
      } else {
        cls[level_points[i]] = INT64_MIN + 2;  // planned, not stored
        out.missing.push_back(level_points[i]);
      }
    }
    if (!out.missing.empty()) {
      std::sort(out.points.begin(), out.points.end());
      out.level = level;
      return out;
    }
    const long s = 1L << (L - level);
    std::vector<char> mixed(active.size());
    for (size_t i = 0; i < active.size(); ++i) {
      const int64_t first = cls[active[i].origin];
      bool m = false;
      ForBox(g, active[i].origin, s, 1, [&](long p, const std::vector<long>&) { m = m || cls[p] != first; });
      mixed[i] = m;
    }
    if (level == L) {  // finest cells: resolved, mixed ones are boundary cells
      for (size_t i = 0; i < active.size(); ++i) out.cells.push_back({active[i].origin, level, mixed[i] != 0});
      break;
    }
    std::vector<Active> next;
    std::vector<long> next_points;
    const long h = s / 2;
    for (size_t g0 = 0; g0 < active.size(); g0 += group_size) {
      const size_t g1 = std::min(active.size(), g0 + group_size);
      bool all_mixed = group_size > 1;
      for (size_t i = g0; i < g1; ++i) all_mixed = all_mixed && mixed[i];
      const int run = all_mixed ? active[g0].run + 1 : 0;
      for (size_t i = g0; i < g1; ++i) {
        if (!mixed[i]) {
          out.cells.push_back({active[i].origin, level, false});
          continue;
        }
        if (r.mixed_after > 0 && run >= r.mixed_after) {  // speckle: stop, keep the samples
          out.cells.push_back({active[i].origin, level, true});
          ++out.cells_mixed;
          continue;
        }
        ForBox(g, active[i].origin, h, 1, [&](long p, const std::vector<long>&) { next.push_back({p, run}); });
        ForBox(g, active[i].origin, h, 2, [&](long p, const std::vector<long>&) {
          if (cls[p] == INT64_MIN) cls[p] = INT64_MIN + 2, next_points.push_back(p);
        });
      }
    }
    std::sort(next_points.begin(), next_points.end());
    active = std::move(next);
    level_points = std::move(next_points);
    group_size = group;
    if (active.empty()) break;  // nothing mixed left: done at a coarser level
  }
  std::sort(out.points.begin(), out.points.end());
  out.level = L;
  out.complete = true;
  return out;
}

StatusOr<RefinedGrid> FillRefinedGrid(const SweepSpec& spec, const std::vector<long>& computed,
                                      const std::vector<PointRecord>& stored) {
  if (computed.size() != stored.size()) return Status::Internal("FillRefinedGrid: points and records differ in count");
  const Grid g(spec);
  std::vector<long> slot(g.points, -1);
  for (size_t i = 0; i < computed.size(); ++i) {
    if (computed[i] < 0 || computed[i] >= g.points) return Status::Internal("FillRefinedGrid: point outside the grid");
    slot[computed[i]] = static_cast<long>(i);
  }
  auto plan = PlanRefinement(spec, [&](const std::vector<long>& pts, std::vector<std::optional<int64_t>>* out) {
    out->clear();
    for (long p : pts)
      out->push_back(slot[p] < 0 ? std::nullopt
                                 : std::optional<int64_t>(RefineClass(spec.refine, spec.base.metrics, stored[slot[p]])));
    return Status::Ok();
  });
  if (!plan.ok()) return plan.status();
  if (!plan->complete) return Status::FailedPrecondition("refined sweep is incomplete: " + std::to_string(plan->missing.size()) +
                                                         " points of level " + std::to_string(plan->level) + " are not stored");
  const int L = spec.refine.levels;
  RefinedGrid out;
  out.computed = static_cast<long>(computed.size());
  out.level.assign(g.points, 0);
  out.fill.assign(g.points, static_cast<double>(RefineFill::kComputed));
  std::vector<int> owner(g.points, -1);  // resolving cell of a point not computed (the finest wins)
  for (size_t ci = 0; ci < plan->cells.size(); ++ci) {
    const RefineCell& c = plan->cells[ci];
    ForBox(g, c.origin, 1, 1L << (L - c.level), [&](long p, const std::vector<long>&) {
      out.level[p] = std::max(out.level[p], static_cast<double>(c.level));
      if (slot[p] < 0) owner[p] = static_cast<int>(ci);
    });
  }
  const auto& catalog = MetricCatalog();
  const size_t width = stored.empty() ? 0 : stored.front().v.size();
  out.records.resize(g.points);
  std::vector<long> corner_slot(1L << g.d);
  std::vector<double> w(1L << g.d);
  for (long p = 0; p < g.points; ++p) {
    if (slot[p] >= 0) {
      out.records[p] = stored[slot[p]];
      continue;
    }
    if (owner[p] < 0) return Status::Internal("FillRefinedGrid: a grid point lies in no resolved cell");
    const RefineCell& c = plan->cells[owner[p]];
    const long s = 1L << (L - c.level);
    out.fill[p] = static_cast<double>(c.mixed ? RefineFill::kChaoticMixed : RefineFill::kInterpolated);
    // Corner weights (multilinear) and the nearest corner (ties to the lower index).
    long nearest = 0;
    for (long b = 0; b < (1L << g.d); ++b) {
      long q = c.origin;
      double wb = 1;
      for (int k = 0; k < g.d; ++k) {
        const int bit = (b >> (g.d - 1 - k)) & 1;
        const double t = static_cast<double>(g.Coord(p, k) - g.Coord(c.origin, k)) / static_cast<double>(s);
        q += bit * s * g.step[k];
        wb *= bit ? t : 1 - t;
      }
      corner_slot[b] = slot[q];
      w[b] = wb;
      if (corner_slot[b] < 0) return Status::Internal("FillRefinedGrid: a resolved cell has a corner not computed");
    }
    for (int k = 0; k < g.d; ++k) {
      const long off = g.Coord(p, k) - g.Coord(c.origin, k);
      if (2 * off > s) nearest |= 1L << (g.d - 1 - k);
    }
    PointRecord rec = stored[corner_slot[nearest]];
    if (!c.mixed)
      for (size_t mi = 0; mi < catalog.size() && mi < width; ++mi) {
        if (catalog[mi].integer) continue;
        double sum = 0;
        bool finite = true;
        for (long b = 0; b < (1L << g.d); ++b) {
          const double v = stored[corner_slot[b]].v[mi];
          finite = finite && std::isfinite(v);
          sum += w[b] * v;
        }
        if (finite) rec.v[mi] = sum;
      }
    out.records[p] = std::move(rec);
  }
  return out;
}

}  // namespace bistable
