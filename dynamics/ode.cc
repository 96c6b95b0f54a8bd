#include "dynamics/ode.h"

namespace bistable {

const char* OdeTerminationName(OdeTermination t) {
  switch (t) {
    case OdeTermination::kOk:
      return "ok";
    case OdeTermination::kStepSizeUnderflow:
      return "step_size_underflow";
    case OdeTermination::kMaxSteps:
      return "max_steps";
    case OdeTermination::kNonFinite:
      return "non_finite";
  }
  return "?";
}

}  // namespace bistable
