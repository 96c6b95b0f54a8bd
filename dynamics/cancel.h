// Cooperative cancellation: one process-wide flag, set by RequestCancel() (async-signal-safe, so a
// SIGINT/SIGTERM handler may call it) and polled by every long loop — the RK4 kernel every
// kCancelCheckSteps steps, the generic and adaptive point paths, chirps and HBM continuation.
//
// The flag is sticky: once set it stays set for the life of the process (tests reset it with
// ScopedCancelReset). That gives callers one simple rule: work that began before the flag was set
// and finished while CancelRequested() is still false ran to completion; anything that returns while
// the flag is set may have been cut short and must not be stored or reported as a result.
#ifndef BISTABLE_DYNAMICS_CANCEL_H_
#define BISTABLE_DYNAMICS_CANCEL_H_

#include <atomic>

#include "base/status.h"

namespace bistable {

namespace cancel_internal {
extern std::atomic<bool> g_requested;
static_assert(std::atomic<bool>::is_always_lock_free, "the cancel flag must be settable from a signal handler");
}  // namespace cancel_internal

// Loops poll the flag once per this many steps (RK4 kernel: ~30 µs of work per lane at h = 0.01).
inline constexpr long kCancelCheckSteps = 1024;

// Sets the flag. Async-signal-safe.
inline void RequestCancel() noexcept { cancel_internal::g_requested.store(true, std::memory_order_relaxed); }
// One relaxed load: cheap enough for any loop.
inline bool CancelRequested() noexcept { return cancel_internal::g_requested.load(std::memory_order_relaxed); }

// Unwinds a cancelled integration from inside an integrator's observer (Dopri5 has no other way
// out). Thrown and caught within one function's call tree in dynamics/; never crosses a module.
struct CancelUnwind {};
inline void ThrowIfCancelled() {
  if (CancelRequested()) [[unlikely]]
    throw CancelUnwind{};
}

// The Status of an operation stopped by cancellation (nothing partial is returned with it).
Status CancelledStatus();

// SIGINT and SIGTERM → RequestCancel(), remembering the signal; `notice` (static storage, may be
// null) is written to stderr with write(2). A second signal while the first is being honoured ends
// the process at once with the default action. Installed with sigaction (SA_RESTART). A SIGINT that
// is ignored on entry (asynchronous commands of a shell script) is left ignored.
void InstallCancelSignalHandlers(const char* notice = nullptr);
// SIGINT and SIGTERM back to their default action (an ignored SIGINT stays ignored).
void RestoreDefaultSignalHandlers();
// The signal that requested cancellation; 0 when none did (or RequestCancel() was called directly).
int CancelSignal();
// Exit status of a command stopped by cancellation: 128 + the signal (130 for SIGINT, 143 for
// SIGTERM), 130 when no signal was involved.
int CancelExitStatus();

// Tests: clears the flag (and the remembered signal) on construction and again on destruction.
class ScopedCancelReset {
 public:
  ScopedCancelReset();
  ~ScopedCancelReset();
  ScopedCancelReset(const ScopedCancelReset&) = delete;
  ScopedCancelReset& operator=(const ScopedCancelReset&) = delete;
};

}  // namespace bistable

#endif  // BISTABLE_DYNAMICS_CANCEL_H_
