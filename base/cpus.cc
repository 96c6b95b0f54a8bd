#include "base/cpus.h"

#include <sched.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <thread>

namespace bistable {
namespace {

std::optional<std::string> ReadSmall(const std::filesystem::path& p) {
  std::ifstream f(p);
  if (!f) return std::nullopt;
  std::string s;
  std::getline(f, s);
  return s;
}

std::optional<double> ParsePositive(const std::string& s) {
  char* end = nullptr;
  const double v = std::strtod(s.c_str(), &end);
  if (end == s.c_str() || !std::isfinite(v) || v <= 0) return std::nullopt;
  return v;
}

void Tighten(std::optional<double>& best, std::optional<double> q) {
  if (q && (!best || *q < *best)) best = q;
}

// The tightest quota in `file_reader(dir)` from `rel` (a cgroup path like "/kubepods/pod1/c2") up to
// the mount root. Inside a container the cgroup namespace makes the path "/", so the root is checked too.
template <class Reader>
std::optional<double> WalkUp(const std::filesystem::path& mount, std::string rel, Reader read) {
  std::optional<double> best;
  std::filesystem::path p = std::filesystem::path(rel).relative_path();
  for (int depth = 0; depth < 64; ++depth) {
    Tighten(best, read(mount / p));
    if (p.empty()) break;
    p = p.parent_path();
  }
  return best;
}

}  // namespace

std::optional<double> CpuQuotaFromCpuMax(const std::string& cpu_max) {
  std::istringstream in(cpu_max);
  std::string quota, period;
  in >> quota >> period;
  if (quota.empty() || quota == "max") return std::nullopt;
  auto q = ParsePositive(quota);
  auto p = period.empty() ? std::optional<double>(100000) : ParsePositive(period);
  if (!q || !p) return std::nullopt;
  return *q / *p;
}

std::optional<double> CpuQuotaFromCfs(const std::string& quota_us, const std::string& period_us) {
  auto q = ParsePositive(quota_us);  // -1: no quota
  auto p = ParsePositive(period_us);
  if (!q || !p) return std::nullopt;
  return *q / *p;
}

std::optional<double> CgroupCpuQuota(const std::string& proc_self_cgroup, const std::string& root) {
  std::optional<double> best;
  std::istringstream lines(proc_self_cgroup);
  std::string line;
  while (std::getline(lines, line)) {
    // "hierarchy-id:controllers:path"
    const size_t a = line.find(':'), b = line.find(':', a == std::string::npos ? a : a + 1);
    if (a == std::string::npos || b == std::string::npos) continue;
    const std::string controllers = line.substr(a + 1, b - a - 1), path = line.substr(b + 1);
    if (line.compare(0, a, "0") == 0 && controllers.empty()) {  // cgroup v2
      Tighten(best, WalkUp(root, path, [](const std::filesystem::path& d) -> std::optional<double> {
                auto t = ReadSmall(d / "cpu.max");
                return t ? CpuQuotaFromCpuMax(*t) : std::nullopt;
              }));
      continue;
    }
    std::istringstream cs(controllers);
    for (std::string c; std::getline(cs, c, ',');) {
      if (c != "cpu") continue;
      for (const char* mount : {"cpu,cpuacct", "cpu", "cpuacct,cpu"}) {
        Tighten(best, WalkUp(std::filesystem::path(root) / mount, path,
                             [](const std::filesystem::path& d) -> std::optional<double> {
                               auto q = ReadSmall(d / "cpu.cfs_quota_us");
                               auto p = ReadSmall(d / "cpu.cfs_period_us");
                               return q && p ? CpuQuotaFromCfs(*q, *p) : std::nullopt;
                             }));
      }
    }
  }
  return best;
}

std::string CpuModelFromCpuinfo(const std::string& cpuinfo) {
  std::istringstream lines(cpuinfo);
  for (std::string line; std::getline(lines, line);) {
    if (line.rfind("model name", 0) != 0) continue;
    const size_t colon = line.find(':');
    if (colon == std::string::npos) continue;
    const size_t b = line.find_first_not_of(" \t", colon + 1);
    if (b == std::string::npos) continue;
    const size_t e = line.find_last_not_of(" \t\r");
    return line.substr(b, std::min<size_t>(e + 1 - b, 200));
  }
  return "";
}

std::string CpuModelName() {
  std::ifstream f("/proc/cpuinfo");  // procfs: size 0, read as a stream; the first CPU's block suffices
  std::string text, line;
  for (int n = 0; n < 64 && std::getline(f, line); ++n) text += line + "\n";
  const std::string name = CpuModelFromCpuinfo(text);
  return name.empty() ? "unknown CPU" : name;
}

const char* CpuVectorIsa() {
#if defined(__x86_64__) || defined(__i386__)
  __builtin_cpu_init();
  if (__builtin_cpu_supports("avx512f")) return "AVX-512";
  if (__builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma")) return "AVX2+FMA";
#endif
  return "scalar";
}

int UsableCpus() {
  int n = 0;
  cpu_set_t set;
  if (sched_getaffinity(0, sizeof set, &set) == 0) n = CPU_COUNT(&set);
  if (n <= 0) n = static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
  std::ifstream f("/proc/self/cgroup");
  std::stringstream text;
  text << f.rdbuf();
  if (auto q = CgroupCpuQuota(text.str(), "/sys/fs/cgroup"))
    n = std::min(n, std::max(1, static_cast<int>(std::ceil(*q - 1e-9))));
  return std::max(1, n);
}

}  // namespace bistable
