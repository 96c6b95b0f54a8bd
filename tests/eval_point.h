// Test helper shared by the dynamics tests: a point that must evaluate.
#ifndef BISTABLE_TESTS_EVAL_POINT_H_
#define BISTABLE_TESTS_EVAL_POINT_H_

#include <gtest/gtest.h>

#include "dynamics/point.h"

namespace bistable {

// The point's result; a failed expectation (with the status) and an empty result when it did not evaluate.
inline PointResult Eval(const PointSpec& s) {
  auto r = EvaluatePoint(s);
  EXPECT_TRUE(r.ok()) << r.status().ToString();
  return r.ok() ? *r : PointResult{};
}

}  // namespace bistable

#endif  // BISTABLE_TESTS_EVAL_POINT_H_
