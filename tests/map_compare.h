// Byte-for-byte comparison of the metric datasets of two map files (tests).
#ifndef BISTABLE_TESTS_MAP_COMPARE_H_
#define BISTABLE_TESTS_MAP_COMPARE_H_

#include <cstring>
#include <string>

#include <gtest/gtest.h>

#include "storage/map_file.h"

namespace bistable_test {

inline void ExpectSameMaps(const std::string& a, const std::string& b) {
  for (const char* metric : {"frf_db", "lle", "motion", "period", "hd_index", "edr_t", "hd_peak_freq"}) {
    auto x = bistable::ReadMapMetric(a, metric);
    auto y = bistable::ReadMapMetric(b, metric);
    ASSERT_TRUE(x.ok() && y.ok()) << metric;
    ASSERT_EQ(x->values.size(), y->values.size());
    EXPECT_EQ(std::memcmp(x->values.data(), y->values.data(), x->values.size() * sizeof(double)), 0) << metric;
  }
}

}  // namespace bistable_test

#endif  // BISTABLE_TESTS_MAP_COMPARE_H_
