// What the bindings of the Python module share (python/bistable_module.cc, python/identify_bindings.cc): Python
// objects checked into C++ values (ValueError naming the keyword), Status into Python's exceptions, the CLI's JSON
// into Python objects, and Compute, which runs work without the GIL and with Ctrl-C as cooperative cancellation.
#ifndef BISTABLE_PYTHON_MODULE_COMMON_H_
#define BISTABLE_PYTHON_MODULE_COMMON_H_

#include <pybind11/pybind11.h>
#include <signal.h>

#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "base/status.h"
#include "dynamics/cancel.h"

namespace py = pybind11;

namespace bistable::py_module {

// Status → the Python exception a user expects (ValueError for bad input; see bistable_module.cc).
[[noreturn]] void Raise(const Status& st);
bool OnPythonMainThread();
py::object ToPython(const nlohmann::json& j);
// A value as an error message shows it, bounded.
std::string Shown(const py::handle& v);
// Checked conversions; each raises ValueError naming `name` ("<name> = <value> violates <name> <bound>").
double Number(const py::handle& v, const std::string& name);                        // finite, any numbers.Real
std::optional<long long> IndexValue(const py::handle& v, const std::string& name);  // nullopt: beyond long long
std::string IntegerText(const py::handle& v);
int Integer(const py::handle& v, const std::string& name);  // |value| <= 2^30
bool Flag(const py::handle& v, const std::string& name);
std::string Text(const py::handle& v, const std::string& name);
[[noreturn]] void UnknownKeyword(const std::string& key, const std::vector<std::string>& known);

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
extern std::mutex g_flight_mutex;  // bistable_module.cc
extern int g_in_flight;

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

// The identify bindings (identify_bindings.cc): _core.identify, identify_predict, identify_synthetic,
// identify_terms.
void DefineIdentify(py::module_& m);

}  // namespace bistable::py_module

#endif  // BISTABLE_PYTHON_MODULE_COMMON_H_
