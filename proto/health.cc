#include "proto/health.h"

#include <chrono>
#include <thread>

#include "proto/status_convert.h"

namespace bistable {

using grpc::health::v1::HealthCheckRequest;
using grpc::health::v1::HealthCheckResponse;

constexpr size_t kMaxServiceNameBytes = 200;

void HealthService::Set(const std::string& service, bool serving) {
  std::lock_guard<std::mutex> lock(mu_);
  serving_[service] = serving && !shutdown_;
}

void HealthService::Shutdown() {
  std::lock_guard<std::mutex> lock(mu_);
  shutdown_ = true;
  for (auto& [name, s] : serving_) s = false;
}

int HealthService::StatusOf(const std::string& service) const {
  std::lock_guard<std::mutex> lock(mu_);
  auto it = serving_.find(service);
  if (it == serving_.end()) return HealthCheckResponse::SERVICE_UNKNOWN;
  return it->second ? HealthCheckResponse::SERVING : HealthCheckResponse::NOT_SERVING;
}

grpc::Status HealthService::Check(grpc::ServerContext*, const HealthCheckRequest* req, HealthCheckResponse* rep) {
  if (req->service().size() > kMaxServiceNameBytes)
    return {grpc::StatusCode::INVALID_ARGUMENT, "service name too long"};
  const int st = StatusOf(req->service());
  if (st == HealthCheckResponse::SERVICE_UNKNOWN) return {grpc::StatusCode::NOT_FOUND, "unknown service"};
  rep->set_status(static_cast<HealthCheckResponse::ServingStatus>(st));
  return grpc::Status::OK;
}

grpc::Status HealthService::Watch(grpc::ServerContext* ctx, const HealthCheckRequest* req,
                                  grpc::ServerWriter<HealthCheckResponse>* writer) {
  if (req->service().size() > kMaxServiceNameBytes)
    return {grpc::StatusCode::INVALID_ARGUMENT, "service name too long"};
  int last = -1;
  while (!ctx->IsCancelled()) {
    const int st = StatusOf(req->service());
    if (st != last) {
      HealthCheckResponse rep;
      rep.set_status(static_cast<HealthCheckResponse::ServingStatus>(st));
      if (!writer->Write(rep)) break;
      last = st;
    }
    if (shutdown_) break;
    std::this_thread::sleep_for(std::chrono::milliseconds(500));
  }
  return grpc::Status::OK;
}

StatusOr<std::unique_ptr<grpc::Server>> StartHealthServer(const std::string& address, HealthService* health,
                                                          int* port) {
  grpc::ServerBuilder b;
  b.AddListeningPort(address, grpc::InsecureServerCredentials(), port);
  b.RegisterService(health);
  b.SetMaxReceiveMessageSize(4096);                   // a health request is a service name
  b.AddChannelArgument(GRPC_ARG_ALLOW_REUSEPORT, 0);  // a port in use is an error, not shared
  grpc::ResourceQuota quota("bistable-health");
  quota.SetMaxThreads(16);  // watches hold a thread each: bounded
  b.SetResourceQuota(quota);
  std::unique_ptr<grpc::Server> s = b.BuildAndStart();
  if (!s || *port == 0)
    return Status::IoError(
        "health", "cannot listen on " + address + " for health checks (in use, or not an address of this host)");
  return s;
}

StatusOr<std::string> CheckHealth(const ConnectOptions& o, const std::string& service, double timeout_seconds) {
  auto ch = MakeChannel(o);
  if (!ch.ok()) return ch.status();
  auto stub = grpc::health::v1::Health::NewStub(*ch);
  auto ctx = CallContext(o, timeout_seconds);
  HealthCheckRequest req;
  req.set_service(service);
  HealthCheckResponse rep;
  const grpc::Status st = stub->Check(ctx.get(), req, &rep);
  if (st.error_code() == grpc::StatusCode::NOT_FOUND) return std::string("SERVICE_UNKNOWN");
  if (st.error_code() == grpc::StatusCode::UNAVAILABLE || st.error_code() == grpc::StatusCode::DEADLINE_EXCEEDED)
    return Status::IoError("coordinator", "cannot reach " + o.address + " (" + st.error_message() + ")");
  if (!st.ok()) return FromGrpcStatus(st);
  return HealthCheckResponse::ServingStatus_Name(rep.status());
}

}  // namespace bistable
