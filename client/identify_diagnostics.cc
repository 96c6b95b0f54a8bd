#include "client/identify_diagnostics.h"

#include <cmath>
#include <cstdio>

#include "engine/json_shapes.h"

namespace bistable {
namespace {

std::string F(double v, int digits = 4) { return FormatSignificant(v, digits); }

nlohmann::json DriftObject(const std::vector<ParamDrift>& drift) {
  nlohmann::json d = nlohmann::json::object();
  for (const ParamDrift& p : drift)
    d[p.name] = {{"before", JsonNumber(p.before)},
                 {"after", JsonNumber(p.after)},
                 {"relative", JsonNumber(p.relative)},
                 {"in_sigma", JsonNumber(p.in_sigma)}};
  return d;
}

nlohmann::json WhitenessObject(const Whiteness& w) {
  return {{"statistic", JsonNumber(w.statistic)},
          {"test", "Ljung-Box"},
          {"dof", w.dof},
          {"diverged", w.diverged},
          {"p_value", JsonNumber(w.p_value)},
          {"alpha", w.alpha},
          {"n_eff", JsonNumber(w.n_eff)},
          {"flatness", JsonNumber(w.flatness)},
          {"predictable_share", JsonNumber(1 - w.flatness)},
          {"predictable_threshold", kPredictableShare},
          {"twin_predictable_share", JsonNumber(w.twin_predictable_share)},
          {"white", w.white},
          {"dominant_frequencies_hz", w.dominant_hz},
          {"residual", w.residual}};
}

}  // namespace

nlohmann::json InvariantsObject(const Invariants& v) {
  nlohmann::json outs = nlohmann::json::object();
  for (const Invariants::Output& o : v.by_output)
    outs[o.name] = {{"hellinger", JsonNumber(o.hellinger)}, {"spectral_error_percent", JsonNumber(o.spectral_error)}};
  return {{"poincare_energy", JsonNumber(v.poincare)},
          {"poincare_floor", JsonNumber(v.poincare_floor)},
          {"section_points", v.section_points},
          {"switching_rate_hz", JsonNumber(v.switching_rate)},
          {"switching_rate_measured_hz", JsonNumber(v.switching_rate_measured)},
          {"switching_rate_error", JsonNumber(v.switching_error)},
          {"right_well_fraction", JsonNumber(v.right_well_fraction)},
          {"right_well_fraction_measured", JsonNumber(v.right_well_fraction_measured)},
          {"well_centres_m",
           {{"simulated", nlohmann::json::array({JsonNumber(v.well_centres[0]), JsonNumber(v.well_centres[1])})},
            {"measured",
             nlohmann::json::array({JsonNumber(v.well_centres_measured[0]), JsonNumber(v.well_centres_measured[1])})}}},
          {"velocity_hellinger", JsonNumber(v.velocity_hellinger)},
          {"spectral_error_percent", JsonNumber(v.spectral_error)},
          {"by_output", outs}};
}

void AddDiagnosticsJson(const IdentifyResult& r, const std::vector<PreparedRecord>& recs, nlohmann::json* j) {
  const LoopDiagnostics& d = r.diagnostics;
  nlohmann::json rec = nlohmann::json::array();
  for (size_t i = 0; i < d.chaos.record_chaotic.size(); ++i)
    rec.push_back({{"name", i < recs.size() ? recs[i].name : std::to_string(i)},
                   {"chaotic", static_cast<bool>(d.chaos.record_chaotic[i])},
                   {"forcing_hz", JsonNumber(d.chaos.forcing_hz[i])},
                   {"input_broadband_share", JsonNumber(d.chaos.input_broadband[i])},
                   {"output_broadband_share", JsonNumber(d.chaos.output_broadband[i])}});
  (*j)["chaos_check"] = {{"chaotic", d.chaos.chaotic}, {"rule", d.chaos.rule}, {"records", rec}};
  if (d.chaos.chaotic) {
    nlohmann::json steps = nlohmann::json::array();
    for (const StepDiagnostics& s : d.steps)
      steps.push_back(
          {{"term", s.term},
           {"kept", s.kept && !s.refound},
           {"refound", s.refound},
           {"before", InvariantsObject(s.before)},
           {"after", InvariantsObject(s.after)},
           {"attractor_lost", s.attractor_loss.empty() ? nlohmann::json() : nlohmann::json(s.attractor_loss)}});
    (*j)["invariants"] = {
        {"before", InvariantsObject(d.declared)},
        {"after", InvariantsObject(d.final)},
        {"steps", steps},
        {"attractor_lost", d.attractor_loss.empty() ? nlohmann::json() : nlohmann::json(d.attractor_loss)}};
  } else {
    (*j)["invariants"] = nullptr;
  }
  (*j)["whiteness"] = WhitenessObject(d.whiteness);
  for (const auto& [name, w] : d.whiteness_by_output) (*j)["whiteness"]["by_output"][name] = WhitenessObject(w);
  if (d.unexplained.empty()) {
    (*j)["unexplained"] = nullptr;
  } else {
    nlohmann::json u = WhitenessObject(d.whiteness);
    u["message"] = d.unexplained;
    (*j)["unexplained"] = u;
  }
  (*j)["correlations"] = nlohmann::json::array();
  for (const ParamCorrelation& c : d.correlations)
    (*j)["correlations"].push_back({{"a", c.a}, {"b", c.b}, {"rho", JsonNumber(c.rho)}});
  (*j)["separability"] = d.separability;
  (*j)["absorbed"] = d.absorbed;
  (*j)["refits"] = nlohmann::json::array();
  size_t added = 0;
  for (const StepDiagnostics& s : d.steps) {
    (*j)["refits"].push_back(
        {{"term", s.term}, {"kept", s.kept && !s.refound}, {"refound", s.refound}, {"drift", DriftObject(s.drift)}});
    if (s.kept && !s.refound && added < (*j)["effects_added"].size())
      (*j)["effects_added"][added++]["drift"] = DriftObject(s.drift);
  }
}

void WriteDiagnosticsReport(std::ostream& md, const IdentifyResult& r) {
  const LoopDiagnostics& d = r.diagnostics;
  if (d.chaos.chaotic) {
    md << "## Invariants (chaotic records)\n\n" << d.chaos.rule << ". Forcing: ";
    for (size_t i = 0; i < d.chaos.forcing_hz.size(); ++i)
      md << (i ? ", " : "") << F(d.chaos.forcing_hz[i]) << " Hz (output broadband share "
         << F(d.chaos.output_broadband[i], 3) << (d.chaos.record_chaotic[i] ? ", chaotic" : "") << ")";
    md << ".\n\n| model | Poincaré H | switches/s (measured) | right-well share (measured) | velocity Hellinger | "
          "spectral error |";
    for (const Invariants::Output& o : d.declared.by_output)
      md << " " << o.name << " Hellinger | " << o.name << " spectral |";
    md << "\n|---|---|---|---|---|---|";
    for (size_t k = 0; k < d.declared.by_output.size(); ++k) md << "---|---|";
    md << "\n";
    auto row = [&](const std::string& what, const Invariants& v) {
      md << "| " << what << " | " << F(v.poincare, 3) << " | " << F(v.switching_rate, 3) << " ("
         << F(v.switching_rate_measured, 3) << ") | " << F(v.right_well_fraction, 2) << " ("
         << F(v.right_well_fraction_measured, 2) << ") | " << F(v.velocity_hellinger, 3) << " | "
         << F(v.spectral_error, 3) << " % |";
      for (size_t k = 0; k < d.declared.by_output.size(); ++k)
        if (k < v.by_output.size())
          md << " " << F(v.by_output[k].hellinger, 3) << " | " << F(v.by_output[k].spectral_error, 3) << " % |";
        else
          md << " – | – |";
      md << "\n";
    };
    row("declared", d.declared);
    for (const StepDiagnostics& s : d.steps)
      row(s.refound ? "refit with " + s.term + ": a better optimum without it"
                    : "+ " + s.term + (s.kept ? "" : " (refit, not kept)"),
          s.after);
    md << "\nThe measured section's first half against its second half gives H = " << F(d.declared.poincare_floor, 3)
       << " (what another stretch of the same measurement gives).\n";
    for (const StepDiagnostics& s : d.steps)
      if (!s.attractor_loss.empty())
        md << "\n**"
           << (s.refound ? "The model refound by the refit with `" + s.term + "` (without it)"
                         : "The model with `" + s.term + "`" + (s.kept ? "" : " (refit, not kept)"))
           << " loses the attractor** that the model before it had: " << s.attractor_loss << ".\n";
    if (!d.attractor_loss.empty())
      md << "\n**The final model loses the attractor** that the declared model had: " << d.attractor_loss << ".\n";
    md << "\nPoincaré H: energy coefficient of the stroboscopic sections (y, y') at the forcing (0 identical, 1 far "
          "apart); "
          "switches: changes of well between forcing periods (the period means of y split into two wells by two-means, "
          "hysteresis a quarter of the wells' distance); right-well share: periods in the right well of those in a "
          "well; "
          "Hellinger distance of the velocity histograms (0 identical, 1 disjoint); spectral error: Eq. 20, "
          "normalised.\n\n";
  }
  md << "## Residual whiteness\n\n";
  const Whiteness& w = d.whiteness;
  md << "Ljung–Box on the band-limited residual of the final model (" << w.residual << "): Q = " << F(w.statistic)
     << " on " << w.dof << " lags, p = " << F(w.p_value, 2) << ", n_eff = " << F(w.n_eff, 5) << "; spectral flatness "
     << F(w.flatness, 3) << " (" << F(100 * (1 - w.flatness), 3)
     << " % of the residual predictable from its past). Far from white when p < " << F(w.alpha, 2)
     << " and that share ≥ " << F(100 * kPredictableShare, 2) << " %. ";
  if (!w.dominant_hz.empty()) {
    md << "Strongest lines:";
    for (double f : w.dominant_hz) md << " " << F(f) << " Hz";
    md << ".";
  }
  if (d.whiteness_by_output.size() > 1) {
    md << "\n\n| output | Q | lags | p | predictable share | white |\n|---|---|---|---|---|---|\n";
    for (const auto& [name, wo] : d.whiteness_by_output)
      md << "| " << name << " | " << F(wo.statistic) << " | " << wo.dof << " | " << F(wo.p_value, 2) << " | "
         << F(100 * (1 - wo.flatness), 3) << " % | " << (wo.white ? "yes" : "no") << " |\n";
  }
  md << "\n\n"
     << (d.unexplained.empty() ? "The residual is white: nothing left unexplained.\n\n"
                               : "**Unexplained:** " + d.unexplained + "\n\n");
  md << "## Parameter correlations and drift\n\n";
  if (r.after.covariance.size() == 0)
    md << "No covariance for the spectral objective: correlations not computed.\n\n";
  else if (d.correlations.empty())
    md << "No pair of parameters correlated beyond |ρ| = " << F(kStrongCorrelation, 2) << ".\n\n";
  for (const ParamCorrelation& c : d.correlations) md << "- ρ(" << c.a << ", " << c.b << ") = " << F(c.rho, 3) << "\n";
  if (!d.correlations.empty()) md << "\n";
  for (const StepDiagnostics& s : d.steps) {
    md << "Refit with `" << s.term << "` ("
       << (s.refound ? "a better optimum without it, not kept"
           : s.kept  ? "kept"
                     : "not kept")
       << "): drift of the parameters before it\n\n"
       << "| parameter | before | after | relative | in σ |\n|---|---|---|---|---|\n";
    for (const ParamDrift& p : s.drift)
      md << "| " << p.name << " | " << F(p.before) << " | " << F(p.after) << " | " << F(100 * p.relative, 3) << " % | "
         << F(p.in_sigma, 3) << " |\n";
    md << "\n";
  }
  for (const std::string& a : d.absorbed) md << "- " << a << ".\n";
  if (!d.absorbed.empty()) md << "\n";
  for (const std::string& h : d.separability) md << "**Separability:** " << h << "\n\n";
}

}  // namespace bistable
