#include "client/plot.h"

#include <fcntl.h>
#include <signal.h>
#include <spawn.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <sstream>

#include "client/plot_internal.h"
#include "engine/metric_catalog.h"

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
      const char esc[6] = {'\\',
                           '0',
                           static_cast<char>('0' + (c >> 6)),
                           static_cast<char>('0' + ((c >> 3) & 7)),
                           static_cast<char>('0' + (c & 7)),
                           '\0'};
      out += esc;
    }
  }
  return out + "\"";
}

std::string EnhancedText(const std::string& text) {
  std::string out;
  for (char c : text) {
    if (c != '\0' && std::strchr("^_@&~{}\\", c) != nullptr) out += '\\';
    out += c;
  }
  return out;
}

namespace {

// A term model's parameter ("main.stiffness_y3.k3", "res.friction.F_s"; model = "terms") as a short symbol: the
// parameter's own name with its index subscripted (k_3, k_{lin}, F_s), the resonator's marked ",r" (F_{s,r}) —
// the full names run past the canvas in a subtitle. "" for any other name.
std::string TermParameterSymbol(const std::string& name) {
  const size_t dot = name.rfind('.');
  const bool main = name.rfind("main.", 0) == 0, res = name.rfind("res.", 0) == 0;
  if (dot == std::string::npos || !(main || res) || dot + 1 >= name.size()) return "";
  const std::string p = name.substr(dot + 1);
  for (char c : p)
    if (!std::isalnum(static_cast<unsigned char>(c)) && c != '_') return "";
  std::string base = p, sub;
  if (const size_t u = p.find('_'); u != std::string::npos) {
    base = p.substr(0, u), sub = p.substr(u + 1);
  } else {
    size_t d = p.size();
    while (d > 1 && std::isdigit(static_cast<unsigned char>(p[d - 1]))) --d;
    base = p.substr(0, d), sub = p.substr(d);
  }
  if (res) sub += sub.empty() ? "r" : ",r";
  if (sub.empty()) return base;
  return base + (sub.size() == 1 ? "_" + sub : "_{" + sub + "}");
}

}  // namespace

std::string SymbolOf(const std::string& name) {
  // UTF-8 letters (pngcairo, svg and pdfcairo draw them; svg text keeps them searchable).
  static const std::pair<const char*, const char*> kSymbols[] = {{"alpha", "α"},
                                                                 {"omega", "Ω"},
                                                                 {"eta", "η"},
                                                                 {"eta_r", "η_r"},
                                                                 {"lambda", "λ"},
                                                                 {"phi", "φ"},
                                                                 {"eps", "ε"},
                                                                 {"ym0", "y_m(0)"},
                                                                 {"vm0", "y_m'(0)"},
                                                                 {"yr0", "y_r(0)"},
                                                                 {"vr0", "y_r'(0)"},
                                                                 {"a0_mm", "A_0"},
                                                                 {"f0_hz", "f_0"},
                                                                 {"m_m", "m_m"},
                                                                 {"k_lin", "k_{lin}"},
                                                                 {"k3", "k_3"},
                                                                 {"c0_m", "c_{0,m}"},
                                                                 {"c2_m", "c_{2,m}"},
                                                                 {"fric_m_fs", "F_{s,m}"},
                                                                 {"fric_m_fc", "F_{c,m}"},
                                                                 {"fric_m_vsp", "v_{sp,m}"},
                                                                 {"fric_m_vt", "v_{t,m}"},
                                                                 {"m_r", "m_r"},
                                                                 {"k_r", "k_r"},
                                                                 {"c0_r", "c_{0,r}"},
                                                                 {"c2_r", "c_{2,r}"},
                                                                 {"fric_r_fs", "F_{s,r}"},
                                                                 {"fric_r_fc", "F_{c,r}"},
                                                                 {"fric_r_vsp", "v_{sp,r}"},
                                                                 {"fric_r_vt", "v_{t,r}"},
                                                                 {"m_main", "m_{main}"},
                                                                 {"m_res", "m_{res}"},
                                                                 {"v_sp", "v_{sp}"},
                                                                 {"v_t", "v_t"}};
  for (const auto& [from, to] : kSymbols)
    if (name == from) return to;
  if (std::string sym = TermParameterSymbol(name); !sym.empty()) return sym;
  return EnhancedText(name);  // a name from a file: literal text, not markup
}

std::string UnitMarkup(const std::string& unit) {
  if (unit.empty() || unit == "1" || unit == "code") return "";
  // Units as stored (plain text) → enhanced text with symbols; the rest literal but for ^ (powers).
  std::string u;
  for (char c : unit) {
    if (c != '^' && c != '\0' && std::strchr("_@&~{}\\", c) != nullptr) u += '\\';
    u += c;
  }
  const std::pair<const char*, const char*> kSubs[] = {
      {"delta\\_s", "δ_s"}, {"omega\\_n", "ω_n"}, {"omega0", "ω_0"}, {"omega\\_r", "ω_r"}, {"A0", "A_0"},
      {"m\\_m", "m_m"},     {"m\\_r", "m_r"},     {"c\\_r", "c_r"},  {"tau", "τ"},         {"k3", "k_3"}};
  for (auto [from, to] : kSubs)
    for (size_t p = u.find(from); p != std::string::npos; p = u.find(from, p + std::strlen(to)))
      u.replace(p, std::strlen(from), to);
  return u;
}

std::string ParameterItem(const std::string& name, double value, const std::string& unit) {
  // Non-dimensional parameters are defined by ratios (AxisUnit's "c/(m_m omega_n)"): no unit shown.
  const bool ratio = unit.find('/') != std::string::npos && unit.find("delta_s") == std::string::npos &&
                     unit.find("tau") == std::string::npos && unit.find(' ') != std::string::npos;
  const bool nondim = name == "alpha" || name == "omega" || name == "eta" || name == "eta_r" || name == "lambda" ||
                      name == "phi" || name == "eps" || ratio;
  std::string item = SymbolOf(name) + " = " + PlotNumber(value);
  const std::string u = nondim ? "" : UnitMarkup(unit);
  return u.empty() ? item : item + " " + u;
}

namespace {

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

// Room on the right for the colour box, its tick labels and its label (pngcairo 900 px wide).
constexpr const char* kColourBoxMargins = "set lmargin 12\nset rmargin 18\n";

}  // namespace

namespace plot_internal {

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
  if (err.fd < 0)
    return Status::IoError("plot", "cannot create a temporary file for gnuplot's messages: " + Errno(errno));
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
    return Status::IoError("plot", "cannot start gnuplot: " + Errno(spawn_rc) +
                                       (spawn_rc == ENOENT ? " (not on PATH; install gnuplot-nox: scripts/setup.sh)"
                                                           : " (install gnuplot-nox: scripts/setup.sh)"));
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
    while (messages.size() < 65536 && (n = ::read(err.fd, buf, sizeof buf)) > 0)
      messages.append(buf, static_cast<size_t>(n));
  }
  const bool exited_ok = status != -1 && WIFEXITED(status) && WEXITSTATUS(status) == 0;
  struct stat st {};
  const bool written = ::stat(tmp.c_str(), &st) == 0 && st.st_size > 0;
  if (!exited_ok || write_errno != 0 || !written) {
    std::string how = status == -1               ? "could not be waited for"
                      : WIFSIGNALED(status)      ? "killed by signal " + std::to_string(WTERMSIG(status))
                      : WEXITSTATUS(status) != 0 ? "exit " + std::to_string(WEXITSTATUS(status))
                      : write_errno != 0         ? "stopped reading its script: " + Errno(write_errno)
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

std::string Terminal(const std::string& format, int w, int h) {
  char size[64];
  std::ostringstream t;
  if (format == "svg") {
    t << "set terminal svg size " << w << "," << h << " dynamic enhanced font 'Helvetica,14' background 'white'\n";
  } else if (format == "pdf") {
    std::snprintf(size, sizeof size, "%.3fin,%.3fin", w / 72.0, h / 72.0);
    t << "set terminal pdfcairo size " << size << " enhanced font 'Helvetica,12'\n";
  } else {
    t << "set terminal pngcairo size " << w << "," << h << " enhanced font 'Helvetica,12'\n";
  }
  t << "set encoding utf8\n";
  return t.str();
}

size_t VisibleLength(const std::string& text) {
  size_t n = 0;
  for (unsigned char c : text) n += (c & 0xC0) != 0x80 && std::strchr("_^{}\\", c) == nullptr;
  return n;
}

namespace {

// Subtitle items joined with ", " into lines of at most `width` visible characters.
std::vector<std::string> WrapItems(const std::vector<std::string>& items, size_t width) {
  std::vector<std::string> lines;
  std::string line;
  for (const std::string& item : items) {
    if (!line.empty() && VisibleLength(line) + 2 + VisibleLength(item) > width) {
      lines.push_back(line + ",");
      line.clear();
    }
    line += (line.empty() ? "" : ", ") + item;
  }
  if (!line.empty()) lines.push_back(line);
  return lines;
}

}  // namespace

void WriteDecor(std::ostream& s, const Decor& d, int w, int h, int* top_px, int* bottom_px, double centre) {
  int tag = 900;
  auto at = [&](double x, int y_px) {
    char b[64];
    std::snprintf(b, sizeof b, " at screen %.4f, %.4f", x, 1.0 - static_cast<double>(y_px) / h);
    return std::string(b);
  };
  int top = 10;
  if (!d.title.empty()) {
    top += 18;
    s << "set label " << tag++ << " " << GnuplotString(d.title) << at(centre, top) << " center font ',15' "
      << (d.title_markup ? "enhanced" : "noenhanced") << "\n";
    top += 8;
  }
  for (const std::string& line :
       WrapItems(d.subtitle, static_cast<size_t>(w / 10))) {  // ~9.4 px per character, and a margin
    top += 18;
    s << "set label " << tag++ << " " << GnuplotString(line) << at(centre, top) << " center font ',12' enhanced\n";
  }
  *top_px = top + 20;
  int bottom = 8;
  if (!d.footer.empty()) {
    s << "set label " << tag++ << " " << GnuplotString(d.footer) << at(0.01, h - bottom - 4)
      << " left font ',9' noenhanced textcolor rgb '#666666'\n";
    bottom += 14;
  }
  std::vector<std::string> notes;  // each note wrapped at spaces to the canvas width
  for (const std::string& note : d.notes) {
    std::vector<std::string> words;
    std::stringstream in(note);
    for (std::string word; std::getline(in, word, ' ');) words.push_back(word);
    std::string line;
    for (const std::string& word : words) {
      if (!line.empty() && VisibleLength(line) + 1 + VisibleLength(word) > static_cast<size_t>(w / 8.5))
        notes.push_back(line), line.clear();
      line += (line.empty() ? "" : " ") + word;
    }
    if (!line.empty()) notes.push_back(line);
  }
  for (auto it = notes.rbegin(); it != notes.rend(); ++it) {
    s << "set label " << tag++ << " " << GnuplotString(*it) << at(0.01, h - bottom - 5)
      << " left font ',11' enhanced\n";
    bottom += 17;
  }
  *bottom_px = bottom;
}

std::string Margins(int w, int h, int l, int r, int b, int t) {
  char buf[200];
  std::snprintf(buf, sizeof buf,
                "set lmargin at screen %.4f\nset rmargin at screen %.4f\nset bmargin at screen %.4f\nset tmargin at "
                "screen %.4f\n",
                static_cast<double>(l) / w, 1.0 - static_cast<double>(r) / w, static_cast<double>(b) / h,
                1.0 - static_cast<double>(t) / h);
  return buf;
}

std::string Num(double v) {
  if (!std::isfinite(v)) return "NaN";
  char b[32];
  std::snprintf(b, sizeof b, "%.9g", v);
  return b;
}

std::vector<double> CellEdges(const std::vector<double>& v) {
  if (v.empty()) return {};
  if (v.size() == 1) {
    const double h = 0.5 * std::max(std::fabs(v[0]) * 0.02, 1e-6);
    return std::vector<double>{v[0] - h, v[0] + h};
  }
  std::vector<double> e(v.size() + 1);
  e[0] = v[0] - 0.5 * (v[1] - v[0]);
  for (size_t k = 1; k < v.size(); ++k) e[k] = 0.5 * (v[k - 1] + v[k]);
  e[v.size()] = v.back() + 0.5 * (v.back() - v[v.size() - 2]);
  return e;
}

void WriteCells(std::ostream& s, const std::vector<double>& xs, const std::vector<double>& ys,
                const std::function<double(size_t, size_t)>& value, const std::string& more_plots) {
  const std::vector<double> xe = CellEdges(xs), ye = CellEdges(ys);
  s << "set xrange [" << Num(xe.front()) << ":" << Num(xe.back()) << "]\n";
  s << "set yrange [" << Num(ye.front()) << ":" << Num(ye.back()) << "]\n";
  s << "set view map\nset pm3d map corners2color c1\nset pm3d interpolate 1,1\n$data << EOD\n";
  for (size_t j = 0; j < ye.size(); ++j) {
    for (size_t i = 0; i < xe.size(); ++i)
      s << Num(xe[i]) << " " << Num(ye[j]) << " " << Num(value(std::min(i, xs.size() - 1), std::min(j, ys.size() - 1)))
        << "\n";
    s << "\n";
  }
  s << "EOD\nsplot $data using 1:2:3 with pm3d notitle" << more_plots << "\n";
}

}  // namespace plot_internal

using plot_internal::Decor;
using plot_internal::kQualitative;
using plot_internal::kViridis;
using plot_internal::Num;
using plot_internal::RunGnuplot;
using plot_internal::Terminal;
using plot_internal::WriteCells;
using plot_internal::WriteDecor;

std::pair<double, double> ColourRange(const std::string& metric, const std::vector<double>& values) {
  double lo = INFINITY, hi = -INFINITY;
  for (double v : values)
    if (std::isfinite(v)) lo = std::min(lo, v), hi = std::max(hi, v);
  if (lo > hi) return {0.0, 1.0};  // nothing finite
  if (DivergesAboutZero(metric)) {
    const double m = std::max({std::fabs(lo), std::fabs(hi), 1e-12});
    return {-m, m};
  }
  // Energy dissipation ratios are percentages of the injected energy: the scale stops at 100 % (values
  // above, where the stored energy fell over the window, take the top colour and the figure says so).
  if (metric.rfind("edr_", 0) == 0 && hi > 100) hi = std::max(100.0, lo + 1e-9);
  if (lo == hi) return {lo - 0.5, hi + 0.5};
  return {lo, hi};
}

std::pair<double, double> HeatmapAxisRange(const std::vector<double>& values) {
  const std::vector<double> e = plot_internal::CellEdges(values);
  if (e.empty()) return {NAN, NAN};
  return {e.front(), e.back()};
}

std::string PlotNumber(double v) {
  if (!std::isfinite(v)) return std::isnan(v) ? "NaN" : (v > 0 ? "inf" : "-inf");
  char b[32];
  std::snprintf(b, sizeof b, "%.4g", v);
  return b;
}

Status CheckGnuplot() {
  const char* path = std::getenv("PATH");
  std::string dirs = path ? path : "/bin:/usr/bin";
  size_t start = 0;
  while (start <= dirs.size()) {
    const size_t end = std::min(dirs.find(':', start), dirs.size());
    const std::string dir = end > start ? dirs.substr(start, end - start) : ".";
    const std::string file = dir + "/gnuplot";
    struct stat st {};
    if (::stat(file.c_str(), &st) == 0 && S_ISREG(st.st_mode) && ::access(file.c_str(), X_OK) == 0) return Status::Ok();
    start = end + 1;
  }
  return Status::FailedPrecondition("gnuplot not found on PATH: install gnuplot-nox (scripts/setup.sh)");
}

std::string AxisLabel(const std::string& name, const std::string& unit) {
  if (name == "a0_mm") return "base amplitude A_0 [mm]";
  if (name == "acc0_g") return "base acceleration amplitude [g]";
  if (name == "force0_n") return "force amplitude F_0 [N]";
  if (name == "f0_hz") return "drive frequency f_0 [Hz]";  // of the base, or of a force (drive = "force")
  const std::string u = UnitMarkup(unit);
  if (u.empty()) return SymbolOf(name);
  // The non-dimensional parameters say what they are scaled by (α = A_0/δ_s); quantities with a
  // unit carry it in brackets (y_m(0) [δ_s]).
  static const char* kScaled[] = {"alpha", "omega", "eta", "eta_r", "lambda", "phi", "eps"};
  const bool scaled = std::find(std::begin(kScaled), std::end(kScaled), name) != std::end(kScaled);
  return SymbolOf(name) + (scaled ? " = " + u : " [" + u + "]");
}

std::string PlotFormatOf(const std::string& out_path) {
  const std::string ext = std::filesystem::path(out_path).extension().string();
  return ext == ".svg" ? "svg" : ext == ".pdf" ? "pdf" : "png";
}

Status RenderBranches(const BranchPlot& d, const std::string& out_path) {
  std::ostringstream s;
  s << Terminal(PlotFormatOf(out_path));
  int top_px = 0, bottom_px = 0;
  WriteDecor(s, Decor{d.title, d.title_markup, d.subtitle, {}, ""}, 900, 700, &top_px, &bottom_px);
  s << "set tmargin at screen " << Num(1.0 - top_px / 700.0) << "\n";
  s << "set xlabel " << GnuplotString(AxisLabel(d.x_name, d.x_unit)) << "\n";
  s << "set ylabel " << GnuplotString(d.y_label)
    << "\nset grid\nset key below center horizontal maxrows 3 noenhanced\n";
  // One colour per branch name (in order of first appearance); each stable/unstable run of a branch
  // is its own segment (blank line between). The legend is compact: one entry per name (its colour,
  // solid), one "unstable (dashed)" entry when an unstable run is drawn, so every entry names
  // something drawn and a cascade of branches does not fill the canvas with legend.
  std::vector<std::string> names;
  for (const auto& br : d.branches)
    if (std::find(names.begin(), names.end(), br.name) == names.end()) names.push_back(br.name);
  std::vector<std::pair<std::string, int>> titled;
  bool any_unstable = false;
  std::string plot = "plot ";
  for (size_t b = 0; b < d.branches.size(); ++b) {
    const auto& br = d.branches[b];
    const size_t colour = std::find(names.begin(), names.end(), br.name) - names.begin();
    for (int stable = 1; stable >= 0; --stable) {
      if (!d.stability && !stable) continue;
      std::ostringstream block;
      bool any = false;
      for (size_t i = 0; i < br.x.size() && i < br.y.size() && i < br.stable.size(); ++i) {
        const bool in = !d.stability || br.stable[i] == static_cast<bool>(stable);
        const bool next_in = i + 1 < br.x.size() && i + 1 < br.stable.size() &&
                             (!d.stability || br.stable[i + 1] == static_cast<bool>(stable));
        if (in && next_in) any = true;  // a segment, not a lone point
        if (in || next_in) block << Num(br.x[i]) << " " << Num(br.y[i]) << "\n";
        if (in && !next_in) block << "\n";
      }
      if (!any) continue;
      const std::string name = "$b" + std::to_string(b) + "s" + std::to_string(stable);
      s << name << " << EOD\n" << block.str() << "EOD\n";
      const bool first = std::find(titled.begin(), titled.end(), std::make_pair(br.name, 1)) == titled.end();
      if (first) titled.emplace_back(br.name, 1);
      any_unstable |= d.stability && !stable;
      plot += name + " using 1:2 with lines lw " + Num(br.width) + " dt " + (stable ? "1" : "2") + " lc rgb " +
              GnuplotString(kQualitative[colour % 12]) + " notitle, ";
      // The name's legend entry: a solid sample in its colour (whatever the first run's stability).
      if (first)
        plot += "NaN with lines lw 2 dt 1 lc rgb " + GnuplotString(kQualitative[colour % 12]) + " title " +
                GnuplotString(br.name.empty() ? "branch" : br.name) + ", ";
    }
  }
  if (any_unstable) plot += "NaN with lines lw 2 dt 2 lc rgb '#555555' title 'unstable (dashed)', ";
  // Folds of every branch: one block, one legend entry.
  std::ostringstream folds;
  for (const auto& br : d.branches)
    for (size_t i = 0; i < br.fold_x.size() && i < br.fold_y.size(); ++i)
      folds << Num(br.fold_x[i]) << " " << Num(br.fold_y[i]) << "\n";
  if (!folds.str().empty()) {
    s << "$folds << EOD\n" << folds.str() << "EOD\n";
    plot += "$folds using 1:2 with points pt 9 ps 1.4 lc rgb 'black' title 'fold', ";
  }
  for (size_t k = 0; k < d.markers.size(); ++k) {
    const BranchPlot::Marker& m = d.markers[k];
    if (m.x.empty()) continue;
    s << "$m" << k << " << EOD\n";
    for (size_t i = 0; i < m.x.size() && i < m.y.size(); ++i) s << Num(m.x[i]) << " " << Num(m.y[i]) << "\n";
    s << "EOD\n";
    plot += "$m" + std::to_string(k) + " using 1:2 with points pt " + std::to_string(m.point_type) + " ps 1.4 lc rgb " +
            GnuplotString(m.colour.empty() ? "#000000" : m.colour) + " title " + GnuplotString(m.label) + ", ";
  }
  if (!d.extra_x.empty()) {
    s << "$extra << EOD\n";
    for (size_t i = 0; i < d.extra_x.size() && i < d.extra_y.size(); ++i)
      s << Num(d.extra_x[i]) << " " << Num(d.extra_y[i]) << "\n";
    s << "EOD\n";
    plot += "$extra using 1:2 with points pt 7 ps 0.3 lc rgb '#999999' title " + GnuplotString(d.extra_label) + ", ";
  }
  if (plot.size() == 5) return Status::InvalidArgument("plot", "no branch segment to plot");
  plot.resize(plot.size() - 2);
  s << plot << "\n";
  return RunGnuplot(s.str(), out_path);
}

Status RenderPanels(const PanelPlot& d, const std::string& out_path) {
  if (d.panels.empty()) return Status::InvalidArgument("plot", "no panels to plot");
  std::ostringstream s;
  const int w = std::clamp(d.panel_width, 100, 4000) * d.cols, h = std::clamp(d.panel_height, 100, 4000) * d.rows + 40;
  s << (std::filesystem::path(out_path).extension() == ".svg"
            ? "set terminal svg size " + std::to_string(w) + "," + std::to_string(h) +
                  " dynamic noenhanced font 'Helvetica,13' background 'white'\n"
            : "set terminal pngcairo size " + std::to_string(w) + "," + std::to_string(h) +
                  " noenhanced font 'Helvetica,11'\n");
  s << "set multiplot layout " << d.rows << "," << d.cols << " title " << GnuplotString(d.title) << "\n";
  // The legend below each panel, where it hides no point (docs/figures.md: a Pareto front's best designs sat under it).
  s << "set grid\nset key below center horizontal samplen 2\nset datafile missing 'NaN'\n";
  int block = 0;
  for (const PanelPlot::Panel& p : d.panels) {
    s << "set title " << GnuplotString(p.title) << "\nset xlabel " << GnuplotString(p.x_label) << "\nset ylabel "
      << GnuplotString(p.y_label) << "\n";
    if (std::isfinite(p.y_lo) && std::isfinite(p.y_hi) && p.y_lo < p.y_hi)
      s << "set yrange [" << Num(p.y_lo) << ":" << Num(p.y_hi) << "]\n";
    else
      s << "set autoscale y\n";
    std::string plot = "plot ";
    for (const PanelPlot::Series& se : p.series) {
      const std::string name = "$b" + std::to_string(block++);
      s << name << " << EOD\n";
      for (size_t i = 0; i < se.x.size() && i < se.y.size(); ++i) s << Num(se.x[i]) << " " << Num(se.y[i]) << "\n";
      s << "EOD\n";
      plot += name + " using 1:2 with " +
              (se.points ? "points pt 7 ps " + Num(std::clamp(se.point_size, 0.01, 10.0)) : "lines lw 1.2") +
              (se.colour.empty() ? "" : " lc rgb " + GnuplotString(se.colour)) + " title " + GnuplotString(se.label) +
              ", ";
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
  s << Terminal(PlotFormatOf(out_path));
  int top_px = 0, bottom_px = 0;
  WriteDecor(s, Decor{d.title, d.title_markup, d.subtitle, {}, d.footer}, 900, 700, &top_px, &bottom_px);
  s << "set tmargin at screen " << Num(1.0 - top_px / 700.0) << "\nset bmargin at screen "
    << Num((bottom_px + 100) / 700.0) << "\n";
  s << "set xlabel " << GnuplotString(AxisLabel(d.x_name, d.x_unit)) << "\n";
  s << "set ylabel " << GnuplotString("y_m at y_m' = 0 [\u03b4_s]") << "\nset grid\n";
  // The legend below the plot, with samples big enough to see (the data's dots are tiny).
  s << "set key at screen 0.5, " << Num((bottom_px + 26) / 700.0) << " center top horizontal samplen 1\n";
  std::string plot = "plot ";
  if (!d.x_up.empty()) {
    s << "$up << EOD\n";
    for (size_t i = 0; i < d.x_up.size(); ++i) s << Num(d.x_up[i]) << " " << Num(d.y_up[i]) << "\n";
    s << "EOD\n";
    plot +=
        "$up using 1:2 with points pt 7 ps 0.15 lc rgb '#2166ac' notitle, NaN with points pt 7 ps 1.5 lc rgb "
        "'#2166ac' title 'increasing', ";
  }
  if (!d.x_down.empty()) {
    s << "$down << EOD\n";
    for (size_t i = 0; i < d.x_down.size(); ++i) s << Num(d.x_down[i]) << " " << Num(d.y_down[i]) << "\n";
    s << "EOD\n";
    plot +=
        "$down using 1:2 with points pt 7 ps 0.15 lc rgb '#b2182b' notitle, NaN with points pt 7 ps 1.5 lc rgb "
        "'#b2182b' title 'decreasing', ";
  }
  if (plot.size() == 5) return Status::InvalidArgument("plot", "no turning points to plot");
  plot.resize(plot.size() - 2);
  s << plot << "\n";
  return RunGnuplot(s.str(), out_path);
}

Status RenderChirpFrf(const ChirpFrfPlot& d, const std::string& out_path) {
  if (d.curves.empty()) return Status::InvalidArgument("plot", "no frequency sweep to plot");
  std::ostringstream s;
  s << (std::filesystem::path(out_path).extension() == ".svg"
            ? "set terminal svg size 1100,1100 dynamic enhanced font 'Helvetica,14' background 'white'\n"
            : "set terminal pngcairo size 1100,1100 enhanced font 'Helvetica,12'\n");
  const char* colours[] = {"#2166ac", "#b2182b", "#1b9e77", "#7570b3"};
  const char* tints[] = {"#c6dbef", "#fcbba1", "#c7e9c0", "#dadaeb"};
  s << "set datafile missing 'NaN'\n";
  for (size_t c = 0; c < d.curves.size(); ++c) {
    const auto& cu = d.curves[c];
    s << "$c" << c << " << EOD\n";
    for (size_t i = 0; i < cu.freq.size(); ++i)
      s << Num(cu.freq[i]) << " " << Num(i < cu.in_mag.size() ? cu.in_mag[i] : NAN) << " "
        << Num(i < cu.out_mag.size() ? cu.out_mag[i] : NAN) << " " << Num(i < cu.db.size() ? cu.db[i] : NAN) << " "
        << Num(i < cu.coherence.size() ? cu.coherence[i] : NAN) << "\n";
    s << "EOD\n$r" << c << " << EOD\n";
    for (size_t i = 0; i < cu.raw_freq.size() && i < cu.raw_db.size(); ++i)
      s << Num(cu.raw_freq[i]) << " " << Num(cu.raw_db[i]) << "\n";
    s << "EOD\n";
  }
  s << "set multiplot layout 3,1 title " << GnuplotString(d.title)
    << " noenhanced\nset grid\nset key outside right top noenhanced samplen 2\n";
  // The same plot width in every row; the legends beside it only as wide as their longest entry (the
  // curves' names in row 1; rows 2 and 3 say what their line styles are).
  size_t longest = std::string("input (dashed)").size();
  for (const auto& c : d.curves) longest = std::max(longest, c.label.size());
  s << "set lmargin 12\nset rmargin " << std::clamp<size_t>(longest + 8, 22, 40) << "\n";
  // 1. Averaged Fourier amplitudes of input (dashed) and output (solid), a colour per curve.
  s << "set ylabel " << GnuplotString(d.mag_label) << "\nset logscale y\nset format y '10^{%L}'\nunset xlabel\nplot ";
  for (size_t c = 0; c < d.curves.size(); ++c)
    s << (c ? ", " : "") << "$c" << c << " using 1:2 with lines lw 1 dt 2 lc rgb " << GnuplotString(colours[c % 4])
      << " notitle, $c" << c << " using 1:3 with lines lw 1.5 lc rgb " << GnuplotString(colours[c % 4]) << " title "
      << GnuplotString(d.curves[c].label);
  s << ", NaN with lines lw 1 dt 2 lc rgb '#555555' title 'input (dashed)'";
  // 2. FRF: H1 (Welch) where the coherence says the ratio means something, over the raw ratio.
  char threshold[16];
  std::snprintf(threshold, sizeof threshold, "%g", kChirpCoherenceMin);
  s << "\nunset logscale y\nset format y '% g'\nset ylabel 'FRF |H_1| [dB re 1]'\n";
  s << "plot 0 with lines dt 3 lc rgb 'black' notitle";
  bool raw = false;
  for (size_t c = 0; c < d.curves.size(); ++c)
    if (!d.curves[c].raw_freq.empty()) {
      raw = true;
      s << ", $r" << c << " using 1:2 with lines lw 0.6 lc rgb " << GnuplotString(tints[c % 4]) << " notitle";
    }
  for (size_t c = 0; c < d.curves.size(); ++c)
    s << ", $c" << c << " using 1:($5 >= " << threshold << " ? $4 : NaN) with lines lw 2 lc rgb "
      << GnuplotString(colours[c % 4]) << " notitle";
  s << ", NaN with lines lw 2 lc rgb '#555555' title " << GnuplotString(std::string("H1 where coh. >= ") + threshold);
  if (raw) s << ", NaN with lines lw 2 lc rgb '#c8c8c8' title 'raw FFT ratio'";
  // 3. Coherence, the threshold marked.
  s << "\nset xlabel " << GnuplotString(d.freq_label)
    << "\nset ylabel 'coherence {/Symbol g}^2'\nset yrange [0:1.05]\nplot " << threshold
    << " with lines dt 3 lc rgb '#555555' title " << GnuplotString(std::string("threshold ") + threshold);
  for (size_t c = 0; c < d.curves.size(); ++c)
    s << ", $c" << c << " using 1:5 with lines lw 1.5 lc rgb " << GnuplotString(colours[c % 4]) << " notitle";
  s << "\nunset multiplot\n";
  return RunGnuplot(s.str(), out_path);
}

Status RenderSpectrogram(const SpectrogramPlot& d, const std::string& out_path) {
  if (d.time.empty() || d.freq.empty())
    return Status::InvalidArgument("spectrogram", "the record is shorter than one window");
  std::ostringstream s;
  s << Terminal(PlotFormatOf(out_path));
  s << "set title " << GnuplotString(d.title) << " noenhanced\nset xlabel " << GnuplotString(d.time_label)
    << "\nset ylabel " << GnuplotString(d.freq_label) << "\nset cblabel 'magnitude [dB re max]'\nset cbrange [-80:0]\n"
    << kViridis << kColourBoxMargins;
  s << "set key off\n";
  WriteCells(s, d.time, d.freq, [&](size_t i, size_t k) { return std::max(-80.0, d.db[i][k]); });
  return RunGnuplot(s.str(), out_path);
}

Status RenderHdScatter(const ScatterData& d, const std::string& out_path) {
  std::ostringstream s;
  s << Terminal(PlotFormatOf(out_path));
  s << "set title " << GnuplotString(d.title) << " noenhanced\n";
  s << "set xlabel " << GnuplotString(AxisLabel("omega", "omega0/omega_n")) << "\n";
  s << "set ylabel " << GnuplotString("spectral peaks of y_m, {/Symbol W}_{peaks} [rad/{/Symbol t}]") << "\n";
  s << "set cblabel 'peak amplitude [{/Symbol d}_s]'\nset logscale cb\nset format cb '10^{%L}'\nset key off\nset grid\n"
    << kViridis << kColourBoxMargins;
  double xmax = 0, ymax = 0;
  for (size_t i = 0; i < d.x.size(); ++i) xmax = std::max(xmax, d.x[i]), ymax = std::max(ymax, d.y[i]);
  s << "set xrange [0:" << Num(xmax * 1.02) << "]\nset yrange [0:" << Num(ymax * 1.05) << "]\n";
  s << "$data << EOD\n";
  for (size_t i = 0; i < d.x.size(); ++i) s << Num(d.x[i]) << " " << Num(d.y[i]) << " " << Num(d.amp[i]) << "\n";
  s << "EOD\n";
  // Integer multiples nΩ of the forcing (the paper's dashed lines).
  s << "plot for [n=1:8] n*x with lines dt 2 lc rgb '#999999' lw 1, $data using 1:2:3 with points pt 7 ps 0.6 lc "
       "palette\n";
  return RunGnuplot(s.str(), out_path);
}

}  // namespace bistable
