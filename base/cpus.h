// How many CPUs this process may use: the CPUs of its affinity mask (taskset, Slurm's cpusets), capped
// by its cgroup's CPU quota (a container's CPU limit: cgroup v2 `cpu.max`, v1 `cpu.cfs_quota_us` /
// `cpu.cfs_period_us`, the tightest of the cgroup and its ancestors), rounded up, at least 1. The
// default thread count of every command that computes in parallel, so a worker given 2 CPUs on a
// 64-core node starts 2 threads, not 64.
#ifndef BISTABLE_BASE_CPUS_H_
#define BISTABLE_BASE_CPUS_H_

#include <optional>
#include <string>

namespace bistable {

int UsableCpus();

// The pieces, for tests: a quota in CPUs from cgroup v2 "cpu.max" text ("max 100000" → none,
// "150000 100000" → 1.5) and from v1 quota/period texts ("-1" → none).
std::optional<double> CpuQuotaFromCpuMax(const std::string& cpu_max);
std::optional<double> CpuQuotaFromCfs(const std::string& quota_us, const std::string& period_us);
// The quota of a process's cgroups: `proc_self_cgroup` is the text of /proc/self/cgroup, `root` the
// cgroup mount root ("/sys/fs/cgroup"). The tightest quota from the cgroup up to the root.
std::optional<double> CgroupCpuQuota(const std::string& proc_self_cgroup, const std::string& root);

// The CPU's model as /proc/cpuinfo names it (its first "model name" line, e.g. "AMD EPYC 7R13 Processor"),
// or "unknown CPU" where there is none (a CPU or kernel that does not give one). The piece for tests:
// the name from cpuinfo text, empty when absent.
std::string CpuModelName();
std::string CpuModelFromCpuinfo(const std::string& cpuinfo);
// The widest vector unit of doubles the CPU has, asked at run time (cpuid), whatever the build targets:
// "AVX-512" (AVX512F), "AVX2+FMA", or "scalar" (neither, or not x86).
const char* CpuVectorIsa();

}  // namespace bistable

#endif  // BISTABLE_BASE_CPUS_H_
