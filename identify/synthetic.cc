#include "identify/synthetic.h"

#include "base/file.h"

#include <cstdio>
#include <fstream>
#include <random>

#include "dynamics/rosenbrock23.h"

namespace bistable {

StatusOr<Record> MakeSyntheticRecord(const DimensionalParams& p, const SyntheticOptions& o, const std::string& name) {
  BISTABLE_RETURN_IF_ERROR(ValidateDimensionalParams(p));
  if (!(o.fs_hz > 0) || !(o.duration_s > 0) || !(o.noise_m >= 0))
    return Status::InvalidArgument("synthetic", "fs_hz, duration_s must be > 0 and noise_m >= 0");
  const BaseMotion base = ChirpBase(o.a0_m, o.f_start_hz, o.f_end_hz, o.duration_s);
  DimensionalModel sys(p, base);
  AdaptiveOptions ao;
  ao.rtol = 1e-8;
  ao.atol = 1e-11;
  ao.h_max = 0.25 / o.fs_hz;
  DimensionalModel::State x;
  x << o.y0_m, 0.0, 0.0, 0.0;
  const size_t n = static_cast<size_t>(o.duration_s * o.fs_hz) + 1;
  const double dt = 1.0 / o.fs_hz;
  std::vector<DimensionalModel::State> samples(n);
  samples[0] = x;
  size_t next = 1;
  Rosenbrock23<DimensionalModel> ros(sys, ao);
  const OdeTermination term = ros.Integrate(0.0, x, (n - 1) * dt, [&](const Rosenbrock23<DimensionalModel>& st) {
    while (next < n && next * dt <= st.t() + 1e-12) {
      st.Interpolate(next * dt, samples[next]);
      ++next;
    }
  });
  if (term != OdeTermination::kOk || next < n)
    return Status::Internal(std::string("synthetic record '") + name + "': integration ended early (" + OdeTerminationName(term) + ")");
  std::mt19937_64 rng(o.seed);
  std::normal_distribution<double> noise(0.0, o.noise_m);
  Record r;
  r.name = name;
  r.dt = dt;
  for (size_t i = 0; i < n; ++i) {
    const double t = i * dt;
    const double x0 = base(t).x;
    r.t.push_back(t);
    r.input.push_back(x0);
    const double xm = x0 + samples[i][0];
    r.output.push_back(xm + (o.noise_m > 0 ? noise(rng) : 0.0));
    if (p.has_resonator) r.resonator.push_back(xm + samples[i][2] + (o.noise_m > 0 ? noise(rng) : 0.0));
  }
  return r;
}

Status WriteRecordCsv(const Record& r, const std::string& path) {
  std::string text = r.resonator.empty() ? "t,x0,x\n" : "t,x0,x,xr\n";
  char buf[160];
  for (size_t i = 0; i < r.t.size(); ++i) {
    if (r.resonator.empty()) std::snprintf(buf, sizeof buf, "%.10g,%.10g,%.10g\n", r.t[i], r.input[i], r.output[i]);
    else std::snprintf(buf, sizeof buf, "%.10g,%.10g,%.10g,%.10g\n", r.t[i], r.input[i], r.output[i], r.resonator[i]);
    text += buf;
  }
  auto f = AtomicFile::Create(path, "csv");  // whole or not at all
  if (!f.ok()) return f.status();
  BISTABLE_RETURN_IF_ERROR((*f)->Write(text));
  return (*f)->Commit();
}

}  // namespace bistable
