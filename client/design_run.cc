#include "client/design_run.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <sstream>

#include "base/cpus.h"
#include "base/limits.h"
#include "base/validate.h"
#include "client/cli_common.h"
#include "client/embedded_run.h"
#include "client/map_source.h"
#include "client/plot.h"
#include "client/progress.h"
#include "dynamics/cancel.h"
#include "engine/evaluate.h"
#include "engine/json_shapes.h"
#include "proto/channel.h"
#include "proto/coordinator_client.h"
#include "server/sweep_coordinator.h"
#include "storage/map_file.h"

namespace bistable {
namespace {

using Clock = std::chrono::steady_clock;
double Since(Clock::time_point t0) { return std::chrono::duration<double>(Clock::now() - t0).count(); }

const char* const kScoreMetrics[] = {"frf_db", "motion", "lle"};

// The three metrics of a map into an outcome (shape from the first).
void Fill(SweepOutcome& o, int k, const MapArray& m) {
  std::vector<double>* dst[] = {&o.frf_db, &o.motion, &o.lle};
  *dst[k] = m.values;
  if (k == 0) {
    o.dims = m.dims;
    o.dim_names = m.dim_names;
    o.axis_values.clear();
    for (const Axis& a : m.axes) o.axis_values.push_back(a.values);
  }
}

class EmbeddedSweeps : public DesignSweeps {
 public:
  EmbeddedSweeps(std::unique_ptr<SweepCoordinator> c, int threads) : c_(std::move(c)), threads_(threads) {}
  StatusOr<SweepOutcome> Run(const std::string& toml) override {
    const auto t0 = Clock::now();
    if (CancelRequested()) return CancelledStatus();
    auto spec = ParseSweepSpec(toml, "design");
    if (!spec.ok()) return spec.status();
    auto plan = c_->Submit(*spec, JobItems(*spec, 0.25));
    if (!plan.ok()) return plan.status();
    // Stored jobs stay stored on cancellation; the search run again resumes from them.
    auto path = ComputeAndPublish(*c_, *spec, threads_, false, "", nullptr);
    if (!path.ok()) return path.status();
    SweepOutcome o;
    o.sweep_id = plan->id;
    o.map_path = *path;
    o.items = plan->items_total;
    o.cached = plan->items_cached;
    for (int k = 0; k < 3; ++k) {
      auto m = ReadMapMetric(*path, kScoreMetrics[k]);
      if (!m.ok()) return m.status();
      Fill(o, k, *m);
    }
    o.seconds = Since(t0);
    return o;
  }
  StatusOr<std::string> LocalMap(const SweepOutcome& o, const std::string&) override { return o.map_path; }

 private:
  std::unique_ptr<SweepCoordinator> c_;
  int threads_;
};

class RemoteSweeps : public DesignSweeps {
 public:
  explicit RemoteSweeps(std::unique_ptr<CoordinatorClient> c) : c_(std::move(c)) {}
  StatusOr<SweepOutcome> Run(const std::string& toml) override {
    const auto t0 = Clock::now();
    if (CancelRequested()) return CancelledStatus();
    // A sweep the coordinator already finished is all cache (a new Submit of it would report its old plan).
    auto parsed = ParseSweepSpec(toml, "design");
    if (!parsed.ok()) return parsed.status();
    auto known = c_->GetStatus(parsed->Id());
    const bool done_before = known.ok() && known->state == SweepState::kDone;
    auto sub = c_->Submit(toml, "bistable design");
    if (!sub.ok()) return sub.status();
    if (done_before) sub.value().items_cached = sub->items_total;
    auto last = c_->Watch(sub->id, [](const SweepInfo&) { return !CancelRequested(); });
    if (!last.ok()) return last.status();
    if (CancelRequested()) return CancelledStatus();  // the coordinator keeps computing; a rerun picks it up
    if (last->state != SweepState::kDone)
      return Status::FailedPrecondition("sweep " + sub->id + " ended " + SweepStateName(last->state) +
                                        (last->error.empty() ? "" : ": " + last->error));
    SweepOutcome o;
    o.sweep_id = sub->id;
    o.items = sub->items_total;
    o.cached = sub->items_cached;
    for (int k = 0; k < 3; ++k) {
      auto m = c_->GetMap(sub->id, kScoreMetrics[k]);
      if (!m.ok()) return m.status();
      Fill(o, k, *m);
    }
    o.seconds = Since(t0);
    return o;
  }
  StatusOr<std::string> LocalMap(const SweepOutcome& o, const std::string& dir) override {
    const std::string out = (std::filesystem::path(dir) / (o.sweep_id + ".h5")).string();
    auto f = FetchMapFile(*c_, o.sweep_id, out);
    if (!f.ok()) return f.status();
    return out;
  }

 private:
  std::unique_ptr<CoordinatorClient> c_;
};

nlohmann::json PointJson(const DesignPoint& x) { return {{"lambda", x[0]}, {"phi", x[1]}, {"eta_r", x[2]}}; }

nlohmann::json Num(double v) { return std::isfinite(v) ? nlohmann::json(v) : nlohmann::json(nullptr); }

nlohmann::json CandidateJson(const Candidate& c) {
  nlohmann::json j = {{"index", c.index}, {"design", PointJson(c.x)}, {"cost", c.cost}};
  if (!c.sweep_id.empty()) j["sweep_id"] = c.sweep_id;
  j["band_width"] = c.score.band_width;
  j["safe_band_width"] = c.score.safe_band_width;
  j["band"] = {Num(c.score.band_lo), Num(c.score.band_hi)};
  j["band_points"] = c.score.band_points;
  j["chaotic_in_band"] = c.score.chaotic_in_band;
  j["chaotic_share_band"] = c.score.chaotic_share_band;
  j["unsafe_in_band"] = c.score.unsafe_in_band;
  j["unsafe_share_band"] = c.score.unsafe_share_band;
  j["chaotic_share"] = c.score.chaotic_share;
  j["feasible"] = c.score.feasible();
  j["items"] = c.items;
  j["computed"] = c.computed;
  j["seconds"] = c.seconds;
  return j;
}

std::string Csv(const std::vector<Candidate>& cs, const std::vector<int>& front) {
  std::ostringstream os;
  os.precision(10);
  os << "index,lambda,phi,eta_r,cost,band_width,safe_band_width,chaotic_share_band,unsafe_share_band,chaotic_share,"
        "feasible,on_front,sweep_id,items,computed,seconds\n";
  for (const Candidate& c : cs)
    os << c.index << "," << c.x[0] << "," << c.x[1] << "," << c.x[2] << "," << c.cost << "," << c.score.band_width
       << "," << c.score.safe_band_width << "," << c.score.chaotic_share_band << "," << c.score.unsafe_share_band << ","
       << c.score.chaotic_share << "," << (c.score.feasible() ? 1 : 0) << ","
       << (std::find(front.begin(), front.end(), c.index) != front.end() ? 1 : 0) << "," << c.sweep_id << "," << c.items
       << "," << c.computed << "," << c.seconds << "\n";
  return os.str();
}

// The Pareto front figure: band width against the cost and against the unsafe (chaotic or diverged) share
// in the band, the front's objectives;
// every candidate in grey, the front in colour, the best design marked (and the brute-force grid's best).
Status RenderFront(const DesignSpec& spec, const SearchResult& r, const Candidate* grid_best, const std::string& out) {
  PanelPlot p;
  p.title = (spec.name.empty() ? "design " + spec.id : spec.name) + ": Pareto front of " +
            std::to_string(r.candidates.size()) + " candidates";
  p.rows = 1, p.cols = 2;
  const std::string cost_label = spec.cost == "phi" ? "cost: phi = m_r/m_m" : "cost: lambda = omega_r/omega_n";
  for (int panel = 0; panel < 2; ++panel) {
    PanelPlot::Panel pa;
    pa.title = panel == 0 ? "band width vs cost" : "band width vs unsafe share in the band";
    pa.x_label = panel == 0 ? cost_label : "unsafe share of the band's \u03a9 points (chaotic or diverged)";
    pa.y_label = "band width: \u03a9 with FRF < 0 dB";
    auto xof = [&](const Candidate& c) { return panel == 0 ? c.cost : c.score.unsafe_share_band; };
    PanelPlot::Series all{"candidates", {}, {}, true, "#999999", 0.6},
        front{"Pareto front", {}, {}, true, "#1f77b4", 1.0};
    for (const Candidate& c : r.candidates) all.x.push_back(xof(c)), all.y.push_back(c.score.band_width);
    for (int i : r.front) front.x.push_back(xof(r.candidates[i])), front.y.push_back(r.candidates[i].score.band_width);
    pa.series = {all, front};
    if (r.best >= 0) {
      const Candidate& b = r.candidates[r.best];
      pa.series.push_back({"best (no chaos in the band)", {xof(b)}, {b.score.band_width}, true, "#d62728", 2.0});
    }
    if (grid_best)
      pa.series.push_back(
          {"brute-force grid best", {xof(*grid_best)}, {grid_best->score.band_width}, true, "#2ca02c", 1.6});
    p.panels.push_back(pa);
  }
  return RenderPanels(p, out);
}

}  // namespace

StatusOr<std::unique_ptr<DesignSweeps>> OpenEmbeddedSweeps(const std::string& data_dir, int threads) {
  auto c = SweepCoordinator::Open(data_dir, EmbeddedCoordinatorOptions());
  if (!c.ok()) return c.status();
  return std::unique_ptr<DesignSweeps>(new EmbeddedSweeps(std::move(c.value()), threads > 0 ? threads : UsableCpus()));
}

StatusOr<std::unique_ptr<DesignSweeps>> OpenRemoteSweeps(const std::string& address, const std::string& token_file,
                                                         const std::string& tls_ca, bool insecure_remote) {
  auto token = LoadToken(token_file);
  if (!token.ok()) return token.status();
  auto c = CoordinatorClient::Connect({address, tls_ca, *token, insecure_remote});
  if (!c.ok()) return c.status();
  return std::unique_ptr<DesignSweeps>(new RemoteSweeps(std::move(c.value())));
}

// report.json's head: the design, where it ran, the search's settings, every candidate, the Pareto front, the
// best design, and the search's counts.
nlohmann::json SearchJson(const DesignSpec& spec, const DesignRunOptions& o, const std::string& out,
                          const SearchResult& r) {
  nlohmann::json j;
  const bool remote = !o.coordinator.empty();
  j["design_id"] = spec.id;
  j["name"] = spec.name;
  j["report_dir"] = std::filesystem::absolute(out).string();
  if (remote)
    j["coordinator"] = o.coordinator;
  else
    j["data"] = std::filesystem::absolute(o.data).string();
  j["optimizer"] = spec.optimizer;
  j["objective"] = "maximise safe_band_width (band_width without cells at unsafe band points)";
  j["cost_parameter"] = spec.cost;
  j["alpha"] = spec.alphas;
  j["omega"] = {{"min", spec.omega.front()}, {"max", spec.omega.back()}, {"count", spec.omega.size()}};
  j["bounds"] = {
      {"lambda", {spec.lo[0], spec.hi[0]}}, {"phi", {spec.lo[1], spec.hi[1]}}, {"eta_r", {spec.lo[2], spec.hi[2]}}};
  j["candidates"] = nlohmann::json::array();
  for (const Candidate& c : r.candidates) j["candidates"].push_back(CandidateJson(c));
  j["front"] = nlohmann::json::array();
  for (int i : r.front) j["front"].push_back(CandidateJson(r.candidates[i]));
  j["best"] = r.best >= 0 ? CandidateJson(r.candidates[r.best]) : nlohmann::json(nullptr);
  j["search"] = {{"candidates", r.candidates.size()},
                 {"points", r.items},
                 {"computed", r.computed},
                 {"cached", r.items - r.computed},
                 {"seconds", r.seconds}};
  return j;
}

// Maps of the best designs: ordinary sweeps over map_alpha x omega (bistable map / query work on them), with
// their default plots; j["maps"].
Status AddBestMaps(const DesignSpec& spec, const DesignRunOptions& o, const std::string& out, const SearchResult& r,
                   DesignSweeps& sweeps, nlohmann::json* j) {
  (*j)["maps"] = nlohmann::json::array();
  const std::vector<int> best = BestCandidates(r.candidates, spec.maps);
  for (size_t k = 0; k < best.size(); ++k) {
    const Candidate& c = r.candidates[best[k]];
    const std::string title = (spec.name.empty() ? "design " + spec.id : spec.name) + " best #" + std::to_string(k + 1);
    const std::string toml = spec.MapToml(c.x, title);
    auto m = sweeps.Run(toml);
    if (!m.ok()) return m.status();
    nlohmann::json mj = {{"rank", k + 1},           {"candidate", c.index}, {"design", PointJson(c.x)},
                         {"sweep_id", m->sweep_id}, {"points", m->items},   {"computed", m->items - m->cached},
                         {"seconds", m->seconds}};
    if (o.plots && CheckGnuplot().ok()) {
      const std::string dir = (std::filesystem::path(out) / ("best-" + std::to_string(k + 1))).string();
      std::error_code ec;
      std::filesystem::create_directories(dir, ec);
      auto local = sweeps.LocalMap(*m, dir);
      auto parsed = ParseSweepSpec(toml, "design");
      if (local.ok() && parsed.ok()) mj["plots"] = RenderDefaultPlots(*parsed, *local, dir);
    }
    (*j)["maps"].push_back(mj);
  }
  return Status::Ok();
}

StatusOr<nlohmann::json> RunDesign(const DesignSpec& spec, const DesignRunOptions& o) {
  if (o.brute_force != 0 && (o.brute_force < 2 || o.brute_force > limits::kMaxBruteForceSide))
    return Violates("brute-force", o.brute_force,
                    "in [2, " + std::to_string(limits::kMaxBruteForceSide) + "] (values per free parameter)");
  if (o.threads < 0 || o.threads > 1024) return Violates("threads", o.threads, "in [0, 1024]");
  const bool remote = !o.coordinator.empty();
  const std::string out = o.out.empty() ? (std::filesystem::path(o.data) / "designs" / spec.id).string() : o.out;
  std::error_code ec;
  std::filesystem::create_directories(out, ec);
  if (ec) return Status::IoError(out, "cannot create the report directory: " + ec.message());
  auto sweeps = remote ? OpenRemoteSweeps(o.coordinator, o.token_file, o.tls_ca, o.insecure_remote)
                       : OpenEmbeddedSweeps(o.data, o.threads);
  if (!sweeps.ok()) return sweeps.status();

  // The search, with a progress line over candidates (ETA from the candidates' pace).
  ProgressBar bar(spec.budget, "design " + spec.id, o.progress, "candidates");
  double best_w = NAN;
  long done = 0;
  auto search = RunDesignSearch(
      spec, [&](const std::string& t) { return sweeps.value()->Run(t); },
      [&](const Candidate& c) {
        ++done;
        if (c.score.feasible() && !(c.score.band_width <= best_w)) best_w = c.score.band_width;
        bar.Update(done, "best band " + (std::isnan(best_w) ? std::string("-") : PlotNumber(best_w)) + ", " +
                             std::to_string(c.computed) + " items computed");
      });
  if (!search.ok()) return search.status();
  bar.Finish(done, search->interrupted ? "interrupted" : "");
  if (search->interrupted) return CancelledStatus();
  const SearchResult& r = *search;

  nlohmann::json j = SearchJson(spec, o, out, r);

  // Maps of the best designs: ordinary sweeps over map_alpha x omega (bistable map / query work on them).
  BISTABLE_RETURN_IF_ERROR(AddBestMaps(spec, o, out, r, *sweeps.value(), &j));

  // Brute force in the same run: one sweep over the N per free parameter grid x alphas x omega, from
  // an empty cache (a data directory of its own, removed afterwards) so its time is the real cost.
  std::vector<Candidate> grid;
  int grid_best = -1;
  if (o.brute_force > 0) {
    const std::string bf_dir = (std::filesystem::path(out) / "brute-force-data").string();
    std::filesystem::remove_all(bf_dir, ec);
    auto bf = remote ? OpenRemoteSweeps(o.coordinator, o.token_file, o.tls_ca, o.insecure_remote)
                     : OpenEmbeddedSweeps(bf_dir, o.threads);
    if (!bf.ok()) return bf.status();
    if (o.progress) std::cerr << "brute force: " << o.brute_force << " values per free parameter\n";
    const auto t0 = Clock::now();
    auto g = bf.value()->Run(spec.BruteForceToml(o.brute_force));
    const double secs = Since(t0);
    bf.value().reset();  // closes the grid's index before its directory goes
    if (!remote) std::filesystem::remove_all(bf_dir, ec);
    if (!g.ok()) return g.status();
    grid = ScoreBruteForce(spec, g->dim_names, g->dims, g->frf_db, g->motion, g->lle, g->axis_values);
    grid_best = BestCandidate(grid);
    const double sw = r.best >= 0 ? r.candidates[r.best].score.band_width : -1;
    const double gw = grid_best >= 0 ? grid[grid_best].score.band_width : -1;
    j["brute_force"] = {{"n", o.brute_force},
                        {"designs", grid.size()},
                        {"sweep_id", g->sweep_id},
                        {"points", g->items},
                        {"computed", g->items - g->cached},
                        {"seconds", secs},
                        {"best", grid_best >= 0 ? CandidateJson(grid[grid_best]) : nlohmann::json(nullptr)},
                        {"points_ratio", g->items ? static_cast<double>(r.items) / static_cast<double>(g->items) : 0.0},
                        {"time_ratio", secs > 0 ? r.seconds / secs : 0.0},
                        {"search_at_least_as_good", sw >= gw && sw >= 0}};
  }

  std::vector<std::string> files;
  if (Status st =
          WriteTextOut((std::filesystem::path(out) / "candidates.csv").string(), Csv(r.candidates, r.front), "out");
      !st.ok())
    return st;
  files.push_back((std::filesystem::path(out) / "candidates.csv").string());
  if (o.plots) {
    if (Status g = CheckGnuplot(); !g.ok()) {
      j["warnings"] = {"no plots: " + g.message()};
    } else {
      const std::string png = (std::filesystem::path(out) / "pareto.png").string();
      Status st = RenderFront(spec, r, grid_best >= 0 ? &grid[grid_best] : nullptr, png);
      if (st.ok())
        files.push_back(png);
      else
        j["warnings"] = {"pareto plot: " + st.ToString()};
    }
  }
  files.push_back((std::filesystem::path(out) / "report.json").string());
  j["files"] = files;
  if (Status st = WriteTextOut(files.back(), DumpJson(j, 2) + "\n", "out"); !st.ok()) return st;
  return j;
}

}  // namespace bistable
