#include "client/plot.h"

#include <sys/wait.h>

#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>

namespace bistable {
namespace {

std::string Quote(const std::string& s) {
  std::string out = "\"";
  for (char c : s) {
    if (c == '"' || c == '\\') out += '\\';
    out += c;
  }
  return out + "\"";
}

std::string Greek(const std::string& name) {
  if (name == "alpha") return "{/Symbol a}";
  if (name == "omega") return "{/Symbol W}";
  if (name == "eta") return "{/Symbol h}";
  if (name == "eta_r") return "{/Symbol h}_r";
  if (name == "lambda") return "{/Symbol l}";
  if (name == "phi") return "{/Symbol f}";
  if (name == "eps") return "{/Symbol e}";
  return name;
}

// Runs gnuplot with the script on stdin; the file appears atomically (written beside, then renamed).
Status RunGnuplot(const std::string& script, const std::string& out_path) {
  const std::string tmp = out_path + ".tmp";
  const std::string log = out_path + ".log";
  const std::string cmd = "gnuplot > /dev/null 2> " + Quote(log);
  FILE* p = ::popen(cmd.c_str(), "w");
  if (!p) return Status::IoError("plot", "cannot start gnuplot (install gnuplot-nox: scripts/setup.sh)");
  std::string full = "set output " + Quote(tmp) + "\n" + script + "\nunset output\n";
  std::fwrite(full.data(), 1, full.size(), p);
  const int rc = ::pclose(p);
  std::string messages;
  {
    std::ifstream in(log);
    messages.assign(std::istreambuf_iterator<char>(in), {});
  }
  std::filesystem::remove(log);
  if (rc != 0 || !std::filesystem::exists(tmp) || std::filesystem::file_size(tmp) == 0) {
    std::filesystem::remove(tmp);
    return Status::IoError("plot", "gnuplot failed writing '" + out_path + "' (exit " + std::to_string(WEXITSTATUS(rc)) +
                                       "): " + messages.substr(0, 400));
  }
  std::error_code ec;
  std::filesystem::rename(tmp, out_path, ec);
  if (ec) return Status::IoError("plot", "rename to '" + out_path + "': " + ec.message());
  return Status::Ok();
}

// Viridis (perceptually uniform, colour-blind safe) as gnuplot 5.4 lacks it built in.
constexpr const char* kViridis =
    "set palette defined (0 '#440154', 0.125 '#46327e', 0.25 '#365c8d', 0.375 '#277f8e', 0.5 '#1fa187', "
    "0.625 '#4ac16d', 0.75 '#a0da39', 0.875 '#d0e11c', 1 '#fde725')\n";

std::string Terminal(const std::string& format) {
  return format == "svg" ? "set terminal svg size 900,700 dynamic enhanced font 'Helvetica,14' background 'white'\n"
                         : "set terminal pngcairo size 900,700 enhanced font 'Helvetica,12'\n";
}

std::string Num(double v) {
  if (!std::isfinite(v)) return "NaN";
  char b[32];
  std::snprintf(b, sizeof b, "%.9g", v);
  return b;
}

}  // namespace

std::string AxisLabel(const std::string& name, const std::string& unit) {
  if (name == "a0_mm") return "base amplitude A_0 [mm]";
  if (name == "f0_hz") return "base frequency f_0 [Hz]";
  // Units as stored (plain text) → gnuplot enhanced text with symbols.
  std::string u = unit;
  const std::pair<const char*, const char*> kSubs[] = {
      {"delta_s", "{/Symbol d}_s"}, {"omega_n", "{/Symbol w}_n"}, {"omega0", "{/Symbol w}_0"}, {"omega_r", "{/Symbol w}_r"},
      {"A0", "A_0"},        {"m_m", "m_m"},         {"m_r", "m_r"},          {"c_r", "c_r"}};
  for (auto [from, to] : kSubs)
    for (size_t p = u.find(from); p != std::string::npos; p = u.find(from, p + std::strlen(to))) u.replace(p, std::strlen(from), to);
  return Greek(name) + (u.empty() ? "" : " = " + u);
}

Status RenderPlot(const PlotData& d, const std::string& out_path, std::string format) {
  if (format.empty()) format = std::filesystem::path(out_path).extension() == ".svg" ? "svg" : "png";
  if (format != "png" && format != "svg")
    return Status::InvalidArgument("format", "format = '" + format + "' violates format in {png, svg}");
  std::ostringstream s;
  s << Terminal(format) << "set title " << Quote(d.title) << " noenhanced\n";
  s << "set xlabel " << Quote(AxisLabel(d.axis_names.back(), d.axis_units.back())) << "\n";
  if (d.axis_names.size() == 2) {
    s << "set ylabel " << Quote(AxisLabel(d.axis_names[0], d.axis_units[0])) << "\n";
    s << "set cblabel " << Quote(d.metric + (d.unit.empty() ? "" : " [" + d.unit + "]")) << " noenhanced\n";
    s << "set datafile missing 'NaN'\nset tics out\nset key off\n";
    const auto& ys = d.axis_values[0];
    const auto& xs = d.axis_values[1];
    s << "set xrange [" << Num(xs.front()) << ":" << Num(xs.back()) << "]\n";
    s << "set yrange [" << Num(ys.front()) << ":" << Num(ys.back()) << "]\n";
    if (d.motion) {
      // Discrete: each code owns one unit-wide band of the colour box.
      s << "set palette defined (-1.5 'gray', -0.5 'gray', -0.5 '#2c7bb6', 0.5 '#2c7bb6', 0.5 '#fdae61', 1.5 '#fdae61', "
           "1.5 '#d7191c', 2.5 '#d7191c')\nset cbrange [-1.5:2.5]\n"
           "set cbtics ('undefined' -1, 'intrawell' 0, 'interwell' 1, 'chaotic' 2)\n";
    } else if (d.metric == "frf_db") {
      // Diverging palette centred on 0 dB: attenuation blue, amplification red.
      double lo = 0, hi = 0;
      for (double v : d.values)
        if (std::isfinite(v)) lo = std::min(lo, v), hi = std::max(hi, v);
      const double m = std::max(std::fabs(lo), std::fabs(hi));
      s << "set palette defined (-1 '#2166ac', 0 'white', 1 '#b2182b')\nset cbrange [" << Num(-m) << ":" << Num(m) << "]\n";
    } else if (d.metric == "lle") {
      s << "set palette defined (-1 '#2166ac', 0 'white', 1 '#b2182b')\n";
      double m = 0;
      for (double v : d.values)
        if (std::isfinite(v)) m = std::max(m, std::fabs(v));
      s << "set cbrange [" << Num(-m) << ":" << Num(m) << "]\n";
    } else {
      s << kViridis;
    }
    // Image with pixel centres at the axis values (non-uniform axes: gnuplot's image needs uniform
    // spacing, so use pm3d map which draws quadrilaterals between the given coordinates).
    s << "set view map\nset pm3d map corners2color c1\nset pm3d interpolate 1,1\n";
    s << "$data << EOD\n";
    for (size_t i = 0; i < ys.size(); ++i) {
      for (size_t j = 0; j < xs.size(); ++j)
        s << Num(xs[j]) << " " << Num(ys[i]) << " " << Num(d.values[i * xs.size() + j]) << "\n";
      s << "\n";
    }
    s << "EOD\nsplot $data using 1:2:3 with pm3d\n";
  } else {
    s << "set ylabel " << Quote(d.metric + (d.unit.empty() ? "" : " [" + d.unit + "]")) << " noenhanced\nset grid\nset key off\n";
    s << "$data << EOD\n";
    for (size_t j = 0; j < d.axis_values[0].size(); ++j) s << Num(d.axis_values[0][j]) << " " << Num(d.values[j]) << "\n";
    s << "EOD\nplot $data using 1:2 with linespoints pt 7 ps 0.5 lw 1.5\n";
  }
  return RunGnuplot(s.str(), out_path);
}

Status RenderBranches(const BranchPlot& d, const std::string& out_path) {
  std::ostringstream s;
  s << Terminal(std::filesystem::path(out_path).extension() == ".svg" ? "svg" : "png");
  s << "set title " << Quote(d.title) << " noenhanced\n";
  s << "set xlabel " << Quote(AxisLabel(d.x_name, d.x_unit)) << "\n";
  s << "set ylabel " << Quote(d.y_label) << "\nset grid\nset key top left\n";
  // One data block per branch; each stable/unstable run is its own segment (blank line between).
  std::string plot = "plot ";
  const char* colours[] = {"#1b9e77", "#d95f02", "#7570b3", "#e7298a", "#66a61e", "#e6ab02", "#a6761d", "#666666"};
  for (size_t b = 0; b < d.branches.size(); ++b) {
    const auto& br = d.branches[b];
    for (int stable = 1; stable >= 0; --stable) {
      s << "$b" << b << "s" << stable << " << EOD\n";
      for (size_t i = 0; i < br.x.size(); ++i) {
        const bool in = br.stable[i] == static_cast<bool>(stable);
        const bool next_in = i + 1 < br.x.size() && br.stable[i + 1] == static_cast<bool>(stable);
        if (in || next_in) s << Num(br.x[i]) << " " << Num(br.y[i]) << "\n";
        if (in && !next_in) s << "\n";
      }
      s << "EOD\n";
      plot += "$b" + std::to_string(b) + "s" + std::to_string(stable) + " using 1:2 with lines lw 2 dt " +
              (stable ? "1" : "2") + " lc rgb '" + colours[b % 8] + "' title " +
              Quote(b == 0 ? (stable ? "stable" : "unstable") : "") + ", ";
    }
    if (!br.fold_x.empty()) {
      s << "$f" << b << " << EOD\n";
      for (size_t i = 0; i < br.fold_x.size(); ++i) s << Num(br.fold_x[i]) << " " << Num(br.fold_y[i]) << "\n";
      s << "EOD\n";
      plot += "$f" + std::to_string(b) + " using 1:2 with points pt 9 ps 1.2 lc rgb 'black' title " + Quote(b == 0 ? "fold" : "") + ", ";
    }
  }
  if (!d.extra_x.empty()) {
    s << "$extra << EOD\n";
    for (size_t i = 0; i < d.extra_x.size(); ++i) s << Num(d.extra_x[i]) << " " << Num(d.extra_y[i]) << "\n";
    s << "EOD\n";
    plot += "$extra using 1:2 with points pt 7 ps 0.3 lc rgb '#999999' title " + Quote(d.extra_label) + ", ";
  }
  if (plot.size() > 5) plot.resize(plot.size() - 2);
  s << plot << "\n";
  return RunGnuplot(s.str(), out_path);
}

Status RenderPanels(const PanelPlot& d, const std::string& out_path) {
  if (d.panels.empty()) return Status::InvalidArgument("plot", "no panels to plot");
  std::ostringstream s;
  const int w = 520 * d.cols, h = 400 * d.rows + 40;
  s << (std::filesystem::path(out_path).extension() == ".svg"
            ? "set terminal svg size " + std::to_string(w) + "," + std::to_string(h) + " dynamic noenhanced font 'Helvetica,13' background 'white'\n"
            : "set terminal pngcairo size " + std::to_string(w) + "," + std::to_string(h) + " noenhanced font 'Helvetica,11'\n");
  s << "set multiplot layout " << d.rows << "," << d.cols << " title " << Quote(d.title) << "\n";
  s << "set grid\nset key top left\nset datafile missing 'NaN'\n";
  int block = 0;
  for (const PanelPlot::Panel& p : d.panels) {
    s << "set title " << Quote(p.title) << "\nset xlabel " << Quote(p.x_label) << "\nset ylabel " << Quote(p.y_label) << "\n";
    std::string plot = "plot ";
    for (const PanelPlot::Series& se : p.series) {
      const std::string name = "$b" + std::to_string(block++);
      s << name << " << EOD\n";
      for (size_t i = 0; i < se.x.size() && i < se.y.size(); ++i) s << Num(se.x[i]) << " " << Num(se.y[i]) << "\n";
      s << "EOD\n";
      plot += name + " using 1:2 with " + (se.points ? "points pt 7 ps 0.25" : "lines lw 1.2") +
              (se.colour.empty() ? "" : " lc rgb " + Quote(se.colour)) + " title " + Quote(se.label) + ", ";
    }
    if (p.series.empty()) plot += "NaN notitle, ";
    plot.resize(plot.size() - 2);
    s << plot << "\n";
  }
  s << "unset multiplot\n";
  return RunGnuplot(s.str(), out_path);
}

Status RenderBifurcation(const BifurcationData& d, const std::string& out_path) {
  std::ostringstream s;
  s << Terminal(std::filesystem::path(out_path).extension() == ".svg" ? "svg" : "png");
  s << "set title " << Quote(d.title) << " noenhanced\n";
  s << "set xlabel " << Quote(AxisLabel(d.x_name, d.x_unit)) << "\n";
  s << "set ylabel " << Quote("y_m at y_m' = 0 [{/Symbol d}_s]") << "\nset grid\nset key top left\n";
  std::string plot = "plot ";
  if (!d.x_up.empty()) {
    s << "$up << EOD\n";
    for (size_t i = 0; i < d.x_up.size(); ++i) s << Num(d.x_up[i]) << " " << Num(d.y_up[i]) << "\n";
    s << "EOD\n";
    plot += "$up using 1:2 with points pt 7 ps 0.15 lc rgb '#2166ac' title 'increasing', ";
  }
  if (!d.x_down.empty()) {
    s << "$down << EOD\n";
    for (size_t i = 0; i < d.x_down.size(); ++i) s << Num(d.x_down[i]) << " " << Num(d.y_down[i]) << "\n";
    s << "EOD\n";
    plot += "$down using 1:2 with points pt 7 ps 0.15 lc rgb '#b2182b' title 'decreasing', ";
  }
  if (plot.size() == 5) return Status::InvalidArgument("plot", "no turning points to plot");
  plot.resize(plot.size() - 2);
  s << plot << "\n";
  return RunGnuplot(s.str(), out_path);
}

Status RenderChirpFrf(const ChirpFrfPlot& d, const std::string& out_path) {
  std::ostringstream s;
  s << (std::filesystem::path(out_path).extension() == ".svg"
            ? "set terminal svg size 900,900 dynamic enhanced font 'Helvetica,14' background 'white'\n"
            : "set terminal pngcairo size 900,900 enhanced font 'Helvetica,12'\n");
  const char* colours[] = {"#2166ac", "#b2182b"};
  for (size_t c = 0; c < d.curves.size(); ++c) {
    s << "$c" << c << " << EOD\n";
    for (size_t i = 0; i < d.curves[c].freq.size(); ++i)
      s << Num(d.curves[c].freq[i]) << " " << Num(d.curves[c].in_mag[i]) << " " << Num(d.curves[c].out_mag[i]) << " "
        << Num(d.curves[c].db[i]) << "\n";
    s << "EOD\n";
  }
  s << "set multiplot layout 2,1 title " << Quote(d.title) << " noenhanced\nset grid\nset key top right\n";
  s << "set ylabel 'Fourier magnitude' noenhanced\nset logscale y\nunset xlabel\nplot ";
  for (size_t c = 0; c < d.curves.size(); ++c)
    s << (c ? ", " : "") << "$c" << c << " using 1:2 with lines lw 1 lc rgb '#999999' title " << Quote(c ? "" : "input")
      << ", $c" << c << " using 1:3 with lines lw 1.5 lc rgb '" << colours[c % 2] << "' title " << Quote("output " + d.curves[c].label);
  s << "\nunset logscale y\nset xlabel " << Quote(d.freq_label) << "\nset ylabel 'FRF [dB]'\n";
  s << "plot 0 with lines dt 2 lc rgb 'black' notitle";
  for (size_t c = 0; c < d.curves.size(); ++c)
    s << ", $c" << c << " using 1:4 with lines lw 1.5 lc rgb '" << colours[c % 2] << "' title " << Quote(d.curves[c].label);
  s << "\nunset multiplot\n";
  return RunGnuplot(s.str(), out_path);
}

Status RenderSpectrogram(const SpectrogramPlot& d, const std::string& out_path) {
  if (d.time.empty() || d.freq.empty()) return Status::InvalidArgument("spectrogram", "the record is shorter than one window");
  std::ostringstream s;
  s << Terminal(std::filesystem::path(out_path).extension() == ".svg" ? "svg" : "png");
  s << "set title " << Quote(d.title) << " noenhanced\nset xlabel " << Quote(d.time_label) << "\nset ylabel "
    << Quote(d.freq_label) << "\nset cblabel 'magnitude [dB re max]'\nset cbrange [-80:0]\n" << kViridis;
  s << "set view map\nset pm3d map corners2color c1\nset xrange [" << Num(d.time.front()) << ":" << Num(d.time.back())
    << "]\nset yrange [0:" << Num(d.freq.back()) << "]\nset key off\n$data << EOD\n";
  for (size_t i = 0; i < d.time.size(); ++i) {
    for (size_t k = 0; k < d.freq.size(); ++k) s << Num(d.time[i]) << " " << Num(d.freq[k]) << " " << Num(std::max(-80.0, d.db[i][k])) << "\n";
    s << "\n";
  }
  s << "EOD\nsplot $data using 1:2:3 with pm3d\n";
  return RunGnuplot(s.str(), out_path);
}

Status RenderHdScatter(const ScatterData& d, const std::string& out_path) {
  std::ostringstream s;
  s << Terminal(std::filesystem::path(out_path).extension() == ".svg" ? "svg" : "png");
  s << "set title " << Quote(d.title) << " noenhanced\n";
  s << "set xlabel " << Quote(AxisLabel("omega", "omega0/omega_n")) << "\n";
  s << "set ylabel " << Quote("spectral peaks of y_m, {/Symbol W}_{peaks} [rad/{/Symbol t}]") << "\n";
  s << "set cblabel 'peak amplitude [delta_s]' noenhanced\nset logscale cb\nset key off\nset grid\n" << kViridis;
  double xmax = 0, ymax = 0;
  for (size_t i = 0; i < d.x.size(); ++i) xmax = std::max(xmax, d.x[i]), ymax = std::max(ymax, d.y[i]);
  s << "set xrange [0:" << Num(xmax * 1.02) << "]\nset yrange [0:" << Num(ymax * 1.05) << "]\n";
  s << "$data << EOD\n";
  for (size_t i = 0; i < d.x.size(); ++i) s << Num(d.x[i]) << " " << Num(d.y[i]) << " " << Num(d.amp[i]) << "\n";
  s << "EOD\n";
  // Integer multiples nΩ of the forcing (the paper's dashed lines).
  s << "plot for [n=1:8] n*x with lines dt 2 lc rgb '#999999' lw 1, $data using 1:2:3 with points pt 7 ps 0.6 lc palette\n";
  return RunGnuplot(s.str(), out_path);
}

}  // namespace bistable
