// A progress line on stderr: bar, done/total, points/s, ETA. On a terminal it redraws in place
// (at most 10 times a second); otherwise it prints a plain line every few seconds, so logs stay readable.
#ifndef BISTABLE_CLIENT_PROGRESS_H_
#define BISTABLE_CLIENT_PROGRESS_H_

#include <chrono>
#include <string>

namespace bistable {

class ProgressBar {
 public:
  // total: items to compute in this run (cached ones excluded); label printed in front; unit names
  // what is counted ("points", "candidates").
  ProgressBar(long total, std::string label, bool enabled, std::string unit = "points");
  // `extra` is appended to the line (e.g. "3 workers").
  void Update(long done, const std::string& extra = "");
  void Finish(long done, const std::string& extra = "");

 private:
  std::string Line(long done, const std::string& extra) const;
  long total_;
  std::string label_, unit_;
  bool enabled_, tty_;
  std::chrono::steady_clock::time_point start_, last_;
};

}  // namespace bistable

#endif  // BISTABLE_CLIENT_PROGRESS_H_
