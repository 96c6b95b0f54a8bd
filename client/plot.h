// Figures through gnuplot (Debian's gnuplot-nox, pngcairo/svg terminals): heatmaps of a metric over
// two axes with axis labels, units, colorbar and title; curves over one axis; the harmonic-diffusion
// scatter of the paper's Fig. 6 (peak frequency vs Ω, point size by amplitude). Data go to gnuplot
// inline; nothing is rasterised here.
//
// Titles, labels and units may come from other users (a sweep's name, an HDF5 file received over the
// network), so no text is ever code: gnuplot runs from an argument vector (posix_spawnp, no shell),
// every string enters the script through GnuplotString, and the output path never enters the script
// (gnuplot writes a file created here in the destination directory, renamed onto the path). A
// destination directory that does not exist is InvalidArgument naming "out"; a missing or failing
// gnuplot is an IoError with gnuplot's message. Callers should ignore SIGPIPE (client/main.cc does);
// the write to gnuplot blocks it in the calling thread regardless.
#ifndef BISTABLE_CLIENT_PLOT_H_
#define BISTABLE_CLIENT_PLOT_H_

#include <string>
#include <string_view>
#include <vector>

#include "base/status.h"

namespace bistable {

struct PlotData {
  std::string title;
  std::string metric, unit;
  std::vector<std::string> axis_names, axis_units;  // 1 (curve) or 2 (heatmap: x = axis 1, y = axis 0)
  std::vector<std::vector<double>> axis_values;
  std::vector<double> values;                       // row-major over the axes
  bool motion = false;                              // discrete palette with named codes
};

// format: "png" or "svg" (from the output's extension when empty).
Status RenderPlot(const PlotData& d, const std::string& out_path, std::string format = "");

// Fig. 6: for each Ω (x) the spectral peak frequencies (y) with amplitudes (point size/colour).
struct ScatterData {
  std::string title;
  std::vector<double> x, y, amp;
};
Status RenderHdScatter(const ScatterData& d, const std::string& out_path);

// Continuation branches (amplitude vs parameter): stable segments solid, unstable dashed, folds
// marked; optional extra points (e.g. the one-harmonic closed form) in grey.
struct BranchPlot {
  std::string title, x_name, x_unit, y_label;
  struct Branch {
    std::vector<double> x, y;
    std::vector<bool> stable;
    std::vector<double> fold_x, fold_y;
  };
  std::vector<Branch> branches;
  std::vector<double> extra_x, extra_y;
  std::string extra_label;
};
Status RenderBranches(const BranchPlot& d, const std::string& out_path);

// Bifurcation diagram (paper Fig. 4): turning points of y_m against the continued parameter, the
// upward sweep and the downward sweep overlaid so hysteresis shows.
struct BifurcationData {
  std::string title, x_name, x_unit;
  std::vector<double> x_up, y_up, x_down, y_down;
};
Status RenderBifurcation(const BifurcationData& d, const std::string& out_path);

// Frequency-sweep FRF (paper Figs. 22–24): top, Fourier magnitudes of input and output; bottom,
// the FRF in dB; one curve per sweep direction.
struct ChirpFrfPlot {
  std::string title, freq_label;
  struct Curve {
    std::string label;
    std::vector<double> freq, in_mag, out_mag, db;
  };
  std::vector<Curve> curves;
};
Status RenderChirpFrf(const ChirpFrfPlot& d, const std::string& out_path);

// Spectrogram: time × frequency, magnitude in dB (colour).
struct SpectrogramPlot {
  std::string title, time_label, freq_label;
  std::vector<double> time, freq;
  std::vector<std::vector<double>> db;  // [time][freq]
};
Status RenderSpectrogram(const SpectrogramPlot& d, const std::string& out_path);

// Panels of curves or point clouds in a grid (multiplot): residual-force surfaces, measured vs
// simulated time histories. Series labels and titles are plain text.
struct PanelPlot {
  std::string title;
  int rows = 1, cols = 1;
  struct Series {
    std::string label;
    std::vector<double> x, y;
    bool points = false;   // point cloud (else a line)
    std::string colour;    // "#rrggbb"; empty: automatic
  };
  struct Panel {
    std::string title, x_label, y_label;
    std::vector<Series> series;
  };
  std::vector<Panel> panels;  // row-major
};
Status RenderPanels(const PanelPlot& d, const std::string& out_path);

// A label like "alpha = A0/delta_s" for axes, as gnuplot enhanced text: known axis names become
// symbols ({/Symbol a}); any other name is shown literally (its markup characters escaped). `unit` is
// markup from AxisUnit (engine/sweep_spec.h), not text from a file.
std::string AxisLabel(const std::string& name, const std::string& unit);

// `text` as a gnuplot double-quoted string literal (quotes included) that gnuplot reads back as
// exactly these bytes and never as code: bytes other than [A-Za-z0-9], space and . , _ - + = : / ( ) [ ] { }
// are written as 4-digit octal escapes "\0ooo" (gnuplot decodes escapes after backquote and macro
// substitution, so an escaped ` @ " \ or newline stays text). NUL bytes are dropped.
std::string GnuplotString(std::string_view text);

}  // namespace bistable

#endif  // BISTABLE_CLIENT_PLOT_H_
