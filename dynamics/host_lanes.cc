#include "dynamics/host_lanes.h"

#include "base/cpus.h"
#include "dynamics/lanes.h"

#ifndef BISTABLE_MARCH_NATIVE
#define BISTABLE_MARCH_NATIVE 0
#endif

namespace bistable {

HostLanes ThisHostLanes() {
  HostLanes h;
  h.cpu_model = CpuModelName();
  h.isa = kLaneIsa;
  h.cpu_isa = CpuVectorIsa();
  h.march = BISTABLE_MARCH_NATIVE ? "native" : "x86-64-v3";
  h.lanes = kSweepLanes;
  return h;
}

std::string HostLanesLine(const HostLanes& h) {
  std::string line = "cpu: " + h.cpu_model + " | isa: " + h.isa;
  if (h.cpu_isa != h.isa) line += " (the CPU has " + h.cpu_isa + ")";
  line += " | lanes: " + std::to_string(h.lanes) + " (fixed at compile time: -march=" + h.march;
  if (h.isa == "scalar") line += ", emulated lane by lane";
  return line + ")";
}

}  // namespace bistable
