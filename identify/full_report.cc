// identify::Summary::FullReport (identify/identify.h): the text of a fit that `bistable identify` prints and the
// Python module returns (its result's full_report()).
#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

#include "identify/diagnostics.h"
#include "identify/identify.h"

namespace bistable::identify {
namespace {

std::string F(double v, int digits = 4) { return FormatSignificant(v, digits); }

// printf into a std::string (the lines of the report).
template <class... Args>
std::string Line(const char* format, Args... args) {
  char b[1024];
  std::snprintf(b, sizeof b, format, args...);
  return b;
}

// A model's parameters as fitted, one a line: name, value, ± σ, unit.
std::string ParameterLines(const IdentModel& model, const FitResult& fit) {
  const auto names = model.ParamNames();
  const auto units = model.ParamUnits();
  std::string s;
  for (size_t i = 0; i < names.size() && i < fit.theta.size(); ++i)
    s += Line("  %-28s %12s ± %-9s %s\n", names[i].c_str(), F(fit.theta[i], 6).c_str(),
              F(i < fit.sigma.size() ? fit.sigma[i] : NAN, 2).c_str(), units[i].c_str());
  return s;
}

// Where the final σ came from when --bootstrap was asked (empty otherwise).
std::string BootstrapLine(const BootstrapResult& b) {
  if (b.twins == 0) return "";
  if (!b.ok()) return "  σ: Gauss–Newton; no bootstrap: " + b.note + "\n";
  return Line("  σ: bootstrap, %d of %d twin records refitted (%.1f s); Gauss–Newton σ in the JSON\n", b.fitted,
              b.twins, b.seconds);
}

// The loop's diagnostics in a few lines: the invariants of chaotic records, a lost attractor, the residual's
// whiteness or what is left unexplained, separability hints.
std::string DiagnosticsLines(const LoopDiagnostics& d) {
  std::string s;
  if (d.chaos.chaotic)
    s += "invariants (declared -> final): Poincare H " + F(d.declared.poincare, 3) + " -> " + F(d.final.poincare, 3) +
         ", switches/s " + F(d.declared.switching_rate, 3) + " -> " + F(d.final.switching_rate, 3) + " (measured " +
         F(d.final.switching_rate_measured, 3) + "), right-well share " + F(d.declared.right_well_fraction, 2) +
         " -> " + F(d.final.right_well_fraction, 2) + " (measured " + F(d.final.right_well_fraction_measured, 2) +
         "), velocity Hellinger " + F(d.declared.velocity_hellinger, 3) + " -> " + F(d.final.velocity_hellinger, 3) +
         "\n";
  if (!d.attractor_loss.empty())
    s += "the final model loses the attractor the declared model had: " + d.attractor_loss + "\n";
  s += d.unexplained.empty() ? WhitenessVerdict(d.whiteness) + "\n" : "unexplained: " + d.unexplained + "\n";
  for (const std::string& h : d.separability) s += h + "\n";
  return s;
}

// A test split's RMS of the main output (NaN where the simulation diverged).
double TestRms(const Errors& e) {
  return !e.record_rms.empty() && std::isfinite(e.record_rms[0]) ? e.record_rms[0] : NAN;
}

}  // namespace

std::string Summary::FullReport() const {
  const IdentifyResult& r = result;
  // The objective the loop ran (objective auto: what its choice made) and, under shooting, the segments' length.
  const Objective ran = r.objective_choice.made ? r.objective_choice.objective : plan.loop.fit.objective;
  const double horizon = r.objective_choice.made ? r.objective_choice.horizon_s : plan.loop.fit.shooting_horizon_s;
  std::string s = "identify: " + std::to_string(records.size()) + " record(s) (";
  for (size_t i = 0; i < records.size(); ++i)
    s += (i ? ", " : "") + records[i].name + ": " + std::to_string(records[i].n()) + " samples";
  s += "), objective " +
       std::string(ran == Objective::kShooting ? "shooting"
                   : ran == Objective::kFft    ? "fft"
                                               : "time") +
       ", frame " + (plan.setup.frame == OutputFrame::kRelative ? "relative" : "absolute") +
       (frame.made ? " (chosen of both)" : "") + "\n";
  s += Line("error (NRMSE of the output): %s %% before, %s %% after   (spectral: %s %% -> %s %%)\n",
            F(r.before.errors.nrmse).c_str(), F(r.after.errors.nrmse).c_str(), F(r.before.errors.fft).c_str(),
            F(r.after.errors.fft).c_str());
  if (std::isfinite(r.after.errors.shooting))
    s += Line("short-horizon error (--objective shooting, %s s segments): %s %% before, %s %% after\n",
              F(horizon).c_str(), F(r.before.errors.shooting).c_str(), F(r.after.errors.shooting).c_str());
  for (const LoopStep& step : r.steps) s += "  " + step.verdict + "\n";
  s += "declared model (fitted):\n" + ParameterLines(r.declared, r.before);
  s += "final model:\n" + ParameterLines(r.final_model, r.after);
  s += BootstrapLine(r.bootstrap);
  for (const TestSplit& t : tests)
    s += Line("test %s [%zu:%zu): RMS %s before, %s after\n", t.record.c_str(), t.begin, t.end,
              F(TestRms(t.before)).c_str(), F(TestRms(t.after)).c_str());
  s += DiagnosticsLines(r.diagnostics);
  s += Line("%.1f s, %lld simulations\n", r.seconds, simulations);
  return s;
}

}  // namespace bistable::identify
