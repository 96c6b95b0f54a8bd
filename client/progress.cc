#include "client/progress.h"

#include <unistd.h>

#include <cstdio>

namespace bistable {

ProgressBar::ProgressBar(long total, std::string label, bool enabled, std::string unit)
    : total_(total),
      label_(std::move(label)),
      unit_(std::move(unit)),
      enabled_(enabled),
      tty_(::isatty(STDERR_FILENO) == 1),
      start_(std::chrono::steady_clock::now()),
      last_(start_) {}

std::string ProgressBar::Line(long done, const std::string& extra) const {
  const double secs = std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count();
  const double frac = total_ > 0 ? static_cast<double>(done) / static_cast<double>(total_) : 1.0;
  const double rate = secs > 0 ? static_cast<double>(done) / secs : 0.0;
  const int width = 30, fill = static_cast<int>(frac * width + 0.5);
  char eta[32] = "--";
  if (rate > 0 && done < total_) {
    const long s = static_cast<long>((total_ - done) / rate + 0.5);
    std::snprintf(eta, sizeof eta, "%ldm%02lds", s / 60, s % 60);
  } else if (done >= total_) {
    std::snprintf(eta, sizeof eta, "0s");
  }
  char buf[256];
  std::snprintf(buf, sizeof buf, "%s [%.*s%.*s] %5.1f%%  %ld/%ld %s  %.*f %s/s  ETA %s", label_.c_str(), fill,
                "##############################", width - fill, "..............................", 100.0 * frac, done,
                total_, unit_.c_str(), rate < 10 ? 1 : 0, rate, unit_.c_str(), eta);
  return extra.empty() ? std::string(buf) : std::string(buf) + "  " + extra;
}

void ProgressBar::Update(long done, const std::string& extra) {
  if (!enabled_) return;
  const auto now = std::chrono::steady_clock::now();
  const double since = std::chrono::duration<double>(now - last_).count();
  if (since < (tty_ ? 0.1 : 5.0)) return;
  last_ = now;
  std::fprintf(stderr, tty_ ? "\r%s\033[K" : "%s\n", Line(done, extra).c_str());
  std::fflush(stderr);
}

void ProgressBar::Finish(long done, const std::string& extra) {
  if (!enabled_) return;
  std::fprintf(stderr, tty_ ? "\r%s\033[K\n" : "%s\n", Line(done, extra).c_str());
  std::fflush(stderr);
}

}  // namespace bistable
