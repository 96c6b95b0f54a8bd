// `bistable completion bash` as a real process, its script loaded by a real bash: `complete -p bistable`
// names the function, and the function (called as bash calls it, with COMP_WORDS and COMP_CWORD) completes
// commands, each command's flags (taken from the CLI's own definition: a flag added there is completed
// without a list to edit) and file names for spec and data paths.
#include <algorithm>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "tests/process_util.h"

namespace {

namespace fs = std::filesystem;
using bistable_test::ExecResult;
using bistable_test::RunArgv;

// The words the completion function offers for the command line `words` (the last one being completed),
// run by bash in `cwd`, one per line.
std::vector<std::string> Complete(const std::vector<std::string>& words, const std::string& cwd) {
  std::string line, array;
  for (const std::string& w : words) {
    line += (line.empty() ? "" : " ") + w;
    array += " '" + w + "'";
  }
  const std::string script = "source <('" BISTABLE_CLI
                             "' completion bash) || exit 9\n"
                             "COMP_WORDS=(" +
                             array + ")\nCOMP_CWORD=" + std::to_string(words.size() - 1) + "\nCOMP_LINE='" + line +
                             "'\nCOMP_POINT=${#COMP_LINE}\n_bistable bistable '" + words.back() + "' '" +
                             words[words.size() - 2] + "'\nprintf '%s\\n' \"${COMPREPLY[@]}\"\n";
  const ExecResult r = RunArgv({"/bin/bash", "-c", script}, cwd);
  EXPECT_EQ(r.exit_code, 0) << r.err;
  std::vector<std::string> out;
  std::istringstream in(r.out);
  for (std::string w; std::getline(in, w);)
    if (!w.empty()) out.push_back(w);
  return out;
}

TEST(CliCompletion, BashScriptCompletesCommandsFlagsAndFiles) {
  const std::string dir = bistable_test::FreshDir("bistable_completion", "bash");
  const ExecResult p =
      RunArgv({"/bin/bash", "-c", "source <('" BISTABLE_CLI "' completion bash); complete -p bistable"});
  ASSERT_EQ(p.exit_code, 0) << p.err;
  EXPECT_EQ(p.out, "complete -F _bistable bistable\n");

  EXPECT_EQ(Complete({"bistable", "ru"}, dir), std::vector<std::string>{"run"});
  const auto all = Complete({"bistable", ""}, dir);
  for (const char* cmd : {"point", "run", "map", "query", "identify", "completion"})
    EXPECT_NE(std::find(all.begin(), all.end(), cmd), all.end()) << cmd;
  EXPECT_EQ(Complete({"bistable", "run", "--no-p"}, dir), std::vector<std::string>{"--no-plots"});
  EXPECT_EQ(Complete({"bistable", "query", "abc", "--li"}, dir), std::vector<std::string>{"--limit"});
  EXPECT_EQ(Complete({"bistable", "map", "abc", "--met"}, dir), std::vector<std::string>{"--metric"});
  EXPECT_EQ(Complete({"bistable", "map", "abc", "--mar"}, dir), (std::vector<std::string>{"--mark", "--marks"}));
  // Every option of a command, flags and options with a value: those of `sweeps` exactly.
  EXPECT_EQ(Complete({"bistable", "sweeps", "--"}, dir),
            (std::vector<std::string>{"--help", "--insecure-remote", "--json", "--coordinator", "--data", "--tls-ca",
                                      "--token-file"}));

  // File names: a spec as run's positional, a data directory after --data.
  std::ofstream(dir + "/my spec.toml") << "name = \"x\"\n";
  fs::create_directories(dir + "/data_dir");
  EXPECT_EQ(Complete({"bistable", "run", "my"}, dir), std::vector<std::string>{"my spec.toml"});
  EXPECT_EQ(Complete({"bistable", "sweeps", "--data", "data_"}, dir), std::vector<std::string>{"data_dir"});
  EXPECT_EQ(Complete({"bistable", "map", "abc", "--marks", "my"}, dir), std::vector<std::string>{"my spec.toml"});
  EXPECT_EQ(Complete({"bistable", "identify", "--data", "-"}, dir), std::vector<std::string>{});

  // Another shell: refused, naming the argument and what is supported.
  const ExecResult zsh = RunArgv({BISTABLE_CLI, "completion", "zsh"});
  EXPECT_EQ(zsh.exit_code, 2);
  EXPECT_NE(zsh.err.find("shell = 'zsh' violates shell in {bash}"), std::string::npos) << zsh.err;
  const ExecResult junk = RunArgv({BISTABLE_CLI, "completion", std::string(5000, 'x') + "\n$(touch pwned)"}, dir);
  EXPECT_EQ(junk.exit_code, 2);
  EXPECT_LT(junk.err.size(), 400u) << junk.err;
  EXPECT_FALSE(fs::exists(dir + "/pwned"));
  fs::remove_all(dir);
}

}  // namespace
