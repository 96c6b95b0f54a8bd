// `bistable identify --predict --model FILE`: a fitted model read back from a previous `identify --json`
// output (or a report directory's report.json) and simulated on other records without refitting;
// its JSON and text output. The computations are identify/predict.h's.
#ifndef BISTABLE_CLIENT_IDENTIFY_PREDICT_H_
#define BISTABLE_CLIENT_IDENTIFY_PREDICT_H_

#include <map>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "identify/options.h"
#include "identify/predict.h"

namespace bistable {

// What a fit's JSON says about its final model. The file is untrusted: bounded in size and nesting,
// every value checked, errors name the field ("model.params.main.linear.k_lin", "model.final_terms[2]").
struct FittedModel {
  std::string path;                     // the JSON file read
  IdentModel model;                     // terms, m_main, m_res, fc; theta the fit's final values
  std::string declared;                 // the fit's --terms ("" when the file lacks it)
  std::string frame;                    // the fit's velocity frame: "absolute", "relative" or "" (not recorded)
  std::string input_kind, output_kind;  // the fit's, "" when not recorded
  std::vector<std::string> notes;       // what was read with a caveat (dropped offsets)
  // The fit's final output weights by output name (errors_by_output.<name>.weight), empty in older files
  // (then the noise weights): a joint error is comparable with the fit's only under its weights.
  std::map<std::string, double> output_weights;
};

// FILE or DIR (then DIR/report.json). The final terms come from "final_terms" or, in older files, from
// "declared" followed by every "effects_added[].term"; their values from "params" (every parameter of
// those terms, finite, signs as the library's; "offset.k", a fit's per-record displacement offsets,
// are dropped: they belong to the fit's records); m_main, m_res, v_sp, v_t from "settings".
StatusOr<FittedModel> ReadFittedModel(const std::string& path);

// Where a predicted record's model starts (--start-well): none (the integrated velocity, zero-mean, as in a
// fit), or that well's centre added.
enum class StartWell { kNone, kLeft, kRight };
// none | left | right (field start-well).
StatusOr<StartWell> ParseStartWell(const std::string& s);
const char* Name(StartWell w);

// What `identify --predict` is asked to do (issue 40: typed, as the CLI's flags and the Python module's keywords
// give it): the fitted model of `model` simulated on every record of `data`, nothing fitted.
struct PredictOptions {
  std::string model;              // --model: a `bistable identify --json` output or a report directory; required
  std::vector<std::string> data;  // the record files (CSV); at least one
  // How the records are read and prepared, as in a fit (identify/options.h: columns, input and output kinds and
  // scales, decimate, range, max_seconds, deriv_cutoff, drift_cutoff, objective, horizon). output_frame kAuto
  // (the default here) is the fit's frame. `terms`, when given, must be the model's declared or final terms; the
  // fit's own (guesses, fit_offsets, test_ranges) must be left empty; its constants are not read: see `known`.
  identify::Options records;
  // --known given: each (m_main, m_res, v_sp, v_t) > 0 and equal to the model's.
  std::map<std::string, double> known;
  // One for all files or one per file; empty: none.
  std::vector<StartWell> start_wells;

  PredictOptions() { records.output_frame = identify::FrameMode::kAuto; }
};

// OK, or the first option out of its bounds or given where --predict takes none (field: its flag name).
Status Validate(const PredictOptions& options);

// One predicted record with what the CLI knows about it: its group values (--columns group=...) and
// the well its simulation started in.
struct PredictedRecord {
  RecordPrediction p;
  std::vector<std::pair<std::string, double>> group;  // column name, value
  std::string start_well;                             // "none", "left", "right"
};

// {"prediction": {model, records, error, observability, settings, seconds}}.
nlohmann::json PredictionJson(const FittedModel& fm, const ModelStatics& st, const std::vector<PredictedRecord>& recs,
                              const Errors& joint, const Setup& setup, const nlohmann::json& settings, double seconds);

// The same as a readable text: the model's wells and small-orbit frequencies, then a table per record.
std::string PredictionText(const nlohmann::json& j);

}  // namespace bistable

#endif  // BISTABLE_CLIENT_IDENTIFY_PREDICT_H_
