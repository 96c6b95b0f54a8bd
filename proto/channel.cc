#include "proto/channel.h"

#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <sstream>

#include "base/address.h"
#include "base/file.h"
#include "base/limits.h"
#include "base/names.h"

namespace bistable {

Status CheckBearerToken(const std::string& token, const std::string& field) {
  // Never echo the token (not even part of it): only where the bad byte is and what it is.
  const std::string rule = "a token is 1 to " + std::to_string(limits::kMaxTokenBytes) +
                           " visible ASCII characters (0x21-0x7e); the token is not shown";
  if (token.size() > limits::kMaxTokenBytes)
    return Status::InvalidArgument(field,
                                   "the token is " + std::to_string(token.size()) + " bytes long (" + rule + ")");
  for (size_t i = 0; i < token.size(); ++i) {
    const auto c = static_cast<unsigned char>(token[i]);
    if (c >= 0x21 && c <= 0x7e) continue;
    char hex[8];
    std::snprintf(hex, sizeof hex, "0x%02x", c);
    const char* what = c == 0                  ? "a NUL byte"
                       : c == ' '              ? "a space"
                       : c < 0x20 || c == 0x7f ? "a control byte"
                                               : "a non-ASCII byte";
    return Status::InvalidArgument(field, "the token holds " + std::string(what) + " (" + hex + ") at byte " +
                                              std::to_string(i + 1) + " (" + rule + ")");
  }
  return Status::Ok();
}

StatusOr<std::string> LoadToken(const std::string& token_file) {
  std::string t, field;
  if (!token_file.empty()) {
    auto text = ReadTextFile(token_file, "token-file", limits::kMaxTokenFileBytes);
    if (!text.ok()) return text.status();
    t = *text;
    field = "token-file";
  } else if (const char* env = std::getenv("BISTABLE_TOKEN")) {
    t = env;
    field = "BISTABLE_TOKEN";
  }
  while (!t.empty() && (t.back() == '\n' || t.back() == '\r' || t.back() == ' ' || t.back() == '\t')) t.pop_back();
  if (Status st = CheckBearerToken(t, field); !st.ok()) return st;
  return t;
}

StatusOr<std::shared_ptr<grpc::Channel>> MakeChannel(const ConnectOptions& o) {
  // Every connection (CLI, worker, Python, health checks) goes through here: a token gRPC would abort
  // on (and log) is refused before any call is made.
  if (Status st = CheckBearerToken(o.token, "token"); !st.ok()) return st;
  if (!o.token.empty() && o.tls_ca.empty() && !o.insecure_remote && !IsLoopbackAddress(o.address))
    return Status::InvalidArgument(
        "insecure-remote", "refusing to send the bearer token in plaintext to " + Printable(o.address, 128) +
                               ", which is not a loopback address: anyone on the path could read it and "
                               "use it; give --tls-ca (the coordinator's CA), or --insecure-remote to send it anyway");
  grpc::ChannelArguments args;
  args.SetMaxReceiveMessageSize(256 << 20);
  args.SetInt(GRPC_ARG_INITIAL_RECONNECT_BACKOFF_MS, 100);
  args.SetInt(GRPC_ARG_MAX_RECONNECT_BACKOFF_MS, 2000);
  // A coordinator whose host died or whose network partitioned (no FIN, no RST) is noticed within ~30 s
  // on an open call (a status watch, a fetch stream) instead of never: HTTP/2 pings during calls.
  args.SetInt(GRPC_ARG_KEEPALIVE_TIME_MS, 20000);
  args.SetInt(GRPC_ARG_KEEPALIVE_TIMEOUT_MS, 10000);
  if (o.tls_ca.empty()) return grpc::CreateCustomChannel(o.address, grpc::InsecureChannelCredentials(), args);
  auto ca = ReadTextFile(o.tls_ca, "tls-ca", limits::kMaxPemFileBytes);
  if (!ca.ok()) return ca.status();
  grpc::SslCredentialsOptions ssl;
  ssl.pem_root_certs = *ca;
  return grpc::CreateCustomChannel(o.address, grpc::SslCredentials(ssl), args);
}

std::unique_ptr<grpc::ClientContext> CallContext(const ConnectOptions& o, double seconds) {
  auto c = std::make_unique<grpc::ClientContext>();
  if (seconds > 0)
    c->set_deadline(std::chrono::system_clock::now() + std::chrono::milliseconds(static_cast<long>(seconds * 1000)));
  if (!o.token.empty()) c->AddMetadata("authorization", "Bearer " + o.token);
  return c;
}

}  // namespace bistable
