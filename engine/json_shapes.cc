#include "engine/json_shapes.h"

#include <cmath>

#include "base/iso_time.h"
#include "engine/metric_catalog.h"

namespace bistable {

std::string DumpJson(const nlohmann::json& j, int indent) {
  return j.dump(indent, ' ', false, nlohmann::json::error_handler_t::replace);
}

nlohmann::json JsonNumber(double v) { return std::isfinite(v) ? nlohmann::json(v) : nlohmann::json(nullptr); }

nlohmann::json JsonTime(double unix_seconds) {
  if (unix_seconds == 0) return nullptr;
  const std::string t = IsoTimeUtc(unix_seconds);
  return t.empty() ? nlohmann::json(nullptr) : nlohmann::json(t);
}

nlohmann::json MetricNumberJson(const std::string& metric, double v) {
  const MetricInfo* m = FindMetric(metric);
  // Integer metrics hold whole numbers in a small range (CheckRecord); anything else prints as it is.
  if (m && m->integer && std::isfinite(v) && v == std::floor(v) && std::fabs(v) < 9e15)
    return nlohmann::json(static_cast<long long>(v));
  return JsonNumber(v);
}

nlohmann::json MetricValueJson(const std::string& metric, double v) {
  if (const char* name = CategoryName(metric, v)) return name;
  return MetricNumberJson(metric, v);
}

nlohmann::json SettingsJson(const PointSpec& s) {
  const auto ic = InitialState(s);
  nlohmann::json j = {
      {"model", ModelName(s.model)},
      {"alpha", s.alpha},
      {"omega", s.omega},
      {"eps", s.params.eps},
      {"eta", s.params.eta},
      {"integrator", IntegratorName(s.integration.integrator)},
      {"dt", s.integration.dt},
      {"t_end", s.integration.t_end},
      {"t_keep", s.integration.t_keep},
      {"ic", {ic[0], ic[1], ic[2], ic[3]}},
      {"ic_default", !s.ic_given},
      {"renorm_every", s.metrics.renorm_every},
      {"chaos_threshold", s.metrics.chaos_threshold},
      {"sample_every", s.metrics.sample_every},
      {"period_tol", s.metrics.period_tol},
      {"max_period", s.metrics.max_period},
      {"hd_level", s.metrics.hd_level},
      {"hd_top_k", s.metrics.hd_top_k},
      {"poincare_phase", s.metrics.poincare_phase},
      {"numerics_version", kNumericsVersion},
      {"labels", LabelModeName(s.integration.labels)},
  };
  if (s.integration.labels == LabelMode::kSettled) {
    j["settle_window"] = s.integration.settle_window;
    j["settle_min_strobes"] = s.integration.settle_min_strobes;
    j["settle_confirm"] = s.integration.settle_confirm;
    j["settle_cap"] = s.integration.settle_cap;
    j["quasi_lle"] = s.metrics.quasi_lle;
    j["chaos_01_min"] = s.metrics.chaos_01_min;
  }
  if (HasResonator(s.model)) {
    j["eta_r"] = s.params.eta_r;
    j["phi"] = s.params.phi;
    j["lambda"] = s.params.lambda;
  }
  if (s.integration.integrator != IntegratorKind::kRk4) {
    j["rtol"] = s.integration.rtol;
    j["atol"] = s.integration.atol;
  }
  return j;
}

nlohmann::json PointJson(const PointSpec& spec, const PointResult& r) {
  nlohmann::json peaks = nlohmann::json::array();
  for (const HdPeak& p : r.hd_peaks) peaks.push_back({{"freq", p.freq}, {"amp", p.amp}});
  return {
      {"frf_db", r.frf_db},
      {"lle", r.lle},
      {"lle_rosenstein", r.lle_rosenstein},
      {"motion", MotionName(r.motion)},
      {"period", r.period},
      {"strobe_samples", r.strobe_samples},
      {"hd_index", r.hd_index},
      {"hd_peaks", peaks},
      {"y_min", r.y_min},
      {"y_max", r.y_max},
      {"edr_b", r.edr_b},
      {"edr_r", r.edr_r},
      {"edr_t", r.edr_t},
      {"energy", {{"w_in", r.w_in}, {"w_net", r.w_net}, {"w_m", r.w_m}, {"w_r", r.w_r}, {"delta_e", r.delta_e}}},
      {"energy_balance_residual", r.energy_balance_residual},
      {"termination", TerminationName(r.termination)},
      {"settle_time", r.settle_time},
      {"lle_sigma", r.lle_sigma},
      {"label_confidence", r.label_confidence},
      {"chaos_01", r.chaos_01},
      {"steps", r.steps},
      {"rhs_evals", r.rhs_evals},
      {"settings", SettingsJson(spec)},
  };
}

void AddSpectrumJson(const LyapunovSpectrum& sp, nlohmann::json* j) {
  (*j)["lyapunov_spectrum"] = sp.exponents;
  (*j)["lyapunov_sum"] = sp.sum;
  (*j)["divergence"] = sp.divergence;
  (*j)["kaplan_yorke"] = sp.kaplan_yorke;
}

nlohmann::json SweepStatusJson(const SweepInfo& s) {
  return {{"id", s.id},
          {"state", SweepStateName(s.state)},
          {"items_done", s.items_done},
          {"items_total", s.items_total},
          {"items_cached", s.items_cached},
          {"workers", s.workers},
          {"seconds", s.seconds},
          {"file", s.file},
          {"name", s.name},
          {"model", s.model},
          {"error", s.error},
          {"owner", s.owner},
          {"created", JsonTime(s.created)},
          {"finished", JsonTime(s.finished)}};
}

nlohmann::json WorkerJson(const WorkerInfo& w) {
  return {{"name", w.name}, {"last_seen", JsonTime(w.last_seen)}, {"leases", w.leases}, {"items_done", w.items_done}};
}

}  // namespace bistable
