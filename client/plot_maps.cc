// RenderPlot (client/plot.h): a map slice as a heatmap over two axes (codes as flat colours with a
// legend, continuous metrics on a colour bar, contours and overlays on the map) or as curves over one.
#include "client/plot.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <functional>
#include <sstream>
#include <string>
#include <string_view>
#include <unordered_map>
#include <utility>
#include <vector>

#include "client/plot_internal.h"
#include "engine/metric_catalog.h"

namespace bistable {

using plot_internal::Decor;
using plot_internal::kQualitative;
using plot_internal::kViridis;
using plot_internal::Margins;
using plot_internal::Num;
using plot_internal::RunGnuplot;
using plot_internal::Terminal;
using plot_internal::VisibleLength;
using plot_internal::WriteCells;
using plot_internal::WriteDecor;

namespace {

// Index of the code whose value is v, or -1.
int CodeIndex(const std::vector<PlotData::Code>& codes, double v) {
  for (size_t i = 0; i < codes.size(); ++i)
    if (codes[i].value == v || (codes[i].at_least && v >= codes[i].value)) return static_cast<int>(i);
  return -1;
}

// The colour of code i: its own, or the next of the qualitative palette.
std::string CodeColour(const std::vector<PlotData::Code>& codes, size_t i) {
  size_t automatic = 0;
  for (size_t k = 0; k < i; ++k) automatic += codes[k].colour.empty();
  return codes[i].colour.empty() ? kQualitative[automatic % 12] : codes[i].colour;
}

// Code i owns the colour band [i, i+1] of a palette over [0, K] (drawn at i + 0.5).
std::string CodePalette(const std::vector<PlotData::Code>& codes) {
  std::ostringstream s;
  s << "set palette defined (";
  for (size_t i = 0; i < codes.size(); ++i) {
    const std::string c = CodeColour(codes, i);
    s << (i ? ", " : "") << i << " " << GnuplotString(c) << ", " << i + 1 << " " << GnuplotString(c);
  }
  s << ")\nset palette maxcolors " << codes.size() << "\nset cbrange [0:" << codes.size() << "]\n";
  return s.str();
}

// Every k-th index of n (k the smallest step leaving at most max_cells), the last always kept so
// the drawn map spans the axis; every index when max_cells <= 0.
std::vector<size_t> Decimate(size_t n, int max_cells) {
  std::vector<size_t> keep;
  const size_t step = max_cells <= 0 || n <= static_cast<size_t>(max_cells)
                          ? 1
                          : (n + static_cast<size_t>(max_cells) - 1) / static_cast<size_t>(max_cells);
  for (size_t i = 0; i < n; i += step) keep.push_back(i);
  if (keep.back() != n - 1) keep.push_back(n - 1);
  return keep;
}

// Marching squares: the level set value == level over the grid (x index i, y index j) as polylines,
// each followed by two blank lines (splot joins scans of equal length into a mesh when one blank line
// separates them); cells with a NaN corner are skipped. The cells' segments are chained through the
// grid edges they share, so a dashed line keeps its pattern along the curve.
std::string ContourLines(const std::vector<double>& xs, const std::vector<double>& ys,
                         const std::function<double(size_t, size_t)>& value, double level, size_t* count) {
  *count = 0;
  if (xs.size() < 2 || ys.size() < 2) return "";
  const size_t nx = xs.size();
  struct Seg {
    size_t e[2];  // grid edge ids: 2 (j nx + i) for (i, j)-(i+1, j), 2 (j nx + i) + 1 for (i, j)-(i, j+1)
    double x[2], y[2];
  };
  std::vector<Seg> segs;
  for (size_t j = 0; j + 1 < ys.size(); ++j)
    for (size_t i = 0; i + 1 < nx; ++i) {
      const double v[4] = {value(i, j), value(i + 1, j), value(i + 1, j + 1), value(i, j + 1)};
      if (!std::isfinite(v[0]) || !std::isfinite(v[1]) || !std::isfinite(v[2]) || !std::isfinite(v[3])) continue;
      const double px[4] = {xs[i], xs[i + 1], xs[i + 1], xs[i]}, py[4] = {ys[j], ys[j], ys[j + 1], ys[j + 1]};
      const size_t edge[4] = {2 * (j * nx + i), 2 * (j * nx + i + 1) + 1, 2 * ((j + 1) * nx + i), 2 * (j * nx + i) + 1};
      struct Cut {
        size_t edge;
        double x, y;
      };
      std::vector<Cut> cut;  // crossings on the cell's edges, in edge order
      for (int e = 0; e < 4; ++e) {
        const int f = (e + 1) % 4;
        if ((v[e] >= level) == (v[f] >= level)) continue;
        const double t = (level - v[e]) / (v[f] - v[e]);
        cut.push_back({edge[e], px[e] + t * (px[f] - px[e]), py[e] + t * (py[f] - py[e])});
      }
      // Two crossings: one segment; four (a saddle): pair them by the cell's mean.
      if (cut.size() == 4 && (0.25 * (v[0] + v[1] + v[2] + v[3]) >= level) != (v[0] >= level))
        std::rotate(cut.begin(), cut.begin() + 1, cut.end());
      for (size_t k = 0; k + 1 < cut.size(); k += 2)
        segs.push_back({{cut[k].edge, cut[k + 1].edge}, {cut[k].x, cut[k + 1].x}, {cut[k].y, cut[k + 1].y}});
    }
  std::unordered_map<size_t, std::vector<size_t>> at_edge;
  for (size_t k = 0; k < segs.size(); ++k) at_edge[segs[k].e[0]].push_back(k), at_edge[segs[k].e[1]].push_back(k);
  std::vector<bool> used(segs.size(), false);
  std::ostringstream out;
  // From segment k's end `end`, follow unused segments through shared edges.
  auto walk = [&](size_t k, int end) {
    std::vector<std::pair<double, double>> pts;
    size_t edge = segs[k].e[end];
    for (;;) {
      size_t next = segs.size();
      for (size_t m : at_edge[edge])
        if (!used[m]) next = m;
      if (next == segs.size()) break;
      used[next] = true;
      const int from = segs[next].e[0] == edge ? 0 : 1;
      pts.emplace_back(segs[next].x[1 - from], segs[next].y[1 - from]);
      edge = segs[next].e[1 - from];
    }
    return pts;
  };
  for (size_t k = 0; k < segs.size(); ++k) {
    if (used[k]) continue;
    used[k] = true;
    std::vector<std::pair<double, double>> back = walk(k, 0), fwd = walk(k, 1);
    std::reverse(back.begin(), back.end());
    back.emplace_back(segs[k].x[0], segs[k].y[0]);
    back.emplace_back(segs[k].x[1], segs[k].y[1]);
    back.insert(back.end(), fwd.begin(), fwd.end());
    for (const auto& [x, y] : back) out << Num(x) << " " << Num(y) << "\n";
    out << "\n\n";
    ++*count;
  }
  return out.str();
}

// The index (0..K-1) at which a coded value is drawn, one unit-wide colour band / y row each; NaN
// for a value no code names.
double Coded(const std::vector<PlotData::Code>& codes, double v) {
  const int i = std::isfinite(v) ? CodeIndex(codes, v) : -1;
  return i < 0 ? std::nan("") : static_cast<double>(i);
}

// The size of RenderPlot's figures in pixels.
constexpr int kWidth = 900, kHeight = 700;

// A heatmap's colours: the codes' palette (the legend beside the map drawn later), or a continuous
// palette over the colour range with a note on the values beyond it. Returns the pixels right of the map.
int WriteColourScale(std::ostream& s, const PlotData& d, const std::string& unit, const std::string& label,
                     Decor* decor) {
  const auto& codes = d.codes;
  int right_px = 170;
  std::pair<double, double> range{0, 1};
  if (!codes.empty()) {
    // Discrete: code i owns the colour band [i, i+1] and is drawn at i + 0.5; the legend beside the
    // map is one flat box per code with its name (no colour bar: no scale between codes).
    size_t longest = VisibleLength(label);
    for (const auto& c : codes) longest = std::max(longest, c.name.size());
    right_px = std::clamp(static_cast<int>(60 + 7.5 * static_cast<double>(longest)), 150, 360);
    s << CodePalette(codes) << "unset colorbox\n";
  } else {
    range = ColourRange(d.metric, d.values);
    if (std::isfinite(d.cb_lo) && std::isfinite(d.cb_hi) && d.cb_lo < d.cb_hi) range = {d.cb_lo, d.cb_hi};
    if (DivergesAboutZero(d.metric))  // blue below 0, red above
      s << "set palette defined (-1 '#2166ac', 0 'white', 1 '#b2182b')\n";
    else
      s << kViridis;
    s << "set cbrange [" << Num(range.first) << ":" << Num(range.second) << "]\n";
    s << "set cblabel " << GnuplotString(label) << " enhanced\n";
    // Values beyond the range take its end colours: say so, and how far they go.
    double above = -INFINITY, below = INFINITY;
    for (double v : d.values)
      if (std::isfinite(v)) above = std::max(above, v), below = std::min(below, v);
    std::string clip;
    const std::string in_unit = unit.empty() ? "" : " " + unit;
    if (above > range.second * (1 + 1e-9) + 1e-12)
      clip = "values above " + PlotNumber(range.second) + in_unit + " (up to " + PlotNumber(above) + in_unit +
             ") are drawn in the top colour";
    if (below < range.first - std::fabs(range.first) * 1e-9 - 1e-12)
      clip += std::string(clip.empty() ? "values" : "; values") + " below " + PlotNumber(range.first) + in_unit +
              " (down to " + PlotNumber(below) + in_unit + ") in the bottom colour";
    if (!clip.empty()) decor->notes.push_back(clip + (d.clip_reason.empty() ? "" : ": " + d.clip_reason));
  }
  if (!d.cb_note.empty()) decor->notes.push_back(d.cb_note);
  return right_px;
}

// A heatmap's contours (continuous maps only) and overlays as data blocks; returns the splot items
// drawing them on the map's plane after the cells, and counts their legend entries in `keyed`.
std::string WriteContoursAndOverlays(std::ostream& s, const PlotData& d, const std::vector<double>& xs,
                                     const std::vector<double>& ys, const std::function<double(size_t, size_t)>& raw,
                                     int* keyed) {
  const auto& codes = d.codes;
  std::string more;
  for (size_t k = 0; k < d.contours.size() && codes.empty(); ++k) {
    const PlotData::Contour& c = d.contours[k];
    size_t n = 0;
    const std::string seg = ContourLines(xs, ys, raw, c.level, &n);
    if (n == 0) continue;  // nothing crosses the level: no line, no legend entry
    s << "$c" << k << " << EOD\n" << seg << "EOD\n";
    more += ", $c" + std::to_string(k) + " using 1:2:(0) with lines lw 1.6 dt " + (c.dashed ? "2" : "1") + " lc rgb " +
            GnuplotString(c.colour.empty() ? "#000000" : c.colour) + " title " + GnuplotString(c.label);
    *keyed += !c.label.empty();
  }
  for (size_t k = 0; k < d.overlays.size(); ++k) {
    const PlotData::Overlay& ov = d.overlays[k];
    s << "$o" << k << " << EOD\n";
    for (size_t i = 0; i < ov.x.size() && i < ov.y.size(); ++i) s << Num(ov.x[i]) << " " << Num(ov.y[i]) << "\n";
    s << "EOD\n";
    more += ", $o" + std::to_string(k) + " using 1:2:(0) with " +
            (ov.points ? "points pt 6 ps 2 lw 2" : "lines lw 2.5") + " lc rgb " +
            GnuplotString(ov.colour.empty() ? "#000000" : ov.colour) + " " +
            (ov.label.empty() ? std::string("notitle") : "title " + GnuplotString(EnhancedText(ov.label)));
    *keyed += !ov.label.empty();
  }
  return more;
}

// The plot area of a heatmap: its margins in pixels from the canvas' edges.
struct PlotArea {
  int left = 0, right = 0, bottom = 0, top = 0;
};

// A heatmap's frame: the decor centred over the map, the legend of contours and overlays below it,
// the margins, and on the right the colour box or the legend of codes (a heading when labelled).
PlotArea WriteHeatmapFrame(std::ostream& s, const PlotData& d, const std::string& label, const Decor& decor,
                           int right_px, int keyed) {
  const int w = kWidth, h = kHeight;
  const auto& codes = d.codes;
  int top_px = 0, bottom_px = 0;
  WriteDecor(s, decor, w, h, &top_px, &bottom_px, (100.0 + w - right_px) / (2.0 * w));
  const int key_px = keyed ? 26 : 0;
  const int plot_bottom = bottom_px + key_px + 78;
  if (keyed)
    s << "set key at screen " << Num(0.5) << ", " << Num(static_cast<double>(bottom_px + key_px) / h)
      << " center top horizontal enhanced samplen 3 spacing 1.1\n";
  s << Margins(w, h, 100, right_px, plot_bottom, top_px);
  if (codes.empty()) {
    char box[160];
    std::snprintf(box, sizeof box, "set colorbox user origin screen %.4f, %.4f size screen %.4f, %.4f\n",
                  1.0 - (right_px - 22.0) / w, static_cast<double>(plot_bottom) / h, 22.0 / w,
                  1.0 - static_cast<double>(top_px + plot_bottom) / h);
    s << box;
  } else {
    // The legend of codes: flat boxes and names, top down beside the map (a heading when labelled).
    const double x0 = 1.0 - (right_px - 22.0) / w, bw = 18.0 / w;
    double y = 1.0 - static_cast<double>(top_px) / h;
    const double step = std::min(24.0, (h - top_px - plot_bottom) / (codes.size() + 1.0)) / h;
    if (!d.value_label.empty()) {
      s << "set label 880 " << GnuplotString(label) << " at screen " << Num(x0) << ", " << Num(y - 0.4 * step)
        << " left enhanced\n";
      y -= step;
    }
    for (size_t i = 0; i < codes.size(); ++i) {
      const double yc = y - (i + 0.5) * step;
      s << "set object " << 800 + i << " rect from screen " << Num(x0) << ", " << Num(yc - 7.0 / h) << " to screen "
        << Num(x0 + bw) << ", " << Num(yc + 7.0 / h) << " fc rgb " << GnuplotString(CodeColour(codes, i))
        << " fs solid 1.0 border lc rgb '#555555' front\n";
      s << "set label " << 800 + i << " " << GnuplotString(codes[i].name) << " at screen " << Num(x0 + bw + 8.0 / w)
        << ", " << Num(yc) << " left noenhanced\n";
    }
  }
  return {100, right_px, plot_bottom, top_px};
}

// The width in pixels of plain text in the marks' font (Helvetica 11 as pngcairo draws it, roughly the same in
// SVG and PDF), from above: narrow, middle and wide ASCII letters as measured, other scripts generously (East
// Asian characters are about twice as wide as Latin ones; without a font for them cairo draws wider boxes still,
// which this does not promise to hold).
double TextPx(std::string_view text) {
  double px = 0;
  for (size_t i = 0; i < text.size();) {
    const unsigned char c = static_cast<unsigned char>(text[i]);
    const size_t len = c < 0x80 ? 1 : (c >> 5) == 6 ? 2 : (c >> 4) == 14 ? 3 : 4;
    if (len == 1)
      px += c == 0                                           ? 0.0
            : std::strchr(" !\"'(),-./:;[\\]`|*fijlrtIJ", c) ? 6.0
            : std::strchr("#%&+<=>@^~MOQWmw", c)             ? 15.0
            : c >= 'A' && c <= 'Z'                           ? 11.0
                                                             : 9.0;
    else
      px += len == 2 ? 11.0 : 18.0;  // Latin, Greek, Cyrillic ...; symbols and East Asian scripts
    i += len;
  }
  return px;
}

// Plain text in lines of at most `max_px` pixels (TextPx), broken at spaces; a longer word is cut between
// characters.
std::vector<std::string> WrapLabel(const std::string& text, double max_px) {
  std::vector<std::string> lines;
  std::string line;
  std::stringstream in(text);
  for (std::string word; std::getline(in, word, ' ');) {
    if (word.empty()) continue;
    while (TextPx(word) > max_px) {  // cut at a character boundary, at least one character a line
      if (!line.empty()) lines.push_back(line), line.clear();
      size_t cut = 0;
      do
        for (++cut; cut < word.size() && (static_cast<unsigned char>(word[cut]) & 0xC0) == 0x80;) ++cut;
      while (cut < word.size() && TextPx(std::string_view(word).substr(0, cut + 1)) <= max_px);
      lines.push_back(word.substr(0, cut));
      word.erase(0, cut);
    }
    if (word.empty()) continue;
    if (!line.empty() && TextPx(line + " " + word) > max_px) lines.push_back(line), line.clear();
    line += (line.empty() ? "" : " ") + word;
  }
  if (!line.empty()) lines.push_back(line);
  return lines;
}

// Marks over a heatmap whose drawn range is [xe.front(), xe.back()] x [ye.front(), ye.back()] in plot area
// `a`: a point each (a black ring, a white disc, a black centre: it reads on every palette and code colour),
// and its label as plain text in a white box beside it, on the side with room, wrapped to stay inside the
// plot area. Returns the splot items drawing the points.
std::string WriteMarks(std::ostream& s, const PlotData& d, const PlotArea& a, const std::vector<double>& xe,
                       const std::vector<double>& ye) {
  if (d.marks.empty()) return "";
  constexpr double kLinePx = 15.0, kGapPx = 12.0;  // font 11: a line's height, the text's distance from the point
  const double pw = kWidth - a.left - a.right, ph = kHeight - a.bottom - a.top;
  s << "set style textbox 1 opaque fillcolor rgb '#ffffff' border lc rgb '#000000' linewidth 1 margins 2,2\n";
  s << "$marks << EOD\n";
  for (const PlotData::Mark& m : d.marks) s << Num(m.x) << " " << Num(m.y) << "\n";
  s << "EOD\n";
  for (size_t i = 0; i < d.marks.size(); ++i) {
    const PlotData::Mark& m = d.marks[i];
    if (m.label.empty()) continue;
    const double px = a.left + (m.x - xe.front()) / (xe.back() - xe.front()) * pw;  // from the canvas' left
    const double py = a.top + (ye.back() - m.y) / (ye.back() - ye.front()) * ph;    // from the canvas' top
    const double room_right = kWidth - a.right - px - kGapPx - 6, room_left = px - a.left - kGapPx - 6;
    const bool right = TextPx(m.label) <= room_right || room_right >= room_left;
    std::string text;
    const std::vector<std::string> lines = WrapLabel(m.label, std::max(60.0, right ? room_right : room_left));
    for (const std::string& line : lines) text += (text.empty() ? "" : "\n") + line;
    if (text.empty()) continue;  // spaces alone
    // The lines centred on the point (gnuplot puts the first line at the position), inside the plot area.
    const double block = static_cast<double>(lines.size()) * kLinePx;
    const double first = std::clamp(py - (block - kLinePx) / 2, a.top + kLinePx / 2 + 3,
                                    std::max(a.top + kLinePx / 2 + 3, kHeight - a.bottom - block + kLinePx / 2 - 3));
    s << "set label " << 1000 + i << " " << GnuplotString(text) << " at screen "
      << Num((right ? px + kGapPx : px - kGapPx) / kWidth) << ", " << Num(1.0 - first / kHeight)
      << (right ? " left" : " right") << " front noenhanced boxed bs 1 font ',11' textcolor rgb '#000000'\n";
  }
  return ", $marks using 1:2:(0) with points pt 7 ps 2.1 lc rgb '#000000' notitle"
         ", $marks using 1:2:(0) with points pt 7 ps 1.4 lc rgb '#ffffff' notitle"
         ", $marks using 1:2:(0) with points pt 7 ps 0.35 lc rgb '#000000' notitle";
}

// A heatmap over two axes (y the first, x the second): the cells of every k-th value in big maps (the
// footer says so), its colours, contours, overlays and frame.
Status WriteHeatmap(std::ostream& s, const PlotData& d, const std::string& unit, const std::string& label,
                    Decor decor) {
  const auto& codes = d.codes;
  const auto& all_ys = d.axis_values[0];
  const auto& all_xs = d.axis_values[1];
  if (all_ys.empty() || all_xs.empty() || d.values.size() != all_xs.size() * all_ys.size())
    return Status::InvalidArgument("plot", "a heatmap needs one value per pair of axis values");
  // Big maps are drawn from every k-th value (the footer says so): gnuplot's time grows with the cells.
  const std::vector<size_t> kx = Decimate(all_xs.size(), d.max_cells), ky = Decimate(all_ys.size(), d.max_cells);
  std::vector<double> xs, ys;
  for (size_t i : kx) xs.push_back(all_xs[i]);
  for (size_t j : ky) ys.push_back(all_ys[j]);
  auto raw = [&](size_t i, size_t j) { return d.values[ky[j] * all_xs.size() + kx[i]]; };
  if (kx.size() < all_xs.size() || ky.size() < all_ys.size())
    decor.footer += (decor.footer.empty() ? "" : "  \xc2\xb7  ") + std::string("drawn from ") +
                    std::to_string(kx.size()) + " x " + std::to_string(ky.size()) + " of the " +
                    std::to_string(all_xs.size()) + " x " + std::to_string(all_ys.size()) + " grid values";
  s << "set ylabel " << GnuplotString(AxisLabel(d.axis_names[0], d.axis_units[0])) << "\n";
  s << "set tics out\nset key off\n";
  const int right_px = WriteColourScale(s, d, unit, label, &decor);
  // Contours and overlays: drawn on the map's plane after the cells, legend below the plot.
  int keyed = 0;
  std::string more = WriteContoursAndOverlays(s, d, xs, ys, raw, &keyed);
  const PlotArea area = WriteHeatmapFrame(s, d, label, decor, right_px, keyed);
  // Marks: over everything else, inside the drawn range (the cells' edges).
  const std::vector<double> xe = plot_internal::CellEdges(xs), ye = plot_internal::CellEdges(ys);
  const double sx = 1e-9 * (xe.back() - xe.front()), sy = 1e-9 * (ye.back() - ye.front());  // rounding at the edges
  for (const PlotData::Mark& m : d.marks)
    if (!(m.x >= xe.front() - sx && m.x <= xe.back() + sx && m.y >= ye.front() - sy && m.y <= ye.back() + sy))
      return Status::InvalidArgument("mark", "a mark at (" + PlotNumber(m.x) + ", " + PlotNumber(m.y) +
                                                 ") is outside the drawn range [" + PlotNumber(xe.front()) + ", " +
                                                 PlotNumber(xe.back()) + "] x [" + PlotNumber(ye.front()) + ", " +
                                                 PlotNumber(ye.back()) + "]");
  more += WriteMarks(s, d, area, xe, ye);
  auto cell = [&](size_t i, size_t j) {
    const double v = raw(i, j);
    return codes.empty() ? v : Coded(codes, v) + 0.5;
  };
  WriteCells(
      s, xs, ys, [&](size_t i, size_t j) { return cell(i, j); }, more);
  return Status::Ok();
}

// Curves over one axis, one per series, the legend below the plot; coded values as points in their
// code's row, a marker per series.
Status WriteCurves(std::ostream& s, const PlotData& d, const std::string& label, const Decor& decor) {
  const int w = kWidth, h = kHeight;
  const auto& codes = d.codes;
  const auto& xs = d.axis_values[0];
  const size_t n_series = std::max<size_t>(1, d.series.size());
  if (xs.empty() || d.values.size() != xs.size() * n_series)
    return Status::InvalidArgument("plot", "a curve needs one value per axis value and series");
  int top_px = 0, bottom_px = 0;
  // The series' legend goes below the plot, in one row: the plot keeps the canvas' width.
  const int left_px = codes.empty() ? 100 : 150, right_px = 40, key_px = d.series.empty() ? 0 : 26;
  WriteDecor(s, decor, w, h, &top_px, &bottom_px, (left_px + w - right_px) / (2.0 * w));
  s << Margins(w, h, left_px, right_px, bottom_px + key_px + 78, top_px);
  s << "set grid\n"
    << (d.series.empty() ? "set key off\n"
                         : "set key at screen 0.5, " + Num(static_cast<double>(bottom_px + key_px) / h) +
                               " center top horizontal Left reverse samplen 3 noenhanced\n");
  for (size_t k = 0; k < n_series; ++k) {
    // Codes: series side by side within the code's row, so up and down stay visible where they agree.
    const double offset = codes.empty() || n_series == 1 ? 0.0 : 0.24 * (static_cast<double>(k) - 0.5 * (n_series - 1));
    s << "$s" << k << " << EOD\n";
    for (size_t j = 0; j < xs.size(); ++j) {
      const double v = d.values[k * xs.size() + j];
      s << Num(xs[j]) << " " << Num(codes.empty() ? v : Coded(codes, v) + offset) << " "
        << Num(codes.empty() ? 0.0 : Coded(codes, v) + 0.5) << "\n";
    }
    s << "EOD\n";
  }
  const char* series_colours[] = {"#2166ac", "#b2182b", "#1b9e77", "#7570b3"};
  std::string plot = "plot ";
  if (!codes.empty()) {
    s << "set ylabel " << GnuplotString(label) << " enhanced\nset yrange [-0.6:" << codes.size() - 0.4
      << "]\nset ytics (";
    for (size_t i = 0; i < codes.size(); ++i)
      s << (i ? ", " : "") << GnuplotString(EnhancedText(codes[i].name)) << " " << i;
    s << ")\nset grid noytics\n";
    // Each point coloured by its code; a series' marker tells the sweep direction.
    s << CodePalette(codes) << "unset colorbox\n";
    const char* markers[] = {"7", "5", "9", "13"};
    for (size_t k = 0; k < n_series; ++k)
      plot +=
          "$s" + std::to_string(k) + " using 1:2:3 with points pt " + markers[k % 4] + " ps 0.8 lc palette notitle, ";
    // The legend tells series apart by marker (the colour is the code's): black samples.
    for (size_t k = 0; k < d.series.size(); ++k)
      plot += "NaN with points pt " + std::string(markers[k % 4]) + " ps 1.2 lc rgb 'black' title " +
              GnuplotString(d.series[k]) + ", ";
  } else {
    s << "set ylabel " << GnuplotString(label) << " enhanced\n";
    for (size_t k = 0; k < n_series; ++k)
      plot += "$s" + std::to_string(k) + " using 1:2 with linespoints pt 7 ps 0.5 lw 1.5 lc rgb '" +
              series_colours[k % 4] + "' title " + GnuplotString(d.series.empty() ? "" : d.series[k]) + ", ";
  }
  plot.resize(plot.size() - 2);
  s << plot << "\n";
  return Status::Ok();
}

}  // namespace

Status RenderPlot(const PlotData& d, const std::string& out_path, std::string format) {
  if (format.empty()) format = PlotFormatOf(out_path);
  if (format != "png" && format != "svg" && format != "pdf")
    return Status::InvalidArgument("format", "format = '" + format + "' violates format in {png, svg, pdf}");
  if (d.axis_names.empty() || d.axis_names.size() > 2 || d.axis_values.size() != d.axis_names.size() ||
      d.axis_units.size() != d.axis_names.size())
    return Status::InvalidArgument("plot", "a plot needs 1 or 2 axes with names, units and values");
  if (!d.marks.empty() && d.axis_names.size() != 2)
    return Status::InvalidArgument("mark", "marks are drawn on heatmaps (two axes), not on curves");
  const std::string unit = UnitMarkup(d.unit);
  const std::string label =
      !d.value_label.empty() ? d.value_label : EnhancedText(d.metric) + (unit.empty() ? "" : " [" + unit + "]");
  Decor decor{d.title, d.title_markup, d.subtitle, {}, d.footer};
  std::ostringstream s;
  s << Terminal(format, kWidth, kHeight);
  s << "set xlabel " << GnuplotString(AxisLabel(d.axis_names.back(), d.axis_units.back())) << "\n";
  s << "set datafile missing 'NaN'\n";
  const Status written =
      d.axis_names.size() == 2 ? WriteHeatmap(s, d, unit, label, decor) : WriteCurves(s, d, label, decor);
  if (!written.ok()) return written;
  return RunGnuplot(s.str(), out_path);
}

}  // namespace bistable
