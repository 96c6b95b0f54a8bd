// Identify(options, records): the library entry point (identify/identify.h).
#include "identify/identify.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <tuple>

#include "base/names.h"
#include "dynamics/cancel.h"

namespace bistable::identify {
namespace {

std::string Fmt(double v, int digits = 4) {
  char b[48];
  std::snprintf(b, sizeof b, "%.*g", digits, v);
  return b;
}

// A fit that returns no numbers is a failure, not a result: report which parameters and stop.
Status CheckFitted(const IdentifyResult& r, ObjectiveMode objective) {
  const std::string name = Name(objective);
  for (const auto& [fm, fr, what] :
       {std::tuple{&r.declared, &r.before, "declared model"}, std::tuple{&r.final_model, &r.after, "final model"}}) {
    const auto names = fm->ParamNames();
    std::string bad;
    for (size_t i = 0; i < fr->theta.size(); ++i)
      if (!std::isfinite(fr->theta[i]))
        bad += (bad.empty() ? "" : ", ") + (i < names.size() ? names[i] : std::to_string(i));
    if (!bad.empty() || fr->theta.size() != names.size())
      return Status::FailedPrecondition(std::string("identify: the fit of the ") + what +
                                        " gave non-finite parameters (" + bad +
                                        "); check the data's units and the scales (--input-scale, --output-scale)");
    const double err = objective == ObjectiveMode::kFft        ? fr->errors.fft
                       : objective == ObjectiveMode::kShooting ? fr->errors.shooting
                                                               : fr->errors.nrmse;
    if (!std::isfinite(err))
      return Status::FailedPrecondition(std::string("identify: the ") + what +
                                        " as fitted cannot be simulated on the records (" + name + " error " +
                                        Fmt(err) + "); check the data's units, the scales and --guess");
  }
  return Status::Ok();
}

// Every test range of every record, simulated with the declared and the final model under the fit's final
// output weights (which the loop may have re-estimated).
StatusOr<std::vector<TestSplit>> TestSplits(const IdentifyResult& r, const std::vector<Record>& loaded,
                                            const Options& o, const Setup& setup) {
  double weights[kOutputSlots] = {1, 1, 1};
  for (int k = 1; k < kOutputSlots; ++k)
    for (const OutputErrors& e : r.after.errors.outputs)
      if (e.name == OutputName(setup, static_cast<OutputSlot>(k))) weights[k] = e.weight;
  std::vector<TestSplit> out;
  for (const auto& [tb, te] : o.test_ranges)
    for (const Record& rec : loaded) {
      auto prepared = PrepareRecord(rec, setup, tb, te, o.deriv_cutoff, rec.name);
      if (!prepared.ok()) return Status::InvalidArgument("test-range", prepared.status().message());
      PreparedRecord p = *prepared;
      std::copy(weights, weights + kOutputSlots, p.weight);
      TestSplit t;
      t.record = rec.name;
      t.begin = tb, t.end = std::min(te, rec.t.size());
      t.before = Evaluate(r.declared, r.before.theta, {p}, setup);
      t.after = Evaluate(r.final_model, r.after.theta, {p}, setup);
      out.push_back(std::move(t));
    }
  return out;
}

// Simulations of both fits; checked: a saturated count stays a count.
long long TotalSimulations(const IdentifyResult& r) {
  long long simulations = 0;
  if (__builtin_add_overflow(static_cast<long long>(std::max(r.before.simulations, 0)),
                             static_cast<long long>(std::max(r.after.simulations, 0)), &simulations))
    simulations = std::numeric_limits<long long>::max();
  return simulations;
}

}  // namespace

double OutputError(const OutputErrors& e, const std::string& metric) {
  return metric == "spectral" ? e.fft : metric == "shooting" ? e.shooting : e.nrmse;
}

Record Decimated(const Record& r, int k) {
  Record d = r;
  d.t.clear(), d.input.clear(), d.output.clear(), d.resonator.clear(), d.voltage.clear();
  for (size_t i = 0; i < r.t.size(); i += k) {
    d.t.push_back(r.t[i]), d.input.push_back(r.input[i]), d.output.push_back(r.output[i]);
    if (!r.resonator.empty()) d.resonator.push_back(r.resonator[i]);
    if (!r.voltage.empty()) d.voltage.push_back(r.voltage[i]);
  }
  d.dt = r.dt * k;
  return d;
}

StatusOr<std::vector<Record>> LoadRecords(const Options& options, const std::vector<std::string>& paths) {
  const ColumnMap columns = Columns(options);
  std::vector<Record> loaded;
  for (const std::string& path : paths) {
    auto recs = ::bistable::LoadRecords(path, columns);
    if (!recs.ok()) return recs.status();
    for (Record& r : recs.value()) loaded.push_back(std::move(r));
  }
  return loaded;
}

StatusOr<std::vector<PreparedRecord>> PrepareFitted(const std::vector<Record>& decimated, const Options& o,
                                                    const Setup& setup) {
  std::vector<PreparedRecord> recs;
  for (const Record& r : decimated) {
    const size_t n = r.t.size();
    size_t b = std::min(o.range.first, n), e = std::min(o.range.second, n);
    if (o.max_seconds > 0) e = std::min<double>(e, static_cast<double>(b) + std::floor(o.max_seconds / r.dt));
    if (o.objective == ObjectiveMode::kShooting && o.horizon < 4 * r.dt)
      return Status::InvalidArgument("horizon", "horizon = " + Fmt(o.horizon) + " s violates horizon >= 4 samples of " +
                                                    Printable(r.name, 64) + " (4 x dt = " + Fmt(4 * r.dt) + " s)");
    auto p = PrepareRecord(r, setup, b, e, o.deriv_cutoff, r.name);
    if (!p.ok()) return p.status();
    recs.push_back(std::move(p).value());
  }
  return recs;
}

}  // namespace bistable::identify

namespace bistable {

StatusOr<identify::Summary> Identify(const identify::Options& options, const std::vector<Record>& records,
                                     identify::ProgressSink progress) {
  using namespace identify;
  auto planned = MakePlan(options);
  if (!planned.ok()) return planned.status();
  if (records.empty()) return Status::InvalidArgument("data", "give at least one --data FILE.csv");
  Summary s;
  s.plan = std::move(planned).value();
  Plan& plan = s.plan;
  std::vector<Record> loaded;
  for (const Record& r : records) loaded.push_back(options.decimate > 1 ? Decimated(r, options.decimate) : r);
  FrameDecision& frame = s.frame;
  for (int f = 0; f < (plan.frame_auto ? 2 : 1); ++f) {
    if (plan.frame_auto) plan.setup.frame = f == 0 ? OutputFrame::kAbsolute : OutputFrame::kRelative;
    auto prepared = PrepareFitted(loaded, options, plan.setup);
    if (!prepared.ok()) return prepared.status();
    if (progress) {
      char line[160];
      std::snprintf(line, sizeof line, "identify: %zu record(s), %zu parameters declared%s; fitting...\n",
                    prepared->size(), static_cast<size_t>(plan.model.NumParams()),
                    plan.frame_auto ? (f == 0 ? " (absolute frame)" : " (relative frame)") : "");
      progress(line);
    }
    IdentifyResult rf = Identify(plan.model, *prepared, plan.setup, plan.loop);
    if (CancelRequested()) return CancelledStatus();  // cut short: nothing of it is reported
    BISTABLE_RETURN_IF_ERROR(CheckFitted(rf, options.objective));
    if (plan.frame_auto) {
      // Every output counts the same here (the fit's noise weights would let the cleanest output decide
      // alone): the RMS over outputs of the final NRMSE (spectral error for the fft objective).
      frame.made = true;
      frame.metric = options.objective == ObjectiveMode::kFft        ? "spectral"
                     : options.objective == ObjectiveMode::kShooting ? "shooting"
                                                                     : "nrmse";
      frame.errors[f] = rf.after.errors;
      double ss = 0;
      for (const OutputErrors& o : rf.after.errors.outputs) ss += std::pow(OutputError(o, frame.metric), 2);
      frame.error[f] = std::sqrt(ss / static_cast<double>(std::max<size_t>(1, rf.after.errors.outputs.size())));
      if (f == 1 && !(frame.error[1] < frame.error[0])) continue;  // keep the absolute frame's
    }
    s.result = std::move(rf);
    s.records = std::move(prepared).value();
  }
  if (frame.made) {
    frame.chosen = frame.error[1] < frame.error[0] ? "relative" : "absolute";
    plan.setup.frame = frame.chosen == "relative" ? OutputFrame::kRelative : OutputFrame::kAbsolute;
  }
  auto tests = TestSplits(s.result, loaded, options, plan.setup);
  if (!tests.ok()) return tests.status();
  s.tests = std::move(tests).value();
  s.simulations = TotalSimulations(s.result);
  if (CancelRequested()) return CancelledStatus();  // the test splits may have been cut short
  return s;
}

}  // namespace bistable
