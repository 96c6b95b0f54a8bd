// grpc.health.v1, the standard gRPC health protocol, on both sides. HealthService is registered on the
// coordinator's server and, with StartHealthServer, alone on a plaintext address of its own (for
// Kubernetes' gRPC probes, which cannot speak TLS, and for the worker, which has no server otherwise).
// Clients: CheckHealth (`bistable health`).
#ifndef BISTABLE_PROTO_HEALTH_H_
#define BISTABLE_PROTO_HEALTH_H_

#include <atomic>
#include <map>
#include <memory>
#include <mutex>
#include <string>

#include <grpcpp/grpcpp.h>

#include "base/status.h"
#include "health.grpc.pb.h"
#include "proto/channel.h"

namespace bistable {

class HealthService final : public grpc::health::v1::Health::Service {
 public:
  // Serving status of `service` ("" is the whole server). Unknown services answer NOT_FOUND.
  void Set(const std::string& service, bool serving);
  // Every service NOT_SERVING, and watches end (call before the server shuts down).
  void Shutdown();

  grpc::Status Check(grpc::ServerContext*, const grpc::health::v1::HealthCheckRequest*,
                     grpc::health::v1::HealthCheckResponse*) override;
  // Sends the status now and whenever it changes (checked every 0.5 s) until the caller leaves.
  grpc::Status Watch(grpc::ServerContext*, const grpc::health::v1::HealthCheckRequest*,
                     grpc::ServerWriter<grpc::health::v1::HealthCheckResponse>*) override;

 private:
  int StatusOf(const std::string& service) const;  // a ServingStatus value
  mutable std::mutex mu_;
  std::map<std::string, bool> serving_;
  std::atomic<bool> shutdown_{false};
};

// A server with only `health` on `address` (plaintext; port 0 picks one, *port says which).
StatusOr<std::unique_ptr<grpc::Server>> StartHealthServer(const std::string& address, HealthService* health, int* port);

// "SERVING", "NOT_SERVING", "SERVICE_UNKNOWN" (NOT_FOUND from the server) or an error.
StatusOr<std::string> CheckHealth(const ConnectOptions& o, const std::string& service, double timeout_seconds);

}  // namespace bistable

#endif  // BISTABLE_PROTO_HEALTH_H_
