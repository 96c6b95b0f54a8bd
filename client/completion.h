// `bistable completion bash`: a bash completion script generated from the CLI11 definition of the commands.
#ifndef BISTABLE_CLIENT_COMPLETION_H_
#define BISTABLE_CLIENT_COMPLETION_H_

#include <string>

#include <CLI/CLI.hpp>

namespace bistable {

// The bash completion script of `app` (the whole `bistable` CLI): its commands, each command's flags (options
// without a value) and options (with one), walked from the App's subcommands and options (option groups
// included), so a command or flag added to the CLI is completed without editing a list. A word after an
// option that takes a value, and a command's positional arguments (spec files, data files, ids), complete
// as file names. Defines the function _bistable and `complete -F _bistable bistable`. Names that are not
// plain words ([A-Za-z0-9_.-]) are left out: nothing from the definition reaches the script unquoted.
std::string BashCompletionScript(const CLI::App& app, const std::string& program = "bistable");

// Adds `bistable completion SHELL` (SHELL: bash) to `app`; it prints the script for the app as defined when
// the command runs (after every other command was added).
void AddCompletionCommand(CLI::App& app, int* exit_code);

}  // namespace bistable

#endif  // BISTABLE_CLIENT_COMPLETION_H_
