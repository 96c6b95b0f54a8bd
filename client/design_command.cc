// `bistable design SPEC.toml`: the design search (issue 17). Candidates are sweeps, embedded here or
// on a coordinator (--coordinator); the report is text (or --json) plus a report directory.
#include <cstdio>
#include <iostream>
#include <memory>
#include <optional>
#include <sstream>

#include <toml++/toml.h>
#include <CLI/CLI.hpp>

#include "base/file.h"
#include "base/limits.h"
#include "client/cli_common.h"
#include "client/design_command.h"
#include "client/design_run.h"
#include "client/plot.h"
#include "dynamics/cancel.h"
#include "engine/json_shapes.h"

namespace bistable {
namespace {

struct DesignArgs {
  std::string spec_path;
  DesignRunOptions run;
  std::optional<long> budget, seed, maps;
  std::string optimizer;
  bool json = false, quiet = false, no_plots = false;
};

// The spec with the flags that override [design] fields written into it: the same checks, naming the field.
StatusOr<DesignSpec> LoadWithFlags(const DesignArgs& a) {
  auto text = ReadTextFile(a.spec_path, "spec", limits::kMaxSpecBytes);
  if (!text.ok()) return text.status();
  if (!a.budget && !a.seed && !a.maps && a.optimizer.empty()) return ParseDesignSpec(*text, a.spec_path);
  toml::table t;
  try {
    t = toml::parse(*text, a.spec_path);
  } catch (const toml::parse_error&) {
    return ParseDesignSpec(*text, a.spec_path);  // its message says where
  }
  if (!t.contains("design")) t.insert("design", toml::table{});
  toml::table& d = *t["design"].as_table();
  if (a.budget) d.insert_or_assign("budget", static_cast<int64_t>(*a.budget));
  if (a.seed) d.insert_or_assign("seed", static_cast<int64_t>(*a.seed));
  if (a.maps) d.insert_or_assign("maps", static_cast<int64_t>(*a.maps));
  if (!a.optimizer.empty()) d.insert_or_assign("optimizer", a.optimizer);
  std::ostringstream os;
  os << t;
  return ParseDesignSpec(os.str(), a.spec_path);
}

void PrintCandidate(const char* label, const nlohmann::json& c) {
  const auto& d = c["design"];
  std::printf(
      "%s lambda = %.4g, phi = %.4g, eta_r = %.4g: band %.4g wide (Omega %s .. %s), chaotic share in band %.3g "
      "(unsafe %.3g), over the line %.3g%s%s\n",
      label, d["lambda"].get<double>(), d["phi"].get<double>(), d["eta_r"].get<double>(), c["band_width"].get<double>(),
      c["band"][0].is_null() ? "-" : PlotNumber(c["band"][0].get<double>()).c_str(),
      c["band"][1].is_null() ? "-" : PlotNumber(c["band"][1].get<double>()).c_str(),
      c["chaotic_share_band"].get<double>(), c["unsafe_share_band"].get<double>(), c["chaotic_share"].get<double>(),
      c.contains("sweep_id") ? ", sweep " : "", c.contains("sweep_id") ? c["sweep_id"].get<std::string>().c_str() : "");
}

int Design(DesignArgs& a) {
  auto spec = LoadWithFlags(a);
  if (!spec.ok()) return Fail(spec.status());
  a.run.progress = !a.quiet && !a.json;
  a.run.plots = !a.no_plots;
  if (a.run.progress)
    std::cerr << "design " << spec->id << ": " << spec->budget << " candidates x "
              << spec->alphas.size() * spec->omega.size() << " points (" << spec->optimizer << ")"
              << (a.run.coordinator.empty() ? "" : " on " + a.run.coordinator) << "\n";
  InstallCancelSignalHandlers("\nstopping: finished candidates are kept (press Ctrl-C again to quit at once)\n");
  auto j = RunDesign(*spec, a.run);
  RestoreDefaultSignalHandlers();
  if (!j.ok()) {
    if (CancelRequested()) {
      std::cerr << "interrupted: every finished candidate is cached; rerun the same command to resume\n";
      return CancelExitStatus();
    }
    return Fail(j.status());
  }
  if (a.json) {
    std::cout << DumpJson(*j, 2) << "\n";
    return kExitOk;
  }
  const auto& s = (*j)["search"];
  std::printf("design %s: %ld candidates, %ld points (%ld computed, %ld reused) in %.2f s\n", spec->id.c_str(),
              s["candidates"].get<long>(), s["points"].get<long>(), s["computed"].get<long>(), s["cached"].get<long>(),
              s["seconds"].get<double>());
  if ((*j)["best"].is_null())
    std::printf("best: none (no candidate has a band without chaotic points)\n");
  else
    PrintCandidate("best:", (*j)["best"]);
  std::printf(
      "Pareto front (band width up, unsafe (chaotic or diverged) share in band down, %s down): %zu candidates\n",
      spec->cost.c_str(), (*j)["front"].size());
  for (const auto& c : (*j)["front"]) PrintCandidate("  ", c);
  for (const auto& m : (*j)["maps"])
    std::printf("map of best #%d: sweep %s (%ld points, %ld computed)\n", m["rank"].get<int>(),
                m["sweep_id"].get<std::string>().c_str(), m["points"].get<long>(), m["computed"].get<long>());
  if (j->contains("brute_force")) {
    const auto& b = (*j)["brute_force"];
    std::printf(
        "brute force %d^k grid: %ld designs, %ld points (%ld computed) in %.2f s; search/grid: points %.3g, time "
        "%.3g\n",
        b["n"].get<int>(), b["designs"].get<long>(), b["points"].get<long>(), b["computed"].get<long>(),
        b["seconds"].get<double>(), b["points_ratio"].get<double>(), b["time_ratio"].get<double>());
    if (!b["best"].is_null()) PrintCandidate("grid best:", b["best"]);
    std::printf("search best at least as good as the grid's: %s\n",
                b["search_at_least_as_good"].get<bool>() ? "yes" : "no");
  }
  if (j->contains("warnings"))
    for (const auto& w : (*j)["warnings"]) std::fprintf(stderr, "warning: %s\n", w.get<std::string>().c_str());
  std::printf("report: %s\n", (*j)["report_dir"].get<std::string>().c_str());
  return kExitOk;
}

}  // namespace

void AddDesignCommand(CLI::App& app, int* exit_code) {
  auto a = std::make_shared<DesignArgs>();
  CLI::App* cmd = app.add_subcommand(
      "design", "Search resonator designs (lambda, phi, eta_r) for the widest attenuation band without chaos");
  cmd->add_option("spec", a->spec_path, "design spec (TOML with a [design] table), e.g. examples/design_band.toml")
      ->required();
  cmd->add_option("--data", a->run.data, "data directory (cache, candidate maps; the report goes to DATA/designs/ID)")
      ->capture_default_str();
  cmd->add_option("--out", a->run.out, "report directory (default DATA/designs/<design id>)");
  cmd->add_option("--threads", a->run.threads, "worker threads (0 = the CPUs this process may use)")
      ->capture_default_str();
  cmd->add_option("--coordinator", a->run.coordinator, "run every candidate on this coordinator instead of embedded");
  cmd->add_option("--token-file", a->run.token_file, "file holding a bearer token (else $BISTABLE_TOKEN)");
  cmd->add_option("--tls-ca", a->run.tls_ca, "PEM CA certificate to verify a TLS coordinator");
  cmd->add_flag("--insecure-remote", a->run.insecure_remote,
                "send the token in plaintext to an address that is not loopback (refused otherwise)");
  cmd->add_option("--budget", a->budget, "candidates (overrides design.budget)");
  cmd->add_option("--seed", a->seed, "seed (overrides design.seed; crs2 only)");
  cmd->add_option("--maps", a->maps, "maps of the best designs, 0-3 (overrides design.maps)");
  cmd->add_option("--optimizer", a->optimizer, "direct-l | crs2 (overrides design.optimizer)");
  cmd->add_option("--brute-force", a->run.brute_force,
                  "also run an N per free parameter grid in this run and compare (N in [2, 64])");
  cmd->add_flag("--json", a->json, "print the report (front, best, every candidate with its sweep id, cost) as JSON");
  cmd->add_flag("--no-plots", a->no_plots, "no figures (Pareto front, best designs' maps)");
  cmd->add_flag("--quiet", a->quiet, "no progress output");
  cmd->footer(
      "Every candidate is an ordinary sweep, cached by content key: running the same search again (after\n"
      "Ctrl-C or kill -9) recomputes nothing it already computed and continues with the rest.\n"
      "Definitions and measured costs: docs/design-search.md.");
  cmd->callback([a, exit_code]() { *exit_code = Design(*a); });
}

}  // namespace bistable
