// Exit codes of every command-line program of the project (documented in README.md).
#ifndef BISTABLE_BASE_EXIT_CODES_H_
#define BISTABLE_BASE_EXIT_CODES_H_

namespace bistable {

inline constexpr int kExitOk = 0;
inline constexpr int kExitNotDone = 1;  // ran, but the answer is "no" (a sweep failed, a check disagreed)
inline constexpr int kExitError = 2;    // bad input or an error: the message names the field and the bound
// Stopped by a signal: 128 + the signal's number (130 for Ctrl-C, 143 for SIGTERM).
constexpr int ExitForSignal(int sig) { return 128 + sig; }

}  // namespace bistable

#endif  // BISTABLE_BASE_EXIT_CODES_H_
