#include "server/dashboard.h"

#include <malloc.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <limits>
#include <memory>
#include <mutex>
#include <optional>
#include <utility>

#include <nlohmann/json.hpp>

#include "base/limits.h"
#include "base/validate.h"
#include "dynamics/point.h"
#include "dynamics/spectrum.h"
#include "engine/json_shapes.h"
#include "engine/query.h"
#include "engine/refine.h"
#include "engine/sweep_kind.h"
#include "server/embedded_files.h"
#include "server/single_flight.h"
#include "storage/map_file.h"

namespace bistable {
namespace {

using nlohmann::json;

// Bounds of what one answer carries (the page draws at most this much).
constexpr size_t kMaxSliceSide = 1024;      // a map slice: at most 1024 × 1024 cells (larger: every k-th cell)
constexpr long kMaxLiveItems = 1 << 18;     // a running sweep's partial map: looked up only up to this many items
constexpr double kCacheSeconds = 2;         // a loaded metric serves every request for (sweep, metric) this long
constexpr size_t kCacheEntries = 8;         // (sweep, metric) pairs kept
constexpr size_t kMaxSeriesRows = 4000;     // time series rows of a cell (decimated)
constexpr size_t kMaxSpectrumBins = 4000;   // spectrum bins of a cell (the low end)
constexpr size_t kMaxSectionPoints = 5000;  // Poincaré section points of a cell
constexpr size_t kMaxParamBytes = 64;       // id, metric, axis names, numbers
constexpr int kSessionSeconds = 12 * 3600;  // the token cookie's lifetime

HttpResponse Json(const json& j, int status = 200) { return {status, "application/json", DumpJson(j), {}}; }

HttpResponse Error(const Status& st) {
  int code = 500;
  switch (st.code()) {
    case Status::Code::kInvalidArgument:
      code = 400;
      break;
    case Status::Code::kNotFound:
      code = 404;
      break;
    case Status::Code::kFailedPrecondition:
      code = 409;
      break;
    case Status::Code::kUnauthenticated:
      code = 401;
      break;
    case Status::Code::kPermissionDenied:
      code = 403;
      break;
    default:
      break;
  }
  HttpResponse r = Json({{"error", st.ToString()}}, code);
  if (code == 401) r.headers.push_back({"WWW-Authenticate", "Bearer"});
  return r;
}

// The request's token: "Authorization: Bearer <token>", else the dashboard's cookie.
std::string TokenOf(const HttpRequest& req) {
  if (req.authorization.rfind("Bearer ", 0) == 0) return req.authorization.substr(7);
  return CookieValue(req.cookie, kDashboardCookie);
}

// A page's read access: viewer, client or admin (a worker token may not read).
Status Authorize(const TokenStore* tokens, const HttpRequest& req, std::string* who = nullptr, Role* role = nullptr) {
  return tokens->CheckToken(TokenOf(req), Op::kStatus, who, role);
}

// Query parameters, each at most kMaxParamBytes (the query text at most limits::kMaxQueryBytes).
StatusOr<std::map<std::string, std::string>> Params(const HttpRequest& req) {
  auto p = ParseQueryString(req.query);
  if (!p.ok()) return p.status();
  for (const auto& [k, v] : *p)
    if (v.size() > (k == "q" ? static_cast<size_t>(limits::kMaxQueryBytes) : kMaxParamBytes))
      return Status::InvalidArgument(k.substr(0, 16), "parameter too long");
  return p;
}

std::string Get(const std::map<std::string, std::string>& p, const std::string& k) {
  auto it = p.find(k);
  return it == p.end() ? "" : it->second;
}

// A whole non-negative integer below `limit`.
StatusOr<long> Index(const std::map<std::string, std::string>& p, const std::string& k, long limit) {
  const std::string v = Get(p, k);
  if (v.empty() || v.size() > 12 || v.find_first_not_of("0123456789") != std::string::npos)
    return Status::InvalidArgument(k, k + " must be a whole number");
  const long n = std::stol(v);
  if (n >= limit) return Status::InvalidArgument(k, k + " = " + v + " violates " + k + " < " + std::to_string(limit));
  return n;
}

struct SweepView {
  std::string id;
  SweepInfo info;
  SweepSpec spec;
};

StatusOr<SweepView> ResolveSweep(SweepCoordinator* c, const std::map<std::string, std::string>& p) {
  const std::string raw = Get(p, "id");
  if (raw.empty()) return Status::InvalidArgument("id", "missing sweep id");
  auto id = c->ResolveId(raw);
  if (!id.ok()) return id.status();
  auto info = c->Info(*id);
  if (!info.ok()) return info.status();
  auto text = c->SpecText(*id);
  if (!text.ok()) return text.status();
  auto spec = ParseSweepSpec(*text, "sweep " + *id);
  if (!spec.ok()) return spec.status();
  return SweepView{*id, *info, std::move(*spec)};
}

// A published sweep: its map file is what every view reads.
bool Published(const SweepInfo& info) { return !info.file.empty() && info.state == SweepState::kDone; }

// The name of the trailing item dimension, as the map file names it (storage/map_file.cc): the
// continuation directions (up, down) of a chained sweep, else the initial conditions.
std::string ItemDim(const SweepSpec& spec) { return KindOf(spec).Dimension(spec).name; }

// The sweep's item shape (axes, then the item dimension when there are several items per point).
MapArray ShapeOf(const SweepSpec& spec) {
  MapArray a;
  a.axes = spec.axes;
  for (const Axis& ax : a.axes) a.dims.push_back(ax.values.size()), a.dim_names.push_back(ax.name);
  if (spec.ic_count() > 1) a.dims.push_back(static_cast<size_t>(spec.ic_count())), a.dim_names.push_back(ItemDim(spec));
  return a;
}

// The datasets a refined map ([refine]) carries besides the catalog's metrics (written at publication).
constexpr const char* kRefineLevel = "refine_level";
constexpr const char* kRefineFill = "refine_fill";

// Metrics a map view offers: the sweep's stored scalar metrics of the catalog, and for a published
// refined sweep its refine_level and refine_fill.
std::vector<std::string> MapMetrics(const SweepSpec& spec, bool published) {
  std::vector<std::string> out;
  for (const std::string& m : spec.metrics)
    if (FindMetric(m)) out.push_back(m);
  if (published && KindOf(spec).InRounds()) out.push_back(kRefineLevel), out.push_back(kRefineFill);
  return out;
}

// [[code, name, colour]...]: colour is CategoryColour's (the CLI figures' for a named code), "" when the page picks.
json CategoriesJson(const std::vector<std::pair<int, std::string>>& cats) {
  json out = json::array();
  for (const auto& [code, name] : cats) out.push_back({code, name, CategoryColour(name)});
  return out;
}

// What /api/sweep says of an offered metric.
json MetricJson(const std::string& m) {
  std::vector<std::pair<int, std::string>> cats;
  if (m == kRefineLevel)
    return {{"name", m},
            {"unit", ""},
            {"definition", "refinement level of the smallest cell holding the point (0: the coarse grid)"},
            {"integer", true},
            {"categories", json::array()}};
  if (m == kRefineFill) {
    for (const Category& k : RefineFillCategories()) cats.push_back({k.code, k.name});
    return {{"name", m},
            {"unit", "code"},
            {"definition", "how the point's values were obtained in the refined map"},
            {"integer", true},
            {"categories", CategoriesJson(cats)}};
  }
  const MetricInfo* info = FindMetric(m);
  for (const Category& k : MetricCategories(m)) cats.push_back({k.code, k.name});
  return {{"name", m},
          {"unit", info->unit},
          {"definition", info->definition},
          {"integer", info->integer},
          {"categories", CategoriesJson(cats)}};
}

// A metric loaded for the views: the whole map's values (empty: not shown, see note) and their range.
struct Loaded {
  std::shared_ptr<const MapArray> array;
  bool partial = false;       // what is stored so far of a running sweep
  std::string note;           // why no values are shown
  double lo = NAN, hi = NAN;  // over every finite value (one colour range for every slice)
};

// Live metrics (what is stored so far of a running sweep), shared by every request for the same sweep and
// metric for kCacheSeconds, and loaded once however many requests miss together (server/single_flight.h): any
// number of open tabs on a running sweep cost one lookup in the point cache per kCacheSeconds. Published maps
// are read through the MapCache the gRPC service shares (server/map_cache.h): once per map file.
using DashboardCache = SingleFlightCache<Loaded>;

// The range of every finite value (one colour range for every slice).
void SetRange(Loaded* l) {
  for (double v : l->array->values)
    if (std::isfinite(v))
      l->lo = std::isnan(l->lo) ? v : std::min(l->lo, v), l->hi = std::isnan(l->hi) ? v : std::max(l->hi, v);
}

// A metric over the sweep's items: the published map file, or what is stored so far of a planned sweep
// (looked up only when the sweep has at most kMaxLiveItems items: the size comes from the spec's axis
// lengths, before anything is loaded; cached for kCacheSeconds).
StatusOr<Loaded> LoadMetric(SweepCoordinator* c, DashboardCache* cache, MapCache* maps, const SweepView& s,
                            const std::string& metric) {
  const bool published = Published(s.info);
  const auto offered = MapMetrics(s.spec, published);
  if (std::find(offered.begin(), offered.end(), metric) == offered.end())
    return Status::InvalidArgument("metric",
                                   "sweep " + s.id + " stores no metric '" + metric.substr(0, 32) + "'" +
                                       (KindOf(s.spec).InRounds() && (metric == kRefineLevel || metric == kRefineFill)
                                            ? " yet (written when the refined map is published)"
                                            : ""));
  if (published) {
    auto a = maps->Metric((std::filesystem::path(c->data_dir()) / s.info.file).string(), metric);
    if (!a.ok()) return a.status();
    if ((*a)->dims.size() != (*a)->axes.size() && (*a)->dims.size() != (*a)->axes.size() + 1)
      return Status::FailedPrecondition("metric '" + metric + "' is not one value per item");
    Loaded l;
    l.array = *a;
    SetRange(&l);
    return l;
  }
  return cache->GetOrLoad(s.id + "\n" + metric + "\nlive", [&]() -> StatusOr<Loaded> {
    Loaded l;
    const MetricInfo* info = FindMetric(metric);
    MapArray a = ShapeOf(s.spec);
    a.metric = metric;
    a.unit = info->unit;
    a.definition = info->definition;
    for (const Category& k : MetricCategories(metric)) a.categories.push_back({k.code, k.name});
    const long items = s.spec.points() * s.spec.ic_count();
    if (items > kMaxLiveItems) {
      l.note = "partial map not shown above " + std::to_string(kMaxLiveItems) + " items (this sweep has " +
               std::to_string(items) + "); the published map will be";
    } else {
      auto values = c->StoredValues(s.id, metric);
      if (!values.ok())
        return Status::NotFound("sweep " + s.id + " has no map yet (state " + SweepStateName(s.info.state) + ")");
      a.values = std::move(*values);
    }
    l.array = std::make_shared<const MapArray>(std::move(a));
    l.partial = true;
    SetRange(&l);
    return l;
  });
}

// Which cells a slice shows: x (and y) axis, every other dimension fixed by "at" = "name:index,...".
// An axis longer than kMaxSliceSide is shown decimated: every stride-th value (0, stride, 2·stride, ...).
struct Slice {
  int x = -1, y = -1;         // dimension indices (y = -1: a one-axis slice)
  std::vector<size_t> fixed;  // index of every dimension (x and y ignored)
  size_t sx = 1, sy = 1;      // strides along x and y
  size_t nx = 1, ny = 1;      // cells shown along x and y
};

StatusOr<Slice> ParseSlice(const std::map<std::string, std::string>& p, const MapArray& a) {
  Slice s;
  s.fixed.assign(a.dims.size(), 0);
  auto dim = [&](const std::string& name) -> int {
    for (size_t d = 0; d < a.dim_names.size(); ++d)
      if (a.dim_names[d] == name) return static_cast<int>(d);
    return -1;
  };
  const std::string xs = Get(p, "x"), ys = Get(p, "y");
  if (!a.axes.empty()) {
    s.x = xs.empty() ? static_cast<int>(a.axes.size()) - 1 : dim(xs);
    if (s.x < 0 || s.x >= static_cast<int>(a.axes.size()))
      return Status::InvalidArgument("x", "x is not an axis of the sweep");
    if (!ys.empty()) {
      s.y = dim(ys);
      if (s.y < 0 || s.y >= static_cast<int>(a.axes.size()) || s.y == s.x)
        return Status::InvalidArgument("y", "y is not another axis of the sweep");
    } else if (a.axes.size() >= 2) {
      s.y = s.x == 0 ? 1 : 0;
    }
  }
  const std::string at = Get(p, "at");
  size_t pos = 0;
  while (pos < at.size()) {
    size_t end = at.find(',', pos);
    if (end == std::string::npos) end = at.size();
    const std::string part = at.substr(pos, end - pos);
    pos = end + 1;
    const size_t colon = part.find(':');
    const int d = colon == std::string::npos ? -1 : dim(part.substr(0, colon));
    if (d < 0) return Status::InvalidArgument("at", "at must be name:index,... over the map's dimensions");
    auto i = Index({{"at", part.substr(colon + 1)}}, "at", static_cast<long>(a.dims[d]));
    if (!i.ok()) return i.status();
    s.fixed[d] = static_cast<size_t>(*i);
  }
  auto decimate = [](size_t n, size_t* stride, size_t* shown) {
    *stride = (n + kMaxSliceSide - 1) / kMaxSliceSide;
    if (*stride < 1) *stride = 1;
    *shown = (n + *stride - 1) / *stride;
  };
  if (s.x >= 0) decimate(a.dims[s.x], &s.sx, &s.nx);
  if (s.y >= 0) decimate(a.dims[s.y], &s.sy, &s.ny);
  return s;
}

// Flat index into a.values of the shown cell (ix, iy) of a slice.
size_t FlatIndex(const MapArray& a, const Slice& s, size_t ix, size_t iy) {
  size_t flat = 0;
  for (size_t d = 0; d < a.dims.size(); ++d) {
    const size_t i = static_cast<int>(d) == s.x ? ix * s.sx : static_cast<int>(d) == s.y ? iy * s.sy : s.fixed[d];
    flat = flat * a.dims[d] + i;
  }
  return flat;
}

// An axis as the page sees it (every stride-th value of a decimated slice axis).
json AxisJson(const Axis& ax, size_t stride = 1) {
  std::vector<double> v;
  for (size_t i = 0; i < ax.values.size(); i += stride) v.push_back(ax.values[i]);
  return {
      {"name", ax.name}, {"unit", AxisUnit(ax.name)}, {"values", v}, {"stride", stride}, {"size", ax.values.size()}};
}

HttpResponse SweepsRoute(SweepCoordinator* c) {
  auto list = c->ListSweeps();
  if (!list.ok()) return Error(list.status());
  json sweeps = json::array();
  for (const SweepInfo& s : *list) {
    json j = SweepStatusJson(s);
    // Points/s over the sweep's life in this process (computed items only), and the time left at that rate.
    const double computed = static_cast<double>(s.items_done - s.items_cached);
    const double rate = s.seconds > 0 && computed > 0 ? computed / s.seconds : 0;
    j["items_per_second"] = rate;
    j["eta_seconds"] =
        rate > 0 && !IsFinal(s.state) ? json(static_cast<double>(s.items_total - s.items_done) / rate) : json(nullptr);
    sweeps.push_back(std::move(j));
  }
  json workers = json::array();
  for (const WorkerInfo& w : c->Workers()) workers.push_back(WorkerJson(w));
  return Json({{"sweeps", sweeps}, {"workers", workers}});
}

HttpResponse SweepRoute(SweepCoordinator* c, const HttpRequest& req) {
  auto p = Params(req);
  if (!p.ok()) return Error(p.status());
  auto s = ResolveSweep(c, *p);
  if (!s.ok()) return Error(s.status());
  json metrics = json::array();
  for (const std::string& m : MapMetrics(s->spec, Published(s->info))) metrics.push_back(MetricJson(m));
  json axes = json::array();
  for (const Axis& ax : s->spec.axes) axes.push_back(AxisJson(ax));
  // Every dimension of the sweep's maps by the name /api/map's "at" takes (the map file's names).
  const MapArray shape = ShapeOf(s->spec);
  json dims = json::array();
  for (size_t d = 0; d < shape.dims.size(); ++d)
    dims.push_back({{"name", shape.dim_names[d]}, {"size", shape.dims[d]}});
  std::string cell_note;
  if (!IsCellModel(s->spec.model))
    cell_note = "cells of " + s->spec.ModelLabel() + " sweeps cannot be opened (bistable point runs cell models)";
  else if (KindOf(s->spec).Chained())
    cell_note = "continuation sweeps start each point from the previous one: a cell alone is not that item";
  const long items = s->spec.points() * s->spec.ic_count();
  return Json({{"status", SweepStatusJson(s->info)},
               {"spec", s->spec.source},
               {"axes", axes},
               {"ic_count", s->spec.ic_count()},
               {"dims", dims},
               {"item_dim", shape.dims.size() > shape.axes.size() ? json(ItemDim(s->spec)) : json(nullptr)},
               {"refined", KindOf(s->spec).InRounds()},
               {"live_map", items <= kMaxLiveItems},
               {"metrics", metrics},
               {"cells", cell_note.empty()},
               {"cell_note", cell_note}});
}

HttpResponse MapRoute(SweepCoordinator* c, DashboardCache* cache, MapCache* maps, const HttpRequest& req) {
  auto p = Params(req);
  if (!p.ok()) return Error(p.status());
  auto s = ResolveSweep(c, *p);
  if (!s.ok()) return Error(s.status());
  auto l = LoadMetric(c, cache, maps, *s, Get(*p, "metric"));
  if (!l.ok()) return Error(l.status());
  const MapArray& a = *l->array;
  auto sl = ParseSlice(*p, a);
  if (!sl.ok()) return Error(sl.status());
  json values = json::array();
  const bool shown = !a.values.empty();
  for (size_t iy = 0; iy < sl->ny; ++iy)
    for (size_t ix = 0; ix < sl->nx; ++ix)
      values.push_back(shown ? JsonNumber(a.values[FlatIndex(a, *sl, ix, iy)]) : json(nullptr));
  json dims = json::array();
  for (size_t d = 0; d < a.dims.size(); ++d) dims.push_back({{"name", a.dim_names[d]}, {"size", a.dims[d]}});
  return Json({{"sweep", s->id},
               {"metric", a.metric},
               {"unit", a.unit},
               {"partial", l->partial},
               {"note", l->note},
               {"x", sl->x >= 0 ? AxisJson(a.axes[sl->x], sl->sx) : json(nullptr)},
               {"y", sl->y >= 0 ? AxisJson(a.axes[sl->y], sl->sy) : json(nullptr)},
               {"stride", {{"x", sl->sx}, {"y", sl->sy}}},
               {"dims", dims},
               {"categories", CategoriesJson(a.categories)},
               {"min", JsonNumber(l->lo)},
               {"max", JsonNumber(l->hi)},
               {"diverging", DivergesAboutZero(a.metric)},
               {"values", values}});
}

HttpResponse QueryRoute(SweepCoordinator* c, DashboardCache* cache, MapCache* maps, const HttpRequest& req) {
  auto p = Params(req);
  if (!p.ok()) return Error(p.status());
  auto s = ResolveSweep(c, *p);
  if (!s.ok()) return Error(s.status());
  std::vector<std::string> names;
  for (const Axis& ax : s->spec.axes) names.push_back(ax.name);
  const auto metrics = MapMetrics(s->spec, Published(s->info));
  for (const std::string& m : metrics) names.push_back(m);
  auto q = Query::Parse(Get(*p, "q"), names);
  if (!q.ok()) return Error(q.status());
  // The slice shown (the same parameters as /api/map) picks the cells to mark: checked before loading.
  const MapArray shape = ShapeOf(s->spec);
  auto sl = ParseSlice(*p, shape);
  if (!sl.ok()) return Error(sl.status());
  std::map<int, Loaded> loaded;
  bool partial = false;
  for (int v : q->used()) {
    if (v < static_cast<int>(s->spec.axes.size())) continue;
    auto l = LoadMetric(c, cache, maps, *s, names[v]);
    if (!l.ok()) return Error(l.status());
    if (l->array->values.empty()) return Error(Status::FailedPrecondition(l->note));
    partial = partial || l->partial;
    loaded.emplace(v, std::move(*l));
  }
  const size_t per_point = static_cast<size_t>(s->spec.ic_count());
  std::vector<int> mask(sl->nx * sl->ny, 0);
  auto column = [&](int v) -> const std::vector<double>& { return loaded.at(v).array->values; };
  const QueryScan scan =
      ScanQuery(*q, s->spec.axes, per_point, column, [&](size_t item, const std::vector<size_t>& idx) {
        for (size_t d = 0; d < s->spec.axes.size(); ++d)
          if (static_cast<int>(d) != sl->x && static_cast<int>(d) != sl->y && idx[d] != sl->fixed[d]) return;
        if (per_point > 1 && item % per_point != sl->fixed.back()) return;
        if ((sl->x >= 0 && idx[sl->x] % sl->sx) || (sl->y >= 0 && idx[sl->y] % sl->sy)) return;  // not a shown cell
        mask[(sl->y >= 0 ? idx[sl->y] / sl->sy * sl->nx : 0) + (sl->x >= 0 ? idx[sl->x] / sl->sx : 0)] = 1;
      });
  return Json({{"sweep", s->id},
               {"count", scan.count},
               {"total", scan.total},
               {"fraction", scan.fraction},
               {"area_fraction", scan.area_fraction},
               {"partial", partial},
               {"stride", {{"x", sl->sx}, {"y", sl->sy}}},
               {"mask", mask}});
}

// The `bistable point` command line that computes this point (every setting it takes); *note says
// what it cannot set when the sweep changed a setting the command has no flag for.
std::string PointCommand(const PointSpec& s, std::string* note) {
  const PointSpec d;
  // Each number in its shortest form that reads back as the same double (6 digits when they do, at
  // most 17): the command stays readable and on one line, and still computes exactly this point.
  auto Short = [](double v) {
    char b[40];
    for (int digits = 6; digits <= 17; ++digits) {
      std::snprintf(b, sizeof b, "%.*g", digits, v);
      if (std::strtod(b, nullptr) == v) break;
    }
    return std::string(b);
  };
  std::string cmd = "bistable point --json --model " + std::string(ModelName(s.model)) + " --alpha " + Short(s.alpha) +
                    " --omega " + Short(s.omega) + " --eps " + Short(s.params.eps) + " --eta " + Short(s.params.eta);
  if (HasResonator(s.model))
    cmd +=
        " --eta-r " + Short(s.params.eta_r) + " --phi " + Short(s.params.phi) + " --lambda " + Short(s.params.lambda);
  cmd += " --integrator " + std::string(IntegratorName(s.integration.integrator)) + " --dt " + Short(s.integration.dt) +
         " --t-end " + Short(s.integration.t_end) + " --t-keep " + Short(s.integration.t_keep);
  if (s.integration.integrator != IntegratorKind::kRk4)
    cmd += " --rtol " + Short(s.integration.rtol) + " --atol " + Short(s.integration.atol);
  if (s.ic_given) cmd += " --ic " + Short(s.ic[0]) + "," + Short(s.ic[1]) + "," + Short(s.ic[2]) + "," + Short(s.ic[3]);
  cmd += " --chaos-threshold " + Short(s.metrics.chaos_threshold) + " --renorm-every " +
         std::to_string(s.metrics.renorm_every) + " --sample-every " + std::to_string(s.metrics.sample_every) +
         " --poincare-phase " + Short(s.metrics.poincare_phase);
  if (!s.metrics.rosenstein) cmd += " --no-rosenstein";
  if (s.metrics.period_tol != d.metrics.period_tol || s.metrics.max_period != d.metrics.max_period ||
      s.metrics.hd_level != d.metrics.hd_level || s.metrics.hd_top_k != d.metrics.hd_top_k)
    *note = "the sweep sets period_tol, max_period, hd_level or hd_top_k, which bistable point takes no flag for";
  return cmd;
}

HttpResponse CellRoute(SweepCoordinator* c, DashboardCache* cache, MapCache* maps, const HttpRequest& req) {
  auto p = Params(req);
  if (!p.ok()) return Error(p.status());
  auto s = ResolveSweep(c, *p);
  if (!s.ok()) return Error(s.status());
  if (!IsCellModel(s->spec.model) || KindOf(s->spec).Chained())
    return Error(
        Status::FailedPrecondition("cells of this sweep cannot be computed alone (see /api/sweep's cell_note)"));
  auto point = Index(*p, "point", s->spec.points());
  if (!point.ok()) return Error(point.status());
  auto ic = Index(*p, "ic", s->spec.ic_count());
  if (!ic.ok()) return Error(ic.status());
  PointSpec spec = s->spec.PointAt(*point, static_cast<int>(*ic));
  spec.metrics.keep_samples = true;  // the window's rows for the orbit and the series (recorded only)
  // Bounded work and memory: a cell runs on the coordinator while other cells wait (limits.h).
  const IntegrationSettings& in = spec.integration;
  const double steps = std::max(in.t_end, in.labels == LabelMode::kSettled ? in.t_keep + in.settle_cap : 0.0) / in.dt;
  const double samples = (in.t_end - in.t_keep) / in.dt / static_cast<double>(spec.metrics.sample_every);
  if (steps > limits::kMaxCellSteps || samples > limits::kMaxCellSamples) {
    std::string note;
    return Json({{"error", "this cell needs " + FormatNumber(steps) + " steps and " + FormatNumber(samples) +
                               " window samples; the dashboard computes cells of at most " +
                               FormatNumber(limits::kMaxCellSteps) + " steps and " +
                               FormatNumber(limits::kMaxCellSamples) + " samples: run it with the command given"},
                 {"command", PointCommand(spec, &note)}},
                422);
  }
  auto r = EvaluatePoint(spec);
  if (!r.ok()) return Error(r.status());
  std::string note;
  json j = {{"sweep", s->id}, {"point", *point}, {"ic", *ic}, {"result", PointJson(spec, *r)}};
  j["command"] = PointCommand(spec, &note);
  j["command_note"] = note;
  // A refined map: how the map got this cell. Where it was interpolated (or filled from a chaotic-mixed
  // cell's corner), the map's values are not this computation's: say so.
  if (KindOf(s->spec).InRounds()) {
    json fill = nullptr;
    std::string refine_note;
    if (Published(s->info)) {
      auto l = LoadMetric(c, cache, maps, *s, kRefineFill);
      const size_t item =
          static_cast<size_t>(*point) * static_cast<size_t>(s->spec.ic_count()) + static_cast<size_t>(*ic);
      if (l.ok() && item < l->array->values.size()) {
        const double code = l->array->values[item];
        for (const Category& k : RefineFillCategories())
          if (code == k.code) fill = k.name;
        if (code == static_cast<int>(RefineFill::kInterpolated))
          refine_note =
              "this cell was interpolated in the refined map (not computed there); the values shown are computed now "
              "at this point";
        else if (code == static_cast<int>(RefineFill::kChaoticMixed))
          refine_note =
              "this cell lies in a chaotic-mixed region of the refined map (its map values are a corner's, not "
              "computed here); "
              "the values shown are computed now at this point";
      }
    } else {
      refine_note =
          "refined sweep still running: the map holds computed points only; the values shown are computed now at this "
          "point";
    }
    j["refine_fill"] = fill;
    j["refine_note"] = refine_note;
  }
  json at = json::object();
  const std::vector<int> idx = s->spec.AxisIndices(*point);
  for (size_t k = 0; k < s->spec.axes.size(); ++k) at[s->spec.axes[k].name] = s->spec.axes[k].values[idx[k]];
  j["at"] = at;
  // The window: rows τ, y_m, y_m', y_r, y_r' (every k-th so at most kMaxSeriesRows).
  const size_t n = r->samples.size(), step = std::max<size_t>(1, (n + kMaxSeriesRows - 1) / kMaxSeriesRows);
  json series = json::array();
  for (size_t i = 0; i < n; i += step) {
    const auto& row = r->samples[i];
    series.push_back(
        {JsonNumber(row[0]), JsonNumber(row[1]), JsonNumber(row[2]), JsonNumber(row[3]), JsonNumber(row[4])});
  }
  j["series"] = {{"columns", {"tau", "y_m", "dy_m", "y_r", "dy_r"}}, {"every", step}, {"rows", series}};
  // The response spectrum of y_m over the window, as the harmonic-diffusion metrics see it.
  if (n >= 4 && r->termination == Termination::kOk) {
    std::vector<double> y(n);
    for (size_t i = 0; i < n; ++i) y[i] = r->samples[i][1];
    const Spectrum sp = AmplitudeSpectrum(y, SampleStep(spec));
    const size_t bins = std::min(sp.amp.size(), kMaxSpectrumBins);
    j["spectrum"] = {{"d_omega", sp.d_omega},
                     {"amp", std::vector<double>(sp.amp.begin(), sp.amp.begin() + static_cast<long>(bins))}};
  }
  json section = json::array();
  for (size_t i = 0; i < r->section_y.size() && i < kMaxSectionPoints; ++i)
    section.push_back({JsonNumber(r->section_y[i]), JsonNumber(r->section_v[i])});
  j["section"] = section;
  return Json(j);
}

HttpResponse SessionRoute(const TokenStore* tokens, const HttpRequest& req) {
  std::string who;
  Role role;
  if (Status st = Authorize(tokens, req, &who, &role); !st.ok()) return Error(st);
  HttpResponse r = Json({{"who", who}, {"role", RoleName(role)}, {"auth", tokens->enabled()}});
  // A token given in the header once is kept in an HttpOnly cookie: the page never holds it.
  const std::string token = TokenOf(req);
  const bool cookie_safe =
      token.find_first_not_of("0123456789abcdefghijklmnopqrstuvwxyzABCDEFGHIJKLMNOPQRSTUVWXYZ._~-") ==
      std::string::npos;
  if (tokens->enabled() && req.authorization.rfind("Bearer ", 0) == 0 && cookie_safe)
    r.headers.push_back({"Set-Cookie", std::string(kDashboardCookie) + "=" + token +
                                           "; Path=/; HttpOnly; SameSite=Strict; Max-Age=" +
                                           std::to_string(kSessionSeconds) + (req.tls ? "; Secure" : "")});
  return r;
}

}  // namespace

HttpServer::Options DashboardHttpOptions() {
  HttpServer::Options o;
  o.slow_routes = {"/api/map", "/api/query", "/api/cell"};
  o.heavy_routes = {"/api/cell"};
  return o;
}

std::map<std::string, HttpHandler> DashboardRoutes(SweepCoordinator* c, const TokenStore* tokens,
                                                   std::vector<std::string> allowed_hosts,
                                                   std::shared_ptr<MapCache> maps) {
  std::map<std::string, HttpHandler> routes;
  auto cache = std::make_shared<DashboardCache>(kCacheSeconds, kCacheEntries);
  if (!maps) maps = std::make_shared<MapCache>();
  for (const EmbeddedFile& f : DashboardAssets()) {
    HttpResponse r{200, std::string(f.content_type), std::string(f.bytes), {}};
    r.headers.push_back(
        {"Content-Security-Policy", "default-src 'self'; img-src 'self' data:; frame-ancestors 'none'"});
    auto serve = [r](const HttpRequest&) { return r; };
    routes["/" + std::string(f.name)] = serve;
    if (f.name == "index.html") routes["/"] = serve;
  }
  // Every /api/ route checks the token first: nothing of a sweep leaves without it.
  auto guarded = [tokens](auto fn) -> HttpHandler {
    return [tokens, fn](const HttpRequest& req) {
      if (Status st = Authorize(tokens, req); !st.ok()) return Error(st);
      return fn(req);
    };
  };
  routes["/api/session"] = [tokens](const HttpRequest& req) { return SessionRoute(tokens, req); };
  routes["/api/logout"] = [](const HttpRequest&) {
    HttpResponse r = Json({{"ok", true}});
    r.headers.push_back(
        {"Set-Cookie", std::string(kDashboardCookie) + "=; Path=/; HttpOnly; SameSite=Strict; Max-Age=0"});
    return r;
  };
  routes["/api/sweeps"] = guarded([c](const HttpRequest&) { return SweepsRoute(c); });
  routes["/api/sweep"] = guarded([c](const HttpRequest& req) { return SweepRoute(c, req); });
  routes["/api/map"] =
      guarded([c, cache, maps](const HttpRequest& req) { return MapRoute(c, cache.get(), maps.get(), req); });
  routes["/api/query"] =
      guarded([c, cache, maps](const HttpRequest& req) { return QueryRoute(c, cache.get(), maps.get(), req); });
  routes["/api/cell"] = guarded([c, cache, maps](const HttpRequest& req) {
    HttpResponse r = CellRoute(c, cache.get(), maps.get(), req);
    // The window's rows and the spectrum are freed, and so are this pool thread's transform tables for the
    // cell's length: their pages go back to the system (a cell holds up to 2^20 samples).
    ReleaseThreadSpectrumCaches();
    ::malloc_trim(0);
    return r;
  });
  // Without tokens, the Host rule of every tokenless listener (DNS rebinding: a page elsewhere names its own host).
  if (!tokens->enabled()) return HostChecked(std::move(routes), std::move(allowed_hosts));
  return routes;
}

}  // namespace bistable
