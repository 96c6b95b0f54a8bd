// Runs the real `bistable` executable as a process for end-to-end tests: exit code, stdout, stderr.
#ifndef BISTABLE_TESTS_PROCESS_UTIL_H_
#define BISTABLE_TESTS_PROCESS_UTIL_H_

#include <fcntl.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cerrno>
#include <chrono>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include <gtest/gtest.h>

namespace bistable_test {

struct ProcessResult {
  int exit_code;  // -1 when the process did not exit normally (a crash)
  std::string out, err;
};

// Starts argv (argv[0] a path; no shell) with stdout to `out_file` and stderr to `out_file`.err, SIGINT
// at its default action (as from an interactive shell, whatever the test runner ignores).
inline pid_t SpawnLogged(const std::vector<std::string>& argv, const std::string& out_file) {
  std::fflush(nullptr);  // the child must not re-emit our buffered output
  const pid_t pid = ::fork();
  if (pid == 0) {
    ::signal(SIGINT, SIG_DFL);
    if (!::freopen(out_file.c_str(), "w", stdout) || !::freopen((out_file + ".err").c_str(), "w", stderr)) ::_exit(126);
    std::vector<char*> args;
    for (const auto& a : argv) args.push_back(const_cast<char*>(a.c_str()));
    args.push_back(nullptr);
    ::execv(args[0], args.data());
    ::_exit(127);
  }
  return pid;
}

// Waits up to `seconds` for a child: its wait status, or -1 on timeout (the child is then killed).
inline int WaitStatusFor(pid_t pid, double seconds) {
  const auto end = std::chrono::steady_clock::now() + std::chrono::duration<double>(seconds);
  int status = 0;
  while (std::chrono::steady_clock::now() < end) {
    if (::waitpid(pid, &status, WNOHANG) == pid) return status;
    std::this_thread::sleep_for(std::chrono::milliseconds(2));
  }
  ::kill(pid, SIGKILL);
  ::waitpid(pid, &status, 0);
  return -1;
}

// Its exit code, -1 when a signal ended it, -2 on timeout.
inline int WaitExitFor(pid_t pid, double seconds) {
  const int st = WaitStatusFor(pid, seconds);
  if (st == -1) return -2;
  return WIFEXITED(st) ? WEXITSTATUS(st) : -1;
}

inline std::string ReadText(const std::string& path) {
  std::ifstream in(path);
  return {std::istreambuf_iterator<char>(in), {}};
}

#ifdef BISTABLE_CLI
// `args` is appended to the binary path and run through the shell (trusted arguments only; hostile
// ones go through RunArgv).
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

#endif  // BISTABLE_CLI

namespace detail {
struct TempDirs {
  std::mutex mu;
  std::vector<std::filesystem::path> dirs;
  pid_t owner = ::getpid();
};
inline TempDirs& TempDirRegistry() {
  static TempDirs* const t = [] {
    auto* r = new TempDirs;  // never destroyed: the exit handler reads it
    std::atexit([] {
      TempDirs& d = TempDirRegistry();
      // Only the process that made them, and only when every test of this program passed: a failure's files stay.
      if (::getpid() != d.owner || ::testing::UnitTest::GetInstance()->Failed()) return;
      std::lock_guard<std::mutex> lock(d.mu);
      for (const auto& p : d.dirs) {
        std::error_code ec;
        std::filesystem::remove_all(p, ec);
      }
    });
    return r;
  }();
  return *t;
}
}  // namespace detail

// Removes `dir` (and what is in it) when this test program ends with every test passed; after a failure it stays
// for a look. Forked children that reach exit() leave it alone.
inline void RemoveWhenAllPass(const std::filesystem::path& dir) {
  detail::TempDirs& d = detail::TempDirRegistry();
  std::lock_guard<std::mutex> lock(d.mu);
  d.dirs.push_back(dir);
}

// A fresh, empty directory under the test temp dir, unique to this process; removed at exit when every test passed.
inline std::string FreshDir(const std::string& prefix, const std::string& name) {
  const std::filesystem::path d =
      std::filesystem::path(::testing::TempDir()) / (prefix + "_" + name + "_" + std::to_string(::getpid()));
  std::filesystem::remove_all(d);
  std::filesystem::create_directories(d);
  RemoveWhenAllPass(d);
  return d.string();
}

// Result of RunArgv: how the process ended and what it wrote.
struct ExecResult {
  int exit_code = -1;  // -1 when it did not exit normally
  int signal = 0;      // the signal that ended it (0: it exited; SIGKILL also when it timed out)
  bool timed_out = false;
  std::string out, err;
};

// Runs argv[0] with arguments argv[1..] by fork + execve: no shell ever sees the arguments. `cwd`:
// working directory of the child ("" = ours); `env`: variables set (or replaced) in the child's
// environment; stdout and stderr are captured through temporary files; killed after timeout_s.
inline ExecResult RunArgv(const std::vector<std::string>& argv, const std::string& cwd = "",
                          const std::map<std::string, std::string>& env = {}, double timeout_s = 300) {
  ExecResult r;
  if (argv.empty()) return r;
  // Everything the child needs is built before fork (no allocation after it).
  std::vector<std::string> env_strings;
  for (char** e = environ; *e != nullptr; ++e) {
    const std::string kv = *e;
    const std::string key = kv.substr(0, kv.find('='));
    if (env.find(key) == env.end()) env_strings.push_back(kv);
  }
  for (const auto& [k, v] : env) env_strings.push_back(k + "=" + v);
  std::vector<char*> envp, args;
  for (auto& kv : env_strings) envp.push_back(kv.data());
  envp.push_back(nullptr);
  std::vector<std::string> argv_copy = argv;
  for (auto& a : argv_copy) args.push_back(a.data());
  args.push_back(nullptr);
  const std::string tmp = ::testing::TempDir();
  std::string out_path = tmp + "/bistable_out_XXXXXX", err_path = tmp + "/bistable_err_XXXXXX";
  const int out_fd = ::mkstemp(out_path.data());
  const int err_fd = ::mkstemp(err_path.data());
  if (out_fd < 0 || err_fd < 0) return r;
  std::fflush(nullptr);
  const pid_t pid = ::fork();
  if (pid == 0) {
    const int in_fd = ::open("/dev/null", O_RDONLY);
    if (in_fd >= 0) ::dup2(in_fd, 0);
    ::dup2(out_fd, 1);
    ::dup2(err_fd, 2);
    if (!cwd.empty() && ::chdir(cwd.c_str()) != 0) ::_exit(126);
    ::execve(args[0], args.data(), envp.data());
    ::_exit(127);
  }
  ::close(out_fd);
  ::close(err_fd);
  int status = 0;
  if (pid > 0) {
    const auto deadline = std::chrono::steady_clock::now() + std::chrono::duration<double>(timeout_s);
    while (true) {
      const pid_t w = ::waitpid(pid, &status, WNOHANG);
      if (w == pid) break;
      if (w < 0 && errno != EINTR) break;
      if (std::chrono::steady_clock::now() > deadline) {
        r.timed_out = true;
        ::kill(pid, SIGKILL);
        ::waitpid(pid, &status, 0);
        break;
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(5));
    }
    if (WIFEXITED(status)) r.exit_code = WEXITSTATUS(status);
    if (WIFSIGNALED(status)) r.signal = WTERMSIG(status);
  }
  std::ifstream o(out_path), e(err_path);
  r.out.assign(std::istreambuf_iterator<char>(o), {});
  r.err.assign(std::istreambuf_iterator<char>(e), {});
  std::filesystem::remove(out_path);
  std::filesystem::remove(err_path);
  return r;
}

}  // namespace bistable_test

#endif  // BISTABLE_TESTS_PROCESS_UTIL_H_
