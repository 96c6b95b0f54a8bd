#include "client/plot.h"

#include <fcntl.h>
#include <signal.h>
#include <spawn.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>

extern char** environ;

namespace bistable {

std::string GnuplotString(std::string_view text) {
  // Bytes that mean nothing to gnuplot's command-line processing inside a double-quoted string (no
  // escape, no end of string, no substitution, no command separator, no comment) are written as they
  // are; the rest as octal escapes. gnuplot 5.4 reads "\0" followed by up to 3 more octal digits
  // ("%4o") and any other "\d" as up to 3 digits, so every escape is written with exactly 4 digits
  // "\0ooo": a following literal digit can never be taken into it. Backquote and macro substitution
  // run on the raw line, before escapes are decoded, so an escaped ` or @ stays text. NUL bytes are
  // dropped (gnuplot would end the string there).
  std::string out = "\"";
  out.reserve(text.size() + 2);
  for (const char ch : text) {
    const unsigned char c = static_cast<unsigned char>(ch);
    if (c == 0) continue;
    const bool safe = (c >= 'A' && c <= 'Z') || (c >= 'a' && c <= 'z') || (c >= '0' && c <= '9') ||
                      std::strchr(" .,_-+=:/()[]{}", c) != nullptr;
    if (safe) {
      out += static_cast<char>(c);
    } else {
      const char esc[6] = {'\\', '0', static_cast<char>('0' + (c >> 6)), static_cast<char>('0' + ((c >> 3) & 7)),
                           static_cast<char>('0' + (c & 7)), '\0'};
      out += esc;
    }
  }
  return out + "\"";
}

namespace {

// Enhanced-text markup characters (^ _ @ & ~ { } \) in text shown literally in an enhanced label.
std::string EnhancedLiteral(const std::string& s) {
  std::string out;
  for (char c : s) {
    if (c != '\0' && std::strchr("^_@&~{}\\", c) != nullptr) out += '\\';
    out += c;
  }
  return out;
}

std::string Greek(const std::string& name) {
  if (name == "alpha") return "{/Symbol a}";
  if (name == "omega") return "{/Symbol W}";
  if (name == "eta") return "{/Symbol h}";
  if (name == "eta_r") return "{/Symbol h}_r";
  if (name == "lambda") return "{/Symbol l}";
  if (name == "phi") return "{/Symbol f}";
  if (name == "eps") return "{/Symbol e}";
  return EnhancedLiteral(name);  // a name from a file: literal text, not markup
}

// The process's file-creation mask, read without changing it (umask(2) would, for every thread).
mode_t CurrentUmask() {
  std::ifstream in("/proc/self/status");
  std::string line;
  while (std::getline(in, line))
    if (line.rfind("Umask:", 0) == 0) return static_cast<mode_t>(std::strtoul(line.c_str() + 6, nullptr, 8) & 0777);
  return 022;
}

// SIGPIPE blocked in this thread while writing to gnuplot (a gnuplot that exits early must give
// EPIPE, not kill the client); one raised meanwhile is discarded before the old mask comes back.
class SigpipeBlock {
 public:
  SigpipeBlock() {
    sigemptyset(&pipe_);
    sigaddset(&pipe_, SIGPIPE);
    sigset_t pending;
    sigemptyset(&pending);
    sigpending(&pending);
    was_pending_ = sigismember(&pending, SIGPIPE) == 1;
    pthread_sigmask(SIG_BLOCK, &pipe_, &old_);
  }
  ~SigpipeBlock() {
    if (!was_pending_) {
      const timespec zero{0, 0};
      while (sigtimedwait(&pipe_, nullptr, &zero) == SIGPIPE) {
      }
    }
    pthread_sigmask(SIG_SETMASK, &old_, nullptr);
  }
  SigpipeBlock(const SigpipeBlock&) = delete;
  SigpipeBlock& operator=(const SigpipeBlock&) = delete;

 private:
  sigset_t pipe_, old_;
  bool was_pending_ = false;
};

// Owns a file descriptor.
struct Fd {
  int fd = -1;
  explicit Fd(int f = -1) : fd(f) {}
  ~Fd() { reset(); }
  void reset(int f = -1) {
    if (fd >= 0) ::close(fd);
    fd = f;
  }
  Fd(const Fd&) = delete;
  Fd& operator=(const Fd&) = delete;
};

std::string Errno(int e) { return std::strerror(e); }

// Runs gnuplot (no shell: an argument vector) with the script on a pipe to its stdin. gnuplot writes
// into a file this function created in the destination directory (its name chosen here, never the
// caller's path), which is renamed onto out_path when gnuplot succeeded: the plot appears atomically
// and the requested path never reaches the script.
Status RunGnuplot(const std::string& script, const std::string& out_path) {
  namespace fs = std::filesystem;
  if (out_path.empty()) return Status::InvalidArgument("out", "the output path is empty");
  const fs::path out(out_path);
  if (!out.has_filename())
    return Status::InvalidArgument("out", "output '" + out_path + "' names a directory, not a file");
  const fs::path dir = out.parent_path().empty() ? fs::path(".") : out.parent_path();
  std::error_code ec;
  if (!fs::is_directory(dir, ec))
    return Status::InvalidArgument("out", "cannot write '" + out_path + "': directory '" + dir.string() +
                                              (fs::exists(dir, ec) ? "' is not a directory" : "' does not exist"));
  const fs::path abs_dir = fs::absolute(dir, ec);
  if (ec) return Status::IoError("out", "cannot resolve directory '" + dir.string() + "': " + ec.message());

  // gnuplot's output: "<dir>/.bistable-plot-XXXXXX" (absolute, so never "|cmd" nor "~").
  std::string tmp = (abs_dir / ".bistable-plot-XXXXXX").string();
  {
    Fd f(::mkostemp(tmp.data(), O_CLOEXEC));
    if (f.fd < 0) return Status::IoError("out", "cannot create a file in '" + dir.string() + "': " + Errno(errno));
    ::fchmod(f.fd, 0666 & ~CurrentUmask());
  }
  struct TmpGuard {
    std::string path;
    bool keep = false;
    ~TmpGuard() {
      if (!keep) ::unlink(path.c_str());
    }
  } tmp_guard{tmp};

  // gnuplot's stderr: an unlinked temporary file, read back for the error message.
  const char* tmpdir_env = std::getenv("TMPDIR");
  std::string log = std::string(tmpdir_env && *tmpdir_env ? tmpdir_env : "/tmp") + "/bistable-gnuplot-XXXXXX";
  Fd err(::mkostemp(log.data(), O_CLOEXEC));
  if (err.fd < 0) {
    log = "/tmp/bistable-gnuplot-XXXXXX";
    err.reset(::mkostemp(log.data(), O_CLOEXEC));
  }
  if (err.fd < 0) return Status::IoError("plot", "cannot create a temporary file for gnuplot's messages: " + Errno(errno));
  ::unlink(log.c_str());

  int fds[2];
  if (::pipe2(fds, O_CLOEXEC) != 0) return Status::IoError("plot", "pipe: " + Errno(errno));
  Fd pipe_r(fds[0]), pipe_w(fds[1]);

  posix_spawn_file_actions_t fa;
  posix_spawnattr_t attr;
  posix_spawn_file_actions_init(&fa);
  posix_spawn_file_actions_adddup2(&fa, pipe_r.fd, STDIN_FILENO);
  posix_spawn_file_actions_addopen(&fa, STDOUT_FILENO, "/dev/null", O_WRONLY, 0);
  posix_spawn_file_actions_adddup2(&fa, err.fd, STDERR_FILENO);
  posix_spawnattr_init(&attr);
  sigset_t none, defaults;
  sigemptyset(&none);
  sigemptyset(&defaults);
  sigaddset(&defaults, SIGPIPE);  // the client ignores SIGPIPE; gnuplot gets the default back
  posix_spawnattr_setsigmask(&attr, &none);
  posix_spawnattr_setsigdefault(&attr, &defaults);
  posix_spawnattr_setflags(&attr, POSIX_SPAWN_SETSIGMASK | POSIX_SPAWN_SETSIGDEF);
  char arg0[] = "gnuplot";
  char* argv[] = {arg0, nullptr};
  pid_t pid = -1;
  const int spawn_rc = ::posix_spawnp(&pid, "gnuplot", &fa, &attr, argv, environ);
  posix_spawn_file_actions_destroy(&fa);
  posix_spawnattr_destroy(&attr);
  if (spawn_rc != 0)
    return Status::IoError("plot", "cannot start gnuplot: " + Errno(spawn_rc) + " (install gnuplot-nox: scripts/setup.sh)");
  pipe_r.reset();

  const std::string full = "set output " + GnuplotString(tmp) + "\n" + script + "\nunset output\n";
  int write_errno = 0;
  {
    SigpipeBlock block;
    size_t done = 0;
    while (done < full.size()) {
      const ssize_t n = ::write(pipe_w.fd, full.data() + done, full.size() - done);
      if (n < 0 && errno == EINTR) continue;
      if (n <= 0) {
        write_errno = n < 0 ? errno : EIO;
        break;
      }
      done += static_cast<size_t>(n);
    }
    pipe_w.reset();
  }
  int status = 0;
  while (::waitpid(pid, &status, 0) < 0) {
    if (errno != EINTR) {
      status = -1;
      break;
    }
  }
  std::string messages;
  if (::lseek(err.fd, 0, SEEK_SET) == 0) {
    char buf[4096];
    ssize_t n;
    while (messages.size() < 65536 && (n = ::read(err.fd, buf, sizeof buf)) > 0) messages.append(buf, static_cast<size_t>(n));
  }
  const bool exited_ok = status != -1 && WIFEXITED(status) && WEXITSTATUS(status) == 0;
  struct stat st{};
  const bool written = ::stat(tmp.c_str(), &st) == 0 && st.st_size > 0;
  if (!exited_ok || write_errno != 0 || !written) {
    std::string how = status == -1            ? "could not be waited for"
                      : WIFSIGNALED(status)   ? "killed by signal " + std::to_string(WTERMSIG(status))
                      : WEXITSTATUS(status) != 0 ? "exit " + std::to_string(WEXITSTATUS(status))
                      : write_errno != 0      ? "stopped reading its script: " + Errno(write_errno)
                                              : "wrote an empty file";
    while (!messages.empty() && (messages.back() == '\n' || messages.back() == ' ')) messages.pop_back();
    return Status::IoError("plot", "gnuplot failed writing '" + out_path + "' (" + how + ")" +
                                       (messages.empty() ? "" : ": " + messages.substr(0, 400)));
  }
  if (::rename(tmp.c_str(), out_path.c_str()) != 0)
    return Status::IoError("out", "rename to '" + out_path + "': " + Errno(errno));
  tmp_guard.keep = true;
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
  s << Terminal(format) << "set title " << GnuplotString(d.title) << " noenhanced\n";
  s << "set xlabel " << GnuplotString(AxisLabel(d.axis_names.back(), d.axis_units.back())) << "\n";
  if (d.axis_names.size() == 2) {
    s << "set ylabel " << GnuplotString(AxisLabel(d.axis_names[0], d.axis_units[0])) << "\n";
    s << "set cblabel " << GnuplotString(d.metric + (d.unit.empty() ? "" : " [" + d.unit + "]")) << " noenhanced\n";
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
    s << "set ylabel " << GnuplotString(d.metric + (d.unit.empty() ? "" : " [" + d.unit + "]")) << " noenhanced\nset grid\nset key off\n";
    s << "$data << EOD\n";
    for (size_t j = 0; j < d.axis_values[0].size(); ++j) s << Num(d.axis_values[0][j]) << " " << Num(d.values[j]) << "\n";
    s << "EOD\nplot $data using 1:2 with linespoints pt 7 ps 0.5 lw 1.5\n";
  }
  return RunGnuplot(s.str(), out_path);
}

Status RenderBranches(const BranchPlot& d, const std::string& out_path) {
  std::ostringstream s;
  s << Terminal(std::filesystem::path(out_path).extension() == ".svg" ? "svg" : "png");
  s << "set title " << GnuplotString(d.title) << " noenhanced\n";
  s << "set xlabel " << GnuplotString(AxisLabel(d.x_name, d.x_unit)) << "\n";
  s << "set ylabel " << GnuplotString(d.y_label) << "\nset grid\nset key top left\n";
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
              GnuplotString(b == 0 ? (stable ? "stable" : "unstable") : "") + ", ";
    }
    if (!br.fold_x.empty()) {
      s << "$f" << b << " << EOD\n";
      for (size_t i = 0; i < br.fold_x.size(); ++i) s << Num(br.fold_x[i]) << " " << Num(br.fold_y[i]) << "\n";
      s << "EOD\n";
      plot += "$f" + std::to_string(b) + " using 1:2 with points pt 9 ps 1.2 lc rgb 'black' title " + GnuplotString(b == 0 ? "fold" : "") + ", ";
    }
  }
  if (!d.extra_x.empty()) {
    s << "$extra << EOD\n";
    for (size_t i = 0; i < d.extra_x.size(); ++i) s << Num(d.extra_x[i]) << " " << Num(d.extra_y[i]) << "\n";
    s << "EOD\n";
    plot += "$extra using 1:2 with points pt 7 ps 0.3 lc rgb '#999999' title " + GnuplotString(d.extra_label) + ", ";
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
  s << "set multiplot layout " << d.rows << "," << d.cols << " title " << GnuplotString(d.title) << "\n";
  s << "set grid\nset key top left\nset datafile missing 'NaN'\n";
  int block = 0;
  for (const PanelPlot::Panel& p : d.panels) {
    s << "set title " << GnuplotString(p.title) << "\nset xlabel " << GnuplotString(p.x_label) << "\nset ylabel " << GnuplotString(p.y_label) << "\n";
    std::string plot = "plot ";
    for (const PanelPlot::Series& se : p.series) {
      const std::string name = "$b" + std::to_string(block++);
      s << name << " << EOD\n";
      for (size_t i = 0; i < se.x.size() && i < se.y.size(); ++i) s << Num(se.x[i]) << " " << Num(se.y[i]) << "\n";
      s << "EOD\n";
      plot += name + " using 1:2 with " + (se.points ? "points pt 7 ps 0.25" : "lines lw 1.2") +
              (se.colour.empty() ? "" : " lc rgb " + GnuplotString(se.colour)) + " title " + GnuplotString(se.label) + ", ";
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
  s << "set title " << GnuplotString(d.title) << " noenhanced\n";
  s << "set xlabel " << GnuplotString(AxisLabel(d.x_name, d.x_unit)) << "\n";
  s << "set ylabel " << GnuplotString("y_m at y_m' = 0 [{/Symbol d}_s]") << "\nset grid\nset key top left\n";
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
  s << "set multiplot layout 2,1 title " << GnuplotString(d.title) << " noenhanced\nset grid\nset key top right\n";
  s << "set ylabel 'Fourier magnitude' noenhanced\nset logscale y\nunset xlabel\nplot ";
  for (size_t c = 0; c < d.curves.size(); ++c)
    s << (c ? ", " : "") << "$c" << c << " using 1:2 with lines lw 1 lc rgb '#999999' title " << GnuplotString(c ? "" : "input")
      << ", $c" << c << " using 1:3 with lines lw 1.5 lc rgb '" << colours[c % 2] << "' title " << GnuplotString("output " + d.curves[c].label);
  s << "\nunset logscale y\nset xlabel " << GnuplotString(d.freq_label) << "\nset ylabel 'FRF [dB]'\n";
  s << "plot 0 with lines dt 2 lc rgb 'black' notitle";
  for (size_t c = 0; c < d.curves.size(); ++c)
    s << ", $c" << c << " using 1:4 with lines lw 1.5 lc rgb '" << colours[c % 2] << "' title " << GnuplotString(d.curves[c].label);
  s << "\nunset multiplot\n";
  return RunGnuplot(s.str(), out_path);
}

Status RenderSpectrogram(const SpectrogramPlot& d, const std::string& out_path) {
  if (d.time.empty() || d.freq.empty()) return Status::InvalidArgument("spectrogram", "the record is shorter than one window");
  std::ostringstream s;
  s << Terminal(std::filesystem::path(out_path).extension() == ".svg" ? "svg" : "png");
  s << "set title " << GnuplotString(d.title) << " noenhanced\nset xlabel " << GnuplotString(d.time_label) << "\nset ylabel "
    << GnuplotString(d.freq_label) << "\nset cblabel 'magnitude [dB re max]'\nset cbrange [-80:0]\n" << kViridis;
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
  s << "set title " << GnuplotString(d.title) << " noenhanced\n";
  s << "set xlabel " << GnuplotString(AxisLabel("omega", "omega0/omega_n")) << "\n";
  s << "set ylabel " << GnuplotString("spectral peaks of y_m, {/Symbol W}_{peaks} [rad/{/Symbol t}]") << "\n";
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
