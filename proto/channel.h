// Client-side connection pieces shared by the worker and the CLI: channels (plain on loopback, TLS
// with a CA file otherwise) and bearer tokens on every call.
#ifndef BISTABLE_PROTO_CHANNEL_H_
#define BISTABLE_PROTO_CHANNEL_H_

#include <memory>
#include <string>

#include <grpcpp/grpcpp.h>

#include "base/status.h"

namespace bistable {

struct ConnectOptions {
  std::string address;
  std::string tls_ca;      // PEM file of the CA that signed the coordinator's certificate ("" = plaintext)
  std::string token;       // bearer token ("" = none)
};

// Reads the token from `token_file`, else from $BISTABLE_TOKEN; "" when neither is set.
StatusOr<std::string> LoadToken(const std::string& token_file);
StatusOr<std::shared_ptr<grpc::Channel>> MakeChannel(const ConnectOptions& o);
// A context with a deadline (seconds ≤ 0: none) and the bearer token.
std::unique_ptr<grpc::ClientContext> CallContext(const ConnectOptions& o, double seconds);

}  // namespace bistable

#endif  // BISTABLE_PROTO_CHANNEL_H_
