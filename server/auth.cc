#include "server/auth.h"

#include <openssl/evp.h>

#include <cstdio>
#include <fstream>
#include <random>
#include <sstream>

namespace bistable {

std::string Sha256Hex(const std::string& data) {
  unsigned char md[EVP_MAX_MD_SIZE];
  unsigned int len = 0;
  EVP_Digest(data.data(), data.size(), md, &len, EVP_sha256(), nullptr);
  std::string hex;
  char b[3];
  for (unsigned i = 0; i < len; ++i) std::snprintf(b, sizeof b, "%02x", md[i]), hex += b;
  return hex;
}

std::string NewToken() {
  std::random_device rd;  // /dev/urandom
  std::string t;
  char b[9];
  for (int i = 0; i < 8; ++i) std::snprintf(b, sizeof b, "%08x", rd()), t += b;
  return t;
}

const char* RoleName(Role r) {
  switch (r) {
    case Role::kClient: return "client";
    case Role::kWorker: return "worker";
    case Role::kAdmin: return "admin";
  }
  return "?";
}

StatusOr<TokenStore> TokenStore::Load(const std::string& path) {
  std::ifstream in(path);
  if (!in) return Status::InvalidArgument("tokens", "cannot read tokens file '" + path + "'");
  TokenStore store;
  std::string line;
  int n = 0;
  while (std::getline(in, line)) {
    ++n;
    if (const size_t hash = line.find('#'); hash != std::string::npos) line.resize(hash);
    std::istringstream ss(line);
    std::string role, digest, name;
    if (!(ss >> role)) continue;
    ss >> digest >> name;
    const std::string where = "tokens file line " + std::to_string(n);
    Role r;
    if (role == "client") r = Role::kClient;
    else if (role == "worker") r = Role::kWorker;
    else if (role == "admin") r = Role::kAdmin;
    else return Status::InvalidArgument("tokens", where + ": role '" + role + "' violates role in {client, worker, admin}");
    if (digest.size() != 64 || digest.find_first_not_of("0123456789abcdef") != std::string::npos)
      return Status::InvalidArgument("tokens", where + ": expected the token's SHA-256 as 64 lowercase hex digits "
                                               "(`bistable token --role " + role + "` prints such a line)");
    store.by_hash_[digest] = {r, name.empty() ? role : name};
  }
  if (store.by_hash_.empty()) return Status::InvalidArgument("tokens", "tokens file '" + path + "' holds no tokens");
  return store;
}

Status TokenStore::Check(const grpc::ServerContext* ctx, Op op, std::string* who) const {
  if (!enabled()) {
    if (who) *who = "local";
    return Status::Ok();
  }
  const auto& md = ctx->client_metadata();
  auto it = md.find("authorization");
  if (it == md.end()) return Status::Unauthenticated("missing 'authorization: Bearer <token>' metadata");
  const std::string value(it->second.data(), it->second.size());
  if (value.rfind("Bearer ", 0) != 0) return Status::Unauthenticated("authorization metadata is not 'Bearer <token>'");
  auto e = by_hash_.find(Sha256Hex(value.substr(7)));
  if (e == by_hash_.end()) return Status::Unauthenticated("unknown token");
  if (who) *who = e->second.name;
  const Role r = e->second.role;
  if (r == Role::kAdmin) return Status::Ok();
  const bool worker_op = op == Op::kRegister || op == Op::kLease || op == Op::kHeartbeat || op == Op::kReport || op == Op::kRelease;
  if (worker_op != (r == Role::kWorker))
    return Status::PermissionDenied(std::string("a ") + RoleName(r) + " token may not make this call");
  return Status::Ok();
}

}  // namespace bistable
