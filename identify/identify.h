// The library entry point of identification (issue 40), after Ceres's `Solve(options, &problem, &summary)`:
//
//   identify::Options o;
//   o.terms = {"main.linear", "main.viscous", "main.friction"};
//   o.m_main = 0.282;
//   auto records = identify::LoadRecords(o, {"chirp_6mm.csv", "chirp_10mm.csv"});
//   auto summary = Identify(o, *records);   // StatusOr<identify::Summary>
//   summary->result.after.theta ...
//
// `bistable identify` (client/identify_command.cc) and the Python module's `bistable.identify` both call it;
// the JSON both print is rendered from the Summary in client/ (IdentifyResultJson), the text from the Summary
// itself (Summary::FullReport).
#ifndef BISTABLE_IDENTIFY_IDENTIFY_H_
#define BISTABLE_IDENTIFY_IDENTIFY_H_

#include <string>
#include <vector>

#include "base/status.h"
#include "identify/loop.h"
#include "identify/options.h"
#include "identify/record.h"

namespace bistable::identify {

// A --test-range split of one record, simulated with the declared and the final model (under the fit's
// final output weights).
struct TestSplit {
  std::string record;
  size_t begin = 0, end = 0;  // samples of the decimated record, end clipped to its length
  Errors before, after;
};

// FrameMode::kAuto: the loop run in both frames; the one with the lower final error over all outputs
// (each output's error counting the same) kept.
struct FrameDecision {
  bool made = false;
  std::string chosen;            // "absolute" | "relative"
  std::string metric = "nrmse";  // errors compared: nrmse, spectral (fft objective) or shooting
  double error[2] = {NAN, NAN};  // absolute, relative: the final error of each frame's loop
  Errors errors[2];
};

struct Summary {
  Plan plan;                            // what the options gave; setup.frame: the frame fitted (chosen, with kAuto)
  IdentifyResult result;                // the loop's result (loop.h): models, fits, steps, diagnostics
  std::vector<PreparedRecord> records;  // the fitted part of every record, as fitted
  std::vector<TestSplit> tests;         // every test range × every record
  FrameDecision frame;
  long long simulations = 0;  // of both fits (saturates)

  // The fit as text, after Ceres's Summary::FullReport: the records and the objective that ran, the errors
  // before and after, every step's verdict, the declared model as fitted and the final model (each parameter
  // with its σ and unit), the test ranges, the diagnostics, wall time and simulations. What `bistable identify`
  // prints without --json and what the Python module's result returns as full_report() (full_report.cc).
  std::string FullReport() const;
};

// An output's error by a metric: "nrmse", "spectral" or "shooting".
double OutputError(const OutputErrors& e, const std::string& metric);

// Every k-th sample of a record (Options::decimate).
Record Decimated(const Record& r, int k);
// The records of every file, read with Columns(options) (each file may hold several: record.h).
StatusOr<std::vector<Record>> LoadRecords(const Options& options, const std::vector<std::string>& paths);
// The fitted part (options.range, options.max_seconds) of each record (decimated already), prepared for `setup`.
StatusOr<std::vector<PreparedRecord>> PrepareFitted(const std::vector<Record>& decimated, const Options& options,
                                                    const Setup& setup);

// Progress lines ("identify: 2 record(s), 5 parameters declared; fitting..."): the CLI prints them without --json.
using ProgressSink = void (*)(const std::string& line);

}  // namespace bistable::identify

namespace bistable {

// Validates the options, decimates and cuts the records (as measured, read by identify::LoadRecords or made
// by a program), runs the loop (twice with FrameMode::kAuto) and simulates the test ranges. Errors: invalid
// options (Validate), records that cannot be prepared, a fit that gives non-finite numbers
// (FailedPrecondition), CancelledStatus() when cancellation was requested (dynamics/cancel.h).
StatusOr<identify::Summary> Identify(const identify::Options& options, const std::vector<Record>& records,
                                     identify::ProgressSink progress = nullptr);

}  // namespace bistable

#endif  // BISTABLE_IDENTIFY_IDENTIFY_H_
