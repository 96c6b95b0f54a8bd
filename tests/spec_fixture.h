// The sweep-spec fixture several suites share: a spec parsed from TOML text, the test failing with the
// parser's error (field and bound) when it does not parse.
#ifndef BISTABLE_TESTS_SPEC_FIXTURE_H_
#define BISTABLE_TESTS_SPEC_FIXTURE_H_

#include <string>

#include <gtest/gtest.h>

#include "engine/sweep_spec.h"

namespace bistable_test {

inline bistable::SweepSpec ParsedSpec(const std::string& toml, const std::string& name = "test.toml") {
  auto s = bistable::ParseSweepSpec(toml, name);
  EXPECT_TRUE(s.ok()) << s.status().ToString();
  return s.ok() ? *s : bistable::SweepSpec{};
}

}  // namespace bistable_test

#endif  // BISTABLE_TESTS_SPEC_FIXTURE_H_
