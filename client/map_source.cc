#include "client/map_source.h"

#include <filesystem>

#include "base/limits.h"
#include "base/names.h"
#include "bistable.grpc.pb.h"
#include "client/cli_common.h"
#include "proto/status_convert.h"
#include "storage/metric_name.h"

namespace bistable {
namespace {

StatusOr<ConnectOptions> Connection(const MapSource& s) {
  auto token = LoadToken(s.token_file);
  if (!token.ok()) return token.status();
  return ConnectOptions{s.coordinator, s.tls_ca, *token};
}

// A metric name is a plain dataset name: never sent or opened when it could be an HDF5 path. (Which
// names a map holds is checked against its list: LoadMetric in map_commands.cc, ReadMapMetric.)
Status CheckPlainMetricName(const std::string& metric) {
  const bool plain = !metric.empty() && metric.size() <= limits::kMaxMetricNameBytes && metric != "." && metric != ".." &&
                     metric.find_first_of(std::string("/\0\n\r", 4)) == std::string::npos;
  if (plain) return Status::Ok();
  return Status::InvalidArgument("metric", "metric '" + Printable(metric) +
                                               "' is not a metric name (a metric is a dataset name of the map: no '/', "
                                               "'.', '..', NUL or newline, at most 64 bytes)");
}

Status Remote(const grpc::Status& st, const std::string& addr) {
  if (st.error_code() == grpc::StatusCode::UNAVAILABLE || st.error_code() == grpc::StatusCode::DEADLINE_EXCEEDED)
    return Status::IoError("coordinator", "cannot reach " + addr + " (" + st.error_message() + ")");
  return FromGrpcStatus(st);
}

}  // namespace

StatusOr<std::vector<std::string>> MapSource::Metrics(const std::string& id_or_prefix, std::string* id, std::string* name) const {
  if (coordinator.empty()) {
    auto ref = FindSweep(data_dir, id_or_prefix);
    if (!ref.ok()) return ref.status();
    *id = ref->row.id;
    *name = ref->row.name;
    if (ref->map_path.empty())
      return Status::FailedPrecondition("sweep " + ref->row.id + " has no published map yet (state " + SweepStateName(ref->row.state) + ")");
    return ListMapMetrics(ref->map_path);
  }
  auto conn = Connection(*this);
  if (!conn.ok()) return conn.status();
  auto ch = MakeChannel(*conn);
  if (!ch.ok()) return ch.status();
  v1::MapRequest req;
  req.set_id(id_or_prefix);
  v1::MetricsReply rep;
  const grpc::Status st = v1::Coordinator::NewStub(*ch)->ListMetrics(CallContext(*conn, 60).get(), req, &rep);
  if (!st.ok()) return Remote(st, coordinator);
  *id = rep.id();
  *name = rep.name();
  return std::vector<std::string>(rep.metrics().begin(), rep.metrics().end());
}

StatusOr<MapArray> MapSource::Metric(const std::string& id, const std::string& metric) const {
  BISTABLE_RETURN_IF_ERROR(CheckPlainMetricName(metric));
  if (coordinator.empty()) {
    auto ref = FindSweep(data_dir, id);
    if (!ref.ok()) return ref.status();
    if (ref->map_path.empty())
      return Status::FailedPrecondition("sweep " + ref->row.id + " has no published map yet (state " + SweepStateName(ref->row.state) +
                                        ", " + std::to_string(ref->row.points_done) + "/" + std::to_string(ref->row.points_total) +
                                        " stored); rerun it to finish");
    return ReadMapMetric(ref->map_path, metric);
  }
  auto conn = Connection(*this);
  if (!conn.ok()) return conn.status();
  auto ch = MakeChannel(*conn);
  if (!ch.ok()) return ch.status();
  v1::MapRequest req;
  req.set_id(id);
  req.set_metric(metric);
  v1::MapReply rep;
  const grpc::Status st = v1::Coordinator::NewStub(*ch)->GetMap(CallContext(*conn, 120).get(), req, &rep);
  if (!st.ok()) return Remote(st, coordinator);
  MapArray m;
  m.metric = rep.metric();
  m.unit = rep.unit();
  m.definition = rep.definition();
  for (const auto& a : rep.axes()) m.axes.push_back(Axis{a.name(), std::vector<double>(a.values().begin(), a.values().end())});
  for (auto d : rep.dims()) m.dims.push_back(d);
  m.dim_names.assign(rep.dim_names().begin(), rep.dim_names().end());
  m.values.assign(rep.values().begin(), rep.values().end());
  return m;
}

}  // namespace bistable
