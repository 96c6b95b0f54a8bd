#include "identify/synthetic.h"

#include "base/file.h"
#include "base/validate.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <random>

#include "dynamics/rosenbrock23.h"

namespace bistable {

namespace {

Status CheckForceTerm(const TermDef& d) {
  if (!d.IsForce() || d.kind == TermKind::kFriction)
    return Status::InvalidArgument("synthetic-extra",
                                   "--synthetic-extra " + d.id +
                                       ": only force terms other than friction (the rig has friction on "
                                       "both bodies already; leave res.friction out of --terms to test it)");
  return Status::Ok();
}

}  // namespace

Status CheckSyntheticExtra(const TermValues& e) {
  const std::string field = "synthetic-extra";
  if (e.term == nullptr) return Status::InvalidArgument(field, "--synthetic-extra: no term");
  const TermDef& d = *e.term;
  BISTABLE_RETURN_IF_ERROR(CheckForceTerm(d));
  for (size_t k = 0; k < e.values.size(); ++k) {
    const double x = e.values[k];
    if (!std::isfinite(x) || std::abs(x) > 1e15)
      return Status::InvalidArgument(field, "--synthetic-extra " + d.id + ": '" + FormatNumber(x) +
                                                "' is not a finite number with |value| <= 1e15");
    if (k < d.params.size() && d.params[k].sign == Sign::kNonNegative && x < 0)
      return Status::InvalidArgument(
          field, "--synthetic-extra " + d.id + "." + d.params[k].name + " = " + FormatNumber(x) + " violates >= 0");
  }
  if (e.values.size() != d.params.size())
    return Status::InvalidArgument(field, "--synthetic-extra " + d.id + " takes " + std::to_string(d.params.size()) +
                                              " value(s), got " + std::to_string(e.values.size()));
  return Status::Ok();
}

StatusOr<TermValues> SyntheticExtra(const std::string& term, const std::vector<double>& values) {
  auto t = FindTerm(term);
  if (!t.ok()) return Status::InvalidArgument("synthetic-extra", "--synthetic-extra: " + t.status().message());
  TermValues e{*t, values};
  BISTABLE_RETURN_IF_ERROR(CheckSyntheticExtra(e));
  return e;
}

StatusOr<TermValues> ParseSyntheticExtra(const std::string& spec) {
  const std::string field = "synthetic-extra";
  if (spec.size() > 200) return Status::InvalidArgument(field, "--synthetic-extra is longer than 200 characters");
  const size_t eq = spec.find('=');
  if (eq == std::string::npos)
    return Status::InvalidArgument(field,
                                   "--synthetic-extra '" + spec + "' is not TERM=VALUE[:VALUE] (e.g. main.drag=5)");
  auto t = FindTerm(spec.substr(0, eq));
  if (!t.ok()) return Status::InvalidArgument(field, "--synthetic-extra: " + t.status().message());
  BISTABLE_RETURN_IF_ERROR(CheckForceTerm(**t));
  std::vector<double> values;
  std::string rest = spec.substr(eq + 1);
  size_t start = 0;
  while (start <= rest.size()) {
    const size_t colon = std::min(rest.find(':', start), rest.size());
    const std::string v = rest.substr(start, colon - start);
    char* end = nullptr;
    const double x = std::strtod(v.c_str(), &end);
    if (v.empty() || end != v.c_str() + v.size() || !std::isfinite(x) || std::abs(x) > 1e15)
      return Status::InvalidArgument(
          field, "--synthetic-extra " + (*t)->id + ": '" + v + "' is not a finite number with |value| <= 1e15");
    values.push_back(x);
    start = colon + 1;
    if (colon == rest.size()) break;
  }
  TermValues e{*t, std::move(values)};
  BISTABLE_RETURN_IF_ERROR(CheckSyntheticExtra(e));
  return e;
}

std::vector<TermValues> TruthTerms(const DimensionalParams& p, const std::vector<TermValues>& extra) {
  std::vector<TermValues> out;
  auto add = [&](const char* id, std::vector<double> v) { out.push_back({*FindTerm(id), std::move(v)}); };
  add("main.linear", {p.k_lin});
  if (p.k3 != 0) add("main.stiffness_y3", {p.k3});
  add("main.viscous", {p.c0_m});
  add("main.damping_y2", {p.c2_m});
  if (p.fric_m.f_s != 0 || p.fric_m.f_c != 0) add("main.friction", {p.fric_m.f_s, p.fric_m.f_c});
  if (p.has_resonator) {
    add("res.linear", {p.k_r});
    add("res.viscous", {p.c0_r});
    add("res.damping_z2", {p.c2_r});
    if (p.fric_r.f_s != 0 || p.fric_r.f_c != 0) add("res.friction", {p.fric_r.f_s, p.fric_r.f_c});
  }
  for (const TermValues& e : extra) {
    auto same = std::find_if(out.begin(), out.end(), [&](const TermValues& t) { return t.term == e.term; });
    if (same == out.end())
      out.push_back(e);
    else
      for (size_t k = 0; k < e.values.size(); ++k) same->values[k] += e.values[k];  // the extra adds to the rig's own
  }
  return out;
}

IdentModel TruthModel(const DimensionalParams& p, const std::vector<TermValues>& extra) {
  IdentModel m;
  m.m_main = p.m_m;
  m.m_res = p.has_resonator ? p.m_r : 0.0;
  for (const TermValues& t : TruthTerms(p, extra)) {
    m.terms.push_back(t.term);
    m.theta.insert(m.theta.end(), t.values.begin(), t.values.end());
  }
  m.fc = FrictionConstants{p.fric_m.v_sp, p.fric_m.v_t};
  return m;
}

double SyntheticWell(const DimensionalParams& p, const std::vector<TermValues>& extra, double y_guess) {
  const StribeckBasis fb(0.002, 0.001);  // unused: friction is no extra
  double y = y_guess;
  for (int it = 0; it < 60; ++it) {
    double f = p.k_lin * y + p.k3 * y * y * y, df = p.k_lin + 3 * p.k3 * y * y;
    for (const TermValues& e : extra) {
      if (e.term->body != Body::kMain) continue;
      double phi[kMaxTermParams], dq[kMaxTermParams], dv[kMaxTermParams];
      TermBasisSlopes(*e.term, y, 0.0, fb, phi, dq, dv);
      for (size_t k = 0; k < e.values.size(); ++k) f += e.values[k] * phi[k], df += e.values[k] * dq[k];
    }
    if (!(std::abs(df) > 0) || !std::isfinite(f)) return y_guess;
    const double step = f / df;
    y -= step;
    if (std::abs(step) < 1e-15 * std::max(1.0, std::abs(y))) return std::isfinite(y) ? y : y_guess;
  }
  return y_guess;
}

namespace {

// The rig plus extra force terms of the library: F_main gains Σ θ φ(y, y'), G_res Σ θ φ(z, z'), in the equations
// y'' = F_m/m_m − a0, z'' = −G_r/m_r − F_m/m_m (F_m the main body's net force: −F_main + G_res).
class RigWithExtras {
 public:
  using State = DimensionalModel::State;
  using Jacobian = DimensionalModel::Jacobian;
  RigWithExtras(const DimensionalParams& p, BaseMotion base, const std::vector<TermValues>& extra)
      : rig_(p, std::move(base)), p_(p), extra_(extra), fb_(0.002, 0.001) {}
  int dim() const { return 4; }
  void operator()(double t, const State& x, State& dx) const {
    rig_(t, x, dx);
    double fm, fmq, fmv, gr, grq, grv;
    Extra(x, &fm, &fmq, &fmv, &gr, &grq, &grv);
    const double dm = (-fm + gr) / p_.m_m;  // extra net force on the main body per mass
    dx[1] += dm;
    if (p_.has_resonator) dx[3] += -gr / p_.m_r - dm;
  }
  void Jac(double t, const State& x, Jacobian& J, State& dfdt) const {
    rig_.Jac(t, x, J, dfdt);
    double fm, fmq, fmv, gr, grq, grv;
    Extra(x, &fm, &fmq, &fmv, &gr, &grq, &grv);
    J(1, 0) -= fmq / p_.m_m, J(1, 1) -= fmv / p_.m_m, J(1, 2) += grq / p_.m_m, J(1, 3) += grv / p_.m_m;
    if (p_.has_resonator) {
      J(3, 0) += fmq / p_.m_m, J(3, 1) += fmv / p_.m_m;
      J(3, 2) += -grq / p_.m_r - grq / p_.m_m, J(3, 3) += -grv / p_.m_r - grv / p_.m_m;
    }
  }

 private:
  void Extra(const State& x, double* fm, double* fmq, double* fmv, double* gr, double* grq, double* grv) const {
    *fm = *fmq = *fmv = *gr = *grq = *grv = 0;
    for (const TermValues& e : extra_) {
      const bool main = e.term->body == Body::kMain;
      const double q = main ? x[0] : x[2], v = main ? x[1] : x[3];
      double phi[kMaxTermParams], dq[kMaxTermParams], dv[kMaxTermParams];
      TermBasisSlopes(*e.term, q, v, fb_, phi, dq, dv);
      for (size_t k = 0; k < e.values.size(); ++k) {
        (main ? *fm : *gr) += e.values[k] * phi[k];
        (main ? *fmq : *grq) += e.values[k] * dq[k];
        (main ? *fmv : *grv) += e.values[k] * dv[k];
      }
    }
  }
  DimensionalModel rig_;
  DimensionalParams p_;
  std::vector<TermValues> extra_;
  StribeckBasis fb_;  // unused: friction is not an extra (ParseSyntheticExtra)
};

// Integrates `sys` from (y0, 0, 0, 0) and samples it every dt (n samples).
template <class System>
Status Integrate(const System& sys, double y0, double dt, size_t n, double fs_hz, const std::string& name,
                 std::vector<DimensionalModel::State>* samples) {
  AdaptiveOptions ao;
  ao.rtol = 1e-8;
  ao.atol = 1e-11;
  ao.h_max = 0.25 / fs_hz;
  DimensionalModel::State x;
  x << y0, 0.0, 0.0, 0.0;
  samples->assign(n, x);
  size_t next = 1;
  Rosenbrock23<System> ros(sys, ao);
  const OdeTermination term = ros.Integrate(0.0, x, (n - 1) * dt, [&](const Rosenbrock23<System>& st) {
    while (next < n && next * dt <= st.t() + 1e-12) {
      st.Interpolate(next * dt, (*samples)[next]);
      ++next;
    }
  });
  if (term != OdeTermination::kOk || next < n)
    return Status::Internal(std::string("synthetic record '") + name + "': integration ended early (" +
                            OdeTerminationName(term) + ")");
  return Status::Ok();
}

}  // namespace

StatusOr<Record> MakeSyntheticRecord(const DimensionalParams& p, const SyntheticOptions& o, const std::string& name) {
  BISTABLE_RETURN_IF_ERROR(ValidateDimensionalParams(p));
  if (!(o.fs_hz > 0) || !(o.duration_s > 0) || !(o.noise_m >= 0) || !(o.input_noise_m >= 0))
    return Status::InvalidArgument("synthetic", "fs_hz, duration_s must be > 0 and noise_m, input_noise_m >= 0");
  if (!(o.duration_s * o.fs_hz <= 1e7))
    return Status::InvalidArgument("synthetic", "duration_s * fs_hz must be <= 1e7 samples");
  for (const TermValues& e : o.extra)
    if (e.term == nullptr || !e.term->IsForce() || e.term->kind == TermKind::kFriction ||
        e.values.size() != e.term->params.size() || (e.term->body == Body::kResonator && !p.has_resonator))
      return Status::InvalidArgument("synthetic-extra",
                                     "an extra must be a force term other than friction, with one value per parameter, "
                                     "on a body the rig has");
  const BaseMotion base = ChirpBase(o.a0_m, o.f_start_hz, o.f_end_hz, o.duration_s);
  const size_t n = static_cast<size_t>(o.duration_s * o.fs_hz) + 1;
  const double dt = 1.0 / o.fs_hz;
  std::vector<DimensionalModel::State> samples;
  if (o.extra.empty())
    BISTABLE_RETURN_IF_ERROR(Integrate(DimensionalModel(p, base), o.y0_m, dt, n, o.fs_hz, name, &samples));
  else
    BISTABLE_RETURN_IF_ERROR(Integrate(RigWithExtras(p, base, o.extra), o.y0_m, dt, n, o.fs_hz, name, &samples));
  std::mt19937_64 rng(o.seed);
  std::normal_distribution<double> noise(0.0, o.noise_m), in_noise(0.0, o.input_noise_m > 0 ? o.input_noise_m : 1.0);
  Record r;
  r.name = name;
  r.dt = dt;
  for (size_t i = 0; i < n; ++i) {
    const double t = i * dt;
    const double x0 = base(t).x;
    r.t.push_back(t);
    const double xm = x0 + samples[i][0];
    r.output.push_back(xm + (o.noise_m > 0 ? noise(rng) : 0.0));
    if (p.has_resonator) r.resonator.push_back(xm + samples[i][2] + (o.noise_m > 0 ? noise(rng) : 0.0));
    r.input.push_back(x0 +
                      (o.input_noise_m > 0 ? in_noise(rng) : 0.0));  // drawn last: records without it keep their bits
  }
  return r;
}

Status WriteRecordCsv(const Record& r, const std::string& path) {
  std::string text = r.resonator.empty() ? "t,x0,x\n" : "t,x0,x,xr\n";
  char buf[160];
  for (size_t i = 0; i < r.t.size(); ++i) {
    if (r.resonator.empty())
      std::snprintf(buf, sizeof buf, "%.10g,%.10g,%.10g\n", r.t[i], r.input[i], r.output[i]);
    else
      std::snprintf(buf, sizeof buf, "%.10g,%.10g,%.10g,%.10g\n", r.t[i], r.input[i], r.output[i], r.resonator[i]);
    text += buf;
  }
  auto f = AtomicFile::Create(path, "csv");  // whole or not at all
  if (!f.ok()) return f.status();
  BISTABLE_RETURN_IF_ERROR((*f)->Write(text));
  return (*f)->Commit();
}

namespace identify {

StatusOr<SyntheticKind> ParseSyntheticKind(const std::string& s) {
  if (s == "linear") return SyntheticKind::kLinear;
  if (s == "coupled") return SyntheticKind::kCoupled;
  if (s == "bistable") return SyntheticKind::kBistable;
  if (s == "bistable-coupled") return SyntheticKind::kBistableCoupled;
  return Status::InvalidArgument("synthetic", "'" + s + "' is not linear, coupled, bistable or bistable-coupled");
}

const char* Name(SyntheticKind k) {
  return k == SyntheticKind::kLinear     ? "linear"
         : k == SyntheticKind::kCoupled  ? "coupled"
         : k == SyntheticKind::kBistable ? "bistable"
                                         : "bistable-coupled";
}

bool IsFamily(SyntheticKind k) { return k == SyntheticKind::kBistable || k == SyntheticKind::kBistableCoupled; }

StatusOr<WellSide> ParseWellSide(const std::string& s) {
  if (s == "left") return WellSide::kLeft;
  if (s == "right") return WellSide::kRight;
  return Status::InvalidArgument("synthetic-start", "--synthetic-start '" + s + "' is not left or right");
}

const char* Name(WellSide w) { return w == WellSide::kLeft ? "left" : "right"; }

Status Validate(const MakeSyntheticOptions& o) {
  if (o.dir.empty()) return Status::InvalidArgument("make-synthetic", "--make-synthetic needs a directory");
  if (!IsFamily(o.kind) && (!o.extra.empty() || !o.amplitudes_mm.empty()))
    return Status::InvalidArgument(
        "synthetic",
        "--synthetic-extra and --synthetic-amplitude are options of --synthetic bistable|bistable-coupled");
  if (!IsFamily(o.kind)) return Status::Ok();
  for (const TermValues& e : o.extra) {
    BISTABLE_RETURN_IF_ERROR(CheckSyntheticExtra(e));
    if (e.term->body == Body::kResonator && o.kind != SyntheticKind::kBistableCoupled)
      return Status::InvalidArgument(
          "synthetic-extra", "--synthetic-extra " + e.term->id + " needs --synthetic bistable-coupled (a resonator)");
  }
  auto check = [](const char* flag, double v, double lo, double hi) -> Status {
    if (!(v >= lo && v <= hi))
      return Status::InvalidArgument(flag, std::string("--") + flag + " = " + FormatNumber(v) + " violates " +
                                               FormatNumber(lo) + " <= value <= " + FormatNumber(hi));
    return Status::Ok();
  };
  BISTABLE_RETURN_IF_ERROR(check("synthetic-f-start", o.f_start_hz, 0.01, 50));
  BISTABLE_RETURN_IF_ERROR(check("synthetic-f-end", o.f_end_hz, 0.01, 50));
  BISTABLE_RETURN_IF_ERROR(check("synthetic-duration", o.duration_s, 1, 600));
  BISTABLE_RETURN_IF_ERROR(check("synthetic-noise", o.noise_mm, 0, 10));
  if (o.amplitudes_mm.size() > 16)
    return Status::InvalidArgument("synthetic-amplitude", "at most 16 --synthetic-amplitude values");
  for (double mm : o.amplitudes_mm) BISTABLE_RETURN_IF_ERROR(check("synthetic-amplitude", mm, 0.01, 100));
  return Status::Ok();
}

}  // namespace identify
}  // namespace bistable
