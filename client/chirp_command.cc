// `bistable chirp`: frequency-sweep simulations with FFT-based FRF and spectrograms (paper §5).
#include <filesystem>
#include <fstream>
#include <iostream>
#include <memory>
#include <sstream>

#include <nlohmann/json.hpp>

#include "client/chirp_command.h"
#include "client/cli_common.h"
#include "client/plot.h"
#include "dynamics/cancel.h"
#include "dynamics/chirp.h"
#include "engine/json_shapes.h"

namespace bistable {
namespace {

struct ChirpArgs {
  std::string model = "coupled", direction = "up", out = "chirp";
  bool json = false;
  double a0_mm = 10;
  int window = 0;
  ChirpOptions o;
};

// Written whole by an exclusive temporary beside the target, renamed over it when complete (AtomicFile).
Status WriteCsv(const std::string& path, const std::string& header, const std::vector<std::vector<double>>& cols) {
  std::ostringstream f;
  f.precision(12);
  f << header << "\n";
  for (size_t i = 0; i < cols[0].size(); ++i) {
    for (size_t c = 0; c < cols.size(); ++c) f << (c ? "," : "") << cols[c][i];
    f << "\n";
  }
  return WriteTextOut(path, f.str(), "out");
}

// The model of --model: the dimensional rig of Table 2 (bistable or linear) at --a0-mm, or a
// non-dimensional model by name.
Status SetChirpModel(ChirpArgs& a, bool dim) {
  if (dim) {
    a.o.model = ModelKind::kDimensional;
    a.o.dim = a.model == "dimensional" ? DimensionalParams::BistableTable2() : DimensionalParams::LinearTable2();
    a.o.a0_m = a.a0_mm * 1e-3;
  } else {
    auto m = ParseModel(a.model);
    if (!m.ok())
      return Status::InvalidArgument("model", m.status().message().substr(0, m.status().message().size() - 1) +
                                                  ", dimensional, dimensional-linear}");
    a.o.model = *m;
  }
  return Status::Ok();
}

// One sweep's entry of the summary: the range of the raw FFT ratio and of H1, H1's mean coherence
// over the bins that have one, and the record's length.
nlohmann::json SweepSummary(const std::string& dir, const FrfEstimate& e, const ChirpFrfPlot::Curve& h1,
                            const ChirpRecord& rec) {
  double peak = -INFINITY, low = INFINITY;
  for (double v : e.db)
    if (std::isfinite(v)) peak = std::max(peak, v), low = std::min(low, v);
  double h1_peak = -INFINITY, h1_low = INFINITY, coherence = 0;
  size_t coherent_bins = 0;
  for (size_t i = 0; i < h1.db.size(); ++i) {
    if (std::isfinite(h1.db[i])) h1_peak = std::max(h1_peak, h1.db[i]), h1_low = std::min(h1_low, h1.db[i]);
    if (std::isfinite(h1.coherence[i])) coherence += h1.coherence[i], ++coherent_bins;
  }
  coherence = coherent_bins ? coherence / static_cast<double>(coherent_bins) : 0.0;  // over the bins that have one
  return {{"direction", dir},        {"frf_max_db", peak},  {"frf_min_db", low},
          {"h1_max_db", h1_peak},    {"h1_min_db", h1_low}, {"coherence_mean", coherence},
          {"samples", rec.t.size()}, {"dt", rec.dt},        {"diverged", rec.diverged}};
}

// The summary as text: each sweep's H1 range and mean coherence, then the files written.
void PrintChirpSummary(const nlohmann::json& summary, double lo, double hi, const std::string& unit) {
  for (const auto& sw : summary.at("sweeps"))
    std::printf(
        "%-4s sweep: H1 FRF from %.1f to %.1f dB over [%g, %g] %s (mean coherence %.2f; raw FFT ratio %.1f to %.1f "
        "dB)\n",
        sw["direction"].get<std::string>().c_str(), sw["h1_min_db"].get<double>(), sw["h1_max_db"].get<double>(), lo,
        hi, unit.c_str(), sw["coherence_mean"].get<double>(), sw["frf_min_db"].get<double>(),
        sw["frf_max_db"].get<double>());
  for (const auto& f : summary.at("files")) std::printf("wrote %s\n", f.get<std::string>().c_str());
}

int RunChirpCommand(ChirpArgs& a) {
  const bool dim = a.model == "dimensional" || a.model == "dimensional-linear";
  if (Status st = SetChirpModel(a, dim); !st.ok()) return Fail(st);
  if (a.direction != "up" && a.direction != "down" && a.direction != "both")
    return Fail(Status::InvalidArgument("direction",
                                        "direction = '" + a.direction + "' violates direction in {up, down, both}"));
  std::error_code ec;
  std::filesystem::create_directories(a.out, ec);
  if (ec) return Fail(Status::IoError("out", "cannot create '" + a.out + "': " + ec.message()));
  const double lo = std::min(a.o.from, a.o.to), hi = std::max(a.o.from, a.o.to);
  const std::string unit = dim ? "Hz" : "rad/tau";
  ChirpFrfPlot frf_plot =
      ChirpFigure("frequency sweep, " + a.model +
                      (dim ? ", A0 = " + PlotNumber(a.a0_mm) + " mm" : ", alpha = " + PlotNumber(a.o.alpha)),
                  dim);
  // The CSV files are the product; without gnuplot the figures are skipped with one warning.
  const Status gnuplot = CheckGnuplot();
  if (!gnuplot.ok()) std::cerr << "warning: no plots: " << gnuplot.message() << "; the CSV files are written\n";
  nlohmann::json summary = {{"files", nlohmann::json::array()}, {"sweeps", nlohmann::json::array()}};
  // Ctrl-C / SIGTERM stop a sweep within ~1024 steps; files of a finished sweep stay (each is written
  // whole, by rename), nothing of an unfinished one is written.
  InstallCancelSignalHandlers();
  auto interrupted = [&] {
    RestoreDefaultSignalHandlers();
    std::cerr << "interrupted: the frequency sweep was not finished; files of finished sweeps are complete\n";
    return CancelExitStatus();
  };
  for (const std::string dir : {"up", "down"}) {
    if (a.direction != "both" && a.direction != dir) continue;
    ChirpOptions o = a.o;
    o.from = dir == "up" ? lo : hi;
    o.to = dir == "up" ? hi : lo;
    auto rec = RunChirp(o);
    if (CancelRequested()) return interrupted();
    if (!rec.ok()) return Fail(rec.status());
    if (rec->diverged) std::cerr << "warning: the " << dir << " sweep diverged; the record is cut short\n";
    const std::string base = (std::filesystem::path(a.out) / ("sweep_" + dir)).string();
    Status st =
        WriteCsv(base + ".csv", dim ? "t_s,x0_m,v0_m_s,y_m,v_abs_m_s,f_inst_hz" : "tau,x0,v0,y_m,v_abs,omega_inst",
                 {rec->t, rec->x0, rec->v0, rec->y, rec->v_abs, rec->inst_freq});
    if (!st.ok()) return Fail(st);
    const FrfEstimate e = FftFrf(rec->v0, rec->v_abs, rec->dt, lo, hi, dim);
    st = WriteCsv(base + "_frf.csv", std::string("freq_") + (dim ? "hz" : "rad_per_tau") + ",in_mag,out_mag,frf_db",
                  {e.freq, e.in_mag, e.out_mag, e.db});
    if (!st.ok()) return Fail(st);
    frf_plot.curves.push_back(ChirpCurve("sweep " + dir, *rec, lo, hi, dim));
    const ChirpFrfPlot::Curve& h1 = frf_plot.curves.back();
    st = WriteCsv(base + "_h1.csv",
                  std::string("freq_") + (dim ? "hz" : "rad_per_tau") + ",in_mag,out_mag,h1_db,coherence",
                  {h1.freq, h1.in_mag, h1.out_mag, h1.db, h1.coherence});
    if (!st.ok()) return Fail(st);
    const int window = a.window > 0
                           ? a.window
                           : std::max(64, static_cast<int>(std::pow(2, std::round(std::log2(rec->t.size() / 60.0)))));
    const Spectrogram sg = ComputeSpectrogram(rec->y, rec->dt, window, 4 * hi, dim);
    // y: the frequency content of the response y_m (harmonics of the forcing show as multiples of
    // the forcing ridge), not the forcing frequency itself.
    SpectrogramPlot sp{frf_plot.title + ", sweep " + dir + ": spectrogram of y_m",
                       dim ? "time t [s]" : "time {/Symbol t}",
                       dim ? "frequency of y_m [Hz]" : "frequency of y_m, {/Symbol w} [rad/{/Symbol t}]",
                       sg.time,
                       sg.freq,
                       sg.db};
    if (gnuplot.ok()) {
      st = RenderSpectrogram(sp, base + "_spectrogram.png");
      if (CancelRequested()) return interrupted();  // gnuplot got the terminal's SIGINT too
      if (!st.ok()) return Fail(st);
    }
    summary["sweeps"].push_back(SweepSummary(dir, e, h1, *rec));
    for (const char* f : {".csv", "_frf.csv", "_h1.csv"}) summary["files"].push_back(base + f);
    if (gnuplot.ok()) summary["files"].push_back(base + "_spectrogram.png");
  }
  RestoreDefaultSignalHandlers();
  const std::string frf_png = (std::filesystem::path(a.out) / "frf.png").string();
  if (gnuplot.ok()) {
    Status st = RenderChirpFrf(frf_plot, frf_png);
    if (!st.ok()) return Fail(st);
    summary["files"].push_back(frf_png);
  }
  summary["unit"] = unit;
  if (a.json) {
    std::cout << DumpJson(summary, 1) << "\n";
  } else {
    PrintChirpSummary(summary, lo, hi, unit);
  }
  return 0;
}

}  // namespace

ChirpFrfPlot::Curve ChirpCurve(const std::string& label, const ChirpRecord& rec, double lo, double hi, bool hz) {
  const H1Estimate h = WelchH1(rec.v0, rec.v_abs, rec.dt, lo, hi, hz);
  const FrfEstimate raw = FftFrf(rec.v0, rec.v_abs, rec.dt, lo, hi, hz);
  return {label, h.freq, h.in_mag, h.out_mag, h.db, h.coherence, raw.freq, raw.db};
}

ChirpFrfPlot ChirpFigure(const std::string& title, bool hz) {
  ChirpFrfPlot p;
  p.title = title;
  p.freq_label = hz ? "frequency f [Hz]" : "frequency {/Symbol w} [rad/{/Symbol t}]";
  // Welch-averaged spectral magnitudes of a swept sine: their scale depends on the sweep rate and the
  // segment (docs/numerics.md), so they are compared with each other, not read as amplitudes.
  p.mag_label = "averaged |velocity spectrum| [a.u.]";
  return p;
}

void AddChirpCommand(CLI::App& app, int* exit_code) {
  auto a = std::make_shared<ChirpArgs>();
  ChirpOptions& o = a->o;
  CLI::App* cmd =
      app.add_subcommand("chirp", "Frequency-sweep simulation: FFT-based FRF and spectrograms (paper Figs. 22-24)");
  cmd->add_option("--model", a->model,
                  "standalone | coupled | linear | linear-coupled | dimensional | dimensional-linear")
      ->capture_default_str();
  cmd->add_option("--alpha", o.alpha, "non-dimensional base amplitude alpha")->capture_default_str();
  cmd->add_option("--a0-mm", a->a0_mm, "dimensional base amplitude A0 [mm]")->capture_default_str();
  cmd->add_option("--from", o.from, "start frequency: Omega [rad/tau], or Hz for dimensional models")
      ->capture_default_str();
  cmd->add_option("--to", o.to, "end frequency")->capture_default_str();
  cmd->add_option("--duration", o.duration, "sweep duration: tau, or s for dimensional models")->capture_default_str();
  cmd->add_option("--dt", o.dt, "RK4 step (non-dimensional) or output step in s (dimensional)")->capture_default_str();
  cmd->add_option("--direction", a->direction, "up | down | both")->capture_default_str();
  cmd->add_option("--window", a->window, "spectrogram window in samples (default: about 1/60 of the record)");
  cmd->add_option("--out", a->out, "output directory")->capture_default_str();
  cmd->add_flag("--json", a->json, "print {files, sweeps: [{direction, frf_max_db, frf_min_db, ...}], unit}");
  cmd->footer(
      "The base follows a linear chirp; the FRF is the Welch-averaged H1 = Sxy/Sxx of output abs. velocity over\n"
      "input velocity in dB with its coherence (sweep_*_h1.csv), and the raw |FFT(out)| / |FFT(in)| (sweep_*_frf.csv;\n"
      "paper Eq. 10 in the frequency domain). Stepped-sine sweeps: a sweep spec with\n"
      "[continuation] axis = \"omega\" (examples/stepped_sine.toml).");
  cmd->callback([a, exit_code]() { *exit_code = RunChirpCommand(*a); });
}

}  // namespace bistable
