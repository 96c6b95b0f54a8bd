// `bistable identify`: its flags mapped onto the library's options (identify/options.h) and the fit run by the
// library's entry point, Identify(options, records) (identify/identify.h), which the Python module calls too;
// here the flags, the JSON of a fit, --predict, --make-synthetic and --list-terms (report.md and the figures:
// identify_report.cc).
#include "client/identify_command.h"

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
#include "base/validate.h"
#include "client/cli_common.h"
#include "client/identify_diagnostics.h"
#include "client/identify_json.h"
#include "client/identify_predict.h"
#include "client/identify_report.h"
#include "client/json_out.h"
#include "dynamics/cancel.h"
#include "engine/json_shapes.h"
#include "engine/sweep_spec.h"
#include "identify/identify.h"
#include "identify/synthetic.h"

namespace bistable {
namespace {

struct IdentifyArgs {
  std::vector<std::string> data;
  std::string terms, known, columns, candidates, guesses;
  std::string input_kind = "base_displacement", output_kind = "displacement", frame = "absolute";
  double input_scale = 1, output_scale = 1, output2_scale = 1;
  std::string output2_kind = "voltage";
  std::string range, objective = "auto", report, synth, synth_kind = "linear";
  std::vector<std::string> test_ranges;
  double max_seconds = 0;
  int decimate = 1, global_evals = 150, lm_iterations = 60, max_added = 3, threads = 0, bootstrap = 0;
  double horizon = 0.5, deriv_cutoff = 0, drift_cutoff = 0;
  bool json = false, list_terms = false, fit_offsets = false;
  std::string output_weights = "residual";
  // --predict: simulate the --data records with the fitted model of --model (nothing fitted).
  bool predict = false;
  std::string model_file, start_well;
  bool frame_given = false;  // --output-frame given (else --predict takes the fit's frame)
  // --synthetic bistable | bistable-coupled: the snap-through family's knobs.
  std::vector<double> synth_amplitudes_mm;
  double synth_f_start = 1, synth_f_end = 8, synth_duration = 30, synth_noise_mm = 0.05;
  unsigned synth_seed = 1;
  std::vector<std::string> synth_extra;
  std::string synth_start = "right";
};

std::string Fmt(double v, int digits = 4) {
  char b[48];
  std::snprintf(b, sizeof b, "%.*g", digits, v);
  return b;
}

// --list-terms: the effect library, as a table or (--json) an array.
nlohmann::json TermsJson() {
  nlohmann::json lib = nlohmann::json::array();
  for (const TermDef& t : EffectLibrary()) {
    nlohmann::json ps = nlohmann::json::array();
    for (const TermParam& p : t.params)
      ps.push_back({{"name", p.name}, {"unit", p.unit}, {"sign", p.sign == Sign::kNonNegative ? ">= 0" : "either"}});
    lib.push_back({{"term", t.id}, {"formula", t.formula}, {"meaning", t.meaning}, {"params", ps}});
  }
  return lib;
}

int ListTerms(bool json) {
  if (json) {
    std::cout << DumpJson(TermsJson(), 2) << "\n";
    return 0;
  }
  for (const TermDef& t : EffectLibrary()) {
    std::string pn;
    for (const TermParam& p : t.params)
      pn += (pn.empty() ? "" : ", ") + p.name + " [" + p.unit + "]" + (p.sign == Sign::kNonNegative ? " >= 0" : "");
    std::printf("%-20s %-44s %s\n", t.id.c_str(),
                t.formula.size() > 44 ? (t.formula.substr(0, 41) + "...").c_str() : t.formula.c_str(), pn.c_str());
  }
  return 0;
}

// truth.json of a synthetic family: the truth `p` (with the `extra` force terms) as a `--predict --model` file
// (final_terms, params, settings) and how its `records` were made.
nlohmann::json TruthJson(const DimensionalParams& p, const identify::MakeSyntheticOptions& a,
                         const nlohmann::json& records) {
  const std::vector<TermValues>& extra = a.extra;
  nlohmann::json params = nlohmann::json::object(), final_terms = nlohmann::json::array(),
                 extras = nlohmann::json::array();
  for (const TermValues& t : TruthTerms(p, extra)) {
    final_terms.push_back(t.term->id);
    for (size_t k = 0; k < t.values.size(); ++k) params[t.term->id + "." + t.term->params[k].name] = t.values[k];
  }
  for (const TermValues& e : extra) {
    nlohmann::json v = nlohmann::json::object();
    for (size_t k = 0; k < e.values.size(); ++k) v[e.term->params[k].name] = e.values[k];
    extras.push_back({{"term", e.term->id}, {"values", v}});
  }
  nlohmann::json settings = {{"m_main", p.m_m},
                             {"v_sp", p.fric_m.v_sp},
                             {"v_t", p.fric_m.v_t},
                             {"input_kind", "base_displacement"},
                             {"output_kind", "displacement"},
                             {"output_frame", "absolute"}};
  if (p.has_resonator) settings["m_res"] = p.m_r;
  return {{"final_terms", final_terms},
          {"params", params},
          {"settings", settings},
          {"synthetic",
           {{"kind", identify::Name(a.kind)},
            {"f_start_hz", a.f_start_hz},
            {"f_end_hz", a.f_end_hz},
            {"duration_s", a.duration_s},
            {"fs_hz", 120},
            {"noise_mm", a.noise_mm},
            {"noise_on", p.has_resonator ? nlohmann::json{"x0", "x", "xr"} : nlohmann::json{"x0", "x"}},
            {"start_well", identify::Name(a.start)},
            {"extra", extras},
            {"records", records}}}};
}

}  // namespace

// --make-synthetic DIR: synthetic records for trying the loop (noise 0.05 mm on every measured
// position, sampled at 120 Hz like the paper's camera):
//   linear   the paper's Table 2 linear rig (no resonator) under 1 → 8 Hz chirps of 6, 10, 14 mm, 20 s each;
//   coupled  the Table 2 bistable beam with its resonator (friction on both bodies), one 1 → 6 Hz chirp of
//            4 mm over 70 s, started in the right well: columns t, x0, x, xr;
//   bistable / bistable-coupled  the snap-through family (issue 37): the Table 2 bistable beam alone or with
//            its resonator, friction and c0 + c2 y² damping on each body, base chirps that cross the hump
//            (--synthetic-amplitude, -f-start, -f-end, -duration), noise on every column, the input too
//            (--synthetic-noise), one record per amplitude (seeds --synthetic-seed, +1, ...), optional extra
//            force terms in the truth (--synthetic-extra main.drag=5), a start well; and truth.json, the true
//            model as a `--predict --model` file (final_terms, params, settings).
StatusOr<nlohmann::json> SyntheticJson(const identify::MakeSyntheticOptions& a) {
  BISTABLE_RETURN_IF_ERROR(identify::Validate(a));  // every option before anything is written
  const std::string& dir = a.dir;
  const bool family = identify::IsFamily(a.kind);
  std::error_code ec;
  std::filesystem::create_directories(dir, ec);
  if (ec) return Status::IoError("make-synthetic", "cannot create '" + dir + "': " + ec.message());
  nlohmann::json files = nlohmann::json::array();
  auto write = [&](const DimensionalParams& p, const SyntheticOptions& o, const std::string& file) -> Status {
    auto r = MakeSyntheticRecord(p, o, file);
    if (!r.ok()) return r.status();
    const std::string path = (std::filesystem::path(dir) / file).string();
    BISTABLE_RETURN_IF_ERROR(WriteRecordCsv(*r, path));
    files.push_back(path);
    return Status::Ok();
  };
  if (family) {
    DimensionalParams p = DimensionalParams::BistableTable2();
    p.has_resonator = a.kind == identify::SyntheticKind::kBistableCoupled;
    std::vector<double> amps = a.amplitudes_mm.empty() ? std::vector<double>{10.0} : a.amplitudes_mm;
    const double well = std::sqrt(-p.k_lin / p.k3);
    unsigned seed = a.seed;
    nlohmann::json records = nlohmann::json::array();
    for (double mm : amps) {
      SyntheticOptions o;
      o.a0_m = mm * 1e-3, o.f_start_hz = a.f_start_hz, o.f_end_hz = a.f_end_hz, o.duration_s = a.duration_s;
      o.noise_m = o.input_noise_m = a.noise_mm * 1e-3;
      o.seed = seed;
      o.y0_m = SyntheticWell(p, a.extra, a.start == identify::WellSide::kLeft ? -well : well);  // the truth's well
      o.extra = a.extra;
      const std::string file = std::string(p.has_resonator ? "coupled" : "standalone") + "_" + Fmt(mm, 4) + "mm_s" +
                               std::to_string(seed) + ".csv";
      BISTABLE_RETURN_IF_ERROR(write(p, o, file));
      records.push_back({{"file", file}, {"amplitude_mm", mm}, {"seed", seed}});
      ++seed;
    }
    // The truth as a model file for `identify --predict --model` (and the tests' reference values).
    const nlohmann::json truth = TruthJson(p, a, records);
    const std::string path = (std::filesystem::path(dir) / "truth.json").string();
    auto f = AtomicFile::Create(path, "json");
    if (!f.ok()) return f.status();
    BISTABLE_RETURN_IF_ERROR((*f)->Write(DumpJson(truth, 2) + "\n"));
    BISTABLE_RETURN_IF_ERROR((*f)->Commit());
    return nlohmann::json{{"files", files}, {"truth", path}};
  }
  if (a.kind == identify::SyntheticKind::kCoupled) {
    const DimensionalParams p = DimensionalParams::BistableTable2();
    SyntheticOptions o;
    o.a0_m = 4e-3, o.f_start_hz = 1, o.f_end_hz = 6, o.duration_s = 70;
    o.y0_m = std::sqrt(-p.k_lin / p.k3);
    BISTABLE_RETURN_IF_ERROR(write(p, o, "coupled_70s.csv"));
    return nlohmann::json{{"files", files}};
  }
  DimensionalParams p = DimensionalParams::LinearTable2();
  p.has_resonator = false;
  unsigned seed = 1;
  for (double mm : {6.0, 10.0, 14.0}) {
    SyntheticOptions o;
    o.a0_m = mm * 1e-3;
    o.seed = seed++;
    BISTABLE_RETURN_IF_ERROR(write(p, o, "chirp_" + Fmt(mm, 3) + "mm.csv"));
  }
  return nlohmann::json{{"files", files}};
}

namespace {

// --make-synthetic's flags onto identify::MakeSyntheticOptions; what only text can get wrong (the kind's and the
// well's names, --synthetic-extra's TERM=VALUE) is checked here, the bounds by identify::Validate.
StatusOr<identify::MakeSyntheticOptions> SyntheticFromFlags(const IdentifyArgs& a) {
  identify::MakeSyntheticOptions o;
  o.dir = a.synth;
  auto kind = identify::ParseSyntheticKind(a.synth_kind);
  if (!kind.ok()) return kind.status();
  o.kind = *kind;
  for (const std::string& e : a.synth_extra) {
    auto x = ParseSyntheticExtra(e);
    if (!x.ok()) return x.status();
    o.extra.push_back(*x);
  }
  auto start = identify::ParseWellSide(a.synth_start);
  if (!start.ok()) return start.status();
  o.start = *start;
  o.amplitudes_mm = a.synth_amplitudes_mm;
  o.f_start_hz = a.synth_f_start, o.f_end_hz = a.synth_f_end, o.duration_s = a.synth_duration;
  o.noise_mm = a.synth_noise_mm, o.seed = a.synth_seed;
  return o;
}

int MakeSynthetic(const IdentifyArgs& a) {
  auto o = SyntheticFromFlags(a);
  if (!o.ok()) return Fail(o.status());
  auto j = SyntheticJson(*o);
  if (!j.ok()) return Fail(j.status());
  if (a.json)
    std::cout << DumpJson(*j, 2) << "\n";
  else {
    for (const auto& f : (*j)["files"]) std::printf("wrote %s\n", f.get<std::string>().c_str());
    if (j->contains("truth"))
      std::printf("wrote %s (the true model: identify --predict --model it)\n",
                  (*j)["truth"].get<std::string>().c_str());
  }
  return 0;
}

// --known: the masses and friction constants, each > 0 (checked on the text given, which the message quotes).
Status ApplyKnown(const std::string& known, identify::Options* o) {
  auto kv = ParseNameValues(known, "known");
  if (!kv.ok()) return kv.status();
  for (const auto& [k, v] : *kv) {
    auto x = ParseFiniteNumber(v, "known." + k);
    if (!x.ok()) return x.status();
    BISTABLE_RETURN_IF_ERROR(identify::SetKnown(k, *x, o));
    if (!(*x > 0)) return Status::InvalidArgument("known." + k, k + " = " + v + " violates " + k + " > 0");
  }
  return Status::Ok();
}

// The flags onto the library's options (identify/options.h). What only text can get wrong is checked here,
// named by its flag: the names of kinds, frames, objectives and weights, --columns, --known, --guess and the
// ranges; every bound is identify::Validate's (MakePlan), checked next.
StatusOr<identify::Options> OptionsFromFlags(const IdentifyArgs& a) {
  identify::Options o;
  o.terms = identify::SplitTerms(a.terms);
  auto in = identify::ParseInputKind(a.input_kind);
  if (!in.ok()) return in.status();
  auto out = identify::ParseOutputKind(a.output_kind);
  if (!out.ok()) return out.status();
  o.input_kind = *in, o.output_kind = *out;
  o.input_scale = a.input_scale, o.output_scale = a.output_scale, o.output2_scale = a.output2_scale;
  BISTABLE_RETURN_IF_ERROR(identify::CheckOutput2Kind(a.output2_kind));
  auto pairs = ParseNameValues(a.columns, "columns");
  if (!pairs.ok()) return pairs.status();
  for (const auto& [k, v] : *pairs) BISTABLE_RETURN_IF_ERROR(identify::SetColumn(k, v, &o));
  auto frame = identify::ParseFrameMode(a.frame);
  if (!frame.ok()) return frame.status();
  o.output_frame = *frame;
  o.drift_cutoff = a.drift_cutoff;
  BISTABLE_RETURN_IF_ERROR(ApplyKnown(a.known, &o));
  auto guesses = ParseNameValues(a.guesses, "guess");
  if (!guesses.ok()) return guesses.status();
  for (const auto& [k, v] : *guesses) {
    auto x = ParseFiniteNumber(v, "guess." + k);
    if (!x.ok()) return x.status();
    o.guesses[k] = *x;
  }
  auto objective = identify::ParseObjectiveMode(a.objective);
  if (!objective.ok()) return objective.status();
  o.objective = *objective;
  o.global_evals = a.global_evals, o.lm_iterations = a.lm_iterations, o.max_added = a.max_added, o.threads = a.threads;
  o.bootstrap = a.bootstrap;
  o.deriv_cutoff = a.deriv_cutoff, o.decimate = a.decimate, o.horizon = a.horizon, o.max_seconds = a.max_seconds;
  o.fit_offsets = a.fit_offsets;
  auto weights = identify::ParseOutputWeights(a.output_weights);
  if (!weights.ok()) return weights.status();
  o.output_weights = *weights;
  o.candidates = identify::SplitTerms(a.candidates);
  if (!a.range.empty()) {
    auto r = identify::ParseRange(a.range, "range");
    if (!r.ok()) return r.status();
    o.range = *r;
  }
  for (const std::string& t : a.test_ranges) {
    auto r = identify::ParseRange(t, "test-range");
    if (!r.ok()) return r.status();
    o.test_ranges.push_back(*r);
  }
  return o;
}

// --predict: terms and known constants are not needed (the model file has them); given, they must agree.
Status CheckPredictAgrees(const PredictOptions& p, const FittedModel& fm) {
  const std::string terms = identify::JoinTerms(p.records.terms);
  if (!p.records.terms.empty()) {
    auto given = ParseTerms(terms);
    if (!given.ok()) return given.status();
    std::set<std::string> g, d;
    for (const TermDef* t : *given) g.insert(t->id);
    if (!fm.declared.empty()) {
      auto declared = ParseTerms(fm.declared);
      if (!declared.ok()) return Status::InvalidArgument("model.declared", declared.status().message());
      for (const TermDef* t : *declared) d.insert(t->id);
    }
    std::set<std::string> final_terms;
    std::string final_list;
    for (const TermDef* t : fm.model.terms)
      final_terms.insert(t->id), final_list += (final_list.empty() ? "" : ",") + t->id;
    if (g != d && g != final_terms)
      return Status::InvalidArgument("terms", "--terms " + terms + " is neither the model's declared terms (" +
                                                  (fm.declared.empty() ? std::string("not recorded") : fm.declared) +
                                                  ") nor its final terms (" + final_list + ") in " + fm.path +
                                                  "; --predict takes the terms from the model file");
  }
  for (const auto& [k, given] : p.known) {
    const double model = k == "m_main"  ? fm.model.m_main
                         : k == "m_res" ? fm.model.m_res
                         : k == "v_sp"  ? fm.model.fc.v_sp
                                        : fm.model.fc.v_t;
    if (given != model)
      return Status::InvalidArgument(
          "known." + k, "--known " + k + "=" + FormatNumber(given) + " differs from the model's " + k + " = " +
                            Fmt(model, 17) + " (" + fm.path +
                            (k == "m_main" && model == 0 ? ": the mass was fitted" : "") + ")");
  }
  return Status::Ok();
}

// Per record: the errors over one and four drive periods and at --horizon from the measured state, and the
// twin experiment of --objective auto under this model (is the record's long simulation meaningful?).
void AddRecordPredictability(const IdentModel& m, const std::vector<double>& th,
                             const std::vector<PreparedRecord>& recs, const Setup& setup, double horizon,
                             nlohmann::json* pj) {
  for (size_t i = 0; i < recs.size(); ++i) {
    const double f = DriveFrequency(recs[i]);
    nlohmann::json h = DrivePeriodErrors(recs[i], setup, {{"nrmse", &m, &th}});
    h.push_back({{"horizon_s", horizon},
                 {"nrmse", JsonNumber(horizon > 0 ? HorizonError(m, th, recs[i], setup, horizon) : NAN)}});
    const Predictability pr = TestPredictability(m, th, recs[i], setup, horizon > 0 ? horizon : 0.5);
    nlohmann::json& rj = (*pj)["prediction"]["records"][i];
    rj["drive_hz"] = JsonNumber(f);
    rj["drive_band_hz"] = recs[i].f_drive;  // the simulation's drive: the input low-passed there (0: as measured)
    rj["horizon_errors"] = h;
    rj["long_simulation_nrmse"] = JsonNumber(HorizonError(m, th, recs[i], setup, 0));
    // Multiple shooting at --horizon (segments from re-estimated states): the shooting objective's error.
    // Its segment states start from the band-limited ones, as a fit of a chaotic record's do (BandLimitedRestarts).
    PreparedRecord banded = recs[i];
    BandLimitedRestarts(&banded);
    rj["shooting_nrmse"] = JsonNumber(horizon > 0 ? Evaluate(m, th, {banded}, setup, horizon).shooting : NAN);
    rj["predictability"] = {{"chaos_floor_percent", JsonNumber(pr.chaos_floor)},
                            {"prediction_horizon_s", JsonNumber(pr.horizon_s)},
                            {"well_changes", pr.well_changes},
                            {"long_meaningful", pr.long_meaningful},
                            {"fit_horizon_s", pr.fit_horizon_s},
                            {"reason", pr.reason}};
  }
}

// --predict's range as the settings show it: "" for the whole record, else "A:B" (B empty: to the end).
std::string RangeText(const identify::SampleRange& r) {
  if (r == identify::kWholeRecord) return "";
  return std::to_string(r.first) + ":" + (r.second == SIZE_MAX ? std::string() : std::to_string(r.second));
}

// The model's start per record: the record's integrated (zero-mean) displacement as in a fit, plus the chosen
// well's centre — the model's offset parameters, one per record. `wells`: one per file; `file_of`: each record's.
Status ApplyStartWells(const std::vector<StartWell>& wells, const std::vector<size_t>& file_of, const Setup& setup,
                       const ModelStatics& statics, IdentModel* m, std::vector<double>* th) {
  if (std::all_of(wells.begin(), wells.end(), [](StartWell w) { return w == StartWell::kNone; })) return Status::Ok();
  if (setup.output != OutputKind::kVelocity)
    return Status::InvalidArgument(
        "start-well", "--start-well is for velocity outputs (a displacement output gives the start itself)");
  if (!statics.bistable)
    return Status::InvalidArgument("start-well",
                                   "the model has one well (no barrier): start left or right has no meaning");
  m->offsets = static_cast<int>(file_of.size());
  for (size_t f : file_of)
    th->push_back(wells[f] == StartWell::kLeft    ? statics.wells[0].at.y
                  : wells[f] == StartWell::kRight ? statics.wells[1].at.y
                                                  : 0.0);
  return Status::Ok();
}

}  // namespace

// --predict: the fitted model of `p.model` simulated on every record of `p.data` (its columns, input, output and
// frame as in a fit, range/max_seconds/decimate selecting the samples); nothing is fitted.
StatusOr<nlohmann::json> PredictJson(const PredictOptions& p) {
  const auto t0 = std::chrono::steady_clock::now();
  BISTABLE_RETURN_IF_ERROR(Validate(p));
  auto read = ReadFittedModel(p.model);
  if (!read.ok()) return read.status();
  FittedModel fitted = std::move(read).value();
  FittedModel* fm = &fitted;
  BISTABLE_RETURN_IF_ERROR(CheckPredictAgrees(p, *fm));
  const identify::Options& o = p.records;
  const ColumnMap columns = identify::Columns(o);
  Setup setup;
  setup.input = o.input_kind;
  setup.output = o.output_kind;
  const std::string input_kind = identify::Name(o.input_kind);
  if (!fm->input_kind.empty() && fm->input_kind != input_kind)
    return Status::InvalidArgument("input-kind", "the model was fitted with --input-kind " + fm->input_kind + " (" +
                                                     fm->path + "); its parameters do not describe a " + input_kind +
                                                     " input");
  const bool frame_auto = o.output_frame == identify::FrameMode::kAuto;
  const std::string frame = frame_auto ? (fm->frame.empty() ? "absolute" : fm->frame) : identify::Name(o.output_frame);
  if (frame == "absolute")
    setup.frame = OutputFrame::kAbsolute;
  else if (frame == "relative")
    setup.frame = OutputFrame::kRelative;
  else
    return Status::InvalidArgument("output-frame",
                                   "'" + frame + "' violates output-frame in {absolute, relative, auto}");
  if (!frame_auto && !fm->frame.empty() && frame != fm->frame)
    fm->notes.push_back("the fit read the velocity as " + fm->frame + "; predicted as " + frame + " (--output-frame)");
  const IdentModel& model = fm->model;
  setup.fc = model.fc;
  setup.drift_cutoff_hz = o.drift_cutoff;
  BISTABLE_RETURN_IF_ERROR(ValidateSetup(setup));
  BISTABLE_RETURN_IF_ERROR(identify::CheckOutputTerms(model.terms, columns, setup, "model.final_terms"));
  const auto loop = identify::LoopOptions(o, columns, setup);
  if (!loop.ok()) return loop.status();
  auto statics = AnalyseStatics(model, model.theta);
  if (!statics.ok()) return statics.status();
  std::vector<StartWell> wells = p.start_wells.empty() ? std::vector<StartWell>{StartWell::kNone} : p.start_wells;
  if (wells.size() == 1) wells.assign(p.data.size(), wells[0]);
  // Every record, with the file it came from.
  std::vector<Record> loaded;
  std::vector<size_t> file_of;
  for (size_t f = 0; f < p.data.size(); ++f) {
    auto recs = LoadRecords(p.data[f], columns);
    if (!recs.ok()) return recs.status();
    for (Record& r : recs.value())
      loaded.push_back(o.decimate > 1 ? identify::Decimated(r, o.decimate) : std::move(r)), file_of.push_back(f);
  }
  auto prepared = identify::PrepareFitted(loaded, o, setup);
  if (!prepared.ok()) return prepared.status();
  std::vector<PreparedRecord> recs = std::move(prepared).value();
  IdentModel m = model;
  std::vector<double> th = m.theta;
  BISTABLE_RETURN_IF_ERROR(ApplyStartWells(wells, file_of, setup, *statics, &m, &th));
  for (size_t i = 0; i < recs.size(); ++i) recs[i].index = static_cast<int>(i);
  SetOutputWeights(&recs);  // the fit's weights where the model file has them
  for (PreparedRecord& r : recs)
    for (int k = 1; k < kOutputSlots; ++k) {
      const auto it = fm->output_weights.find(OutputName(setup, static_cast<OutputSlot>(k)));
      if (it != fm->output_weights.end()) r.weight[k] = it->second;
    }
  std::vector<PredictedRecord> out;
  for (size_t i = 0; i < recs.size(); ++i) {
    PredictedRecord pr;
    pr.p = PredictRecord(m, th, recs[i], setup, *statics, loop->fit.objective);
    for (size_t g = 0; g < columns.group.size() && g < loaded[i].group_values.size(); ++g)
      pr.group.emplace_back(columns.group[g], loaded[i].group_values[g]);
    pr.start_well = Name(wells[file_of[i]]);
    out.push_back(std::move(pr));
  }
  const Errors joint = Evaluate(m, th, recs, setup);
  std::vector<std::string> well_names;
  for (StartWell w : wells) well_names.push_back(Name(w));
  nlohmann::json settings = {{"data", p.data},
                             {"decimate", o.decimate},
                             {"max_seconds", o.max_seconds},
                             {"range", RangeText(o.range)},
                             {"deriv_cutoff_hz", o.deriv_cutoff},
                             {"objective", identify::Name(o.objective)},
                             {"input_kind", input_kind},
                             {"output_kind", identify::Name(o.output_kind)},
                             {"output_frame", frame},
                             {"drift_cutoff_hz", o.drift_cutoff},
                             {"start_well", well_names}};
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  nlohmann::json pj = PredictionJson(*fm, *statics, out, joint, setup, settings, seconds);
  AddRecordPredictability(m, th, recs, setup, o.horizon, &pj);
  return pj;
}

namespace {

// --predict's flags onto PredictOptions (client/identify_predict.h): the records' flags as a fit's
// (OptionsFromFlags), --known kept as given (each compared with the model's), --output-frame not given: the fit's.
StatusOr<PredictOptions> PredictFromFlags(const IdentifyArgs& a) {
  if (!a.report.empty()) return Status::InvalidArgument("report", "--predict writes no report directory (use --json)");
  PredictOptions p;
  p.model = a.model_file;
  p.data = a.data;
  auto o = OptionsFromFlags(a);
  if (!o.ok()) return o.status();
  p.records = std::move(o).value();
  if (!a.frame_given) p.records.output_frame = identify::FrameMode::kAuto;
  auto kv = ParseNameValues(a.known, "known");
  if (!kv.ok()) return kv.status();
  for (const auto& [k, v] : *kv) {
    auto x = ParseFiniteNumber(v, "known." + k);
    if (!x.ok()) return x.status();
    p.known[k] = *x;
  }
  std::stringstream ss(a.start_well);
  std::string item;
  while (!a.start_well.empty() && std::getline(ss, item, ',')) {
    auto w = ParseStartWell(item);
    if (!w.ok()) return w.status();
    p.start_wells.push_back(*w);
  }
  return p;
}

// The fit of the records of `data` (identify/identify.h) as --json prints it; the report directory is
// written when asked, the text summary printed when `text`; `full_report` (optional) receives the text
// (Summary::FullReport).
StatusOr<nlohmann::json> FitJson(const identify::Options& o, const std::vector<std::string>& data,
                                 const std::string& report, bool text, std::string* full_report = nullptr) {
  auto plan = identify::MakePlan(o);  // the options' errors before any file is read
  if (!plan.ok()) return plan.status();
  // Resonator terms without a resonator column: the resonator is then a hidden state, started where the main body
  // is, and its parameters rest on the main body's motion alone (on the coupled snap-through records they
  // collapsed to 0). Said, not refused: a hidden resonator is a model a user may mean.
  if (plan->model.HasResonator() && plan->columns.resonator.empty())
    std::fprintf(
        stderr,
        "identify: warning: the model has res.* terms but no resonator column; the resonator is fitted as a hidden "
        "state (add --columns resonator=NAME for its absolute displacement, e.g. resonator=xr for --make-synthetic "
        "records)\n");
  const auto loaded = identify::LoadRecords(o, data);
  if (!loaded.ok()) return loaded.status();
  const auto s =
      Identify(o, *loaded, text ? +[](const std::string& line) { std::fputs(line.c_str(), stderr); } : nullptr);
  if (!s.ok()) return s.status();
  const nlohmann::json j = ResultJson(o, *s);
  if (!report.empty()) BISTABLE_RETURN_IF_ERROR(WriteReport(report, identify::JoinTerms(o.terms), *s, j));
  if (text) PrintSummary(report, *s);
  if (full_report) *full_report = s->FullReport();
  return j;
}

// What the command prints: the library (--list-terms), synthetic records (--make-synthetic), a prediction
// (--predict) or the fit.
StatusOr<nlohmann::json> IdentifyJson(const IdentifyArgs& a) {
  if (a.list_terms) return TermsJson();
  if (a.predict) {
    const auto p = PredictFromFlags(a);
    if (!p.ok()) return p.status();
    return PredictJson(*p);
  }
  if (!a.model_file.empty())
    return Status::InvalidArgument("model", "--model is read by --predict (add --predict, or drop --model to fit)");
  if (!a.start_well.empty()) return Status::InvalidArgument("start-well", "--start-well is a --predict option");
  if (a.data.empty()) return Status::InvalidArgument("data", "give at least one --data FILE.csv");
  const auto o = OptionsFromFlags(a);
  if (!o.ok()) return o.status();
  return FitJson(*o, a.data, a.report, !a.json);
}

int RunIdentify(const IdentifyArgs& a) {
  if (a.list_terms) return ListTerms(a.json);
  if (!a.synth.empty()) return MakeSynthetic(a);
  // Ctrl-C / SIGTERM: every simulation stops at its next sample, the loop ends, nothing is printed or written.
  InstallCancelSignalHandlers();
  auto j = IdentifyJson(a);
  RestoreDefaultSignalHandlers();
  if (CancelRequested()) {
    std::cerr << "interrupted: the identification was stopped; nothing was printed or written\n";
    return CancelExitStatus();
  }
  if (!j.ok()) return Fail(j.status());
  if (a.json)
    std::cout << DumpJson(*j, 2) << "\n";
  else if (a.predict)
    std::cout << PredictionText(*j);
  return 0;
}

// --make-synthetic and the --synthetic-* options (the records identify can make for itself).
void AddSyntheticOptions(CLI::App* c, IdentifyArgs* a) {
  c->add_option("--make-synthetic", a->synth, "write synthetic chirp records into DIR and exit (see --synthetic)");
  c->add_option("--synthetic", a->synth_kind,
                "linear: Table 2 linear rig, 1-8 Hz chirps of 6/10/14 mm, 20 s each | coupled: Table 2 bistable beam + "
                "resonator, friction on both, 1-6 Hz chirp of 4 mm, 70 s (120 Hz, 0.05 mm noise) | "
                "bistable, bistable-coupled: the snap-through family (beam alone or with the resonator; the "
                "--synthetic-* options; noise on every "
                "column; truth.json)")
      ->capture_default_str();
  c->add_option("--synthetic-amplitude", a->synth_amplitudes_mm,
                "bistable family: base chirp amplitude [mm], repeatable (one record each; default 10)");
  c->add_option("--synthetic-f-start", a->synth_f_start, "bistable family: chirp start frequency [Hz]")
      ->capture_default_str();
  c->add_option("--synthetic-f-end", a->synth_f_end, "bistable family: chirp end frequency [Hz]")
      ->capture_default_str();
  c->add_option("--synthetic-duration", a->synth_duration, "bistable family: record length [s]")->capture_default_str();
  c->add_option("--synthetic-noise", a->synth_noise_mm,
                "bistable family: noise standard deviation on every column, the input too [mm]")
      ->capture_default_str();
  c->add_option("--synthetic-seed", a->synth_seed,
                "bistable family: noise seed of the first record (the next records +1, +2, ...)")
      ->capture_default_str();
  c->add_option("--synthetic-extra", a->synth_extra,
                "bistable family: a force term added to the truth, TERM=VALUE[:VALUE] in the library's units "
                "(e.g. main.drag=5, main.stiffness_y5=2e9, res.stiffness_z3=1e6); repeatable");
  c->add_option("--synthetic-start", a->synth_start, "bistable family: the well the beam starts in, left | right")
      ->capture_default_str();
}

void AddIdentifyOptions(CLI::App* c, IdentifyArgs* a) {
  c->add_option("--data", a->data,
                "CSV record(s) with a header: , tab or ; separated, # comments, units in names "
                "(docs/identification.md); repeat for several, fitted jointly");
  c->add_option("--terms", a->terms,
                "declared terms, comma-separated (see --list-terms), e.g. main.linear,main.stiffness_y3,main.viscous");
  c->add_option("--known", a->known,
                "known constants: m_main, m_res [kg], v_sp, v_t [m/s] (defaults 0.002, 0.001), e.g. m_main=0.282");
  c->add_option("--columns", a->columns,
                "column roles: t=..,input=..,output=..,output2=..,resonator=..,group=a;b (defaults t, x0|a0|u, x|v|y; "
                "output2: a second output, the piezo voltage, fitted jointly with the first)");
  c->add_option("--input-kind", a->input_kind, "base_displacement [m] | base_acceleration [m/s^2] | force [N]")
      ->capture_default_str();
  c->add_option("--input-scale", a->input_scale, "factor to SI for the input column (9.81 for g)")
      ->capture_default_str();
  c->add_option("--output-kind", a->output_kind,
                "displacement [m] | velocity [m/s] | analogue (a displacement-like signal)")
      ->capture_default_str();
  c->add_option("--output-scale", a->output_scale, "factor to SI for the output column")->capture_default_str();
  c->add_option("--output2-kind", a->output2_kind,
                "kind of the output2 column: voltage [V] (compared with main.piezo's voltage state)")
      ->capture_default_str();
  c->add_option("--output2-scale", a->output2_scale, "factor to SI (volts) for the output2 column")
      ->capture_default_str();
  c->add_option("--output-frame", a->frame,
                "absolute | relative (to the base) | auto (velocity output, base acceleration input: run the loop "
                "in both frames, keep the lower final error, report both; with --predict: the fit's frame, "
                "also the default there)")
      ->capture_default_str()
      ->each([a](const std::string&) { a->frame_given = true; });
  c->add_option("--range", a->range,
                "sample range A:B used for fitting (0-based, end exclusive; samples after --decimate)");
  c->add_option("--test-range", a->test_ranges,
                "sample range A:B simulated for a test error (repeatable; samples after --decimate)");
  c->add_option("--max-seconds", a->max_seconds, "use at most this many seconds of each record (0: all)");
  c->add_option("--decimate", a->decimate, "keep every k-th sample")->capture_default_str();
  c->add_option("--deriv-cutoff", a->deriv_cutoff,
                "low-pass cutoff of measured derivatives [Hz] (0: four times the 99.9 % power bandwidth)")
      ->capture_default_str();
  c->add_option(
       "--drift-cutoff", a->drift_cutoff,
       "velocity outputs: high-pass [Hz] of the displacement integrated from the velocity (0: mean removed only); "
       "for records in one well, below the drive (e.g. 0.5 Hz at 6.5 Hz), where the integral's slow part is sensor "
       "drift; "
       "keep 0 on records that change well")
      ->capture_default_str();
  c->add_option("--objective", a->objective,
                "auto (per record: the whole simulation where twins started at the noise level stay within 5 %, "
                "else short horizons from the measured state; the JSON's objective_choice says why) | time (every "
                "record's whole simulation, NRMSE) | fft (the paper's Eq. 20) | shooting (chaotic records: segments of "
                "--horizon from re-estimated states, scored on invariants)")
      ->capture_default_str();
  c->add_option("--global-evals", a->global_evals, "evaluations of the global stage (NLopt CRS2; 0: none)")
      ->capture_default_str();
  c->add_option(
       "--lm-iterations", a->lm_iterations,
       "iterations of each Levenberg-Marquardt stage, in [1, 10000] (a stage that reaches them stops unconverged)")
      ->capture_default_str();
  c->add_option("--horizon", a->horizon,
                "time objective: short-horizon first stage [s] (0: none); shooting objective: the segment "
                "length [s] (a few forcing periods)")
      ->capture_default_str();
  c->add_option("--max-added", a->max_added, "at most this many effects added")->capture_default_str();
  c->add_option("--bootstrap", a->bootstrap,
                "sigma and covariance from N refits of the final model's twin records (simulated with the record's "
                "input and noise levels; 8-256, e.g. 32; 0: Gauss-Newton). Friction's static peak and other "
                "parameters acting through events get an honest sigma (docs/identification.md)")
      ->capture_default_str();
  c->add_option("--candidates", a->candidates,
                "terms the trace may add (default: the force terms of the bodies measured; with an output2 "
                "voltage also main.piezo and out.<output>.offset/.scale of every output)");
  c->add_option("--guess", a->guesses, "initial values, e.g. main.linear.k_lin=480 (others from the regression)");
  c->add_option("--threads", a->threads,
                "records simulated in parallel (0: the CPUs this process may use: affinity and cgroup quota)")
      ->capture_default_str();
  c->add_option("--report", a->report, "directory for report.md, report.json and PNG figures");
  AddSyntheticOptions(c, a);
  c->add_flag("--fit-offsets", a->fit_offsets, "velocity outputs: fit each record's displacement offset (which well)");
  c->add_option(
       "--output-weights", a->output_weights,
       "several outputs: weight of each output's error in the joint fit — residual: from each output's error in the "
       "declared fit and after every added effect, floored at its noise (maximum likelihood with per-output error "
       "levels) | noise: from the noise levels alone")
      ->capture_default_str();
  c->add_flag("--list-terms", a->list_terms, "list the effect library (ids, formulas, units) and exit");
  c->add_flag("--json", a->json, "print the result as JSON");
  c->add_flag("--predict", a->predict,
              "fit nothing: simulate every --data record with the fitted model of --model and report errors, the "
              "amplitudes at the drive frequency (measured, predicted), well switching, invariants of chaotic "
              "records, and the model's wells and small-orbit frequencies");
  c->add_option(
      "--model", a->model_file,
      "with --predict: a previous `bistable identify --json` output, or a --report directory (its report.json)");
  c->add_option("--start-well", a->start_well,
                "with --predict, velocity outputs: where the model starts, none | left | right, one for all "
                "--data files or one per file, comma-separated (none: the integrated velocity, zero-mean, as "
                "in a fit; left/right: plus that well's centre)");
}

}  // namespace

void AddIdentifyCommand(CLI::App& app, int* exit_code) {
  auto a = std::make_shared<IdentifyArgs>();
  CLI::App* c = app.add_subcommand(
      "identify",
      "Fit the model to measured records, trace the residual to missing effects, add them, report before/after");
  AddIdentifyOptions(c, a.get());
  c->callback([a, exit_code] { *exit_code = RunIdentify(*a); });
}

StatusOr<nlohmann::json> IdentifyFitJson(const identify::Options& options, const std::vector<std::string>& data,
                                         const std::string& report, std::string* full_report) {
  if (data.empty()) return Status::InvalidArgument("data", "give at least one data file (CSV)");
  return FitJson(options, data, report, false, full_report);
}

nlohmann::json IdentifyTermsJson() { return TermsJson(); }

}  // namespace bistable
