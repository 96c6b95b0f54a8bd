// Bearer tokens with roles for the coordinator. The tokens file holds one token per line as
// "<role> <sha256-hex-of-token> [name]" (roles: viewer, client, worker, admin; '#' starts a comment), so the
// file never contains a usable token; tokens are never logged. Without a tokens file (loopback
// only) every call is allowed: a single-user local service.
// Permissions: viewer — read only: status, watch, list, map, workers (and the dashboard, server/dashboard.h);
// client — those and submit, cancel of sweeps it submitted; worker — register, lease, heartbeat, report,
// release; admin — everything. The same tokens and roles guard gRPC calls (Check) and HTTP requests
// (CheckBearer on the Authorization header or the dashboard's cookie).
#ifndef BISTABLE_SERVER_AUTH_H_
#define BISTABLE_SERVER_AUTH_H_

#include <map>
#include <mutex>
#include <string>

#include <grpcpp/grpcpp.h>

#include "base/address.h"  // IsLoopbackAddress (callers of auth decide exposure by it)
#include "base/sha256.h"
#include "base/status.h"

namespace bistable {

enum class Role { kViewer, kClient, kWorker, kAdmin };
enum class Op { kSubmit, kStatus, kCancel, kList, kMap, kWorkers, kRegister, kLease, kHeartbeat, kReport, kRelease };

// A fresh random token (64 hex digits).
std::string NewToken();

class TokenStore {
 public:
  // Empty store: auth off.
  TokenStore() = default;
  // Reads a tokens file ('<role> <sha256-of-token> [name]' per line). Refused (InvalidArgument naming
  // the file and its mode) when every user may write it: anyone could add an admin token. Used, with
  // lax_mode() set, when the group may write it or every user may read it (hashes and names only).
  static StatusOr<TokenStore> Load(const std::string& path);
  bool enabled() const { return !by_hash_.empty(); }
  // The loaded file's permission bits ("0664") when the group may write it or every user may read it, the
  // caller's to warn of with lax_reason() ("the group may write it; chmod 600 ..."); "" otherwise (0600,
  // 0640, 0400, ...).
  const std::string& lax_mode() const { return lax_mode_; }
  const std::string& lax_reason() const { return lax_reason_; }
  // Checks the call's "authorization: Bearer <token>" metadata for `op`; on success *who is the
  // token's identity — its name, or "token:<first 12 hex digits of its hash>" when unnamed, so two
  // unnamed tokens are two owners — and *role its role (admin when auth is off, identity "local").
  // Unauthenticated vs PermissionDenied, with the reason.
  Status Check(const grpc::ServerContext* ctx, Op op, std::string* who, Role* role = nullptr) const;
  // The same for a bare token (an HTTP request's "Bearer <token>" or cookie value; "" = none given).
  Status CheckToken(const std::string& token, Op op, std::string* who, Role* role = nullptr) const;

 private:
  struct Entry {
    Role role;
    std::string name;
  };
  std::map<std::string, Entry> by_hash_;
  std::string lax_mode_, lax_reason_;
};

const char* RoleName(Role r);

// A token's name in the tokens file (and `bistable token --name`): "" or at most 64 visible ASCII
// characters without ':' — it is an owner in the index and in log lines. InvalidArgument(`field`).
Status CheckTokenName(const std::string& name, const std::string& field);

}  // namespace bistable

#endif  // BISTABLE_SERVER_AUTH_H_
