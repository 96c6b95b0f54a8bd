#include "dynamics/chirp.h"

#include <algorithm>
#include <cmath>
#include <complex>
#include <optional>

#include "base/validate.h"
#include "dynamics/cancel.h"
#include "dynamics/dopri5.h"
#include "dynamics/nondim_models.h"
#include "dynamics/point.h"
#include "dynamics/rk4.h"
#include "dynamics/spectrum.h"

namespace bistable {
namespace {

// A non-dimensional model under a general base motion x0(τ): every mass feels −x0''(τ).
template <class Model>
struct ForcedSystem {
  static constexpr int D = Model::kDim;
  using State = Eigen::Matrix<double, D, 1>;
  CellCoeffs<Vec<1>> c;
  BaseMotion base;
  int dim() const { return D; }
  void operator()(double t, const State& z, State& dz) const {
    Vec<1> x[D], dx[D];
    for (int d = 0; d < D; ++d) x[d][0] = z[d];
    Model::Rhs(c, x, Vec<1>{-base(t).a}, dx);
    for (int d = 0; d < D; ++d) dz[d] = dx[d][0];
  }
};

// Both runs poll cancellation (every kCancelCheckSteps RK4 steps, every accepted adaptive step) and
// then return nullopt: a cut-short record is no result.
template <class Model>
std::optional<ChirpRecord> RunNondim(const ChirpOptions& o) {
  PointSpec s;
  s.model = o.model;
  s.params = o.params;
  const LaneInput lane = LaneFor(s);
  ForcedSystem<Model> sys{{{lane.coeffs.k_lin},
                           {lane.coeffs.eps},
                           {lane.coeffs.eta},
                           {lane.coeffs.eta_r},
                           {lane.coeffs.phi},
                           {lane.coeffs.lambda2}},
                          ChirpBase(o.alpha, o.from / (2 * M_PI), o.to / (2 * M_PI), o.duration)};
  typename ForcedSystem<Model>::State x;
  for (int d = 0; d < Model::kDim; ++d) x[d] = lane.x0[d];
  Rk4<ForcedSystem<Model>> rk(sys);
  ChirpRecord r;
  r.dt = o.dt * o.sample_every;
  const long n = std::lround(o.duration / o.dt);
  auto record = [&](double t) {
    const BaseKinematics b = sys.base(t);
    r.t.push_back(t), r.x0.push_back(b.x), r.v0.push_back(b.v), r.y.push_back(x[0]), r.v_abs.push_back(x[1] + b.v);
    r.inst_freq.push_back(o.from + (o.to - o.from) * t / o.duration);
  };
  record(0.0);
  for (long k = 1; k <= n; ++k) {
    if (k % kCancelCheckSteps == 0 && CancelRequested()) return std::nullopt;
    rk.Step((k - 1) * o.dt, x, o.dt);
    if (!x.allFinite()) {
      r.diverged = true;
      break;
    }
    if (k % o.sample_every == 0) record(k * o.dt);
  }
  return r;
}

std::optional<ChirpRecord> RunDimensional(const ChirpOptions& o) {
  DimensionalModel m(o.dim, ChirpBase(o.a0_m, o.from, o.to, o.duration));
  AdaptiveOptions ao;
  ao.rtol = o.rtol;
  ao.atol = o.atol;
  Dopri5<DimensionalModel> dp(m, ao);
  DimensionalModel::State x;
  x << (o.dim.k_lin < 0 ? std::sqrt(-o.dim.k_lin / o.dim.k3) : 0.0), 0, 0, 0;
  ChirpRecord r;
  r.dt = o.dt;
  const long n = std::lround(o.duration / o.dt);
  long next = 0;
  DimensionalModel::State xi;
  auto record = [&](double t, const DimensionalModel::State& s) {
    const BaseKinematics b = ChirpBase(o.a0_m, o.from, o.to, o.duration)(t);
    r.t.push_back(t), r.x0.push_back(b.x), r.v0.push_back(b.v), r.y.push_back(s[0]), r.v_abs.push_back(s[1] + b.v);
    r.inst_freq.push_back(o.from + (o.to - o.from) * t / o.duration);
  };
  record(0.0, x);
  next = 1;
  OdeTermination term;
  try {
    term = dp.Integrate(0.0, x, o.duration, [&](const Dopri5<DimensionalModel>& st) {
      ThrowIfCancelled();
      while (next <= n && next * o.dt <= st.t() * (1 + 1e-12)) {
        st.Interpolate(next * o.dt, xi);
        record(next * o.dt, xi);
        ++next;
      }
    });
  } catch (const CancelUnwind&) {
    return std::nullopt;
  }
  r.diverged = term != OdeTermination::kOk;
  return r;
}

}  // namespace

Status ValidateChirpOptions(const ChirpOptions& o) {
  BISTABLE_RETURN_IF_ERROR(CheckPositive("from", o.from));
  BISTABLE_RETURN_IF_ERROR(CheckPositive("to", o.to));
  if (o.from == o.to) return Violates("to", o.to, "!= from");
  BISTABLE_RETURN_IF_ERROR(CheckPositive("duration", o.duration));
  BISTABLE_RETURN_IF_ERROR(CheckPositive("dt", o.dt));
  if (o.duration / o.dt > 5e7) return Violates("duration", o.duration, "<= 5e7 dt");
  if (o.sample_every < 1) return Violates("sample_every", o.sample_every, ">= 1");
  if (o.model == ModelKind::kSeries)
    return Status::InvalidArgument("model",
                                   "model = 'series' violates model in {standalone, coupled, linear, linear-coupled, "
                                   "dimensional} (chirp)");
  if (o.model == ModelKind::kDimensional) {
    BISTABLE_RETURN_IF_ERROR(CheckPositive("a0", o.a0_m));
    BISTABLE_RETURN_IF_ERROR(ValidateDimensionalParams(o.dim));
    // Nyquist of the output grid must clear the sweep's top frequency by a factor 5.
    if (1.0 / o.dt < 10 * std::max(o.from, o.to)) return Violates("dt", o.dt, "<= 1/(10 f_max) s");
  } else {
    BISTABLE_RETURN_IF_ERROR(CheckPositive("alpha", o.alpha));
    PointSpec s;
    s.model = o.model;
    s.params = o.params;
    s.integration.t_end = 500;
    s.integration.t_keep = 250;
    BISTABLE_RETURN_IF_ERROR(ValidatePointSpec(s));
    const double nyquist = M_PI / (o.dt * o.sample_every);
    if (nyquist < 5 * std::max(o.from, o.to))
      return Violates("sample_every", o.sample_every, "small enough for Nyquist >= 5 Omega_max");
  }
  return Status::Ok();
}

StatusOr<ChirpRecord> RunChirp(const ChirpOptions& o) {
  BISTABLE_RETURN_IF_ERROR(ValidateChirpOptions(o));
  std::optional<ChirpRecord> r = o.model == ModelKind::kDimensional ? RunDimensional(o)
                                 : HasResonator(o.model)            ? RunNondim<CoupledModel>(o)
                                                                    : RunNondim<SingleModel>(o);
  if (!r) return CancelledStatus();
  return std::move(*r);
}

FrfEstimate FftFrf(const std::vector<double>& in, const std::vector<double>& out, double dt, double f_lo, double f_hi,
                   bool hz) {
  FrfEstimate e;
  const size_t n = std::min(in.size(), out.size());
  if (n < 8) return e;
  std::vector<std::complex<double>> a, b;
  // Both records zero-padded to a 2^a3^b5^c length: the ratio is unchanged in expectation and the
  // transform never takes kissfft's slow path for large prime factors.
  const size_t m = NextFastFftLength(n);
  std::vector<double> xi(m, 0.0), xo(m, 0.0);
  std::copy(in.begin(), in.begin() + n, xi.begin());
  std::copy(out.begin(), out.begin() + n, xo.begin());
  RealFftHalf(xi, &a);
  RealFftHalf(xo, &b);
  const double df = (hz ? 1.0 : 2.0 * M_PI) / (m * dt);
  for (size_t k = 1; k < a.size(); ++k) {
    const double f = k * df;
    if (f < f_lo || f > f_hi) continue;
    const double mi = std::abs(a[k]) * 2.0 / n, mo = std::abs(b[k]) * 2.0 / n;
    e.freq.push_back(f), e.in_mag.push_back(mi), e.out_mag.push_back(mo);
    e.db.push_back(mi > 0 ? 20.0 * std::log10(mo / mi) : NAN);
  }
  return e;
}

H1Estimate WelchH1(const std::vector<double>& in, const std::vector<double>& out, double dt, double f_lo, double f_hi,
                   bool hz, int segment) {
  H1Estimate e;
  const size_t n = std::min(in.size(), out.size());
  if (segment <= 0) {
    segment = 64;
    while (static_cast<size_t>(segment) * 2 <= n / 4) segment *= 2;
  }
  if (n < static_cast<size_t>(segment) || segment < 16) return e;
  const size_t w_len = static_cast<size_t>(segment), hop = w_len / 2;
  std::vector<double> w(w_len), xi(w_len), xo(w_len);
  double w_sum = 0;
  for (size_t i = 0; i < w_len; ++i) w[i] = 0.5 - 0.5 * std::cos(2.0 * M_PI * i / w_len), w_sum += w[i];
  const size_t bins = w_len / 2 + 1;
  std::vector<double> sxx(bins, 0.0), syy(bins, 0.0);
  std::vector<std::complex<double>> sxy(bins, 0.0), a, b;
  int k_seg = 0;
  for (size_t start = 0; start + w_len <= n; start += hop, ++k_seg) {
    double mi = 0, mo = 0;
    for (size_t i = 0; i < w_len; ++i) mi += in[start + i], mo += out[start + i];
    mi /= w_len, mo /= w_len;
    for (size_t i = 0; i < w_len; ++i) xi[i] = (in[start + i] - mi) * w[i], xo[i] = (out[start + i] - mo) * w[i];
    RealFftHalf(xi, &a);
    RealFftHalf(xo, &b);
    for (size_t k = 0; k < bins; ++k)
      sxx[k] += std::norm(a[k]), syy[k] += std::norm(b[k]), sxy[k] += std::conj(a[k]) * b[k];
  }
  e.segments = k_seg;
  e.segment = segment;
  const double df = (hz ? 1.0 : 2.0 * M_PI) / (w_len * dt);
  const double scale = 2.0 / w_sum;
  for (size_t k = 1; k < bins; ++k) {
    const double f = k * df;
    if (f < f_lo || f > f_hi) continue;
    e.freq.push_back(f);
    e.in_mag.push_back(std::sqrt(sxx[k] / k_seg) * scale);
    e.out_mag.push_back(std::sqrt(syy[k] / k_seg) * scale);
    e.db.push_back(sxx[k] > 0 ? 20.0 * std::log10(std::abs(sxy[k]) / sxx[k]) : NAN);
    e.coherence.push_back(sxx[k] > 0 && syy[k] > 0 ? std::min(1.0, std::norm(sxy[k]) / (sxx[k] * syy[k])) : NAN);
  }
  return e;
}

Spectrogram ComputeSpectrogram(const std::vector<double>& x, double dt, int window, double f_max, bool hz) {
  Spectrogram s;
  if (window < 16 || static_cast<int>(x.size()) < window) return s;
  std::vector<double> w(window), seg(window);
  for (int i = 0; i < window; ++i) w[i] = 0.5 - 0.5 * std::cos(2.0 * M_PI * i / window);
  const double df = (hz ? 1.0 : 2.0 * M_PI) / (window * dt);
  const int kmax = std::min(window / 2, static_cast<int>(f_max / df) + 1);
  for (int k = 0; k <= kmax; ++k) s.freq.push_back(k * df);
  double top = 0;
  std::vector<std::complex<double>> spec;
  for (size_t start = 0; start + window <= x.size(); start += window / 4) {
    double mean = 0;
    for (int i = 0; i < window; ++i) mean += x[start + i];
    mean /= window;
    for (int i = 0; i < window; ++i) seg[i] = (x[start + i] - mean) * w[i];
    RealFftHalf(seg, &spec);
    std::vector<double> row(kmax + 1);
    for (int k = 0; k <= kmax; ++k) row[k] = std::abs(spec[k]), top = std::max(top, row[k]);
    s.time.push_back((start + window / 2.0) * dt);
    s.db.push_back(std::move(row));
  }
  for (auto& row : s.db)
    for (double& v : row) v = top > 0 && v > 0 ? 20.0 * std::log10(v / top) : -200.0;
  return s;
}

}  // namespace bistable
