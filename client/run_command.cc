// `bistable run SPEC.toml`: the embedded deployment — the sweep coordinator and worker threads in
// one process over a local data directory; with --shard I/N one slice of it into a shard store, and
// `bistable merge` to assemble the slices (client/shard_run.h).
#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <csignal>
#include <filesystem>
#include <iostream>
#include <memory>
#include <mutex>
#include <thread>

#include <nlohmann/json.hpp>

#include "base/cpus.h"
#include "base/validate.h"
#include "client/cli_common.h"
#include "client/embedded_run.h"
#include "client/map_slice.h"
#include "client/plot.h"
#include "client/progress.h"
#include "client/shard_run.h"
#include "client/sweep_commands.h"
#include "client/terms_report.h"
#include "dynamics/cancel.h"
#include "engine/evaluate.h"
#include "engine/json_shapes.h"
#include "engine/sweep_kind.h"
#include "net/http_server.h"
#include "server/dashboard.h"
#include "server/sweep_coordinator.h"
#include "storage/map_file.h"

namespace bistable {
namespace {

struct RunArgs {
  std::string spec_path;
  std::string data = kDefaultDataDir;
  int threads = 0;
  bool json = false, no_plots = false, quiet = false;
  std::string serve;  // dashboard address (loopback)
  long job_items = 0;
  std::string shard;                // "I/N": one slice into its shard store
  std::string plot_format = "png";  // the default figures: png, svg or pdf (docs/figures.md)
};

// `bistable run SPEC --shard I/N`: the shard's items into <data>/shards/<id>-<I>-of-<N>/ (client/shard_run.h).
int RunShardOf(const RunArgs& a, const SweepSpec& spec, int threads) {
  auto shard = ParseShard(a.shard);
  if (!shard.ok()) return Fail(shard.status());
  if (Status st = CheckShardable(spec); !st.ok()) return Fail(st);
  if (!a.serve.empty())
    return Fail(Status::InvalidArgument("serve",
                                        "--serve shows a coordinator's sweeps; a shard run has none (its "
                                        "store is assembled by bistable merge)"));
  const auto t0 = std::chrono::steady_clock::now();
  InstallCancelSignalHandlers("\nstopping: finished jobs are kept (press Ctrl-C again to quit at once)\n");
  ShardRunResult r;
  const Status st = RunShard(spec, *shard, a.data, threads, a.job_items, !a.quiet && !a.json, &r);
  RestoreDefaultSignalHandlers();
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  if (!st.ok() && CancelRequested()) {
    std::cerr << "interrupted: " << r.cached + r.computed << "/" << r.items << " items of shard " << shard->Label()
              << " stored in " << r.store << "; rerun the same command to resume\n";
    return CancelExitStatus();
  }
  if (!st.ok()) {
    std::cerr << "error: " << st.ToString() << "\n";
    if (!r.store.empty())
      std::cerr << "finished jobs are stored in " << r.store << "; rerun the same command to resume\n";
    return kExitError;
  }
  if (a.json) {
    const nlohmann::json j = {{"id", spec.Id()},    {"shard", shard->Label()}, {"store", r.store},
                              {"items", r.items},   {"cached", r.cached},      {"computed", r.computed},
                              {"seconds", seconds}, {"threads", threads},      {"complete", true}};
    std::cout << DumpJson(j, 2) << "\n";
  } else {
    std::printf("shard %s of sweep %s done: %ld items (%ld computed, %ld reused from its store) in %.1f s\n",
                shard->Label().c_str(), spec.Id().c_str(), r.items, r.computed, r.cached, seconds);
    std::printf("store: %s\nwhen every shard is done: bistable merge %s --data %s\n", r.store.c_str(),
                a.spec_path.c_str(), a.data.c_str());
  }
  return 0;
}

// --serve: the dashboard over this process's coordinator on a loopback address (it has no tokens).
Status StartDashboard(const std::string& serve, SweepCoordinator* c, const TokenStore* tokens,
                      std::unique_ptr<HttpServer>* dashboard) {
  if (!IsLoopbackAddress(serve))
    return Status::InvalidArgument("serve", serve +
                                                " is not a loopback address (the embedded dashboard has no tokens; "
                                                "use bistable-coordinator --http with TLS and tokens to serve others)");
  auto h = HttpServer::Start(serve, DashboardRoutes(c, tokens), DashboardHttpOptions());
  if (!h.ok()) return h.status();
  *dashboard = std::move(h).value();
  std::cerr << "dashboard on http://" << serve.substr(0, serve.rfind(':')) << ":" << (*dashboard)->port() << "/"
            << std::endl;
  return Status::Ok();
}

// The default figures of the map at `path` beside it (appended to files), or without gnuplot one
// warning saying so.
void AddDefaultPlots(const RunArgs& a, const SweepSpec& spec, const std::string& path, std::vector<std::string>* files,
                     std::vector<std::string>* warnings) {
  // The map is the product; figures are a view of it. Without gnuplot: one warning saying what is
  // missing and where the map is, and success (exit 0).
  if (Status g = CheckGnuplot(); !g.ok()) {
    warnings->push_back("no plots: " + g.message() + ", or pass --no-plots; the map is written to " + path);
    std::cerr << "warning: " << warnings->back() << "\n";
  } else {
    const auto plot_dir = std::filesystem::path(path).replace_extension("").string();
    for (auto& f : RenderDefaultPlots(spec, path, plot_dir, a.plot_format, !a.quiet && !a.json)) files->push_back(f);
  }
}

// A basin map: each attractor's share of the starts (the map's group attractors holds them too);
// none for other sweeps.
std::vector<BasinShare> BasinSharesOf(const SweepSpec& spec, const std::string& path) {
  std::vector<BasinShare> basins;
  if (spec.IsBasinSweep()) {
    auto att = ReadMapMetric(path, "attractor");
    if (att.ok()) basins = BasinShares(*att);
  }
  return basins;
}

// The dashboard after the sweep: serves until Ctrl-C / SIGTERM.
void ServeUntilCancelled() {
  std::fflush(stdout);
  std::cerr << "dashboard: the sweep is done; serving until Ctrl-C" << std::endl;
  InstallCancelSignalHandlers();
  while (!CancelRequested()) std::this_thread::sleep_for(std::chrono::milliseconds(100));
  RestoreDefaultSignalHandlers();
}

int RunSweep(const RunArgs& a) {
  auto spec = LoadClientSweepSpec(a.spec_path);
  if (!spec.ok()) return Fail(spec.status());
  if (a.threads < 0 || a.threads > 1024)
    return Fail(Status::InvalidArgument("threads",
                                        "threads = " + std::to_string(a.threads) + " violates threads in [0, 1024]"));
  if (!a.shard.empty()) return RunShardOf(a, *spec, a.threads > 0 ? a.threads : UsableCpus());
  auto coord = SweepCoordinator::Open(a.data, EmbeddedCoordinatorOptions());
  if (!coord.ok()) return Fail(coord.status());
  SweepCoordinator& c = **coord;
  // --serve: the dashboard over this process's coordinator (no tokens: loopback only).
  const TokenStore open_tokens;
  std::unique_ptr<HttpServer> dashboard;
  if (!a.serve.empty())
    if (Status st = StartDashboard(a.serve, &c, &open_tokens, &dashboard); !st.ok()) return Fail(st);
  const auto t0 = std::chrono::steady_clock::now();
  auto plan = c.Submit(*spec, a.job_items > 0 ? a.job_items : JobItems(*spec, 0.25));
  if (!plan.ok()) return Fail(plan.status());
  const auto t_planned = std::chrono::steady_clock::now();
  const int threads = a.threads > 0 ? a.threads : UsableCpus();
  const long to_compute = plan->items_total - plan->items_cached;
  if (!a.quiet && !a.json) {
    std::cerr << "sweep " << plan->id << (spec->name.empty() ? "" : " (" + spec->name + ")") << ": " << spec->points()
              << " points x " << spec->ic_count() << " initial condition(s); " << plan->items_cached
              << " reused from the cache, " << to_compute << " to compute on " << threads << " thread(s)\n";
  }

  // Ctrl-C / SIGTERM: the computing jobs stop within about a millisecond of kernel work
  // (dynamics/cancel.h), are released unreported, and every job already stored stays stored.
  InstallCancelSignalHandlers("\nstopping: finished jobs are kept (press Ctrl-C again to quit at once)\n");
  EmbeddedRunStats run;
  auto path = ComputeAndPublish(c, *spec, threads, !a.quiet && !a.json, "sweep " + plan->id, &run);
  RestoreDefaultSignalHandlers();
  if (!path.ok() && CancelRequested()) {
    const SweepProgress p = c.progress(plan->id);
    std::cerr << "interrupted: " << p.items_done << "/" << p.items_total
              << " items stored; rerun the same command to resume\n";
    return CancelExitStatus();
  }
  if (!path.ok()) {
    std::cerr << "error: " << path.status().ToString() << "\n"
              << "finished blocks are stored; rerun the same command to resume\n";
    return kExitError;
  }
  const auto t_published = std::chrono::steady_clock::now();
  const auto t_computed = t_published - std::chrono::duration_cast<std::chrono::steady_clock::duration>(
                                            std::chrono::duration<double>(run.publish_seconds));
  const long computed = run.computed, items = run.items;
  const double seconds = std::chrono::duration<double>(t_published - t0).count();
  auto secs = [](auto a, auto b) { return std::chrono::duration<double>(b - a).count(); };
  std::vector<std::string> files = {*path};
  std::vector<std::string> warnings;
  if (!a.no_plots) AddDefaultPlots(a, *spec, *path, &files, &warnings);
  const std::vector<BasinShare> basins = BasinSharesOf(*spec, *path);
  if (a.json) {
    nlohmann::json j = {{"id", plan->id},
                        {"data", std::filesystem::absolute(a.data).string()},
                        {"files", files},
                        {"points", spec->points()},
                        {"items", items},
                        {"cached", items - computed},
                        {"computed", computed},
                        {"seconds", seconds},
                        {"points_per_second", seconds > 0 ? static_cast<double>(computed) / seconds : 0.0},
                        {"threads", threads},
                        {"timing",
                         {{"plan", secs(t0, t_planned)},
                          {"compute", secs(t_planned, t_computed)},
                          {"publish", secs(t_computed, t_published)}}}};
    if (!warnings.empty()) j["warnings"] = warnings;
    if (!basins.empty()) {
      j["attractors"] = nlohmann::json::array();
      for (const BasinShare& b : basins)
        j["attractors"].push_back({{"id", b.id}, {"name", b.name}, {"basin_fraction", b.fraction}});
    }
    std::cout << DumpJson(j, 2) << "\n";
  } else {
    std::printf(
        "sweep %s done: %ld points x %d = %ld items (%ld computed, %ld reused) in %.1f s, %.0f computed items/s\n",
        plan->id.c_str(), spec->points(), spec->ic_count(), items, computed, items - computed, seconds,
        seconds > 0 ? static_cast<double>(computed) / seconds : 0.0);
    if (KindOf(*spec).InRounds())
      std::printf("refined map: %ld of %ld grid points integrated (%.1f %% of the uniform grid), the rest filled\n",
                  items, spec->points(), 100.0 * static_cast<double>(items) / static_cast<double>(spec->points()));
    if (!basins.empty()) {
      std::printf("basins:");
      for (size_t i = 0; i < basins.size(); ++i)
        std::printf("%s %s %.1f %%", i ? ";" : "", basins[i].name.c_str(), 100 * basins[i].fraction);
      std::printf("\n");
    }
    std::printf("map: %s\n", path->c_str());
    for (size_t i = 1; i < files.size(); ++i) std::printf("plot: %s\n", files[i].c_str());
  }
  if (dashboard) ServeUntilCancelled();  // the sweep is done; its maps stay on view until Ctrl-C / SIGTERM
  return 0;
}

int MergeSweep(const std::string& spec_path, const std::vector<std::string>& stores, const std::string& data,
               bool json) {
  auto spec = LoadClientSweepSpec(spec_path);
  if (!spec.ok()) return Fail(spec.status());
  const auto t0 = std::chrono::steady_clock::now();
  auto merged = MergeShards(*spec, stores, data);
  if (!merged.ok()) return Fail(merged.status());
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  if (json) {
    const nlohmann::json j = {{"id", merged->id},       {"data", std::filesystem::absolute(data).string()},
                              {"files", {merged->map}}, {"shards", merged->shards},
                              {"items", merged->items}, {"seconds", seconds}};
    std::cout << DumpJson(j, 2) << "\n";
  } else {
    std::printf("sweep %s merged from %d shards: %ld items in %.1f s\nmap: %s\n", merged->id.c_str(), merged->shards,
                merged->items, seconds, merged->map.c_str());
  }
  return 0;
}

}  // namespace

void AddMergeCommand(CLI::App& app, int* exit_code) {
  struct MergeArgs {
    std::string spec_path, data = kDefaultDataDir;
    std::vector<std::string> stores;
    bool json = false;
  };
  auto a = std::make_shared<MergeArgs>();
  CLI::App* cmd = app.add_subcommand(
      "merge", "Assemble the shard stores of `bistable run SPEC --shard I/N` into the sweep's map (a job array's end)");
  cmd->add_option("spec", a->spec_path, "the sweep spec (TOML) the shards were run with")->required();
  cmd->add_option("stores", a->stores,
                  "shard store directories (default: every <data>/shards/<id>-* store of this spec)");
  cmd->add_option("--data", a->data, "data directory the map is written to and indexed in (sweeps/<id>.h5)")
      ->capture_default_str();
  cmd->add_flag("--json", a->json, "print {id, data, files, shards, items, seconds} as JSON");
  cmd->footer(
      "The map is the one `bistable run SPEC` writes, bit for bit (every dataset and attribute), but for its\n"
      "provenance: the root attribute merged_from_shards = N and the history line say it was merged (history also\n"
      "carries the time it was written). The records are added to the data directory's point cache too.\n"
      "Refused, naming the store and the problem, with nothing written: a directory that is not a shard store, a\n"
      "shard of another spec or of another numerics version, stores of different shard counts, a shard given\n"
      "twice, a shard missing, or a shard incomplete (interrupted: rerun its `bistable run --shard I/N`).\n"
      "No plots: draw them from the map (bistable map ID --data DIR).");
  cmd->callback([a, exit_code]() { *exit_code = MergeSweep(a->spec_path, a->stores, a->data, a->json); });
}

void AddRunCommand(CLI::App& app, int* exit_code) {
  auto a = std::make_shared<RunArgs>();
  CLI::App* cmd = app.add_subcommand("run", "Run a sweep embedded in this process (all cores) and write its maps");
  cmd->add_option("spec", a->spec_path, "sweep spec (TOML), e.g. examples/paper_fig8_frf.toml")->required();
  cmd->add_option("--data", a->data, "data directory (index.sqlite, sweeps/*.h5, plots)")->capture_default_str();
  cmd->add_option("--threads", a->threads,
                  "worker threads (0 = the CPUs this process may use: affinity and cgroup quota)")
      ->capture_default_str();
  cmd->add_option("--job-items", a->job_items, "items per job (0 = about 0.25 s of work)");
  cmd->add_flag("--json", a->json, "print {id, data, files, points, seconds, ...} as JSON");
  cmd->add_flag("--no-plots", a->no_plots,
                "do not render the default plots (without gnuplot they are skipped with a warning)");
  cmd->add_flag("--quiet", a->quiet, "no progress output");
  cmd->add_option("--plot-format", a->plot_format,
                  "format of the default figures: png, svg (vector, editable text) or pdf (vector; docs/figures.md)")
      ->check(CLI::IsMember({"png", "svg", "pdf"}))
      ->capture_default_str();
  cmd->add_option("--shard", a->shard,
                  "I/N: compute only shard I of N of the sweep (0 <= I < N; a job array's task) into its own store, "
                  "<data>/shards/<id>-<I>-of-<N>/; then bistable merge assembles the map")
      ->type_name("I/N");
  cmd->add_option("--serve", a->serve,
                  "serve the live dashboard on HOST:PORT (loopback; docs/dashboard.md) while the sweep runs and, "
                  "after it is done, until Ctrl-C");
  cmd->footer(
      "Re-running a spec reuses every stored point (content-keyed), so an interrupted sweep resumes\n"
      "where it stopped and overlapping sweeps only compute what is new. Ctrl-C (or SIGTERM) stops within\n"
      "a second and keeps every finished job (exit status 130, 143 for SIGTERM); a second Ctrl-C quits at once.\n\n"
      "Integrators ([integration] integrator in the spec; docs/sweep-spec.md): rk4, the paper's, the default of\n"
      "the non-dimensional models; adaptive (Dormand-Prince, one point at a time); rosenbrock, the rig's default\n"
      "(model = \"dimensional\": ROS34PW2 in lanes, 10.8-16.6x faster than Dormand-Prince at its accuracy). The rig "
      "with\n"
      "rk4 is 2x faster again but off a converged reference: periods equal on 72 % of the example's points, LLEs\n"
      "within 0.05 /s on 58 % (measured: docs/numerics.md, bench/rig_ratio.sh).\n\n"
      "Job arrays (--shard I/N; deploy/slurm/README.md, array.sbatch): for clusters that allow no service or\n"
      "open port on compute nodes. Each task computes a deterministic slice (items dealt round-robin; continuation\n"
      "chains whole) into its own store, with no map and no plots; a rerun resumes it. `bistable merge SPEC`\n"
      "assembles the N stores into the map this command writes without --shard, bit for bit. Refined sweeps\n"
      "([refine]) cannot be sharded: each round is planned from the whole previous round.");
  cmd->callback([a, exit_code]() { *exit_code = RunSweep(*a); });
}

}  // namespace bistable
