// Field checks shared by every options struct: each returns InvalidArgument naming the field and the
// bound it violates, in one format: "alpha = -1 violates alpha > 0".
#ifndef BISTABLE_BASE_VALIDATE_H_
#define BISTABLE_BASE_VALIDATE_H_

#include <string>

#include "base/status.h"

namespace bistable {

std::string FormatNumber(double v);
// "<field> = <v> violates <field> <bound>".
Status Violates(const std::string& field, double v, const std::string& bound);
Status CheckFinite(const std::string& field, double v);
Status CheckPositive(const std::string& field, double v);     // finite and > 0
Status CheckNonNegative(const std::string& field, double v);  // finite and >= 0

}  // namespace bistable

#endif  // BISTABLE_BASE_VALIDATE_H_
