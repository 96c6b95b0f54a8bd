// `bistable design`: the design search command (client/design_run.h does the work).
#ifndef BISTABLE_CLIENT_DESIGN_COMMAND_H_
#define BISTABLE_CLIENT_DESIGN_COMMAND_H_

#include <CLI/CLI.hpp>

namespace bistable {

void AddDesignCommand(CLI::App& app, int* exit_code);

}  // namespace bistable

#endif  // BISTABLE_CLIENT_DESIGN_COMMAND_H_
