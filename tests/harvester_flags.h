// The measured bistable harvester (README of the data: base acceleration in g, laser volts / 10 = m/s)
// as the identify tests read it: its files and the flags of docs/identification.md's harvester runs.
#ifndef BISTABLE_TESTS_HARVESTER_FLAGS_H_
#define BISTABLE_TESTS_HARVESTER_FLAGS_H_

#include <string>

namespace bistable_test {

// A file of the harvester data (tests skip when it is absent); BISTABLE_MEASURED_DIR comes from CMake.
inline std::string HarvesterFile(const std::string& name) {
  return std::string(BISTABLE_MEASURED_DIR) + "/bistable-harvester/" + name;
}

// Input, output and the declared Duffing model per unit mass; columns are the caller's.
inline const char* const kHarvesterFlags =
    " --input-kind base_acceleration --input-scale 9.81 --output-kind velocity --output-scale 0.1"
    " --known m_main=1 --terms main.linear,main.stiffness_y3,main.viscous";

}  // namespace bistable_test

#endif  // BISTABLE_TESTS_HARVESTER_FLAGS_H_
