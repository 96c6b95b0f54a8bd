#include "proto/grpc_log.h"

#include <grpc/support/log.h>

#include "base/log.h"

namespace bistable {
namespace {

void ToTheLog(gpr_log_func_args* a) {
  if (a == nullptr) return;
  const log::Level level = a->severity == GPR_LOG_SEVERITY_ERROR  ? log::Level::kError
                           : a->severity == GPR_LOG_SEVERITY_INFO ? log::Level::kInfo
                                                                  : log::Level::kDebug;
  log::Event(level, "grpc.log",
             {{"file", a->file ? a->file : ""}, {"line", a->line}, {"message", a->message ? a->message : ""}});
}

}  // namespace

void RouteGrpcLogsToTheLog() { gpr_set_log_function(ToTheLog); }

}  // namespace bistable
