// The lanes this build runs and the CPU it runs on, said in one place: the header line of every
// benchmark (bench/) and `bistable info`, and the provenance attributes of a map file (storage/).
// The lane width is kSweepLanes (dynamics/lanes.h), the engine's own: a property of the build (its
// -march), fixed at compile time; the CPU's model and vector unit are asked at run time, so a portable
// build on a wider CPU, or a native build copied to another machine, says so.
#ifndef BISTABLE_DYNAMICS_HOST_LANES_H_
#define BISTABLE_DYNAMICS_HOST_LANES_H_

#include <string>

namespace bistable {

struct HostLanes {
  std::string cpu_model;  // /proc/cpuinfo "model name" ("unknown CPU" without one)
  std::string isa;        // the build's vector unit: "AVX-512", "AVX2+FMA", "AVX+FMA" or "scalar" (kLaneIsa)
  std::string cpu_isa;    // the CPU's widest unit at run time: "AVX-512", "AVX2+FMA" or "scalar"
  std::string march;      // the build's target: "native" (BISTABLE_NATIVE) or "x86-64-v3"
  int lanes = 0;          // kSweepLanes: lanes per kernel call in sweeps
};

HostLanes ThisHostLanes();

// One line, e.g. "cpu: AMD EPYC 7R13 Processor | isa: AVX-512 | lanes: 8 (fixed at compile time: -march=native)";
// the CPU's own unit is added where it differs from the build's ("isa: AVX2+FMA (the CPU has AVX-512)").
std::string HostLanesLine(const HostLanes& h);
inline std::string HostLanesLine() { return HostLanesLine(ThisHostLanes()); }

}  // namespace bistable

#endif  // BISTABLE_DYNAMICS_HOST_LANES_H_
