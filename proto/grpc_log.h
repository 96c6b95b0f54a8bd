// gRPC's own log lines (its core: TLS handshakes, transports, name resolution) as events of the process's
// structured log — event "grpc.log" with the severity as the level and file, line and message as fields — so a
// service started with --log-format json writes JSON lines only, and gRPC's messages are cleaned and bounded
// like every other field instead of going to stderr as raw text.
#ifndef BISTABLE_PROTO_GRPC_LOG_H_
#define BISTABLE_PROTO_GRPC_LOG_H_

namespace bistable {

// Call once, after log::Configure and before the first gRPC object is made.
void RouteGrpcLogsToTheLog();

}  // namespace bistable

#endif  // BISTABLE_PROTO_GRPC_LOG_H_
