// bistable: the command-line client (composition root).
#include <iostream>

#include <CLI/CLI.hpp>

#include "client/point_command.h"
#include "dynamics/point_spec.h"

int main(int argc, char** argv) {
  CLI::App app{"bistable-sweep: maps of bistable (snap-through) oscillators, alone or with a tuned resonator"};
  app.set_version_flag("--version", std::string("bistable ") + bistable::kNumericsVersion);
  app.require_subcommand(1);
  int exit_code = 0;
  bistable::AddPointCommand(app, &exit_code);
  try {
    app.parse(argc, argv);
  } catch (const CLI::CallForHelp& e) {
    return app.exit(e);
  } catch (const CLI::CallForAllHelp& e) {
    return app.exit(e);
  } catch (const CLI::CallForVersion& e) {
    return app.exit(e);
  } catch (const CLI::ParseError& e) {
    std::cerr << "error: " << e.what() << "\n";
    std::cerr << "run with --help for usage\n";
    return 2;
  }
  return exit_code;
}
