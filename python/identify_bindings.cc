// The identify bindings of the Python module (issue 40): keywords onto the library's typed options —
// identify::Options for a fit, PredictOptions for predict=True, identify::MakeSyntheticOptions for
// make_synthetic=DIR — and the same functions the CLI calls (IdentifyFitJson, PredictJson, SyntheticJson).
// No command-line text: a bad keyword raises ValueError naming it and its bound.
#include <pybind11/stl.h>

#include <map>
#include <optional>
#include <string>
#include <vector>

#include "base/limits.h"
#include "client/identify_command.h"
#include "client/identify_predict.h"
#include "identify/options.h"
#include "identify/synthetic.h"
#include "python/module_common.h"

namespace bistable::py_module {
namespace {

// Term ids: "a,b" as --terms takes them, or a list of ids.
std::vector<std::string> TermList(const py::handle& v, const std::string& name) {
  if (py::isinstance<py::str>(v)) return identify::SplitTerms(v.cast<std::string>());
  if (!py::isinstance<py::list>(v) && !py::isinstance<py::tuple>(v))
    throw py::value_error(name + " = " + Shown(v) + " violates " + name +
                          " a string of comma-separated term ids or a list of them");
  std::vector<std::string> out;
  for (const py::handle& t : py::reinterpret_borrow<py::sequence>(v)) out.push_back(Text(t, name + "[]"));
  return out;
}

py::dict Dict(const py::handle& v, const std::string& name) {
  if (!py::isinstance<py::dict>(v)) throw py::value_error(name + " = " + Shown(v) + " violates " + name + " a dict");
  return py::reinterpret_borrow<py::dict>(v);
}

// A sample range: "A:B" as --range takes it, or (A, B) (B None: to the record's end).
identify::SampleRange Range(const py::handle& v, const std::string& name) {
  if (py::isinstance<py::str>(v)) return Unwrap(identify::ParseRange(v.cast<std::string>(), name));
  if (!py::isinstance<py::tuple>(v) && !py::isinstance<py::list>(v))
    throw py::value_error(name + " = " + Shown(v) + " violates " + name + " \"A:B\" or (A, B)");
  const auto seq = py::reinterpret_borrow<py::sequence>(v);
  if (seq.size() != 2) throw py::value_error(name + " = " + Shown(v) + " violates " + name + " \"A:B\" or (A, B)");
  auto side = [&](const py::handle& x, size_t none) -> size_t {
    if (x.is_none()) return none;
    const std::optional<long long> i = IndexValue(x, name);
    if (!i || *i < 0 || *i > limits::kMaxDataRows)
      throw py::value_error(name + " = " + Shown(v) + " violates 0 <= " + name +
                            " <= " + std::to_string(limits::kMaxDataRows));
    return static_cast<size_t>(*i);
  };
  return {side(seq[0], 0), side(seq[1], SIZE_MAX)};
}

// The options of a fit by keyword (identify/options.h), the flags of `bistable identify` with '_' for '-':
// typed values, no command-line text, onto *options (not validated). *report gets `report` (a directory, "" none).
void IdentifyOptionsFromKeywords(const py::dict& kw, identify::Options* options, std::string* report) {
  identify::Options& o = *options;
  std::map<std::string, double*> numbers = {
      {"input_scale", &o.input_scale}, {"output_scale", &o.output_scale}, {"output2_scale", &o.output2_scale},
      {"max_seconds", &o.max_seconds}, {"deriv_cutoff", &o.deriv_cutoff}, {"drift_cutoff", &o.drift_cutoff},
      {"horizon", &o.horizon}};
  std::map<std::string, int*> integers = {
      {"decimate", &o.decimate},   {"global_evals", &o.global_evals}, {"lm_iterations", &o.lm_iterations},
      {"max_added", &o.max_added}, {"threads", &o.threads},           {"bootstrap", &o.bootstrap}};
  std::vector<std::string> known = {"terms",          "candidates",  "known",        "guess",        "columns",
                                    "input_kind",     "output_kind", "output_frame", "output2_kind", "objective",
                                    "output_weights", "fit_offsets", "range",        "test_range",   "report"};
  for (const auto& [k, _] : numbers) known.push_back(k);
  for (const auto& [k, _] : integers) known.push_back(k);
  for (const auto& [key, value] : kw) {
    const std::string k = py::str(key);
    if (auto it = numbers.find(k); it != numbers.end()) {
      *it->second = Number(value, k);
    } else if (auto jt = integers.find(k); jt != integers.end()) {
      *jt->second = Integer(value, k);
    } else if (k == "terms") {
      o.terms = TermList(value, k);
    } else if (k == "candidates") {
      o.candidates = TermList(value, k);
    } else if (k == "known") {
      for (const auto& [name, v] : Dict(value, k)) {
        const std::string n = py::str(name);
        const double x = Number(v, "known." + n);
        const bistable::Status st = identify::SetKnown(n, x, &o);
        if (!st.ok()) Raise(st);
      }
    } else if (k == "guess") {
      for (const auto& [name, v] : Dict(value, k))
        o.guesses[py::str(name)] = Number(v, "guess." + std::string(py::str(name)));
    } else if (k == "columns") {
      for (const auto& [role, v] : Dict(value, k)) {
        const std::string r = py::str(role);
        if (r == "group" && !py::isinstance<py::str>(v)) {
          for (const std::string& g : TermList(v, "columns.group")) o.group_columns.push_back(g);
          continue;
        }
        const bistable::Status st = identify::SetColumn(r, Text(v, "columns." + r), &o);
        if (!st.ok()) Raise(st);
      }
    } else if (k == "input_kind") {
      o.input_kind = Unwrap(identify::ParseInputKind(Text(value, k)));
    } else if (k == "output_kind") {
      o.output_kind = Unwrap(identify::ParseOutputKind(Text(value, k)));
    } else if (k == "output_frame") {
      o.output_frame = Unwrap(identify::ParseFrameMode(Text(value, k)));
    } else if (k == "output2_kind") {
      const bistable::Status st = identify::CheckOutput2Kind(Text(value, k));
      if (!st.ok()) Raise(st);
    } else if (k == "objective") {
      o.objective = Unwrap(identify::ParseObjectiveMode(Text(value, k)));
    } else if (k == "output_weights") {
      o.output_weights = Unwrap(identify::ParseOutputWeights(Text(value, k)));
    } else if (k == "fit_offsets") {
      o.fit_offsets = Flag(value, k);
    } else if (k == "range") {
      o.range = Range(value, k);
    } else if (k == "test_range") {  // one range, or a list of them
      const bool one =
          py::isinstance<py::str>(value) || (py::isinstance<py::tuple>(value) && py::len(value) == 2 &&
                                             !py::isinstance<py::str>(py::reinterpret_borrow<py::tuple>(value)[0]) &&
                                             !py::isinstance<py::tuple>(py::reinterpret_borrow<py::tuple>(value)[0]));
      if (one) {
        o.test_ranges.push_back(Range(value, k));
      } else {
        if (!py::isinstance<py::list>(value) && !py::isinstance<py::tuple>(value))
          throw py::value_error(k + " = " + Shown(value) + " violates " + k + " a range or a list of ranges");
        for (const py::handle& r : py::reinterpret_borrow<py::sequence>(value)) o.test_ranges.push_back(Range(r, k));
      }
    } else if (k == "report") {
      *report = Text(value, k);
    } else {
      UnknownKeyword(k, known);
    }
  }
}

std::vector<std::string> Paths(const py::list& data) {
  std::vector<std::string> paths;
  for (const py::handle& p : data) {
    if (py::isinstance<py::bytes>(p))
      paths.push_back(p.cast<std::string>());
    else
      paths.push_back(Text(p, "data"));
  }
  return paths;
}

void Check(const bistable::Status& st) {
  if (!st.ok()) Raise(st);
}

// One value or a list of them (a str is one value).
std::vector<py::handle> OneOrMany(const py::handle& v) {
  if (py::isinstance<py::list>(v) || py::isinstance<py::tuple>(v)) {
    std::vector<py::handle> out;
    for (const py::handle& x : py::reinterpret_borrow<py::sequence>(v)) out.push_back(x);
    return out;
  }
  return {v};
}

// --predict by keyword (PredictOptions, client/identify_predict.h): `model` (the fit's JSON or a report
// directory), `start_well` ("left", "left,right" or a list), `known` (each compared with the model's) and the fit's
// record keywords; what `identify --predict --json` prints.
py::object IdentifyPredict(const py::list& data, const py::dict& kw) {
  PredictOptions p;
  p.data = Paths(data);
  py::dict rest;
  for (const auto& [key, value] : kw) {
    const std::string k = py::str(key);
    if (k == "predict") {
      if (!Flag(value, k)) throw py::value_error("predict = False: not a prediction");
    } else if (k == "model") {
      p.model = Text(value, k);
    } else if (k == "start_well") {
      for (const py::handle& w : OneOrMany(value)) {
        const std::string text = Text(w, k);
        for (const std::string& item : identify::SplitTerms(text))
          p.start_wells.push_back(Unwrap(ParseStartWell(item)));
      }
    } else if (k == "known") {
      for (const auto& [name, v] : Dict(value, k)) {
        const std::string n = py::str(name);
        p.known[n] = Number(v, "known." + n);
      }
    } else {
      rest[key] = value;
    }
  }
  std::string report;
  IdentifyOptionsFromKeywords(rest, &p.records, &report);
  if (!report.empty())
    Raise(bistable::Status::InvalidArgument("report", "--predict writes no report directory (use --json)"));
  Check(Validate(p));
  return ToPython(Unwrap(Compute([&] { return PredictJson(p); })));
}

// --synthetic-extra by keyword: "TERM=VALUE[:VALUE]", a list of them, or {term: value or (values...)}.
void SyntheticExtras(const py::handle& v, const std::string& k, std::vector<TermValues>* out) {
  if (py::isinstance<py::dict>(v)) {
    for (const auto& [term, values] : py::reinterpret_borrow<py::dict>(v)) {
      const std::string t = Text(term, k);
      std::vector<double> xs;
      for (const py::handle& x : OneOrMany(values)) xs.push_back(Number(x, k + "." + t));
      out->push_back(Unwrap(SyntheticExtra(t, xs)));
    }
    return;
  }
  for (const py::handle& e : OneOrMany(v)) out->push_back(Unwrap(ParseSyntheticExtra(Text(e, k))));
}

// --make-synthetic by keyword (identify::MakeSyntheticOptions, identify/synthetic.h): `make_synthetic` (the
// directory), `synthetic` (the kind) and the synthetic_* knobs; what `identify --make-synthetic --json` prints.
py::object IdentifySynthetic(const py::dict& kw) {
  identify::MakeSyntheticOptions o;
  std::map<std::string, double*> numbers = {{"synthetic_f_start", &o.f_start_hz},
                                            {"synthetic_f_end", &o.f_end_hz},
                                            {"synthetic_duration", &o.duration_s},
                                            {"synthetic_noise", &o.noise_mm}};
  std::vector<std::string> known = {"make_synthetic", "synthetic",       "synthetic_amplitude",
                                    "synthetic_seed", "synthetic_extra", "synthetic_start"};
  for (const auto& [k, _] : numbers) known.push_back(k);
  for (const auto& [key, value] : kw) {
    const std::string k = py::str(key);
    if (auto it = numbers.find(k); it != numbers.end()) {
      *it->second = Number(value, k);
    } else if (k == "make_synthetic") {
      o.dir = Text(value, k);
    } else if (k == "synthetic") {
      o.kind = Unwrap(identify::ParseSyntheticKind(Text(value, k)));
    } else if (k == "synthetic_amplitude") {
      for (const py::handle& a : OneOrMany(value)) o.amplitudes_mm.push_back(Number(a, k));
    } else if (k == "synthetic_seed") {
      const std::optional<long long> x = IndexValue(value, k);
      if (!x || *x < 0 || *x > 4294967295LL)
        throw py::value_error(k + " = " + IntegerText(value) + " violates 0 <= " + k + " <= 4294967295");
      o.seed = static_cast<unsigned>(*x);
    } else if (k == "synthetic_extra") {
      SyntheticExtras(value, k, &o.extra);
    } else if (k == "synthetic_start") {
      o.start = Unwrap(identify::ParseWellSide(Text(value, k)));
    } else {
      UnknownKeyword(k, known);
    }
  }
  Check(identify::Validate(o));
  return ToPython(Unwrap(Compute([&] { return SyntheticJson(o); })));
}

// A fit: the records of the files `data` (bytes or str paths) under the keyword options; (what --json prints,
// the fit as text: identify::Summary::FullReport).
py::object IdentifyFit(const py::list& data, const py::dict& kw) {
  const std::vector<std::string> paths = Paths(data);
  std::string report;
  identify::Options o;
  IdentifyOptionsFromKeywords(kw, &o, &report);
  Check(identify::Validate(o));
  std::string full_report;
  const nlohmann::json j = Unwrap(Compute([&] { return IdentifyFitJson(o, paths, report, &full_report); }));
  // A record's name holds what its file name held (any bytes): invalid UTF-8 becomes U+FFFD, as in the JSON.
  PyObject* text = PyUnicode_DecodeUTF8(full_report.data(), static_cast<Py_ssize_t>(full_report.size()), "replace");
  if (!text) throw py::error_already_set();
  return py::make_tuple(ToPython(j), py::reinterpret_steal<py::str>(text));
}

}  // namespace

void DefineIdentify(py::module_& m) {
  m.def("identify", &IdentifyFit, py::arg("data"), py::arg("options"));
  m.def("identify_predict", &IdentifyPredict, py::arg("data"), py::arg("options"));
  m.def("identify_synthetic", &IdentifySynthetic, py::arg("options"));
  m.def("identify_terms", [] { return ToPython(IdentifyTermsJson()); });
}

}  // namespace bistable::py_module
