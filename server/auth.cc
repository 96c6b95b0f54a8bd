#include "server/auth.h"

#include <sys/stat.h>

#include <algorithm>
#include <cstdio>
#include <random>
#include <sstream>

#include "base/file.h"
#include "base/limits.h"
#include "base/names.h"

namespace bistable {

std::string NewToken() {
  std::random_device rd;  // /dev/urandom
  std::string t;
  char b[9];
  for (int i = 0; i < 8; ++i) std::snprintf(b, sizeof b, "%08x", rd()), t += b;
  return t;
}

Status CheckTokenName(const std::string& name, const std::string& field) {
  // The name is an owner in the index and in log lines: visible ASCII only (never echoed as given).
  if (name.size() > 64 || name.find(':') != std::string::npos || std::any_of(name.begin(), name.end(), [](char c) {
        return static_cast<unsigned char>(c) < 0x21 || static_cast<unsigned char>(c) > 0x7e;
      }))
    return Status::InvalidArgument(field,
                                   "name '" + Printable(name, 64) +
                                       "' violates name: at most 64 visible ASCII characters (0x21-0x7e) without ':'");
  return Status::Ok();
}

const char* RoleName(Role r) {
  switch (r) {
    case Role::kViewer:
      return "viewer";
    case Role::kClient:
      return "client";
    case Role::kWorker:
      return "worker";
    case Role::kAdmin:
      return "admin";
  }
  return "?";
}

StatusOr<TokenStore> TokenStore::Load(const std::string& path) {
  // A regular file within its limit (base/file: a FIFO or device neither blocks nor streams forever).
  auto text = ReadTextFile(path, "tokens", limits::kMaxTokensFileBytes);
  if (!text.ok()) return text.status();
  std::istringstream in(*text);
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
    if (role == "viewer")
      r = Role::kViewer;
    else if (role == "client")
      r = Role::kClient;
    else if (role == "worker")
      r = Role::kWorker;
    else if (role == "admin")
      r = Role::kAdmin;
    else
      return Status::InvalidArgument("tokens",
                                     where + ": role '" + role + "' violates role in {viewer, client, worker, admin}");
    if (digest.size() != 64 || digest.find_first_not_of("0123456789abcdef") != std::string::npos)
      return Status::InvalidArgument("tokens", where +
                                                   ": expected the token's SHA-256 as 64 lowercase hex digits "
                                                   "(`bistable token --role " +
                                                   role + "` prints such a line)");
    if (Status st = CheckTokenName(name, "tokens"); !st.ok())
      return Status::InvalidArgument("tokens", where + ": " + st.message());
    store.by_hash_[digest] = {r, name.empty() ? "token:" + digest.substr(0, 12) : name};
  }
  if (store.by_hash_.empty()) return Status::InvalidArgument("tokens", "tokens file '" + path + "' holds no tokens");
  // Who else may change or read it (stat follows a link: a Kubernetes Secret's file is one).
  struct stat st {};
  if (::stat(path.c_str(), &st) == 0) {
    char mode[8];
    std::snprintf(mode, sizeof mode, "%04o", static_cast<unsigned>(st.st_mode & 07777));
    if (st.st_mode & S_IWOTH)
      return Status::InvalidArgument("tokens", "tokens file '" + path + "' has mode " + mode +
                                                   ": every user may write it (and add an admin token); chmod 600 '" +
                                                   path + "' (640 for a group that reads it)");
    if (st.st_mode & (S_IWGRP | S_IROTH)) {
      store.lax_mode_ = mode;
      store.lax_reason_ = std::string(st.st_mode & S_IWGRP ? "the group may write it" : "") +
                          (st.st_mode & S_IWGRP && st.st_mode & S_IROTH ? " and " : "") +
                          (st.st_mode & S_IROTH ? "every user may read it" : "") +
                          "; chmod 600 (640 for a group that reads it)";
    }
  }
  return store;
}

Status TokenStore::Check(const grpc::ServerContext* ctx, Op op, std::string* who, Role* role) const {
  if (!enabled()) return CheckToken("", op, who, role);
  const auto& md = ctx->client_metadata();
  auto it = md.find("authorization");
  if (it == md.end()) return Status::Unauthenticated("missing 'authorization: Bearer <token>' metadata");
  const std::string value(it->second.data(), it->second.size());
  if (value.rfind("Bearer ", 0) != 0) return Status::Unauthenticated("authorization metadata is not 'Bearer <token>'");
  return CheckToken(value.substr(7), op, who, role);
}

Status TokenStore::CheckToken(const std::string& token, Op op, std::string* who, Role* role) const {
  if (!enabled()) {
    if (who) *who = "local";
    if (role) *role = Role::kAdmin;
    return Status::Ok();
  }
  if (token.empty()) return Status::Unauthenticated("missing token");
  auto e = by_hash_.find(Sha256Hex(token));
  if (e == by_hash_.end()) return Status::Unauthenticated("unknown token");
  if (who) *who = e->second.name;
  const Role r = e->second.role;
  if (role) *role = r;
  if (r == Role::kAdmin) return Status::Ok();
  const bool worker_op =
      op == Op::kRegister || op == Op::kLease || op == Op::kHeartbeat || op == Op::kReport || op == Op::kRelease;
  const bool read_op = op == Op::kStatus || op == Op::kList || op == Op::kMap || op == Op::kWorkers;
  if (r == Role::kViewer ? !read_op : worker_op != (r == Role::kWorker))
    return Status::PermissionDenied(std::string("a ") + RoleName(r) + " token may not make this call");
  return Status::Ok();
}

}  // namespace bistable
