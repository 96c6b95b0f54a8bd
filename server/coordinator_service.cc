#include "server/coordinator_service.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <thread>

#include "base/limits.h"
#include "base/log.h"
#include "base/sha256.h"
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
  // One coordinator per port: without this gRPC sets SO_REUSEPORT, and a second coordinator started on
  // a port in use would start "fine" and take half of the connections.
  builder.AddChannelArgument(GRPC_ARG_ALLOW_REUSEPORT, 0);
  builder.AddChannelArgument(GRPC_ARG_HTTP2_STREAM_LOOKAHEAD_BYTES, 1 << 20);
  // Keepalive: clients ping every 20 s during a call (proto/channel.cc), which the server accepts; the
  // server pings idle-looking connections every 60 s, so a watcher whose host died gives its thread back
  // within ~80 s rather than at the TCP retransmission timeout.
  builder.AddChannelArgument(GRPC_ARG_HTTP2_MIN_RECV_PING_INTERVAL_WITHOUT_DATA_MS, 10000);
  builder.AddChannelArgument(GRPC_ARG_KEEPALIVE_TIME_MS, 60000);
  builder.AddChannelArgument(GRPC_ARG_KEEPALIVE_TIMEOUT_MS, 20000);
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

// At most this many refusals a second are logged (a hostile client cannot flood the log); the rest
// are counted in the metrics and summed up in the next logged line.
constexpr int kRefusalLogsPerSecond = 20;

const char* GrpcCodeName(grpc::StatusCode c) {
  switch (c) {
    case grpc::StatusCode::OK: return "OK";
    case grpc::StatusCode::CANCELLED: return "CANCELLED";
    case grpc::StatusCode::INVALID_ARGUMENT: return "INVALID_ARGUMENT";
    case grpc::StatusCode::DEADLINE_EXCEEDED: return "DEADLINE_EXCEEDED";
    case grpc::StatusCode::NOT_FOUND: return "NOT_FOUND";
    case grpc::StatusCode::ALREADY_EXISTS: return "ALREADY_EXISTS";
    case grpc::StatusCode::PERMISSION_DENIED: return "PERMISSION_DENIED";
    case grpc::StatusCode::RESOURCE_EXHAUSTED: return "RESOURCE_EXHAUSTED";
    case grpc::StatusCode::FAILED_PRECONDITION: return "FAILED_PRECONDITION";
    case grpc::StatusCode::ABORTED: return "ABORTED";
    case grpc::StatusCode::OUT_OF_RANGE: return "OUT_OF_RANGE";
    case grpc::StatusCode::UNIMPLEMENTED: return "UNIMPLEMENTED";
    case grpc::StatusCode::INTERNAL: return "INTERNAL";
    case grpc::StatusCode::UNAVAILABLE: return "UNAVAILABLE";
    case grpc::StatusCode::DATA_LOSS: return "DATA_LOSS";
    case grpc::StatusCode::UNAUTHENTICATED: return "UNAUTHENTICATED";
    default: return "UNKNOWN";
  }
}

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

grpc::Status CoordinatorService::Answer(const grpc::ServerContext* ctx, const char* method, const Status& st) {
  if (st.ok()) return grpc::Status::OK;
  grpc::Status g = ToGrpcStatus(st);
  const char* code = GrpcCodeName(g.error_code());
  if (metrics_) metrics_->CountRefusal(method, code);
  const bool auth = g.error_code() == grpc::StatusCode::UNAUTHENTICATED || g.error_code() == grpc::StatusCode::PERMISSION_DENIED;
  const log::Level level = auth ? log::Level::kWarn : log::Level::kInfo;
  if (!log::Enabled(level)) return g;
  const long long second = std::chrono::duration_cast<std::chrono::seconds>(std::chrono::steady_clock::now().time_since_epoch()).count();
  long long suppressed = 0;
  {
    std::lock_guard<std::mutex> lock(refusal_log_mu_);
    if (second != refusal_log_second_) refusal_log_second_ = second, refusal_logs_this_second_ = 0;
    if (++refusal_logs_this_second_ > kRefusalLogsPerSecond) {
      ++refusals_suppressed_;
      return g;
    }
    std::swap(suppressed, refusals_suppressed_);
  }
  // The reason is the answer the caller gets (it never holds a token); the peer is the transport's address.
  log::Event(level, "call.refused",
             {{"method", method}, {"code", code}, {"peer", ctx->peer()}, {"reason", g.error_message()}, {"suppressed", suppressed}});
  return g;
}

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
  if (Status st = tokens_.Check(ctx, Op::kSubmit, &who); !st.ok()) return Answer(ctx, "Submit", st);
  if (req->spec_toml().size() > limits::kMaxSpecBytes)
    return Answer(ctx, "Submit", Status::InvalidArgument("spec", "spec is " + std::to_string(req->spec_toml().size()) +
                                                            " bytes, over the limit of " + std::to_string(limits::kMaxSpecBytes)));
  // The origin only names the spec in messages: bounded, printable, never a path that is opened.
  const std::string origin = req->origin().empty() ? "submitted spec" : Printable(req->origin(), limits::kMaxNameBytes);
  auto spec = ParseSweepSpec(req->spec_toml(), origin);
  if (!spec.ok()) return Answer(ctx, "Submit", spec.status());
  // Jobs of about job_seconds of work on one core, at least 64 per sweep (the last jobs balance).
  const long items = JobItems(*spec, job_seconds_, 64);
  auto plan = c_->Submit(*spec, items, who);
  if (!plan.ok()) return Answer(ctx, "Submit", plan.status());
  rep->set_id(plan->id);
  rep->set_items_total(plan->items_total);
  rep->set_items_cached(plan->items_cached);
  rep->set_jobs(plan->jobs);
  return grpc::Status::OK;
}

grpc::Status CoordinatorService::GetStatus(grpc::ServerContext* ctx, const v1::StatusRequest* req, v1::SweepStatus* rep) {
  std::string who;
  if (Status st = tokens_.Check(ctx, Op::kStatus, &who); !st.ok()) return Answer(ctx, "GetStatus", st);
  auto id = c_->ResolveId(req->id());
  if (!id.ok()) return Answer(ctx, "GetStatus", id.status());
  auto info = c_->Info(*id);
  if (!info.ok()) return Answer(ctx, "GetStatus", info.status());
  ToProto(*info, rep);
  return grpc::Status::OK;
}

grpc::Status CoordinatorService::WatchStatus(grpc::ServerContext* ctx, const v1::StatusRequest* req,
                                             grpc::ServerWriter<v1::SweepStatus>* writer) {
  std::string who;
  if (Status st = tokens_.Check(ctx, Op::kStatus, &who); !st.ok()) return Answer(ctx, "WatchStatus", st);
  auto id = c_->ResolveId(req->id());
  if (!id.ok()) return Answer(ctx, "WatchStatus", id.status());
  auto last = std::chrono::steady_clock::now() - std::chrono::seconds(1);
  for (bool first = true; !ctx->IsCancelled() && !shutting_down_; first = false) {
    auto info = first ? c_->Info(*id) : c_->AwaitFinal(*id, 0.5);  // progress every 0.5 s, the end at once
    if (!info.ok()) return Answer(ctx, "WatchStatus", info.status());
    // Never faster than limits::kMinWatchInterval, whatever the sweep's state.
    const auto due = last + std::chrono::duration_cast<std::chrono::steady_clock::duration>(
                                std::chrono::duration<double>(limits::kMinWatchInterval));
    const bool final_state = IsFinal(info->state);
    if (!final_state && std::chrono::steady_clock::now() < due) std::this_thread::sleep_until(due);
    last = std::chrono::steady_clock::now();
    v1::SweepStatus s;
    ToProto(*info, &s);
    if (!writer->Write(s) || final_state) return grpc::Status::OK;
  }
  // Ended by a shutdown, not by the sweep: the watcher must not take the last status for the end.
  if (shutting_down_ && !ctx->IsCancelled())
    return grpc::Status(grpc::StatusCode::UNAVAILABLE, "the coordinator is shutting down; the sweep goes on when it restarts");
  return grpc::Status::OK;
}

grpc::Status CoordinatorService::Cancel(grpc::ServerContext* ctx, const v1::CancelRequest* req, v1::CancelReply*) {
  std::string who;
  Role role = Role::kClient;
  if (Status st = tokens_.Check(ctx, Op::kCancel, &who, &role); !st.ok()) return Answer(ctx, "Cancel", st);
  auto id = c_->ResolveId(req->id());
  if (!id.ok()) return Answer(ctx, "Cancel", id.status());
  // Clients cancel their own sweeps (the owner is stored with the sweep and survives restarts);
  // admins any.
  auto info = c_->Info(*id);
  if (!info.ok()) return Answer(ctx, "Cancel", info.status());
  if (role != Role::kAdmin && info->owner != who)
    return Answer(ctx, "Cancel", Status::PermissionDenied("only the token that submitted sweep " + *id + " (or an admin) may cancel it"));
  return Answer(ctx, "Cancel", c_->Cancel(*id));
}

grpc::Status CoordinatorService::ListSweeps(grpc::ServerContext* ctx, const v1::ListSweepsRequest*, v1::ListSweepsReply* rep) {
  std::string who;
  if (Status st = tokens_.Check(ctx, Op::kList, &who); !st.ok()) return Answer(ctx, "ListSweeps", st);
  auto infos = c_->ListSweeps();
  if (!infos.ok()) return Answer(ctx, "ListSweeps", infos.status());
  for (const SweepInfo& info : *infos) ToProto(info, rep->add_sweeps());
  return grpc::Status::OK;
}

grpc::Status CoordinatorService::GetMap(grpc::ServerContext* ctx, const v1::MapRequest* req, v1::MapReply* rep) {
  std::string who;
  if (Status st = tokens_.Check(ctx, Op::kMap, &who); !st.ok()) return Answer(ctx, "GetMap", st);
  auto map = PublishedMap(req->id());
  if (!map.ok()) return Answer(ctx, "GetMap", map.status());
  // ReadMapMetric opens only a metric the map lists (never an arbitrary HDF5 path from the request).
  auto m = ReadMapMetric(map->second, req->metric());
  if (!m.ok()) return Answer(ctx, "GetMap", m.status());
  ToProto(*m, rep);
  return grpc::Status::OK;
}

grpc::Status CoordinatorService::ListMetrics(grpc::ServerContext* ctx, const v1::MapRequest* req, v1::MetricsReply* rep) {
  std::string who;
  if (Status st = tokens_.Check(ctx, Op::kMap, &who); !st.ok()) return Answer(ctx, "ListMetrics", st);
  auto map = PublishedMap(req->id());
  if (!map.ok()) return Answer(ctx, "ListMetrics", map.status());
  auto names = ListMapMetrics(map->second);
  if (!names.ok()) return Answer(ctx, "ListMetrics", names.status());
  auto info = c_->Info(map->first);
  rep->set_id(map->first);
  rep->set_name(info.ok() ? info->name : "");
  for (const auto& n : *names) rep->add_metrics(n);
  return grpc::Status::OK;
}

grpc::Status CoordinatorService::RegisterWorker(grpc::ServerContext* ctx, const v1::RegisterRequest* req, v1::RegisterReply* rep) {
  std::string who;
  if (Status st = tokens_.Check(ctx, Op::kRegister, &who); !st.ok()) return Answer(ctx, "RegisterWorker", st);
  if (Status st = CheckWorkerName(req->name()); !st.ok()) return Answer(ctx, "RegisterWorker", st);
  log::Event(log::Level::kInfo, "worker.registered",
             {{"worker", req->name()}, {"threads", static_cast<long long>(req->threads())}, {"peer", ctx->peer()}, {"identity", who}});
  rep->set_lease_seconds(lease_seconds_);
  return grpc::Status::OK;
}

grpc::Status CoordinatorService::Lease(grpc::ServerContext* ctx, const v1::LeaseRequest* req, v1::LeaseReply* rep) {
  std::string who;
  if (Status st = tokens_.Check(ctx, Op::kLease, &who); !st.ok()) return Answer(ctx, "Lease", st);
  return Answer(ctx, "Lease", LeaseInto(req->worker(), who, rep, req->max_jobs()));
}

Status CoordinatorService::LeaseInto(const std::string& worker, const std::string& who, v1::LeaseReply* rep, int max_jobs) {
  BISTABLE_RETURN_IF_ERROR(CheckWorkerName(worker));
  if (max_jobs < 0 || max_jobs > static_cast<int>(limits::kMaxJobsPerLease))
    return Status::InvalidArgument("max_jobs", "max_jobs = " + std::to_string(max_jobs) + " violates max_jobs in [0, " +
                                                   std::to_string(limits::kMaxJobsPerLease) + "]");
  if (shutting_down_) return Status::IoError("coordinator", "shutting down");
  auto g = c_->Lease(worker, "", std::max(1, max_jobs), who);
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
  if (Status st = tokens_.Check(ctx, Op::kHeartbeat, &who); !st.ok()) return Answer(ctx, "Heartbeat", st);
  if (Status st = CheckLeaseId(req->lease_id()); !st.ok()) return Answer(ctx, "Heartbeat", st);
  return Answer(ctx, "Heartbeat", c_->Extend(req->lease_id(), who));
}

grpc::Status CoordinatorService::Report(grpc::ServerContext* ctx, const v1::ReportRequest* req, v1::ReportReply* rep) {
  const auto start = std::chrono::steady_clock::now();
  struct Timer {  // the latency histogram sees every answer, refused or not
    CoordinatorMetrics* m;
    std::chrono::steady_clock::time_point t0;
    ~Timer() {
      if (m) m->ObserveReport(std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());
    }
  } timer{metrics_, start};
  std::string who;
  if (Status st = tokens_.Check(ctx, Op::kReport, &who); !st.ok()) return Answer(ctx, "Report", st);
  if (!req->lease_next_for().empty())
    if (Status st = tokens_.Check(ctx, Op::kLease, &who); !st.ok()) return Answer(ctx, "Report", st);
  if (Status st = CheckLeaseId(req->lease_id()); !st.ok()) return Answer(ctx, "Report", st);
  if (req->catalog_hash() != CatalogHash())
    return Answer(ctx, "Report", Status::FailedPrecondition(
        "the report's metric catalog differs from this coordinator's (a worker of another build?): its records would "
        "be stored under the wrong names; run workers of the coordinator's version"));
  // The coordinator checks the lease, its job's size and layout and every value's domain before it
  // copies anything out of the request.
  if (Status st = c_->Report(req->lease_id(), req->record_width(), req->values().data(), static_cast<size_t>(req->values_size()), who);
      !st.ok())
    return Answer(ctx, "Report", st);
  if (req->lease_next_for().empty()) return grpc::Status::OK;
  // The report is stored; a failure to lease now is not the report's failure (the worker polls).
  if (Status st = LeaseInto(req->lease_next_for(), who, rep->mutable_next(), req->next_max_jobs()); !st.ok()) {
    rep->mutable_next()->Clear();
    rep->mutable_next()->set_has_job(false);
  }
  return grpc::Status::OK;
}

grpc::Status CoordinatorService::Release(grpc::ServerContext* ctx, const v1::ReleaseRequest* req, v1::ReleaseReply*) {
  std::string who;
  if (Status st = tokens_.Check(ctx, Op::kRelease, &who); !st.ok()) return Answer(ctx, "Release", st);
  if (Status st = CheckLeaseId(req->lease_id()); !st.ok()) return Answer(ctx, "Release", st);
  return Answer(ctx, "Release", c_->Release(req->lease_id(), who));
}

grpc::Status CoordinatorService::ListWorkers(grpc::ServerContext* ctx, const v1::ListWorkersRequest*, v1::ListWorkersReply* rep) {
  std::string who;
  if (Status st = tokens_.Check(ctx, Op::kWorkers, &who); !st.ok()) return Answer(ctx, "ListWorkers", st);
  for (const WorkerInfo& w : c_->Workers()) ToProto(w, rep->add_workers());
  return grpc::Status::OK;
}

grpc::Status CoordinatorService::FetchMap(grpc::ServerContext* ctx, const v1::FetchMapRequest* req,
                                          grpc::ServerWriter<v1::FileChunk>* writer) {
  std::string who;
  if (Status st = tokens_.Check(ctx, Op::kMap, &who); !st.ok()) return Answer(ctx, "FetchMap", st);
  auto map = PublishedMap(req->id());
  if (!map.ok()) return Answer(ctx, "FetchMap", map.status());
  // The open descriptor keeps this version of the file: a republication (rename) meanwhile does not
  // mix two files into one stream.
  std::ifstream f(map->second, std::ios::binary);
  std::error_code ec;
  const auto total = std::filesystem::file_size(map->second, ec);
  if (!f || ec) return Answer(ctx, "FetchMap", Status::IoError("map", "cannot open the map of sweep " + map->first));
  Sha256 sha;
  std::string buf(limits::kFetchChunkBytes, '\0');
  uint64_t offset = 0;
  const auto start = std::chrono::steady_clock::now();
  while (true) {
    if (ctx->IsCancelled() || shutting_down_) return grpc::Status(grpc::StatusCode::CANCELLED, "fetch cancelled");
    f.read(buf.data(), static_cast<std::streamsize>(buf.size()));
    const size_t n = static_cast<size_t>(f.gcount());
    v1::FileChunk chunk;
    chunk.set_id(map->first);
    chunk.set_offset(offset);
    chunk.set_total_bytes(total);
    chunk.set_data(buf.data(), n);
    sha.Update(std::string_view(buf.data(), n));
    offset += n;
    const bool last = n < buf.size() || offset >= total;
    if (last) {
      if (offset != total)
        return Answer(ctx, "FetchMap", Status::IoError("map", "the map of sweep " + map->first + " changed size while read"));
      chunk.set_sha256(sha.HexDigest());
    }
    if (!writer->Write(chunk)) return grpc::Status(grpc::StatusCode::CANCELLED, "client went away");
    if (last) break;
  }
  log::Event(log::Level::kInfo, "map.fetched",
             {{"sweep", map->first}, {"bytes", static_cast<long long>(total)}, {"identity", who}, {"peer", ctx->peer()},
              {"ms", std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count()}});
  return grpc::Status::OK;
}

}  // namespace bistable
