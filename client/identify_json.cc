#include "client/identify_json.h"
// The JSON of a fit as `bistable identify --json` prints it and the Python module returns it (identify_json.h).

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <limits>
#include <map>
#include <set>
#include <sstream>

#include <nlohmann/json.hpp>

#include "base/file.h"
#include "base/limits.h"
#include "base/names.h"
#include "client/cli_common.h"
#include "client/identify_diagnostics.h"
#include "client/identify_predict.h"
#include "client/identify_report.h"
#include "client/json_out.h"
#include "dynamics/cancel.h"
#include "engine/json_shapes.h"
#include "engine/sweep_spec.h"
#include "identify/identify.h"
#include "identify/synthetic.h"

namespace bistable {

// --bootstrap N (null when not asked): twins asked and fitted, the refits' mean, the Gauss–Newton σ the
// bootstrap replaced, or why there is no bootstrap (note).
static nlohmann::json BootstrapJson(const BootstrapResult& b, const std::vector<std::string>& names) {
  if (b.twins == 0) return nullptr;
  nlohmann::json j = {{"twins", b.twins}, {"fitted", b.fitted}, {"seconds", JsonNumber(b.seconds)}};
  if (!b.note.empty()) j["note"] = b.note;
  nlohmann::json mean = nlohmann::json::object(), gn = nlohmann::json::object();
  for (size_t i = 0; i < names.size(); ++i) {
    if (i < b.mean.size()) mean[names[i]] = JsonNumber(b.mean[i]);
    if (i < b.gauss_newton_sigma.size()) gn[names[i]] = JsonNumber(b.gauss_newton_sigma[i]);
  }
  j["mean"] = mean;
  j["gauss_newton_sigma"] = gn;
  return j;
}

nlohmann::json ParamsJson(const IdentModel& m, const FitResult& f) {
  nlohmann::json j = nlohmann::json::object();
  const auto names = m.ParamNames();
  for (size_t i = 0; i < names.size(); ++i) j[names[i]] = JsonNumber(f.theta[i]);
  return j;
}

namespace {

// --test-range splits: JSON.
nlohmann::json TestsJson(const std::vector<identify::TestSplit>& tests) {
  nlohmann::json out = nlohmann::json::array();
  for (const identify::TestSplit& t : tests)
    out.push_back({{"record", t.record},
                   {"range", std::to_string(t.begin) + ":" + std::to_string(t.end)},
                   {"rms_before", JsonNumber(t.before.record_rms[0])},
                   {"rms_after", JsonNumber(t.after.record_rms[0])},
                   {"nrmse_before", JsonNumber(t.before.nrmse)},
                   {"nrmse_after", JsonNumber(t.after.nrmse)}});
  return out;
}

nlohmann::json ErrorsByOutputJson(const Errors& before, const Errors& after) {
  nlohmann::json j = nlohmann::json::object();
  for (size_t k = 0; k < after.outputs.size(); ++k) {
    const OutputErrors& a = after.outputs[k];
    const OutputErrors* b = k < before.outputs.size() ? &before.outputs[k] : nullptr;
    j[a.name] = {{"before", JsonNumber(b ? b->nrmse : NAN)},
                 {"after", JsonNumber(a.nrmse)},
                 {"fft_before", JsonNumber(b ? b->fft : NAN)},
                 {"fft_after", JsonNumber(a.fft)},
                 {"shooting_before", JsonNumber(b ? b->shooting : NAN)},
                 {"shooting_after", JsonNumber(a.shooting)},
                 {"noise", JsonNumber(a.noise)},
                 {"weight", JsonNumber(a.weight)}};
  }
  return j;
}

nlohmann::json FrameJson(const identify::FrameDecision& f) {
  if (!f.made) return nullptr;
  nlohmann::json by = nlohmann::json::object();
  for (int k = 0; k < 2; ++k) {
    nlohmann::json o = nlohmann::json::object();
    for (const OutputErrors& e : f.errors[k].outputs) o[e.name] = JsonNumber(identify::OutputError(e, f.metric));
    by[k == 0 ? "absolute" : "relative"] = o;
  }
  return {{"chosen", f.chosen},
          {"metric", f.metric},
          {"error_absolute", JsonNumber(f.error[0])},
          {"error_relative", JsonNumber(f.error[1])},
          {"errors_by_output", by}};
}

}  // namespace

nlohmann::json DrivePeriodErrors(const PreparedRecord& r, const Setup& setup, const std::vector<KeyedModel>& models) {
  const double f = DriveFrequency(r);
  nlohmann::json h = nlohmann::json::array();
  for (double periods : {1.0, 4.0}) {
    const double hs = std::isfinite(f) && f > 0 ? periods / f : NAN;
    nlohmann::json e = {{"drive_periods", periods}, {"horizon_s", JsonNumber(hs)}};
    for (const KeyedModel& km : models)
      e[km.key] = JsonNumber(std::isfinite(hs) ? HorizonError(*km.m, *km.th, r, setup, hs) : NAN);
    h.push_back(e);
  }
  return h;
}

namespace {

// --objective auto: per record the twin experiment that chose its horizon (null for the other objectives).
nlohmann::json ObjectiveChoiceJson(const ObjectiveChoice& c) {
  if (!c.made) return nullptr;
  auto records = [](const std::vector<Predictability>& ps) {
    nlohmann::json recs = nlohmann::json::array();
    for (const Predictability& p : ps)
      recs.push_back({{"record", p.record},
                      {"objective", p.long_meaningful ? "long simulation" : "short horizon"},
                      {"fit_horizon_s", p.fit_horizon_s},
                      {"chaos_floor_percent", JsonNumber(p.chaos_floor)},
                      {"model_long_error_percent", JsonNumber(p.long_error)},
                      {"followed", p.followed},
                      {"prediction_horizon_s", JsonNumber(p.horizon_s)},
                      {"duration_s", p.duration_s},
                      {"well_changes", p.well_changes},
                      {"reason", p.reason}});
    return recs;
  };
  const ObjectiveChoice::Continuation& k = c.continuation;
  nlohmann::json cont = nullptr;
  if (k.tried)
    cont = {{"ran", k.ran},
            {"long_error_before_percent", JsonNumber(k.long_before)},
            {"long_error_after_percent", JsonNumber(k.long_after)},
            {"reason", k.reason},
            {"records", records(k.records)}};
  return {{"decided_with", c.model},  {"meaningful_below_percent", kMeaningfulFloor},
          {"seconds", c.seconds},     {"objective", c.objective == Objective::kShooting ? "shooting" : "time"},
          {"horizon_s", c.horizon_s}, {"records", records(c.records)},
          {"continuation", cont}};
}

// The loop's evidence: per step the verdict and every candidate's scores.
nlohmann::json StepsJson(const IdentifyResult& r) {
  nlohmann::json steps = nlohmann::json::array();
  for (const LoopStep& s : r.steps) {
    nlohmann::json sc = nlohmann::json::array();
    for (const CandidateScore& c : s.scores)
      sc.push_back({{"term", c.term},
                    {"delta_bic", JsonNumber(c.delta_bic)},
                    {"explained", JsonNumber(c.explained)},
                    {"sign_ok", c.sign_ok},
                    {"force_delta_bic", JsonNumber(c.force_delta_bic)},
                    {"force_explained", JsonNumber(c.force_explained)},
                    {"twin_explained", JsonNumber(c.twin_explained)}});
    steps.push_back({{"verdict", s.verdict},
                     {"chosen", s.chosen},
                     {"n_eff", JsonNumber(s.n_eff)},
                     {"record_n_eff", JsonNumber(s.record_n_eff)},
                     {"residual_force_rms", JsonNumber(s.residual_rms)},
                     {"scores", sc}});
  }
  return steps;
}

}  // namespace

// The result as printed by --json and written to report.json.
nlohmann::json ResultJson(const identify::Options& o, const identify::Summary& s) {
  const IdentifyResult& r = s.result;
  const std::vector<PreparedRecord>& recs = s.records;
  const identify::Plan& plan = s.plan;
  nlohmann::json j;
  j["error_before"] = JsonNumber(r.before.errors.nrmse);
  j["error_after"] = JsonNumber(r.after.errors.nrmse);
  j["fft_error_before"] = JsonNumber(r.before.errors.fft);
  j["fft_error_after"] = JsonNumber(r.after.errors.fft);
  j["eq20_before"] = JsonNumber(r.before.errors.eq20);
  j["eq20_after"] = JsonNumber(r.after.errors.eq20);
  j["shooting_error_before"] = JsonNumber(r.before.errors.shooting);  // null unless --objective shooting
  j["shooting_error_after"] = JsonNumber(r.after.errors.shooting);
  j["objective"] = identify::Name(o.objective);
  j["objective_choice"] = ObjectiveChoiceJson(r.objective_choice);
  // The objective the loop ran and its error before and after (auto: what objective_choice chose).
  const Objective ran = r.objective_choice.made ? r.objective_choice.objective : plan.loop.fit.objective;
  auto objective_error = [&](const Errors& e) {
    return ran == Objective::kShooting ? e.shooting : ran == Objective::kFft ? e.fft : e.nrmse;
  };
  j["objective_ran"] = ran == Objective::kShooting ? "shooting" : ran == Objective::kFft ? "fft" : "time";
  j["objective_error_before"] = JsonNumber(objective_error(r.before.errors));
  j["objective_error_after"] = JsonNumber(objective_error(r.after.errors));
  j["long_simulation_error_before"] = JsonNumber(r.before.errors.long_nrmse);
  j["long_simulation_error_after"] = JsonNumber(r.after.errors.long_nrmse);
  j["declared"] = identify::JoinTerms(o.terms);
  j["final_terms"] = nlohmann::json::array();  // the final model's terms in order (--predict rebuilds it from them)
  for (const TermDef* t : r.final_model.terms) j["final_terms"].push_back(t->id);
  j["effects_added"] = nlohmann::json::array();
  for (const AddedEffect& e : r.added) {
    nlohmann::json p = nlohmann::json::object(), u = nlohmann::json::object();
    for (size_t i = 0; i < e.names.size(); ++i)
      p[e.names[i]] = JsonNumber(e.params[i]), u[e.names[i]] = JsonNumber(e.sigma[i]);
    j["effects_added"].push_back({{"term", e.term},
                                  {"params", p},
                                  {"uncertainty", u},
                                  {"error_before", JsonNumber(e.error_before)},
                                  {"error_after", JsonNumber(e.error_after)}});
  }
  j["params"] = ParamsJson(r.final_model, r.after);
  j["uncertainty"] = nlohmann::json::object();
  const auto names = r.final_model.ParamNames();
  for (size_t i = 0; i < names.size(); ++i) j["uncertainty"][names[i]] = JsonNumber(r.after.sigma[i]);
  // The final fit's covariance over `params` (Gauss–Newton, or the bootstrap's with --bootstrap) (row by row, in the
  // order of `names`; null for the spectral objective, which has none): what a robustness map of the fitted model draws
  // from (issue 42).
  j["covariance"] = nullptr;
  if (r.after.covariance.rows() == static_cast<Eigen::Index>(names.size()) &&
      r.after.covariance.cols() == static_cast<Eigen::Index>(names.size())) {
    nlohmann::json rows = nlohmann::json::array();
    for (Eigen::Index a = 0; a < r.after.covariance.rows(); ++a) {
      nlohmann::json row = nlohmann::json::array();
      for (Eigen::Index b = 0; b < r.after.covariance.cols(); ++b) row.push_back(JsonNumber(r.after.covariance(a, b)));
      rows.push_back(row);
    }
    j["covariance"] = {{"names", names}, {"matrix", rows}, {"method", r.bootstrap.ok() ? "bootstrap" : "gauss-newton"}};
  }
  j["bootstrap"] = BootstrapJson(r.bootstrap, names);
  j["params_declared_fit"] = ParamsJson(r.declared, r.before);
  j["errors_by_output"] = ErrorsByOutputJson(r.before.errors, r.after.errors);
  j["records"] = nlohmann::json::array();
  for (size_t i = 0; i < recs.size(); ++i)
    j["records"].push_back(
        {{"name", recs[i].name},
         {"samples", recs[i].n()},
         {"nrmse_before", JsonNumber(r.before.errors.record_nrmse[i])},
         {"nrmse_after", JsonNumber(r.after.errors.record_nrmse[i])},
         {"fft_before", JsonNumber(r.before.errors.record_fft[i])},
         {"fft_after", JsonNumber(r.after.errors.record_fft[i])},
         {"long_nrmse_before",
          JsonNumber(i < r.before.errors.record_long_nrmse.size() ? r.before.errors.record_long_nrmse[i] : NAN)},
         {"long_nrmse_after",
          JsonNumber(i < r.after.errors.record_long_nrmse.size() ? r.after.errors.record_long_nrmse[i] : NAN)},
         {"horizon_s", recs[i].horizon_s},
         {"rms_before", JsonNumber(r.before.errors.record_rms[i])},
         {"rms_after", JsonNumber(r.after.errors.record_rms[i])}});
  // Errors a reader can compare, per record: over one and four drive periods from the measured state, and the
  // whole simulation (long_nrmse_*), before and after.
  for (size_t i = 0; i < recs.size(); ++i) {
    const double f = DriveFrequency(recs[i]);
    nlohmann::json h = DrivePeriodErrors(
        recs[i], plan.setup, {{"before", &r.declared, &r.before.theta}, {"after", &r.final_model, &r.after.theta}});
    j["records"][i]["drive_hz"] = JsonNumber(f);
    j["records"][i]["drive_band_hz"] =
        recs[i].f_drive;  // the simulation's drive: the input low-passed there (0: as measured)
    j["records"][i]["horizon_errors"] = h;
  }
  j["tests"] = TestsJson(s.tests);
  j["steps"] = StepsJson(r);
  j["seconds"] = r.seconds;
  j["simulations"] = s.simulations;
  j["settings"] = {{"v_sp", plan.setup.fc.v_sp},
                   {"v_t", plan.setup.fc.v_t},
                   {"m_main", plan.model.m_main},
                   {"m_res", plan.model.m_res},
                   {"deriv_cutoff_hz", recs.empty() ? 0.0 : recs[0].f_cut},
                   {"global_evals", o.global_evals},
                   {"lm_iterations", o.lm_iterations},
                   {"shooting_horizon_s", o.horizon},
                   {"decimate", o.decimate},
                   {"max_seconds", o.max_seconds},
                   {"input_kind", identify::Name(o.input_kind)},
                   {"output_kind", identify::Name(o.output_kind)},
                   {"output_frame", plan.setup.frame == OutputFrame::kRelative ? "relative" : "absolute"},
                   {"drift_cutoff_hz", o.drift_cutoff},
                   {"fit_offsets", o.fit_offsets},
                   {"output_weights", identify::Name(o.output_weights)}};
  AddDiagnosticsJson(r, recs, &j);
  j["velocity_frame"] = FrameJson(s.frame);
  return j;
}

}  // namespace bistable
