// What an identification is asked to do, as a program gives it (issue 40): the options of
// `bistable identify` as typed fields in SI units with documented defaults, and their validation —
// after Ceres's `Solver::Options` and `Solver::Options::IsValid`. The CLI maps its flags onto
// `identify::Options` (client/identify_command.cc), the Python module its keyword arguments
// (python/bistable_module.cc); both then call `Identify(options, records)` (identify/identify.h).
//
// Validation errors are Status::InvalidArgument whose field() is the option's name as a flag
// (`lm-iterations` for `Options::lm_iterations`, `known.m_main` for `Options::m_main`, `columns` for
// the column names) and whose message states the bound violated — the messages the CLI has always
// printed for its flags.
#ifndef BISTABLE_IDENTIFY_OPTIONS_H_
#define BISTABLE_IDENTIFY_OPTIONS_H_

#include <cstddef>
#include <cstdint>
#include <map>
#include <string>
#include <utility>
#include <vector>

#include "base/status.h"
#include "identify/loop.h"
#include "identify/model.h"
#include "identify/record.h"

namespace bistable::identify {

// The objective (--objective): kAuto chooses per record between the whole simulation and short horizons from
// the measured state (IdentifyOptions::choose_objective); the others are fit.h's.
enum class ObjectiveMode { kAuto, kTime, kFft, kShooting };
// How a velocity sensor reads (--output-frame): kAuto runs the loop in both frames and keeps the lower final
// error (velocity output with a base-acceleration input only).
enum class FrameMode { kAbsolute, kRelative, kAuto };
using OutputWeights = IdentifyOptions::OutputWeights;

// A sample range [begin, end) of a record after decimation; end SIZE_MAX: to the record's end.
using SampleRange = std::pair<size_t, size_t>;
inline constexpr SampleRange kWholeRecord{0, SIZE_MAX};

struct Options {
  // --- The declared model ---
  std::vector<std::string> terms;  // declared term ids, in order (`identify --list-terms`); required
  double m_main = 0;               // kg; 0: unknown, fitted (force input only); m_main=1 gives parameters per unit mass
  double m_res = 0;                // kg; required (> 0) when a res.* term is declared
  double v_sp = 0.002;             // m/s, the friction law's Stribeck velocity (> 0)
  double v_t = 0.001;              // m/s, its tanh transition velocity (> 0)
  std::map<std::string, double>
      guesses;  // start values, "term.param" → value in the parameter's unit; others from the regression

  // --- The records: what the columns hold (record.h) ---
  InputKind input_kind = InputKind::kBaseDisplacement;  // x0 [m] | a0 [m/s²] | u [N]
  OutputKind output_kind = OutputKind::kDisplacement;   // x [m] | x' [m/s] | an analogue of displacement
  FrameMode output_frame = FrameMode::kAbsolute;
  double input_scale = 1, output_scale = 1, output2_scale = 1;  // factors to SI (finite, ≠ 0); 1 with a header unit
  std::string time_column = "t";
  std::string input_column, output_column;  // "": by kind (x0, a0, u; x, v, y)
  std::string resonator_column;             // the resonator's absolute displacement [m]; "": none
  std::string output2_column;               // a second output, the piezo voltage [V]; "": none
  std::vector<std::string> group_columns;   // a change of their values starts a new record
  int decimate = 1;                         // keep every k-th sample, in [1, 1000]
  SampleRange range = kWholeRecord;         // the fitted samples of each record (after decimation)
  std::vector<SampleRange> test_ranges;     // samples simulated for a test error (declared and final model)
  double max_seconds = 0;                   // s, at most this much of each record from range.first; 0: all; ≤ 1e6
  double deriv_cutoff = 0;                  // Hz, low-pass of measured derivatives; 0: four times the 99.9 % power band
  double drift_cutoff = 0;  // Hz, high-pass of the displacement integrated from a velocity output; 0: off

  // --- The loop ---
  ObjectiveMode objective = ObjectiveMode::kAuto;
  int global_evals = 150;               // NLopt CRS2 evaluations, [0, 100000]; 0: none
  int lm_iterations = 60;               // iterations of each Levenberg–Marquardt stage, [1, 10000]
  double horizon = 0.5;                 // s, [0, 3600]: the time objective's short-horizon stage (0: none);
                                        // the shooting objective's segment length (> 0, ≥ 4 samples)
  int max_added = 3;                    // at most this many effects added, [0, 10]
  std::vector<std::string> candidates;  // terms the trace may add; empty: the default set (loop.h)
  bool fit_offsets = false;             // velocity outputs: fit each record's displacement offset
  OutputWeights output_weights = OutputWeights::kResidual;
  int threads = 0;    // records simulated in parallel, [0, 1024]; 0: the usable CPUs
  int bootstrap = 0;  // σ from this many refits of twin records (identify/bootstrap.h), 0 or [8, 256]; 0: Gauss–Newton
};

// OK, or the first option out of its bounds (field: the option's flag name; message: the bound).
Status Validate(const Options& options);

// What valid options give the loop: the loader's columns, the setup, the declared model (constants and
// guesses applied) and the loop's own options.
struct Plan {
  ColumnMap columns;
  Setup setup;  // its frame absolute when options.output_frame is kAuto (each run sets it)
  IdentModel model;
  IdentifyOptions loop;
  bool frame_auto = false;
};
StatusOr<Plan> MakePlan(const Options& options);

// The columns a record file is read with (LoadRecords) under these options.
ColumnMap Columns(const Options& options);
// The records' scales and the loop's options (objective, budgets, candidates checked against the run's
// outputs, ranges): what `identify --predict` needs of the options, its model coming from a file.
StatusOr<IdentifyOptions> LoopOptions(const Options& options, const ColumnMap& columns, const Setup& setup);
// Output terms (out.<output>.offset / .scale) must name an output of this run; `field`: where they were given.
Status CheckOutputTerms(const std::vector<const TermDef*>& terms, const ColumnMap& columns, const Setup& setup,
                        const std::string& field);

// --- Names: the options' values as the CLI and the Python module spell them (errors as the CLI prints them) ---
StatusOr<InputKind> ParseInputKind(const std::string& s);          // base_displacement | base_acceleration | force
StatusOr<OutputKind> ParseOutputKind(const std::string& s);        // displacement | velocity | analogue
StatusOr<FrameMode> ParseFrameMode(const std::string& s);          // absolute | relative | auto
StatusOr<ObjectiveMode> ParseObjectiveMode(const std::string& s);  // auto | time | fft | shooting
StatusOr<OutputWeights> ParseOutputWeights(const std::string& s);  // residual | noise
Status CheckOutput2Kind(const std::string& s);                     // voltage (the only kind of a second output)
const char* Name(InputKind k);
const char* Name(OutputKind k);
const char* Name(FrameMode f);
const char* Name(ObjectiveMode o);
const char* Name(OutputWeights w);
// "A:B" (0-based, end exclusive, either side may be empty; decimal digits, each ≤ limits::kMaxDataRows);
// `field`: the flag named in errors (range, test-range).
StatusOr<SampleRange> ParseRange(const std::string& s, const std::string& field);
// A column role (t, input, output, output2, resonator, group: names separated by ';') set to `name`.
Status SetColumn(const std::string& role, const std::string& name, Options* options);
// A known constant (m_main, m_res [kg], v_sp, v_t [m/s]) set to `value` (its bound is Validate's).
Status SetKnown(const std::string& name, double value, Options* options);
// Comma-separated term ids as Options::terms holds them: split at every comma, nothing trimmed, so that
// JoinTerms gives the text back ("" gives no terms).
std::vector<std::string> SplitTerms(const std::string& list);
std::string JoinTerms(const std::vector<std::string>& terms);

}  // namespace bistable::identify

#endif  // BISTABLE_IDENTIFY_OPTIONS_H_
