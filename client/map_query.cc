#include "client/map_query.h"

#include "base/names.h"

#include <algorithm>
#include <filesystem>
#include <map>

#include "client/json_out.h"
#include "engine/query.h"
#include "engine/sweep_state.h"

namespace bistable {

StatusOr<nlohmann::json> QueryJson(const MapSource& src, const std::string& id, const std::string& expr,
                                   size_t max_points) {
  std::string sweep_id, sweep_name;
  auto metrics = src.Metrics(id, &sweep_id, &sweep_name);
  if (!metrics.ok()) return metrics.status();
  std::vector<std::string> vars;
  for (const auto& m : *metrics)
    if (m != "hd_peak_freq" && m != "hd_peak_amp") vars.push_back(m);
  if (vars.empty()) return Status::FailedPrecondition("sweep " + sweep_id + " stores no metric a query can use");
  auto first = src.Metric(sweep_id, vars.front());
  if (!first.ok()) return first.status();
  const std::vector<Axis> axes = first->axes;
  const size_t n_axes_vars = axes.size();
  std::vector<std::string> names;
  for (const Axis& ax : axes) names.push_back(ax.name);
  for (const auto& m : vars) names.push_back(m);
  auto q = Query::Parse(expr, names);
  if (!q.ok()) return q.status();
  // Load only the metrics the query uses; items = points (× ic when present).
  std::map<int, MapArray> loaded;
  size_t n_items = 1, n_points = 1;
  for (const Axis& ax : axes) n_points *= ax.values.size();
  for (int v : q->used()) {
    if (v < static_cast<int>(n_axes_vars)) continue;
    auto m = src.Metric(sweep_id, names[v]);
    if (!m.ok()) return m.status();
    n_items = std::max(n_items, m->values.size());
    loaded.emplace(v, std::move(*m));
  }
  n_items = std::max(n_items, n_points);
  const size_t per_point = n_items / n_points;
  // The item dimension's name as the map file gives it: "ic" (initial conditions) or "direction" (a
  // continuation sweep's up and down chains).
  std::string item_dim = "ic";
  for (const auto& [v, m] : loaded)
    if (m.values.size() == n_items && m.dim_names.size() > axes.size() && m.dim_names[axes.size()] == "direction")
      item_dim = "direction";  // only the two names the project writes: a file's label never renames a key
  nlohmann::json points = nlohmann::json::array();
  auto column = [&](int v) -> const std::vector<double>& { return loaded.at(v).values; };
  const QueryScan scan = ScanQuery(*q, axes, per_point, column, [&](size_t item, const std::vector<size_t>& idx) {
    if (points.size() >= max_points) return;
    nlohmann::json pt = nlohmann::json::object();
    for (size_t k = 0; k < axes.size(); ++k) pt[axes[k].name] = axes[k].values[idx[k]];
    if (per_point > 1) pt[item_dim] = item % per_point;
    for (int v : q->used()) {
      if (v < static_cast<int>(n_axes_vars)) continue;
      const std::vector<double>& m = loaded.at(v).values;
      pt[names[v]] = MetricValueJson(names[v], m.size() == n_items ? m[item] : m[item / per_point]);
    }
    points.push_back(pt);
  });
  return nlohmann::json{{"sweep", sweep_id},
                        {"query", expr},
                        {"count", scan.count},
                        {"total", scan.total},
                        {"fraction", scan.fraction},
                        {"area_fraction", scan.area_fraction},
                        {"truncated", static_cast<long>(points.size()) < static_cast<long>(scan.count)},
                        {"points", points}};
}

nlohmann::json LocalSweepsJson(IndexDb& db, const std::vector<SweepRow>& rows, const std::string& data_dir) {
  nlohmann::json arr = nlohmann::json::array();
  for (const SweepRow& r : rows) {
    nlohmann::json maps = nlohmann::json::array();
    if (auto ms = db.ListMaps(r.id); ms.ok())
      for (const MapRow& m : *ms)
        maps.push_back({{"metric", m.metric},
                        {"shape", m.shape},
                        {"min", MetricNumberJson(m.metric, m.min)},
                        {"max", MetricNumberJson(m.metric, m.max)}});
    arr.push_back({{"id", r.id},
                   {"name", r.name},
                   {"model", r.model},
                   {"status", SweepStateName(r.state)},
                   {"items_total", r.items_total},
                   {"items_done", r.items_done},
                   {"file", r.file.empty() ? nlohmann::json(nullptr)
                                           : nlohmann::json((std::filesystem::path(data_dir) / r.file).string())},
                   {"created", JsonTime(r.created)},
                   {"finished", JsonTime(r.finished)},
                   {"seconds", r.seconds},
                   {"maps", maps}});
  }
  return arr;
}

Status CheckDataDirOrAbsent(const std::string& data_dir) {
  std::error_code ec;
  const auto st = std::filesystem::status(data_dir, ec);
  if (std::filesystem::exists(st) && !std::filesystem::is_directory(st))
    return Status::InvalidArgument(
        "data",
        "'" + Printable(data_dir, 200) + "' is not a directory (a data directory holds index.sqlite and sweeps/)");
  return Status::Ok();
}

StatusOr<nlohmann::json> LocalSweepsJson(const std::string& data_dir) {
  BISTABLE_RETURN_IF_ERROR(CheckDataDirOrAbsent(data_dir));
  const auto index = std::filesystem::path(data_dir) / "index.sqlite";
  if (!std::filesystem::exists(index)) return nlohmann::json::array();
  auto db = IndexDb::Open(index.string());
  if (!db.ok()) return db.status();
  auto rows = (*db)->ListSweeps();
  if (!rows.ok()) return rows.status();
  return LocalSweepsJson(**db, *rows, data_dir);
}

}  // namespace bistable
