#include "proto/coordinator_client.h"

#include <algorithm>

#include "base/limits.h"
#include "base/names.h"
#include "base/sha256.h"
#include "bistable.grpc.pb.h"
#include "proto/convert.h"
#include "proto/status_convert.h"

namespace bistable {

struct CoordinatorClient::Impl {
  std::unique_ptr<v1::Coordinator::Stub> stub;
};

CoordinatorClient::CoordinatorClient(ConnectOptions o, std::unique_ptr<Impl> impl)
    : o_(std::move(o)), impl_(std::move(impl)) {}
CoordinatorClient::~CoordinatorClient() = default;

StatusOr<std::unique_ptr<CoordinatorClient>> CoordinatorClient::Connect(const ConnectOptions& o) {
  auto ch = MakeChannel(o);
  if (!ch.ok()) return ch.status();
  auto impl = std::make_unique<Impl>();
  impl->stub = v1::Coordinator::NewStub(*ch);
  return std::unique_ptr<CoordinatorClient>(new CoordinatorClient(o, std::move(impl)));
}

namespace {

// A failed call as a Status; an unreachable coordinator is an IoError naming its address.
Status FromCall(const grpc::Status& s, const std::string& address) {
  if (s.error_code() == grpc::StatusCode::UNAVAILABLE || s.error_code() == grpc::StatusCode::DEADLINE_EXCEEDED)
    return Status::IoError("coordinator", "cannot reach " + address + " (" + s.error_message() + ")");
  return FromGrpcStatus(s);
}

}  // namespace

#define BISTABLE_RPC(call, seconds, req, rep)                                            \
  do {                                                                                   \
    const grpc::Status _s = impl_->stub->call(CallContext(o_, seconds).get(), req, rep); \
    if (!_s.ok()) return FromCall(_s, o_.address);                                       \
  } while (0)

StatusOr<CoordinatorClient::Submitted> CoordinatorClient::Submit(const std::string& spec_toml,
                                                                 const std::string& origin) {
  v1::SubmitRequest req;
  req.set_spec_toml(spec_toml);
  req.set_origin(origin);
  v1::SubmitReply rep;
  BISTABLE_RPC(Submit, 30, req, &rep);
  return FromProto(rep);
}

StatusOr<SweepInfo> CoordinatorClient::GetStatus(const std::string& id) {
  v1::StatusRequest req;
  req.set_id(id);
  v1::SweepStatus rep;
  BISTABLE_RPC(GetStatus, 30, req, &rep);
  return FromProto(rep);
}

StatusOr<SweepInfo> CoordinatorClient::Watch(const std::string& id,
                                             const std::function<bool(const SweepInfo&)>& on_status) {
  v1::StatusRequest req;
  req.set_id(id);
  auto ctx = CallContext(o_, 0);  // no deadline: the stream lasts as long as the sweep
  auto reader = impl_->stub->WatchStatus(ctx.get(), req);
  v1::SweepStatus st;
  SweepInfo last;
  while (reader->Read(&st)) {
    last = FromProto(st);
    if (!on_status(last)) {
      ctx->TryCancel();
      break;
    }
  }
  const grpc::Status s = reader->Finish();
  if (!s.ok() && s.error_code() != grpc::StatusCode::CANCELLED) return FromCall(s, o_.address);
  return last;
}

Status CoordinatorClient::Cancel(const std::string& id) {
  v1::CancelRequest req;
  req.set_id(id);
  v1::CancelReply rep;
  BISTABLE_RPC(Cancel, 30, req, &rep);
  return Status::Ok();
}

StatusOr<std::vector<WorkerInfo>> CoordinatorClient::Workers() {
  v1::ListWorkersRequest req;
  v1::ListWorkersReply rep;
  BISTABLE_RPC(ListWorkers, 30, req, &rep);
  std::vector<WorkerInfo> out;
  for (const auto& w : rep.workers()) out.push_back(FromProto(w));
  return out;
}

StatusOr<CoordinatorClient::MetricList> CoordinatorClient::ListMetrics(const std::string& id) {
  v1::MapRequest req;
  req.set_id(id);
  v1::MetricsReply rep;
  BISTABLE_RPC(ListMetrics, 60, req, &rep);
  return FromProto(rep);
}

StatusOr<MapArray> CoordinatorClient::GetMap(const std::string& id, const std::string& metric) {
  v1::MapRequest req;
  req.set_id(id);
  req.set_metric(metric);
  v1::MapReply rep;
  BISTABLE_RPC(GetMap, 120, req, &rep);
  return FromProto(rep);
}

StatusOr<std::vector<SweepInfo>> CoordinatorClient::ListSweeps() {
  v1::ListSweepsRequest req;
  v1::ListSweepsReply rep;
  BISTABLE_RPC(ListSweeps, 30, req, &rep);
  std::vector<SweepInfo> out;
  for (const auto& s : rep.sweeps()) out.push_back(FromProto(s));
  return out;
}

StatusOr<CoordinatorClient::Fetched> CoordinatorClient::FetchMap(const std::string& id,
                                                                 const std::function<Status(std::string_view)>& sink) {
  v1::FetchMapRequest req;
  req.set_id(id);
  auto ctx = CallContext(o_, 0);  // no deadline: a large map over a slow link takes what it takes
  auto reader = impl_->stub->FetchMap(ctx.get(), req);
  Fetched out;
  Sha256 sha;
  v1::FileChunk chunk;
  uint64_t total = 0;
  bool first = true, finished = false;
  auto refuse = [&](const std::string& why) {
    ctx->TryCancel();
    return Status::Internal("the coordinator's map stream is invalid: " + why);
  };
  while (reader->Read(&chunk)) {
    if (finished) return refuse("data after the checksum");
    if (first) {
      out.id = chunk.id();
      total = chunk.total_bytes();
      if (out.id.empty() || out.id.size() > limits::kMaxIdBytes ||
          out.id.find_first_not_of("0123456789abcdef") != std::string::npos)
        return refuse("the sweep id is not lowercase hex of at most " + std::to_string(limits::kMaxIdBytes) +
                      " digits");
      if (total > limits::kMaxFetchBytes)
        return refuse("the file is announced as " + std::to_string(total) + " bytes, over the limit of " +
                      std::to_string(limits::kMaxFetchBytes));
      first = false;
    }
    if (chunk.id() != out.id || chunk.total_bytes() != total) return refuse("the id or size changed mid-stream");
    if (chunk.offset() != out.bytes)
      return refuse("chunk at offset " + std::to_string(chunk.offset()) + ", expected " + std::to_string(out.bytes));
    if (chunk.data().size() > total - out.bytes) return refuse("more data than the announced size");
    sha.Update(chunk.data());
    out.bytes += chunk.data().size();
    if (Status st = sink(chunk.data()); !st.ok()) {
      ctx->TryCancel();
      return st;
    }
    if (!chunk.sha256().empty()) {
      finished = true;
      out.sha256 = sha.HexDigest();
      if (out.bytes != total)
        return refuse("the checksum came at " + std::to_string(out.bytes) + " of " + std::to_string(total) + " bytes");
      if (chunk.sha256() != out.sha256)
        return refuse("SHA-256 mismatch: received " + out.sha256 + ", the coordinator sent " +
                      Printable(chunk.sha256(), 80));
    }
  }
  const grpc::Status st = reader->Finish();
  if (!st.ok()) return FromCall(st, o_.address);
  if (!finished) return refuse("the stream ended without a checksum after " + std::to_string(out.bytes) + " bytes");
  return out;
}

StatusOr<double> CoordinatorClient::Register(const std::string& name, int threads) {
  v1::RegisterRequest req;
  req.set_name(name);
  req.set_threads(threads);
  v1::RegisterReply rep;
  BISTABLE_RPC(RegisterWorker, 5, req, &rep);
  // The worker heartbeats at a third of it: a NaN, negative or absurd period from a broken or hostile
  // coordinator is refused, not slept on.
  if (!(rep.lease_seconds() > 0 && rep.lease_seconds() <= limits::kMaxLeaseSeconds))
    return Status::InvalidArgument("lease_seconds",
                                   "the coordinator's lease_seconds = " + std::to_string(rep.lease_seconds()) +
                                       " violates lease_seconds in (0, " +
                                       std::to_string(static_cast<long>(limits::kMaxLeaseSeconds)) + "]");
  return rep.lease_seconds();
}

StatusOr<std::optional<CoordinatorClient::Lease>> CoordinatorClient::LeaseJob(
    const std::string& worker, int max_jobs, const std::vector<std::string>& known_specs) {
  v1::LeaseRequest req;
  req.set_worker(worker);
  req.set_max_jobs(max_jobs);
  for (const auto& k : known_specs) req.add_known_specs(k);
  v1::LeaseReply rep;
  BISTABLE_RPC(Lease, 10, req, &rep);
  return FromProto(rep);
}

StatusOr<SpecText> CoordinatorClient::GetSpec(const std::string& sweep_id) {
  v1::SpecRequest req;
  req.set_sweep_id(sweep_id);
  v1::SpecReply rep;
  BISTABLE_RPC(GetSpec, 30, req, &rep);
  auto spec = FromProto(rep);
  if (spec.ok() && spec->sweep_id != sweep_id)
    return Status::InvalidArgument(
        "spec", "the coordinator answered with the spec of sweep " + spec->sweep_id + " for " + sweep_id);
  return spec;
}

Status CoordinatorClient::Heartbeat(const std::string& lease_id) {
  v1::HeartbeatRequest req;
  req.set_lease_id(lease_id);
  v1::HeartbeatReply rep;
  BISTABLE_RPC(Heartbeat, 5, req, &rep);
  return Status::Ok();
}

Status CoordinatorClient::Report(const std::string& lease_id, const std::vector<PointRecord>& records,
                                 const std::string& lease_next_for, std::optional<Lease>* next, int next_max_jobs,
                                 const std::vector<std::string>& next_known_specs) {
  v1::ReportRequest req;
  req.set_lease_id(lease_id);
  ToProto(records, &req);
  req.set_lease_next_for(lease_next_for);
  req.set_next_max_jobs(next_max_jobs);
  for (const auto& k : next_known_specs) req.add_next_known_specs(k);
  v1::ReportReply rep;
  BISTABLE_RPC(Report, 30, req, &rep);
  if (next && rep.has_next()) {
    auto n = FromProto(rep.next());
    if (n.ok()) *next = std::move(*n);
  }
  return Status::Ok();
}

Status CoordinatorClient::Release(const std::string& lease_id) {
  v1::ReleaseRequest req;
  req.set_lease_id(lease_id);
  v1::ReleaseReply rep;
  BISTABLE_RPC(Release, 5, req, &rep);
  return Status::Ok();
}

#undef BISTABLE_RPC

}  // namespace bistable
