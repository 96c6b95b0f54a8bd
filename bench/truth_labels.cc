// Long-run truth labels for held-out samples of a sweep's grid (issue 38): every listed point of the
// spec's grid integrated with the project's RK4 kernel (the code `bistable point` runs; lanes give the
// same bits at any width) to τ = t_long, and labelled (motion, period, LLE, HD, FRF) from two windows:
// [t_long/3, 2 t_long/3] and [2 t_long/3, t_long] (defaults τ 10,000–20,000 and 20,000–30,000). A point
// whose two windows disagree has a truth that has not settled.
//
//   truth_labels SPEC.toml INDICES.txt [--t-long 30000] [--threads 1] > truth.csv
//
// INDICES.txt: one grid point index per line (row-major over the axes, last axis fastest, as PointAt).
// Output CSV: index,alpha,omega, then per window (a = earlier, b = later) motion,period,lle,hd,frf,ymin,ymax.
#include <array>
#include <atomic>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <iostream>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "dynamics/point.h"
#include "engine/sweep_spec.h"

using namespace bistable;

namespace {

struct Labels {
  int motion = -1, period = 0;
  double lle = 0, hd = 0, frf = 0, ymin = 0, ymax = 0;
};

constexpr int kW = 8;

// Points [start, start + n) of idx, window [t_keep, t_end].
void Window(const SweepSpec& spec, const std::vector<long>& idx, size_t start, int n, double t_keep, double t_end,
            Labels* out) {
  std::array<PointSpec, kW> specs;
  std::array<LaneInput, kW> lanes;
  std::array<RawLane, kW> raw;
  std::array<PointResult, kW> res;
  for (int l = 0; l < n; ++l) {
    specs[l] = spec.PointAt(idx[start + l], 0);
    specs[l].integration.t_end = t_end;
    specs[l].integration.t_keep = t_keep;
    specs[l].metrics.rosenstein = false;
    lanes[l] = LaneFor(specs[l]);
  }
  const KernelSettings ks = KernelSettingsFor(specs[0]);
  if (!RunKernel<kW>(specs[0].model, lanes.data(), n, ks, raw.data())) std::exit(3);
  ComputeBlockMetrics<kW>(raw.data(), specs.data(), n, res.data());
  for (int l = 0; l < n; ++l) {
    const PointResult& r = res[l];
    Labels& o = out[l];
    o.motion = r.termination == Termination::kOk ? static_cast<int>(r.motion) : -1;
    o.period = r.period;
    o.lle = r.lle;
    o.hd = r.hd_index;
    o.frf = r.frf_db;
    o.ymin = r.y_min;
    o.ymax = r.y_max;
  }
}

}  // namespace

int main(int argc, char** argv) {
  if (argc < 3) {
    std::fprintf(stderr, "usage: truth_labels SPEC.toml INDICES.txt [--t-long T] [--threads N]\n");
    return 2;
  }
  double t_long = 30000;
  int threads = 1;
  for (int i = 3; i + 1 < argc; i += 2) {
    const std::string a = argv[i];
    if (a == "--t-long")
      t_long = std::atof(argv[i + 1]);
    else if (a == "--threads")
      threads = std::atoi(argv[i + 1]);
  }
  std::ifstream f(argv[1]);
  std::stringstream ss;
  ss << f.rdbuf();
  auto spec = ParseSweepSpec(ss.str(), argv[1]);
  if (!spec.ok()) {
    std::fprintf(stderr, "%s\n", spec.status().ToString().c_str());
    return 2;
  }
  std::vector<long> idx;
  std::ifstream fi(argv[2]);
  for (long v; fi >> v;) idx.push_back(v);
  const size_t m = idx.size();
  std::vector<Labels> a(m), b(m);
  std::atomic<size_t> next{0};
  std::atomic<size_t> done{0};
  auto work = [&] {
    for (;;) {
      const size_t s = next.fetch_add(kW);
      if (s >= m) return;
      const int n = static_cast<int>(std::min<size_t>(kW, m - s));
      Window(*spec, idx, s, n, t_long / 3, 2 * t_long / 3, &a[s]);
      Window(*spec, idx, s, n, 2 * t_long / 3, t_long, &b[s]);
      const size_t d = done.fetch_add(n) + n;
      if (d / 200 != (d - n) / 200) std::fprintf(stderr, "%zu / %zu\n", d, m);
    }
  };
  std::vector<std::thread> pool;
  for (int t = 0; t < threads; ++t) pool.emplace_back(work);
  for (auto& t : pool) t.join();
  std::printf(
      "index,alpha,omega,motion_a,period_a,lle_a,hd_a,frf_a,ymin_a,ymax_a,"
      "motion_b,period_b,lle_b,hd_b,frf_b,ymin_b,ymax_b\n");
  for (size_t i = 0; i < m; ++i) {
    const PointSpec p = spec->PointAt(idx[i], 0);
    std::printf("%ld,%.17g,%.17g", idx[i], p.alpha, p.omega);
    for (const Labels* L : {&a[i], &b[i]})
      std::printf(",%d,%d,%.9g,%.9g,%.9g,%.9g,%.9g", L->motion, L->period, L->lle, L->hd, L->frf, L->ymin, L->ymax);
    std::printf("\n");
  }
  return 0;
}
