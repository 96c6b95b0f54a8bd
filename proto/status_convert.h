// The one place where Status and grpc::Status meet (after Arrow Flight's util_internal.cc): an
// exhaustive switch each way, so handlers only decode, call, convert.
#ifndef BISTABLE_PROTO_STATUS_CONVERT_H_
#define BISTABLE_PROTO_STATUS_CONVERT_H_

#include <grpcpp/grpcpp.h>

#include "base/status.h"

namespace bistable {

grpc::Status ToGrpcStatus(const Status& s);
Status FromGrpcStatus(const grpc::Status& s);
// The code's name as gRPC spells it ("PERMISSION_DENIED"): metrics labels and log lines.
const char* GrpcCodeName(grpc::StatusCode c);

}  // namespace bistable

#endif  // BISTABLE_PROTO_STATUS_CONVERT_H_
