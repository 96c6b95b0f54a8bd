// bistable: the command-line client (composition root).
#include <signal.h>

#include <iostream>

#include <CLI/CLI.hpp>

#include "base/exit_codes.h"
#include "base/names.h"
#include "base/version.h"
#include "client/chirp_command.h"
#include "client/completion.h"
#include "client/design_command.h"
#include "client/hbm_command.h"
#include "client/identify_command.h"
#include "client/point_command.h"
#include "client/remote_commands.h"
#include "client/reproduce_command.h"
#include "client/sweep_commands.h"
#include "dynamics/point_spec.h"

int main(int argc, char** argv) {
  // A reader that goes away (gnuplot exiting early, `| head`) makes the write fail with EPIPE, to be
  // reported as an error, instead of killing the client.
  struct sigaction ignore_pipe {};
  ignore_pipe.sa_handler = SIG_IGN;
  sigemptyset(&ignore_pipe.sa_mask);
  sigaction(SIGPIPE, &ignore_pipe, nullptr);
  CLI::App app{"bistable-sweep: maps of bistable (snap-through) oscillators, alone or with a tuned resonator"};
  // The software's version (CMake's project version, as the map files' software_version and bistable.__version__),
  // then the numerics version that keys stored results.
  app.set_version_flag("--version", std::string("bistable ") + bistable::kSoftwareVersion + " (numerics " +
                                        bistable::kNumericsVersion + ")");
  app.require_subcommand(1);
  int exit_code = 0;
  bistable::AddPointCommand(app, &exit_code);
  bistable::AddRunCommand(app, &exit_code);
  bistable::AddMergeCommand(app, &exit_code);
  bistable::AddHbmCommand(app, &exit_code);
  bistable::AddChirpCommand(app, &exit_code);
  bistable::AddReproduceCommand(app, &exit_code);
  bistable::AddDesignCommand(app, &exit_code);
  bistable::AddIdentifyCommand(app, &exit_code);
  bistable::AddRemoteCommands(app, &exit_code);
  bistable::AddSweepsCommand(app, &exit_code);
  bistable::AddMapCommand(app, &exit_code);
  bistable::AddQueryCommand(app, &exit_code);
  bistable::AddInfoCommand(app, &exit_code);
  bistable::AddCompletionCommand(app, &exit_code);  // last: its script walks every command above
  const auto subs = app.get_subcommands([](CLI::App*) { return true; });
  auto is_known = [&](const std::string& name) {
    for (const CLI::App* sub : subs)
      if (sub->get_name() == name) return true;
    return false;
  };
  if (argc > 1 && argv[1][0] != '-' && !is_known(argv[1])) {
    std::string known;
    for (const CLI::App* sub : subs) known += (known.empty() ? "" : ", ") + sub->get_name();
    std::cerr << "error: invalid argument (command: '" << bistable::Printable(argv[1], 64) << "' is not one of {"
              << known << "})\n";
    return bistable::kExitError;
  }
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
    return bistable::kExitError;
  } catch (const std::exception& e) {  // a defect or exhausted memory: said, not an abort (files are atomic)
    std::cerr << "error: internal (" << bistable::Printable(e.what(), 200) << ")\n";
    return bistable::kExitError;
  }
  return exit_code;
}
