// The C++ half of the Python module `bistable` (pybind11): thin bindings over the same functions the
// CLI calls, so a point, a map or a branch computed from Python is the CLI's, bit for bit. Python-side
// conveniences (xarray datasets, numpy arrays, keyword defaults) live in bistable/__init__.py.
//
// Rules every binding follows:
//  * arguments arrive as Python objects and are checked here (names against a table, numbers finite
//    where the CLI requires it); a bad one raises ValueError with the library's field-naming message;
//  * the GIL is released while computing (gil_scoped_release), so other Python threads run;
//  * Ctrl-C while a computation runs from the main thread requests cooperative cancellation
//    (dynamics/cancel.h); the call then raises KeyboardInterrupt and nothing partial is returned; the
//    process-wide flag is cleared once no computation is in flight (see Compute);
//  * results come back as Python dicts/lists built from the CLI's JSON objects (nlohmann::json → Python
//    with doubles as they are, non-finite numbers as None exactly as --json prints null), or numpy arrays.
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>
#include <signal.h>

#include <chrono>
#include <cmath>
#include <map>
#include <mutex>
#include <optional>
#include <string>
#include <thread>

#include "base/cpus.h"
#include "base/limits.h"
#include "base/names.h"
#include "base/status.h"
#include "base/version.h"
#include "client/cli_common.h"
#include "client/embedded_run.h"
#include "client/hbm_json.h"
#include "client/identify_command.h"
#include "client/json_out.h"
#include "client/map_query.h"
#include "client/map_source.h"
#include "client/poincare_section.h"
#include "client/shard_run.h"
#include "client/terms_report.h"
#include "dynamics/cancel.h"
#include "dynamics/hbm.h"
#include "dynamics/point.h"
#include "engine/sweep_plan.h"
#include "engine/sweep_spec.h"
#include "engine/sweep_state.h"
#include "proto/coordinator_client.h"
#include "python/module_common.h"

namespace bistable::py_module {

// Python delivers signals to its main thread only; only there may a call take SIGINT over.
bool OnPythonMainThread() {
  py::module_ threading = py::module_::import("threading");
  return threading.attr("get_ident")().cast<unsigned long>() ==
         threading.attr("main_thread")().attr("ident").cast<unsigned long>();
}

// Status → the Python exception a user expects: bad input is ValueError, a missing sweep LookupError
// (KeyError would quote the message), files and connections OSError, credentials PermissionError.
// Text as a Python str; bytes that are not UTF-8 (a file name, a label read from a file) become U+FFFD,
// as in the CLI's --json (engine/json_shapes.h: DumpJson).
py::str Utf8(const std::string& s) {
  PyObject* o = PyUnicode_DecodeUTF8(s.data(), static_cast<Py_ssize_t>(s.size()), "replace");
  if (!o) throw py::error_already_set();
  return py::reinterpret_steal<py::str>(o);
}

[[noreturn]] void Raise(const Status& st) {
  const py::str msg = Utf8(st.ToString());
  PyObject* type = PyExc_RuntimeError;
  switch (st.code()) {
    case Status::Code::kInvalidArgument:
    case Status::Code::kFailedPrecondition:
      type = PyExc_ValueError;
      break;
    case Status::Code::kNotFound:
      type = PyExc_LookupError;
      break;
    case Status::Code::kIoError:
      type = PyExc_OSError;
      break;
    case Status::Code::kUnauthenticated:
    case Status::Code::kPermissionDenied:
      type = PyExc_PermissionError;
      break;
    default:
      break;
  }
  PyErr_SetObject(type, msg.ptr());
  throw py::error_already_set();
}

std::mutex g_flight_mutex;
int g_in_flight = 0;

py::object ToPython(const nlohmann::json& j) {
  switch (j.type()) {
    case nlohmann::json::value_t::null:
      return py::none();
    case nlohmann::json::value_t::boolean:
      return py::bool_(j.get<bool>());
    case nlohmann::json::value_t::number_integer:
      return py::int_(j.get<long long>());
    case nlohmann::json::value_t::number_unsigned:
      return py::int_(j.get<unsigned long long>());
    case nlohmann::json::value_t::number_float: {  // NaN/inf as --json prints them: null
      const double v = j.get<double>();
      return std::isfinite(v) ? py::object(py::float_(v)) : py::object(py::none());
    }
    case nlohmann::json::value_t::string:
      return Utf8(j.get_ref<const std::string&>());
    case nlohmann::json::value_t::array: {
      py::list l;
      for (const auto& v : j) l.append(ToPython(v));
      return l;
    }
    case nlohmann::json::value_t::object: {
      py::dict d;
      for (const auto& [k, v] : j.items()) d[Utf8(k)] = ToPython(v);
      return d;
    }
    default:
      return py::none();
  }
}

// A bool, Python's or numpy's (numpy.bool_ converts to float and, in old numpy, to an index): never a
// number or an integer here.
bool IsBool(const py::handle& v) {
  if (py::isinstance<py::bool_>(v)) return true;
  const py::handle type = reinterpret_cast<PyObject*>(Py_TYPE(v.ptr()));
  return py::str(type.attr("__module__")).cast<std::string>() == "numpy" &&
         py::str(type.attr("__name__")).cast<std::string>().rfind("bool", 0) == 0;
}

// A value as an error message shows it, bounded: strings cut to 64 characters, integers up to about 1000
// digits (beyond, their digit count: str() of a huge int raises past 4300), numbers as repr() prints them (cut to 64
// characters), anything else by its type's name (no user __repr__ runs for it).
std::string Shown(const py::handle& v) {
  try {
    if (py::isinstance<py::str>(v)) {
      const py::str sv = py::reinterpret_borrow<py::str>(v);
      const size_t n = py::len(sv);
      const py::object head = sv[py::slice(0, 64, 1)];
      return std::string(py::str(py::repr(head))) + (n > 64 ? "... (" + std::to_string(n) + " characters)" : "");
    }
    if (!IsBool(v) && PyIndex_Check(v.ptr())) {
      const py::object i = py::reinterpret_steal<py::object>(PyNumber_Index(v.ptr()));
      if (!i) throw py::error_already_set();
      const long long bits = py::int_(i.attr("bit_length")()).cast<long long>();
      if (bits > 3300)
        return "an integer of about " + std::to_string(static_cast<long long>(bits * 0.30103) + 1) + " digits";
      return py::str(i);
    }
    static const py::object& real = *new py::object(py::module_::import("numbers").attr("Real"));  // never destroyed
    if (py::isinstance<py::float_>(v) || py::isinstance(v, real) || IsBool(v)) {
      const std::string r = py::str(py::repr(v));
      return r.size() > 64 ? r.substr(0, 64) + "..." : r;
    }
    if (v.is_none()) return "None";
    const bool tuple = py::isinstance<py::tuple>(v);
    if (tuple || py::isinstance<py::list>(v)) {  // a few elements, each shown this way
      const py::sequence seq = py::reinterpret_borrow<py::sequence>(v);
      const size_t n = py::len(seq);
      std::string out = tuple ? "(" : "[";
      for (size_t i = 0; i < std::min<size_t>(n, 8); ++i) out += (i ? ", " : "") + Shown(seq[i]);
      if (n > 8) out += ", ... (" + std::to_string(n) + " elements)";
      return out + (tuple ? (n == 1 ? ",)" : ")") : "]");
    }
  } catch (const py::error_already_set&) {
  }
  std::string type = Py_TYPE(v.ptr())->tp_name;
  return "<" + type.substr(0, 64) + ">";
}

// A finite number from a Python object — any numbers.Real but a bool: int, float, numpy.float32, numpy.int64 ...;
// ValueError naming the keyword otherwise.
double Number(const py::handle& v, const std::string& name) {
  static const py::object& real = *new py::object(py::module_::import("numbers").attr("Real"));  // never destroyed
  if (IsBool(v) || !py::isinstance(v, real))
    throw py::value_error(name + " = " + Shown(v) + " violates " + name + " a number");
  double x = NAN;
  try {
    x = py::float_(py::reinterpret_borrow<py::object>(v)).cast<double>();
  } catch (const py::error_already_set&) {  // an int beyond a double's range: OverflowError in float()
    x = INFINITY;
  }
  if (!std::isfinite(x)) throw py::value_error(name + " = " + Shown(v) + " violates " + name + " finite");
  return x;
}

// An integer from a Python int or anything with __index__ (numpy.int64 ...), bools not; nullopt when it does
// not fit a long long. ValueError naming the keyword when it is not an integer.
std::optional<long long> IndexValue(const py::handle& v, const std::string& name) {
  if (IsBool(v) || !PyIndex_Check(v.ptr()))
    throw py::value_error(name + " = " + Shown(v) + " violates " + name + " an integer");
  const py::object i = py::reinterpret_steal<py::object>(PyNumber_Index(v.ptr()));
  if (!i) throw py::error_already_set();
  int overflow = 0;  // beyond long long: out of range (v.cast would raise a bare RuntimeError)
  const long long x = PyLong_AsLongLongAndOverflow(i.ptr(), &overflow);
  if (overflow != 0) return std::nullopt;
  return x;
}

// An integer's value as Python prints it (numpy.int64(5) as 5), bounded (Shown).
std::string IntegerText(const py::handle& v) { return Shown(v); }

int Integer(const py::handle& v, const std::string& name) {
  const std::optional<long long> x = IndexValue(v, name);
  if (!x || *x < -(1LL << 30) || *x > (1LL << 30))
    throw py::value_error(name + " = " + IntegerText(v) + " violates |" + name + "| <= 2^30");
  return static_cast<int>(*x);
}

bool Flag(const py::handle& v, const std::string& name) {
  if (!py::isinstance<py::bool_>(v))
    throw py::value_error(name + " = " + Shown(v) + " violates " + name + " True or False");
  return v.cast<bool>();
}

std::string Text(const py::handle& v, const std::string& name) {
  if (!py::isinstance<py::str>(v)) throw py::value_error(name + " = " + Shown(v) + " violates " + name + " a string");
  return v.cast<std::string>();
}

[[noreturn]] void UnknownKeyword(const std::string& key, const std::vector<std::string>& known) {
  throw py::value_error(UnknownNameMessage("keyword", key, known));
}

}  // namespace bistable::py_module

namespace bistable {
namespace {

using namespace py_module;

// `poincare_periods`: an integer, however large (one beyond `long` is outside the bound SetPoincareWindow
// checks: the same message, with the value as given).
long Periods(const py::handle& v, const std::string& name) {
  const std::optional<long long> x = IndexValue(v, name);
  if (!x)
    throw py::value_error(name + " = " + IntegerText(v) + " violates " + name + " in [1, " +
                          std::to_string(limits::kMaxPoincarePeriods) + "]");
  return static_cast<long>(*x);
}

// The point options by keyword — the flags of `bistable point` with '-' as '_'. `poincare_periods`
// (> 0 when given) sets the window as `point --poincare-periods` does; *section_limit gets it (0 when
// not given: the whole window's section).
PointSpec PointFromKeywords(const py::dict& kw, long* section_limit = nullptr) {
  PointSpec s;
  std::string model = "coupled", integrator = "rk4";
  bool alpha = false, omega = false, t_end = false;
  std::optional<long> periods;
  std::map<std::string, double*> numbers = {{"alpha", &s.alpha},
                                            {"omega", &s.omega},
                                            {"eps", &s.params.eps},
                                            {"eta", &s.params.eta},
                                            {"eta_r", &s.params.eta_r},
                                            {"phi", &s.params.phi},
                                            {"lambda", &s.params.lambda},
                                            {"t_end", &s.integration.t_end},
                                            {"t_keep", &s.integration.t_keep},
                                            {"dt", &s.integration.dt},
                                            {"rtol", &s.integration.rtol},
                                            {"atol", &s.integration.atol},
                                            {"chaos_threshold", &s.metrics.chaos_threshold},
                                            {"poincare_phase", &s.metrics.poincare_phase}};
  std::map<std::string, int*> integers = {{"renorm_every", &s.metrics.renorm_every},
                                          {"sample_every", &s.metrics.sample_every}};
  std::vector<std::string> known = {"model", "integrator", "ic", "rosenstein", "poincare_periods"};
  for (const auto& [k, _] : numbers) known.push_back(k);
  for (const auto& [k, _] : integers) known.push_back(k);
  for (const auto& [key, value] : kw) {
    const std::string k = py::str(key);
    if (auto it = numbers.find(k); it != numbers.end()) {
      *it->second = Number(value, k);
      alpha |= k == "alpha", omega |= k == "omega", t_end |= k == "t_end";
    } else if (k == "poincare_periods") {
      periods = Periods(value, k);
    } else if (auto jt = integers.find(k); jt != integers.end()) {
      *jt->second = Integer(value, k);
    } else if (k == "model") {
      model = Text(value, k);
    } else if (k == "integrator") {
      integrator = Text(value, k);
    } else if (k == "rosenstein") {
      s.metrics.rosenstein = Flag(value, k);
    } else if (k == "ic") {
      if (!py::isinstance<py::sequence>(value) || py::isinstance<py::str>(value))
        throw py::value_error("ic = " + Shown(value) + " violates ic = (ym, vm) or (ym, vm, yr, vr)");
      const auto seq = py::reinterpret_borrow<py::sequence>(value);
      if (seq.size() != 2 && seq.size() != 4)
        throw py::value_error("ic has " + std::to_string(seq.size()) +
                              " numbers; violates ic = (ym, vm) or (ym, vm, yr, vr)");
      for (size_t i = 0; i < seq.size(); ++i) s.ic[i] = Number(seq[i], "ic[" + std::to_string(i) + "]");
      s.ic_given = true;
    } else {
      UnknownKeyword(k, known);
    }
  }
  if (!alpha) throw py::value_error("alpha is required (base amplitude A0/delta_s, > 0)");
  if (!omega) throw py::value_error("omega is required (base frequency omega0/omega_n, > 0)");
  s.model = Unwrap(ParseModel(model));
  s.integration.integrator = Unwrap(ParseIntegrator(integrator));
  if (periods) {
    if (t_end)
      throw py::value_error(
          "t_end excludes poincare_periods (the window is made poincare_periods + 1 forcing periods long): "
          "give one of them");
    const Status st = SetPoincareWindow(*periods, "poincare_periods", &s);
    if (!st.ok()) Raise(st);
  }
  if (section_limit) *section_limit = periods.value_or(0);
  return s;
}

// The section as `point --poincare - --json` gives it (phase, count, k0, columns, units), its points
// as one numpy array per column instead of rows: "k" (int64), "tau", "y_m", "dy_m" (, "y_r", "dy_r").
py::dict SectionDict(const PointSpec& spec, const PointResult& r, long limit) {
  py::dict out = ToPython(SectionJson(spec, r, limit, ""));
  const auto columns = SectionColumns(spec);
  const size_t n = SectionCount(r, limit);
  std::vector<py::array_t<double>> arrays;
  for (size_t c = 0; c < columns.size(); ++c) arrays.emplace_back(n);
  for (size_t i = 0; i < n; ++i) {
    const std::vector<double> row = SectionRow(spec, r, i);
    for (size_t c = 0; c < columns.size(); ++c) arrays[c].mutable_at(i) = row[c];
  }
  for (size_t c = 0; c < columns.size(); ++c)
    out[py::str(columns[c].first)] =
        columns[c].first == "k" ? py::object(arrays[c].attr("astype")("int64")) : py::object(arrays[c]);
  return out;
}

py::dict Point(const py::kwargs& kw) {
  py::dict rest = py::reinterpret_borrow<py::dict>(kw).attr("copy")();
  bool spectrum = false, poincare = false;
  if (rest.contains("spectrum"))
    spectrum = Flag(rest["spectrum"], "spectrum"), PyDict_DelItemString(rest.ptr(), "spectrum");
  if (rest.contains("poincare"))
    poincare = Flag(rest["poincare"], "poincare"), PyDict_DelItemString(rest.ptr(), "poincare");
  long section_limit = 0;
  const PointSpec spec = PointFromKeywords(rest, &section_limit);
  const PointResult r = Unwrap(Compute([&] { return EvaluatePoint(spec); }));
  nlohmann::json j = PointJson(spec, r);
  if (spectrum) AddSpectrumJson(Unwrap(Compute([&] { return EvaluateLyapunovSpectrum(spec); })), &j);
  py::dict out = ToPython(j);
  // As `point --json`: the section whenever it was asked for (poincare) or its window set (poincare_periods).
  if (poincare || section_limit > 0) out["poincare"] = SectionDict(spec, r, section_limit);
  return out;
}

// The sampled window: tau, y_m, dy_m, y_r, dy_r as numpy arrays, plus the metrics.
py::dict Trajectory(const py::kwargs& kw) {
  PointSpec spec = PointFromKeywords(kw);
  spec.metrics.keep_samples = true;
  PointResult r = Unwrap(Compute([&] { return EvaluatePoint(spec); }));
  const size_t n = r.samples.size();
  static const char* kNames[] = {"tau", "y_m", "dy_m", "y_r", "dy_r"};
  py::dict out;
  for (int c = 0; c < 5; ++c) {
    py::array_t<double> a(n);
    auto m = a.mutable_unchecked<1>();
    for (size_t i = 0; i < n; ++i) m(i) = r.samples[i][c];
    out[kNames[c]] = a;
  }
  r.samples.clear();
  out["metrics"] = ToPython(PointJson(spec, r));
  return out;
}

// spec: TOML text; origin names it in error messages. Returns {"id", "file"}.
py::dict Run(const std::string& toml, const std::string& origin, const std::string& data, int threads, bool progress) {
  // [terms] report = "..." read here, relative to the spec's file (origin) or the working directory, as `bistable run`.
  SweepSpec spec = Unwrap(ParseSweepSpec(Unwrap(InlineTermsReport(toml, origin)), origin));
  if (threads < 0 || threads > 1024)
    throw py::value_error("threads = " + std::to_string(threads) + " violates threads in [0, 1024]");
  const int n = threads > 0 ? threads : UsableCpus();  // as `bistable run`
  const std::string path = Unwrap(Compute([&] { return RunEmbeddedSweep(spec, data, n, progress); }));
  py::dict out;
  out["id"] = spec.Id();
  out["file"] = path;
  return out;
}

// {"id", "name", "state", "file"} of a sweep in a local data directory, by id or unique prefix.
py::dict Find(const std::string& id, const std::string& data) {
  SweepRef ref = Unwrap(FindSweep(data, id));
  py::dict out;
  out["id"] = ref.row.id;
  out["name"] = ref.row.name;
  out["state"] = SweepStateName(ref.row.state);
  out["file"] = ref.map_path.empty() ? py::object(py::none()) : py::object(py::str(ref.map_path));
  return out;
}

// `alpha_range` / `omega_range` of the fold curves: (lo, hi), two numbers (their bounds are
// ValidateFoldCurveOptions', as in `hbm --alpha-range`).
void Range(const py::handle& v, const std::string& name, double* lo, double* hi) {
  if (!py::isinstance<py::sequence>(v) || py::isinstance<py::str>(v) || py::len(v) != 2)
    throw py::value_error(name + " = " + Shown(v) + " violates " + name + " = (lo, hi), two numbers");
  const auto seq = py::reinterpret_borrow<py::sequence>(v);
  *lo = Number(seq[0], name + "[0]"), *hi = Number(seq[1], name + "[1]");
}

// Points given as a JSON list of objects (`shape`: one of them, for the keys and their types) as one
// column per key: numbers a float64 array (null as NaN), booleans a bool array, strings a list.
py::dict Columns(const nlohmann::json& points, const nlohmann::json& shape) {
  py::dict d;
  const size_t n = points.size();
  for (const auto& [key, proto] : shape.items()) {
    if (proto.is_boolean()) {
      py::array_t<bool> a(n);
      for (size_t i = 0; i < n; ++i) a.mutable_at(i) = points[i].at(key).get<bool>();
      d[py::str(key)] = a;
    } else if (proto.is_number()) {
      py::array_t<double> a(n);
      for (size_t i = 0; i < n; ++i) {
        const nlohmann::json& v = points[i].at(key);
        a.mutable_at(i) = v.is_null() ? NAN : v.get<double>();
      }
      d[py::str(key)] = a;
    } else {
      py::list l;
      for (size_t i = 0; i < n; ++i) l.append(ToPython(points[i].at(key)));
      d[py::str(key)] = l;
    }
  }
  return d;
}

py::dict Hbm(const py::kwargs& kw) {
  HbmOptions o;
  FoldCurveOptions f;
  bool fold_curve = false;
  std::string model = "standalone", param = "omega";
  std::map<std::string, double*> numbers = {
      {"start", &o.from},           {"stop", &o.to},        {"alpha", &o.alpha},        {"omega", &o.omega},
      {"eps", &o.params.eps},       {"eta", &o.params.eta}, {"eta_r", &o.params.eta_r}, {"phi", &o.params.phi},
      {"lambda", &o.params.lambda}, {"ds", &o.ds}};
  std::vector<std::string> known = {"model",     "param",      "harmonics",   "zero_mean",
                                    "switch_pd", "fold_curve", "alpha_range", "omega_range"};
  for (const auto& [k, _] : numbers) known.push_back(k);
  for (const auto& [key, value] : kw) {
    const std::string k = py::str(key);
    if (auto it = numbers.find(k); it != numbers.end())
      *it->second = Number(value, k);
    else if (k == "model")
      model = Text(value, k);
    else if (k == "param")
      param = Text(value, k);
    else if (k == "harmonics")
      o.harmonics = Integer(value, k);
    else if (k == "switch_pd")
      o.switch_depth = Integer(value, k);
    else if (k == "zero_mean")
      o.zero_mean = Flag(value, k);
    else if (k == "fold_curve")
      fold_curve = Flag(value, k);
    else if (k == "alpha_range")
      Range(value, k, &f.alpha_lo, &f.alpha_hi);
    else if (k == "omega_range")
      Range(value, k, &f.omega_lo, &f.omega_hi);
    else
      UnknownKeyword(k, known);
  }
  o.model = Unwrap(ParseModel(model));
  if (param == "omega")
    o.param = ContinuationParam::kOmega;
  else if (param == "alpha")
    o.param = ContinuationParam::kAlpha;
  else
    throw py::value_error("param = '" + param + "' violates param in {omega, alpha}");
  if (const Status st = ValidateFoldCurveOptions(f); !st.ok()) Raise(st);  // as `hbm`: the ranges are checked always
  // `hbm --fold-curve`'s two steps: the branches, then the fold curves through their folds.
  auto [branches_or, curves_or] = Compute([&] {
    StatusOr<HbmResult> branches = ContinueBranches(o);
    StatusOr<std::vector<FoldCurve>> curves = std::vector<FoldCurve>{};
    if (branches.ok() && fold_curve) curves = ContinueFoldCurves(o, f, *branches);
    return std::make_pair(std::move(branches), std::move(curves));
  });
  HbmResult r = Unwrap(std::move(branches_or));
  const std::vector<FoldCurve> curves = Unwrap(std::move(curves_or));
  py::list branches;
  for (const HbmBranch& b : r.branches) {
    const size_t n = b.points.size();
    py::array_t<double> om(n), al(n), amp(n), mean(n), mu(n), ylo(n), yhi(n);
    py::list well;
    py::array_t<bool> stable(n), fold(n), bp(n), conv(n), pd(n), ns(n);
    size_t h = n ? b.points[0].harmonics.size() : 0;
    py::array_t<double> harm({n, h});
    auto H = harm.mutable_unchecked<2>();
    for (size_t i = 0; i < n; ++i) {
      const HbmPoint& p = b.points[i];
      om.mutable_at(i) = p.omega, al.mutable_at(i) = p.alpha, amp.mutable_at(i) = p.amplitude,
      mean.mutable_at(i) = p.mean;
      mu.mutable_at(i) = p.max_multiplier, stable.mutable_at(i) = p.stable, fold.mutable_at(i) = p.fold;
      bp.mutable_at(i) = p.branch_point, conv.mutable_at(i) = p.converged;
      pd.mutable_at(i) = p.period_doubling, ns.mutable_at(i) = p.neimark_sacker;
      ylo.mutable_at(i) = p.y_min, yhi.mutable_at(i) = p.y_max;
      well.append(OrbitWellName(WellOf(p)));
      for (size_t k = 0; k < h && k < p.harmonics.size(); ++k) H(i, k) = p.harmonics[k];
    }
    py::dict d;
    d["start"] = b.start;
    d["period"] = b.period;
    d["period_doubling"] = pd, d["neimark_sacker"] = ns;
    d["omega"] = om, d["alpha"] = al, d["amplitude"] = amp, d["mean"] = mean, d["max_multiplier"] = mu;
    d["y_min"] = ylo, d["y_max"] = yhi;
    if (IsBistable(o.model)) d["well"] = well;  // as `hbm --json`: one well only in the linear models
    d["stable"] = stable, d["fold"] = fold, d["branch_point"] = bp, d["converged"] = conv, d["harmonics"] = harm;
    branches.append(d);
  }
  py::dict settings;
  settings["model"] = ModelName(o.model), settings["param"] = param, settings["start"] = o.from,
  settings["stop"] = o.to;
  settings["alpha"] = o.alpha, settings["omega"] = o.omega, settings["harmonics"] = o.harmonics,
  settings["zero_mean"] = o.zero_mean;
  settings["eps"] = o.params.eps, settings["eta"] = o.params.eta;
  if (HasResonator(o.model))
    settings["eta_r"] = o.params.eta_r, settings["phi"] = o.params.phi, settings["lambda"] = o.params.lambda;
  settings["numerics_version"] = kNumericsVersion;
  py::dict out;
  out["branches"] = branches;
  out["settings"] = settings;
  out["bifurcations"] = ToPython(BifurcationsJson(r));  // as `hbm --json`: one dict per flagged point
  out["truncation_change"] = r.truncation_change;
  out["notes"] = r.notes;
  settings["switch_pd"] = o.switch_depth;
  if (fold_curve) {  // `hbm --fold-curve --json`'s fold_curves, each curve's points as columns
    const bool bistable = IsBistable(o.model);
    const nlohmann::json shape = FoldCurvePointJson(FoldCurvePoint{}, bistable);
    py::list folds;
    for (const nlohmann::json& c : FoldCurvesJson(curves, bistable)) {
      py::dict d = Columns(c.at("points"), shape);
      d["start"] = c.at("start").get<std::string>();
      d["converged"] = c.at("converged").get<bool>();
      folds.append(d);
    }
    out["fold_curves"] = folds;
    settings["alpha_range"] = std::vector<double>{f.alpha_lo, f.alpha_hi};  // lists, as --json prints them
    settings["omega_range"] = std::vector<double>{f.omega_lo, f.omega_hi};
  }
  return out;
}

// One shard of a sweep into its own store (`bistable run --shard I/N`): {"store", "items", "cached", "computed"}.
py::dict RunShardPy(const std::string& toml, const std::string& origin, const std::string& shard,
                    const std::string& data, int threads, bool progress) {
  SweepSpec spec = Unwrap(ParseSweepSpec(Unwrap(InlineTermsReport(toml, origin)), origin));
  const Shard sh = Unwrap(ParseShard(shard));
  if (Status st = CheckShardable(spec); !st.ok()) Raise(st);
  if (threads < 0 || threads > 1024)
    throw py::value_error("threads = " + std::to_string(threads) + " violates threads in [0, 1024]");
  const int n = threads > 0 ? threads : UsableCpus();
  ShardRunResult r;
  Unwrap(Compute([&]() -> StatusOr<bool> {
    BISTABLE_RETURN_IF_ERROR(RunShard(spec, sh, data, n, 0, progress, &r));
    return true;
  }));
  py::dict out;
  out["store"] = r.store, out["items"] = r.items, out["cached"] = r.cached, out["computed"] = r.computed;
  return out;
}

// The shards' stores assembled into the map (`bistable merge`): {"id", "file", "shards", "items"}.
py::dict MergePy(const std::string& toml, const std::string& origin, const std::vector<std::string>& stores,
                 const std::string& data) {
  SweepSpec spec = Unwrap(ParseSweepSpec(Unwrap(InlineTermsReport(toml, origin)), origin));
  const MergeResult r = Unwrap(Compute([&] { return MergeShards(spec, stores, data); }));
  py::dict out;
  out["id"] = r.id, out["file"] = r.map, out["shards"] = r.shards, out["items"] = r.items;
  return out;
}

py::object Sweeps(const std::string& data) { return ToPython(Unwrap(LocalSweepsJson(data))); }

py::object QueryMap(const std::string& id, const std::string& expr, const std::string& data, long long limit) {
  MapSource src;
  src.data_dir = data;
  const size_t max_points = limit < 0 ? SIZE_MAX : static_cast<size_t>(limit);
  return ToPython(Unwrap(Compute([&] { return QueryJson(src, id, expr, max_points); })));
}

// A coordinator, through the CLI's CoordinatorClient (one channel; the token on every call).
class PyClient {
 public:
  PyClient(const std::string& address, const std::string& token, const std::string& tls_ca, bool insecure_remote)
      : c_(Unwrap(CoordinatorClient::Connect({address, tls_ca, token, insecure_remote}))) {}

  py::object Submit(const std::string& toml, const std::string& origin) {
    return ToPython(SubmittedJson(Unwrap(Compute([&] { return c_->Submit(toml, origin); }, false))));
  }
  py::object Status(const std::string& id) {
    return ToPython(SweepStatusJson(Unwrap(Compute([&] { return c_->GetStatus(id); }, false))));
  }
  // Until the sweep is final, or `timeout` seconds (< 0: no limit) pass: its last status.
  py::object Wait(const std::string& id, double timeout) {
    const auto start = std::chrono::steady_clock::now();
    auto last = Compute([&] {
      return c_->Watch(id, [&](const SweepInfo&) {
        return !CancelRequested() &&
               (timeout < 0 ||
                std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count() < timeout);
      });
    });
    return ToPython(SweepStatusJson(Unwrap(std::move(last))));
  }
  void Cancel(const std::string& id) {
    const bistable::Status st = Compute([&] { return c_->Cancel(id); }, false);
    if (!st.ok()) Raise(st);
  }
  py::object Sweeps() {
    auto list = Unwrap(Compute([&] { return c_->ListSweeps(); }, false));
    nlohmann::json arr = nlohmann::json::array();
    for (const SweepInfo& s : list) arr.push_back(RemoteSweepJson(s));
    return ToPython(arr);
  }
  py::object Workers() {
    auto list = Unwrap(Compute([&] { return c_->Workers(); }, false));
    nlohmann::json arr = nlohmann::json::array();
    for (const WorkerInfo& w : list) arr.push_back(WorkerJson(w));
    return ToPython(arr);
  }
  py::object Fetch(const std::string& id, const std::string& path) {
    return ToPython(Unwrap(Compute([&] { return FetchMapFile(*c_, id, path); })));
  }

 private:
  std::unique_ptr<CoordinatorClient> c_;
};

}  // namespace
}  // namespace bistable

PYBIND11_MODULE(_core, m) {
  using namespace bistable;
  m.doc() = "bistable-sweep's C++ core (see the package bistable for the documented API)";
  m.attr("__version__") = kSoftwareVersion;
  m.attr("numerics_version") = kNumericsVersion;
  m.def("point", &Point, "Integrate one point; the dict `bistable point --json` prints");
  m.def("trajectory", &Trajectory, "Integrate one point; the sampled window as numpy arrays");
  m.def("run", &Run, py::arg("toml"), py::arg("origin"), py::arg("data"), py::arg("threads"), py::arg("progress"));
  m.def("run_shard", &RunShardPy, py::arg("toml"), py::arg("origin"), py::arg("shard"), py::arg("data"),
        py::arg("threads"), py::arg("progress"));
  m.def("merge", &MergePy, py::arg("toml"), py::arg("origin"), py::arg("stores"), py::arg("data"));
  m.def("find", &Find, py::arg("id"), py::arg("data"));
  m.def("hbm", &Hbm, "Harmonic balance with continuation and stability");
  m.def("sweeps", &Sweeps, py::arg("data"));
  m.def("query", &QueryMap, py::arg("id"), py::arg("expr"), py::arg("data"), py::arg("limit"));
  py_module::DefineIdentify(m);
  py::class_<PyClient>(m, "Client")
      .def(py::init<const std::string&, const std::string&, const std::string&, bool>(), py::arg("address"),
           py::arg("token"), py::arg("tls_ca"), py::arg("insecure_remote"))
      .def("submit", &PyClient::Submit)
      .def("status", &PyClient::Status)
      .def("wait", &PyClient::Wait)
      .def("cancel", &PyClient::Cancel)
      .def("sweeps", &PyClient::Sweeps)
      .def("workers", &PyClient::Workers)
      .def("fetch", &PyClient::Fetch);
}
