// The simulation error a fit minimises (fit.h's objectives): every record simulated, the residual vectors and their
// Jacobians, and the cost functions Ceres evaluates (SimCost, SimCostFunction, ForwardDiffFunction). Split from
// fit.cc (issue 40); internal to identify/ through sim_cost.h.
#include "identify/sim_cost.h"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <complex>
#include <exception>
#include <future>
#include <limits>
#include <memory>
#include <mutex>
#include <thread>

#include "base/cpus.h"
#include "base/limits.h"
#include "dynamics/spectrum.h"
#include "identify/shooting.h"

namespace bistable {
namespace {

// one(i) for every record i < n, on up to `cpus` threads (records dealt round robin).
template <class F>
void ForEachRecord(size_t n, int cpus, const F& one) {  // cpus ≤ 0: all usable
  const size_t nt = std::min<size_t>(n, static_cast<size_t>(cpus > 0 ? cpus : UsableCpus()));
  if (nt <= 1) {
    for (size_t i = 0; i < n; ++i) one(i);
    return;
  }
  std::vector<std::future<void>> fs;
  for (size_t w = 0; w < nt; ++w)
    fs.push_back(std::async(std::launch::async, [&, w] {
      for (size_t i = w; i < n; i += nt) one(i);
    }));
  for (auto& f : fs) f.get();
}

// The outputs of the spectral objective: the main output (velocity form) and a voltage (as is).
bool InSpectrum(OutputSlot k) { return k != OutputSlot::kResonator; }

// FFT / n of the velocity form of a compared output (derivative of displacement outputs), mean removed:
// linear in the series, so a sensitivity column goes through the same map.
std::vector<std::complex<double>> VelocitySpectrum(const std::vector<double>& series, double dt, bool displacement) {
  std::vector<double> v = displacement ? SavitzkyGolay(series, dt, 3, 1) : series;
  double mean = 0;
  for (double x : v) mean += x;
  mean /= static_cast<double>(v.size());
  const size_t len = NextFastFftLength(v.size());
  std::vector<double> x(len, 0.0);
  for (size_t i = 0; i < v.size(); ++i) x[i] = v[i] - mean;
  std::vector<std::complex<double>> X;
  RealFftFull(x, &X);
  X.resize(len / 2 + 1);
  for (auto& c : X) c /= static_cast<double>(v.size());
  return X;
}

}  // namespace

// The substeps a simulation of record i at th runs: the held ones raised to what keeps RK4 stable (below),
// or, with none held, SubstepsFor's.
int SubstepsAt(const IdentModel& m, const std::vector<double>& th, const std::vector<PreparedRecord>& recs,
               const std::vector<int>& substeps, size_t i) {
  // Held substeps are raised to what keeps RK4 stable at th (StableSubsteps): below it the state chatters
  // where friction sticks, bounded by the law's saturation, while its sensitivities grow without bound (on
  // the coupled rig the third LM iteration ran 6 substeps where SubstepsFor asked 24: a gradient of 1e62, and which
  // basin the fit reached depended on the last bits of tanh). The count is then a function of θ, constant
  // between stiffness thresholds.
  return substeps.empty() ? SubstepsFor(m, th, recs[i]) : std::max(substeps[i], StableSubsteps(m, th, recs[i]));
}

// Every record simulated (in parallel over records); with `extra` given, with sensitivities to the
// model's parameters and those terms'. `shoot`: the shooting objective's simulation (ShootRecord) with
// segments of horizon_s.
Sims SimulateAll(const IdentModel& m, const std::vector<double>& th, const std::vector<PreparedRecord>& recs,
                 const Setup& setup, const std::vector<int>& substeps, int threads, double horizon_s,
                 const std::vector<const TermDef*>* extra, std::vector<EarlyStop>* stops, bool shoot,
                 const std::vector<std::vector<double>>* start, std::vector<std::vector<double>>* fitted, bool whole,
                 bool start_is_fitted) {
  Sims s;
  s.o.resize(recs.size());
  if (fitted) fitted->assign(recs.size(), {});
  std::vector<char> ok(recs.size(), 1);
  const std::vector<const TermDef*> none;
  const int cpus = threads > 0 ? threads : UsableCpus();
  // Shooting: the CPUs left over by the records run a record's segments side by side.
  const int inner = std::max<int>(1, cpus / static_cast<int>(std::max<size_t>(1, recs.size())));
  auto one = [&](size_t i) {
    const int sub = substeps.empty() ? 0 : SubstepsAt(m, th, recs, substeps, i);
    // A stage's horizon, else the record's own (PreparedRecord::horizon_s) unless the whole simulation is asked for.
    const double h = horizon_s > 0 ? horizon_s : whole ? 0.0 : recs[i].horizon_s;
    const int restart = h > 0 ? ShootingSegment(h, recs[i].dt) : 0;
    if (shoot) {
      ok[i] = restart > 0 && ShootRecord(m, th, extra, recs[i], setup, sub, restart, &s.o[i],
                                         start && i < start->size() ? &(*start)[i] : nullptr,
                                         fitted ? &(*fitted)[i] : nullptr, inner, start_is_fitted);
      return;
    }
    ok[i] = SimulateOutputs(m, th, extra ? *extra : none, recs[i], setup, sub, restart, extra != nullptr, &s.o[i],
                            stops ? &(*stops)[i] : nullptr);
  };
  ForEachRecord(recs.size(), cpus, one);
  for (char c : ok) s.ok = s.ok && c;
  return s;
}

// |FFT| / n of the velocity form of a compared output.
std::vector<double> VelocityMagnitudes(const std::vector<double>& series, double dt, bool displacement) {
  const std::vector<std::complex<double>> X = VelocitySpectrum(series, dt, displacement);
  std::vector<double> mag(X.size());
  for (size_t k = 0; k < mag.size(); ++k) mag[k] = std::abs(X[k]);
  return mag;
}

size_t NumResiduals(const std::vector<PreparedRecord>& recs, Objective obj) {
  size_t n = 0;
  for (const PreparedRecord& r : recs)
    for (int k = 0; k < kOutputSlots; ++k) {
      const OutputSlot slot = static_cast<OutputSlot>(k);
      if (!r.Has(slot)) continue;
      if (obj != Objective::kFft)
        n += r.n();
      else if (InSpectrum(slot))
        n += NextFastFftLength(r.n()) / 2 + 1;
    }
  return n;
}

namespace {

bool ResidualsOf(const IdentModel& m, const std::vector<PreparedRecord>& recs, const Setup& setup, Objective obj,
                 const Magnitudes& meas_mag, const Sims& s, double* res, Eigen::MatrixXd* jac,
                 const std::vector<const TermDef*>& extra);

// Residuals of the objective; false when a simulation diverged. With `jac` (and `extra`): the
// residuals' derivatives by θ (N × P: the model's parameters, then the extra terms' at 0), from one
// pass of SimulateSensitivities per record.
bool Residuals(const IdentModel& m, const std::vector<double>& th, const std::vector<PreparedRecord>& recs,
               const Setup& setup, Objective obj, const std::vector<int>& substeps, int threads,
               const Magnitudes& meas_mag, double* res, double horizon_s = 0, Eigen::MatrixXd* jac = nullptr,
               const std::vector<const TermDef*>& extra = {}, ShootCache* cache = nullptr) {
  std::vector<std::vector<double>> fitted;
  const std::vector<std::vector<double>>* done = cache ? cache->At(th) : nullptr;
  const Sims s = SimulateAll(m, th, recs, setup, substeps, threads, horizon_s, jac ? &extra : nullptr, nullptr,
                             obj == Objective::kShooting,
                             done                              ? done
                             : cache && !cache->anchor.empty() ? &cache->anchor
                                                               : nullptr,
                             cache && !done ? &fitted : nullptr, false, done != nullptr);
  if (cache && !done && s.ok) cache->Remember(th, cache->version, std::move(fitted));
  if (!s.ok) return false;
  return ResidualsOf(m, recs, setup, obj, meas_mag, s, res, jac, extra);
}

// The residuals (and with `jac` their derivatives) of the objective from the records' simulations.
bool ResidualsOf(const IdentModel& m, const std::vector<PreparedRecord>& recs, const Setup& setup, Objective obj,
                 const Magnitudes& meas_mag, const Sims& s, double* res, Eigen::MatrixXd* jac,
                 const std::vector<const TermDef*>& extra) {
  if (jac) {
    long P = m.NumParams();
    for (const TermDef* t : extra) P += static_cast<long>(t->params.size());
    jac->resize(static_cast<long>(NumResiduals(recs, obj)), P);
  }
  size_t k = 0;
  for (size_t i = 0; i < recs.size(); ++i) {
    const PreparedRecord& r = recs[i];
    const long n = static_cast<long>(r.n());
    for (int slot = 0; slot < kOutputSlots; ++slot) {
      const OutputSlot os = static_cast<OutputSlot>(slot);
      if (!r.Has(os)) continue;
      const std::vector<double>& sim = s.o[i].out[slot];
      const std::vector<double>& meas = r.Measured(os);
      if (obj != Objective::kFft) {
        // Σ squares = λ NRMSE² of this output on this record (λ = 1 for the main output).
        const double w = std::sqrt(r.weight[slot]) / (r.Scale(os) * std::sqrt(static_cast<double>(r.n())));
        if (jac) jac->middleRows(static_cast<long>(k), n) = s.o[i].d[slot] * w;
        for (size_t j = 0; j < r.n(); ++j) res[k++] = (sim[j] - meas[j]) * w;
        continue;
      }
      if (!InSpectrum(os)) continue;
      const bool disp = os == OutputSlot::kMain && setup.output != OutputKind::kVelocity;
      const std::vector<std::complex<double>> X = VelocitySpectrum(sim, r.dt, disp);
      double norm = 0;
      for (double v : meas_mag[i][slot]) norm += v * v;
      norm = std::sqrt(std::max(norm, 1e-300)) / std::sqrt(r.weight[slot]);
      if (jac) {  // d|X| = Re(conj(X) dX) / |X|
        for (long c = 0; c < jac->cols(); ++c) {
          const Eigen::VectorXd col = s.o[i].d[slot].col(c);
          const std::vector<std::complex<double>> dX =
              VelocitySpectrum(std::vector<double>(col.data(), col.data() + n), r.dt, disp);
          for (size_t j = 0; j < X.size(); ++j) {
            const double a = std::abs(X[j]);
            (*jac)(static_cast<long>(k + j), c) = a > 0 ? std::real(std::conj(X[j]) * dX[j]) / a / norm : 0.0;
          }
        }
      }
      for (size_t j = 0; j < X.size(); ++j) res[k++] = (std::abs(X[j]) - meas_mag[i][slot][j]) / norm;
    }
  }
  for (size_t j = 0; j < k; ++j)
    if (!std::isfinite(res[j])) return false;
  if (jac && !jac->allFinite()) return false;
  return true;
}

}  // namespace

Magnitudes MeasuredMagnitudes(const std::vector<PreparedRecord>& recs, const Setup& setup) {
  Magnitudes out;
  for (const PreparedRecord& r : recs) {
    out.emplace_back();
    out.back()[0] = VelocityMagnitudes(r.meas, r.dt, setup.output != OutputKind::kVelocity);
    if (r.Has(OutputSlot::kVoltage)) out.back()[2] = VelocityMagnitudes(r.volt, r.dt, false);
  }
  return out;
}

bool ObjectiveResiduals(const IdentModel& m, const std::vector<double>& th, const std::vector<PreparedRecord>& recs,
                        const Setup& setup, Objective obj, const std::vector<int>& substeps, std::vector<double>* out,
                        double horizon_s) {
  out->assign(NumResiduals(recs, obj), 0.0);
  const auto mags = obj == Objective::kFft ? MeasuredMagnitudes(recs, setup) : Magnitudes{};
  return Residuals(m, th, recs, setup, obj, substeps, 0, mags, out->data(),
                   obj == Objective::kShooting ? horizon_s : 0.0);
}

// Samples per shooting segment: horizon_s / dt rounded, at least 2; clamped in double first, so a horizon of
// more samples than an int holds (a record has at most limits::kMaxDataRows) is the whole record, not a wrap.
int ShootingSegment(double horizon_s, double dt) {
  const double n = std::clamp(std::round(horizon_s / dt), 2.0, static_cast<double>(limits::kMaxDataRows));
  return std::isfinite(n) ? static_cast<int>(n) : 2;
}

bool SimulateShooting(const IdentModel& m, const std::vector<double>& th, const PreparedRecord& r, const Setup& setup,
                      double horizon_s, SimOutputs* out) {
  return ShootRecord(m, th, nullptr, r, setup, 0, ShootingSegment(horizon_s, r.dt), out);
}

bool ObjectiveJacobian(const IdentModel& m, const std::vector<double>& th, const std::vector<PreparedRecord>& recs,
                       const Setup& setup, Objective obj, const std::vector<int>& substeps,
                       const std::vector<const TermDef*>& extra, std::vector<double>* out, Eigen::MatrixXd* jac,
                       double horizon_s) {
  out->assign(NumResiduals(recs, obj), 0.0);
  const auto mags = obj == Objective::kFft ? MeasuredMagnitudes(recs, setup) : Magnitudes{};
  return Residuals(m, th, recs, setup, obj, substeps, 0, mags, out->data(),
                   obj == Objective::kShooting ? horizon_s : 0.0, jac, extra);
}

std::vector<int> FixedSubsteps(const IdentModel& m, const std::vector<double>& th,
                               const std::vector<PreparedRecord>& recs, Objective obj, double safety) {
  // Short horizons (the shooting objective): the safety is accuracy's headroom as the parameters move, and
  // stability needs none, since every evaluation runs at least StableSubsteps at its own parameters
  // (SubstepsAt). Where the oscillations set the step that is SubstepsFor's count times the safety, as for the
  // other objectives; where a sticking friction law does (the snap-through rig) it is the stable count, whose
  // error over a 0.125 s segment is 50× below the records' noise (bench_identify_steps), where SubstepsFor's
  // times 1.5 ran twice the steps. A long simulation accumulates its error over the record: SubstepsFor's
  // margin times the safety stays.
  std::vector<int> sub;
  for (const PreparedRecord& r : recs)
    sub.push_back(
        obj == Objective::kShooting
            ? std::max(static_cast<int>(std::ceil(safety * OscillationSubsteps(m, th, r))), StableSubsteps(m, th, r))
            : static_cast<int>(std::ceil(safety * SubstepsFor(m, th, r))));
  return sub;
}

bool SimCost::operator()(double const* const* params, double* residuals) const {
  ++calls;
  return Residuals(*m, Theta(params[0]), *recs, *setup, obj, substeps, threads, meas_mag, residuals, horizon_s, nullptr,
                   {}, warm.get());
}

// The residuals at several scaled points u side by side (rs[l] for us[l]), records on `threads`: each record's
// simulations in SIMD lanes (SimulateOutputsLanes) where they run the same substeps, one by one otherwise.
// (Short horizons and segment states: one point after the other, through operator().)
bool SimCost::LaneResiduals(const std::vector<const double*>& us, std::vector<double>* rs, int threads) const {
  const size_t L = us.size();
  if (horizon_s != 0 || warm || obj == Objective::kShooting) {  // segments: one evaluation at a time
    SimCost c = *this;
    c.threads = threads;
    for (size_t l = 0; l < L; ++l) {
      rs[l].assign(NumResiduals(*recs, obj), 0.0);
      const double* pp[1] = {us[l]};
      if (!c(pp, rs[l].data())) return false;
    }
    return true;
  }
  std::vector<std::vector<double>> ths;
  for (const double* u : us) ths.push_back(Theta(u));
  std::vector<Sims> sims(L);
  for (Sims& sl : sims) sl.o.resize(recs->size());
  std::vector<char> ok(recs->size(), 1);
  ForEachRecord(recs->size(), threads, [&](size_t i) {
    std::vector<int> sub(L);
    for (size_t l = 0; l < L; ++l) sub[l] = SubstepsAt(*m, ths[l], *recs, substeps, i);
    if (std::all_of(sub.begin(), sub.end(), [&](int v) { return v == sub[0]; })) {
      std::vector<const std::vector<double>*> lanes;
      for (const std::vector<double>& th : ths) lanes.push_back(&th);
      std::vector<SimOutputs> outs;
      ok[i] = SimulateOutputsLanes(*m, lanes, (*recs)[i], *setup, sub[0], &outs);
      for (size_t l = 0; l < L; ++l) sims[l].o[i] = std::move(outs[l]);
    } else {
      for (size_t l = 0; l < L && ok[i]; ++l)
        ok[i] = SimulateOutputs(*m, ths[l], {}, (*recs)[i], *setup, sub[l], 0, false, &sims[l].o[i]);
    }
  });
  for (char c : ok)
    if (!c) return false;
  const size_t n = NumResiduals(*recs, obj);
  for (size_t l = 0; l < L; ++l) {
    rs[l].assign(n, 0.0);
    if (!ResidualsOf(*m, *recs, *setup, obj, meas_mag, sims[l], rs[l].data(), nullptr, {})) return false;
  }
  return true;
}

// Residuals and, when `jac` is given, their derivatives by the scaled parameters u (row-major,
// Ceres' layout), from one sensitivity pass.
bool SimCost::Eval(const double* u, double* residuals, double* jac) const {
  ++calls;
  if (!jac)
    return Residuals(*m, Theta(u), *recs, *setup, obj, substeps, threads, meas_mag, residuals, horizon_s, nullptr, {},
                     warm.get());
  Eigen::MatrixXd J;
  if (!Residuals(*m, Theta(u), *recs, *setup, obj, substeps, threads, meas_mag, residuals, horizon_s, &J, {},
                 warm.get()))
    return false;
  const long p = static_cast<long>(scale.size());
  for (long r = 0; r < J.rows(); ++r)
    for (long j = 0; j < p; ++j) jac[r * p + j] = J(r, j) * scale[static_cast<size_t>(j)];
  return true;
}

bool ForwardDiffFunction::Evaluate(double const* const* params, double* residuals, double** jacobians) const {
  if (!jacobians || !jacobians[0]) return c_(params, residuals);
  const int p = parameter_block_sizes()[0], n = num_residuals();
  const double* u = params[0];
  const double min_step = std::sqrt(std::numeric_limits<double>::epsilon());
  // Simulation 0 at u (the residuals), simulation j + 1 at u + δ_j e_j (column j), side by side in SIMD
  // lanes (SimCost::LaneResiduals: every lane the bits of its own simulation), packs of up to kMaxSimLanes
  // spread over the threads. A pack of 4 lanes costs about one scalar simulation, one of 8 about 1.3
  // (build/bench/bench_identify_lanes), so up to 8 simulations take one pack on one thread and leave the
  // other cores to the work beside (a refit's second start).
  const int sims = p + 1;
  std::vector<std::vector<double>> us(static_cast<size_t>(sims), std::vector<double>(u, u + p));
  std::vector<double> delta(static_cast<size_t>(p));
  for (int j = 0; j < p; ++j) {
    delta[j] = std::max(min_step, std::abs(u[j]) * 1e-6);
    us[j + 1][j] = u[j] + delta[j];
  }
  const int threads = std::min(threads_, sims);
  const int width = std::min(kMaxSimLanes, sims), packs = (sims + width - 1) / width;
  std::vector<std::vector<double>> r(static_cast<size_t>(sims));
  std::atomic<int> next{0};
  std::atomic<bool> ok{true};
  std::exception_ptr error;
  std::mutex error_mu;
  auto work = [&] {
    try {
      for (int k = next++; k < packs && ok; k = next++) {
        std::vector<const double*> lanes;
        for (int l = k * width; l < std::min(sims, (k + 1) * width); ++l) lanes.push_back(us[l].data());
        // The packs are the parallelism when there are several (Residuals does not depend on threads).
        if (!c_.LaneResiduals(lanes, &r[static_cast<size_t>(k * width)],
                              std::min(threads, packs) > 1 ? 1 : c_.threads)) {
          ok = false;
          return;
        }
      }
    } catch (...) {  // rethrown on the calling thread once every thread has joined
      std::lock_guard<std::mutex> lock(error_mu);
      if (!error) error = std::current_exception();
      ok = false;
    }
  };
  std::vector<std::thread> pool;
  try {
    for (int t = 1; t < std::min(threads, packs); ++t) pool.emplace_back(work);  // packs > 1: more than 8 simulations
  } catch (...) {  // no thread to be had: the packs left run on this one
  }
  work();
  for (std::thread& t : pool) t.join();
  if (error) std::rethrow_exception(error);
  if (!ok) return false;
  std::copy(r[0].begin(), r[0].end(), residuals);
  for (int j = 0; j < p; ++j) {
    const double inv = 1.0 / delta[j];
    for (int i = 0; i < n; ++i) jacobians[0][static_cast<size_t>(i) * p + j] = (r[j + 1][i] - residuals[i]) * inv;
  }
  return true;
}

bool SpectralForwardJacobian(const IdentModel& m, const std::vector<double>& scale, const std::vector<double>& u,
                             const std::vector<PreparedRecord>& recs, const Setup& setup,
                             const std::vector<int>& substeps, int column_threads, bool ceres_reference,
                             std::vector<double>* residuals, std::vector<double>* jac) {
  const int p = static_cast<int>(u.size());
  if (p == 0 || static_cast<int>(scale.size()) != p) return false;
  const SimCost lc{&m, &recs, &setup, Objective::kFft, substeps, scale, MeasuredMagnitudes(recs, setup),
                   0,  0.0,   nullptr};
  const int n = static_cast<int>(NumResiduals(recs, Objective::kFft));
  std::unique_ptr<ceres::DynamicCostFunction> fn;
  if (ceres_reference)
    fn.reset(
        new ceres::DynamicNumericDiffCostFunction<SimCost, ceres::FORWARD>(new SimCost(lc), ceres::TAKE_OWNERSHIP));
  else
    fn.reset(new ForwardDiffFunction(lc, column_threads));
  fn->AddParameterBlock(p);
  fn->SetNumResiduals(n);
  residuals->assign(static_cast<size_t>(n), 0.0);
  jac->assign(static_cast<size_t>(n) * p, 0.0);
  const double* params[1] = {u.data()};
  double* jacs[1] = {jac->data()};
  return fn->Evaluate(params, residuals->data(), jacs);
}

}  // namespace bistable
