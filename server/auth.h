// Bearer tokens with roles for the coordinator. The tokens file holds one token per line as
// "<role> <sha256-hex-of-token> [name]" (roles: client, worker, admin; '#' starts a comment), so the
// file never contains a usable token; tokens are never logged. Without a tokens file (loopback
// only) every call is allowed: a single-user local service.
// Permissions: client — submit, status, watch, list, map, workers, cancel of sweeps it submitted;
// worker — register, lease, heartbeat, report, release; admin — everything.
#ifndef BISTABLE_SERVER_AUTH_H_
#define BISTABLE_SERVER_AUTH_H_

#include <map>
#include <mutex>
#include <string>

#include <grpcpp/grpcpp.h>

#include "dynamics/status.h"

namespace bistable {

enum class Role { kClient, kWorker, kAdmin };
enum class Op { kSubmit, kStatus, kCancel, kList, kMap, kWorkers, kRegister, kLease, kHeartbeat, kReport, kRelease };

std::string Sha256Hex(const std::string& data);
// A fresh random token (64 hex digits).
std::string NewToken();

class TokenStore {
 public:
  // Empty store: auth off.
  TokenStore() = default;
  static StatusOr<TokenStore> Load(const std::string& path);
  bool enabled() const { return !by_hash_.empty(); }
  // Checks the call's "authorization: Bearer <token>" metadata for `op`; on success *who is the
  // token's name (or its role when unnamed). Unauthenticated vs PermissionDenied, with the reason.
  Status Check(const grpc::ServerContext* ctx, Op op, std::string* who) const;

 private:
  struct Entry {
    Role role;
    std::string name;
  };
  std::map<std::string, Entry> by_hash_;
};

const char* RoleName(Role r);

}  // namespace bistable

#endif  // BISTABLE_SERVER_AUTH_H_
