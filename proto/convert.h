// Every conversion between the project's types and the wire's messages (proto/bistable.proto), in one
// place: the service and the clients (CLI, worker) both go through these.
#ifndef BISTABLE_PROTO_CONVERT_H_
#define BISTABLE_PROTO_CONVERT_H_

#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "base/status.h"
#include "bistable.pb.h"
#include "engine/map_array.h"
#include "engine/metric_catalog.h"
#include "engine/sweep_spec.h"
#include "engine/sweep_state.h"

namespace bistable {

void ToProto(const SweepInfo& in, v1::SweepStatus* out);
SweepInfo FromProto(const v1::SweepStatus& in);  // an unknown state name reads as failed

void ToProto(const WorkerInfo& in, v1::WorkerStatus* out);
WorkerInfo FromProto(const v1::WorkerStatus& in);

void ToProto(const MapArray& in, v1::MapReply* out);  // axis units from AxisUnit
MapArray FromProto(const v1::MapReply& in);

// A lease's items (grid points and their initial-condition slots).
void ToProto(const std::vector<WorkItem>& items, v1::LeaseReply* out);
StatusOr<std::vector<WorkItem>> ItemsFromProto(const v1::LeaseReply& in);  // points and ics of equal length

// A submitted sweep's plan (SubmitReply).
struct SubmitResult {
  std::string id;
  long items_total = 0, items_cached = 0, jobs = 0;
};
void ToProto(const SubmitResult& in, v1::SubmitReply* out);
SubmitResult FromProto(const v1::SubmitReply& in);

// The metrics of a published map (MetricsReply).
struct MetricList {
  std::string id, name;
  std::vector<std::string> metrics;
};
void ToProto(const MetricList& in, v1::MetricsReply* out);
MetricList FromProto(const v1::MetricsReply& in);

// A spec's key: the SHA-256 (64 lowercase hex digits) of its exact text. Workers keep parsed specs by it,
// and a lease names it instead of resending the text the worker holds.
std::string SpecKey(std::string_view spec_toml);
bool IsSpecKey(std::string_view key);
// A request's spec keys (LeaseRequest.known_specs, ReportRequest.next_known_specs): at most
// limits::kMaxKnownSpecs, each a spec key; InvalidArgument(`field`) naming the entry and the bound.
StatusOr<std::vector<std::string>> KnownSpecsFromProto(const google::protobuf::RepeatedPtrField<std::string>& in,
                                                       const std::string& field);

// A lease as the wire carries it (a LeaseReply with has_job).
struct LeasedWork {
  std::string lease_id, sweep_id;
  long job_id = 0;
  std::string spec_toml;  // "" when the worker named spec_key among the specs it holds
  std::string spec_key;   // SpecKey(the sweep's spec text); "" from coordinators before issue 40
  std::vector<WorkItem> items;
  double deadline = 0;
};
void ToProto(const LeasedWork& in, v1::LeaseReply* out);  // has_job true
// nullopt without a job. Checked, since a coordinator may be spoofed or broken: lease_id 1 to
// limits::kMaxIdBytes visible ASCII, sweep_id 1 to kMaxIdBytes lowercase hex, spec_key "" or a spec key,
// the spec text at most limits::kMaxSpecBytes, the items (ItemsFromProto).
StatusOr<std::optional<LeasedWork>> FromProto(const v1::LeaseReply& in);

// A sweep's spec text and key (SpecReply); FromProto checks the ids and the text's size, and that the key
// is the text's (SpecKey).
struct SpecText {
  std::string sweep_id, spec_toml, spec_key;
};
void ToProto(const SpecText& in, v1::SpecReply* out);
StatusOr<SpecText> FromProto(const v1::SpecReply& in);

// One chunk of a streamed map file (FileChunk); sha256 only in the last.
struct MapChunk {
  std::string_view id;
  std::uint64_t offset = 0, total_bytes = 0;
  std::string_view data, sha256;
};
void ToProto(const MapChunk& in, v1::FileChunk* out);

// A job's records into a report: width, values in item order, the catalog hash.
void ToProto(const std::vector<PointRecord>& records, v1::ReportRequest* out);

}  // namespace bistable

#endif  // BISTABLE_PROTO_CONVERT_H_
