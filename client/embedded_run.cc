#include "client/embedded_run.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <mutex>
#include <thread>

#include "base/validate.h"
#include "client/map_slice.h"
#include "client/plot.h"
#include "dynamics/cancel.h"
#include "engine/evaluate.h"
#include "engine/sweep_kind.h"
#include "storage/map_file.h"
#include "worker/pull_loop.h"

namespace bistable {

// Default figures: each plotted metric over the two longest axes, one figure per value of the others
// (at most 12); a single-axis sweep gives curves, and with hd_peaks over Ω the Fig. 6 scatter.
namespace {

// One combination of values of the axes not in `free`: their indices (free axes left at 0), a file
// name suffix "_eta=0.1" and a title fragment ", eta = 0.1".
struct AxisCombo {
  std::vector<size_t> fixed;
  std::string suffix, title;
};

long ComboCount(const SweepSpec& spec, const std::vector<size_t>& free) {
  long n = 1;
  for (size_t k = 0; k < spec.axes.size(); ++k)
    if (std::find(free.begin(), free.end(), k) == free.end()) n *= static_cast<long>(spec.axes[k].values.size());
  return n;
}

AxisCombo Combo(const SweepSpec& spec, const std::vector<size_t>& free, long c) {
  AxisCombo combo;
  combo.fixed.assign(spec.axes.size(), 0);
  for (long k = static_cast<long>(spec.axes.size()) - 1; k >= 0; --k) {
    if (std::find(free.begin(), free.end(), static_cast<size_t>(k)) != free.end()) continue;
    const long n = static_cast<long>(spec.axes[k].values.size());
    combo.fixed[k] = static_cast<size_t>(c % n);
    c /= n;
    const double v = spec.axes[k].values[combo.fixed[k]];
    combo.suffix += "_" + spec.axes[k].name + "=" + FormatNumber(v);  // file names: every digit that tells values apart
    combo.title += ", " + spec.axes[k].name + " = " + PlotNumber(v);
  }
  return combo;
}

long PointIndex(const SweepSpec& spec, const std::vector<size_t>& idx) {
  long point = 0;
  for (size_t k = 0; k < spec.axes.size(); ++k)
    point = point * static_cast<long>(spec.axes[k].values.size()) + static_cast<long>(idx[k]);
  return point;
}

// The directory, extension and format of the default figures, and what came of them: the files
// written, and whether gnuplot could not start.
struct FigureSink {
  std::string dir, ext, format;
  std::vector<std::string> files;
  bool gnuplot_gone = false;
  bool progress = false;  // a line per figure on stderr, with the time since the last one (issue 43)
  std::chrono::steady_clock::time_point last = std::chrono::steady_clock::now();
  // Each failed figure is a warning; a gnuplot that cannot start stops the rest (one warning, not one per figure).
  void Render(const Status& st, const std::string& out) {
    if (st.ok()) {
      files.push_back(out);
      if (progress) {
        const auto now = std::chrono::steady_clock::now();
        std::fprintf(stderr, "  plotted %s in %.1f s\n", std::filesystem::path(out).filename().c_str(),
                     std::chrono::duration<double>(now - last).count());
        last = now;
      }
      return;
    }
    gnuplot_gone = st.message().find("cannot start gnuplot") != std::string::npos;
    std::cerr << "warning: " << st.ToString() << "\n";
  }
};

// The figures of one metric over the free axes and their files: one per combination of the other
// axes (at most 12), and with continuation in both directions a heatmap per direction.
std::vector<std::pair<PlotData, std::string>> MetricFigures(const SweepSpec& spec, const MapArray& m,
                                                            const std::string& metric, const std::vector<size_t>& free,
                                                            const MapContext& context, const FigureSink& sink) {
  const long combos = std::min<long>(ComboCount(spec, free), 12);
  // With continuation in both directions, a heatmap per direction; curves show both (MapFigure).
  const int directions = KindOf(spec).Chained() ? KindOf(spec).Slots(spec) : 1;
  const bool has_direction_dim = std::find(m.dim_names.begin(), m.dim_names.end(), "direction") != m.dim_names.end();
  const int per_combo = free.size() == 2 && has_direction_dim ? directions : 1;
  std::vector<std::pair<PlotData, std::string>> figures;  // the figures of this metric and their files
  for (long c = 0; c < combos; ++c) {
    const AxisCombo combo = Combo(spec, free, c);
    for (int item = 0; item < per_combo; ++item) {
      std::map<std::string, double> at;
      for (size_t k = 0; k < spec.axes.size(); ++k)
        if (std::find(free.begin(), free.end(), k) == free.end())
          at[spec.axes[k].name] = spec.axes[k].values[combo.fixed[k]];
      std::string suffix = combo.suffix;
      if (per_combo == 2) at["direction"] = item, suffix += spec.ChainGoesDown(item) ? "_down" : "_up";
      auto d = MapFigure(m, at, context);
      if (!d.ok()) continue;
      if (std::none_of(d->values.begin(), d->values.end(), [](double v) { return std::isfinite(v); })) continue;
      figures.emplace_back(std::move(*d), (std::filesystem::path(sink.dir) / (metric + suffix + sink.ext)).string());
    }
  }
  return figures;
}

// Maps of one metric from one sweep are compared with each other: one colour range for all.
void ShareColourRange(const std::string& metric, std::vector<std::pair<PlotData, std::string>>* figures) {
  size_t heatmaps = 0;
  std::vector<double> all;
  for (const auto& [d, out] : *figures)
    if (d.axis_names.size() == 2 && d.codes.empty())
      ++heatmaps, all.insert(all.end(), d.values.begin(), d.values.end());
  if (heatmaps > 1) {
    const auto [lo, hi] = ColourRange(metric, all);
    for (auto& [d, out] : *figures) {
      if (d.axis_names.size() != 2 || !d.codes.empty()) continue;
      d.cb_lo = lo, d.cb_hi = hi;
      d.cb_note = "one colour scale for the " + std::to_string(heatmaps) + " maps of this quantity in this sweep";
    }
  }
}

// Each plotted metric over the two longest axes, one figure per value of the others (at most 12).
void RenderMetricFigures(const SweepSpec& spec, const std::string& map_path, const MapContext& context,
                         FigureSink* sink) {
  std::vector<size_t> order(spec.axes.size());
  for (size_t i = 0; i < order.size(); ++i) order[i] = i;
  std::stable_sort(order.begin(), order.end(),
                   [&](size_t a, size_t b) { return spec.axes[a].values.size() > spec.axes[b].values.size(); });
  std::vector<size_t> free(order.begin(), order.begin() + std::min<size_t>(2, order.size()));
  for (const std::string& metric : spec.plots) {
    auto m = ReadMapMetric(map_path, metric);
    if (!m.ok()) {
      std::cerr << "warning: plot " << metric << ": " << m.status().ToString() << "\n";
      continue;
    }
    std::vector<std::pair<PlotData, std::string>> figures = MetricFigures(spec, *m, metric, free, context, *sink);
    ShareColourRange(metric, &figures);
    for (const auto& [d, out] : figures) {
      if (CancelRequested() || sink->gnuplot_gone) break;  // asked to stop: no more gnuplot runs
      sink->Render(RenderPlot(d, out, sink->format), out);
    }
  }
}

// Fig. 6: one harmonic-diffusion scatter per combination of the axes other than omega (at most 3,
// like the paper's two amplitudes; `bistable map ID --metric hd_scatter --at ...` draws any other).
void RenderHdScatters(const SweepSpec& spec, const std::string& map_path, FigureSink* sink) {
  const bool has_peaks = std::find(spec.metrics.begin(), spec.metrics.end(), "hd_peaks") != spec.metrics.end();
  size_t omega_axis = spec.axes.size();
  for (size_t k = 0; k < spec.axes.size(); ++k)
    if (spec.axes[k].name == "omega") omega_axis = k;
  const long scatter_combos = omega_axis < spec.axes.size() ? ComboCount(spec, {omega_axis}) : 0;
  if (!has_peaks || omega_axis >= spec.axes.size() || scatter_combos > 3 || spec.ic_count() != 1) return;
  auto f = ReadMapMetric(map_path, "hd_peak_freq");
  auto a = ReadMapMetric(map_path, "hd_peak_amp");
  if (!f.ok() || !a.ok()) return;
  const size_t k_peaks = f->dims.back();
  for (long c = 0; c < scatter_combos && !CancelRequested(); ++c) {
    AxisCombo combo = Combo(spec, {omega_axis}, c);
    ScatterData sd;
    sd.title = (spec.name.empty() ? spec.Id() : spec.name) + ": harmonic diffusion" + combo.title;
    const std::string suffix = combo.suffix;
    for (size_t i = 0; i < spec.axes[omega_axis].values.size(); ++i) {
      combo.fixed[omega_axis] = i;
      const long point = PointIndex(spec, combo.fixed);
      for (size_t j = 0; j < k_peaks; ++j) {
        const size_t off = static_cast<size_t>(point) * k_peaks + j;
        if (std::isfinite(f->values[off]))
          sd.x.push_back(spec.axes[omega_axis].values[i]), sd.y.push_back(f->values[off]),
              sd.amp.push_back(a->values[off]);
      }
    }
    const std::string out = (std::filesystem::path(sink->dir) / ("hd_scatter" + suffix + sink->ext)).string();
    if (!sink->gnuplot_gone) sink->Render(RenderHdScatter(sd, out), out);
  }
}

// The bifurcation diagram of one combination of the axes other than the continued one (axis `cont`):
// the turning points of y_m over that axis, increasing and decreasing apart.
BifurcationData BifurcationOf(const SweepSpec& spec, const MapContext& context, const MapArray& tp, size_t cont,
                              AxisCombo combo) {
  const int nic = spec.ic_count();
  BifurcationData bd;
  bd.x_name = spec.continuation.axis;
  bd.x_unit = AxisUnit(spec.continuation.axis);
  bd.title = "Bifurcation diagram: turning points of y_m";
  bd.title_markup = true;
  for (const FixedParameter& p : context.fixed) bd.subtitle.push_back(ParameterItem(p.name, p.value, p.unit));
  for (size_t k = 0; k < spec.axes.size(); ++k)
    if (k != cont)
      bd.subtitle.push_back(
          ParameterItem(spec.axes[k].name, spec.axes[k].values[combo.fixed[k]], AxisUnit(spec.axes[k].name)));
  bd.footer = context.name.empty() ? "sweep " + context.id : context.name + "  \u00b7  sweep " + context.id;
  for (size_t i = 0; i < spec.axes[cont].values.size(); ++i) {
    combo.fixed[cont] = i;
    const long point = PointIndex(spec, combo.fixed);
    for (int ic = 0; ic < nic; ++ic) {
      const bool down = spec.ChainGoesDown(ic);
      for (int k = 0; k < kTurningPointsStored; ++k) {
        const double y = tp.values[(static_cast<size_t>(point) * nic + ic) * kTurningPointsStored + k];
        if (!std::isfinite(y)) continue;
        (down ? bd.x_down : bd.x_up).push_back(spec.axes[cont].values[i]);
        (down ? bd.y_down : bd.y_up).push_back(y);
      }
    }
  }
  return bd;
}

// Fig. 4: bifurcation diagrams, one per combination of the axes other than the continued one (≤ 6).
void RenderBifurcations(const SweepSpec& spec, const std::string& map_path, const MapContext& context,
                        FigureSink* sink) {
  if (!spec.continuation.enabled() || !spec.base.metrics.turning_points) return;
  auto tp = ReadMapMetric(map_path, "turning_points");
  size_t cont = 0;
  for (size_t k = 0; k < spec.axes.size(); ++k)
    if (spec.axes[k].name == spec.continuation.axis) cont = k;
  const long combos = ComboCount(spec, {cont});
  if (!tp.ok() || combos > 6) return;
  for (long c = 0; c < combos && !CancelRequested(); ++c) {
    const AxisCombo combo = Combo(spec, {cont}, c);
    const BifurcationData bd = BifurcationOf(spec, context, *tp, cont, combo);
    const std::string out = (std::filesystem::path(sink->dir) / ("bifurcation" + combo.suffix + sink->ext)).string();
    if (!sink->gnuplot_gone) sink->Render(RenderBifurcation(bd, out), out);
  }
}

}  // namespace

std::vector<std::string> RenderDefaultPlots(const SweepSpec& spec, const std::string& map_path, const std::string& dir,
                                            const std::string& format, bool progress) {
  FigureSink sink{dir, "." + format, format, {}, false, progress};
  std::error_code ec;
  std::filesystem::create_directories(dir, ec);
  if (ec) {
    std::cerr << "warning: no plots: cannot create '" << dir << "': " << ec.message() << "\n";
    return sink.files;
  }
  const MapContext context = MapContextOf(spec);
  RenderMetricFigures(spec, map_path, context, &sink);
  RenderHdScatters(spec, map_path, &sink);
  RenderBifurcations(spec, map_path, context, &sink);
  return std::move(sink.files);
}

namespace {

// Jobs of one sweep from the coordinator in this process (the embedded side of worker/pull_loop.h).
class EmbeddedJobSource : public JobSource {
 public:
  EmbeddedJobSource(SweepCoordinator& c, std::shared_ptr<const SweepSpec> spec)
      : c_(c), spec_(std::move(spec)), id_(spec_->Id()) {}
  StatusOr<std::optional<LeasedJob>> Lease() override {
    auto g = c_.Lease("embedded", id_);
    if (!g) return std::optional<LeasedJob>();
    return std::optional<LeasedJob>(LeasedJob{g->lease_id, spec_, std::move(g->items)});
  }
  void Heartbeat(const LeasedJob&) override {}  // embedded leases last an hour
  Status Report(const LeasedJob& job, const std::vector<PointRecord>& records, std::optional<LeasedJob>*) override {
    return c_.Report(job.lease_id, records);
  }
  Status Release(const LeasedJob& job) override { return c_.Release(job.lease_id); }

 private:
  SweepCoordinator& c_;
  std::shared_ptr<const SweepSpec> spec_;
  std::string id_;
};

}  // namespace

Status RunPullThreads(JobSource& source, int threads, const std::function<std::pair<long, long>()>& done_of,
                      const std::function<void()>& halt, std::atomic<bool>* stop, ProgressBar* bar) {
  std::mutex err_mu;
  Status worker_error;
  std::atomic<bool> failed{false};
  std::vector<std::thread> pool;
  const long start = done_of().first;
  auto stopping = [&] { return CancelRequested() || (stop && stop->load()) || failed.load(); };
  std::atomic<int> running{0};
  for (int t = 0; t < threads; ++t) {
    ++running;
    pool.emplace_back([&] {
      PullLoopOptions opt;
      opt.name = "embedded";
      opt.until_idle = true;
      opt.report_retries = 0;
      opt.stop_on_error = true;
      opt.log = false;
      opt.stop = stopping;
      const PullLoopResult r = RunPullLoop(source, opt);
      if (!r.error.ok()) {
        std::lock_guard<std::mutex> lock(err_mu);
        if (worker_error.ok()) worker_error = r.error;
        failed.store(true);
        halt();
      }
      --running;
    });
  }
  while (!pool.empty()) {
    if (stopping()) halt();
    const auto [done, total] = done_of();
    if (done >= total || stopping() || running.load() == 0) break;
    if (bar) bar->Update(done - start);
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  for (auto& th : pool) th.join();
  if (bar) bar->Finish(done_of().first - start);
  return worker_error;
}

Status ComputeEmbedded(SweepCoordinator& c, const SweepSpec& spec, int threads, bool any_work, std::atomic<bool>* stop,
                       ProgressBar* bar) {
  const std::string id = spec.Id();
  EmbeddedJobSource source(c, std::make_shared<const SweepSpec>(spec));
  return RunPullThreads(
      source, any_work ? threads : 0,
      [&] {
        const SweepProgress p = c.progress(id);
        return std::pair<long, long>(p.items_done, p.items_total);
      },
      [&] { c.Stop(); }, stop, bar);
}

StatusOr<std::string> ComputeAndPublish(SweepCoordinator& c, const SweepSpec& spec, int threads, bool progress,
                                        const std::string& label, EmbeddedRunStats* stats) {
  const std::string id = spec.Id();
  const long first = c.progress(id).items_done;
  // A refined sweep ([refine]) computes round by round: the publisher's step for a stored round plans the next
  // one (one progress line per round); any other sweep goes round once. Publish asks the coordinator's
  // publisher (server/publisher.h, the one place a publication starts) and waits for its step.
  for (;;) {
    const SweepProgress p = c.progress(id);
    const long to_compute = p.items_total - p.items_done;
    // The coordinator's round, so a resumed run names the round it resumes (0: the coarse grid).
    const std::string round = p.refine_round >= 0 ? " (refine round " + std::to_string(p.refine_round) + ")" : "";
    ProgressBar bar(to_compute, label + round, progress);
    const Status worker_error = ComputeEmbedded(c, spec, threads, to_compute > 0, nullptr, progress ? &bar : nullptr);
    const SweepProgress after = c.progress(id);
    if (stats) stats->computed = after.items_done - first, stats->items = after.items_total;
    // (A refined sweep's next level may be planned already, by the publisher thread: its items are not missing.)
    if (!worker_error.ok() || CancelRequested() || (!KindOf(spec).InRounds() && after.items_done < after.items_total)) {
      c.MarkInterrupted(id);  // stored jobs stay stored; a later run resumes from them
      if (!worker_error.ok()) return worker_error;
      return CancelledStatus();
    }
    const auto t0 = std::chrono::steady_clock::now();
    // Publishing writes the map file (HDF5, compressed; a refined sweep fills its finest grid first) or plans a
    // refined sweep's next round: seconds on big maps, said rather than silent (issue 43).
    if (progress) std::fprintf(stderr, "%s: publishing (%ld items)...\n", label.c_str(), after.items_total);
    auto path = c.Publish(id);
    const double published = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    if (stats) stats->publish_seconds += published;
    if (progress && path.ok()) std::fprintf(stderr, "%s: map written in %.1f s\n", label.c_str(), published);
    if (path.ok() || !KindOf(spec).InRounds()) return path;
    const SweepProgress next = c.progress(id);
    if (next.items_done >= next.items_total) return path;  // no new round was planned: the failure stands
    // (Rounds end: every round splits cells into smaller ones, down to the grid spacing.)
  }
}

SweepCoordinator::Options EmbeddedCoordinatorOptions() {
  return {.lease_seconds = 3600, .resume = false, .log = false, .warn = [](const std::string& message) {
            std::cerr << "warning: " << message << std::endl;
          }};
}

StatusOr<std::string> RunEmbeddedSweep(const SweepSpec& spec, const std::string& data_dir, int threads, bool progress) {
  if (CancelRequested()) return CancelledStatus();  // not even the planning of a new sweep
  auto coord = SweepCoordinator::Open(data_dir, EmbeddedCoordinatorOptions());
  if (!coord.ok()) return coord.status();
  auto plan = (*coord)->Submit(spec, JobItems(spec, 0.25));
  if (!plan.ok()) return plan.status();
  return ComputeAndPublish(**coord, spec, threads, progress, "  " + (spec.name.empty() ? plan->id : spec.name),
                           nullptr);
}

}  // namespace bistable
