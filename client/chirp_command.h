// `bistable chirp`: frequency sweeps with FFT-based FRF and spectrograms.
#ifndef BISTABLE_CLIENT_CHIRP_COMMAND_H_
#define BISTABLE_CLIENT_CHIRP_COMMAND_H_

#include <string>

#include <CLI/CLI.hpp>

#include "client/plot.h"
#include "dynamics/chirp.h"

namespace bistable {
void AddChirpCommand(CLI::App& app, int* exit_code);

// One sweep of a record for the FRF figure: the Welch H1 estimate with its coherence and averaged
// amplitudes (WelchH1, default segments) and the raw single-FFT ratio (FftFrf) behind it, over [lo, hi].
ChirpFrfPlot::Curve ChirpCurve(const std::string& label, const ChirpRecord& rec, double lo, double hi, bool hz);

// The FRF figure's labels: frequency in Hz (dimensional) or rad/τ, amplitudes of absolute velocities
// in m/s or δs·ωn.
ChirpFrfPlot ChirpFigure(const std::string& title, bool hz);
}  // namespace bistable

#endif  // BISTABLE_CLIENT_CHIRP_COMMAND_H_
