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
#include "base/limits.h"
#include "client/cli_common.h"
#include "client/json_out.h"
#include "client/model_flags.h"
#include "client/plot.h"
#include "client/poincare_section.h"
#include "dynamics/cancel.h"
#include "dynamics/point.h"
#include "engine/json_shapes.h"

namespace bistable {
namespace {

struct PointArgs {
  std::string model = "coupled";
  std::string integrator = "rk4";
  std::string labels = "paper";
  std::string ic;
  std::string trace;
  std::string poincare, poincare_plot;  // section CSV ("-": standard output) and figure
  long poincare_periods = 0;            // > 0: the window is this many forcing periods (+1)
  bool poincare_periods_given = false;
  bool json = false;
  bool no_rosenstein = false;
  bool spectrum = false;
  PointSpec spec;
};

Status ParseIc(const std::string& text, std::array<double, 4>* ic) {
  std::stringstream ss(text);
  std::string item;
  int i = 0;
  while (std::getline(ss, item, ',')) {
    if (i >= 4)
      return Status::InvalidArgument("ic", "ic = '" + text + "' violates ic = ym,vm[,yr,vr] (at most 4 numbers)");
    char* end = nullptr;
    const double v = std::strtod(item.c_str(), &end);
    if (end == item.c_str() || *end != '\0')
      return Status::InvalidArgument("ic", "ic[" + std::to_string(i) + "] = '" + item + "' violates ic[i] a number");
    (*ic)[i++] = v;
  }
  if (i != 2 && i != 4) return Status::InvalidArgument("ic", "ic = '" + text + "' violates ic = ym,vm or ym,vm,yr,vr");
  return Status::Ok();
}

// The rows to `path` ("-": standard output), written whole by an exclusive temporary beside the target and
// renamed over it when complete (AtomicFile).
Status WriteTrace(const std::string& path, const PointResult& r) {
  std::ostringstream out;
  out << "tau,y_m,dy_m,y_r,dy_r\n";
  out.precision(17);
  for (const auto& row : r.samples)
    out << row[0] << ',' << row[1] << ',' << row[2] << ',' << row[3] << ',' << row[4] << '\n';
  return WriteTextOut(path, out.str(), "trace");
}

std::string SectionCsv(const PointSpec& spec, const PointResult& r, long limit) {
  std::ostringstream out;
  // One header line, units in brackets (as measured-data files write them): every CSV reader takes it.
  const auto cols = SectionColumns(spec);
  for (size_t c = 0; c < cols.size(); ++c)
    out << (c ? "," : "") << cols[c].first << (cols[c].second.empty() ? "" : " [" + cols[c].second + "]");
  out << "\n";
  char b[32];
  for (size_t i = 0; i < SectionCount(r, limit); ++i) {
    const std::vector<double> row = SectionRow(spec, r, i);
    for (size_t c = 0; c < row.size(); ++c) {
      std::snprintf(b, sizeof b, c == 0 ? "%.0f" : "%.17g", row[c]);
      out << (c ? "," : "") << b;
    }
    out << "\n";
  }
  return out.str();
}

// The section as panels of points: (y_m, y_m'), and (y_r, y_r') beside it for coupled models.
Status PlotSection(const PointSpec& spec, const PointResult& r, long limit, const std::string& path) {
  const size_t n = SectionCount(r, limit);
  if (n == 0)
    return Status::InvalidArgument("poincare_plot",
                                   "the section has no points to plot (the run diverged, termination " +
                                       std::string(TerminationName(r.termination)) + ")");
  PanelPlot d;
  d.title = "Poincare section: " + std::string(ModelName(spec.model)) + ", alpha " + PlotNumber(spec.alpha) +
            ", Omega " + PlotNumber(spec.omega) + ", eta " + PlotNumber(spec.params.eta) + ", phase " +
            PlotNumber(spec.metrics.poincare_phase) + " rad, " + std::to_string(n) + " points";
  const bool res = HasResonator(spec.model);
  d.cols = res ? 2 : 1;
  d.panel_width = res ? 640 : 900;
  d.panel_height = res ? 600 : 760;
  const double ps = n > 2000 ? 0.12 : n > 200 ? 0.3 : 0.8;
  auto panel = [&](const char* title, const char* x, const char* y, const std::vector<double>& xs,
                   const std::vector<double>& ys) {
    PanelPlot::Series se{"",
                         std::vector<double>(xs.begin(), xs.begin() + n),
                         std::vector<double>(ys.begin(), ys.begin() + n),
                         true,
                         "#2166ac",
                         ps};
    d.panels.push_back({title, x, y, {se}});
  };
  panel("main mass at tau_k = (phase + 2 pi k)/Omega", "y_m [delta_s]", "dy_m/dtau [delta_s/tau]", r.section_y,
        r.section_v);
  if (res) panel("resonator at the same tau_k", "y_r [delta_s]", "dy_r/dtau [delta_s/tau]", r.section_yr, r.section_vr);
  return RenderPanels(d, path);
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
  auto labels = ParseLabelMode(a.labels);
  if (!labels.ok()) return Fail(labels.status());
  spec.integration.labels = *labels;
  if (!a.ic.empty()) {
    spec.ic_given = true;
    Status st = ParseIc(a.ic, &spec.ic);
    if (!st.ok()) return Fail(st);
  }
  spec.metrics.rosenstein = !a.no_rosenstein;
  spec.metrics.keep_samples = !a.trace.empty();
  if (a.poincare_periods_given) {
    Status st = SetPoincareWindow(a.poincare_periods, "--poincare-periods", &spec);
    if (!st.ok()) return Fail(st);
  }
  const long section_limit = a.poincare_periods_given ? a.poincare_periods : 0;
  const bool section_to_stdout = a.poincare == "-";
  const bool trace_to_stdout = a.trace == "-";  // without --json: standard output is the trace CSV alone
  if (trace_to_stdout && (a.json || section_to_stdout || a.spectrum))
    return Fail(
        Status::InvalidArgument("trace", std::string("--trace - writes the trace CSV to standard output, which ") +
                                             (a.json              ? "--json"
                                              : section_to_stdout ? "--poincare -"
                                                                  : "--spectrum") +
                                             " uses too: give --trace a file name"));
  if (!a.poincare_plot.empty()) {
    const std::string ext = std::filesystem::path(a.poincare_plot).extension().string();
    if (ext != ".png" && ext != ".svg")
      return Fail(Status::InvalidArgument(
          "poincare_plot", "--poincare-plot '" + a.poincare_plot + "' violates --poincare-plot ends in .png or .svg"));
  }
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
  // The section: a CSV file, or standard output (with --json: inside the JSON instead).
  if (!a.poincare.empty() && !(section_to_stdout && a.json)) {
    Status st = WriteTextOut(a.poincare, SectionCsv(spec, *result, section_limit), "poincare");
    if (!st.ok()) return Fail(st);
  }
  if (!a.poincare_plot.empty()) {
    Status st = PlotSection(spec, *result, section_limit, a.poincare_plot);
    if (!st.ok()) return Fail(st);
  }
  if (a.json) {
    nlohmann::json j = PointJson(spec, *result);
    if (spectrum) AddSpectrumJson(**spectrum, &j);
    if (!a.poincare.empty() || !a.poincare_plot.empty() || a.poincare_periods_given)
      j["poincare"] = SectionJson(spec, *result, section_limit, a.poincare);
    std::cout << DumpJson(j, 2) << "\n";
  } else if (!section_to_stdout && !trace_to_stdout) {  // "-" without --json: standard output is the CSV alone
    PrintHuman(spec, *result);
    if (spectrum) PrintSpectrum(**spectrum);
    if (!a.trace.empty()) std::printf("  trace written to %s (%zu rows)\n", a.trace.c_str(), result->samples.size());
    if (!a.poincare.empty())
      std::printf("  Poincare section written to %s (%zu points, phase %g rad)\n", a.poincare.c_str(),
                  SectionCount(*result, section_limit), spec.metrics.poincare_phase);
    if (!a.poincare_plot.empty()) std::printf("  Poincare section plotted in %s\n", a.poincare_plot.c_str());
  }
  return 0;
}

}  // namespace

void AddPointCommand(CLI::App& app, int* exit_code) {
  auto args = std::make_shared<PointArgs>();
  PointSpec& s = args->spec;
  CLI::App* cmd = app.add_subcommand("point", "Integrate one (alpha, Omega) point and print every metric");
  AddNondimModelOptions(cmd, &args->model, &s.params);
  cmd->add_option("--alpha", s.alpha, "base amplitude alpha = A0/delta_s (> 0)")->required();
  cmd->add_option("--omega", s.omega, "base frequency Omega = omega0/omega_n (> 0)")->required();
  cmd->add_option("--t-end", s.integration.t_end, "end of the run, tau")->capture_default_str();
  cmd->add_option("--t-keep", s.integration.t_keep, "start of the steady-state window, tau")->capture_default_str();
  cmd->add_option("--integrator", args->integrator, "rk4 (fixed step, the paper's) | adaptive (Dormand-Prince 5(4))")
      ->capture_default_str();
  cmd->add_option("--dt", s.integration.dt, "RK4 step / output sampling step, tau")->capture_default_str();
  cmd->add_option("--rtol", s.integration.rtol, "adaptive: relative tolerance")->capture_default_str();
  cmd->add_option("--atol", s.integration.atol, "adaptive: absolute tolerance")->capture_default_str();
  cmd->add_option("--ic", args->ic,
                  "initial state ym,vm[,yr,vr] (default: at rest in the positive well; linear: origin)");
  cmd->add_option("--chaos-threshold", s.metrics.chaos_threshold, "LLE above which motion is chaotic")
      ->capture_default_str();
  cmd->add_option("--labels", args->labels,
                  "paper (one window [t_keep, t_end]) | settled (windows of --settle-window from t_keep until the "
                  "label settles, up to --settle-cap; t_end unused; docs/numerics.md)")
      ->capture_default_str();
  cmd->add_option("--settle-window", s.integration.settle_window, "settled labels: window, tau")->capture_default_str();
  cmd->add_option("--settle-confirm", s.integration.settle_confirm,
                  "settled labels: tau after t_keep before a chaotic or quasi-periodic label")
      ->capture_default_str();
  cmd->add_option("--chaos-01-min", s.metrics.chaos_01_min,
                  "settled labels: chaos also needs the 0-1 test's K above this (-1: K stored, no veto)")
      ->capture_default_str();
  cmd->add_option("--settle-cap", s.integration.settle_cap, "settled labels: tau after t_keep, then unresolved")
      ->capture_default_str();
  cmd->add_option("--renorm-every", s.metrics.renorm_every, "Benettin renormalisation interval, steps")
      ->capture_default_str();
  cmd->add_option("--sample-every", s.metrics.sample_every, "window sampling for spectrum/Rosenstein/trace, steps")
      ->capture_default_str();
  cmd->add_flag("--no-rosenstein", args->no_rosenstein, "skip the Rosenstein estimate");
  cmd->add_flag("--spectrum", args->spectrum,
                "also the Lyapunov spectrum by QR (all exponents, their sum against the exact divergence, the "
                "Kaplan-Yorke dimension; rk4 only; about D+1 times the point's cost)");
  cmd->add_flag("--json", args->json, "print one JSON object");
  cmd->add_option("--trace", args->trace,
                  "write tau,y_m,dy_m,y_r,dy_r over the window to this CSV (-: standard output, alone)");
  cmd->add_option(
      "--poincare", args->poincare,
      "write the Poincare (stroboscopic) section to this CSV ('-': standard output; with --json, into the JSON)");
  cmd->add_option("--poincare-phase", s.metrics.poincare_phase,
                  "section phase in [0, 2 pi), radians of Omega tau: strobes at tau_k = (phase + 2 pi k)/Omega "
                  "(the period test uses the same strobes)")
      ->capture_default_str();
  CLI::Option* periods =
      cmd->add_option("--poincare-periods", args->poincare_periods,
                      "make the window N + 1 forcing periods long and keep the first N section points, N in [1, " +
                          std::to_string(limits::kMaxPoincarePeriods) +
                          "] (instead of --t-end; very long windows need a "
                          "larger --sample-every, see docs/limits.md)");
  cmd->add_option("--poincare-plot", args->poincare_plot,
                  "plot the section (y_m, y_m'; and y_r, y_r') into this .png or .svg");
  periods->excludes(cmd->get_option("--t-end"));
  cmd->footer(
      "Units are non-dimensional (model.md): tau = omega_n t, lengths in delta_s. FRF is the absolute-velocity\n"
      "transmissibility 20 log10(max|x_m'| / (alpha Omega)) over the window; LLE per unit tau.\n"
      "Poincare section: the state at tau_k = (phase + 2 pi k)/Omega for every k with tau_k in the window,\n"
      "y in delta_s and y' = dy/dtau in delta_s/tau (delta_s omega_n in physical units); CSV columns "
      "k,tau,y_m,dy_m[,y_r,dy_r], units in the header.");
  cmd->callback([args, exit_code, periods]() {
    args->poincare_periods_given = periods->count() > 0;
    *exit_code = RunPoint(*args);
  });
}

}  // namespace bistable
