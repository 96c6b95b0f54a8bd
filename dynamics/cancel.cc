#include "dynamics/cancel.h"

#include <signal.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>

#include "base/exit_codes.h"

namespace bistable {

namespace cancel_internal {
std::atomic<bool> g_requested{false};
}  // namespace cancel_internal

namespace {

std::atomic<int> g_signal{0};
static_assert(std::atomic<int>::is_always_lock_free, "the signal number is stored from a signal handler");
const char* g_notice = nullptr;  // written before the handlers are installed, read in them

extern "C" void OnCancelSignal(int sig) {
  const int saved_errno = errno;
  if (g_signal.exchange(sig) != 0) {
    // Second signal: the user insists. Default action now (the raised signal is delivered when
    // this handler returns, since it is blocked while the handler runs).
    struct sigaction dfl {};
    dfl.sa_handler = SIG_DFL;
    sigemptyset(&dfl.sa_mask);
    ::sigaction(sig, &dfl, nullptr);
    ::raise(sig);
    errno = saved_errno;
    return;
  }
  RequestCancel();
  if (g_notice) {
    const ssize_t ignored = ::write(STDERR_FILENO, g_notice, std::strlen(g_notice));
    (void)ignored;
  }
  errno = saved_errno;
}

void SetHandler(int sig, void (*handler)(int)) {
  struct sigaction sa {};
  sa.sa_handler = handler;
  sigemptyset(&sa.sa_mask);
  sigaddset(&sa.sa_mask, SIGINT);  // one handler at a time, whichever of the two arrives
  sigaddset(&sa.sa_mask, SIGTERM);
  sa.sa_flags = SA_RESTART;
  ::sigaction(sig, &sa, nullptr);
}

}  // namespace

Status CancelledStatus() {
  return Status::FailedPrecondition("cancelled (interrupted by a signal); nothing partial was kept");
}

void InstallCancelSignalHandlers(const char* notice) {
  g_notice = notice;
  // A SIGINT ignored on entry stays ignored: shells start asynchronous commands of scripts that way so
  // that the terminal's Ctrl-C reaches only the foreground (SIGTERM still stops such a process).
  struct sigaction old {};
  if (::sigaction(SIGINT, nullptr, &old) != 0 || old.sa_handler != SIG_IGN) SetHandler(SIGINT, OnCancelSignal);
  SetHandler(SIGTERM, OnCancelSignal);
}

void RestoreDefaultSignalHandlers() {
  struct sigaction old {};
  if (::sigaction(SIGINT, nullptr, &old) != 0 || old.sa_handler != SIG_IGN) SetHandler(SIGINT, SIG_DFL);
  SetHandler(SIGTERM, SIG_DFL);
}

int CancelSignal() { return g_signal.load(); }

int CancelExitStatus() {
  const int sig = CancelSignal();
  return ExitForSignal(sig > 0 ? sig : SIGINT);
}

ScopedCancelReset::ScopedCancelReset() {
  cancel_internal::g_requested.store(false);
  g_signal.store(0);
}

ScopedCancelReset::~ScopedCancelReset() {
  cancel_internal::g_requested.store(false);
  g_signal.store(0);
}

}  // namespace bistable
