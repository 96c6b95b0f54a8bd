// identify::Options: names, validation and the plan they give (identify/options.h). The checks and their
// messages are those `bistable identify` printed for its flags before the options had a type of their own.
#include "identify/options.h"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <sstream>
#include <string_view>

#include "base/limits.h"
#include "base/names.h"

namespace bistable::identify {
namespace {

std::string Fmt(double v, int digits = 4) {
  char b[48];
  std::snprintf(b, sizeof b, "%.*g", digits, v);
  return b;
}

// The shortest text that reads back as v (a value a program gave, not a flag's text).
std::string Shortest(double v) {
  char b[64];
  const auto r = std::to_chars(b, b + sizeof b, v);
  return std::string(b, r.ptr);
}

// The declared model: terms, kinds, scales, frame, constants, setup, output terms, guesses.
Status PlanModel(const Options& o, Plan* plan) {
  if (o.terms.empty())
    return Status::InvalidArgument("terms", "declare the model: --terms main.linear,main.viscous,... (--list-terms)");
  auto terms = ParseTerms(JoinTerms(o.terms));
  if (!terms.ok()) return terms.status();
  plan->columns = Columns(o);
  Setup& setup = plan->setup;
  setup.input = o.input_kind;
  setup.output = o.output_kind;
  setup.frame = o.output_frame == FrameMode::kRelative ? OutputFrame::kRelative : OutputFrame::kAbsolute;
  plan->frame_auto = o.output_frame == FrameMode::kAuto;
  setup.drift_cutoff_hz = o.drift_cutoff;
  if (plan->frame_auto && !(setup.output == OutputKind::kVelocity && setup.input == InputKind::kBaseAcceleration))
    return Status::InvalidArgument(
        "output-frame",
        "--output-frame auto decides whether a velocity sensor reads absolute or base-relative "
        "velocity: it needs --output-kind velocity and --input-kind base_acceleration");
  IdentModel& model = plan->model;
  model.terms = *terms;
  // The constants: m_main 0 is "unknown" (fitted with a force input); the others must be positive.
  for (const auto& [name, v] :
       {std::pair<const char*, double>{"m_main", o.m_main}, {"m_res", o.m_res}, {"v_sp", o.v_sp}, {"v_t", o.v_t}}) {
    const bool may_be_zero = std::string_view(name).substr(0, 2) == "m_";
    if (!std::isfinite(v) || v < 0 || (v == 0 && !may_be_zero))
      return Status::InvalidArgument(std::string("known.") + name,
                                     std::string(name) + " = " + Shortest(v) + " violates " + name + " > 0");
  }
  model.m_main = o.m_main;
  model.m_res = o.m_res;
  setup.fc.v_sp = o.v_sp;
  setup.fc.v_t = o.v_t;
  model.fc = setup.fc;
  if (model.m_main <= 0 && setup.input != InputKind::kForce)
    return Status::InvalidArgument("known.m_main",
                                   "the main mass is needed with a base input (--known m_main=0.282; "
                                   "m_main=1 gives parameters per unit mass); only a force input can identify it");
  if (model.HasResonator() && !(model.m_res > 0))
    return Status::InvalidArgument("known.m_res", "resonator terms are declared: give its mass (--known m_res=0.62)");
  BISTABLE_RETURN_IF_ERROR(ValidateSetup(setup));
  BISTABLE_RETURN_IF_ERROR(CheckOutputTerms(model.terms, plan->columns, setup, "terms"));
  if (o.guesses.empty()) return Status::Ok();
  // Start values of the declared model's parameters (the others NaN: from the regression).
  const auto names = model.ParamNames();
  model.theta.assign(names.size(), NAN);
  for (const auto& [k, v] : o.guesses) {
    auto it = std::find(names.begin(), names.end(), k);
    if (it == names.end())
      return Status::InvalidArgument("guess", UnknownNameMessage("parameter of the declared model", k, names));
    if (!std::isfinite(v))
      return Status::InvalidArgument("guess." + k, "guess." + k + " = " + Shortest(v) + " violates a finite number");
    model.theta[it - names.begin()] = v;
  }
  return Status::Ok();
}

Status CheckRange(const SampleRange& r, const std::string& field) {
  const size_t max = static_cast<size_t>(limits::kMaxDataRows);
  if (r.first > max || (r.second > max && r.second != SIZE_MAX))
    return Status::InvalidArgument(
        field, field + " = " + std::to_string(r.first) + ":" + std::to_string(r.second) + " violates " + field +
                   " = A:B (sample indices, 0-based, end exclusive; each <= " + std::to_string(limits::kMaxDataRows) +
                   ")");
  if (r.second <= r.first)
    return Status::InvalidArgument(field, field + " = " + std::to_string(r.first) + ":" + std::to_string(r.second) +
                                              " is empty (the end must exceed the start)");
  return Status::Ok();
}

}  // namespace

std::vector<std::string> SplitTerms(const std::string& list) {
  std::vector<std::string> out;
  if (list.empty()) return out;
  size_t start = 0;
  while (true) {
    const size_t end = list.find(',', start);
    out.push_back(list.substr(start, end == std::string::npos ? std::string::npos : end - start));
    if (end == std::string::npos) return out;
    start = end + 1;
  }
}

std::string JoinTerms(const std::vector<std::string>& terms) {
  std::string s;
  for (size_t i = 0; i < terms.size(); ++i) s += (i ? "," : "") + terms[i];
  return s;
}

ColumnMap Columns(const Options& o) {
  ColumnMap c;
  c.input_kind = o.input_kind;
  c.output_kind = o.output_kind;
  // By kind (ColumnMap's own defaults are x0 and x): base_displacement x0, base_acceleration a0, force u; displacement
  // x, velocity v, analogue y.
  const std::string input = o.input_kind == InputKind::kBaseAcceleration ? "a0"
                            : o.input_kind == InputKind::kForce          ? "u"
                                                                         : "x0";
  const std::string output = o.output_kind == OutputKind::kVelocity   ? "v"
                             : o.output_kind == OutputKind::kAnalogue ? "y"
                                                                      : "x";
  c.input = o.input_column.empty() ? input : o.input_column;
  c.output = o.output_column.empty() ? output : o.output_column;
  c.time = o.time_column;
  c.resonator = o.resonator_column;
  c.voltage = o.output2_column;
  c.group = o.group_columns;
  c.input_scale = o.input_scale;
  c.output_scale = o.output_scale;
  c.voltage_scale = o.output2_scale;
  return c;
}

Status CheckOutputTerms(const std::vector<const TermDef*>& terms, const ColumnMap& columns, const Setup& setup,
                        const std::string& field) {
  std::vector<std::string> outputs = {OutputName(setup, OutputSlot::kMain)};
  if (!columns.resonator.empty()) outputs.push_back("resonator");
  if (!columns.voltage.empty()) outputs.push_back("voltage");
  for (const TermDef* t : terms) {
    if (t->body != Body::kOutput || std::find(outputs.begin(), outputs.end(), t->output) != outputs.end()) continue;
    std::string list;
    for (const std::string& out : outputs) list += (list.empty() ? "" : ", ") + out;
    return Status::InvalidArgument(
        field, "term '" + t->id + "' acts on a " + t->output + " output; this run's outputs are " + list);
  }
  return Status::Ok();
}

StatusOr<IdentifyOptions> LoopOptions(const Options& o, const ColumnMap& columns, const Setup& setup) {
  if (!(o.input_scale != 0) || !std::isfinite(o.input_scale))
    return Status::InvalidArgument("input-scale", "must be a finite non-zero factor");
  if (!(o.output_scale != 0) || !std::isfinite(o.output_scale))
    return Status::InvalidArgument("output-scale", "must be a finite non-zero factor");
  if (!(o.output2_scale != 0) || !std::isfinite(o.output2_scale))
    return Status::InvalidArgument("output2-scale", "must be a finite non-zero factor");
  IdentifyOptions opt;
  opt.fit.objective = o.objective == ObjectiveMode::kFft        ? Objective::kFft
                      : o.objective == ObjectiveMode::kShooting ? Objective::kShooting
                                                                : Objective::kTime;
  opt.choose_objective = o.objective == ObjectiveMode::kAuto;
  if (o.global_evals < 0 || o.global_evals > 100000)
    return Status::InvalidArgument("global-evals", "must be in [0, 100000]");
  if (o.lm_iterations < 1 || o.lm_iterations > 10000)
    return Status::InvalidArgument("lm-iterations", "must be in [1, 10000]");
  if (o.max_added < 0 || o.max_added > 10) return Status::InvalidArgument("max-added", "must be in [0, 10]");
  if (!(o.deriv_cutoff >= 0))
    return Status::InvalidArgument("deriv-cutoff",
                                   "deriv-cutoff = " + Fmt(o.deriv_cutoff) + " violates deriv-cutoff >= 0 Hz");
  if (o.decimate < 1 || o.decimate > 1000) return Status::InvalidArgument("decimate", "must be in [1, 1000]");
  if (!(o.horizon >= 0) || !(o.horizon <= 3600))
    return Status::InvalidArgument("horizon", "horizon = " + Fmt(o.horizon) + " violates 0 <= horizon <= 3600 s");
  if (!(o.max_seconds >= 0) || !(o.max_seconds <= 1e6))
    return Status::InvalidArgument(
        "max-seconds", "max-seconds = " + Fmt(o.max_seconds) + " violates 0 <= max-seconds <= 1e6 s (0: all)");
  if (o.threads < 0 || o.threads > 1024)
    return Status::InvalidArgument(
        "threads", "threads = " + std::to_string(o.threads) + " violates threads in [0, 1024] (0: the usable CPUs)");
  if (o.objective == ObjectiveMode::kShooting && !(o.horizon > 0))
    return Status::InvalidArgument(
        "horizon",
        "horizon = 0 violates horizon > 0 s (--objective shooting cuts the records into segments of --horizon)");
  opt.fit.global_evals = o.global_evals;
  opt.fit.lm_iterations = o.lm_iterations;
  opt.fit.threads = o.threads;
  opt.fit.shooting_horizon_s = o.horizon;
  opt.max_added = o.max_added;
  if (o.bootstrap != 0 && (o.bootstrap < kMinBootstrapTwins || o.bootstrap > kMaxBootstrapTwins))
    return Status::InvalidArgument("bootstrap", "bootstrap = " + std::to_string(o.bootstrap) +
                                                    " violates bootstrap = 0 or " + std::to_string(kMinBootstrapTwins) +
                                                    " <= bootstrap <= " + std::to_string(kMaxBootstrapTwins) +
                                                    " (twin records refitted)");
  opt.bootstrap = o.bootstrap;
  opt.fit_offsets = o.fit_offsets;
  opt.output_weights = o.output_weights;
  if (!o.candidates.empty()) {
    auto c = ParseTerms(JoinTerms(o.candidates));
    if (!c.ok()) return Status::InvalidArgument("candidates", c.status().message());
    BISTABLE_RETURN_IF_ERROR(CheckOutputTerms(*c, columns, setup, "candidates"));
    opt.candidates = *c;
  }
  BISTABLE_RETURN_IF_ERROR(CheckRange(o.range, "range"));
  for (const SampleRange& r : o.test_ranges) BISTABLE_RETURN_IF_ERROR(CheckRange(r, "test-range"));
  return opt;
}

StatusOr<Plan> MakePlan(const Options& o) {
  Plan plan;
  BISTABLE_RETURN_IF_ERROR(PlanModel(o, &plan));
  auto loop = LoopOptions(o, plan.columns, plan.setup);
  if (!loop.ok()) return loop.status();
  plan.loop = std::move(loop).value();
  return plan;
}

Status Validate(const Options& options) { return MakePlan(options).status(); }

// --- Names ---

StatusOr<InputKind> ParseInputKind(const std::string& s) {
  if (s == "base_displacement") return InputKind::kBaseDisplacement;
  if (s == "base_acceleration") return InputKind::kBaseAcceleration;
  if (s == "force") return InputKind::kForce;
  return Status::InvalidArgument("input-kind",
                                 "'" + s + "' violates input-kind in {base_displacement, base_acceleration, force}");
}

StatusOr<OutputKind> ParseOutputKind(const std::string& s) {
  if (s == "displacement") return OutputKind::kDisplacement;
  if (s == "velocity") return OutputKind::kVelocity;
  if (s == "analogue") return OutputKind::kAnalogue;
  return Status::InvalidArgument("output-kind",
                                 "'" + s + "' violates output-kind in {displacement, velocity, analogue}");
}

StatusOr<FrameMode> ParseFrameMode(const std::string& s) {
  if (s == "absolute") return FrameMode::kAbsolute;
  if (s == "relative") return FrameMode::kRelative;
  if (s == "auto") return FrameMode::kAuto;
  return Status::InvalidArgument("output-frame", "'" + s + "' violates output-frame in {absolute, relative, auto}");
}

StatusOr<ObjectiveMode> ParseObjectiveMode(const std::string& s) {
  if (s == "auto") return ObjectiveMode::kAuto;
  if (s == "time") return ObjectiveMode::kTime;
  if (s == "fft") return ObjectiveMode::kFft;
  if (s == "shooting") return ObjectiveMode::kShooting;
  return Status::InvalidArgument("objective", "'" + s + "' violates objective in {auto, time, fft, shooting}");
}

StatusOr<OutputWeights> ParseOutputWeights(const std::string& s) {
  if (s == "residual") return OutputWeights::kResidual;
  if (s == "noise") return OutputWeights::kNoise;
  return Status::InvalidArgument("output-weights", "'" + s + "' violates output-weights in {residual, noise}");
}

Status CheckOutput2Kind(const std::string& s) {
  if (s == "voltage") return Status::Ok();
  return Status::InvalidArgument(
      "output2-kind", "'" + s +
                          "' violates output2-kind in {voltage} (a second output is the "
                          "piezo voltage, compared with main.piezo's state; a resonator is --columns resonator=...)");
}

const char* Name(InputKind k) {
  return k == InputKind::kBaseDisplacement   ? "base_displacement"
         : k == InputKind::kBaseAcceleration ? "base_acceleration"
                                             : "force";
}
const char* Name(OutputKind k) {
  return k == OutputKind::kDisplacement ? "displacement" : k == OutputKind::kVelocity ? "velocity" : "analogue";
}
const char* Name(FrameMode f) {
  return f == FrameMode::kAbsolute ? "absolute" : f == FrameMode::kRelative ? "relative" : "auto";
}
const char* Name(ObjectiveMode o) {
  return o == ObjectiveMode::kAuto   ? "auto"
         : o == ObjectiveMode::kTime ? "time"
         : o == ObjectiveMode::kFft  ? "fft"
                                     : "shooting";
}
const char* Name(OutputWeights w) { return w == OutputWeights::kResidual ? "residual" : "noise"; }

StatusOr<SampleRange> ParseRange(const std::string& s, const std::string& field) {
  const std::string bad = field + " = '" + Printable(s, 64) + "' violates " + field +
                          " = A:B (sample indices, 0-based, end exclusive; decimal digits, each <= " +
                          std::to_string(limits::kMaxDataRows) + ")";
  const size_t c = s.find(':');
  if (c == std::string::npos || s.size() > 32) return Status::InvalidArgument(field, bad);
  auto side = [&](std::string_view t, size_t none, size_t* v) {
    if (t.empty()) return *v = none, true;
    if (t.find_first_not_of("0123456789") != std::string_view::npos) return false;
    unsigned long long x = 0;
    const auto [end, ec] = std::from_chars(t.data(), t.data() + t.size(), x);
    if (ec != std::errc() || end != t.data() + t.size() || x > static_cast<unsigned long long>(limits::kMaxDataRows))
      return false;
    return *v = static_cast<size_t>(x), true;
  };
  size_t a = 0, b = SIZE_MAX;
  const std::string_view sv(s);
  if (!side(sv.substr(0, c), 0, &a) || !side(sv.substr(c + 1), SIZE_MAX, &b))
    return Status::InvalidArgument(field, bad);
  if (b <= a)
    return Status::InvalidArgument(field,
                                   field + " = '" + Printable(s, 64) + "' is empty (the end must exceed the start)");
  return SampleRange{a, b};
}

Status SetColumn(const std::string& role, const std::string& name, Options* o) {
  if (role == "t")
    o->time_column = name;
  else if (role == "input")
    o->input_column = name;
  else if (role == "output")
    o->output_column = name;
  else if (role == "resonator")
    o->resonator_column = name;
  else if (role == "output2")
    o->output2_column = name;
  else if (role == "group") {
    std::stringstream ss(name);
    std::string g;
    while (std::getline(ss, g, ';')) o->group_columns.push_back(g);
  } else {
    return Status::InvalidArgument(
        "columns", UnknownNameMessage("role", role, {"t", "input", "output", "output2", "resonator", "group"}));
  }
  return Status::Ok();
}

Status SetKnown(const std::string& name, double value, Options* o) {
  if (name == "m_main")
    o->m_main = value;
  else if (name == "m_res")
    o->m_res = value;
  else if (name == "v_sp")
    o->v_sp = value;
  else if (name == "v_t")
    o->v_t = value;
  else {
    return Status::InvalidArgument("known", UnknownNameMessage("constant", name, {"m_main", "m_res", "v_sp", "v_t"}) +
                                                "; units: m_main, m_res [kg], v_sp, v_t [m/s]");
  }
  return Status::Ok();
}

}  // namespace bistable::identify
