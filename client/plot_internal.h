// What the figure writers of client/plot.cc (curves, branches, panels, chirp FRF, spectrograms) and
// client/plot_maps.cc (RenderPlot: heatmaps and curves of a map slice) share: running gnuplot, the
// terminal, the title/subtitle/notes/footer labels, margins, numbers, palettes and pm3d cells. Not
// part of the interface (client/plot.h is); only those two files include it.
#ifndef BISTABLE_CLIENT_PLOT_INTERNAL_H_
#define BISTABLE_CLIENT_PLOT_INTERNAL_H_

#include <cstddef>
#include <functional>
#include <ostream>
#include <string>
#include <vector>

#include "base/status.h"

namespace bistable::plot_internal {

// Runs gnuplot (no shell: an argument vector) with the script on a pipe to its stdin. gnuplot writes
// into a file this function created in the destination directory (its name chosen here, never the
// caller's path), which is renamed onto out_path when gnuplot succeeded: the plot appears atomically
// and the requested path never reaches the script.
Status RunGnuplot(const std::string& script, const std::string& out_path);

// Viridis (perceptually uniform, colour-blind safe) as gnuplot 5.4 lacks it built in.
inline constexpr const char* kViridis =
    "set palette defined (0 '#440154', 0.125 '#46327e', 0.25 '#365c8d', 0.375 '#277f8e', 0.5 '#1fa187', "
    "0.625 '#4ac16d', 0.75 '#a0da39', 0.875 '#d0e11c', 1 '#fde725')\n";

// A qualitative palette (ColorBrewer Dark2 and Set1, colour-blind aware in the first few) for codes
// and named branches.
inline constexpr const char* kQualitative[] = {"#1b9e77", "#d95f02", "#7570b3", "#e7298a", "#66a61e", "#e6ab02",
                                               "#a6761d", "#377eb8", "#e41a1c", "#984ea3", "#ff7f00", "#666666"};

// The terminal of a w x h pixel figure: PNG (pngcairo), SVG, or PDF (pdfcairo, 72 pixels to the inch,
// so a PDF looks like its PNG); UTF-8 text either way.
std::string Terminal(const std::string& format, int w = 900, int h = 700);

// The visible length of enhanced text, roughly (markup characters and UTF-8 continuation bytes not counted).
size_t VisibleLength(const std::string& text);

// Title, subtitle, notes and footer as labels at fixed places of the canvas (never outside it):
// the title centred at the top, the subtitle under it, notes and the footer at the bottom. Sets
// the pixels they take at the top and the bottom.
struct Decor {
  std::string title;
  bool title_markup = false;
  std::vector<std::string> subtitle, notes;  // enhanced text
  std::string footer;                        // plain text
};
void WriteDecor(std::ostream& s, const Decor& d, int w, int h, int* top_px, int* bottom_px, double centre = 0.5);

// Margins of the plot area at screen fractions from pixels (left, right, bottom, top).
std::string Margins(int w, int h, int l, int r, int b, int t);

// A number for a data block: "%.9g", or NaN when it is not finite.
std::string Num(double v);

// The cell edges of grid values v (strictly increasing) as WriteCells draws them: midpoints between
// values, half a step beyond the ends (a single value: a cell 2 % of its size wide).
std::vector<double> CellEdges(const std::vector<double>& v);

// A pm3d map in which every value owns a whole cell centred on its grid point (heatmaps, spectrograms):
// pm3d colours each quadrilateral by its first corner (c1), so the corners are the cell edges —
// midpoints between grid values, half a step beyond the ends — and edge (i, j) carries value(i, j);
// the last edges only close the cells. Writes the ranges, the data block and the splot. x and y are
// strictly increasing (axes, times, frequencies); pm3d takes uneven spacing, gnuplot's image does not.
void WriteCells(std::ostream& s, const std::vector<double>& xs, const std::vector<double>& ys,
                const std::function<double(size_t, size_t)>& value, const std::string& more_plots = "");

}  // namespace bistable::plot_internal

#endif  // BISTABLE_CLIENT_PLOT_INTERNAL_H_
