// `bistable run SPEC.toml`: the embedded deployment — the sweep coordinator and worker threads in
// one process over a local data directory.
#include <algorithm>
#include <cmath>
#include <csignal>
#include <atomic>
#include <chrono>
#include <filesystem>
#include <iostream>
#include <memory>
#include <mutex>
#include <thread>

#include <nlohmann/json.hpp>

#include "client/cli_common.h"
#include "dynamics/validate.h"
#include "client/map_slice.h"
#include "client/plot.h"
#include "client/progress.h"
#include "client/sweep_commands.h"
#include "server/sweep_coordinator.h"
#include "storage/map_file.h"
#include "worker/block_worker.h"

namespace bistable {
namespace {

std::atomic<bool> g_interrupted{false};
extern "C" void OnSignal(int) { g_interrupted.store(true); }

struct RunArgs {
  std::string spec_path;
  std::string data = kDefaultDataDir;
  int threads = 0;
  bool json = false, no_plots = false, quiet = false;
  long job_items = 0;
};

// Items per job: about `seconds` of work on one core, a multiple of the lane width.
long JobItems(const SweepSpec& spec, double seconds) {
  const double steps = spec.base.integration.t_end / spec.base.integration.dt;
  const double per_item = steps / 1.5e7;  // ≈ 15 M lane-steps/s/core including metrics (conservative)
  long n = static_cast<long>(seconds / std::max(per_item, 1e-9));
  n = std::clamp<long>(n, kSweepLanes, 4096);
  return (n / kSweepLanes) * kSweepLanes;
}

// Default figures: each plotted metric over the two longest axes, one figure per value of the others
// (at most 12); a single-axis sweep gives curves, and with hd_peaks over Ω the Fig. 6 scatter.
std::vector<std::string> RenderDefaultPlots(const SweepSpec& spec, const std::string& map_path, const std::string& dir) {
  std::vector<std::string> files;
  std::filesystem::create_directories(dir);
  std::vector<size_t> order(spec.axes.size());
  for (size_t i = 0; i < order.size(); ++i) order[i] = i;
  std::stable_sort(order.begin(), order.end(),
                   [&](size_t a, size_t b) { return spec.axes[a].values.size() > spec.axes[b].values.size(); });
  std::vector<size_t> free(order.begin(), order.begin() + std::min<size_t>(2, order.size()));
  std::vector<size_t> others(order.begin() + free.size(), order.end());
  long combos = 1;
  for (size_t k : others) combos *= static_cast<long>(spec.axes[k].values.size());
  combos = std::min<long>(combos, 12);
  for (const std::string& metric : spec.plots) {
    auto m = ReadMapMetric(map_path, metric);
    if (!m.ok()) {
      std::cerr << "warning: plot " << metric << ": " << m.status().ToString() << "\n";
      continue;
    }
    for (long c = 0; c < combos; ++c) {
      std::map<std::string, double> at;
      std::string suffix;
      long rest = c;
      for (size_t k : others) {
        const auto& vals = spec.axes[k].values;
        const double v = vals[rest % static_cast<long>(vals.size())];
        rest /= static_cast<long>(vals.size());
        at[spec.axes[k].name] = v;
        suffix += "_" + spec.axes[k].name + "=" + FormatNumber(v);
      }
      auto slice = SliceMap(*m, at, 2);
      if (!slice.ok()) continue;
      if (std::none_of(slice->values.begin(), slice->values.end(), [](double v) { return std::isfinite(v); })) continue;
      PlotData d;
      d.metric = metric;
      d.unit = slice->unit;
      d.motion = metric == "motion";
      for (const Axis& a : slice->free) d.axis_names.push_back(a.name), d.axis_units.push_back(AxisUnit(a.name)), d.axis_values.push_back(a.values);
      d.values = slice->values;
      d.title = (spec.name.empty() ? spec.Id() : spec.name) + ": " + metric + suffix;
      const std::string out = (std::filesystem::path(dir) / (metric + suffix + ".png")).string();
      Status st = RenderPlot(d, out);
      if (st.ok()) files.push_back(out);
      else std::cerr << "warning: " << st.ToString() << "\n";
    }
  }
  // Fig. 6: one harmonic-diffusion scatter per combination of the axes other than omega (at most 3,
  // like the paper's two amplitudes; `bistable map ID --metric hd_scatter --at ...` draws any other).
  const bool has_peaks = std::find(spec.metrics.begin(), spec.metrics.end(), "hd_peaks") != spec.metrics.end();
  size_t omega_axis = spec.axes.size();
  for (size_t k = 0; k < spec.axes.size(); ++k)
    if (spec.axes[k].name == "omega") omega_axis = k;
  long scatter_combos = 1;
  for (size_t k = 0; k < spec.axes.size(); ++k)
    if (k != omega_axis) scatter_combos *= static_cast<long>(spec.axes[k].values.size());
  if (has_peaks && omega_axis < spec.axes.size() && scatter_combos <= 3 && spec.ic_count() == 1) {
    auto f = ReadMapMetric(map_path, "hd_peak_freq");
    auto a = ReadMapMetric(map_path, "hd_peak_amp");
    if (f.ok() && a.ok()) {
      const size_t k_peaks = f->dims.back();
      for (long c = 0; c < scatter_combos; ++c) {
        ScatterData sd;
        sd.title = (spec.name.empty() ? spec.Id() : spec.name) + ": harmonic diffusion";
        std::string suffix;
        long rest = c;
        std::vector<size_t> fixed(spec.axes.size(), 0);
        for (long k = static_cast<long>(spec.axes.size()) - 1; k >= 0; --k) {
          if (static_cast<size_t>(k) == omega_axis) continue;
          const long n = static_cast<long>(spec.axes[k].values.size());
          fixed[k] = static_cast<size_t>(rest % n);
          rest /= n;
          suffix += "_" + spec.axes[k].name + "=" + FormatNumber(spec.axes[k].values[fixed[k]]);
          sd.title += ", " + spec.axes[k].name + " = " + FormatNumber(spec.axes[k].values[fixed[k]]);
        }
        for (size_t i = 0; i < spec.axes[omega_axis].values.size(); ++i) {
          fixed[omega_axis] = i;
          long point = 0;
          for (size_t k = 0; k < spec.axes.size(); ++k) point = point * static_cast<long>(spec.axes[k].values.size()) + static_cast<long>(fixed[k]);
          for (size_t j = 0; j < k_peaks; ++j) {
            const size_t off = static_cast<size_t>(point) * k_peaks + j;
            if (std::isfinite(f->values[off]))
              sd.x.push_back(spec.axes[omega_axis].values[i]), sd.y.push_back(f->values[off]), sd.amp.push_back(a->values[off]);
          }
        }
        const std::string out = (std::filesystem::path(dir) / ("hd_scatter" + suffix + ".png")).string();
        if (RenderHdScatter(sd, out).ok()) files.push_back(out);
      }
    }
  }
  // Fig. 4: bifurcation diagrams, one per combination of the axes other than the continued one (≤ 6).
  if (spec.continuation.enabled() && spec.base.metrics.turning_points) {
    auto tp = ReadMapMetric(map_path, "turning_points");
    size_t cont = 0;
    for (size_t k = 0; k < spec.axes.size(); ++k)
      if (spec.axes[k].name == spec.continuation.axis) cont = k;
    long combos = 1;
    for (size_t k = 0; k < spec.axes.size(); ++k)
      if (k != cont) combos *= static_cast<long>(spec.axes[k].values.size());
    if (tp.ok() && combos <= 6) {
      const int nic = spec.ic_count();
      for (long c = 0; c < combos; ++c) {
        BifurcationData bd;
        bd.x_name = spec.continuation.axis;
        bd.x_unit = AxisUnit(spec.continuation.axis);
        bd.title = (spec.name.empty() ? spec.Id() : spec.name) + ": bifurcation diagram";
        std::string suffix;
        std::vector<size_t> fixed(spec.axes.size(), 0);
        long rest = c;
        for (long k = static_cast<long>(spec.axes.size()) - 1; k >= 0; --k) {
          if (static_cast<size_t>(k) == cont) continue;
          const long n = static_cast<long>(spec.axes[k].values.size());
          fixed[k] = static_cast<size_t>(rest % n);
          rest /= n;
          suffix += "_" + spec.axes[k].name + "=" + FormatNumber(spec.axes[k].values[fixed[k]]);
          bd.title += ", " + spec.axes[k].name + " = " + FormatNumber(spec.axes[k].values[fixed[k]]);
        }
        for (size_t i = 0; i < spec.axes[cont].values.size(); ++i) {
          fixed[cont] = i;
          long point = 0;
          for (size_t k = 0; k < spec.axes.size(); ++k) point = point * static_cast<long>(spec.axes[k].values.size()) + static_cast<long>(fixed[k]);
          for (int ic = 0; ic < nic; ++ic) {
            const bool down = spec.ChainGoesDown(ic);
            for (int k = 0; k < kTurningPointsStored; ++k) {
              const double y = tp->values[(static_cast<size_t>(point) * nic + ic) * kTurningPointsStored + k];
              if (!std::isfinite(y)) continue;
              (down ? bd.x_down : bd.x_up).push_back(spec.axes[cont].values[i]);
              (down ? bd.y_down : bd.y_up).push_back(y);
            }
          }
        }
        const std::string out = (std::filesystem::path(dir) / ("bifurcation" + suffix + ".png")).string();
        if (RenderBifurcation(bd, out).ok()) files.push_back(out);
      }
    }
  }
  return files;
}

int RunSweep(const RunArgs& a) {
  auto spec = LoadSweepSpec(a.spec_path);
  if (!spec.ok()) return Fail(spec.status());
  if (a.threads < 0 || a.threads > 1024) return Fail(Status::InvalidArgument("threads", "threads = " + std::to_string(a.threads) + " violates threads in [0, 1024]"));
  auto coord = SweepCoordinator::Open(a.data);
  if (!coord.ok()) return Fail(coord.status());
  SweepCoordinator& c = **coord;
  const auto t0 = std::chrono::steady_clock::now();
  auto plan = c.Submit(*spec, a.job_items > 0 ? a.job_items : JobItems(*spec, 0.25));
  if (!plan.ok()) return Fail(plan.status());
  const auto t_planned = std::chrono::steady_clock::now();
  const int threads = a.threads > 0 ? a.threads : static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
  const long to_compute = plan->items_total - plan->items_cached;
  if (!a.quiet && !a.json) {
    std::cerr << "sweep " << plan->id << (spec->name.empty() ? "" : " (" + spec->name + ")") << ": "
              << spec->points() << " points x " << spec->ic_count() << " initial condition(s); " << plan->items_cached
              << " reused from the cache, " << to_compute << " to compute on " << threads << " thread(s)\n";
  }

  std::signal(SIGINT, OnSignal);
  std::signal(SIGTERM, OnSignal);
  std::mutex err_mu;
  Status worker_error;
  std::atomic<bool> failed{false};
  std::vector<std::thread> pool;
  for (int t = 0; t < threads && to_compute > 0; ++t) {
    pool.emplace_back([&] {
      while (auto job = c.Lease()) {
        const std::vector<PointRecord> records = ComputeItems(*spec, job->items);
        Status st = c.Report(job->id, records);
        if (!st.ok()) {
          std::lock_guard<std::mutex> lock(err_mu);
          if (worker_error.ok()) worker_error = st;
          failed.store(true);
          c.Stop();
        }
      }
    });
  }
  ProgressBar bar(to_compute, "sweep " + plan->id, !a.quiet && !a.json);
  auto done = [&] { return c.progress().items_done - plan->items_cached; };
  while (!pool.empty()) {
    if (g_interrupted.load()) c.Stop();
    if (c.progress().items_done >= plan->items_total || g_interrupted.load() || failed.load()) break;
    bar.Update(done());
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
  }
  for (auto& th : pool) th.join();
  bar.Finish(done());
  std::signal(SIGINT, SIG_DFL);
  std::signal(SIGTERM, SIG_DFL);
  if (!worker_error.ok()) {
    c.MarkInterrupted();
    std::cerr << "error: " << worker_error.ToString() << "\n"
              << "finished blocks are stored; rerun the same command to resume\n";
    return kExitBadInput;
  }
  if (g_interrupted.load() || c.progress().items_done < plan->items_total) {
    c.MarkInterrupted();
    std::cerr << "interrupted: " << c.progress().items_done << "/" << plan->items_total
              << " items stored; rerun the same command to resume\n";
    return kExitInterrupted;
  }
  const auto t_computed = std::chrono::steady_clock::now();
  auto path = c.Publish();
  if (!path.ok()) return Fail(path.status());
  const auto t_published = std::chrono::steady_clock::now();
  const double seconds = std::chrono::duration<double>(t_published - t0).count();
  auto secs = [](auto a, auto b) { return std::chrono::duration<double>(b - a).count(); };
  std::vector<std::string> files = {*path};
  if (!a.no_plots) {
    const auto plot_dir = std::filesystem::path(*path).replace_extension("").string();
    for (auto& f : RenderDefaultPlots(*spec, *path, plot_dir)) files.push_back(f);
  }
  if (a.json) {
    nlohmann::json j = {{"id", plan->id},
                        {"data", std::filesystem::absolute(a.data).string()},
                        {"files", files},
                        {"points", spec->points()},
                        {"items", plan->items_total},
                        {"cached", plan->items_cached},
                        {"computed", to_compute},
                        {"seconds", seconds},
                        {"points_per_second", seconds > 0 ? static_cast<double>(to_compute) / seconds : 0.0},
                        {"threads", threads},
                        {"timing", {{"plan", secs(t0, t_planned)}, {"compute", secs(t_planned, t_computed)},
                                    {"publish", secs(t_computed, t_published)}}}};
    std::cout << j.dump(2) << "\n";
  } else {
    std::printf("sweep %s done: %ld points x %d = %ld items (%ld computed, %ld reused) in %.1f s, %.0f computed items/s\n",
                plan->id.c_str(), spec->points(), spec->ic_count(), plan->items_total, to_compute, plan->items_cached,
                seconds, seconds > 0 ? static_cast<double>(to_compute) / seconds : 0.0);
    std::printf("map: %s\n", path->c_str());
    for (size_t i = 1; i < files.size(); ++i) std::printf("plot: %s\n", files[i].c_str());
  }
  return 0;
}

}  // namespace

void AddRunCommand(CLI::App& app, int* exit_code) {
  auto a = std::make_shared<RunArgs>();
  CLI::App* cmd = app.add_subcommand("run", "Run a sweep embedded in this process (all cores) and write its maps");
  cmd->add_option("spec", a->spec_path, "sweep spec (TOML), e.g. examples/paper_fig8_frf.toml")->required();
  cmd->add_option("--data", a->data, "data directory (index.sqlite, sweeps/*.h5, plots)")->capture_default_str();
  cmd->add_option("--threads", a->threads, "worker threads (0 = all cores)")->capture_default_str();
  cmd->add_option("--job-items", a->job_items, "items per job (0 = about 0.25 s of work)");
  cmd->add_flag("--json", a->json, "print {id, data, files, points, seconds, ...} as JSON");
  cmd->add_flag("--no-plots", a->no_plots, "do not render the default plots");
  cmd->add_flag("--quiet", a->quiet, "no progress output");
  cmd->footer(
      "Re-running a spec reuses every stored point (content-keyed), so an interrupted sweep resumes\n"
      "where it stopped and overlapping sweeps only compute what is new. Ctrl-C keeps finished jobs.");
  cmd->callback([a, exit_code]() { *exit_code = RunSweep(*a); });
}

}  // namespace bistable
