// report.md, report.json, the figures and the text summary of `bistable identify` (client/identify_report.h).
#include "client/identify_report.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <sstream>
#include <vector>

#include "client/cli_common.h"
#include "client/identify_diagnostics.h"
#include "client/plot.h"
#include "engine/json_shapes.h"

namespace bistable {
namespace {

std::string Fmt(double v, int digits = 4) {
  char b[48];
  std::snprintf(b, sizeof b, "%.*g", digits, v);
  return b;
}

// Plots: residual force against y and y' before/after; measured vs simulated for each record.
Status WritePlots(const IdentifyResult& r, const std::vector<PreparedRecord>& recs, const Setup& setup,
                  const std::string& dir, std::vector<std::string>* files) {
  PanelPlot res;
  res.title = "restoring-force residual of the main body (force the model lacks), before and after";
  res.rows = 2, res.cols = 2;
  auto cloud = [](const ResidualCloud& c, bool vel, const std::string& colour) {
    PanelPlot::Series s;
    s.points = true, s.colour = colour;
    for (size_t i = 0; i < c.r.size(); ++i) s.x.push_back(vel ? c.v[i] : c.q[i] * 1e3), s.y.push_back(c.r[i]);
    return s;
  };
  const std::string yl = setup.input == InputKind::kBaseDisplacement ? "y = x - x0 [mm]" : "y [mm]";
  for (int row = 0; row < 2; ++row) {
    const ResidualCloud& c = row == 0 ? r.residual_before : r.residual_after;
    const std::string when = row == 0 ? "declared model" : "final model";
    for (int col = 0; col < 2; ++col) {
      PanelPlot::Panel p;
      p.title = when + (col == 0 ? ": against displacement" : ": against velocity");
      p.x_label = col == 0 ? yl : "y' [m/s]";
      p.y_label = "residual force [N]";
      p.series.push_back(cloud(c, col == 1, row == 0 ? "#b2182b" : "#2166ac"));
      p.series.back().label = when;
      res.panels.push_back(p);
    }
  }
  const std::string f1 = (std::filesystem::path(dir) / "residual_force.png").string();
  BISTABLE_RETURN_IF_ERROR(RenderPanels(res, f1));
  files->push_back("residual_force.png");
  for (size_t i = 0; i < recs.size(); ++i) {
    SimOutputs before, after;
    SimulateOutputs(r.declared, r.before.theta, {}, recs[i], setup, 0, 0, false, &before);
    SimulateOutputs(r.final_model, r.after.theta, {}, recs[i], setup, 0, 0, false, &after);
    const bool volt = recs[i].Has(OutputSlot::kVoltage);
    PanelPlot tp;
    tp.title = "record " + recs[i].name + ": measured and simulated output" + (volt ? "s" : "");
    tp.rows = volt ? 4 : 2, tp.cols = 1;
    for (int row = 0; row < tp.rows; ++row) {
      const int slot = row < 2 ? 0 : 2;
      const bool declared = row % 2 == 0;
      PanelPlot::Panel p;
      p.title = std::string(declared ? "declared model" : "final model") +
                (volt ? ": " + OutputName(setup, static_cast<OutputSlot>(slot)) : "");
      p.x_label = "t [s]";
      p.y_label = slot == 2 ? "voltage [V]" : "output (SI)";
      PanelPlot::Series m, s, e;
      m.label = "measured", m.colour = "#444444";
      s.label = "simulated", s.colour = declared ? "#b2182b" : "#2166ac";
      e.label = "error", e.colour = "#1a9850";
      const std::vector<double>& sim = (declared ? before : after).out[slot];
      const std::vector<double>& meas = recs[i].Measured(static_cast<OutputSlot>(slot));
      const size_t stride = std::max<size_t>(1, recs[i].n() / 6000);
      for (size_t k = 0; k < recs[i].n() && k < sim.size(); k += stride) {
        const double t = recs[i].t0 + k * recs[i].dt;
        m.x.push_back(t), m.y.push_back(meas[k]);
        s.x.push_back(t), s.y.push_back(sim[k]);
        e.x.push_back(t), e.y.push_back(sim[k] - meas[k]);
      }
      p.series = {m, s, e};
      tp.panels.push_back(p);
    }
    const std::string name = "record_" + std::to_string(i + 1) + ".png";
    BISTABLE_RETURN_IF_ERROR(RenderPanels(tp, (std::filesystem::path(dir) / name).string()));
    files->push_back(name);
  }
  return Status::Ok();
}

// A test split's RMS as formatted in the report and the summary (NaN when it diverged: null in JSON).
std::string TestRms(const nlohmann::json& t, const char* key) {
  return Fmt(t[key].is_null() ? NAN : t[key].get<double>());
}

// report.md's sections from the errors to the evidence: error before/after (records, tests), the
// effects added, and every step's candidate table.
std::string JsonFmt(const nlohmann::json& v) { return Fmt(v.is_number() ? v.get<double>() : NAN); }

void WriteReportEvidence(std::ostream& md, const IdentifyResult& r, const std::vector<PreparedRecord>& recs,
                         const nlohmann::json& j) {
  const nlohmann::json& tests = j["tests"];
  md << "## Error before and after\n\n| | declared model | final model |\n|---|---|---|\n";
  md << "| NRMSE of the output, all records | " << Fmt(r.before.errors.nrmse) << " % | " << Fmt(r.after.errors.nrmse)
     << " % |\n";
  md << "| spectral error (Eq. 20, normalised) | " << Fmt(r.before.errors.fft) << " % | " << Fmt(r.after.errors.fft)
     << " % |\n";
  if (std::isfinite(r.after.errors.shooting))
    md << "| short-horizon (shooting) NRMSE | " << Fmt(r.before.errors.shooting) << " % | "
       << Fmt(r.after.errors.shooting) << " % |\n";
  for (size_t i = 0; i < recs.size(); ++i)
    md << "| `" << recs[i].name << "` NRMSE / RMS | " << Fmt(r.before.errors.record_nrmse[i]) << " % / "
       << Fmt(r.before.errors.record_rms[i]) << " | " << Fmt(r.after.errors.record_nrmse[i]) << " % / "
       << Fmt(r.after.errors.record_rms[i]) << " |\n";
  for (const auto& t : tests)
    md << "| test `" << t["record"].get<std::string>() << "` [" << t["range"].get<std::string>() << ") RMS | "
       << TestRms(t, "rms_before") << " | " << TestRms(t, "rms_after") << " |\n";
  if (!j["errors_by_output"].empty()) {
    md << "\n## Outputs\n\nFitted jointly; each output's NRMSE² weighs λ = (ν_main/ν)² in the objective, ν = noise σ / "
          "RMS "
          "(σ from the spectral floor above the signal's band).\n\n| output | NRMSE declared | NRMSE final | spectral "
          "declared | "
          "spectral final | noise σ | weight λ |\n|---|---|---|---|---|---|---|\n";
    for (const auto& [name, o] : j["errors_by_output"].items())
      md << "| " << name << " | " << JsonFmt(o["before"]) << " % | " << JsonFmt(o["after"]) << " % | "
         << JsonFmt(o["fft_before"]) << " % | " << JsonFmt(o["fft_after"]) << " % | " << JsonFmt(o["noise"]) << " | "
         << JsonFmt(o["weight"]) << " |\n";
  }
  if (!j["velocity_frame"].is_null()) {
    const auto& f = j["velocity_frame"];
    md << "\n## Velocity frame\n\nThe loop was run with the sensor read as absolute and as base-relative velocity; "
          "final error "
          "(RMS over the outputs of each one's "
       << (f["metric"] == "spectral" ? "spectral error" : "NRMSE") << ") " << JsonFmt(f["error_absolute"])
       << " % (absolute) and " << JsonFmt(f["error_relative"]) << " % (relative): **" << f["chosen"].get<std::string>()
       << "** kept.\n\n| frame | final error per output |\n|---|---|\n";
    for (const char* fr : {"absolute", "relative"}) {
      md << "| " << fr << " |";
      for (const auto& [name, v] : f["errors_by_output"][fr].items()) md << " " << name << " " << JsonFmt(v) << " %;";
      md << " |\n";
    }
  }
  md << "\n## Effects added\n\n";
  if (r.added.empty()) md << "None: nothing in the residual beat the noise.\n";
  for (const AddedEffect& e : r.added) {
    const TermDef* t = *FindTerm(e.term);
    md << "- **" << e.term << "** (" << t->meaning << "; `" << t->formula << "`): ";
    for (size_t i = 0; i < e.names.size(); ++i)
      md << (i ? ", " : "") << e.names[i] << " = " << Fmt(e.params[i]) << " ± " << Fmt(e.sigma[i], 2) << " "
         << e.units[i];
    md << "; error " << Fmt(e.error_before) << " % → " << Fmt(e.error_after) << " % when added.\n";
  }
  md << "\n## Evidence\n\n";
  for (size_t k = 0; k < r.steps.size(); ++k) {
    const LoopStep& s = r.steps[k];
    md << "Step " << k + 1 << ": " << s.verdict << " (n_eff " << Fmt(s.n_eff, 4) << ", residual force RMS "
       << Fmt(s.residual_rms, 3) << " N).\n\n";
    md << "| candidate | ΔBIC (simulation residual) | explained | signed | ΔBIC (force residual) | explained "
          "|\n|---|---|---|---|---|---|\n";
    for (size_t i = 0; i < std::min<size_t>(s.scores.size(), 8); ++i) {
      const CandidateScore& c = s.scores[i];
      md << "| " << c.term << " | " << Fmt(c.delta_bic) << " | " << Fmt(100 * c.explained, 3) << " % | "
         << (c.sign_ok ? "yes" : "no") << " | " << Fmt(c.force_delta_bic) << " | " << Fmt(100 * c.force_explained, 3)
         << " % |\n";
    }
    md << "\n";
  }
}

}  // namespace

// --report DIR: the figures, report.md and report.json (the result `j`).
Status WriteReport(const std::string& report, const std::string& declared, const identify::Summary& s,
                   const nlohmann::json& j) {
  const IdentifyResult& r = s.result;
  const std::vector<PreparedRecord>& recs = s.records;
  const Setup& setup = s.plan.setup;
  std::error_code ec;
  std::filesystem::create_directories(report, ec);
  if (ec) return Status::IoError("report", "cannot create '" + report + "': " + ec.message());
  std::vector<std::string> figs;
  BISTABLE_RETURN_IF_ERROR(WritePlots(r, recs, setup, report, &figs));
  std::ostringstream md;  // written whole or not at all, like report.json (AtomicFile)
  md << "# Identification report\n\n";
  md << "Declared terms: `" << declared << "`; records: ";
  for (size_t i = 0; i < recs.size(); ++i)
    md << (i ? ", " : "") << "`" << recs[i].name << "` (" << recs[i].n() << " samples)";
  md << ".\n\n";
  WriteReportEvidence(md, r, recs, j);
  WriteDiagnosticsReport(md, r);
  md << "## Final model\n\n| parameter | value | ± σ | unit |\n|---|---|---|---|\n";
  const auto names = r.final_model.ParamNames();
  const auto units = r.final_model.ParamUnits();
  for (size_t i = 0; i < names.size(); ++i)
    md << "| " << names[i] << " | " << Fmt(r.after.theta[i], 6) << " | " << Fmt(r.after.sigma[i], 2) << " | "
       << units[i] << " |\n";
  md << (r.bootstrap.ok() ? "\nσ: bootstrap, the spread of " + std::to_string(r.bootstrap.fitted) + " of " +
                                std::to_string(r.bootstrap.twins) + " twin records refitted (`--bootstrap`)."
                          : std::string("\nσ: Gauss–Newton covariance scaled by the residual's correlation time."))
     << " Friction constants v_sp = " << setup.fc.v_sp << " m/s, v_t = " << setup.fc.v_t << " m/s. Wall time "
     << Fmt(r.seconds, 3) << " s, " << s.simulations << " simulations.\n\n## Figures\n\n";
  for (const std::string& f : figs) md << "![" << f << "](" << f << ")\n\n";
  const std::filesystem::path dir(report);
  BISTABLE_RETURN_IF_ERROR(WriteTextOut((dir / "report.json").string(), DumpJson(j, 2) + "\n", "report"));
  return WriteTextOut((dir / "report.md").string(), md.str(), "report");
}

// The human-readable result on stdout.
void PrintSummary(const std::string& report, const identify::Summary& s) {
  std::printf("%s", s.FullReport().c_str());
  if (!report.empty()) std::printf("report in %s\n", report.c_str());
}

}  // namespace bistable
