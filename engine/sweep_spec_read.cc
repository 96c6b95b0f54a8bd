// The sweep spec's TOML reader (ParseSweepSpec, LoadSweepSpec): every table and key checked, every field and bound
// named in errors. The spec itself (axes, keys, robustness samples, its canonical text) is engine/sweep_spec.cc.
#include "engine/sweep_spec.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <limits>
#include <map>
#include <set>
#include <sstream>

#include <toml++/toml.h>

#include "base/file.h"
#include "base/limits.h"
#include "base/names.h"
#include "base/validate.h"
#include "engine/content_hash.h"
#include "engine/metric_catalog.h"
#include "engine/spec_toml.h"
#include "engine/sweep_kind.h"
#include "engine/sweep_spec_keys.h"

namespace bistable {

using spec_keys::CheckTerms;
using spec_keys::kParamKeys;
using spec_keys::kRefineCriteria;
using spec_keys::kToleranceKeys;
using spec_keys::ParamSlot;
using spec_keys::ReadTerms;
using spec_keys::TermAxisNames;
using spec_keys::TermParamKeys;

namespace {
// The rig's default relative tolerances (model = "dimensional"): ROS34PW2 in lanes, its default integrator,
// and Dormand–Prince (integrator = "adaptive"), measured against the rtol 1e-10 reference in docs/numerics.md.
constexpr double kRigRosenbrockRtol = 5e-6, kRigDopriRtol = 1e-6;
}  // namespace
namespace {

const std::vector<std::string> kTopKeys = {
    "name",   "model",  "params",      "axes",         "integration", "metrics", "initial_conditions",
    "output", "series", "dimensional", "continuation", "robustness",  "refine",  "terms"};
const std::vector<std::string> kRefineKeys = {"levels", "criterion", "mixed_after"};
const std::vector<std::string> kRobustnessKeys = {"samples", "seed", "tolerance", "ic_radius", "covariance"};
const std::vector<std::string> kContinuationKeys = {"axis", "direction"};
const std::vector<std::string> kSeriesKeys = {"cells", "resonators", "bistable", "cell"};
const std::vector<std::string> kCellOverrideKeys = {"eps", "eta", "eta_r", "phi", "lambda"};
const std::vector<std::string> kDimensionalKeys = {"preset", "resonator", "m_m",  "k_lin", "k3",  "c0_m",
                                                   "c2_m",   "fs_m",      "fc_m", "m_r",   "k_r", "c0_r",
                                                   "c2_r",   "fs_r",      "fc_r", "v_sp",  "v_t"};
const std::vector<std::string> kDimensionalParamKeys = {"a0_mm", "f0_hz"};
const std::vector<std::string> kAxisForms = {"list", "linspace", "logspace"};
const std::vector<std::string> kIntegrationKeys = {
    "integrator",     "dt",        "t_end", "t_keep", "rtol", "atol", "labels", "settle_window", "settle_min_strobes",
    "settle_confirm", "settle_cap"};
const std::vector<std::string> kMetricKeys = {"store",        "chaos_threshold", "chaos_01_min",  "rosenstein",
                                              "renorm_every", "sample_every",    "period_tol",    "max_period",
                                              "hd_level",     "poincare_points", "poincare_phase"};
// Section points stored per point when "poincare" is stored and poincare_points is not given.
constexpr int kDefaultPoincarePoints = 32;
const std::vector<std::string> kIcKeys = {"states"};
const std::vector<std::string> kOutputKeys = {"plots"};

StatusOr<std::vector<std::string>> StringArray(const toml::node& n, const std::string& field) {
  const toml::array* a = n.as_array();
  if (!a) return Status::InvalidArgument(field, field + " must be an array of strings");
  std::vector<std::string> out;
  for (size_t i = 0; i < a->size(); ++i) {
    auto v = String((*a)[i], field + "[" + std::to_string(i) + "]");
    if (!v.ok()) return v.status();
    out.push_back(*v);
  }
  return out;
}

StatusOr<Axis> ParseAxis(const std::string& name, const toml::node& n) {
  constexpr long kMaxValues = limits::kMaxAxisValues;
  const std::string field = "axes." + name;
  Axis axis{name, {}};
  if (n.is_array()) {  // shorthand: alpha = [0.1, 0.2]
    auto v = NumberArray(n, field);
    if (!v.ok()) return v.status();
    axis.values = *v;
  } else if (const toml::table* t = n.as_table()) {
    if (t->size() != 1) return Status::InvalidArgument(field, field + " needs exactly one of list, linspace, logspace");
    const auto it = t->begin();  // toml++ iterators own the proxy pair they hand out: keep it alive
    const std::string form(it->first.str());
    const toml::node& v = it->second;
    if (std::find(kAxisForms.begin(), kAxisForms.end(), form) == kAxisForms.end())
      return Unknown(field, form, kAxisForms);
    auto nums = NumberArray(v, field + "." + form);
    if (!nums.ok()) return nums.status();
    if (form == "list") {
      axis.values = *nums;
    } else {
      if (nums->size() != 3)
        return Status::InvalidArgument(field + "." + form, field + "." + form + " = [start, stop, count] (3 numbers)");
      const double a = (*nums)[0], b = (*nums)[1], cnt = (*nums)[2];
      BISTABLE_RETURN_IF_ERROR(CheckFinite(field + "." + form + ".start", a));
      BISTABLE_RETURN_IF_ERROR(CheckFinite(field + "." + form + ".stop", b));
      if (!(cnt >= 1 && cnt <= static_cast<double>(kMaxValues) && cnt == std::floor(cnt)))
        return Violates(field + "." + form + ".count", cnt,
                        "a whole number in [1, " + std::to_string(kMaxValues) + "]");
      if (form == "logspace" && !(a > 0 && b > 0))
        return Violates(field + ".logspace.start", std::min(a, b), "> 0 (logspace spans values, both ends positive)");
      const long m = static_cast<long>(cnt);
      for (long i = 0; i < m; ++i) {
        const double f = m == 1 ? 0.0 : static_cast<double>(i) / static_cast<double>(m - 1);
        axis.values.push_back(form == "linspace" ? a + f * (b - a) : a * std::pow(b / a, f));
      }
    }
  } else {
    return Status::InvalidArgument(field, field + " must be a list or {list|linspace|logspace = ...}");
  }
  if (axis.values.empty()) return Status::InvalidArgument(field, field + " is empty (needs at least one value)");
  if (static_cast<long>(axis.values.size()) > kMaxValues)
    return Violates(field, static_cast<double>(axis.values.size()), "count <= " + std::to_string(kMaxValues));
  for (size_t i = 0; i < axis.values.size(); ++i) {
    BISTABLE_RETURN_IF_ERROR(CheckFinite(field + "[" + std::to_string(i) + "]", axis.values[i]));
    if (i > 0 && !(axis.values[i] > axis.values[i - 1]))
      return Status::InvalidArgument(field, field + " must be strictly increasing (value " + std::to_string(i) + " = " +
                                                FormatNumber(axis.values[i]) + " after " +
                                                FormatNumber(axis.values[i - 1]) + "); an inverted or empty range?");
  }
  return axis;
}

// name, model.
Status ReadNameAndModel(const toml::table& root, SweepSpec& spec) {
  if (const toml::node* n = root.get("name")) {
    auto s = String(*n, "name");
    if (!s.ok()) return s.status();
    BISTABLE_RETURN_IF_ERROR(CheckPlainText("name", *s, limits::kMaxNameBytes));
    spec.name = *s;
  }
  const toml::node* model = root.get("model");
  if (!model)
    return Status::InvalidArgument(
        "model", "model is required (standalone, coupled, linear, linear-coupled, series, dimensional, terms)");
  {
    auto s = String(*model, "model");
    if (!s.ok()) return s.status();
    if (*s == "terms") {  // a model of effect-library terms: SI points like the rig's ([terms], ReadTerms)
      spec.model = ModelKind::kDimensional;
      spec.base.model = ModelKind::kStandalone;
      spec.terms.emplace();
      return Status::Ok();
    }
    auto m = ParseAnyModel(*s);
    if (!m.ok()) return m.status();
    spec.model = *m;
    spec.base.model = *m;  // a cell; series and dimensional set their proxy below
  }
  return Status::Ok();
}

// [series] (model = "series" only).
Status ReadSeries(const toml::table& root, SweepSpec& spec) {
  if (root.get("series") && spec.model != ModelKind::kSeries)
    return Status::InvalidArgument("series", "a [series] table needs model = \"series\"");
  if (root.get("dimensional") && spec.model != ModelKind::kDimensional)
    return Status::InvalidArgument("dimensional", "a [dimensional] table needs model = \"dimensional\"");
  if (spec.model == ModelKind::kSeries) {
    if (const toml::node* n = root.get("series")) {
      const toml::table* t = n->as_table();
      if (!t) return Status::InvalidArgument("series", "series must be a table");
      BISTABLE_RETURN_IF_ERROR(CheckKeys(*t, "series", kSeriesKeys));
      int cells = spec.series.cells;
      BISTABLE_RETURN_IF_ERROR(ReadInt(*t, "cells", "series.cells", &cells, 1, limits::kMaxSeriesCells));
      spec.series.cells = cells;
      for (const char* flag : {"resonators", "bistable"}) {
        if (const toml::node* b = t->get(flag)) {
          if (!b->is_boolean())
            return Status::InvalidArgument(std::string("series.") + flag,
                                           std::string("series.") + flag + " must be true or false");
          (std::string(flag) == "resonators" ? spec.series.resonators : spec.series.bistable) = *b->value<bool>();
        }
      }
      if (const toml::node* c = t->get("cell")) {
        const toml::array* a = c->as_array();
        if (!a) return Status::InvalidArgument("series.cell", "series.cell must be an array of tables, one per cell");
        if (static_cast<int>(a->size()) > spec.series.cells)
          return Violates("series.cell", static_cast<double>(a->size()),
                          "count <= series.cells = " + std::to_string(spec.series.cells));
        for (size_t i = 0; i < a->size(); ++i) {
          const std::string f = "series.cell[" + std::to_string(i) + "]";
          const toml::table* ct = (*a)[i].as_table();
          if (!ct) return Status::InvalidArgument(f, f + " must be a table like {eta = 0.2}");
          BISTABLE_RETURN_IF_ERROR(CheckKeys(*ct, f, kCellOverrideKeys));
          std::vector<std::pair<std::string, double>> ov;
          for (const std::string& k : kCellOverrideKeys) {
            double v = 0;
            if (ct->get(k)) {
              BISTABLE_RETURN_IF_ERROR(ReadNumber(*ct, k, f + "." + k, &v));
              ov.emplace_back(k, v);
            }
          }
          spec.series.overrides.push_back(ov);
        }
      }
    }
    spec.base.model = spec.series.bistable ? (spec.series.resonators ? ModelKind::kCoupled : ModelKind::kStandalone)
                                           : (spec.series.resonators ? ModelKind::kLinearCoupled : ModelKind::kLinear);
  }
  return Status::Ok();
}

// [dimensional] (model = "dimensional" only): its preset, parameters and SI defaults.
Status ReadDimensional(const toml::table& root, SweepSpec& spec) {
  if (spec.model == ModelKind::kDimensional && !spec.terms) {
    spec.base.model = ModelKind::kStandalone;
    IntegrationSettings& in = spec.base.integration;  // seconds; ROS34PW2 in lanes with tangent (issue 41)
    in.integrator = IntegratorKind::kRosenbrock;
    in.t_end = 20.0;
    in.t_keep = 10.0;
    in.dt = 0.001;
    in.rtol = kRigRosenbrockRtol;
    in.atol = 1e-9;
    spec.base.alpha = spec.dimensional.a0_mm;
    spec.base.omega = spec.dimensional.f0_hz;
    if (const toml::node* n = root.get("dimensional")) {
      const toml::table* t = n->as_table();
      if (!t) return Status::InvalidArgument("dimensional", "dimensional must be a table");
      BISTABLE_RETURN_IF_ERROR(CheckKeys(*t, "dimensional", kDimensionalKeys));
      if (const toml::node* pr = t->get("preset")) {
        auto name = String(*pr, "dimensional.preset");
        if (!name.ok()) return name.status();
        if (*name == "bistable")
          spec.dimensional.params = DimensionalParams::BistableTable2(), spec.dimensional.bistable = true;
        else if (*name == "linear")
          spec.dimensional.params = DimensionalParams::LinearTable2(), spec.dimensional.bistable = false;
        else
          return Status::InvalidArgument("dimensional.preset",
                                         "dimensional.preset = '" + *name + "' violates preset in {bistable, linear}");
      }
      DimensionalParams& d = spec.dimensional.params;
      if (const toml::node* r = t->get("resonator")) {
        if (!r->is_boolean())
          return Status::InvalidArgument("dimensional.resonator", "dimensional.resonator must be true or false");
        d.has_resonator = *r->value<bool>();
      }
      const std::pair<const char*, double*> slots[] = {
          {"m_m", &d.m_m},        {"k_lin", &d.k_lin},     {"k3", &d.k3},           {"c0_m", &d.c0_m},
          {"c2_m", &d.c2_m},      {"fs_m", &d.fric_m.f_s}, {"fc_m", &d.fric_m.f_c}, {"m_r", &d.m_r},
          {"k_r", &d.k_r},        {"c0_r", &d.c0_r},       {"c2_r", &d.c2_r},       {"fs_r", &d.fric_r.f_s},
          {"fc_r", &d.fric_r.f_c}};
      for (auto [k, slot] : slots) BISTABLE_RETURN_IF_ERROR(ReadNumber(*t, k, std::string("dimensional.") + k, slot));
      double v_sp = d.fric_m.v_sp, v_t = d.fric_m.v_t;
      BISTABLE_RETURN_IF_ERROR(ReadNumber(*t, "v_sp", "dimensional.v_sp", &v_sp));
      BISTABLE_RETURN_IF_ERROR(ReadNumber(*t, "v_t", "dimensional.v_t", &v_t));
      d.fric_m.v_sp = d.fric_r.v_sp = v_sp;
      d.fric_m.v_t = d.fric_r.v_t = v_t;
      spec.dimensional.bistable = d.k_lin < 0;
      if (Status st = ValidateDimensionalParams(d); !st.ok())
        return Status::InvalidArgument("dimensional." + st.field(), st.message());
    }
  }
  return Status::Ok();
}

// [params] and [axes]: fixed values and the grid (its size checked while it is read).
Status ReadParamsAndAxes(const toml::table& root, SweepSpec& spec, std::set<std::string>& swept) {
  const bool dimensional = spec.model == ModelKind::kDimensional;
  const std::vector<std::string> param_keys = spec.terms    ? TermParamKeys(spec)
                                              : dimensional ? kDimensionalParamKeys
                                                            : kParamKeys;
  const std::vector<std::string> axis_names = spec.terms    ? TermAxisNames(spec)
                                              : dimensional ? DimensionalAxisNames()
                                                            : CanonicalAxisNames();
  if (const toml::node* n = root.get("params")) {
    const toml::table* t = n->as_table();
    if (!t) return Status::InvalidArgument("params", "params must be a table");
    BISTABLE_RETURN_IF_ERROR(CheckKeys(*t, "params", param_keys));
    for (const std::string& k : param_keys)
      BISTABLE_RETURN_IF_ERROR(ReadNumber(*t, k, "params." + k, spec.Slot(spec.base, k)));
  }
  if (const toml::node* n = root.get("axes")) {
    const toml::table* t = n->as_table();
    if (!t) return Status::InvalidArgument("axes", "axes must be a table");
    BISTABLE_RETURN_IF_ERROR(CheckKeys(*t, "axes", axis_names));
    long product = 1;  // grid points so far: checked as each axis is read, before the next is generated
    for (const std::string& name : axis_names) {
      if (const toml::node* a = t->get(name)) {
        auto axis = ParseAxis(name, *a);
        if (!axis.ok()) return axis.status();
        if (__builtin_mul_overflow(product, static_cast<long>(axis->values.size()), &product) ||
            product > limits::kMaxSweepItems)
          return Status::InvalidArgument(
              "axes." + name, "the grid up to axes." + name + " has more than " +
                                  std::to_string(limits::kMaxSweepItems) +
                                  " points (the limit of points x initial conditions per sweep; split the sweep)");
        spec.axes.push_back(*axis);
        swept.insert(name);
      }
    }
  }
  return Status::Ok();
}

// [integration].
Status ReadIntegration(const toml::table& root, SweepSpec& spec) {
  if (const toml::node* n = root.get("integration")) {
    const toml::table* t = n->as_table();
    if (!t) return Status::InvalidArgument("integration", "integration must be a table");
    BISTABLE_RETURN_IF_ERROR(CheckKeys(*t, "integration", kIntegrationKeys));
    if (const toml::node* i = t->get("integrator")) {
      auto s = String(*i, "integration.integrator");
      if (!s.ok()) return s.status();
      auto k = ParseIntegrator(*s);
      if (!k.ok()) return Status::InvalidArgument("integration.integrator", k.status().message());
      spec.base.integration.integrator = *k;
    }
    IntegrationSettings& in = spec.base.integration;
    // The rig's default tolerance follows its integrator: ROS34PW2 in lanes (the default) rtol 5e-6, issue 41's
    // accuracy on three grids; Dormand–Prince (integrator = "adaptive") rtol 1e-6, the rig's default before
    // numerics 1.5.0 (docs/numerics.md). A given rtol is taken as it is.
    if (spec.model == ModelKind::kDimensional)
      in.rtol = in.integrator == IntegratorKind::kRosenbrock ? kRigRosenbrockRtol : kRigDopriRtol;
    BISTABLE_RETURN_IF_ERROR(ReadNumber(*t, "dt", "integration.dt", &in.dt));
    BISTABLE_RETURN_IF_ERROR(ReadNumber(*t, "t_end", "integration.t_end", &in.t_end));
    BISTABLE_RETURN_IF_ERROR(ReadNumber(*t, "t_keep", "integration.t_keep", &in.t_keep));
    BISTABLE_RETURN_IF_ERROR(ReadNumber(*t, "rtol", "integration.rtol", &in.rtol));
    BISTABLE_RETURN_IF_ERROR(ReadNumber(*t, "atol", "integration.atol", &in.atol));
    if (const toml::node* l = t->get("labels")) {
      auto s = String(*l, "integration.labels");
      if (!s.ok()) return s.status();
      auto k = ParseLabelMode(*s);
      if (!k.ok()) return Status::InvalidArgument("integration.labels", k.status().message());
      in.labels = *k;
    }
    BISTABLE_RETURN_IF_ERROR(ReadNumber(*t, "settle_window", "integration.settle_window", &in.settle_window));
    BISTABLE_RETURN_IF_ERROR(
        ReadInt(*t, "settle_min_strobes", "integration.settle_min_strobes", &in.settle_min_strobes, 1, 64));
    BISTABLE_RETURN_IF_ERROR(ReadNumber(*t, "settle_confirm", "integration.settle_confirm", &in.settle_confirm));
    BISTABLE_RETURN_IF_ERROR(ReadNumber(*t, "settle_cap", "integration.settle_cap", &in.settle_cap));
  }
  return Status::Ok();
}

// [metrics]: what is stored and the metric settings.
Status ReadMetrics(const toml::table& root, SweepSpec& spec) {
  spec.metrics = {"frf_db",   "lle",   "motion",     "period", "hd_index",
                  "hd_peaks", "edr_b", "edr_r",      "edr_t",  "energy_balance_residual",
                  "y_min",    "y_max", "termination"};
  if (const toml::node* n = root.get("metrics")) {
    const toml::table* t = n->as_table();
    if (!t) return Status::InvalidArgument("metrics", "metrics must be a table");
    BISTABLE_RETURN_IF_ERROR(CheckKeys(*t, "metrics", kMetricKeys));
    MetricSettings& m = spec.base.metrics;
    if (const toml::node* s = t->get("store")) {
      auto names = StringArray(*s, "metrics.store");
      if (!names.ok()) return names.status();
      const std::vector<std::string> known = MetricNames();
      for (size_t i = 0; i < names->size(); ++i) {
        const std::string& nm = (*names)[i];
        if (std::find(known.begin(), known.end(), nm) == known.end())
          return UnknownValue("metrics.store[" + std::to_string(i) + "]", nm, known);
      }
      spec.metrics = *names;
      if (std::find(spec.metrics.begin(), spec.metrics.end(), "termination") == spec.metrics.end())
        spec.metrics.push_back("termination");  // always stored: a map must say which points failed
    }
    BISTABLE_RETURN_IF_ERROR(ReadNumber(*t, "chaos_threshold", "metrics.chaos_threshold", &m.chaos_threshold));
    BISTABLE_RETURN_IF_ERROR(ReadNumber(*t, "chaos_01_min", "metrics.chaos_01_min", &m.chaos_01_min));
    BISTABLE_RETURN_IF_ERROR(ReadNumber(*t, "period_tol", "metrics.period_tol", &m.period_tol));
    BISTABLE_RETURN_IF_ERROR(ReadNumber(*t, "hd_level", "metrics.hd_level", &m.hd_level));
    BISTABLE_RETURN_IF_ERROR(
        ReadInt(*t, "renorm_every", "metrics.renorm_every", &m.renorm_every, 1, limits::kMaxEvery));
    BISTABLE_RETURN_IF_ERROR(
        ReadInt(*t, "sample_every", "metrics.sample_every", &m.sample_every, 1, limits::kMaxEvery));
    BISTABLE_RETURN_IF_ERROR(ReadInt(*t, "max_period", "metrics.max_period", &m.max_period, 1, limits::kMaxPeriod));
    if (const toml::node* r = t->get("rosenstein")) {
      if (!r->is_boolean())
        return Status::InvalidArgument("metrics.rosenstein", "metrics.rosenstein must be true or false");
      m.rosenstein = *r->value<bool>();
    }
    // The Poincaré section: its phase (also the period test's strobes) and the points stored.
    BISTABLE_RETURN_IF_ERROR(ReadNumber(*t, "poincare_phase", "metrics.poincare_phase", &m.poincare_phase));
    if (!(m.poincare_phase >= 0 && m.poincare_phase < 2 * M_PI))
      return Violates("metrics.poincare_phase", m.poincare_phase, "in [0, 2 pi) (radians of Omega tau)");
    const bool stored = std::find(spec.metrics.begin(), spec.metrics.end(), "poincare") != spec.metrics.end();
    if (stored) m.poincare_points = kDefaultPoincarePoints;
    BISTABLE_RETURN_IF_ERROR(ReadInt(*t, "poincare_points", "metrics.poincare_points", &m.poincare_points, 1,
                                     limits::kMaxPoincarePointsStored));
    if (t->get("poincare_points") && !stored)
      return Status::InvalidArgument(
          "metrics.poincare_points",
          "metrics.poincare_points needs \"poincare\" in metrics.store (it sets how many section "
          "points are stored)");
  }
  spec.base.metrics.turning_points =
      std::find(spec.metrics.begin(), spec.metrics.end(), "turning_points") != spec.metrics.end();
  if (spec.base.metrics.rosenstein &&
      std::find(spec.metrics.begin(), spec.metrics.end(), "lle_rosenstein") == spec.metrics.end())
    spec.metrics.push_back("lle_rosenstein");
  return Status::Ok();
}

// [initial_conditions].
Status ReadInitialConditions(const toml::table& root, SweepSpec& spec) {
  if (const toml::node* n = root.get("initial_conditions")) {
    const toml::table* t = n->as_table();
    if (!t) return Status::InvalidArgument("initial_conditions", "initial_conditions must be a table");
    BISTABLE_RETURN_IF_ERROR(CheckKeys(*t, "initial_conditions", kIcKeys));
    if (spec.model == ModelKind::kSeries)
      return Status::InvalidArgument("initial_conditions",
                                     "initial_conditions are not supported for series chains yet; "
                                     "they start at rest in every link's positive well");
    if (const toml::node* s = t->get("states")) {
      const toml::array* a = s->as_array();
      if (!a || a->empty())
        return Status::InvalidArgument("initial_conditions.states",
                                       "initial_conditions.states must be a non-empty array of [ym, vm, yr, vr]");
      if (a->size() > static_cast<size_t>(limits::kMaxInitialStates))
        return Violates("initial_conditions.states", static_cast<double>(a->size()),
                        "count <= " + std::to_string(limits::kMaxInitialStates));
      for (size_t i = 0; i < a->size(); ++i) {
        const std::string f = "initial_conditions.states[" + std::to_string(i) + "]";
        auto v = NumberArray((*a)[i], f);
        if (!v.ok()) return v.status();
        if (v->size() != 2 && v->size() != 4)
          return Status::InvalidArgument(f, f + " must be [ym, vm] or [ym, vm, yr, vr]");
        std::array<double, 4> ic = {0, 0, 0, 0};
        for (size_t j = 0; j < v->size(); ++j) {
          BISTABLE_RETURN_IF_ERROR(CheckFinite(f + "[" + std::to_string(j) + "]", (*v)[j]));
          ic[j] = (*v)[j];
        }
        spec.initial_states.push_back(ic);
      }
    }
  }
  return Status::Ok();
}

// [continuation].
Status ReadContinuation(const toml::table& root, SweepSpec& spec) {
  if (const toml::node* n = root.get("continuation")) {
    const toml::table* t = n->as_table();
    if (!t) return Status::InvalidArgument("continuation", "continuation must be a table");
    BISTABLE_RETURN_IF_ERROR(CheckKeys(*t, "continuation", kContinuationKeys));
    if (!IsCellModel(spec.model))
      return Status::InvalidArgument("continuation",
                                     "continuation runs for standalone, coupled and linear models only");
    auto axis = t->get("axis") ? String(*t->get("axis"), "continuation.axis") : StatusOr<std::string>(std::string());
    if (!axis.ok()) return axis.status();
    std::vector<std::string> swept_names;
    for (const Axis& a : spec.axes) swept_names.push_back(a.name);
    if (std::find(swept_names.begin(), swept_names.end(), *axis) == swept_names.end())
      return UnknownValue("continuation.axis", *axis, swept_names);
    spec.continuation.axis = *axis;
    if (const toml::node* d = t->get("direction")) {
      auto dir = String(*d, "continuation.direction");
      if (!dir.ok()) return dir.status();
      if (*dir == "up")
        spec.continuation.down = false;
      else if (*dir == "down")
        spec.continuation.up = false;
      else if (*dir != "both")
        return Status::InvalidArgument(
            "continuation.direction", "continuation.direction = '" + *dir + "' violates direction in {up, down, both}");
    }
    if (spec.initial_states.size() > 1)
      return Status::InvalidArgument("initial_conditions.states",
                                     "with continuation, give at most one start state (the chains' start)");
  }
  return Status::Ok();
}

// [robustness].
Status ReadRobustness(const toml::table& root, SweepSpec& spec) {
  const toml::node* n = root.get("robustness");
  if (!n) return Status::Ok();
  const toml::table* t = n->as_table();
  if (!t) return Status::InvalidArgument("robustness", "robustness must be a table");
  BISTABLE_RETURN_IF_ERROR(CheckKeys(*t, "robustness", kRobustnessKeys));
  if (!IsCellModel(spec.model) && !spec.terms)
    return Status::InvalidArgument("robustness",
                                   "robustness maps run for standalone, coupled, linear and term models only");
  RobustnessConfig& r = spec.robustness;
  if (const toml::node* c = t->get("covariance")) {
    if (!c->is_boolean())
      return Status::InvalidArgument("robustness.covariance", "robustness.covariance must be true or false");
    r.covariance = *c->value<bool>();
    if (r.covariance && !spec.terms)
      return Status::InvalidArgument("robustness.covariance",
                                     "robustness.covariance draws a term model's parameters (model = \"terms\"); "
                                     "the other models take robustness.tolerance");
  }
  int samples = 0, seed = 1;
  BISTABLE_RETURN_IF_ERROR(ReadInt(*t, "samples", "robustness.samples", &samples, 1, limits::kMaxRobustnessSamples));
  if (samples == 0)
    return Status::InvalidArgument("robustness.samples", "robustness.samples is required (samples per grid point)");
  BISTABLE_RETURN_IF_ERROR(ReadInt(*t, "seed", "robustness.seed", &seed, 0, 2147483647));
  r.samples = samples;
  r.seed = static_cast<uint64_t>(seed);
  if (const toml::node* tn = t->get("tolerance")) {
    const toml::table* tt = tn->as_table();
    if (!tt)
      return Status::InvalidArgument("robustness.tolerance",
                                     "robustness.tolerance must be a table, e.g. { eta = 0.2, lambda = 0.02 }");
    BISTABLE_RETURN_IF_ERROR(CheckKeys(*tt, "robustness.tolerance", kToleranceKeys));
    for (const std::string& k : kToleranceKeys) {
      if (!tt->get(k)) continue;
      double v = 0;
      BISTABLE_RETURN_IF_ERROR(ReadNumber(*tt, k, "robustness.tolerance." + k, &v));
      if (!(v >= 0 && v <= 0.5)) return Violates("robustness.tolerance." + k, v, "in [0, 0.5] (relative)");
      r.tolerance[k] = v;
    }
  }
  BISTABLE_RETURN_IF_ERROR(ReadNumber(*t, "ic_radius", "robustness.ic_radius", &r.ic_radius));
  if (!(r.ic_radius >= 0 && r.ic_radius <= 10))
    return Violates("robustness.ic_radius", r.ic_radius, "in [0, 10] (delta_s)");
  if (spec.initial_states.size() > 1)
    return Status::InvalidArgument("initial_conditions.states",
                                   "with [robustness] give at most one state (the centre of the start disc)");
  if (spec.continuation.enabled())
    return Status::InvalidArgument("robustness", "robustness samples cannot be combined with continuation");
  if (spec.HasInitialStateAxes())
    return Status::InvalidArgument("robustness", "robustness samples cannot be combined with initial-state axes");
  return Status::Ok();
}

// [refine]: needs a grid whose every axis splits into 2^levels equal index steps, one item per point.
Status ReadRefine(const toml::table& root, SweepSpec& spec) {
  const toml::node* n = root.get("refine");
  if (!n) return Status::Ok();
  const toml::table* t = n->as_table();
  if (!t)
    return Status::InvalidArgument("refine", "refine must be a table, e.g. { levels = 3, criterion = \"motion\" }");
  BISTABLE_RETURN_IF_ERROR(CheckKeys(*t, "refine", kRefineKeys));
  RefineConfig& r = spec.refine;
  int levels = 0;
  BISTABLE_RETURN_IF_ERROR(ReadInt(*t, "levels", "refine.levels", &levels, 1, limits::kMaxRefineLevels));
  if (levels == 0)
    return Status::InvalidArgument("refine.levels",
                                   "refine.levels is required (halvings from the coarse grid to the axes' grid)");
  BISTABLE_RETURN_IF_ERROR(
      ReadInt(*t, "mixed_after", "refine.mixed_after", &r.mixed_after, 0, limits::kMaxRefineLevels));
  if (const toml::node* c = t->get("criterion")) {
    auto s = String(*c, "refine.criterion");
    if (!s.ok()) return s.status();
    const auto it = std::find(kRefineCriteria.begin(), kRefineCriteria.end(), *s);
    if (it == kRefineCriteria.end()) return UnknownValue("refine.criterion", *s, kRefineCriteria);
    r.criterion = static_cast<RefineCriterion>(it - kRefineCriteria.begin());
  }
  if (spec.axes.empty() || spec.axes.size() > 3)
    return Violates("axes", static_cast<double>(spec.axes.size()), "1 <= swept axes <= 3 with [refine]");
  const long step = 1L << levels;
  for (const Axis& a : spec.axes) {
    const long n_values = static_cast<long>(a.values.size());
    if (n_values < step + 1 || (n_values - 1) % step != 0)
      return Status::InvalidArgument(
          "axes." + a.name, "axes." + a.name + " has " + std::to_string(n_values) + " values; with refine.levels = " +
                                std::to_string(levels) + " it needs k * " + std::to_string(step) +
                                " + 1 values (k >= 1), e.g. " + std::to_string(step * ((n_values - 1) / step + 1) + 1));
  }
  if (spec.initial_states.size() > 1 || spec.continuation.enabled() || spec.robustness.enabled() ||
      spec.HasInitialStateAxes())
    return Status::InvalidArgument("refine",
                                   "refined maps take one item per grid point: no several initial states, "
                                   "continuation, robustness samples or initial-state axes");
  r.levels = levels;
  return Status::Ok();
}

// [output].
Status ReadOutput(const toml::table& root, SweepSpec& spec) {
  spec.plots = {};
  if (const toml::node* n = root.get("output")) {
    const toml::table* t = n->as_table();
    if (!t) return Status::InvalidArgument("output", "output must be a table");
    BISTABLE_RETURN_IF_ERROR(CheckKeys(*t, "output", kOutputKeys));
    if (const toml::node* p = t->get("plots")) {
      auto names = StringArray(*p, "output.plots");
      if (!names.ok()) return names.status();
      std::vector<std::string> plottable = spec.metrics;
      if (spec.initial_states.size() > 1 || spec.robustness.enabled())
        for (const char* f : {"frac_intrawell", "frac_interwell", "frac_chaotic"}) plottable.push_back(f);
      if (spec.IsBasinSweep()) plottable.push_back("attractor");
      if (spec.refine.enabled()) plottable.push_back("refine_level");
      for (size_t i = 0; i < names->size(); ++i)
        if (std::find(plottable.begin(), plottable.end(), (*names)[i]) == plottable.end())
          return UnknownValue("output.plots[" + std::to_string(i) + "]", (*names)[i], plottable);
      spec.plots = *names;
    }
  } else {
    for (const char* m : {"frf_db", "lle", "motion", "edr_t"})
      if (std::find(spec.metrics.begin(), spec.metrics.end(), m) != spec.metrics.end()) spec.plots.push_back(m);
    if (spec.refine.enabled()) spec.plots.push_back("refine_level");
  }

  return Status::Ok();
}

// Whole-spec checks after every section is read.
Status CheckWholeSpec(SweepSpec& spec, const std::set<std::string>& swept) {
  BISTABLE_RETURN_IF_ERROR(CheckTerms(spec));
  const bool dimensional = spec.model == ModelKind::kDimensional;
  const std::vector<std::string> param_keys = spec.terms    ? TermParamKeys(spec)
                                              : dimensional ? kDimensionalParamKeys
                                                            : kParamKeys;
  // Whole-spec checks: a representative point validates every fixed value and setting; swept values
  // are checked one axis value at a time so the message names the axis.
  auto field_of = [&](const std::string& f) {
    if (!dimensional) return f;
    const std::string drive = spec.terms ? spec.terms->DriveAxis() : "a0_mm";
    return f == "alpha" ? drive : f == "omega" ? std::string("f0_hz") : f;
  };
  PointSpec probe = KindOf(spec).Start(spec, 0);
  for (const Axis& a : spec.axes) *spec.Slot(probe, a.name) = a.values.front();
  if (spec.HasInitialStateAxes()) {
    if (!IsCellModel(spec.model))
      return Status::InvalidArgument("axes", "initial-state axes (ym0, vm0, yr0, vr0) sweep the cell models only");
    if (spec.initial_states.size() > 1)
      return Status::InvalidArgument(
          "initial_conditions.states",
          "with initial-state axes give at most one state (it sets the components not swept)");
    if (spec.continuation.enabled())
      return Status::InvalidArgument("continuation",
                                     "continuation chains start states along an axis; it cannot be "
                                     "combined with initial-state axes");
    for (const Axis& a : spec.axes)
      if ((a.name == "yr0" || a.name == "vr0") && !HasResonator(spec.model))
        return Status::InvalidArgument("axes." + a.name,
                                       "axes." + a.name + " needs a model with a resonator (coupled, linear-coupled)");
  }
  if (spec.base.integration.integrator == IntegratorKind::kRosenbrock) {
    if (spec.model != ModelKind::kDimensional)
      return Status::InvalidArgument("integration.integrator",
                                     "integrator = 'rosenbrock' is for the rig (model = "
                                     "'dimensional'); the other models use 'rk4' or 'adaptive'");
    // The stage polynomials of the forcing phase cover 2 pi f0 dt <= kMaxPhasePerStep.
    const double f0_max = kMaxPhasePerStep / (2.0 * M_PI * spec.base.integration.dt);
    auto check_f0 = [&](double f0, const std::string& field) -> Status {
      if (f0 > f0_max)
        return Status::InvalidArgument(
            field, field + " = " + FormatNumber(f0) + " violates f0_hz <= " + FormatNumber(f0_max) +
                       " (integrator = 'rosenbrock': 2 pi f0 dt <= " + FormatNumber(kMaxPhasePerStep) +
                       "; a smaller dt allows higher f0, and integrator = 'adaptive' any)");
      return Status::Ok();
    };
    bool f0_swept = false;
    for (const Axis& a : spec.axes)
      if (a.name == "f0_hz") {
        f0_swept = true;
        for (size_t i = 0; i < a.values.size(); ++i)
          BISTABLE_RETURN_IF_ERROR(check_f0(a.values[i], "axes.f0_hz[" + std::to_string(i) + "]"));
      }
    if (!f0_swept) BISTABLE_RETURN_IF_ERROR(check_f0(spec.base.omega, "params.f0_hz"));
  }
  if (spec.model == ModelKind::kDimensional && !spec.terms &&
      spec.base.integration.integrator == IntegratorKind::kRk4) {
    const int n = Rk4Substeps(spec.dimensional.params, spec.base.integration.dt);
    if (n > limits::kMaxRk4Substeps)
      return Status::InvalidArgument(
          "dimensional.v_t",
          "integrator = \"rk4\" needs " + std::to_string(n) +
              " RK4 steps per dt = " + FormatNumber(spec.base.integration.dt) + " s for this rig (limit " +
              std::to_string(limits::kMaxRk4Substeps) +
              "): its friction transition is too fast for fixed steps; use the rosenbrock integrator");
  }
  if (spec.base.integration.labels == LabelMode::kSettled && !IsCellModel(spec.model))
    return Status::InvalidArgument("integration.labels",
                                   "labels = 'settled' is for the cell models (standalone, coupled, "
                                   "linear, linear-coupled); series and rig maps use 'paper'");
  for (const Axis& a : spec.axes) {
    for (size_t i = 0; i < a.values.size(); ++i) {
      PointSpec p = probe;
      *spec.Slot(p, a.name) = a.values[i];
      if (Status st = ValidatePointSpec(p); !st.ok() && field_of(st.field()) == a.name)
        return Status::InvalidArgument("axes." + a.name + "[" + std::to_string(i) + "]", st.message());
    }
  }
  if (Status st = ValidatePointSpec(probe); !st.ok()) {
    const std::string f = field_of(st.field());
    const bool is_axis = swept.count(f) > 0;
    const bool is_param = std::find(param_keys.begin(), param_keys.end(), f) != param_keys.end();
    // The metric settings ValidatePointSpec checks (hd_level, max_period, ...) live in [metrics]: the message
    // named integration.hd_level for a bad [metrics] hd_level.
    const bool is_metric = std::find(kMetricKeys.begin(), kMetricKeys.end(), f) != kMetricKeys.end();
    const std::string section = is_axis ? "axes." : is_param ? "params." : is_metric ? "metrics." : "integration.";
    return Status::InvalidArgument(section + f, st.message());
  }
  if (spec.model == ModelKind::kSeries) {
    for (const Axis& a : spec.axes)
      for (size_t i = 0; i < a.values.size(); ++i) {
        PointSpec p = probe;
        *ParamSlot(p, a.name) = a.values[i];
        if (Status st = ValidateSeriesCells(spec.SeriesCells(p)); !st.ok())
          return Status::InvalidArgument("series." + st.field(), st.message());
      }
    if (Status st = ValidateSeriesCells(spec.SeriesCells(probe)); !st.ok())
      return Status::InvalidArgument("series." + st.field(), st.message());
  }
  const double items = static_cast<double>(spec.points()) * spec.ic_count();
  if (items > static_cast<double>(limits::kMaxSweepItems))
    return Violates("axes", items,
                    "points x initial conditions <= " + std::to_string(limits::kMaxSweepItems) + " (split the sweep)");
  if (spec.continuation.enabled()) {
    // A chain runs whole inside one job, and a job's report must fit one message.
    for (const Axis& a : spec.axes)
      if (a.name == spec.continuation.axis && static_cast<long>(a.values.size()) > limits::kMaxJobItems)
        return Violates("axes." + a.name, static_cast<double>(a.values.size()),
                        "count <= " + std::to_string(limits::kMaxJobItems) + " along the continuation axis");
  }
  return Status::Ok();
}

}  // namespace

StatusOr<SweepSpec> ParseSweepSpec(const std::string& text, const std::string& origin) {
  auto parsed = ParseSpecToml(text, origin);
  if (!parsed.ok()) return parsed.status();
  const toml::table& root = *parsed;
  BISTABLE_RETURN_IF_ERROR(CheckKeys(root, "", kTopKeys));
  SweepSpec spec;
  spec.source = text;
  spec.base.metrics.rosenstein = false;  // expensive; opt in per sweep
  BISTABLE_RETURN_IF_ERROR(ReadNameAndModel(root, spec));
  BISTABLE_RETURN_IF_ERROR(ReadSeries(root, spec));
  BISTABLE_RETURN_IF_ERROR(ReadDimensional(root, spec));
  BISTABLE_RETURN_IF_ERROR(ReadTerms(root, spec));
  std::set<std::string> swept;
  BISTABLE_RETURN_IF_ERROR(ReadParamsAndAxes(root, spec, swept));
  BISTABLE_RETURN_IF_ERROR(ReadIntegration(root, spec));
  BISTABLE_RETURN_IF_ERROR(ReadMetrics(root, spec));
  BISTABLE_RETURN_IF_ERROR(ReadInitialConditions(root, spec));
  BISTABLE_RETURN_IF_ERROR(ReadContinuation(root, spec));
  BISTABLE_RETURN_IF_ERROR(ReadRobustness(root, spec));
  BISTABLE_RETURN_IF_ERROR(ReadRefine(root, spec));
  BISTABLE_RETURN_IF_ERROR(ReadOutput(root, spec));
  BISTABLE_RETURN_IF_ERROR(CheckWholeSpec(spec, swept));
  spec.canonical_hash = ContentHashHex(spec.CanonicalText());
  return spec;
}

StatusOr<SweepSpec> LoadSweepSpec(const std::string& path) {
  auto text = ReadTextFile(path, "spec", limits::kMaxSpecBytes);
  if (!text.ok()) return text.status();
  return ParseSweepSpec(*text, path);
}

}  // namespace bistable
