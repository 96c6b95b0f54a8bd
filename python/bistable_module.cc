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
#include "client/terms_report.h"
#include "dynamics/cancel.h"
#include "dynamics/hbm.h"
#include "dynamics/point.h"
#include "engine/sweep_spec.h"
#include "engine/sweep_state.h"
#include "identify/options.h"
#include "identify/synthetic.h"
#include "proto/coordinator_client.h"

namespace py = pybind11;

namespace bistable {
namespace {

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

template <typename T>
T Unwrap(StatusOr<T> v) {
  if (!v.ok()) Raise(v.status());
  return std::move(v).value();
}

// Runs `work` without the GIL and raises KeyboardInterrupt if cancellation was requested meanwhile
// (its result may be cut short; nothing of it is returned).
//
// The cancel flag (dynamics/cancel.h) is process-wide and, for the engine, sticky: work that sees it
// must not store what it cut short (engine/evaluate.cc checks it after a job). So it is cleared only
// when no computation of this module is in flight — under the same mutex that admits new ones — and
// a computation never starts, runs and finishes across a clear.
//
// `cancellable` work (it polls the flag: points, sweeps, HBM, queries, watching, fetching) started
// from Python's main thread takes SIGINT for its duration: the first Ctrl-C requests cancellation,
// a second one ends the process with the default action, as in the CLI; Python's handler is put back
// afterwards. A SIGINT that was ignored stays ignored. Other work leaves Python's handler in place
// (Ctrl-C then arrives as KeyboardInterrupt when the call returns).
std::mutex g_flight_mutex;
int g_in_flight = 0;

template <typename F>
auto Compute(F&& work, bool cancellable = true) -> decltype(work()) {
  static std::mutex handler_mutex;
  std::unique_lock<std::mutex> handler(handler_mutex, std::defer_lock);
  struct sigaction old {};
  bool installed = false;
  if (cancellable && OnPythonMainThread() && handler.try_lock() && ::sigaction(SIGINT, nullptr, &old) == 0 &&
      old.sa_handler != SIG_IGN) {
    struct sigaction sa {};
    sa.sa_handler = [](int) {
      if (CancelRequested()) {  // the second Ctrl-C: stop now (async-signal-safe calls only)
        ::signal(SIGINT, SIG_DFL);
        ::raise(SIGINT);
      }
      RequestCancel();
    };
    sigemptyset(&sa.sa_mask);
    sa.sa_flags = SA_RESTART;
    installed = ::sigaction(SIGINT, &sa, nullptr) == 0;
  }
  {
    std::lock_guard<std::mutex> lock(g_flight_mutex);
    ++g_in_flight;
  }
  auto finish = [&] {
    if (installed) ::sigaction(SIGINT, &old, nullptr);
    std::lock_guard<std::mutex> lock(g_flight_mutex);
    const bool cancelled = CancelRequested();
    if (--g_in_flight == 0 && cancelled) ScopedCancelReset reset;  // nothing running: the next call starts clean
    return cancelled;
  };
  std::optional<decltype(work())> result;
  try {
    py::gil_scoped_release release;
    result.emplace(work());
  } catch (...) {
    finish();
    throw;
  }
  if (finish()) {
    PyErr_SetNone(PyExc_KeyboardInterrupt);
    throw py::error_already_set();
  }
  return std::move(*result);
}

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

py::object Sweeps(const std::string& data) { return ToPython(Unwrap(LocalSweepsJson(data))); }

py::object QueryMap(const std::string& id, const std::string& expr, const std::string& data, long long limit) {
  MapSource src;
  src.data_dir = data;
  const size_t max_points = limit < 0 ? SIZE_MAX : static_cast<size_t>(limit);
  return ToPython(Unwrap(Compute([&] { return QueryJson(src, id, expr, max_points); })));
}

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
  std::map<std::string, int*> integers = {{"decimate", &o.decimate},
                                          {"global_evals", &o.global_evals},
                                          {"lm_iterations", &o.lm_iterations},
                                          {"max_added", &o.max_added},
                                          {"threads", &o.threads}};
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
  m.def("find", &Find, py::arg("id"), py::arg("data"));
  m.def("hbm", &Hbm, "Harmonic balance with continuation and stability");
  m.def("sweeps", &Sweeps, py::arg("data"));
  m.def("query", &QueryMap, py::arg("id"), py::arg("expr"), py::arg("data"), py::arg("limit"));
  m.def("identify", &IdentifyFit, py::arg("data"), py::arg("options"));
  m.def("identify_predict", &IdentifyPredict, py::arg("data"), py::arg("options"));
  m.def("identify_synthetic", &IdentifySynthetic, py::arg("options"));
  m.def("identify_terms", [] { return ToPython(IdentifyTermsJson()); });
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
