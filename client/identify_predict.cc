#include "client/identify_predict.h"

#include <cmath>
#include <filesystem>
#include <set>
#include <sstream>

#include "base/file.h"
#include "base/json_text.h"
#include "base/limits.h"
#include "base/validate.h"
#include "client/identify_diagnostics.h"
#include "engine/json_shapes.h"

namespace bistable {
namespace {

std::string F(double v, int digits = 4) { return FormatSignificant(v, digits); }

StatusOr<std::string> JsonString(const nlohmann::json& v, const std::string& field, size_t max_bytes = 4096) {
  if (!v.is_string()) return Status::InvalidArgument(field, field + " is not a string");
  const std::string s = v.get<std::string>();
  if (s.size() > max_bytes)
    return Status::InvalidArgument(field, field + " is longer than " + std::to_string(max_bytes) + " bytes");
  return s;
}

StatusOr<double> JsonFinite(const nlohmann::json& v, const std::string& field) {
  if (!v.is_number())
    return Status::InvalidArgument(
        field, field + " is not a number" + (v.is_null() ? " (null: the fit gave no finite value)" : ""));
  const double x = v.get<double>();
  if (!std::isfinite(x) || std::abs(x) > limits::kMaxModelParamMagnitude)
    return Status::InvalidArgument(field, field + " = " + F(x) + " violates |value| <= 1e100 (finite)");
  return x;
}

// The final model's terms: "final_terms", or "declared" and the effects added in order.
StatusOr<std::string> FinalTerms(const nlohmann::json& j, std::string* declared) {
  if (j.contains("declared")) {
    auto d = JsonString(j["declared"], "model.declared");
    if (!d.ok()) return d.status();
    *declared = *d;
  }
  std::string list;
  if (j.contains("final_terms")) {
    const nlohmann::json& ft = j["final_terms"];
    if (!ft.is_array() || ft.empty() || ft.size() > 64)
      return Status::InvalidArgument("model.final_terms", "model.final_terms is not an array of 1 to 64 term ids");
    for (size_t i = 0; i < ft.size(); ++i) {
      auto t = JsonString(ft[i], "model.final_terms[" + std::to_string(i) + "]", 64);
      if (!t.ok()) return t.status();
      if (t->find(',') != std::string::npos)
        return Status::InvalidArgument("model.final_terms",
                                       "model.final_terms[" + std::to_string(i) + "] is not a term id");
      list += (list.empty() ? "" : ",") + *t;
    }
    return list;
  }
  if (declared->empty())
    return Status::InvalidArgument(
        "model",
        "the model file has neither \"final_terms\" nor \"declared\": it is not a `bistable identify --json` output");
  list = *declared;
  if (j.contains("effects_added")) {
    const nlohmann::json& ea = j["effects_added"];
    if (!ea.is_array() || ea.size() > 64)
      return Status::InvalidArgument("model.effects_added",
                                     "model.effects_added is not an array of at most 64 effects");
    for (size_t i = 0; i < ea.size(); ++i) {
      const std::string f = "model.effects_added[" + std::to_string(i) + "].term";
      if (!ea[i].is_object() || !ea[i].contains("term")) return Status::InvalidArgument(f, f + " is missing");
      auto t = JsonString(ea[i]["term"], f, 64);
      if (!t.ok()) return t.status();
      list += "," + *t;
    }
  }
  return list;
}

// settings.<key>: a finite number ≥ 0 (> 0 when `positive`), or `fallback` when absent.
StatusOr<double> Setting(const nlohmann::json& j, const char* key, double fallback, bool positive) {
  if (!j.contains("settings") || !j["settings"].is_object() || !j["settings"].contains(key)) return fallback;
  const std::string field = std::string("model.settings.") + key;
  auto v = JsonFinite(j["settings"][key], field);
  if (!v.ok()) return v.status();
  if (positive ? !(*v > 0) : !(*v >= 0))
    return Status::InvalidArgument(field, field + " = " + F(*v) + (positive ? " violates > 0" : " violates >= 0"));
  return *v;
}

std::string SettingString(const nlohmann::json& j, const char* key) {
  if (!j.contains("settings") || !j["settings"].is_object() || !j["settings"].contains(key) ||
      !j["settings"][key].is_string())
    return "";
  const std::string s = j["settings"][key].get<std::string>();
  return s.size() <= 64 ? s : "";
}

nlohmann::json WellJson(const Well& w) {
  nlohmann::json c = nullptr;
  if (w.with_circuit)
    c = {{"hz", JsonNumber(w.coupled.hz)},
         {"damping_ratio", JsonNumber(w.coupled.damping_ratio)},
         {"added_stiffness", JsonNumber(w.piezo_stiffness)},
         {"added_damping", JsonNumber(w.piezo_damping)}};
  return {{"side", w.side},
          {"y_m", JsonNumber(w.at.y)},
          {"stiffness", JsonNumber(w.at.stiffness)},
          {"damping", JsonNumber(w.at.damping)},
          {"depth", JsonNumber(w.depth)},
          {"small_orbit_hz", JsonNumber(w.small_orbit_hz)},
          {"damping_ratio", JsonNumber(w.damping_ratio)},
          {"with_circuit", c}};
}

nlohmann::json ModelJson(const FittedModel& fm, const ModelStatics& st, const Setup& setup) {
  nlohmann::json m;
  m["file"] = fm.path;
  m["terms"] = nlohmann::json::array();
  for (const TermDef* t : fm.model.terms) m["terms"].push_back(t->id);
  m["params"] = nlohmann::json::object();
  const auto names = fm.model.ParamNames();
  for (size_t i = 0; i < names.size(); ++i) m["params"][names[i]] = JsonNumber(fm.model.theta[i]);
  m["m_main"] = JsonNumber(st.mass);
  m["fitted_frame"] = fm.frame.empty() ? nlohmann::json(nullptr) : nlohmann::json(fm.frame);
  m["frame"] = setup.frame == OutputFrame::kRelative ? "relative" : "absolute";
  m["static_force_coefficients"] = nlohmann::json::array();
  for (double c : st.force_coef) m["static_force_coefficients"].push_back(JsonNumber(c));
  m["equilibria"] = nlohmann::json::array();
  for (const Equilibrium& e : st.equilibria)
    m["equilibria"].push_back({{"y_m", JsonNumber(e.y)},
                               {"stable", e.stable},
                               {"stiffness", JsonNumber(e.stiffness)},
                               {"energy", JsonNumber(e.energy)}});
  m["bistable"] = st.bistable;
  m["barrier"] = st.bistable
                     ? nlohmann::json{{"y_m", JsonNumber(st.barrier.y)}, {"energy", JsonNumber(st.barrier.energy)}}
                     : nlohmann::json(nullptr);
  m["wells"] = nlohmann::json::array();
  m["small_orbit_hz"] = nlohmann::json::array();
  nlohmann::json coupled = nlohmann::json::array();
  for (const Well& w : st.wells) {
    m["wells"].push_back(WellJson(w));
    m["small_orbit_hz"].push_back(JsonNumber(w.small_orbit_hz));
    coupled.push_back(JsonNumber(w.coupled.hz));
  }
  m["small_orbit_hz_with_circuit"] = st.piezo ? coupled : nlohmann::json(nullptr);
  m["piezo"] = st.piezo ? nlohmann::json{{"a", JsonNumber(st.piezo_a)},
                                         {"b", JsonNumber(st.piezo_b)},
                                         {"c", JsonNumber(st.piezo_c)},
                                         {"a_c", JsonNumber(st.piezo_a * st.piezo_c)},
                                         {"damps_the_beam", st.piezo_a * st.piezo_c > 0}}
                        : nlohmann::json(nullptr);
  m["notes"] = fm.notes;
  m["units"] =
      "SI with the fit's m_main: with m_main = 1 (base acceleration input) forces are per kg, stiffness in 1/s^2, "
      "depth and energy in J/kg";
  return m;
}

nlohmann::json RecordJson(const PredictedRecord& pr) {
  const RecordPrediction& p = pr.p;
  nlohmann::json g = nlohmann::json::object();
  for (const auto& [name, v] : pr.group) g[name] = JsonNumber(v);
  nlohmann::json outs = nlohmann::json::object();
  for (const OutputPrediction& o : p.outputs)
    outs[o.name] = {{"nrmse", JsonNumber(o.nrmse)},
                    {"spectral_error", JsonNumber(o.spectral)},
                    {"amplitude_measured", JsonNumber(o.amplitude_measured)},
                    {"amplitude_predicted", JsonNumber(o.amplitude_predicted)},
                    {"amplitude_ratio", JsonNumber(o.amplitude_predicted / o.amplitude_measured)},
                    {"rms_measured", JsonNumber(o.rms_measured)},
                    {"rms_predicted", JsonNumber(o.rms_predicted)}};
  const SwitchCounts& s = p.switches;
  return {{"name", p.name},
          {"group", g},
          {"seconds", p.seconds},
          {"start_well", pr.start_well},
          {"start_y_m", JsonNumber(p.start_y)},
          {"forcing_hz", JsonNumber(p.forcing_hz)},
          {"input_amplitude", JsonNumber(p.input_amplitude)},
          {"diverged", p.diverged},
          {"outputs", outs},
          {"displacement_amplitude_m",
           {{"measured", JsonNumber(p.displacement_amplitude_measured)},
            {"predicted", JsonNumber(p.displacement_amplitude_predicted)}}},
          {"mean_displacement_m",
           {{"measured", JsonNumber(p.mean_displacement_measured)},
            {"predicted", JsonNumber(p.mean_displacement_predicted)}}},
          {"switches_per_s",
           {{"measured", JsonNumber(s.measured)},
            {"predicted", JsonNumber(s.predicted)},
            {"hysteresis_m", JsonNumber(s.hysteresis)},
            {"well_scale",
             {{"measured", JsonNumber(s.well_measured)},
              {"predicted", JsonNumber(s.well_predicted)},
              {"hysteresis_m", JsonNumber(s.well_hysteresis)}}},
            {"model", JsonNumber(s.model)},
            {"model_crosses_wells", std::isfinite(s.model) ? nlohmann::json(s.model > 0) : nlohmann::json(nullptr)},
            {"model_right_fraction", JsonNumber(s.model_right_fraction)}}},
          {"chaotic", p.chaotic},
          {"output_broadband", JsonNumber(p.output_broadband)},
          {"invariants", p.chaotic && !p.diverged ? InvariantsObject(p.invariants) : nlohmann::json(nullptr)}};
}

std::vector<std::string> Observability(const Setup& setup, bool piezo) {
  std::vector<std::string> o;
  if (setup.output == OutputKind::kVelocity)
    o.push_back(
        "well centres: not measured. The sensor gives velocity; its integral is zero-mean, so where the beam sits "
        "(which "
        "well, how far out) is not in the data. The wells are the model's; mean_displacement_m.measured is null.");
  else
    o.push_back(
        "well centres: a displacement output gives each record's mean displacement (mean_displacement_m.measured); it "
        "is "
        "a well centre only for a record that stays in one well.");
  o.push_back(
      "small-orbit frequency: not measured by forced records at one drive frequency (a free decay or a slow sine sweep "
      "through the well's resonance would measure it); the values are the model's, linearised in each well.");
  if (piezo)
    o.push_back(
        "with_circuit: the beam and the piezo circuit linearised together, (m s^2 + C s + K)(s + b) + a c s = 0; "
        "added_stiffness and added_damping are the circuit's a c w^2/(b^2 + w^2) and a c b/(b^2 + w^2) at the "
        "mechanical "
        "small-orbit frequency w.");
  o.push_back(
      "switches_per_s.measured/predicted: changes of well by forcing period on the zero-mean displacement (each "
      "series' "
      "period means split into two wells by its own two-means; hysteresis_m a quarter of the measured wells' "
      "distance): an "
      "orbit inside one well does not count. well_scale: the same displacement with the "
      "hysteresis half the model's barrier-to-well distance (a small orbit in one well does not count; an orbit in one "
      "well "
      "wider than that band still does). model: the model's own displacement (not zero-mean) across its barrier: "
      "whether "
      "the model really changes wells; the measured counterpart is not observable from a velocity.");
  o.push_back(
      "amplitudes: the component at the drive frequency (the input's strongest line), Hann-weighted projection over "
      "the whole record, start transient included.");
  return o;
}

}  // namespace

StatusOr<StartWell> ParseStartWell(const std::string& s) {
  if (s == "none") return StartWell::kNone;
  if (s == "left") return StartWell::kLeft;
  if (s == "right") return StartWell::kRight;
  return Status::InvalidArgument("start-well", "'" + s + "' violates start-well in {none, left, right}");
}

const char* Name(StartWell w) { return w == StartWell::kNone ? "none" : w == StartWell::kLeft ? "left" : "right"; }

Status Validate(const PredictOptions& p) {
  if (p.model.empty())
    return Status::InvalidArgument(
        "model",
        "--predict needs --model FILE: a `bistable identify --json` output or a report directory (its report.json)");
  if (p.data.empty()) return Status::InvalidArgument("data", "give at least one --data FILE.csv to predict");
  const identify::Options& o = p.records;
  if (!o.guesses.empty())
    return Status::InvalidArgument("guess", "--predict fits nothing: the parameter values are the model file's");
  if (o.fit_offsets)
    return Status::InvalidArgument("fit-offsets", "--predict fits nothing; --start-well sets where each record starts");
  if (!o.test_ranges.empty())
    return Status::InvalidArgument(
        "test-range",
        "--predict simulates the --data records themselves (--range and --max-seconds select the samples)");
  identify::Options scratch;
  for (const auto& [k, v] : p.known) {
    BISTABLE_RETURN_IF_ERROR(identify::SetKnown(k, v, &scratch));
    if (!(v > 0)) return Status::InvalidArgument("known." + k, k + " = " + FormatNumber(v) + " violates " + k + " > 0");
  }
  const size_t n = p.start_wells.size();
  if (n > 1 && n != p.data.size())
    return Status::InvalidArgument("start-well", "give one value for all --data files or one per file (" +
                                                     std::to_string(p.data.size()) + "), not " + std::to_string(n));
  return Status::Ok();
}

StatusOr<FittedModel> ReadFittedModel(const std::string& path_in) {
  FittedModel fm;
  std::error_code ec;
  fm.path =
      std::filesystem::is_directory(path_in, ec) ? (std::filesystem::path(path_in) / "report.json").string() : path_in;
  auto text = ReadTextFile(fm.path, "model", limits::kMaxModelJsonBytes);
  if (!text.ok()) return text.status();
  if (JsonNestingDepth(*text) > limits::kMaxModelJsonDepth)
    return Status::InvalidArgument("model", "model file '" + fm.path + "' nests deeper than " +
                                                std::to_string(limits::kMaxModelJsonDepth) + " levels");
  nlohmann::json j;
  try {
    j = nlohmann::json::parse(*text);
  } catch (const nlohmann::json::exception& e) {
    return Status::InvalidArgument("model", "model file '" + fm.path + "' is not JSON: " + e.what());
  }
  if (!j.is_object())
    return Status::InvalidArgument(
        "model", "model file '" + fm.path + "' is not a JSON object (a `bistable identify --json` output)");
  if (j.contains("prediction") && !j.contains("params"))
    return Status::InvalidArgument(
        "model", "model file '" + fm.path + "' is a --predict output; give the fit's `--json` output");
  if (!j.contains("params") || !j["params"].is_object())
    return Status::InvalidArgument(
        "model.params",
        "model file '" + fm.path + "' has no \"params\" object: it is not a `bistable identify --json` output");
  auto list = FinalTerms(j, &fm.declared);
  if (!list.ok()) return list.status();
  auto terms = ParseTerms(*list);
  if (!terms.ok()) return Status::InvalidArgument("model.final_terms", terms.status().message());
  IdentModel& m = fm.model;
  m.terms = *terms;
  auto m_main = Setting(j, "m_main", 0.0, false);
  auto m_res = Setting(j, "m_res", 0.0, false);
  auto v_sp = Setting(j, "v_sp", m.fc.v_sp, true);
  auto v_t = Setting(j, "v_t", m.fc.v_t, true);
  for (const auto* s : {&m_main, &m_res, &v_sp, &v_t})
    if (!s->ok()) return s->status();
  m.m_main = *m_main, m.m_res = *m_res, m.fc.v_sp = *v_sp, m.fc.v_t = *v_t;
  if (m.HasResonator() && !(m.m_res > 0))
    return Status::InvalidArgument("model.settings.m_res", "the model has resonator terms but no m_res > 0");
  fm.frame = SettingString(j, "output_frame");
  if (fm.frame != "absolute" && fm.frame != "relative") fm.frame.clear();
  if (j.contains("errors_by_output") && j["errors_by_output"].is_object() &&
      j["errors_by_output"].size() <= kOutputSlots)
    for (const auto& [name, o] : j["errors_by_output"].items()) {
      if (!o.is_object() || !o.contains("weight") || name.size() > 16) continue;
      const std::string field = "model.errors_by_output." + name + ".weight";
      auto w = JsonFinite(o["weight"], field);
      if (!w.ok()) return w.status();
      if (!(*w >= kMinOutputWeight && *w <= kMaxOutputWeight))
        return Status::InvalidArgument(
            field, field + " = " + F(*w) + " violates " + F(kMinOutputWeight) + " <= weight <= " + F(kMaxOutputWeight));
      fm.output_weights[name] = *w;
    }
  fm.input_kind = SettingString(j, "input_kind");
  fm.output_kind = SettingString(j, "output_kind");
  const nlohmann::json& params = j["params"];
  const auto names = m.ParamNames();
  const auto signs = m.ParamSigns();
  std::set<std::string> known(names.begin(), names.end());
  int offsets = 0;
  for (const auto& [k, v] : params.items()) {
    if (known.count(k)) continue;
    if (k.rfind("offset.", 0) == 0 && k.size() < 16) {
      ++offsets;
      continue;
    }
    std::string list_names;
    for (const std::string& n : names) list_names += (list_names.empty() ? "" : ", ") + n;
    return Status::InvalidArgument("model.params", "model.params has '" +
                                                       (k.size() > 80 ? k.substr(0, 80) + "..." : k) +
                                                       "', not a parameter of the model's terms (" + list_names + ")");
  }
  if (offsets > 0)
    fm.notes.push_back("the fit's " + std::to_string(offsets) +
                       " displacement offset(s) (offset.k, --fit-offsets) are dropped: they "
                       "belong to the fit's records; --start-well sets the start of each predicted record");
  m.theta.clear();
  for (size_t i = 0; i < names.size(); ++i) {
    const std::string field = "model.params." + names[i];
    if (!params.contains(names[i]))
      return Status::InvalidArgument(field, field + " is missing (the model's terms are " + *list + ")");
    auto v = JsonFinite(params[names[i]], field);
    if (!v.ok()) return v.status();
    if (signs[i] == Sign::kNonNegative && *v < 0)
      return Status::InvalidArgument(field, field + " = " + F(*v) + " violates >= 0");
    m.theta.push_back(*v);
  }
  if (m.FitsMass() && !(m.theta.back() > 0))
    return Status::InvalidArgument("model.params.m_main", "model.params.m_main must be > 0");
  return fm;
}

nlohmann::json PredictionJson(const FittedModel& fm, const ModelStatics& st, const std::vector<PredictedRecord>& recs,
                              const Errors& joint, const Setup& setup, const nlohmann::json& settings, double seconds) {
  nlohmann::json p;
  p["model"] = ModelJson(fm, st, setup);
  p["records"] = nlohmann::json::array();
  for (const PredictedRecord& r : recs) p["records"].push_back(RecordJson(r));
  nlohmann::json by = nlohmann::json::object();
  for (const OutputErrors& o : joint.outputs)
    by[o.name] = {
        {"nrmse", JsonNumber(o.nrmse)}, {"spectral_error", JsonNumber(o.fft)}, {"weight", JsonNumber(o.weight)}};
  p["error"] = {{"nrmse", JsonNumber(joint.nrmse)},
                {"spectral_error", JsonNumber(joint.fft)},
                {"by_output", by},
                {"diverged", joint.diverged}};
  p["observability"] = Observability(setup, st.piezo);
  p["settings"] = settings;
  p["seconds"] = seconds;
  return {{"prediction", p}};
}

namespace {

// A number of the JSON as text (null: "-").
std::string N(const nlohmann::json& v, double scale = 1, int digits = 4) {
  return v.is_number() ? F(v.get<double>() * scale, digits) : "-";
}

}  // namespace

std::string PredictionText(const nlohmann::json& root) {
  const nlohmann::json& p = root["prediction"];
  const nlohmann::json& m = p["model"];
  std::ostringstream o;
  o << "prediction with the model of " << m["file"].get<std::string>() << " (nothing refitted; frame "
    << m["frame"].get<std::string>() << ")\n";
  o << "terms:";
  for (const auto& t : m["terms"]) o << " " << t.get<std::string>();
  o << "\nmodel wells (" << (m["bistable"].get<bool>() ? "bistable" : "monostable") << "):";
  if (!m["barrier"].is_null()) o << " barrier at " << N(m["barrier"]["y_m"], 1e3) << " mm";
  o << "\n  well    y [mm]   K [N/m]    depth [J]   small orbit [Hz]   ζ mech";
  if (!m["piezo"].is_null()) o << "   with circuit [Hz]   ζ   (added K, C)";
  o << "\n";
  for (const auto& w : m["wells"]) {
    char line[256];
    std::snprintf(line, sizeof line, "  %-6s %8s %9s %12s %18s %8s", w["side"].get<std::string>().c_str(),
                  N(w["y_m"], 1e3).c_str(), N(w["stiffness"]).c_str(), N(w["depth"]).c_str(),
                  N(w["small_orbit_hz"]).c_str(), N(w["damping_ratio"], 1, 3).c_str());
    o << line;
    if (!w["with_circuit"].is_null()) {
      const auto& c = w["with_circuit"];
      o << "   " << N(c["hz"]) << "   " << N(c["damping_ratio"], 1, 3) << "   (" << N(c["added_stiffness"]) << ", "
        << N(c["added_damping"]) << ")";
    }
    o << "\n";
  }
  o << "units: " << m["units"].get<std::string>() << "\n";
  if (!m["piezo"].is_null())
    o << "piezo a c = " << N(m["piezo"]["a_c"])
      << (m["piezo"]["damps_the_beam"].get<bool>() ? " > 0: damps the beam" : " <= 0: feeds the beam") << "\n";
  for (const auto& n : m["notes"]) o << "note: " << n.get<std::string>() << "\n";
  o << "\nrecord                         f [Hz]  output     amp meas    amp pred   ratio  NRMSE %  spectral %\n";
  for (const auto& r : p["records"]) {
    std::string name = r["name"].get<std::string>();
    for (const auto& [g, v] : r["group"].items()) name += " " + g + "=" + N(v);
    if (name.size() > 30) name = "..." + name.substr(name.size() - 27);
    bool first = true;
    for (const auto& [out, v] : r["outputs"].items()) {
      char line[256];
      std::snprintf(line, sizeof line, "%-30s %7s  %-9s %10s %11s %7s %8s %11s\n", first ? name.c_str() : "",
                    first ? N(r["forcing_hz"]).c_str() : "", out.c_str(), N(v["amplitude_measured"]).c_str(),
                    N(v["amplitude_predicted"]).c_str(), N(v["amplitude_ratio"], 1, 3).c_str(), N(v["nrmse"]).c_str(),
                    N(v["spectral_error"]).c_str());
      o << line;
      first = false;
    }
    const auto& s = r["switches_per_s"];
    o << "    switches/s (well scale) measured " << N(s["well_scale"]["measured"], 1, 3) << ", predicted "
      << N(s["well_scale"]["predicted"], 1, 3) << "; model crosses its barrier " << N(s["model"], 1, 3)
      << "/s (right of it " << N(s["model_right_fraction"], 100, 3) << " % of the time)"
      << "; start " << r["start_well"].get<std::string>() << (r["diverged"].get<bool>() ? "; DIVERGED" : "") << "\n";
    if (!r["invariants"].is_null()) {
      const auto& v = r["invariants"];
      o << "    chaotic: Poincare H " << N(v["poincare_energy"], 1, 3) << " (floor " << N(v["poincare_floor"], 1, 3)
        << "), switches/s " << N(v["switching_rate_hz"], 1, 3) << " (measured "
        << N(v["switching_rate_measured_hz"], 1, 3) << "), right-well share " << N(v["right_well_fraction"], 1, 2)
        << " (measured " << N(v["right_well_fraction_measured"], 1, 2) << "), velocity Hellinger "
        << N(v["velocity_hellinger"], 1, 3) << "\n";
    }
  }
  o << "amplitudes at the drive frequency in SI (velocity m/s, voltage V); all records: NRMSE "
    << N(p["error"]["nrmse"]) << " %, spectral " << N(p["error"]["spectral_error"]) << " %\n";
  for (const auto& n : p["observability"]) o << "- " << n.get<std::string>() << "\n";
  return o.str();
}

}  // namespace bistable
