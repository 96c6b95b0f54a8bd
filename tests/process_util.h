// Runs the real `bistable` executable as a process for end-to-end tests: exit code, stdout, stderr.
#ifndef BISTABLE_TESTS_PROCESS_UTIL_H_
#define BISTABLE_TESTS_PROCESS_UTIL_H_

#include <sys/wait.h>
#include <unistd.h>

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <string>

#include <gtest/gtest.h>

namespace bistable_test {

struct ProcessResult {
  int exit_code;  // -1 when the process did not exit normally (a crash)
  std::string out, err;
};

// `args` is appended to the binary path and run through the shell.
inline ProcessResult Bistable(const std::string& args) {
  const std::string err_file = ::testing::TempDir() + "/bistable_stderr_" + std::to_string(::getpid()) + ".txt";
  ProcessResult r{-1, "", ""};
  FILE* p = ::popen((std::string(BISTABLE_CLI) + " " + args + " 2>" + err_file).c_str(), "r");
  if (!p) return r;
  char buf[4096];
  size_t n;
  while ((n = std::fread(buf, 1, sizeof buf, p)) > 0) r.out.append(buf, n);
  const int status = ::pclose(p);
  r.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  std::ifstream e(err_file);
  r.err.assign(std::istreambuf_iterator<char>(e), {});
  std::filesystem::remove(err_file);
  return r;
}

// A fresh, empty directory under the test temp dir, unique to this process.
inline std::string FreshDir(const std::string& prefix, const std::string& name) {
  const std::filesystem::path d =
      std::filesystem::path(::testing::TempDir()) / (prefix + "_" + name + "_" + std::to_string(::getpid()));
  std::filesystem::remove_all(d);
  std::filesystem::create_directories(d);
  return d.string();
}

}  // namespace bistable_test

#endif  // BISTABLE_TESTS_PROCESS_UTIL_H_
