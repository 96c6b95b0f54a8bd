#include "server/dashboard.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <limits>

#include <nlohmann/json.hpp>

#include "base/limits.h"
#include "dynamics/point.h"
#include "dynamics/spectrum.h"
#include "engine/json_shapes.h"
#include "engine/query.h"
#include "server/embedded_files.h"
#include "storage/map_file.h"

namespace bistable {
namespace {

using nlohmann::json;

// Bounds of what one answer carries (the page draws at most this much).
constexpr size_t kMaxSliceCells = 1 << 20;     // a map slice: 1024 × 1024 cells
constexpr size_t kMaxSeriesRows = 4000;        // time series rows of a cell (decimated)
constexpr size_t kMaxSpectrumBins = 4000;      // spectrum bins of a cell (the low end)
constexpr size_t kMaxSectionPoints = 5000;     // Poincaré section points of a cell
constexpr size_t kMaxParamBytes = 64;          // id, metric, axis names, numbers
constexpr int kSessionSeconds = 12 * 3600;     // the token cookie's lifetime

HttpResponse Json(const json& j, int status = 200) {
  return {status, "application/json", j.dump(-1, ' ', false, json::error_handler_t::replace), {}};
}

HttpResponse Error(const Status& st) {
  int code = 500;
  switch (st.code()) {
    case Status::Code::kInvalidArgument: code = 400; break;
    case Status::Code::kNotFound: code = 404; break;
    case Status::Code::kFailedPrecondition: code = 409; break;
    case Status::Code::kUnauthenticated: code = 401; break;
    case Status::Code::kPermissionDenied: code = 403; break;
    default: break;
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

// Metrics a map view offers: the sweep's stored scalar metrics of the catalog.
std::vector<std::string> MapMetrics(const SweepSpec& spec) {
  std::vector<std::string> out;
  for (const std::string& m : spec.metrics)
    if (FindMetric(m)) out.push_back(m);
  return out;
}

json CategoriesJson(const std::vector<std::pair<int, std::string>>& cats) {
  json out = json::array();
  for (const auto& [code, name] : cats) out.push_back({code, name});
  return out;
}

// A metric over the sweep's items: the published map file, or what is stored so far of a planned sweep.
StatusOr<MapArray> LoadMetric(SweepCoordinator* c, const SweepView& s, const std::string& metric, bool* partial) {
  const auto offered = MapMetrics(s.spec);
  if (std::find(offered.begin(), offered.end(), metric) == offered.end())
    return Status::InvalidArgument("metric", "sweep " + s.id + " stores no metric '" + metric.substr(0, 32) + "'");
  const MetricInfo* info = FindMetric(metric);
  *partial = false;
  if (!s.info.file.empty() && s.info.state == SweepState::kDone) {
    auto a = ReadMapMetric((std::filesystem::path(c->data_dir()) / s.info.file).string(), metric);
    if (!a.ok()) return a.status();
    if (a->dims.size() != a->axes.size() && a->dims.size() != a->axes.size() + 1)
      return Status::FailedPrecondition("metric '" + metric + "' is not one value per item");
    return a;
  }
  auto values = c->StoredValues(s.id, metric);
  if (!values.ok()) return Status::NotFound("sweep " + s.id + " has no map yet (state " + SweepStateName(s.info.state) + ")");
  MapArray a;
  a.metric = metric;
  a.axes = s.spec.axes;
  for (const Axis& ax : a.axes) a.dims.push_back(ax.values.size()), a.dim_names.push_back(ax.name);
  if (s.spec.ic_count() > 1) a.dims.push_back(static_cast<size_t>(s.spec.ic_count())), a.dim_names.push_back("ic");
  a.values = std::move(*values);
  a.unit = info->unit;
  a.definition = info->definition;
  for (const Category& k : MetricCategories(metric)) a.categories.push_back({k.code, k.name});
  *partial = true;
  return a;
}

// Which cells a slice shows: x (and y) axis, every other dimension fixed by "at" = "name:index,...".
struct Slice {
  int x = -1, y = -1;           // dimension indices (y = -1: a one-axis slice)
  std::vector<size_t> fixed;    // index of every dimension (x and y ignored)
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
    if (s.x < 0 || s.x >= static_cast<int>(a.axes.size())) return Status::InvalidArgument("x", "x is not an axis of the sweep");
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
  const size_t nx = s.x >= 0 ? a.dims[s.x] : 1, ny = s.y >= 0 ? a.dims[s.y] : 1;
  if (nx * ny > kMaxSliceCells) return Status::InvalidArgument("x", "the slice has more than 2^20 cells");
  return s;
}

// Flat index into a.values of the cell (ix, iy) of a slice.
size_t FlatIndex(const MapArray& a, const Slice& s, size_t ix, size_t iy) {
  size_t flat = 0;
  for (size_t d = 0; d < a.dims.size(); ++d) {
    const size_t i = static_cast<int>(d) == s.x ? ix : static_cast<int>(d) == s.y ? iy : s.fixed[d];
    flat = flat * a.dims[d] + i;
  }
  return flat;
}

json AxisJson(const Axis& ax) { return {{"name", ax.name}, {"unit", AxisUnit(ax.name)}, {"values", ax.values}}; }

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
    j["eta_seconds"] = rate > 0 && !IsFinal(s.state) ? json(static_cast<double>(s.items_total - s.items_done) / rate) : json(nullptr);
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
  for (const std::string& m : MapMetrics(s->spec)) {
    const MetricInfo* info = FindMetric(m);
    std::vector<std::pair<int, std::string>> cats;
    for (const Category& k : MetricCategories(m)) cats.push_back({k.code, k.name});
    metrics.push_back({{"name", m}, {"unit", info->unit}, {"definition", info->definition}, {"integer", info->integer},
                       {"categories", CategoriesJson(cats)}});
  }
  json axes = json::array();
  for (const Axis& ax : s->spec.axes) axes.push_back(AxisJson(ax));
  std::string cell_note;
  if (!IsCellModel(s->spec.model)) cell_note = "cells of " + s->spec.ModelLabel() + " sweeps cannot be opened (bistable point runs cell models)";
  else if (s->spec.continuation.enabled()) cell_note = "continuation sweeps start each point from the previous one: a cell alone is not that item";
  return Json({{"status", SweepStatusJson(s->info)}, {"spec", s->spec.source}, {"axes", axes}, {"ic_count", s->spec.ic_count()},
               {"metrics", metrics}, {"cells", cell_note.empty()}, {"cell_note", cell_note}});
}

HttpResponse MapRoute(SweepCoordinator* c, const HttpRequest& req) {
  auto p = Params(req);
  if (!p.ok()) return Error(p.status());
  auto s = ResolveSweep(c, *p);
  if (!s.ok()) return Error(s.status());
  bool partial = false;
  auto a = LoadMetric(c, *s, Get(*p, "metric"), &partial);
  if (!a.ok()) return Error(a.status());
  auto sl = ParseSlice(*p, *a);
  if (!sl.ok()) return Error(sl.status());
  const size_t nx = sl->x >= 0 ? a->dims[sl->x] : 1, ny = sl->y >= 0 ? a->dims[sl->y] : 1;
  json values = json::array();
  double lo = NAN, hi = NAN;
  for (size_t iy = 0; iy < ny; ++iy)
    for (size_t ix = 0; ix < nx; ++ix) values.push_back(JsonNumber(a->values[FlatIndex(*a, *sl, ix, iy)]));
  for (double v : a->values)  // one colour range for every slice of the metric
    if (std::isfinite(v)) lo = std::isnan(lo) ? v : std::min(lo, v), hi = std::isnan(hi) ? v : std::max(hi, v);
  json dims = json::array();
  for (size_t d = 0; d < a->dims.size(); ++d) dims.push_back({{"name", a->dim_names[d]}, {"size", a->dims[d]}});
  return Json({{"sweep", s->id}, {"metric", a->metric}, {"unit", a->unit}, {"partial", partial},
               {"x", sl->x >= 0 ? AxisJson(a->axes[sl->x]) : json(nullptr)},
               {"y", sl->y >= 0 ? AxisJson(a->axes[sl->y]) : json(nullptr)}, {"dims", dims},
               {"categories", CategoriesJson(a->categories)}, {"min", JsonNumber(lo)}, {"max", JsonNumber(hi)},
               {"values", values}});
}

HttpResponse QueryRoute(SweepCoordinator* c, const HttpRequest& req) {
  auto p = Params(req);
  if (!p.ok()) return Error(p.status());
  auto s = ResolveSweep(c, *p);
  if (!s.ok()) return Error(s.status());
  std::vector<std::string> names;
  for (const Axis& ax : s->spec.axes) names.push_back(ax.name);
  const auto metrics = MapMetrics(s->spec);
  for (const std::string& m : metrics) names.push_back(m);
  auto q = Query::Parse(Get(*p, "q"), names);
  if (!q.ok()) return Error(q.status());
  std::map<int, MapArray> loaded;
  bool partial = false;
  for (int v : q->used()) {
    if (v < static_cast<int>(s->spec.axes.size())) continue;
    auto a = LoadMetric(c, *s, names[v], &partial);
    if (!a.ok()) return Error(a.status());
    loaded.emplace(v, std::move(*a));
  }
  // The slice shown (the same parameters as /api/map) picks the cells to mark.
  MapArray shape;
  shape.axes = s->spec.axes;
  for (const Axis& ax : shape.axes) shape.dims.push_back(ax.values.size()), shape.dim_names.push_back(ax.name);
  const size_t per_point = static_cast<size_t>(s->spec.ic_count());
  if (per_point > 1) shape.dims.push_back(per_point), shape.dim_names.push_back("ic");
  auto sl = ParseSlice(*p, shape);
  if (!sl.ok()) return Error(sl.status());
  const size_t nx = sl->x >= 0 ? shape.dims[sl->x] : 1, ny = sl->y >= 0 ? shape.dims[sl->y] : 1;
  std::vector<int> mask(nx * ny, 0);
  auto column = [&](int v) -> const std::vector<double>& { return loaded.at(v).values; };
  const QueryScan scan = ScanQuery(*q, s->spec.axes, per_point, column, [&](size_t item, const std::vector<size_t>& idx) {
    for (size_t d = 0; d < s->spec.axes.size(); ++d)
      if (static_cast<int>(d) != sl->x && static_cast<int>(d) != sl->y && idx[d] != sl->fixed[d]) return;
    if (per_point > 1 && item % per_point != sl->fixed.back()) return;
    mask[(sl->y >= 0 ? idx[sl->y] * nx : 0) + (sl->x >= 0 ? idx[sl->x] : 0)] = 1;
  });
  return Json({{"sweep", s->id}, {"count", scan.count}, {"total", scan.total}, {"fraction", scan.fraction},
               {"area_fraction", scan.area_fraction}, {"partial", partial}, {"mask", mask}});
}

std::string Num(double v) {
  char b[40];
  std::snprintf(b, sizeof b, "%.17g", v);
  return b;
}

// The `bistable point` command line that computes this point (every setting it takes); *note says
// what it cannot set when the sweep changed a setting the command has no flag for.
std::string PointCommand(const PointSpec& s, std::string* note) {
  const PointSpec d;
  std::string cmd = "bistable point --json --model " + std::string(ModelName(s.model)) + " --alpha " + Num(s.alpha) +
                    " --omega " + Num(s.omega) + " --eps " + Num(s.params.eps) + " --eta " + Num(s.params.eta);
  if (HasResonator(s.model))
    cmd += " --eta-r " + Num(s.params.eta_r) + " --phi " + Num(s.params.phi) + " --lambda " + Num(s.params.lambda);
  cmd += " --integrator " + std::string(IntegratorName(s.integration.integrator)) + " --dt " + Num(s.integration.dt) +
         " --t-end " + Num(s.integration.t_end) + " --t-keep " + Num(s.integration.t_keep);
  if (s.integration.integrator == IntegratorKind::kAdaptive)
    cmd += " --rtol " + Num(s.integration.rtol) + " --atol " + Num(s.integration.atol);
  if (s.ic_given) cmd += " --ic " + Num(s.ic[0]) + "," + Num(s.ic[1]) + "," + Num(s.ic[2]) + "," + Num(s.ic[3]);
  cmd += " --chaos-threshold " + Num(s.metrics.chaos_threshold) + " --renorm-every " + std::to_string(s.metrics.renorm_every) +
         " --sample-every " + std::to_string(s.metrics.sample_every) + " --poincare-phase " + Num(s.metrics.poincare_phase);
  if (!s.metrics.rosenstein) cmd += " --no-rosenstein";
  if (s.metrics.period_tol != d.metrics.period_tol || s.metrics.max_period != d.metrics.max_period ||
      s.metrics.hd_level != d.metrics.hd_level || s.metrics.hd_top_k != d.metrics.hd_top_k)
    *note = "the sweep sets period_tol, max_period, hd_level or hd_top_k, which bistable point takes no flag for";
  return cmd;
}

HttpResponse CellRoute(SweepCoordinator* c, const HttpRequest& req) {
  auto p = Params(req);
  if (!p.ok()) return Error(p.status());
  auto s = ResolveSweep(c, *p);
  if (!s.ok()) return Error(s.status());
  if (!IsCellModel(s->spec.model) || s->spec.continuation.enabled())
    return Error(Status::FailedPrecondition("cells of this sweep cannot be computed alone (see /api/sweep's cell_note)"));
  auto point = Index(*p, "point", s->spec.points());
  if (!point.ok()) return Error(point.status());
  auto ic = Index(*p, "ic", s->spec.ic_count());
  if (!ic.ok()) return Error(ic.status());
  PointSpec spec = s->spec.PointAt(*point, static_cast<int>(*ic));
  spec.metrics.keep_samples = true;  // the window's rows for the orbit and the series (recorded only)
  auto r = EvaluatePoint(spec);
  if (!r.ok()) return Error(r.status());
  std::string note;
  json j = {{"sweep", s->id}, {"point", *point}, {"ic", *ic}, {"result", PointJson(spec, *r)}};
  j["command"] = PointCommand(spec, &note);
  j["command_note"] = note;
  json at = json::object();
  const std::vector<int> idx = s->spec.AxisIndices(*point);
  for (size_t k = 0; k < s->spec.axes.size(); ++k) at[s->spec.axes[k].name] = s->spec.axes[k].values[idx[k]];
  j["at"] = at;
  // The window: rows τ, y_m, y_m', y_r, y_r' (every k-th so at most kMaxSeriesRows).
  const size_t n = r->samples.size(), step = std::max<size_t>(1, (n + kMaxSeriesRows - 1) / kMaxSeriesRows);
  json series = json::array();
  for (size_t i = 0; i < n; i += step) {
    const auto& row = r->samples[i];
    series.push_back({JsonNumber(row[0]), JsonNumber(row[1]), JsonNumber(row[2]), JsonNumber(row[3]), JsonNumber(row[4])});
  }
  j["series"] = {{"columns", {"tau", "y_m", "dy_m", "y_r", "dy_r"}}, {"every", step}, {"rows", series}};
  // The response spectrum of y_m over the window, as the harmonic-diffusion metrics see it.
  if (n >= 4 && r->termination == Termination::kOk) {
    std::vector<double> y(n);
    for (size_t i = 0; i < n; ++i) y[i] = r->samples[i][1];
    const Spectrum sp = AmplitudeSpectrum(y, SampleStep(spec));
    const size_t bins = std::min(sp.amp.size(), kMaxSpectrumBins);
    j["spectrum"] = {{"d_omega", sp.d_omega}, {"amp", std::vector<double>(sp.amp.begin(), sp.amp.begin() + static_cast<long>(bins))}};
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
  const bool cookie_safe = token.find_first_not_of("0123456789abcdefghijklmnopqrstuvwxyzABCDEFGHIJKLMNOPQRSTUVWXYZ._~-") == std::string::npos;
  if (tokens->enabled() && req.authorization.rfind("Bearer ", 0) == 0 && cookie_safe)
    r.headers.push_back({"Set-Cookie", std::string(kDashboardCookie) + "=" + token + "; Path=/; HttpOnly; SameSite=Strict; Max-Age=" +
                                           std::to_string(kSessionSeconds) + (req.tls ? "; Secure" : "")});
  return r;
}

}  // namespace

std::map<std::string, HttpHandler> DashboardRoutes(SweepCoordinator* c, const TokenStore* tokens) {
  std::map<std::string, HttpHandler> routes;
  for (const EmbeddedFile& f : DashboardAssets()) {
    HttpResponse r{200, std::string(f.content_type), std::string(f.bytes), {}};
    r.headers.push_back({"Content-Security-Policy", "default-src 'self'; img-src 'self' data:; frame-ancestors 'none'"});
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
    r.headers.push_back({"Set-Cookie", std::string(kDashboardCookie) + "=; Path=/; HttpOnly; SameSite=Strict; Max-Age=0"});
    return r;
  };
  routes["/api/sweeps"] = guarded([c](const HttpRequest&) { return SweepsRoute(c); });
  routes["/api/sweep"] = guarded([c](const HttpRequest& req) { return SweepRoute(c, req); });
  routes["/api/map"] = guarded([c](const HttpRequest& req) { return MapRoute(c, req); });
  routes["/api/query"] = guarded([c](const HttpRequest& req) { return QueryRoute(c, req); });
  routes["/api/cell"] = guarded([c](const HttpRequest& req) { return CellRoute(c, req); });
  return routes;
}

}  // namespace bistable
