#include "base/status.h"

namespace bistable {

std::string Status::ToString() const {
  const char* name = "ok";
  switch (code_) {
    case Code::kOk:
      return "ok";
    case Code::kInvalidArgument:
      name = "invalid argument";
      break;
    case Code::kNotFound:
      name = "not found";
      break;
    case Code::kFailedPrecondition:
      name = "failed precondition";
      break;
    case Code::kInternal:
      name = "internal error";
      break;
    case Code::kIoError:
      name = "i/o error";
      break;
    case Code::kUnauthenticated:
      name = "unauthenticated";
      break;
    case Code::kPermissionDenied:
      name = "permission denied";
      break;
  }
  std::string s = name;
  if (!field_.empty()) return s + " (" + field_ + ": " + message_ + ")";
  return s + ": " + message_;
}

}  // namespace bistable
