// Whether a network address ("host:port", "[v6]:port", "unix:path") is this machine only: decided on the
// address, not the text — the host must be an IP literal in 127.0.0.0/8 or ::1 (v4-mapped included), the
// name "localhost", or a unix socket; any other name counts as not loopback. Used by the coordinator (what
// it may listen on without TLS and tokens) and by clients (where a bearer token may go in plaintext).
#ifndef BISTABLE_BASE_ADDRESS_H_
#define BISTABLE_BASE_ADDRESS_H_

#include <string>

namespace bistable {

bool IsLoopbackAddress(const std::string& address);

}  // namespace bistable

#endif  // BISTABLE_BASE_ADDRESS_H_
