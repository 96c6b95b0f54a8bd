#include "design/design_spec.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <sstream>

#include <toml++/toml.h>

#include "base/limits.h"
#include "base/names.h"
#include "base/validate.h"
#include "engine/content_hash.h"
#include "engine/spec_toml.h"

namespace bistable {
namespace {

const std::vector<std::string> kDesignKeys = {"bounds",    "alpha", "omega", "budget",   "seed",
                                              "optimizer", "cost",  "maps",  "map_alpha"};
const std::vector<std::string> kBoundKeys(kDesignParameters.begin(), kDesignParameters.end());
const std::vector<std::string> kOptimizers = {"direct-l", "crs2"};
const std::vector<std::string> kCosts = {"phi", "lambda"};
// Sections of a sweep spec that do not fit a search whose candidates are one start per point over Ω.
const std::vector<std::string> kRefusedSections = {"axes", "continuation", "robustness"};

std::string Toml(const toml::table& t) {
  std::ostringstream os;
  os << t;
  return os.str();
}

std::string Toml(const toml::node& n) {
  toml::table t;
  t.insert("v", n);
  if (toml::table* inner = t["v"].as_table()) inner->is_inline(true);
  std::string s = Toml(t);
  return s.substr(s.find('=') + 1);
}

StatusOr<double> Num(const toml::node& n, const std::string& field) {
  // An integer beyond double's exact range (seed = 99999999999999999) is still a number: its range check
  // names the bound (toml++ gives no double for it, and it was called "not a number").
  if (n.is_integer()) return static_cast<double>(n.as_integer()->get());
  if (auto v = n.value<double>(); v && n.is_number()) return *v;
  return Status::InvalidArgument(field, field + " must be a number");
}

// The engine reports errors of a spec built here by its own field names (axes.omega); the user wrote
// them under [design] (design.omega). `renames`: engine prefix -> design field.
Status Renamed(Status st, const std::vector<std::pair<std::string, std::string>>& renames) {
  if (st.ok() || st.code() != Status::Code::kInvalidArgument) return st;
  std::string field = st.field(), msg = st.message();
  for (const auto& [from, to] : renames)
    for (std::string* s : {&field, &msg})
      for (size_t p = s->find(from); p != std::string::npos; p = s->find(from, p + to.size()))
        s->replace(p, from.size(), to);
  return Status::InvalidArgument(field, msg);
}
const std::vector<std::pair<std::string, std::string>> kCandidateFields = {{"axes.omega", "design.omega"},
                                                                           {"axes.alpha", "design.alpha"}};

toml::table ParseTable(const std::string& text) { return toml::parse(text, std::string("design")); }

// The base with params, axes, metrics and output set for one sweep of the search.
std::string SpecWith(const std::string& base_toml, const DesignPoint& x, const std::string& name,
                     const std::string& axes_toml, const std::vector<std::string>& plots, double alpha) {
  toml::table t = ParseTable(base_toml);
  t.insert_or_assign("name", name);
  if (!t.contains("params")) t.insert("params", toml::table{});
  toml::table& p = *t["params"].as_table();
  for (int k = 0; k < 3; ++k) p.insert_or_assign(kDesignParameters[k], x[k]);
  if (std::isfinite(alpha))
    p.insert_or_assign("alpha", alpha);
  else
    p.erase("alpha");
  p.erase("omega");
  t.insert_or_assign("axes", ParseTable(axes_toml));
  toml::table out;
  toml::array pl;
  for (const auto& m : plots) pl.push_back(m);
  out.insert("plots", pl);
  t.insert_or_assign("output", out);
  return Toml(t);
}

}  // namespace

std::string DesignSpec::CandidateToml(const DesignPoint& x) const {
  std::string axes = "omega = " + omega_toml + "\n";
  if (alphas.size() > 1) axes += "alpha = " + alpha_toml + "\n";
  std::ostringstream nm;
  nm << (name.empty() ? "design " + id : name) << ": lambda = " << FormatNumber(x[0])
     << ", phi = " << FormatNumber(x[1]) << ", eta_r = " << FormatNumber(x[2]);
  return SpecWith(base_toml, x, nm.str(), axes, {}, alphas.size() > 1 ? NAN : alphas[0]);
}

std::string DesignSpec::MapToml(const DesignPoint& x, const std::string& title) const {
  if (map_alpha_toml.empty()) return "";
  return SpecWith(base_toml, x, title, "omega = " + omega_toml + "\nalpha = " + map_alpha_toml + "\n",
                  {"frf_db", "motion"}, NAN);
}

std::string DesignSpec::BruteForceToml(int n) const {
  std::string axes = "omega = " + omega_toml + "\n";
  if (alphas.size() > 1) axes += "alpha = " + alpha_toml + "\n";
  DesignPoint x = lo;
  for (int k = 0; k < 3; ++k)
    if (Free(k))
      axes += kDesignParameters[k] + " = { linspace = [" + FormatNumber(lo[k]) + ", " + FormatNumber(hi[k]) + ", " +
              std::to_string(n) + "] }\n";
  // linspace ends are written with 10 digits: the grid spans the bounds to that precision.
  std::string s = SpecWith(base_toml, x,
                           (name.empty() ? "design " + id : name) + ": brute force " + std::to_string(n) + "^" +
                               std::to_string((Free(0) ? 1 : 0) + (Free(1) ? 1 : 0) + (Free(2) ? 1 : 0)),
                           axes, {}, alphas.size() > 1 ? NAN : alphas[0]);
  // Swept parameters must not also be fixed in [params].
  toml::table t = ParseTable(s);
  for (int k = 0; k < 3; ++k)
    if (Free(k)) t["params"].as_table()->erase(kDesignParameters[k]);
  return Toml(t);
}

std::string DesignSpec::CanonicalText() const {
  // One field a line, each named, every text length-prefixed: no two different searches share a text
  // (a joined "0.1" "12" and "0.11" "2" would). The base spec carries [metrics] (chaos_threshold) and the name.
  std::string out = "bistable-design-v2\n";
  auto text = [&](const char* key, const std::string& v) {
    out += std::string(key) + " " + std::to_string(v.size()) + ":" + v + "\n";
  };
  text("base", base_toml);
  text("omega", omega_toml);
  text("alpha", alpha_toml);
  text("map_alpha", map_alpha_toml);
  text("optimizer", optimizer);
  text("cost", cost);
  out +=
      "budget " + std::to_string(budget) + "\nseed " + std::to_string(seed) + "\nmaps " + std::to_string(maps) + "\n";
  auto exact = [](double v) {  // 17 significant digits: every double its own text
    char b[32];
    std::snprintf(b, sizeof b, "%.17g", v);
    return std::string(b);
  };
  for (size_t k = 0; k < kDesignParameters.size(); ++k)
    out += "bounds." + kDesignParameters[k] + " " + exact(lo[k]) + " " + exact(hi[k]) + "\n";
  return out;
}

namespace {

// The base spec alone, as the engine reads it: model, params, integration, metrics, one start state. Sets the
// design's name, chaos threshold and (until design.bounds) its bounds at [params].
Status ReadBase(const toml::table& base, const std::string& origin, DesignSpec* out) {
  DesignSpec& d = *out;
  toml::table probe = base;
  if (!probe.contains("params")) probe.insert("params", toml::table{});
  auto spec = ParseSweepSpec(Toml(probe), origin);
  if (!spec.ok()) return spec.status();
  if (spec->model != ModelKind::kCoupled && spec->model != ModelKind::kLinearCoupled)
    return Status::InvalidArgument(
        "model", "model = " + std::string(ModelName(spec->model)) +
                     " violates model in {coupled, linear-coupled} (a design search tunes the resonator)");
  if (spec->ic_count() != 1)
    return Violates("initial_conditions.states", spec->ic_count(),
                    "count <= 1 (a design search runs one start per point)");
  d.name = spec->name;
  d.chaos_threshold = spec->base.metrics.chaos_threshold;
  const NondimParams& p = spec->base.params;
  d.lo = d.hi = {p.lambda, p.phi, p.eta_r};
  return Status::Ok();
}

// Stored metrics: what the score reads (frf_db, lle, motion), whatever else the base asks for.
Status StoreScoreMetrics(toml::table* base_in) {
  toml::table& base = *base_in;
  if (!base.contains("metrics")) base.insert("metrics", toml::table{});
  toml::table& m = *base["metrics"].as_table();
  if (!m.contains("store")) m.insert("store", toml::array{});
  toml::array* store = m["store"].as_array();
  if (!store) return Status::InvalidArgument("metrics.store", "metrics.store must be a list of metric names");
  for (const char* need : {"frf_db", "lle", "motion"}) {
    bool has = false;
    for (auto& e : *store) has = has || (e.value<std::string>() && *e.value<std::string>() == need);
    if (!has) store->push_back(need);
  }
  return Status::Ok();
}

// design.bounds = { lambda = [lo, hi], phi = [lo, hi], eta_r = [lo, hi] }; an omitted one stays at [params].
// At least one parameter must be free.
Status ReadBounds(const toml::table* design, DesignSpec* out) {
  DesignSpec& d = *out;
  if (const toml::node* b = design->get("bounds")) {
    const toml::table* bt = b->as_table();
    if (!bt)
      return Status::InvalidArgument(
          "design.bounds", "design.bounds must be a table: { lambda = [lo, hi], phi = [lo, hi], eta_r = [lo, hi] }");
    for (auto&& [k, v] : *bt) {
      const std::string key(k.str());
      const std::string field = "design.bounds." + key;
      const auto it = std::find(kBoundKeys.begin(), kBoundKeys.end(), key);
      if (it == kBoundKeys.end()) return Status::InvalidArgument(field, UnknownNameMessage("key", key, kBoundKeys));
      const int i = static_cast<int>(it - kBoundKeys.begin());
      const toml::array* a = v.as_array();
      if (!a || a->size() != 2) return Status::InvalidArgument(field, field + " must be [lo, hi] (2 numbers)");
      auto l = Num(*a->get(0), field + "[0]");
      if (!l.ok()) return l.status();
      auto h = Num(*a->get(1), field + "[1]");
      if (!h.ok()) return h.status();
      const double min = key == "eta_r" ? limits::kMinDesignDamping : limits::kMinDesignRatio;
      const double max = key == "eta_r" ? limits::kMaxDesignDamping : limits::kMaxDesignRatio;
      const std::string range = "in [" + FormatNumber(min) + ", " + FormatNumber(max) + "]";
      if (!(*l >= min && *l <= max)) return Violates(field + "[0]", *l, range);
      if (!(*h >= min && *h <= max)) return Violates(field + "[1]", *h, range);
      if (!(*h >= *l)) return Violates(field + "[1]", *h, ">= " + field + "[0] = " + FormatNumber(*l));
      d.lo[i] = *l, d.hi[i] = *h;
    }
  }
  if (!d.Free(0) && !d.Free(1) && !d.Free(2))
    return Status::InvalidArgument(
        "design.bounds",
        "design.bounds: no parameter is free (give at least one of lambda, phi, eta_r as [lo, hi] with lo < hi)");
  return Status::Ok();
}

// design.alpha = 1.0 or [0.5, 1.0]: the forcing amplitude(s) the band must hold at.
Status ReadAlphas(const toml::table* design, DesignSpec* out) {
  DesignSpec& d = *out;
  const toml::node* a = design->get("alpha");
  if (!a)
    return Status::InvalidArgument("design.alpha",
                                   "design.alpha is required: the forcing amplitude (a number or a list)");
  if (a->is_array()) {
    for (size_t i = 0; i < a->as_array()->size(); ++i) {
      auto v = Num(*a->as_array()->get(i), "design.alpha[" + std::to_string(i) + "]");
      if (!v.ok()) return v.status();
      d.alphas.push_back(*v);
    }
  } else {
    auto v = Num(*a, "design.alpha");
    if (!v.ok()) return v.status();
    d.alphas.push_back(*v);
  }
  if (d.alphas.empty() || static_cast<int>(d.alphas.size()) > limits::kMaxDesignAlphas)
    return Violates("design.alpha", static_cast<double>(d.alphas.size()),
                    "count in [1, " + std::to_string(limits::kMaxDesignAlphas) + "]");
  for (size_t i = 0; i < d.alphas.size(); ++i) {
    const std::string f = d.alphas.size() == 1 ? "design.alpha" : "design.alpha[" + std::to_string(i) + "]";
    BISTABLE_RETURN_IF_ERROR(CheckPositive(f, d.alphas[i]));
  }
  d.alpha_toml = Toml(*a);
  return Status::Ok();
}

// design.budget, seed, maps (whole numbers within their limits), optimizer and cost (names).
Status ReadSearchSettings(const toml::table* design, DesignSpec* spec) {
  DesignSpec& d = *spec;
  auto integer = [&](const char* key, long lo, long hi, long* out) -> Status {
    const toml::node* n = design->get(key);
    if (!n) return Status::Ok();
    const std::string field = std::string("design.") + key;
    auto v = Num(*n, field);
    if (!v.ok()) return v.status();
    if (!(*v >= static_cast<double>(lo) && *v <= static_cast<double>(hi) && *v == std::floor(*v)))
      return Violates(field, *v, "a whole number in [" + std::to_string(lo) + ", " + std::to_string(hi) + "]");
    *out = static_cast<long>(*v);
    return Status::Ok();
  };
  long budget = d.budget, seed = static_cast<long>(d.seed), maps = d.maps;
  BISTABLE_RETURN_IF_ERROR(integer("budget", 1, limits::kMaxDesignBudget, &budget));
  BISTABLE_RETURN_IF_ERROR(integer("seed", 0, 2147483647, &seed));
  BISTABLE_RETURN_IF_ERROR(integer("maps", 0, limits::kMaxDesignMaps, &maps));
  d.budget = static_cast<int>(budget), d.seed = static_cast<uint64_t>(seed), d.maps = static_cast<int>(maps);
  auto word = [&](const char* key, const std::vector<std::string>& allowed, std::string* out) -> Status {
    const toml::node* n = design->get(key);
    if (!n) return Status::Ok();
    const std::string field = std::string("design.") + key;
    auto s = n->value<std::string>();
    if (!s || !n->is_string()) return Status::InvalidArgument(field, field + " must be a string");
    if (std::find(allowed.begin(), allowed.end(), *s) == allowed.end())
      return Status::InvalidArgument(field, UnknownNameMessage("value of " + field, *s, allowed));
    *out = *s;
    return Status::Ok();
  };
  BISTABLE_RETURN_IF_ERROR(word("optimizer", kOptimizers, &d.optimizer));
  BISTABLE_RETURN_IF_ERROR(word("cost", kCosts, &d.cost));
  return Status::Ok();
}

// Every sweep the search runs is an ordinary spec: checked with the engine's parser now, before any work. Sets
// the design's id and its Omega values.
Status CheckSweeps(const std::string& origin, DesignSpec* out) {
  DesignSpec& d = *out;
  d.id = ContentHashHex(d.CanonicalText()).substr(0, 12);
  auto cand = ParseSweepSpec(d.CandidateToml(d.lo), origin);
  if (!cand.ok()) return Renamed(cand.status(), kCandidateFields);
  for (const Axis& a : cand->axes)
    if (a.name == "omega") d.omega = a.values;
  if (d.omega.size() < 2)
    return Violates("design.omega", static_cast<double>(d.omega.size()),
                    "count >= 2 (a band is measured between Omega values)");
  if (auto hi = ParseSweepSpec(d.CandidateToml(d.hi), origin); !hi.ok()) return Renamed(hi.status(), kCandidateFields);
  if (d.maps > 0) {
    auto m = ParseSweepSpec(d.MapToml(d.lo, "map"), origin);
    // design.omega passed with the candidates: what fails at the map's omega axis is the grid that
    // design.map_alpha spans with it (an oversized map_alpha was reported as design.omega).
    if (!m.ok()) return Renamed(m.status(), {{"axes.alpha", "design.map_alpha"}, {"axes.omega", "design.map_alpha"}});
  }
  return Status::Ok();
}

}  // namespace

StatusOr<DesignSpec> ParseDesignSpec(const std::string& text, const std::string& origin) {
  auto parsed = ParseSpecToml(text, origin);
  if (!parsed.ok()) return parsed.status();
  const toml::table& root = *parsed;
  DesignSpec d;
  d.origin = origin;
  d.source = text;
  const toml::table* design = root["design"].as_table();
  if (!design)
    return Status::InvalidArgument("design", "a design spec needs a [design] table (bounds, alpha, omega, budget)");
  for (auto&& [k, v] : *design) {
    (void)v;
    const std::string key(k.str());
    if (std::find(kDesignKeys.begin(), kDesignKeys.end(), key) == kDesignKeys.end())
      return Status::InvalidArgument("design." + key, UnknownNameMessage("key", key, kDesignKeys));
  }
  for (const std::string& s : kRefusedSections)
    if (root.contains(s))
      return Status::InvalidArgument(
          s, "[" + s +
                 "] is not part of a design spec: candidates sweep design.omega (and design.alpha) "
                 "with the parameters the optimiser picks within design.bounds");
  toml::table base = root;
  base.erase("design");

  BISTABLE_RETURN_IF_ERROR(ReadBase(base, origin, &d));
  BISTABLE_RETURN_IF_ERROR(StoreScoreMetrics(&base));
  d.base_toml = Toml(base);

  BISTABLE_RETURN_IF_ERROR(ReadBounds(design, &d));
  BISTABLE_RETURN_IF_ERROR(ReadAlphas(design, &d));
  // omega: any axis form; the engine computes its values.
  {
    const toml::node* o = design->get("omega");
    if (!o)
      return Status::InvalidArgument("design.omega",
                                     "design.omega is required: the Omega line, e.g. { linspace = [0.2, 3.0, 57] }");
    d.omega_toml = Toml(*o);
  }
  if (const toml::node* m = design->get("map_alpha"))
    d.map_alpha_toml = Toml(*m);
  else
    d.map_alpha_toml = "{ linspace = [0.1, 3.0, 30] }";

  BISTABLE_RETURN_IF_ERROR(ReadSearchSettings(design, &d));

  BISTABLE_RETURN_IF_ERROR(CheckSweeps(origin, &d));
  return d;
}

}  // namespace bistable
