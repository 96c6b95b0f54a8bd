#include "dynamics/point_spec.h"

#include <cmath>
#include <limits>

#include "base/limits.h"
#include "base/names.h"
#include "base/validate.h"

namespace bistable {
namespace {

bool IsWholeSteps(double t, double dt) {
  const double n = t / dt;
  return std::fabs(n - std::round(n)) <= 1e-9 * std::max(1.0, n);
}

}  // namespace

const char* ModelName(ModelKind m) {
  switch (m) {
    case ModelKind::kStandalone:
      return "standalone";
    case ModelKind::kCoupled:
      return "coupled";
    case ModelKind::kLinear:
      return "linear";
    case ModelKind::kLinearCoupled:
      return "linear-coupled";
    case ModelKind::kSeries:
      return "series";
    case ModelKind::kDimensional:
      return "dimensional";
  }
  return "?";
}

StatusOr<ModelKind> ParseModel(const std::string& name) {
  for (ModelKind m : {ModelKind::kStandalone, ModelKind::kCoupled, ModelKind::kLinear, ModelKind::kLinearCoupled})
    if (name == ModelName(m)) return m;
  return Status::InvalidArgument(
      "model", "model = '" + Printable(name) + "' violates model in {standalone, coupled, linear, linear-coupled}");
}

StatusOr<ModelKind> ParseAnyModel(const std::string& name) {
  if (name == "series") return ModelKind::kSeries;
  if (name == "dimensional") return ModelKind::kDimensional;
  auto m = ParseModel(name);
  if (m.ok()) return m;
  return Status::InvalidArgument(
      "model", "model = '" + Printable(name) +
                   "' violates model in {standalone, coupled, linear, linear-coupled, series, dimensional}");
}

bool IsCellModel(ModelKind m) { return m != ModelKind::kSeries && m != ModelKind::kDimensional; }

bool HasResonator(ModelKind m) { return m == ModelKind::kCoupled || m == ModelKind::kLinearCoupled; }
bool IsBistable(ModelKind m) { return m == ModelKind::kStandalone || m == ModelKind::kCoupled; }

const char* IntegratorName(IntegratorKind k) {
  switch (k) {
    case IntegratorKind::kRk4:
      return "rk4";
    case IntegratorKind::kRosenbrock:
      return "rosenbrock";
    default:
      return "adaptive";
  }
}

StatusOr<IntegratorKind> ParseIntegrator(const std::string& name) {
  if (name == "rk4") return IntegratorKind::kRk4;
  if (name == "adaptive" || name == "dopri5") return IntegratorKind::kAdaptive;
  if (name == "rosenbrock") return IntegratorKind::kRosenbrock;
  return Status::InvalidArgument("integrator",
                                 "integrator = '" + name + "' violates integrator in {rk4, adaptive, rosenbrock}");
}

const char* MotionName(Motion m) {
  switch (m) {
    case Motion::kIntrawell:
      return "intrawell";
    case Motion::kInterwell:
      return "interwell";
    case Motion::kChaotic:
      return "chaotic";
    case Motion::kUndefined:
      return "undefined";
    case Motion::kQuasiPeriodic:
      return "quasi-periodic";
    case Motion::kUnresolved:
      return "unresolved";
  }
  return "?";
}

PointResult DivergedResult(const std::array<double, 4>& final_state) {
  const double nan = std::numeric_limits<double>::quiet_NaN();
  PointResult r;
  r.termination = Termination::kDiverged;
  r.frf_db = r.lle = r.lle_rosenstein = r.hd_index = r.strobe_y = r.strobe_v = nan;
  r.y_min = r.y_max = nan;
  r.w_in = r.w_net = r.w_m = r.w_r = r.delta_e = nan;
  r.edr_b = r.edr_r = r.edr_t = r.energy_balance_residual = nan;
  r.final_state = final_state;
  return r;
}

const char* LabelModeName(LabelMode m) { return m == LabelMode::kPaper ? "paper" : "settled"; }

StatusOr<LabelMode> ParseLabelMode(const std::string& name) {
  if (name == "paper") return LabelMode::kPaper;
  if (name == "settled") return LabelMode::kSettled;
  return Status::InvalidArgument("labels", "labels = '" + name + "' violates labels in {paper, settled}");
}

const char* TerminationName(Termination t) {
  switch (t) {
    case Termination::kOk:
      return "ok";
    case Termination::kDiverged:
      return "diverged";
    case Termination::kStepSizeUnderflow:
      return "step_size_underflow";
    case Termination::kMaxSteps:
      return "max_steps";
  }
  return "?";
}

long StepsFor(double t, double dt) { return std::lround(t / dt); }

std::array<double, 4> InitialState(const PointSpec& spec) {
  if (spec.ic_given) return spec.ic;
  if (!IsBistable(spec.model)) return {0, 0, 0, 0};
  const double well = 1.0 / std::sqrt(spec.params.eps);
  return {well, 0, HasResonator(spec.model) ? well : 0.0, 0};
}

Status ValidatePointSpec(const PointSpec& s) {
  if (!IsCellModel(s.model))
    return Status::InvalidArgument("model",
                                   std::string("model = '") + ModelName(s.model) +
                                       "' violates model in {standalone, coupled, linear, linear-coupled} (a point)");
  BISTABLE_RETURN_IF_ERROR(CheckPositive("alpha", s.alpha));
  BISTABLE_RETURN_IF_ERROR(CheckPositive("omega", s.omega));
  if (IsBistable(s.model)) BISTABLE_RETURN_IF_ERROR(CheckPositive("eps", s.params.eps));
  BISTABLE_RETURN_IF_ERROR(CheckNonNegative("eta", s.params.eta));
  if (HasResonator(s.model)) {
    BISTABLE_RETURN_IF_ERROR(CheckNonNegative("eta_r", s.params.eta_r));
    BISTABLE_RETURN_IF_ERROR(CheckPositive("phi", s.params.phi));
    BISTABLE_RETURN_IF_ERROR(CheckPositive("lambda", s.params.lambda));
  }
  for (int i = 0; i < 4; ++i) BISTABLE_RETURN_IF_ERROR(CheckFinite("ic[" + std::to_string(i) + "]", s.ic[i]));

  const IntegrationSettings& in = s.integration;
  BISTABLE_RETURN_IF_ERROR(CheckPositive("dt", in.dt));
  BISTABLE_RETURN_IF_ERROR(CheckPositive("t_end", in.t_end));
  BISTABLE_RETURN_IF_ERROR(CheckNonNegative("t_keep", in.t_keep));
  if (!(in.t_keep < in.t_end)) return Violates("t_keep", in.t_keep, "< t_end = " + FormatNumber(in.t_end));
  if (in.dt > (in.t_end - in.t_keep) / 16)
    return Violates("dt", in.dt, "<= (t_end - t_keep)/16 = " + FormatNumber((in.t_end - in.t_keep) / 16));
  if (!IsWholeSteps(in.t_end, in.dt))
    return Violates("t_end", in.t_end, "a whole multiple of dt = " + FormatNumber(in.dt));
  if (!IsWholeSteps(in.t_keep, in.dt))
    return Violates("t_keep", in.t_keep, "a whole multiple of dt = " + FormatNumber(in.dt));
  if (in.t_end / in.dt > limits::kMaxStepsPerPoint)
    return Violates("t_end", in.t_end,
                    "<= " + FormatNumber(limits::kMaxStepsPerPoint) +
                        " dt = " + FormatNumber(limits::kMaxStepsPerPoint * in.dt) + " (steps per point limit)");
  if (in.integrator != IntegratorKind::kRk4) {
    BISTABLE_RETURN_IF_ERROR(CheckPositive("rtol", in.rtol));
    BISTABLE_RETURN_IF_ERROR(CheckPositive("atol", in.atol));
    if (in.rtol < 1e-14) return Violates("rtol", in.rtol, ">= 1e-14");
  }

  if (in.labels == LabelMode::kSettled) {
    if (in.integrator != IntegratorKind::kRk4)
      return Status::InvalidArgument("labels", "labels = 'settled' needs integrator = 'rk4'");
    BISTABLE_RETURN_IF_ERROR(CheckPositive("settle_window", in.settle_window));
    if (!IsWholeSteps(in.settle_window, in.dt))
      return Violates("settle_window", in.settle_window, "a whole multiple of dt = " + FormatNumber(in.dt));
    if (in.dt > in.settle_window / 16) return Violates("settle_window", in.settle_window, ">= 16 dt");
    if (in.settle_min_strobes < 1 || in.settle_min_strobes > 64)
      return Violates("settle_min_strobes", in.settle_min_strobes, "in [1, 64]");
    BISTABLE_RETURN_IF_ERROR(CheckNonNegative("settle_confirm", in.settle_confirm));
    BISTABLE_RETURN_IF_ERROR(CheckPositive("settle_cap", in.settle_cap));
    if ((in.t_keep + in.settle_cap) / in.dt > limits::kMaxStepsPerPoint)
      return Violates("settle_cap", in.settle_cap,
                      "<= " + FormatNumber(limits::kMaxStepsPerPoint) + " dt - t_keep (steps per point limit)");
    if (in.settle_window * s.omega / (2 * M_PI) > limits::kMaxWindowSamples)
      return Violates("omega", s.omega, "<= 2 pi " + FormatNumber(limits::kMaxWindowSamples) + " / settle_window");
  }
  const MetricSettings& m = s.metrics;
  if (!(m.quasi_lle >= 0 && m.quasi_lle < 1)) return Violates("quasi_lle", m.quasi_lle, "in [0, 1)");
  if (m.renorm_every < 1) return Violates("renorm_every", m.renorm_every, ">= 1");
  if (m.sample_every < 1) return Violates("sample_every", m.sample_every, ">= 1");
  // Stroboscopic samples: one per forcing period in the window.
  if ((in.t_end - in.t_keep) * s.omega / (2 * M_PI) > limits::kMaxWindowSamples)
    return Violates("omega", s.omega,
                    "<= 2 pi " + FormatNumber(limits::kMaxWindowSamples) + " / (t_end - t_keep) = " +
                        FormatNumber(2 * M_PI * limits::kMaxWindowSamples / (in.t_end - in.t_keep)) +
                        " (forcing periods per window limit)");
  // Window buffers (spectrum samples, trace rows) grow with the window's samples: bound them.
  const double samples = (in.t_end - in.t_keep) / in.dt / m.sample_every;
  if (samples > limits::kMaxWindowSamples)
    return Violates("sample_every", m.sample_every,
                    ">= (t_end - t_keep)/dt / " + FormatNumber(limits::kMaxWindowSamples) + " = " +
                        FormatNumber(std::ceil((in.t_end - in.t_keep) / in.dt / limits::kMaxWindowSamples)) +
                        " (window samples per point limit)");
  BISTABLE_RETURN_IF_ERROR(CheckFinite("chaos_threshold", m.chaos_threshold));
  BISTABLE_RETURN_IF_ERROR(CheckPositive("period_tol", m.period_tol));
  if (m.max_period < 1 || m.max_period > 64) return Violates("max_period", m.max_period, "in [1, 64]");
  if (!(m.hd_level > 0 && m.hd_level < 1)) return Violates("hd_level", m.hd_level, "in (0, 1)");
  if (m.hd_top_k < 1 || m.hd_top_k > 100) return Violates("hd_top_k", m.hd_top_k, "in [1, 100]");
  if (!(m.poincare_phase >= 0 && m.poincare_phase < 2 * M_PI))
    return Violates("poincare_phase", m.poincare_phase, "in [0, 2 pi) (radians of Omega tau)");
  if (m.poincare_points < 0 || m.poincare_points > limits::kMaxPoincarePointsStored)
    return Violates("poincare_points", m.poincare_points,
                    "in [0, " + std::to_string(limits::kMaxPoincarePointsStored) + "]");
  return Status::Ok();
}

}  // namespace bistable
