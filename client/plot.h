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
// gnuplot is an IoError with gnuplot's message (CheckGnuplot tells beforehand whether there is one).
// Figure conventions (titles, labels with symbols and units, fixed parameters in a subtitle,
// categorical legends, contours, sizes, formats): docs/figures.md. Callers should ignore SIGPIPE (client/main.cc does);
// the write to gnuplot blocks it in the calling thread regardless.
#ifndef BISTABLE_CLIENT_PLOT_H_
#define BISTABLE_CLIENT_PLOT_H_

#include <cmath>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "base/status.h"

namespace bistable {

struct PlotData {
  // The title: plain text shown literally, or gnuplot enhanced text when title_markup (MapFigure
  // builds it from the metric catalogue; any text from a file in it is escaped with EnhancedText).
  std::string title;
  bool title_markup = false;
  // Subtitle items (enhanced text, e.g. "η = 0.1"), joined with ", " and wrapped on a line or two
  // under the title: the fixed parameters and the slice's fixed axis values.
  std::vector<std::string> subtitle;
  std::string footer;  // plain text, small and grey in the bottom-left corner (provenance)
  std::string metric, unit;
  // The colour-bar (heatmap) or value-axis (curve) label, enhanced text ("FRF [dB]"); empty: the
  // metric name with its unit ("[unit]" only for a unit that is not "", "1" or "code").
  std::string value_label;
  std::vector<std::string> axis_names, axis_units;  // 1 (curve) or 2 (heatmap: x = axis 1, y = axis 0)
  std::vector<std::vector<double>> axis_values;
  std::vector<double> values;       // row-major over the axes; curves: one block per series
  std::vector<std::string> series;  // curves: a legend label per block (e.g. "up", "down")
  // Integer codes (motion, period, termination): one colour and one legend entry per code
  // (heatmaps: a legend of flat boxes beside the map), points on the code's row with the names on
  // the y axis (curves). Values not among the codes are drawn as missing. Empty: a continuous metric.
  struct Code {
    double value;
    std::string name, colour;  // colour "#rrggbb"; empty: the next of a qualitative palette
    bool at_least = false;     // the class of every value >= value (the tail of many periods)
  };
  std::vector<Code> codes;
  // Colour range (heatmaps of continuous metrics) shared with other maps; NaN: ColourRange of values.
  // Values beyond the range take its end colours and the figure says so under the plot, with
  // clip_reason when given (enhanced text).
  double cb_lo = NAN, cb_hi = NAN;
  std::string clip_reason;
  std::string cb_note;  // enhanced text under the plot about the colour scale ("shared by ...")
  // Heatmaps of continuous metrics: contour lines at these levels (e.g. 0 dB, the chaos threshold),
  // each with a legend entry below the plot.
  struct Contour {
    double level;
    std::string label;  // enhanced text
    std::string colour = "#000000";
    bool dashed = false;
  };
  std::vector<Contour> contours;
  // Heatmaps: curves (or points) in the axes' coordinates drawn over the map (e.g. fold curves of
  // harmonic balance), each with a legend entry (below the plot) unless its label is empty.
  struct Overlay {
    std::string label;
    std::vector<double> x, y;
    bool points = false;
    std::string colour = "#000000";
  };
  std::vector<Overlay> overlays;
  // Heatmaps: marked points (where measurements were taken), x on the horizontal axis (axis 1), y on the
  // vertical (axis 0), each drawn as a black-ringed white disc with a black centre (it reads on every
  // palette and code colour) and its label beside it: plain text (never markup), in a white box, on the
  // side of the point with room, wrapped to stay inside the plot area. Callers check them (client/map_marks.h:
  // finite, in the drawn range, labels bounded and printable); RenderPlot refuses marks on a curve.
  struct Mark {
    double x = 0, y = 0;
    std::string label;
  };
  std::vector<Mark> marks;
  // Heatmaps: at most this many cells drawn along each axis (every k-th grid value; the footer says
  // so), so a 1601 x 1601 map draws in a second; 0: every value.
  int max_cells = 600;
};

// format: "png", "svg" or "pdf" (from the output's extension when empty).
Status RenderPlot(const PlotData& d, const std::string& out_path, std::string format = "");

// The figure format of an output path by its extension: "svg", "pdf", else "png".
std::string PlotFormatOf(const std::string& out_path);

// `text` shown literally inside gnuplot enhanced text (its markup characters ^ _ @ & ~ { } \ escaped).
std::string EnhancedText(const std::string& text);

// A parameter or axis name as a symbol in enhanced text ("eta_r" → "η_r", "k_lin" → "k_{lin}"); a
// name not in the table is shown literally.
std::string SymbolOf(const std::string& name);

// A unit as stored (AxisUnit's or a map file's unit_label: "delta_s/tau", "1/tau", "N s/m^3") as
// enhanced text with symbols ("δ_s/τ"); "" for "", "1" and "code".
std::string UnitMarkup(const std::string& unit);

// "η = 0.1" (PlotNumber) with the unit when it is dimensional ("m_m = 0.0123 kg").
std::string ParameterItem(const std::string& name, double value, const std::string& unit);

// The colour range of a continuous metric's heatmap: symmetric about 0 for the diverging metrics
// (frf_db: attenuation blue, amplification red; lle: stable blue, chaotic red), [min, max] otherwise.
// Give it the values of every map meant to be compared to share one range.
std::pair<double, double> ColourRange(const std::string& metric, const std::vector<double>& values);

// The range a heatmap draws a (strictly increasing) axis over: from half a grid step before its first value
// to half a step beyond its last, the edges of its end cells. {NaN, NaN} for no values.
std::pair<double, double> HeatmapAxisRange(const std::vector<double>& values);

// A number for titles and legends: 4 significant digits (1/3 → "0.3333", 3 → "3").
std::string PlotNumber(double v);

// Ok when an executable gnuplot is on PATH; otherwise FailedPrecondition saying so and how to get it.
Status CheckGnuplot();

// Fig. 6: for each Ω (x) the spectral peak frequencies (y) with amplitudes (point size/colour).
struct ScatterData {
  std::string title;
  std::vector<double> x, y, amp;
};
Status RenderHdScatter(const ScatterData& d, const std::string& out_path);

// Continuation branches (amplitude vs parameter): each branch piece named (e.g. "+well", "-well",
// "interwell"; one colour per name), stable runs solid, unstable dashed, folds marked; the legend (below
// the plot) has one entry per name drawn, "unstable (dashed)" when an unstable run is, "fold" when a fold is.
// Further markers (period doublings, Neimark–Sacker points, cusps) with their own legend entries.
// Optional extra points (e.g. the one-harmonic closed form) in grey. With stability = false every
// curve is solid and its legend entry is its name alone (curves that are not orbits: fold curves).
struct BranchPlot {
  std::string title, x_name, x_unit, y_label;  // y_label: enhanced text
  bool title_markup = false;                   // the title is enhanced text (else shown literally)
  std::vector<std::string> subtitle;           // enhanced text items (the fixed parameters)
  struct Branch {
    std::string name;
    double width = 2;  // line width (a wider curve drawn first stays visible under one it coincides with)
    std::vector<double> x, y;
    std::vector<bool> stable;
    std::vector<double> fold_x, fold_y;
  };
  std::vector<Branch> branches;
  struct Marker {
    std::string label;   // legend entry (one per marker set that has points)
    int point_type = 7;  // gnuplot pt
    std::string colour;  // "#rrggbb"
    std::vector<double> x, y;
  };
  std::vector<Marker> markers;
  bool stability = true;
  std::vector<double> extra_x, extra_y;
  std::string extra_label;
};
Status RenderBranches(const BranchPlot& d, const std::string& out_path);

// Bifurcation diagram (paper Fig. 4): turning points of y_m against the continued parameter, the
// upward sweep and the downward sweep overlaid so hysteresis shows.
struct BifurcationData {
  std::string title, x_name, x_unit;
  bool title_markup = false;
  std::vector<std::string> subtitle;  // enhanced text items (the fixed parameters)
  std::string footer;                 // plain text (the sweep's name and id)
  std::vector<double> x_up, y_up, x_down, y_down;
};
Status RenderBifurcation(const BifurcationData& d, const std::string& out_path);

// Frequency-sweep FRF (paper Figs. 23–24), three rows over frequency: the averaged Fourier amplitudes
// of input and output (mag_label names the quantity and its unit), the FRF in dB (Welch H1 in colour,
// only where the coherence is at least kChirpCoherenceMin: elsewhere the input has too little energy
// for a ratio, over the raw single-FFT ratio in a light tint), and the coherence γ² in [0, 1] with the
// threshold; one colour per curve, named once (row 1).
inline constexpr double kChirpCoherenceMin = 0.5;
struct ChirpFrfPlot {
  std::string title, freq_label, mag_label;
  struct Curve {
    std::string label;
    std::vector<double> freq, in_mag, out_mag, db, coherence;  // Welch bins
    std::vector<double> raw_freq, raw_db;                      // the raw ratio (optional)
  };
  std::vector<Curve> curves;
};
Status RenderChirpFrf(const ChirpFrfPlot& d, const std::string& out_path);

// Spectrogram: time × frequency of the response (freq_label names it: the output's frequency, not
// the forcing's), magnitude in dB re the largest (colour).
struct SpectrogramPlot {
  std::string title, time_label, freq_label;
  std::vector<double> time, freq;
  std::vector<std::vector<double>> db;  // [time][freq]
};
Status RenderSpectrogram(const SpectrogramPlot& d, const std::string& out_path);

// Panels of curves or point clouds in a grid (multiplot): residual-force surfaces, measured vs
// simulated time histories, Poincaré sections. Series labels and titles are plain text.
struct PanelPlot {
  std::string title;
  int rows = 1, cols = 1;
  int panel_width = 520, panel_height = 400;  // pixels of one panel (PNG; SVG the same units)
  struct Series {
    std::string label;
    std::vector<double> x, y;
    bool points = false;       // point cloud (else a line)
    std::string colour;        // "#rrggbb"; empty: automatic
    double point_size = 0.25;  // points: gnuplot's pointsize of pt 7 (filled circle)
  };
  struct Panel {
    std::string title, x_label, y_label;
    std::vector<Series> series;
    double y_lo = NAN, y_hi = NAN;  // y range (e.g. shared by panels to compare); NaN: automatic
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
