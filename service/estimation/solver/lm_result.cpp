#include "estimation/solver/lm_result.h"

namespace rilo {

const char* toString(LmStatus s) {
  switch (s) {
    case LmStatus::kErrorTolerance:
      return "error tolerance";
    case LmStatus::kGradientTolerance:
      return "gradient tolerance";
    case LmStatus::kStepTolerance:
      return "step tolerance";
    case LmStatus::kMaxIterations:
      return "max iterations";
    case LmStatus::kLambdaMaxReached:
      return "lambda max reached";
    case LmStatus::kNonFiniteError:
      return "non-finite error";
    case LmStatus::kLinearSolverFailure:
      return "linear solver failure";
    case LmStatus::kCancelled:
      return "cancelled";
  }
  return "unknown";
}

}  // namespace rilo
