#include "server/coordinator_service.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <thread>
#include <type_traits>

#include "base/limits.h"
#include "base/log.h"
#include "base/names.h"
#include "base/sha256.h"
#include "engine/evaluate.h"
#include "proto/convert.h"
#include "proto/status_convert.h"

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

// A worker's name: printable ASCII, bounded (it is shown to every client by `bistable workers`).
Status CheckWorkerName(const std::string& name) {
  if (name.empty()) return Status::InvalidArgument("worker", "worker name is empty");
  if (name.size() > limits::kMaxWorkerNameBytes)
    return Status::InvalidArgument("worker", "worker name is " + std::to_string(name.size()) +
                                                 " bytes, over the limit of " +
                                                 std::to_string(limits::kMaxWorkerNameBytes));
  for (char c : name)
    if (c < 0x21 || c > 0x7e)
      return Status::InvalidArgument("worker", "worker name must be printable ASCII without spaces (host:pid)");
  return Status::Ok();
}

Status CheckLeaseId(const std::string& id) {
  if (id.empty() || id.size() > limits::kMaxIdBytes)
    return Status::InvalidArgument("lease_id",
                                   "lease_id must be 1 to " + std::to_string(limits::kMaxIdBytes) + " bytes");
  return Status::Ok();
}

}  // namespace

grpc::Status CoordinatorService::Answer(const grpc::ServerContext* ctx, const char* method, const Status& st) {
  if (st.ok()) return grpc::Status::OK;
  grpc::Status g = ToGrpcStatus(st);
  const char* code = GrpcCodeName(g.error_code());
  if (metrics_) metrics_->CountRefusal(method, code);
  const bool auth =
      g.error_code() == grpc::StatusCode::UNAUTHENTICATED || g.error_code() == grpc::StatusCode::PERMISSION_DENIED;
  const log::Level level = auth ? log::Level::kWarn : log::Level::kInfo;
  if (!log::Enabled(level)) return g;
  const long long second =
      std::chrono::duration_cast<std::chrono::seconds>(std::chrono::steady_clock::now().time_since_epoch()).count();
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
             {{"method", method},
              {"code", code},
              {"peer", ctx->peer()},
              {"reason", g.error_message()},
              {"suppressed", suppressed}});
  return g;
}

// The published map of a sweep (id or prefix): its resolved id and the file's absolute path.
StatusOr<std::pair<std::string, std::string>> CoordinatorService::PublishedMap(const std::string& id_or_prefix) const {
  auto id = c_->ResolveId(id_or_prefix);
  if (!id.ok()) return id.status();
  auto info = c_->Info(*id);
  if (!info.ok()) return info.status();
  if (info->file.empty())
    return Status::FailedPrecondition("sweep " + *id + " has no published map yet (state " +
                                      SweepStateName(info->state) + ")");
  return std::make_pair(*id, (std::filesystem::path(c_->data_dir()) / info->file).string());
}

template <class Body>
grpc::Status CoordinatorService::Serve(grpc::ServerContext* ctx, const char* method, Op op, Body&& body) {
  Caller caller;
  if (Status st = tokens_.Check(ctx, op, &caller.who, &caller.role); !st.ok()) return Answer(ctx, method, st);
  if constexpr (std::is_same_v<std::invoke_result_t<Body, const Caller&>, grpc::Status>) {
    return body(static_cast<const Caller&>(caller));
  } else {
    return Answer(ctx, method, body(static_cast<const Caller&>(caller)));
  }
}

StatusOr<SpecText> CoordinatorService::KeyedSpec(const std::string& sweep_id, const std::string& spec_key) {
  if (!spec_key.empty()) {
    std::lock_guard<std::mutex> lock(spec_texts_mu_);
    if (auto it = spec_texts_.find(spec_key); it != spec_texts_.end()) return SpecText{sweep_id, it->second, spec_key};
  }
  std::string key;
  auto text = c_->SpecText(sweep_id, &key);
  if (!text.ok()) return text.status();
  SpecText keyed{sweep_id, std::move(*text), std::move(key)};
  std::lock_guard<std::mutex> lock(spec_texts_mu_);
  if (!spec_texts_.count(keyed.spec_key)) {
    // At most kMaxKnownSpecs texts kept (a text pushed out is asked of the coordinator again).
    if (spec_texts_.size() >= static_cast<size_t>(limits::kMaxKnownSpecs)) spec_texts_.erase(spec_texts_.begin());
    spec_texts_.emplace(keyed.spec_key, keyed.spec_toml);
  }
  return keyed;
}

grpc::Status CoordinatorService::Submit(grpc::ServerContext* ctx, const v1::SubmitRequest* req, v1::SubmitReply* rep) {
  return Serve(ctx, "Submit", Op::kSubmit, [&](const Caller& caller) -> Status {
    if (req->spec_toml().size() > limits::kMaxSpecBytes)
      return Status::InvalidArgument("spec", "spec is " + std::to_string(req->spec_toml().size()) +
                                                 " bytes, over the limit of " + std::to_string(limits::kMaxSpecBytes));
    // The origin only names the spec in messages: bounded, printable, never a path that is opened.
    const std::string origin =
        req->origin().empty() ? "submitted spec" : Printable(req->origin(), limits::kMaxNameBytes);
    auto spec = ParseSweepSpec(req->spec_toml(), origin);
    if (!spec.ok()) return spec.status();
    // Jobs of about job_seconds of work on one core, at least 64 per sweep (the last jobs balance).
    const long items = JobItems(*spec, job_seconds_, 64);
    auto plan = c_->Submit(*spec, items, caller.who);
    if (!plan.ok()) return plan.status();
    ToProto(SubmitResult{plan->id, plan->items_total, plan->items_cached, plan->jobs}, rep);
    return Status::Ok();
  });
}

grpc::Status CoordinatorService::GetStatus(grpc::ServerContext* ctx, const v1::StatusRequest* req,
                                           v1::SweepStatus* rep) {
  return Serve(ctx, "GetStatus", Op::kStatus, [&](const Caller&) -> Status {
    auto id = c_->ResolveId(req->id());
    if (!id.ok()) return id.status();
    auto info = c_->Info(*id);
    if (!info.ok()) return info.status();
    ToProto(*info, rep);
    return Status::Ok();
  });
}

grpc::Status CoordinatorService::WatchStatus(grpc::ServerContext* ctx, const v1::StatusRequest* req,
                                             grpc::ServerWriter<v1::SweepStatus>* writer) {
  return Serve(ctx, "WatchStatus", Op::kStatus, [&](const Caller&) -> grpc::Status {
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
      return grpc::Status(grpc::StatusCode::UNAVAILABLE,
                          "the coordinator is shutting down; the sweep goes on when it restarts");
    return grpc::Status::OK;
  });
}

grpc::Status CoordinatorService::Cancel(grpc::ServerContext* ctx, const v1::CancelRequest* req, v1::CancelReply*) {
  return Serve(ctx, "Cancel", Op::kCancel, [&](const Caller& caller) -> Status {
    auto id = c_->ResolveId(req->id());
    if (!id.ok()) return id.status();
    // Clients cancel their own sweeps (the owner is stored with the sweep and survives restarts);
    // admins any.
    auto info = c_->Info(*id);
    if (!info.ok()) return info.status();
    if (caller.role != Role::kAdmin && info->owner != caller.who)
      return Status::PermissionDenied("only the token that submitted sweep " + *id + " (or an admin) may cancel it");
    return c_->Cancel(*id);
  });
}

grpc::Status CoordinatorService::ListSweeps(grpc::ServerContext* ctx, const v1::ListSweepsRequest*,
                                            v1::ListSweepsReply* rep) {
  return Serve(ctx, "ListSweeps", Op::kList, [&](const Caller&) -> Status {
    auto infos = c_->ListSweeps();
    if (!infos.ok()) return infos.status();
    for (const SweepInfo& info : *infos) ToProto(info, rep->add_sweeps());
    return Status::Ok();
  });
}

grpc::Status CoordinatorService::GetMap(grpc::ServerContext* ctx, const v1::MapRequest* req, v1::MapReply* rep) {
  return Serve(ctx, "GetMap", Op::kMap, [&](const Caller&) -> Status {
    auto map = PublishedMap(req->id());
    if (!map.ok()) return map.status();
    // Only a metric the map lists is read (never an arbitrary HDF5 path from the request), once per file.
    auto m = maps_->Metric(map->second, req->metric());
    if (!m.ok()) return m.status();
    ToProto(**m, rep);
    return Status::Ok();
  });
}

grpc::Status CoordinatorService::ListMetrics(grpc::ServerContext* ctx, const v1::MapRequest* req,
                                             v1::MetricsReply* rep) {
  return Serve(ctx, "ListMetrics", Op::kMap, [&](const Caller&) -> Status {
    auto map = PublishedMap(req->id());
    if (!map.ok()) return map.status();
    auto names = maps_->Metrics(map->second);
    if (!names.ok()) return names.status();
    auto info = c_->Info(map->first);
    ToProto(MetricList{map->first, info.ok() ? info->name : "", **names}, rep);
    return Status::Ok();
  });
}

grpc::Status CoordinatorService::RegisterWorker(grpc::ServerContext* ctx, const v1::RegisterRequest* req,
                                                v1::RegisterReply* rep) {
  return Serve(ctx, "RegisterWorker", Op::kRegister, [&](const Caller& caller) -> Status {
    BISTABLE_RETURN_IF_ERROR(CheckWorkerName(req->name()));
    log::Event(log::Level::kInfo, "worker.registered",
               {{"worker", req->name()},
                {"threads", static_cast<long long>(req->threads())},
                {"peer", ctx->peer()},
                {"identity", caller.who}});
    rep->set_lease_seconds(lease_seconds_);
    return Status::Ok();
  });
}

grpc::Status CoordinatorService::Lease(grpc::ServerContext* ctx, const v1::LeaseRequest* req, v1::LeaseReply* rep) {
  return Serve(ctx, "Lease", Op::kLease, [&](const Caller& caller) -> Status {
    auto known = KnownSpecsFromProto(req->known_specs(), "known_specs");
    if (!known.ok()) return known.status();
    return LeaseInto(req->worker(), caller.who, rep, req->max_jobs(), *known);
  });
}

Status CoordinatorService::LeaseInto(const std::string& worker, const std::string& who, v1::LeaseReply* rep,
                                     int max_jobs, const std::vector<std::string>& known_specs) {
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
  // The text travels only to a worker that does not name its key (an old worker names none); the lease
  // carries the key, so a worker that holds the spec costs no copy of its text.
  if (std::find(known_specs.begin(), known_specs.end(), g->spec_key) != known_specs.end()) {
    ToProto(LeasedWork{g->lease_id, g->sweep_id, g->job_id, "", g->spec_key, std::move(g->items), g->deadline}, rep);
    return Status::Ok();
  }
  auto spec = KeyedSpec(g->sweep_id, g->spec_key);
  if (!spec.ok()) return spec.status();
  ToProto(LeasedWork{g->lease_id, g->sweep_id, g->job_id, std::move(spec->spec_toml), spec->spec_key,
                     std::move(g->items), g->deadline},
          rep);
  return Status::Ok();
}

grpc::Status CoordinatorService::GetSpec(grpc::ServerContext* ctx, const v1::SpecRequest* req, v1::SpecReply* rep) {
  return Serve(ctx, "GetSpec", Op::kLease, [&](const Caller&) -> Status {
    // A whole sweep id, as a lease names it (no prefixes: a worker never guesses).
    if (req->sweep_id().empty() || req->sweep_id().size() > limits::kMaxIdBytes ||
        req->sweep_id().find_first_not_of("0123456789abcdef") != std::string::npos)
      return Status::InvalidArgument(
          "sweep_id", "sweep_id must be 1 to " + std::to_string(limits::kMaxIdBytes) + " lowercase hex digits");
    auto spec = KeyedSpec(req->sweep_id(), "");
    if (!spec.ok()) return spec.status();
    ToProto(*spec, rep);
    return Status::Ok();
  });
}

grpc::Status CoordinatorService::Heartbeat(grpc::ServerContext* ctx, const v1::HeartbeatRequest* req,
                                           v1::HeartbeatReply*) {
  return Serve(ctx, "Heartbeat", Op::kHeartbeat, [&](const Caller& caller) -> Status {
    BISTABLE_RETURN_IF_ERROR(CheckLeaseId(req->lease_id()));
    return c_->Extend(req->lease_id(), caller.who);
  });
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
  return Serve(ctx, "Report", Op::kReport, [&](const Caller& caller) -> Status {
    std::string who = caller.who;
    if (!req->lease_next_for().empty()) BISTABLE_RETURN_IF_ERROR(tokens_.Check(ctx, Op::kLease, &who));
    BISTABLE_RETURN_IF_ERROR(CheckLeaseId(req->lease_id()));
    if (req->catalog_hash() != CatalogHash())
      return Status::FailedPrecondition(
          "the report's metric catalog differs from this coordinator's (a worker of another build?): its records would "
          "be stored under the wrong names; run workers of the coordinator's version");
    auto known = KnownSpecsFromProto(req->next_known_specs(), "next_known_specs");  // refused before anything is stored
    if (!known.ok()) return known.status();
    // The coordinator checks the lease, its job's size and layout and every value's domain before it
    // copies anything out of the request.
    BISTABLE_RETURN_IF_ERROR(c_->Report(req->lease_id(), req->record_width(), req->values().data(),
                                        static_cast<size_t>(req->values_size()), who));
    if (req->lease_next_for().empty()) return Status::Ok();
    // The report is stored; a failure to lease now is not the report's failure (the worker polls).
    if (Status st = LeaseInto(req->lease_next_for(), who, rep->mutable_next(), req->next_max_jobs(), *known);
        !st.ok()) {
      rep->mutable_next()->Clear();
      rep->mutable_next()->set_has_job(false);
    }
    return Status::Ok();
  });
}

grpc::Status CoordinatorService::Release(grpc::ServerContext* ctx, const v1::ReleaseRequest* req, v1::ReleaseReply*) {
  return Serve(ctx, "Release", Op::kRelease, [&](const Caller& caller) -> Status {
    BISTABLE_RETURN_IF_ERROR(CheckLeaseId(req->lease_id()));
    return c_->Release(req->lease_id(), caller.who);
  });
}

grpc::Status CoordinatorService::ListWorkers(grpc::ServerContext* ctx, const v1::ListWorkersRequest*,
                                             v1::ListWorkersReply* rep) {
  return Serve(ctx, "ListWorkers", Op::kWorkers, [&](const Caller&) -> Status {
    for (const WorkerInfo& w : c_->Workers()) ToProto(w, rep->add_workers());
    return Status::Ok();
  });
}

grpc::Status CoordinatorService::FetchMap(grpc::ServerContext* ctx, const v1::FetchMapRequest* req,
                                          grpc::ServerWriter<v1::FileChunk>* writer) {
  return Serve(ctx, "FetchMap", Op::kMap, [&](const Caller& caller) -> grpc::Status {
    auto map = PublishedMap(req->id());
    if (!map.ok()) return Answer(ctx, "FetchMap", map.status());
    // The open descriptor keeps this version of the file: a republication (rename) meanwhile does not
    // mix two files into one stream. (The file's bytes are streamed as they are: no HDF5 is opened.)
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
      sha.Update(std::string_view(buf.data(), n));
      offset += n;
      const bool last = n < buf.size() || offset >= total;
      std::string digest;
      if (last) {
        if (offset != total)
          return Answer(ctx, "FetchMap",
                        Status::IoError("map", "the map of sweep " + map->first + " changed size while read"));
        digest = sha.HexDigest();
      }
      v1::FileChunk chunk;
      ToProto(MapChunk{map->first, offset - n, total, std::string_view(buf.data(), n), digest}, &chunk);
      if (!writer->Write(chunk)) return grpc::Status(grpc::StatusCode::CANCELLED, "client went away");
      if (last) break;
    }
    log::Event(log::Level::kInfo, "map.fetched",
               {{"sweep", map->first},
                {"bytes", static_cast<long long>(total)},
                {"identity", caller.who},
                {"peer", ctx->peer()},
                {"ms", std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count()}});
    return grpc::Status::OK;
  });
}

}  // namespace bistable
