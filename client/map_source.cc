#include "client/map_source.h"

#include <filesystem>

#include "base/file.h"
#include "base/limits.h"
#include "base/names.h"
#include "client/cli_common.h"
#include "dynamics/cancel.h"
#include "proto/coordinator_client.h"
#include "storage/metric_name.h"

namespace bistable {
namespace {

StatusOr<std::unique_ptr<CoordinatorClient>> Client(const MapSource& s) {
  auto token = LoadToken(s.token_file);
  if (!token.ok()) return token.status();
  return CoordinatorClient::Connect({s.coordinator, s.tls_ca, *token, s.insecure_remote});
}

// A metric name is a plain dataset name: never sent or opened when it could be an HDF5 path. (Which
// names a map holds is checked against its list: LoadMetric in map_commands.cc, ReadMapMetric.)
Status CheckPlainMetricName(const std::string& metric) {
  if (IsPlainMetricName(metric)) return Status::Ok();
  return Status::InvalidArgument("metric", "metric '" + Printable(metric) +
                                               "' is not a metric name (a metric is a dataset name of the map: no '/', "
                                               "'.', '..', NUL or newline, at most 64 bytes)");
}

}  // namespace

StatusOr<std::vector<std::string>> MapSource::Metrics(const std::string& id_or_prefix, std::string* id,
                                                      std::string* name) const {
  if (coordinator.empty()) {
    auto ref = FindSweep(data_dir, id_or_prefix);
    if (!ref.ok()) return ref.status();
    *id = ref->row.id;
    *name = ref->row.name;
    if (ref->map_path.empty())
      return Status::FailedPrecondition("sweep " + ref->row.id + " has no published map yet (state " +
                                        SweepStateName(ref->row.state) + ")");
    return ListMapMetrics(ref->map_path);
  }
  auto client = Client(*this);
  if (!client.ok()) return client.status();
  auto list = (*client)->ListMetrics(id_or_prefix);
  if (!list.ok()) return list.status();
  *id = list->id;
  *name = list->name;
  return list->metrics;
}

StatusOr<MapArray> MapSource::Metric(const std::string& id, const std::string& metric) const {
  BISTABLE_RETURN_IF_ERROR(CheckPlainMetricName(metric));
  if (coordinator.empty()) {
    auto ref = FindSweep(data_dir, id);
    if (!ref.ok()) return ref.status();
    if (ref->map_path.empty())
      return Status::FailedPrecondition("sweep " + ref->row.id + " has no published map yet (state " +
                                        SweepStateName(ref->row.state) + ", " + std::to_string(ref->row.items_done) +
                                        "/" + std::to_string(ref->row.items_total) + " stored); rerun it to finish");
    return ReadMapMetric(ref->map_path, metric);
  }
  auto client = Client(*this);
  if (!client.ok()) return client.status();
  return (*client)->GetMap(id, metric);
}

Status CheckFetchOut(const std::string& out) {
  return NotStdout(out, "out", "--out",
                   "a fetched map is written to a file and checked (SHA-256) before it is renamed into place");
}

StatusOr<nlohmann::json> FetchMapFile(CoordinatorClient& c, const std::string& id, const std::string& out) {
  BISTABLE_RETURN_IF_ERROR(CheckFetchOut(out));
  std::unique_ptr<AtomicFile> file;
  auto fetched = c.FetchMap(id, [&](std::string_view data) -> Status {
    if (CancelRequested()) return Status::IoError("fetch", "interrupted");
    if (!file) {
      auto f = AtomicFile::Create(out, "out");
      if (!f.ok()) return f.status();
      file = std::move(f).value();
    }
    return file->Write(data);
  });
  if (!fetched.ok()) return fetched.status();
  if (!file) {  // an empty file: nothing was written yet
    auto f = AtomicFile::Create(out, "out");
    if (!f.ok()) return f.status();
    file = std::move(f).value();
  }
  BISTABLE_RETURN_IF_ERROR(file->Commit());
  return nlohmann::json{{"id", fetched->id}, {"file", out}, {"bytes", fetched->bytes}, {"sha256", fetched->sha256}};
}

}  // namespace bistable
