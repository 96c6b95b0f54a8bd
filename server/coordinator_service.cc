#include "server/coordinator_service.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <thread>

#include "base/limits.h"
#include "base/names.h"
#include "engine/evaluate.h"
#include "proto/convert.h"
#include "proto/status_convert.h"
#include "storage/map_file.h"

namespace bistable {

void ConfigureServerBuilder(grpc::ServerBuilder& builder) {
  // Every request is bounded before it is decoded: the largest legitimate one is a report of a job of
  // limits::kMaxJobItems records (about 3 MB) or a spec (1 MB).
  builder.SetMaxReceiveMessageSize(static_cast<int>(limits::kMaxMessageBytes));
  // Transport memory per connection stays bounded: no bandwidth-delay probing that grows the receive
  // window without limit (an oversized message is then refused before megabytes of it are buffered).
  builder.AddChannelArgument(GRPC_ARG_HTTP2_BDP_PROBE, 0);
  builder.AddChannelArgument(GRPC_ARG_HTTP2_STREAM_LOOKAHEAD_BYTES, 1 << 20);
  // Threads and transport memory of the whole server are bounded: calls beyond them are answered
  // RESOURCE_EXHAUSTED instead of growing the process (one thread per open watch, for instance).
  grpc::ResourceQuota quota("bistable-coordinator");
  quota.SetMaxThreads(limits::kMaxServerThreads);
  quota.Resize(limits::kMaxServerMemoryBytes);
  builder.SetResourceQuota(quota);
  builder.SetSyncServerOption(grpc::ServerBuilder::SyncServerOption::NUM_CQS, 1);
  builder.SetSyncServerOption(grpc::ServerBuilder::SyncServerOption::MIN_POLLERS, 2);
  builder.SetSyncServerOption(grpc::ServerBuilder::SyncServerOption::MAX_POLLERS, 16);
}
namespace {

// A worker's name: printable ASCII, bounded (it is shown to every client by `bistable workers`).
Status CheckWorkerName(const std::string& name) {
  if (name.empty()) return Status::InvalidArgument("worker", "worker name is empty");
  if (name.size() > limits::kMaxWorkerNameBytes)
    return Status::InvalidArgument("worker", "worker name is " + std::to_string(name.size()) + " bytes, over the limit of " +
                                                 std::to_string(limits::kMaxWorkerNameBytes));
  for (char c : name)
    if (c < 0x21 || c > 0x7e)
      return Status::InvalidArgument("worker", "worker name must be printable ASCII without spaces (host:pid)");
  return Status::Ok();
}

Status CheckLeaseId(const std::string& id) {
  if (id.empty() || id.size() > limits::kMaxIdBytes)
    return Status::InvalidArgument("lease_id", "lease_id must be 1 to " + std::to_string(limits::kMaxIdBytes) + " bytes");
  return Status::Ok();
}


}  // namespace

// The published map of a sweep (id or prefix): its resolved id and the file's absolute path.
StatusOr<std::pair<std::string, std::string>> CoordinatorService::PublishedMap(const std::string& id_or_prefix) const {
  auto id = c_->ResolveId(id_or_prefix);
  if (!id.ok()) return id.status();
  auto info = c_->Info(*id);
  if (!info.ok()) return info.status();
  if (info->file.empty())
    return Status::FailedPrecondition("sweep " + *id + " has no published map yet (state " + SweepStateName(info->state) + ")");
  return std::make_pair(*id, (std::filesystem::path(c_->data_dir()) / info->file).string());
}

grpc::Status CoordinatorService::Submit(grpc::ServerContext* ctx, const v1::SubmitRequest* req, v1::SubmitReply* rep) {
  std::string who;
  if (Status st = tokens_.Check(ctx, Op::kSubmit, &who); !st.ok()) return ToGrpcStatus(st);
  if (req->spec_toml().size() > limits::kMaxSpecBytes)
    return ToGrpcStatus(Status::InvalidArgument("spec", "spec is " + std::to_string(req->spec_toml().size()) +
                                                            " bytes, over the limit of " + std::to_string(limits::kMaxSpecBytes)));
  // The origin only names the spec in messages: bounded, printable, never a path that is opened.
  const std::string origin = req->origin().empty() ? "submitted spec" : Printable(req->origin(), limits::kMaxNameBytes);
  auto spec = ParseSweepSpec(req->spec_toml(), origin);
  if (!spec.ok()) return ToGrpcStatus(spec.status());
  // Jobs of about job_seconds of work on one core, at least 64 per sweep (the last jobs balance).
  const long items = JobItems(*spec, job_seconds_, 64);
  auto plan = c_->Submit(*spec, items, who);
  if (!plan.ok()) return ToGrpcStatus(plan.status());
  rep->set_id(plan->id);
  rep->set_items_total(plan->items_total);
  rep->set_items_cached(plan->items_cached);
  rep->set_jobs(plan->jobs);
  return grpc::Status::OK;
}

grpc::Status CoordinatorService::GetStatus(grpc::ServerContext* ctx, const v1::StatusRequest* req, v1::SweepStatus* rep) {
  std::string who;
  if (Status st = tokens_.Check(ctx, Op::kStatus, &who); !st.ok()) return ToGrpcStatus(st);
  auto id = c_->ResolveId(req->id());
  if (!id.ok()) return ToGrpcStatus(id.status());
  auto info = c_->Info(*id);
  if (!info.ok()) return ToGrpcStatus(info.status());
  ToProto(*info, rep);
  return grpc::Status::OK;
}

grpc::Status CoordinatorService::WatchStatus(grpc::ServerContext* ctx, const v1::StatusRequest* req,
                                             grpc::ServerWriter<v1::SweepStatus>* writer) {
  std::string who;
  if (Status st = tokens_.Check(ctx, Op::kStatus, &who); !st.ok()) return ToGrpcStatus(st);
  auto id = c_->ResolveId(req->id());
  if (!id.ok()) return ToGrpcStatus(id.status());
  auto last = std::chrono::steady_clock::now() - std::chrono::seconds(1);
  for (bool first = true; !ctx->IsCancelled() && !shutting_down_; first = false) {
    auto info = first ? c_->Info(*id) : c_->AwaitFinal(*id, 0.5);  // progress every 0.5 s, the end at once
    if (!info.ok()) return ToGrpcStatus(info.status());
    // Never faster than limits::kMinWatchInterval, whatever the sweep's state.
    const auto due = last + std::chrono::duration_cast<std::chrono::steady_clock::duration>(
                                std::chrono::duration<double>(limits::kMinWatchInterval));
    const bool final_state = IsFinal(info->state);
    if (!final_state && std::chrono::steady_clock::now() < due) std::this_thread::sleep_until(due);
    last = std::chrono::steady_clock::now();
    v1::SweepStatus s;
    ToProto(*info, &s);
    if (!writer->Write(s)) break;
    if (final_state) break;
  }
  return grpc::Status::OK;
}

grpc::Status CoordinatorService::Cancel(grpc::ServerContext* ctx, const v1::CancelRequest* req, v1::CancelReply*) {
  std::string who;
  Role role = Role::kClient;
  if (Status st = tokens_.Check(ctx, Op::kCancel, &who, &role); !st.ok()) return ToGrpcStatus(st);
  auto id = c_->ResolveId(req->id());
  if (!id.ok()) return ToGrpcStatus(id.status());
  // Clients cancel their own sweeps (the owner is stored with the sweep and survives restarts);
  // admins any.
  auto info = c_->Info(*id);
  if (!info.ok()) return ToGrpcStatus(info.status());
  if (role != Role::kAdmin && info->owner != who)
    return ToGrpcStatus(Status::PermissionDenied("only the token that submitted sweep " + *id + " (or an admin) may cancel it"));
  return ToGrpcStatus(c_->Cancel(*id));
}

grpc::Status CoordinatorService::ListSweeps(grpc::ServerContext* ctx, const v1::ListSweepsRequest*, v1::ListSweepsReply* rep) {
  std::string who;
  if (Status st = tokens_.Check(ctx, Op::kList, &who); !st.ok()) return ToGrpcStatus(st);
  auto infos = c_->ListSweeps();
  if (!infos.ok()) return ToGrpcStatus(infos.status());
  for (const SweepInfo& info : *infos) ToProto(info, rep->add_sweeps());
  return grpc::Status::OK;
}

grpc::Status CoordinatorService::GetMap(grpc::ServerContext* ctx, const v1::MapRequest* req, v1::MapReply* rep) {
  std::string who;
  if (Status st = tokens_.Check(ctx, Op::kMap, &who); !st.ok()) return ToGrpcStatus(st);
  auto map = PublishedMap(req->id());
  if (!map.ok()) return ToGrpcStatus(map.status());
  // ReadMapMetric opens only a metric the map lists (never an arbitrary HDF5 path from the request).
  auto m = ReadMapMetric(map->second, req->metric());
  if (!m.ok()) return ToGrpcStatus(m.status());
  ToProto(*m, rep);
  return grpc::Status::OK;
}

grpc::Status CoordinatorService::ListMetrics(grpc::ServerContext* ctx, const v1::MapRequest* req, v1::MetricsReply* rep) {
  std::string who;
  if (Status st = tokens_.Check(ctx, Op::kMap, &who); !st.ok()) return ToGrpcStatus(st);
  auto map = PublishedMap(req->id());
  if (!map.ok()) return ToGrpcStatus(map.status());
  auto names = ListMapMetrics(map->second);
  if (!names.ok()) return ToGrpcStatus(names.status());
  auto info = c_->Info(map->first);
  rep->set_id(map->first);
  rep->set_name(info.ok() ? info->name : "");
  for (const auto& n : *names) rep->add_metrics(n);
  return grpc::Status::OK;
}

grpc::Status CoordinatorService::RegisterWorker(grpc::ServerContext* ctx, const v1::RegisterRequest* req, v1::RegisterReply* rep) {
  std::string who;
  if (Status st = tokens_.Check(ctx, Op::kRegister, &who); !st.ok()) return ToGrpcStatus(st);
  if (Status st = CheckWorkerName(req->name()); !st.ok()) return ToGrpcStatus(st);
  rep->set_lease_seconds(lease_seconds_);
  return grpc::Status::OK;
}

grpc::Status CoordinatorService::Lease(grpc::ServerContext* ctx, const v1::LeaseRequest* req, v1::LeaseReply* rep) {
  std::string who;
  if (Status st = tokens_.Check(ctx, Op::kLease, &who); !st.ok()) return ToGrpcStatus(st);
  return ToGrpcStatus(LeaseInto(req->worker(), rep));
}

Status CoordinatorService::LeaseInto(const std::string& worker, v1::LeaseReply* rep) {
  BISTABLE_RETURN_IF_ERROR(CheckWorkerName(worker));
  if (shutting_down_) return Status::IoError("coordinator", "shutting down");
  auto g = c_->Lease(worker);
  if (!g) {
    rep->set_has_job(false);
    return Status::Ok();
  }
  auto spec = c_->SpecText(g->sweep_id);
  if (!spec.ok()) return spec.status();
  rep->set_has_job(true);
  rep->set_lease_id(g->lease_id);
  rep->set_sweep_id(g->sweep_id);
  rep->set_job_id(g->job_id);
  rep->set_spec_toml(*spec);
  ToProto(g->items, rep);
  rep->set_deadline(g->deadline);
  return Status::Ok();
}

grpc::Status CoordinatorService::Heartbeat(grpc::ServerContext* ctx, const v1::HeartbeatRequest* req, v1::HeartbeatReply*) {
  std::string who;
  if (Status st = tokens_.Check(ctx, Op::kHeartbeat, &who); !st.ok()) return ToGrpcStatus(st);
  if (Status st = CheckLeaseId(req->lease_id()); !st.ok()) return ToGrpcStatus(st);
  return ToGrpcStatus(c_->Extend(req->lease_id()));
}

grpc::Status CoordinatorService::Report(grpc::ServerContext* ctx, const v1::ReportRequest* req, v1::ReportReply* rep) {
  std::string who;
  if (Status st = tokens_.Check(ctx, Op::kReport, &who); !st.ok()) return ToGrpcStatus(st);
  if (!req->lease_next_for().empty())
    if (Status st = tokens_.Check(ctx, Op::kLease, &who); !st.ok()) return ToGrpcStatus(st);
  if (Status st = CheckLeaseId(req->lease_id()); !st.ok()) return ToGrpcStatus(st);
  if (req->catalog_hash() != CatalogHash())
    return ToGrpcStatus(Status::FailedPrecondition(
        "the report's metric catalog differs from this coordinator's (a worker of another build?): its records would "
        "be stored under the wrong names; run workers of the coordinator's version"));
  // The coordinator checks the lease, its job's size and layout and every value's domain before it
  // copies anything out of the request.
  if (Status st = c_->Report(req->lease_id(), req->record_width(), req->values().data(), static_cast<size_t>(req->values_size()));
      !st.ok())
    return ToGrpcStatus(st);
  if (req->lease_next_for().empty()) return grpc::Status::OK;
  // The report is stored; a failure to lease now is not the report's failure (the worker polls).
  if (Status st = LeaseInto(req->lease_next_for(), rep->mutable_next()); !st.ok()) rep->mutable_next()->set_has_job(false);
  return grpc::Status::OK;
}

grpc::Status CoordinatorService::Release(grpc::ServerContext* ctx, const v1::ReleaseRequest* req, v1::ReleaseReply*) {
  std::string who;
  if (Status st = tokens_.Check(ctx, Op::kRelease, &who); !st.ok()) return ToGrpcStatus(st);
  if (Status st = CheckLeaseId(req->lease_id()); !st.ok()) return ToGrpcStatus(st);
  return ToGrpcStatus(c_->Release(req->lease_id()));
}

grpc::Status CoordinatorService::ListWorkers(grpc::ServerContext* ctx, const v1::ListWorkersRequest*, v1::ListWorkersReply* rep) {
  std::string who;
  if (Status st = tokens_.Check(ctx, Op::kWorkers, &who); !st.ok()) return ToGrpcStatus(st);
  for (const WorkerInfo& w : c_->Workers()) ToProto(w, rep->add_workers());
  return grpc::Status::OK;
}

}  // namespace bistable
