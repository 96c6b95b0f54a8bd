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
  std::string tls_ca;            // PEM file of the CA that signed the coordinator's certificate ("" = plaintext)
  std::string token;             // bearer token ("" = none)
  bool insecure_remote = false;  // allow the token in plaintext to an address that is not loopback
};

// Whether `token` may be sent as a bearer token: "" (none) or 1 to limits::kMaxTokenBytes visible ASCII
// characters. A newline, NUL or other control byte would make gRPC log the whole metadata and abort the
// process; InvalidArgument(`field`) names the offending byte's position and kind, never the token.
Status CheckBearerToken(const std::string& token, const std::string& field);
// Reads the token from `token_file`, else from $BISTABLE_TOKEN; "" when neither is set. Trailing white
// space is dropped; the rest must pass CheckBearerToken (field "token-file" or "BISTABLE_TOKEN").
StatusOr<std::string> LoadToken(const std::string& token_file);
// Checks o.token (CheckBearerToken, field "token") before anything else, and refuses to send a token
// in plaintext (no tls_ca) to an address that is not loopback (base/address.h) unless
// o.insecure_remote: anyone on the path would read it (InvalidArgument "insecure-remote", saying why).
StatusOr<std::shared_ptr<grpc::Channel>> MakeChannel(const ConnectOptions& o);
// A context with a deadline (seconds ≤ 0: none) and the bearer token.
std::unique_ptr<grpc::ClientContext> CallContext(const ConnectOptions& o, double seconds);

}  // namespace bistable

#endif  // BISTABLE_PROTO_CHANNEL_H_
