#include "engine/sweep_kind.h"

#include <cmath>
#include <cstdio>

#include "engine/basins.h"
#include "engine/content_hash.h"
#include "engine/refine.h"
#include "engine/sweep_spec_keys.h"

namespace bistable {
namespace {

std::string G17(double v) {
  char b[40];
  std::snprintf(b, sizeof b, "%.17g", v);
  return b;
}

KindVariable Variable(std::string name, KindVariable::Over over, std::vector<double> values, bool integer = false) {
  KindVariable v;
  v.name = std::move(name);
  v.over = over;
  v.values = std::move(values);
  v.integer = integer;
  return v;
}

KindAttribute Attribute(std::string name, KindAttribute::Type type) {
  KindAttribute a;
  a.name = std::move(name);
  a.type = type;
  return a;
}

std::vector<std::pair<int, std::string>> Labels(const std::vector<Category>& cats) {
  std::vector<std::pair<int, std::string>> out;
  for (const Category& c : cats) out.emplace_back(c.code, c.name);
  return out;
}

// The fraction of each motion type over a point's slots (several initial states, or tolerance samples),
// and with `stderr` their Monte-Carlo standard errors: a probability estimated from the samples.
std::vector<KindVariable> MotionFractions(const SweepSpec& spec, const std::vector<PointRecord>& records,
                                          bool with_stderr) {
  std::vector<KindVariable> out;
  const long np = spec.points();
  const int nic = KindOf(spec).Slots(spec);
  const size_t motion_index = MetricIndex("motion");
  static const char* kNames[] = {"frac_intrawell", "frac_interwell", "frac_chaotic"};
  for (int code = 0; code <= 2; ++code) {
    KindVariable f = Variable(kNames[code], KindVariable::Over::kPoints, std::vector<double>(np, 0.0));
    for (long p = 0; p < np; ++p) {
      int hit = 0;
      for (int i = 0; i < nic; ++i) hit += records[p * nic + i].Get(motion_index) == code;
      f.values[p] = static_cast<double>(hit) / nic;
    }
    const std::string motion = MotionName(code == 0   ? Motion::kIntrawell
                                          : code == 1 ? Motion::kInterwell
                                                      : Motion::kChaotic);
    f.long_name = "fraction of the initial conditions ending in " + motion + " motion";
    f.unit = "fraction";
    f.definition = "fraction of the initial conditions whose motion type is this one";
    out.push_back(f);
    if (!with_stderr) continue;
    KindVariable se =
        Variable(std::string(kNames[code]) + "_stderr", KindVariable::Over::kPoints, std::vector<double>(np));
    for (long p = 0; p < np; ++p) se.values[p] = std::sqrt(f.values[p] * (1.0 - f.values[p]) / nic);
    se.long_name = "Monte-Carlo standard error of " + std::string(kNames[code]);
    se.unit = "fraction";
    se.definition = "sqrt(p (1 - p) / samples) of the fraction p over the tolerance samples";
    out.push_back(std::move(se));
  }
  return out;
}

// [initial_conditions]: one item per state (one default start without states).
class GridKind : public SweepKind {
 public:
  const char* Name() const override { return "grid"; }
  int Slots(const SweepSpec& spec) const override {
    return spec.initial_states.empty() ? 1 : static_cast<int>(spec.initial_states.size());
  }
  KindMapPart MapPart(const SweepSpec& spec, const std::vector<PointRecord>& records,
                      const RefinedGrid*) const override {
    KindMapPart part;  // multistability: the fraction of initial conditions ending in each motion type
    if (Slots(spec) > 1) part.variables = MotionFractions(spec, records, /*with_stderr=*/false);
    return part;
  }

 protected:
  size_t StateOf(int slot) const override { return static_cast<size_t>(slot); }
};

// [continuation]: chains along one axis, up and/or down; slot 0 the first direction, 1 the second.
class ContinuationKind : public SweepKind {
 public:
  const char* Name() const override { return "continuation"; }
  bool Chained() const override { return true; }
  int Slots(const SweepSpec& spec) const override { return spec.continuation.directions(); }
  SlotDimension Dimension(const SweepSpec& spec) const override {
    return {
        "direction", "direction of the continuation sweep along " + spec.continuation.axis, {{0, "up"}, {1, "down"}}};
  }
  // A chained point's start state is the previous point's end state: it is determined by the whole spec
  // and the point's place in its chain, so that is what the key hashes. (The canonical text is hashed once
  // per spec, not once per item: it holds every axis value.)
  std::string ItemKey(const SweepSpec& spec, long point, int slot) const override {
    return ContentHashHex((spec.canonical_hash.empty() ? ContentHashHex(spec.CanonicalText()) : spec.canonical_hash) +
                          "|chain|" + std::to_string(point) + "|" + std::to_string(slot));
  }
  std::vector<std::vector<WorkItem>> Chains(const SweepSpec& spec) const override {
    std::vector<std::vector<WorkItem>> chains;
    long stride = 1, n = 1;
    for (long k = static_cast<long>(spec.axes.size()) - 1; k >= 0; --k) {
      if (spec.axes[k].name == spec.continuation.axis) {
        n = static_cast<long>(spec.axes[k].values.size());
        break;
      }
      stride *= static_cast<long>(spec.axes[k].values.size());
    }
    for (long p = 0; p < spec.points(); ++p) {
      if (Index(spec, p) != 0) continue;  // p is a line's first point
      for (int ic = 0; ic < Slots(spec); ++ic) {
        std::vector<WorkItem> chain;
        for (long i = 0; i < n; ++i) chain.push_back({p + (spec.ChainGoesDown(ic) ? n - 1 - i : i) * stride, ic});
        chains.push_back(std::move(chain));
      }
    }
    return chains;
  }
  // The same line and direction, the next index along the axis.
  bool Continues(const SweepSpec& spec, const WorkItem& prev, const WorkItem& next) const override {
    const int step = spec.ChainGoesDown(next.ic) ? -1 : 1;
    return prev.ic == next.ic && Line(spec, prev.point) == Line(spec, next.point) &&
           Index(spec, next.point) == Index(spec, prev.point) + step;
  }
  std::string CanonicalLine(const SweepSpec& spec) const override {
    const ContinuationConfig& c = spec.continuation;
    return "continuation=" + c.axis + "," + std::to_string(c.up) + "," + std::to_string(c.down) + "\n";
  }

 private:
  // The point's index along the continuation axis, and its line (the point with that index zeroed).
  static int Index(const SweepSpec& spec, long point) {
    const std::vector<int> idx = spec.AxisIndices(point);
    for (size_t k = 0; k < spec.axes.size(); ++k)
      if (spec.axes[k].name == spec.continuation.axis) return idx[k];
    return 0;
  }
  static long Line(const SweepSpec& spec, long point) {
    long stride = 1;
    for (long k = static_cast<long>(spec.axes.size()) - 1; k >= 0; --k) {
      if (spec.axes[k].name == spec.continuation.axis) return point - Index(spec, point) * stride;
      stride *= static_cast<long>(spec.axes[k].values.size());
    }
    return point;
  }
};

// [robustness]: samples of the point's parameters and start (ApplyRobustnessSample).
class RobustnessKind : public SweepKind {
 public:
  const char* Name() const override { return "robustness"; }
  int Slots(const SweepSpec& spec) const override { return spec.robustness.samples; }
  SlotDimension Dimension(const SweepSpec&) const override {
    return {"ic", "index of the tolerance sample ([robustness]: seeded, shifted Halton sequence)", {}};
  }
  KindMapPart MapPart(const SweepSpec& spec, const std::vector<PointRecord>& records,
                      const RefinedGrid*) const override {
    KindMapPart part;
    if (Slots(spec) > 1) part.variables = MotionFractions(spec, records, /*with_stderr=*/true);
    return part;
  }
  std::string CanonicalLine(const SweepSpec& spec) const override {
    const RobustnessConfig& r = spec.robustness;
    std::string s = "robustness=" + std::to_string(r.samples) + "," + std::to_string(r.seed) + "," + G17(r.ic_radius);
    for (const auto& [k, v] : r.tolerance) s += "," + k + ":" + G17(v);
    return s + "\n";
  }

 protected:
  void Vary(const SweepSpec& spec, int slot, PointSpec* p) const override {
    ApplyRobustnessSample(spec.robustness, slot, p);
  }
};

// Every axis an initial-state axis: the attractor of each start and the table of attractors.
class BasinsKind : public GridKind {
 public:
  const char* Name() const override { return "basins"; }
  KindMapPart MapPart(const SweepSpec& spec, const std::vector<PointRecord>& records,
                      const RefinedGrid*) const override {
    const BasinMap basins = ClassifyAttractors(spec, records, 10 * spec.base.metrics.period_tol);
    std::vector<std::pair<int, std::string>> legend;
    for (const Attractor& a : basins.attractors) legend.emplace_back(a.id, a.label);
    KindMapPart part;
    KindVariable ids = Variable("attractor", KindVariable::Over::kItems,
                                std::vector<double>(basins.ids.begin(), basins.ids.end()), /*integer=*/true);
    ids.long_name = "attractor reached from the initial state (basin map)";
    ids.unit = "code";
    ids.definition =
        "id of the attractor this start ends on (0 = largest basin; -1 undefined); the group attractors describes each";
    ids.labels = legend;
    part.variables.push_back(std::move(ids));
    // The table of attractors, one row per id, in the group "attractors" (a netCDF-4 group: xarray's
    // open_dataset(path, group="attractors")), so the root holds only gridded variables.
    const long n = static_cast<long>(basins.attractors.size());
    part.table = KindMapPart::Table{"attractors", "attractor_id", "attractor id (0 = largest basin)", n, legend};
    auto column = [&](const char* name, auto get, bool integer, const char* long_name, const std::string& unit,
                      const std::string& definition, std::vector<std::pair<int, std::string>> labels = {}) {
      KindVariable v{name,       KindVariable::Over::kTable, std::vector<double>(n), integer, long_name, unit,
                     definition, std::move(labels)};
      for (long k = 0; k < n; ++k) v.values[k] = get(basins.attractors[k]);
      part.table_variables.push_back(std::move(v));
    };
    column(
        "basin_fraction", [](const Attractor& a) { return a.basin_fraction; }, false,
        "fraction of the starts ending on the attractor", "fraction", "cells of its basin / all starts");
    column(
        "boundary_fraction", [](const Attractor& a) { return a.boundary_fraction; }, false,
        "fraction of the basin's cells on a basin boundary", "fraction",
        "cells with a grid neighbour (+-1 along an axis) ending on another attractor / cells of the basin");
    column(
        "motion", [](const Attractor& a) { return static_cast<double>(a.motion < 0 ? kMotionUndefined : a.motion); },
        true, "type of motion on the attractor", "code", MotionCodesText(), Labels(MetricCategories("motion")));
    column(
        "period", [](const Attractor& a) { return static_cast<double>(a.period); }, true,
        "period of the attractor in forcing periods (0: not periodic)", "forcing periods", "stroboscopic period");
    column(
        "strobe_y", [](const Attractor& a) { return a.strobe_y; }, false,
        "displacement at the attractor's Poincare fingerprint", "delta_s",
        "strobe_y of the attractor (NaN: not periodic)");
    column(
        "strobe_v", [](const Attractor& a) { return a.strobe_v; }, false,
        "velocity at the attractor's Poincare fingerprint", "delta_s/tau",
        "strobe_v of the attractor (NaN: not periodic)");
    KindAttribute boundary = Attribute("basin_boundary_fraction", KindAttribute::Type::kDouble);
    boundary.number = basins.boundary_fraction;
    part.attributes.push_back(std::move(boundary));
    return part;
  }
};

// [refine]: rounds over a coarse-to-fine grid (engine/refine.h), one item per point.
class RefinedKind : public GridKind {
 public:
  const char* Name() const override { return "refined"; }
  bool InRounds() const override { return true; }
  StatusOr<RefinedGrid> Fill(const SweepSpec& spec, const std::vector<long>& points,
                             const std::vector<PointRecord>& stored) const override {
    return FillRefinedGrid(spec, points, stored);
  }
  // How each grid point got its values, and the cost in global attributes.
  KindMapPart MapPart(const SweepSpec& spec, const std::vector<PointRecord>&,
                      const RefinedGrid* refined) const override {
    KindMapPart part;
    if (!refined) return part;
    const std::string levels = std::to_string(spec.refine.levels);
    const char* criterion = RefineCriterionName(spec.refine.criterion);
    KindVariable level = Variable("refine_level", KindVariable::Over::kItems, refined->level, /*integer=*/true);
    level.long_name = "refinement level of the smallest cell holding the point";
    level.definition = "0 = the coarse grid (every 2^" + levels + "-th axis value), " + levels +
                       " = the axes' own spacing; cells split where their corners disagree on " + criterion;
    part.variables.push_back(std::move(level));
    KindVariable fill = Variable("refine_fill", KindVariable::Over::kItems, refined->fill, /*integer=*/true);
    fill.long_name = "how the point's values were obtained in the refined map";
    fill.unit = "code";
    fill.definition =
        "computed = integrated at this point; interpolated = inside a cell whose corners agree on the criterion "
        "(real-valued metrics multilinear in the corners, codes from the nearest corner); chaotic_mixed = inside a "
        "cell that stayed mixed in every child for refine.mixed_after levels (values of the nearest corner sample)";
    fill.labels = Labels(RefineFillCategories());
    part.variables.push_back(std::move(fill));
    KindAttribute computed = Attribute("refine_points_computed", KindAttribute::Type::kLong);
    computed.integer = refined->computed;
    KindAttribute uniform = Attribute("refine_points_uniform", KindAttribute::Type::kLong);
    uniform.integer = spec.points();
    KindAttribute named = Attribute("refine_criterion", KindAttribute::Type::kString);
    named.text = criterion;
    part.attributes.insert(part.attributes.end(), {computed, uniform, named});
    return part;
  }
  std::string CanonicalLine(const SweepSpec& spec) const override {
    return "refine=" + std::to_string(spec.refine.levels) + "," + RefineCriterionName(spec.refine.criterion) + "," +
           std::to_string(spec.refine.mixed_after) + "\n";
  }
};

}  // namespace

SlotDimension SweepKind::Dimension(const SweepSpec&) const {
  return {"ic", "index into the sweep's initial states ([initial_conditions] states)", {}};
}

PointSpec SweepKind::Start(const SweepSpec& spec, int slot) const {
  PointSpec p = spec.base;
  if (!spec.initial_states.empty()) {
    p.ic_given = true;
    p.ic = spec.initial_states[StateOf(slot)];
  } else if (spec.HasInitialStateAxes()) {  // the model's default start, whose swept components the axes set
    p.ic = InitialState(p);
    p.ic_given = true;
  }
  return p;
}

PointSpec SweepKind::PointAt(const SweepSpec& spec, long point, int slot) const {
  PointSpec p = Start(spec, slot);
  const std::vector<int> idx = spec.AxisIndices(point);
  for (size_t k = 0; k < spec.axes.size(); ++k)
    *spec_keys::ParamSlot(p, spec.axes[k].name) = spec.axes[k].values[idx[k]];
  Vary(spec, slot, &p);
  return p;
}

std::string SweepKind::ItemKey(const SweepSpec& spec, long point, int slot) const {
  const std::string key = PointKey(PointAt(spec, point, slot));
  if (IsCellModel(spec.model)) return key;
  return ContentHashHex(spec.ModelConfigText() + "|" + key);
}

std::vector<std::vector<WorkItem>> SweepKind::Chains(const SweepSpec&) const { return {}; }

StatusOr<RefinedGrid> SweepKind::Fill(const SweepSpec& spec, const std::vector<long>&,
                                      const std::vector<PointRecord>&) const {
  return Status::Internal(std::string("Fill on a ") + Name() + " sweep (" + spec.Id() + "), which is not in rounds");
}

bool SweepKind::Continues(const SweepSpec&, const WorkItem&, const WorkItem&) const { return false; }

KindMapPart SweepKind::MapPart(const SweepSpec&, const std::vector<PointRecord>&, const RefinedGrid*) const {
  return {};
}

std::string SweepKind::CanonicalLine(const SweepSpec&) const { return ""; }

const SweepKind& KindOf(const SweepSpec& spec) {
  static const GridKind kGrid;
  static const ContinuationKind kContinuation;
  static const RobustnessKind kRobustness;
  static const BasinsKind kBasins;
  static const RefinedKind kRefined;
  if (spec.refine.enabled()) return kRefined;
  if (spec.continuation.enabled()) return kContinuation;
  if (spec.robustness.enabled()) return kRobustness;
  if (spec.IsBasinSweep()) return kBasins;
  return kGrid;
}

}  // namespace bistable
