// `bistable chirp`: frequency sweeps with FFT-based FRF and spectrograms.
#ifndef BISTABLE_CLIENT_CHIRP_COMMAND_H_
#define BISTABLE_CLIENT_CHIRP_COMMAND_H_

#include <CLI/CLI.hpp>

namespace bistable {
void AddChirpCommand(CLI::App& app, int* exit_code);
}  // namespace bistable

#endif  // BISTABLE_CLIENT_CHIRP_COMMAND_H_
