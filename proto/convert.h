// Every conversion between the project's types and the wire's messages (proto/bistable.proto), in one
// place: the service and the clients (CLI, worker) both go through these.
#ifndef BISTABLE_PROTO_CONVERT_H_
#define BISTABLE_PROTO_CONVERT_H_

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

// A job's records into a report: width, values in item order, the catalog hash.
void ToProto(const std::vector<PointRecord>& records, v1::ReportRequest* out);

}  // namespace bistable

#endif  // BISTABLE_PROTO_CONVERT_H_
