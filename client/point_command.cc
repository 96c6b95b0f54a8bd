#include "client/point_command.h"

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <memory>
#include <optional>
#include <sstream>

#include "base/exit_codes.h"
#include "client/json_out.h"
#include "dynamics/cancel.h"
#include "dynamics/point.h"

namespace bistable {
namespace {

struct PointArgs {
  std::string model = "coupled";
  std::string integrator = "rk4";
  std::string ic;
  std::string trace;
  bool json = false;
  bool no_rosenstein = false;
  bool spectrum = false;
  PointSpec spec;
};

int Fail(const Status& st) {
  std::cerr << "error: " << st.ToString() << "\n";
  return bistable::kExitError;
}

Status ParseIc(const std::string& text, std::array<double, 4>* ic) {
  std::stringstream ss(text);
  std::string item;
  int i = 0;
  while (std::getline(ss, item, ',')) {
    if (i >= 4) return Status::InvalidArgument("ic", "ic = '" + text + "' violates ic = ym,vm[,yr,vr] (at most 4 numbers)");
    char* end = nullptr;
    const double v = std::strtod(item.c_str(), &end);
    if (end == item.c_str() || *end != '\0')
      return Status::InvalidArgument("ic", "ic[" + std::to_string(i) + "] = '" + item + "' violates ic[i] a number");
    (*ic)[i++] = v;
  }
  if (i != 2 && i != 4) return Status::InvalidArgument("ic", "ic = '" + text + "' violates ic = ym,vm or ym,vm,yr,vr");
  return Status::Ok();
}

// Writes rows atomically: a temporary beside the target, renamed over it when complete.
Status WriteTrace(const std::string& path, const PointResult& r) {
  const std::string tmp = path + ".tmp";
  {
    std::ofstream out(tmp);
    if (!out) return Status::IoError("trace", "cannot open '" + tmp + "' for writing");
    out << "tau,y_m,dy_m,y_r,dy_r\n";
    out.precision(17);
    for (const auto& row : r.samples) out << row[0] << ',' << row[1] << ',' << row[2] << ',' << row[3] << ',' << row[4] << '\n';
    out.flush();
    if (!out) return Status::IoError("trace", "write to '" + tmp + "' failed");
  }
  std::error_code ec;
  std::filesystem::rename(tmp, path, ec);
  if (ec) return Status::IoError("trace", "rename to '" + path + "' failed: " + ec.message());
  return Status::Ok();
}

void PrintHuman(const PointSpec& spec, const PointResult& r) {
  auto line = [](const char* k, const std::string& v, const char* unit = "") {
    std::printf("  %-26s %s %s\n", k, v.c_str(), unit);
  };
  auto num = [](double v) {
    char b[64];
    std::snprintf(b, sizeof b, "%.6g", v);
    return std::string(b);
  };
  std::printf("%s point  alpha=%g  omega=%g  (%s, dt=%g, window tau in [%g, %g])\n", ModelName(spec.model), spec.alpha,
              spec.omega, IntegratorName(spec.integration.integrator), spec.integration.dt, spec.integration.t_keep,
              spec.integration.t_end);
  if (r.termination != Termination::kOk) line("termination", TerminationName(r.termination));
  line("FRF (abs. velocity)", num(r.frf_db), "dB");
  line("LLE (Benettin)", num(r.lle), "per unit tau");
  line("LLE (Rosenstein, y_m)", num(r.lle_rosenstein), "per unit tau");
  line("motion", MotionName(r.motion));
  line("period (strobe)", r.period ? std::to_string(r.period) : std::string("none"),
       ("(" + std::to_string(r.strobe_samples) + " samples)").c_str());
  line("y_m range", "[" + num(r.y_min) + ", " + num(r.y_max) + "]");
  line("harmonic diffusion index", num(r.hd_index), "(power fraction off k*Omega)");
  std::string peaks;
  for (size_t i = 0; i < r.hd_peaks.size() && i < 5; ++i)
    peaks += (i ? ", " : "") + num(r.hd_peaks[i].freq) + "@" + num(r.hd_peaks[i].amp);
  line("spectral peaks freq@amp", peaks.empty() ? "-" : peaks);
  line("EDR_B / EDR_R / EDR_T", num(r.edr_b) + " / " + num(r.edr_r) + " / " + num(r.edr_t), "% of W_in");
  line("W_in, W_m, W_r, dE", num(r.w_in) + ", " + num(r.w_m) + ", " + num(r.w_r) + ", " + num(r.delta_e));
  line("energy balance residual", num(r.energy_balance_residual), "(relative to W_in)");
}

void PrintSpectrum(const LyapunovSpectrum& sp) {
  std::printf("  Lyapunov spectrum (QR, per unit tau)\n");
  for (size_t j = 0; j < sp.exponents.size(); ++j) std::printf("    lambda_%zu %+.6e\n", j + 1, sp.exponents[j]);
  std::printf("    sum      %+.6e   (exact divergence tr J = %+.6e)\n", sp.sum, sp.divergence);
  std::printf("    Kaplan-Yorke dimension %.4f (flow, with the forcing phase; Poincare section: %.4f)\n",
              sp.kaplan_yorke, sp.kaplan_yorke > 0 ? sp.kaplan_yorke - 1 : 0.0);
}

int RunPoint(PointArgs& a) {
  auto model = ParseModel(a.model);
  if (!model.ok()) return Fail(model.status());
  auto integ = ParseIntegrator(a.integrator);
  if (!integ.ok()) return Fail(integ.status());
  PointSpec spec = a.spec;
  spec.model = *model;
  spec.integration.integrator = *integ;
  if (!a.ic.empty()) {
    spec.ic_given = true;
    Status st = ParseIc(a.ic, &spec.ic);
    if (!st.ok()) return Fail(st);
  }
  spec.metrics.rosenstein = !a.no_rosenstein;
  spec.metrics.keep_samples = !a.trace.empty();
  // Ctrl-C / SIGTERM stop the integration within ~1024 steps; nothing is printed or written then.
  InstallCancelSignalHandlers();
  auto result = EvaluatePoint(spec);
  std::optional<StatusOr<LyapunovSpectrum>> spectrum;
  if (a.spectrum && result.ok() && !CancelRequested()) spectrum = EvaluateLyapunovSpectrum(spec);
  RestoreDefaultSignalHandlers();
  if (CancelRequested()) {
    std::cerr << "interrupted: the point was not finished; nothing was printed or written\n";
    return CancelExitStatus();
  }
  if (!result.ok()) return Fail(result.status());
  if (spectrum && !spectrum->ok()) return Fail(spectrum->status());
  if (!a.trace.empty()) {
    Status st = WriteTrace(a.trace, *result);
    if (!st.ok()) return Fail(st);
  }
  if (a.json) {
    nlohmann::json j = PointJson(spec, *result);
    if (spectrum) {
      const LyapunovSpectrum& sp = **spectrum;
      j["lyapunov_spectrum"] = sp.exponents;
      j["lyapunov_sum"] = sp.sum;
      j["divergence"] = sp.divergence;
      j["kaplan_yorke"] = sp.kaplan_yorke;
    }
    std::cout << j.dump(2) << "\n";
  } else {
    PrintHuman(spec, *result);
    if (spectrum) PrintSpectrum(**spectrum);
    if (!a.trace.empty()) std::printf("  trace written to %s (%zu rows)\n", a.trace.c_str(), result->samples.size());
  }
  return 0;
}

}  // namespace

void AddPointCommand(CLI::App& app, int* exit_code) {
  auto args = std::make_shared<PointArgs>();
  PointSpec& s = args->spec;
  CLI::App* cmd = app.add_subcommand("point", "Integrate one (alpha, Omega) point and print every metric");
  cmd->add_option("--model", args->model, "standalone | coupled | linear | linear-coupled")->capture_default_str();
  cmd->add_option("--alpha", s.alpha, "base amplitude alpha = A0/delta_s (> 0)")->required();
  cmd->add_option("--omega", s.omega, "base frequency Omega = omega0/omega_n (> 0)")->required();
  cmd->add_option("--eps", s.params.eps, "cubic stiffness epsilon (> 0)")->capture_default_str();
  cmd->add_option("--eta", s.params.eta, "main damping eta = c/(m_m omega_n) (>= 0)")->capture_default_str();
  cmd->add_option("--eta-r", s.params.eta_r, "resonator damping eta_r = c_r/(m_r omega_n) (>= 0)")->capture_default_str();
  cmd->add_option("--phi", s.params.phi, "mass ratio phi = m_r/m_m (> 0)")->capture_default_str();
  cmd->add_option("--lambda", s.params.lambda, "tuning lambda = omega_r/omega_n (> 0)")->capture_default_str();
  cmd->add_option("--t-end", s.integration.t_end, "end of the run, tau")->capture_default_str();
  cmd->add_option("--t-keep", s.integration.t_keep, "start of the steady-state window, tau")->capture_default_str();
  cmd->add_option("--integrator", args->integrator, "rk4 (fixed step, the paper's) | adaptive (Dormand-Prince 5(4))")
      ->capture_default_str();
  cmd->add_option("--dt", s.integration.dt, "RK4 step / output sampling step, tau")->capture_default_str();
  cmd->add_option("--rtol", s.integration.rtol, "adaptive: relative tolerance")->capture_default_str();
  cmd->add_option("--atol", s.integration.atol, "adaptive: absolute tolerance")->capture_default_str();
  cmd->add_option("--ic", args->ic, "initial state ym,vm[,yr,vr] (default: at rest in the positive well; linear: origin)");
  cmd->add_option("--chaos-threshold", s.metrics.chaos_threshold, "LLE above which motion is chaotic")->capture_default_str();
  cmd->add_option("--renorm-every", s.metrics.renorm_every, "Benettin renormalisation interval, steps")->capture_default_str();
  cmd->add_option("--sample-every", s.metrics.sample_every, "window sampling for spectrum/Rosenstein/trace, steps")
      ->capture_default_str();
  cmd->add_flag("--no-rosenstein", args->no_rosenstein, "skip the Rosenstein estimate");
  cmd->add_flag("--spectrum", args->spectrum,
                "also the Lyapunov spectrum by QR (all exponents, their sum against the exact divergence, the "
                "Kaplan-Yorke dimension; rk4 only; about D+1 times the point's cost)");
  cmd->add_flag("--json", args->json, "print one JSON object");
  cmd->add_option("--trace", args->trace, "write tau,y_m,dy_m,y_r,dy_r over the window to this CSV");
  cmd->footer(
      "Units are non-dimensional (model.md): tau = omega_n t, lengths in delta_s. FRF is the absolute-velocity\n"
      "transmissibility 20 log10(max|x_m'| / (alpha Omega)) over the window; LLE per unit tau.");
  cmd->callback([args, exit_code]() { *exit_code = RunPoint(*args); });
}

}  // namespace bistable
