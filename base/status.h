// Status values at module boundaries (after leveldb's include/leveldb/status.h).
// A Status is either OK or carries a code, the field it concerns and a human message.
// Non-convergence of a numerical method is NOT a Status error: it is a result with a termination code.
#ifndef BISTABLE_BASE_STATUS_H_
#define BISTABLE_BASE_STATUS_H_

#include <optional>
#include <string>
#include <utility>

namespace bistable {

class Status {
 public:
  enum class Code {
    kOk = 0,
    kInvalidArgument,
    kNotFound,
    kFailedPrecondition,
    kInternal,
    kIoError,
    kUnauthenticated,   // no or unknown credentials
    kPermissionDenied,  // valid credentials, role not allowed
  };

  Status() = default;
  static Status Ok() { return Status(); }
  // `field` names the offending input ("alpha", "window.t_keep"); `why` states the bound it violates.
  static Status InvalidArgument(std::string field, std::string why) {
    return Status(Code::kInvalidArgument, std::move(field), std::move(why));
  }
  static Status NotFound(std::string what) { return Status(Code::kNotFound, "", std::move(what)); }
  static Status FailedPrecondition(std::string why) { return Status(Code::kFailedPrecondition, "", std::move(why)); }
  static Status Internal(std::string why) { return Status(Code::kInternal, "", std::move(why)); }
  static Status IoError(std::string what, std::string why) {
    return Status(Code::kIoError, std::move(what), std::move(why));
  }
  static Status Unauthenticated(std::string why) { return Status(Code::kUnauthenticated, "", std::move(why)); }
  static Status PermissionDenied(std::string why) { return Status(Code::kPermissionDenied, "", std::move(why)); }

  bool ok() const { return code_ == Code::kOk; }
  Code code() const { return code_; }
  const std::string& field() const { return field_; }
  const std::string& message() const { return message_; }
  // "invalid argument (alpha: alpha = -1 violates alpha > 0)".
  std::string ToString() const;

 private:
  Status(Code code, std::string field, std::string message)
      : code_(code), field_(std::move(field)), message_(std::move(message)) {}
  Code code_ = Code::kOk;
  std::string field_;
  std::string message_;
};

// A value or the Status explaining why there is none.
template <class T>
class StatusOr {
 public:
  StatusOr(T value) : value_(std::move(value)) {}          // NOLINT: implicit by design
  StatusOr(Status status) : status_(std::move(status)) {}  // NOLINT: must not be OK
  bool ok() const { return status_.ok(); }
  const Status& status() const { return status_; }
  const T& value() const& { return *value_; }
  T& value() & { return *value_; }
  T&& value() && { return std::move(*value_); }
  const T& operator*() const { return *value_; }
  const T* operator->() const { return &*value_; }

 private:
  Status status_;
  std::optional<T> value_;
};

#define BISTABLE_RETURN_IF_ERROR(expr) \
  do {                                 \
    ::bistable::Status _st = (expr);   \
    if (!_st.ok()) return _st;         \
  } while (0)

}  // namespace bistable

#endif  // BISTABLE_BASE_STATUS_H_
