#include "proto/channel.h"

#include <chrono>
#include <cstdlib>
#include <fstream>
#include <sstream>

#include "base/file.h"
#include "base/limits.h"

namespace bistable {

StatusOr<std::string> LoadToken(const std::string& token_file) {
  std::string t;
  if (!token_file.empty()) {
    auto text = ReadTextFile(token_file, "token-file", limits::kMaxTokenFileBytes);
    if (!text.ok()) return text.status();
    t = *text;
  } else if (const char* env = std::getenv("BISTABLE_TOKEN")) {
    t = env;
  }
  while (!t.empty() && (t.back() == '\n' || t.back() == '\r' || t.back() == ' ')) t.pop_back();
  return t;
}

StatusOr<std::shared_ptr<grpc::Channel>> MakeChannel(const ConnectOptions& o) {
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
