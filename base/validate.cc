#include "base/validate.h"

#include <cmath>
#include <sstream>

namespace bistable {

std::string FormatNumber(double v) {
  std::ostringstream os;
  os.precision(10);
  os << v;
  return os.str();
}

Status Violates(const std::string& field, double v, const std::string& bound) {
  return Status::InvalidArgument(field, field + " = " + FormatNumber(v) + " violates " + field + " " + bound);
}

Status CheckFinite(const std::string& field, double v) {
  return std::isfinite(v) ? Status::Ok() : Violates(field, v, "finite");
}

Status CheckPositive(const std::string& field, double v) {
  BISTABLE_RETURN_IF_ERROR(CheckFinite(field, v));
  return v > 0 ? Status::Ok() : Violates(field, v, "> 0");
}

Status CheckNonNegative(const std::string& field, double v) {
  BISTABLE_RETURN_IF_ERROR(CheckFinite(field, v));
  return v >= 0 ? Status::Ok() : Violates(field, v, ">= 0");
}

}  // namespace bistable
