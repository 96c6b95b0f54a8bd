// `bistable sweeps`, `bistable map`, `bistable query`, `bistable info`: reading what sweeps stored.
#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cctype>
#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <functional>
#include <iostream>
#include <memory>
#include <random>

#include <nlohmann/json.hpp>

#include "base/file.h"
#include "base/names.h"
#include "client/cli_common.h"
#include "client/json_out.h"
#include "client/map_marks.h"
#include "client/map_query.h"
#include "client/map_slice.h"
#include "client/map_source.h"
#include "client/plot.h"
#include "client/sweep_commands.h"
#include "dynamics/host_lanes.h"
#include "engine/json_shapes.h"
#include "engine/metric_catalog.h"
#include "engine/query.h"
#include "proto/coordinator_client.h"
#include "storage/data_dir.h"
#include "storage/map_file.h"
#include "storage/metric_name.h"

namespace bistable {
namespace {

// ---- sweeps ----
struct SweepsArgs {
  std::string data = kDefaultDataDir;
  MapSource src;  // src.coordinator non-empty: list a coordinator's sweeps
  bool json = false;
};

// The sweeps a coordinator holds (ListSweeps over gRPC), in the same table and JSON as a data dir's.
int ListRemoteSweeps(const SweepsArgs& a) {
  auto token = LoadToken(a.src.token_file);
  if (!token.ok()) return Fail(token.status());
  auto client = CoordinatorClient::Connect({a.src.coordinator, a.src.tls_ca, *token, a.src.insecure_remote});
  if (!client.ok()) return Fail(client.status());
  auto sweeps = (*client)->ListSweeps();
  if (!sweeps.ok()) return Fail(sweeps.status());
  if (a.json) {
    nlohmann::json arr = nlohmann::json::array();
    for (const SweepInfo& s : *sweeps) arr.push_back(RemoteSweepJson(s));
    std::cout << DumpJson(arr, 2) << "\n";
    return 0;
  }
  std::printf("%-12s  %-11s  %-14s  %13s  %8s  %-12s  %s\n", "id", "status", "model", "done/total", "seconds", "owner",
              "name");
  for (const SweepInfo& s : *sweeps) {
    char prog[48];
    std::snprintf(prog, sizeof prog, "%ld/%ld", s.items_done, s.items_total);
    std::printf("%-12.12s  %-11s  %-14s  %13s  %8.1f  %-12s  %s\n", s.id.c_str(), SweepStateName(s.state),
                Printable(s.model, 14).c_str(), prog, s.seconds, Printable(s.owner, 12).c_str(),
                Printable(s.name, 80).c_str());
  }
  return 0;
}

// Map files of the data directory that its index lacks (an empty, missing or damaged index): said, not
// repaired here (a reader does not write; a run or a coordinator's start indexes them again).
void WarnOfUnindexedMaps(IndexDb* db, const std::string& data) {
  auto orphans = UnindexedMapFiles(db, data);
  if (!orphans.ok() || orphans->empty()) return;
  std::cerr << "warning: " << orphans->size() << " map file(s) of '"
            << (std::filesystem::path(data) / "sweeps").string() << "' have no row in '"
            << (std::filesystem::path(data) / "index.sqlite").string()
            << "' (an empty, missing or damaged index): a `bistable run` or a coordinator started on this directory "
               "indexes them again\n";
}

int ListSweeps(const SweepsArgs& a) {
  if (!a.src.coordinator.empty()) return ListRemoteSweeps(a);
  if (Status st = CheckDataDirOrAbsent(a.data); !st.ok()) return Fail(st);
  const auto index = std::filesystem::path(a.data) / "index.sqlite";
  if (!std::filesystem::exists(index)) {
    WarnOfUnindexedMaps(nullptr, a.data);
    if (a.json)
      std::cout << "[]\n";
    else
      std::cout << "no sweeps in " << a.data << "\n";
    return 0;
  }
  auto db = IndexDb::Open(index.string());
  if (!db.ok()) return Fail(db.status());
  auto rows = (*db)->ListSweeps();
  if (!rows.ok()) return Fail(rows.status());
  WarnOfUnindexedMaps(db->get(), a.data);
  if (a.json) {
    std::cout << DumpJson(LocalSweepsJson(**db, *rows, a.data), 2) << "\n";
    return 0;
  }
  std::printf("%-12s  %-11s  %-14s  %13s  %8s  %s\n", "id", "status", "model", "done/total", "seconds", "name");
  for (const SweepRow& r : *rows) {
    char prog[48];
    std::snprintf(prog, sizeof prog, "%ld/%ld", r.items_done, r.items_total);
    std::printf("%-12s  %-11s  %-14s  %13s  %8.1f  %s\n", r.id.c_str(), SweepStateName(r.state), r.model.c_str(), prog,
                r.seconds, r.name.c_str());
  }
  return 0;
}

// ---- map ----
struct MapArgs {
  std::string id, metric, at, format = "json", out, data = kDefaultDataDir;
  std::vector<std::string> mark;  // --mark X,Y,LABEL (repeatable)
  std::string marks;              // --marks FILE.csv
  MapSource src;
};

// A published sweep as seen through a MapSource: its resolved id and name.
struct SweepRefLite {
  std::string id, name;
};

// The metric is checked against the map's own list before any dataset is opened (or asked for).
StatusOr<MapArray> LoadMetric(const MapSource& src, const std::string& id, const std::string& metric, SweepRefLite* ref,
                              const std::vector<std::string>& extra = {}) {
  auto names = src.Metrics(id, &ref->id, &ref->name);
  if (!names.ok()) return names.status();
  BISTABLE_RETURN_IF_ERROR(CheckMetricName(metric, *names, extra));
  return src.Metric(ref->id, metric);
}

// --out - is standard output (for every format); a file literally named "-" is ./-.
bool IsStdout(const std::string& out) { return out == "-"; }

// Text formats: to standard output, or into the file (its directory must exist; the file is written
// beside and renamed).
Status WriteOut(const std::string& path, const std::string& text) { return WriteTextOut(path, text, "out"); }

// A plot for --out -: `render` draws it into a private temporary directory, whose file's bytes then go
// to standard output (never PNG bytes onto a terminal). Otherwise `render` writes `out` and its path
// is printed.
Status PlotOut(const std::string& out, const std::string& format,
               const std::function<Status(const std::string&)>& render) {
  if (!IsStdout(out)) {
    BISTABLE_RETURN_IF_ERROR(render(out));
    std::cout << out << "\n";
    return Status::Ok();
  }
  if ((format == "png" || format == "pdf") && ::isatty(STDOUT_FILENO))
    return Status::InvalidArgument("out", "--out - would write " + std::string(format == "png" ? "PNG" : "PDF") +
                                              " bytes to a terminal; redirect standard output (> map." + format +
                                              ") or give a file name");
  const char* tmpdir = std::getenv("TMPDIR");
  const std::string parent = tmpdir && *tmpdir ? tmpdir : "/tmp";
  std::string dir = parent + "/bistable-plot-XXXXXX";
  if (!::mkdtemp(dir.data()))
    return Status::IoError("out", "cannot create a temporary directory for the plot in '" + Printable(parent) +
                                      "': " + std::strerror(errno));
  struct RemoveDir {
    std::string dir;
    ~RemoveDir() {
      std::error_code ec;
      std::filesystem::remove_all(dir, ec);
    }
  } remove{dir};
  const std::string file = dir + "/plot." + format;
  BISTABLE_RETURN_IF_ERROR(render(file));
  auto bytes = ReadTextFile(file, "out");
  if (!bytes.ok()) return bytes.status();
  return WriteStdout(*bytes, "out");
}

nlohmann::json NestedValues(const Slice& s) {
  if (s.free.size() == 1) {
    nlohmann::json v = nlohmann::json::array();
    for (double x : s.values) v.push_back(MetricValueJson(s.metric, x));
    return v;
  }
  nlohmann::json rows = nlohmann::json::array();
  const size_t nx = s.free[1].values.size();
  for (size_t i = 0; i < s.free[0].values.size(); ++i) {
    nlohmann::json row = nlohmann::json::array();
    for (size_t j = 0; j < nx; ++j) row.push_back(MetricValueJson(s.metric, s.values[i * nx + j]));
    rows.push_back(row);
  }
  return rows;
}

// --at values off the grid take the nearest grid value, said on stderr (SnapAtToGrid).
Status SnapAt(const MapArray& m, std::map<std::string, double>* at) {
  auto notes = SnapAtToGrid(m, at);
  if (!notes.ok()) return notes.status();
  for (const std::string& note : *notes) std::cerr << "map: " << note << "\n";
  return Status::Ok();
}

int HdScatter(const MapArgs& a) {
  SweepRefLite ref;
  auto f = LoadMetric(a.src, a.id, "hd_peak_freq", &ref);
  if (!f.ok()) return Fail(f.status());
  auto amp = a.src.Metric(ref.id, "hd_peak_amp");
  if (!amp.ok()) return Fail(amp.status());
  auto at = ParseAt(a.at);
  if (!at.ok()) return Fail(at.status());
  if (Status st = SnapAt(*f, &at.value()); !st.ok()) return Fail(st);
  // Fix everything but omega and the peak dimension.
  size_t omega_dim = f->axes.size();
  for (size_t k = 0; k < f->axes.size(); ++k)
    if (f->axes[k].name == "omega") omega_dim = k;
  if (omega_dim == f->axes.size()) return Fail(Status::InvalidArgument("metric", "hd_scatter needs an omega axis"));
  ScatterData sd;
  sd.title = ref.id + ": harmonic diffusion";
  const size_t rank = f->dims.size();
  std::vector<size_t> stride(rank, 1);
  for (long k = static_cast<long>(rank) - 2; k >= 0; --k) stride[k] = stride[k + 1] * f->dims[k + 1];
  size_t base = 0;
  for (size_t k = 0; k + 1 < rank; ++k) {
    if (k == omega_dim) continue;
    const std::string& name = f->dim_names[k];
    size_t idx = 0;
    auto it = at->find(name);
    if (k < f->axes.size()) {
      if (it == at->end() && f->dims[k] > 1)
        return Fail(Status::InvalidArgument("at", "hd_scatter: fix " + name + " with --at " + name + "=value"));
      if (it != at->end()) {
        const auto& v = f->axes[k].values;
        idx = v.size();
        for (size_t i = 0; i < v.size(); ++i)
          if (std::fabs(v[i] - it->second) <= 1e-9 * std::max(1.0, std::fabs(it->second))) idx = i;
        if (idx == v.size()) return Fail(Status::InvalidArgument("at", "--at " + name + " value is not on the axis"));
        sd.title += ", " + name + " = " + PlotNumber(it->second);
      }
    } else if (it != at->end()) {
      idx = static_cast<size_t>(it->second);
    }
    base += idx * stride[k];
  }
  for (size_t i = 0; i < f->dims[omega_dim]; ++i)
    for (size_t j = 0; j < f->dims.back(); ++j) {
      const size_t off = base + i * stride[omega_dim] + j;
      if (std::isfinite(f->values[off]))
        sd.x.push_back(f->axes[omega_dim].values[i]), sd.y.push_back(f->values[off]),
            sd.amp.push_back(amp->values[off]);
    }
  const std::string out = a.out.empty() ? ref.id + "_hd_scatter.png" : a.out;
  Status st = PlotOut(out, "png", [&](const std::string& path) { return RenderHdScatter(sd, path); });
  return st.ok() ? 0 : Fail(st);
}

int ShowMap(const MapArgs& a) {
  if (a.format != "json" && a.format != "csv" && a.format != "png" && a.format != "svg" && a.format != "pdf")
    return Fail(
        Status::InvalidArgument("format", "format = '" + a.format + "' violates format in {csv, json, png, svg, pdf}"));
  // Marks are checked before any map is read, and only figures take them.
  auto marks = ParseMarks(a.mark, a.marks);
  if (!marks.ok()) return Fail(marks.status());
  const std::string mark_field = a.mark.empty() ? "marks" : "mark";
  if (!marks->empty() && a.metric == "hd_scatter")
    return Fail(Status::InvalidArgument(
        mark_field, "--mark and --marks draw on a map's heatmap, not on the hd_scatter figure (peaks over omega)"));
  if (!marks->empty() && (a.format == "json" || a.format == "csv"))
    return Fail(Status::InvalidArgument(
        mark_field, "--mark and --marks draw on a figure: give --format png, svg or pdf (not " + a.format + ")"));
  if (a.metric == "hd_scatter") return HdScatter(a);
  SweepRefLite ref;
  auto m = LoadMetric(a.src, a.id, a.metric, &ref, {"hd_scatter"});
  if (!m.ok()) return Fail(m.status());
  auto at = ParseAt(a.at);
  if (!at.ok()) return Fail(at.status());
  if (Status st = SnapAt(*m, &at.value()); !st.ok()) return Fail(st);
  auto s = SliceMap(*m, *at, 2);
  if (!s.ok()) return Fail(s.status());
  if (a.format == "json") {
    nlohmann::json axes = nlohmann::json::object(), fixed = nlohmann::json::object();
    for (const Axis& ax : s->free) axes[ax.name] = ax.values;
    for (const auto& [k, v] : s->fixed) fixed[k] = v;
    // A category's values print as names (MetricValueJson), which have no unit.
    const bool named = IsCategoryMetric(s->metric);
    nlohmann::json j = {{"metric", s->metric}, {"unit", named ? nlohmann::json(nullptr) : nlohmann::json(s->unit)},
                        {"axes", axes},        {"axis_order", nlohmann::json::array()},
                        {"fixed", fixed},      {"values", NestedValues(*s)},
                        {"sweep", ref.id}};
    for (const Axis& ax : s->free) j["axis_order"].push_back(ax.name);
    const Status st = WriteOut(a.out, DumpJson(j, 1) + "\n");
    return st.ok() ? 0 : Fail(st);
  }
  if (a.format == "csv") {
    std::ostringstream os;
    os.precision(17);
    for (const Axis& ax : s->free) os << ax.name << ",";
    os << s->metric << "\n";
    if (s->free.size() == 1) {
      for (size_t i = 0; i < s->values.size(); ++i) os << s->free[0].values[i] << "," << s->values[i] << "\n";
    } else {
      const size_t nx = s->free[1].values.size();
      for (size_t i = 0; i < s->free[0].values.size(); ++i)
        for (size_t j = 0; j < nx; ++j)
          os << s->free[0].values[i] << "," << s->free[1].values[j] << "," << s->values[i * nx + j] << "\n";
    }
    const Status st = WriteOut(a.out, os.str());
    return st.ok() ? 0 : Fail(st);
  }
  // The figure's subtitle (fixed parameters) and threshold come from the spec stored in a local map
  // file; a coordinator's map gives the name and id alone.
  MapContext context{ref.name, ref.id, {}, NAN};
  if (a.src.coordinator.empty())
    if (auto local = FindSweep(a.src.data_dir, ref.id); local.ok() && !local->map_path.empty())
      context = MapContextOfFile(local->map_path);
  auto d = MapFigure(*m, *at, context);
  if (!d.ok()) return Fail(d.status());
  if (Status st = AddMarks(*marks, &d.value()); !st.ok()) return Fail(st);
  const std::string out = a.out.empty() ? ref.id + "_" + s->metric + "." + a.format : a.out;
  Status st = PlotOut(out, a.format, [&](const std::string& path) { return RenderPlot(*d, path, a.format); });
  return st.ok() ? 0 : Fail(st);
}

// ---- query ----
struct QueryArgs {
  std::string id, expr, data = kDefaultDataDir;
  MapSource src;
  bool json = false;
  std::string limit;  // empty: not given (text: 20 points; --json: every point)
};

// The most points --limit may ask for (docs/limits.md).
constexpr long kMaxQueryLimit = 10'000'000;

// --limit N: decimal digits, 0 ≤ N ≤ kMaxQueryLimit in the text output (0: the count alone), 1 ≤ N with --json.
StatusOr<size_t> QueryLimit(const QueryArgs& a) {
  if (a.limit.empty()) return a.json ? SIZE_MAX : size_t{20};
  const long lo = a.json ? 1 : 0;
  const std::string bound = std::to_string(lo) + " <= --limit <= " + std::to_string(kMaxQueryLimit) +
                            (a.json ? " with --json (without --limit, --json lists every point)" : "");
  const std::string& t = a.limit;
  bool digits = !t.empty() && t.size() <= 18;
  for (size_t i = 0; i < t.size() && digits; ++i)
    digits = std::isdigit(static_cast<unsigned char>(t[i])) || (i == 0 && t[i] == '-' && t.size() > 1);
  const long n = digits ? std::strtol(t.c_str(), nullptr, 10) : -1;
  if (!digits || n < lo || n > kMaxQueryLimit)
    return Status::InvalidArgument("limit", "--limit = " + Printable(t, 64) + " violates " + bound);
  return static_cast<size_t>(n);
}

int RunQuery(const QueryArgs& a) {
  auto limit = QueryLimit(a);
  if (!limit.ok()) return Fail(limit.status());
  auto j = QueryJson(a.src, a.id, a.expr, *limit);
  if (!j.ok()) return Fail(j.status());
  if (a.json) {
    std::cout << DumpJson(*j, 1) << "\n";
    return 0;
  }
  const long count = (*j)["count"].get<long>();
  std::printf("%ld of %zu points match (%.2f%% of points, %.2f%% of the grid's area): %s\n", count,
              (*j)["total"].get<size_t>(), 100 * (*j)["fraction"].get<double>(),
              100 * (*j)["area_fraction"].get<double>(), a.expr.c_str());
  for (const auto& pt : (*j)["points"]) std::cout << "  " << DumpJson(pt) << "\n";
  if (count > static_cast<long>((*j)["points"].size()))
    std::printf("  ... (%ld more; --json lists all)\n", count - static_cast<long>((*j)["points"].size()));
  return 0;
}

// ---- info ----
struct InfoArgs {
  std::string id, data = kDefaultDataDir;
  bool json = false;
};

// The provenance `bistable info ID` prints, in this order (docs/map-files.md).
constexpr const char* kProvenance[] = {"sweep_id",         "name",    "model",          "software_version",
                                       "numerics_version", "history", "host_cpu_model", "host_simd_isa",
                                       "host_lane_width"};

int ShowInfo(const InfoArgs& a) {
  if (a.id.empty()) {  // this build on this CPU
    const HostLanes h = ThisHostLanes();
    if (a.json)
      std::cout << DumpJson({{"cpu_model", h.cpu_model},
                             {"simd_isa", h.isa},
                             {"cpu_simd_isa", h.cpu_isa},
                             {"march", h.march},
                             {"lane_width", h.lanes}},
                            2)
                << "\n";
    else
      std::cout << HostLanesLine(h) << "\n";
    return 0;
  }
  std::string path;
  std::error_code ec;
  if (a.id.size() > 3 && a.id.compare(a.id.size() - 3, 3, ".h5") == 0 && std::filesystem::is_regular_file(a.id, ec)) {
    path = a.id;
  } else {
    auto ref = FindSweep(a.data, a.id);
    if (!ref.ok()) return Fail(ref.status());
    if (ref->map_path.empty())
      return Fail(Status::FailedPrecondition("sweep " + ref->row.id + " has no published map yet (state " +
                                             SweepStateName(ref->row.state) + ")"));
    path = ref->map_path;
  }
  nlohmann::json j = {{"file", path}};
  for (const char* name : kProvenance) {
    auto v = ReadMapAttribute(path, name);
    if (!v.ok()) return Fail(v.status());
    // Absent in maps written before the attribute was: null, and "(not recorded)" in the text.
    if (v->empty())
      j[name] = nullptr;
    else if (std::string(name) == "host_lane_width")
      j[name] = std::atoi(v->c_str());
    else
      j[name] = *v;
  }
  if (a.json) {
    std::cout << DumpJson(j, 2) << "\n";
    return 0;
  }
  std::printf("%-17s %s\n", "file", Printable(path, 400).c_str());
  for (const char* name : kProvenance) {
    const nlohmann::json& v = j[name];
    std::printf("%-17s %s\n", name,
                v.is_null()     ? "(not recorded)"
                : v.is_string() ? Printable(v.get<std::string>(), 400).c_str()
                                : v.dump().c_str());
  }
  return 0;
}

}  // namespace

void AddInfoCommand(CLI::App& app, int* exit_code) {
  auto a = std::make_shared<InfoArgs>();
  CLI::App* cmd = app.add_subcommand(
      "info",
      "Where a map was made (versions, time, the writing host's CPU, ISA and lane width); without an id, this "
      "build's lanes on this CPU");
  cmd->add_option("id", a->id,
                  "sweep id (or a unique prefix) of --data, or a map file (.h5); none: this build and CPU");
  cmd->add_option("--data", a->data, "data directory")->capture_default_str();
  cmd->add_flag("--json", a->json, "print a JSON object");
  cmd->callback([a, exit_code]() { *exit_code = ShowInfo(*a); });
}

void AddSweepsCommand(CLI::App& app, int* exit_code) {
  auto a = std::make_shared<SweepsArgs>();
  CLI::App* cmd = app.add_subcommand("sweeps", "List the sweeps in a data directory, or on a coordinator");
  cmd->add_option("--data", a->data, "data directory")->capture_default_str();
  cmd->add_option("--coordinator", a->src.coordinator, "list a coordinator's sweeps instead of --data");
  cmd->add_option("--token-file", a->src.token_file, "bearer token file (else $BISTABLE_TOKEN)");
  cmd->add_option("--tls-ca", a->src.tls_ca, "PEM CA of a TLS coordinator");
  cmd->add_flag("--insecure-remote", a->src.insecure_remote,
                "send the token in plaintext to an address that is not loopback (refused otherwise)");
  cmd->add_flag("--json", a->json, "print a JSON array");
  cmd->callback([a, exit_code]() { *exit_code = ListSweeps(*a); });
}

void AddMapCommand(CLI::App& app, int* exit_code) {
  auto a = std::make_shared<MapArgs>();
  CLI::App* cmd = app.add_subcommand("map", "Print or plot a metric of a sweep over one or two free axes");
  cmd->add_option("id", a->id, "sweep id (or a unique prefix)")->required();
  cmd->add_option("--metric", a->metric, "metric (frf_db, lle, motion, edr_t, ...; hd_scatter for Fig. 6)")->required();
  cmd->add_option("--at", a->at,
                  "fix axes: eta=0.1,lambda=0.8 (ic=K for a multi-IC sweep; default ic=0); a value off the grid takes "
                  "the nearest grid value (said on stderr), one beyond the axis's range by more than half a grid step "
                  "is refused");
  cmd->add_option("--format", a->format, "csv | json | png | svg | pdf")->capture_default_str();
  cmd->add_option("--mark", a->mark,
                  "mark a measurement on the figure (png/svg/pdf of a map with two free axes; repeatable): "
                  "X on the horizontal axis (the map's second free axis, omega on an alpha x omega map), Y on the "
                  "vertical (the first free axis, alpha), in the axes' units, inside the drawn range (else refused); "
                  "LABEL plain text beside the point, at most 80 printable characters, shown literally (may hold "
                  "commas; \"...\" CSV quoting). At most 200 marks with --marks")
      ->type_name("X,Y,LABEL")
      ->allow_extra_args(false)
      ->multi_option_policy(CLI::MultiOptionPolicy::TakeAll);
  cmd->add_option("--marks", a->marks,
                  "marks from a CSV file of rows x,y,label (as --mark; a header row x,y,label, blank lines and lines "
                  "starting with # skipped; at most 1 MiB)")
      ->type_name("FILE.csv");
  cmd->add_option(
      "--out", a->out,
      "output file; - is stdout, for plots too (default: stdout for csv/json, <id>_<metric>.<fmt> for plots)");
  cmd->add_option("--data", a->data, "data directory")->capture_default_str();
  cmd->add_option("--coordinator", a->src.coordinator, "read from a coordinator instead of --data");
  cmd->add_option("--token-file", a->src.token_file, "bearer token file (else $BISTABLE_TOKEN)");
  cmd->add_option("--tls-ca", a->src.tls_ca, "PEM CA of a TLS coordinator");
  cmd->add_flag("--insecure-remote", a->src.insecure_remote,
                "send the token in plaintext to an address that is not loopback (refused otherwise)");
  cmd->callback([a, exit_code]() {
    a->src.data_dir = a->data;
    *exit_code = ShowMap(*a);
  });
}

void AddQueryCommand(CLI::App& app, int* exit_code) {
  auto a = std::make_shared<QueryArgs>();
  CLI::App* cmd = app.add_subcommand("query", "Find the region of a map where a condition holds");
  cmd->add_option("id", a->id, "sweep id (or a unique prefix)")->required();
  cmd->add_option("expr", a->expr, "e.g. \"frf_db < -3 and lle < 0.01\" or \"motion == chaotic\"")->required();
  cmd->add_option("--data", a->data, "data directory")->capture_default_str();
  cmd->add_option("--limit", a->limit,
                  "points listed: the text output lists the first N matches (default 20; 0: the count alone) and "
                  "says how many more; --json lists every match unless --limit N is given (1 <= N <= 10000000), "
                  "then the first N, with \"count\" every match and \"truncated\": true when the list was cut");
  cmd->add_flag("--json", a->json, "print {count, total, fraction, area_fraction, truncated, points} as JSON");
  cmd->add_option("--coordinator", a->src.coordinator, "read from a coordinator instead of --data");
  cmd->add_option("--token-file", a->src.token_file, "bearer token file (else $BISTABLE_TOKEN)");
  cmd->add_option("--tls-ca", a->src.tls_ca, "PEM CA of a TLS coordinator");
  cmd->add_flag("--insecure-remote", a->src.insecure_remote,
                "send the token in plaintext to an address that is not loopback (refused otherwise)");
  cmd->callback([a, exit_code]() {
    a->src.data_dir = a->data;
    *exit_code = RunQuery(*a);
  });
}

}  // namespace bistable
