#include "engine/refine.h"

#include <algorithm>
#include <climits>
#include <cmath>
#include <map>

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
  int level;
  int run;     // levels in a row the parent's sibling group was all mixed
  long group;  // the split that made this cell (siblings share it); -1: a coarse or reopened cell
};

}  // namespace

const std::vector<Category>& RefineFillCategories() {
  static const std::vector<Category> kFill = {{0, "computed"}, {1, "interpolated"}, {2, "chaotic_mixed"}};
  return kFill;
}

RefineMark RefineClass(const RefineConfig& r, const MetricSettings& m, const PointRecord& rec) {
  RefineMark out;
  out.chaotic = rec.Get("motion") == MotionCode(Motion::kChaotic);
  switch (r.criterion) {
    case RefineCriterion::kFrf0db: {
      const double v = rec.Get("frf_db");
      out.cls = !std::isfinite(v) ? kNonFinite : v >= 0 ? 1 : 0;
      break;
    }
    case RefineCriterion::kLleSign: {
      const double v = rec.Get("lle");
      out.cls = !std::isfinite(v) ? kNonFinite : v > m.chaos_threshold ? 1 : 0;
      break;
    }
    case RefineCriterion::kMotion:
    case RefineCriterion::kPeriod: {
      const double v = rec.Get(r.criterion == RefineCriterion::kMotion ? "motion" : "period");
      out.cls = !std::isfinite(v) ? kNonFinite : static_cast<int64_t>(std::llround(v));
      break;
    }
  }
  return out;
}

struct RefinePlanner::State {
  explicit State(const SweepSpec& spec) : g(spec), r(spec.refine), L(spec.refine.levels) {}
  static constexpr int64_t kUnplanned = INT64_MIN, kPending = INT64_MIN + 2;
  Grid g;
  RefineConfig r;
  int L;
  std::vector<int64_t> cls;
  std::vector<char> chaotic;
  std::vector<long> points;                   // every point planned (rounds 0..round), in planning order
  std::vector<long> round_points;             // the current round's points, ascending
  std::vector<Active> active;                 // the cells the current round's points decide
  std::vector<RefineCell> resolved, uniform;  // final cells; agreeing cells (reopened when a face point disagrees)
  long groups = 0, cells_mixed = 0;
  int round = 0;
  bool complete = false;
  long stride(int level) const { return 1L << (L - level); }
};

RefinePlanner::RefinePlanner(const SweepSpec& spec) : st_(std::make_unique<State>(spec)) {
  State& s = *st_;
  s.cls.assign(s.g.points, State::kUnplanned);
  s.chaotic.assign(s.g.points, 0);
  // Round 0: the coarse grid, and its cells.
  const long s0 = s.stride(0);
  std::vector<long> c(s.g.d, 0);
  while (true) {
    long p = 0;
    bool origin = true;
    for (int k = 0; k < s.g.d; ++k) p += c[k] * s0 * s.g.step[k], origin = origin && (c[k] + 1) * s0 <= s.g.n[k] - 1;
    s.round_points.push_back(p);
    s.cls[p] = State::kPending;
    if (origin) s.active.push_back({p, 0, 0, -1});
    int k = s.g.d - 1;
    while (k >= 0 && (c[k] + 1) * s0 > s.g.n[k] - 1) c[k--] = 0;
    if (k < 0) break;
    ++c[k];
  }
  s.points = s.round_points;
}

RefinePlanner::~RefinePlanner() = default;

StatusOr<RefineStep> RefinePlanner::Advance(const RefineLookup& lookup) {
  State& s = *st_;
  const Grid& g = s.g;
  RefineStep out;
  while (!s.complete) {
    std::vector<std::optional<RefineMark>> got;
    BISTABLE_RETURN_IF_ERROR(lookup(s.round_points, &got));
    if (got.size() != s.round_points.size()) return Status::Internal("refine lookup returned a wrong count");
    for (size_t i = 0; i < s.round_points.size(); ++i) {
      if (got[i]) {
        s.cls[s.round_points[i]] = got[i]->cls;
        s.chaotic[s.round_points[i]] = got[i]->chaotic;
      } else {
        out.missing.push_back(s.round_points[i]);
      }
    }
    if (!out.missing.empty()) {
      out.points = s.points;
      std::sort(out.points.begin(), out.points.end());
      out.round = s.round;
      return out;
    }
    auto known = [&](long p) { return s.cls[p] != State::kUnplanned && s.cls[p] != State::kPending; };
    // Agreeing cells with a disagreeing point on a face (computed since, by a finer neighbour) reopen.
    if (s.round > 0) {
      std::vector<RefineCell> keep;
      for (const RefineCell& c : s.uniform) {
        const int64_t first = s.cls[c.origin];
        bool disagree = false;
        ForBox(g, c.origin, 1, s.stride(c.level),
               [&](long p, const std::vector<long>&) { disagree = disagree || (known(p) && s.cls[p] != first); });
        if (disagree)
          s.active.push_back({c.origin, c.level, 0, -1});
        else
          keep.push_back(c);
      }
      s.uniform = std::move(keep);
    }
    if (s.active.empty()) break;
    // Mixed: any two computed points of the cell (its corners, and points on its faces computed by
    // finer neighbours) disagree. A sibling group is all mixed when every one of its 2^d cells is.
    std::vector<char> mixed(s.active.size()), has_chaos(s.active.size());
    std::map<long, int> group_mixed, group_size;
    for (size_t i = 0; i < s.active.size(); ++i) {
      const int64_t first = s.cls[s.active[i].origin];
      bool m = false, ch = false;
      ForBox(g, s.active[i].origin, 1, s.stride(s.active[i].level), [&](long p, const std::vector<long>&) {
        if (!known(p)) return;
        m = m || s.cls[p] != first;
        ch = ch || s.chaotic[p];
      });
      mixed[i] = m, has_chaos[i] = ch;
      if (s.active[i].group >= 0) ++group_size[s.active[i].group], group_mixed[s.active[i].group] += m;
    }
    std::vector<Active> next;
    std::vector<long> next_points;
    for (size_t i = 0; i < s.active.size(); ++i) {
      const Active& a = s.active[i];
      const long st = s.stride(a.level);
      if (!mixed[i]) {
        s.uniform.push_back({a.origin, a.level, false});
        continue;
      }
      if (st == 1) {  // a boundary cell: every point of it computed
        s.resolved.push_back({a.origin, a.level, true});
        continue;
      }
      const bool all_mixed = a.group >= 0 && group_size[a.group] == (1 << g.d) && group_mixed[a.group] == (1 << g.d);
      const int run = all_mixed ? a.run + 1 : 0;
      if (s.r.mixed_after > 0 && run >= s.r.mixed_after && has_chaos[i]) {  // chaotic speckle: stop, keep the samples
        s.resolved.push_back({a.origin, a.level, true});
        ++s.cells_mixed;
        continue;
      }
      const long group = s.groups++;
      ForBox(g, a.origin, st / 2, 1, [&](long p, const std::vector<long>&) {
        next.push_back({p, a.level + 1, run, group});
      });
      ForBox(g, a.origin, st / 2, 2, [&](long p, const std::vector<long>&) {
        if (s.cls[p] == State::kUnplanned) s.cls[p] = State::kPending, next_points.push_back(p);
      });
    }
    std::sort(next_points.begin(), next_points.end());
    s.active = std::move(next);
    s.round_points = std::move(next_points);
    s.points.insert(s.points.end(), s.round_points.begin(), s.round_points.end());
    ++s.round;
  }
  s.complete = true;
  // Coarse to fine (the fill lets a finer cell own the points it shares with a coarser one).
  out.cells = s.uniform;
  out.cells.insert(out.cells.end(), s.resolved.begin(), s.resolved.end());
  std::stable_sort(out.cells.begin(), out.cells.end(),
                   [](const RefineCell& a, const RefineCell& b) { return a.level < b.level; });
  out.points = s.points;
  std::sort(out.points.begin(), out.points.end());
  out.round = s.round;
  out.complete = true;
  out.cells_mixed = s.cells_mixed;
  return out;
}

StatusOr<RefineStep> PlanRefinement(const SweepSpec& spec, const RefineLookup& lookup) {
  if (!spec.refine.enabled()) return Status::Internal("PlanRefinement on a sweep without [refine]");
  RefinePlanner planner(spec);
  return planner.Advance(lookup);
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
  auto plan = PlanRefinement(spec, [&](const std::vector<long>& pts, std::vector<std::optional<RefineMark>>* out) {
    out->clear();
    for (long p : pts)
      out->push_back(slot[p] < 0
                         ? std::nullopt
                         : std::optional<RefineMark>(RefineClass(spec.refine, spec.base.metrics, stored[slot[p]])));
    return Status::Ok();
  });
  if (!plan.ok()) return plan.status();
  if (!plan->complete)
    return Status::FailedPrecondition("refined sweep is incomplete: " + std::to_string(plan->missing.size()) +
                                      " points of round " + std::to_string(plan->round) + " are not stored");
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
