// `bistable hbm`: harmonic balance with continuation and stability (model.md §4): branches with folds,
// period doublings and Neimark–Sacker points, branch switching onto period-2 branches, and fold
// curves in (α, Ω) — the boundary of the bistable region — alone or over a motion map.
#include <algorithm>
#include <filesystem>
#include <iostream>
#include <memory>
#include <sstream>

#include <nlohmann/json.hpp>

#include "base/validate.h"
#include "client/cli_common.h"
#include "client/hbm_command.h"
#include "client/hbm_json.h"
#include "client/map_slice.h"
#include "client/map_source.h"
#include "client/model_flags.h"
#include "client/plot.h"
#include "dynamics/cancel.h"
#include "dynamics/hbm.h"
#include "engine/json_shapes.h"
#include "storage/map_file.h"
#include "storage/metric_name.h"

namespace bistable {
namespace {

struct HbmArgs {
  std::string model = "standalone", param = "omega", format, out;
  bool json = false, eq9 = false, fold_curve = false;
  std::vector<double> alpha_range{0.01, 3.0}, omega_range{0.05, 3.0};
  std::string fold_out, over_map, map_metric = "motion", at, data = kDefaultDataDir;
  HbmOptions o;
};

nlohmann::json PointJson(const HbmPoint& p) {
  nlohmann::json mu = nlohmann::json::array();
  for (const auto& m : p.multipliers) mu.push_back(ComplexJson(m));
  nlohmann::json j = {{"omega", p.omega},
                      {"alpha", p.alpha},
                      {"amplitude", JsonNumber(p.amplitude)},
                      {"mean", JsonNumber(p.mean)},
                      {"stable", p.stable},
                      {"max_multiplier", JsonNumber(p.max_multiplier)},
                      {"converged", p.converged},
                      {"fold", p.fold},
                      {"branch_point", p.branch_point},
                      {"harmonics", p.harmonics},
                      {"y_min", JsonNumber(p.y_min)},
                      {"y_max", JsonNumber(p.y_max)},
                      {"period", p.period},
                      {"multipliers", mu},
                      {"period_doubling", p.period_doubling},
                      {"neimark_sacker", p.neimark_sacker}};
  if (p.fold && p.fold_at.valid()) j["fold_at"] = LocatedJson(p.fold_at);
  if (p.period_doubling && p.period_doubling_at.valid()) j["period_doubling_at"] = LocatedJson(p.period_doubling_at);
  if (p.neimark_sacker && p.neimark_sacker_at.valid()) j["neimark_sacker_at"] = LocatedJson(p.neimark_sacker_at);
  return j;
}

// The fold curves as a figure in (Ω, α) (x = Ω, y = α as in the maps), one colour per well, cusps marked.
BranchPlot FoldCurvePlot(const std::vector<FoldCurve>& curves, const HbmArgs& a) {
  BranchPlot d;
  d.title = "Fold curves of harmonic balance";
  d.subtitle = {std::string(ModelName(a.o.model)) + " model", "H = " + std::to_string(a.o.harmonics),
                ParameterItem("eta", a.o.params.eta, "")};
  d.x_name = "omega";
  d.x_unit = "omega0/omega_n";
  d.y_label = AxisLabel("alpha", "A0/delta_s");
  d.stability = false;
  BranchPlot::Marker cusps{"cusp", 13, "#000000", {}, {}};
  for (const FoldCurve& c : curves) {
    BranchPlot::Branch br;
    for (const FoldCurvePoint& p : c.points) {
      const std::string name = IsBistable(a.o.model) ? std::string("fold curve, ") + FoldWellName(p) : "fold curve";
      if (!br.x.empty() && name != br.name) {  // the orbit at the fold changes well: a new piece from here
        br.x.push_back(p.omega), br.y.push_back(p.alpha), br.stable.push_back(true);
        d.branches.push_back(std::move(br));
        br = BranchPlot::Branch{};
      }
      br.name = name;
      br.x.push_back(p.omega), br.y.push_back(p.alpha), br.stable.push_back(true);
      if (p.cusp) cusps.x.push_back(p.omega), cusps.y.push_back(p.alpha);
    }
    if (!br.x.empty()) d.branches.push_back(std::move(br));
  }
  d.markers.push_back(std::move(cusps));
  return d;
}

// The map parameter `key` (from --at when it is an axis fixed there, else the spec's value) against
// the harmonic balance's: an overlay on a map of other parameters would mislead.
Status CheckMapParam(const std::map<std::string, double>& at, const std::string& canonical, const std::string& key,
                     double mine, const std::string& flag) {
  double theirs = NAN;
  if (auto it = at.find(key); it != at.end()) {
    theirs = it->second;
  } else {
    std::istringstream in(canonical);
    std::string line;
    while (std::getline(in, line))
      if (line.rfind(key + "=", 0) == 0) theirs = std::strtod(line.c_str() + key.size() + 1, nullptr);
  }
  if (std::isfinite(theirs) && std::fabs(theirs - mine) > 1e-12 * std::max(1.0, std::fabs(mine)))
    return Status::InvalidArgument("over_map", "the map has " + key + " = " + FormatNumber(theirs) +
                                                   ", the harmonic balance " + key + " = " + FormatNumber(mine) +
                                                   ": pass " + flag + " " + FormatNumber(theirs) +
                                                   " (or fix the map's axis with --at)");
  return Status::Ok();
}

// The fold curves over a map (a map file of `bistable run`, or a sweep id in --data): its slice at
// --at must have the free axes alpha and omega, and its model and parameters must be the balance's.
StatusOr<PlotData> FoldsOverMap(const HbmArgs& a, const std::vector<FoldCurve>& curves) {
  std::string path, prefix;
  std::error_code ec;
  if (std::filesystem::is_regular_file(a.over_map, ec)) {
    path = a.over_map;
    prefix = std::filesystem::path(a.over_map).filename().string();
  } else {
    auto ref = FindSweep(a.data, a.over_map);
    if (!ref.ok())
      return Status::InvalidArgument("over_map", "'" + a.over_map + "' is neither a map file nor a sweep in " + a.data +
                                                     ": " + ref.status().message());
    if (ref->map_path.empty()) return Status::FailedPrecondition("sweep " + ref->row.id + " has no published map yet");
    path = ref->map_path;
    prefix = ref->row.name.empty() ? ref->row.id : ref->row.name;
  }
  auto names = ListMapMetrics(path);
  if (!names.ok()) return names.status();
  BISTABLE_RETURN_IF_ERROR(CheckMetricName(a.map_metric, *names));
  auto m = ReadMapMetric(path, a.map_metric);
  if (!m.ok()) return m.status();
  auto at = ParseAt(a.at);
  if (!at.ok()) return at.status();
  auto model = ReadMapAttribute(path, "model");
  if (!model.ok()) return model.status();
  if (*model != ModelName(a.o.model))
    return Status::InvalidArgument("over_map", "the map is of model '" + *model + "', the harmonic balance of '" +
                                                   ModelName(a.o.model) + "': pass --model " + *model);
  auto canonical = ReadMapAttribute(path, "canonical_spec");
  if (!canonical.ok()) return canonical.status();
  const NondimParams& p = a.o.params;
  BISTABLE_RETURN_IF_ERROR(CheckMapParam(*at, *canonical, "eta", p.eta, "--eta"));
  if (IsBistable(a.o.model)) BISTABLE_RETURN_IF_ERROR(CheckMapParam(*at, *canonical, "eps", p.eps, "--eps"));
  if (HasResonator(a.o.model)) {
    BISTABLE_RETURN_IF_ERROR(CheckMapParam(*at, *canonical, "eta_r", p.eta_r, "--eta-r"));
    BISTABLE_RETURN_IF_ERROR(CheckMapParam(*at, *canonical, "phi", p.phi, "--phi"));
    BISTABLE_RETURN_IF_ERROR(CheckMapParam(*at, *canonical, "lambda", p.lambda, "--lambda"));
  }
  MapContext context = MapContextOfFile(path);
  if (context.name.empty() && context.id.empty()) context.name = prefix;
  auto fig = MapFigure(*m, *at, context);
  if (!fig.ok()) return fig.status();
  PlotData d = std::move(fig).value();
  const auto& ax = d.axis_names;
  if (ax.size() != 2 || !((ax[0] == "alpha" && ax[1] == "omega") || (ax[0] == "omega" && ax[1] == "alpha")))
    return Status::InvalidArgument(
        "over_map", "fold curves lie in (alpha, omega), the map's slice has free axes " +
                        (ax.empty() ? std::string("none") : ax[0] + (ax.size() > 1 ? ", " + ax[1] : "")) +
                        ": fix the others with --at");
  const bool x_omega = ax[1] == "omega";
  bool first = true;
  PlotData::Overlay cusps{"cusp", {}, {}, true, "#000000"};
  for (const FoldCurve& c : curves) {
    PlotData::Overlay ov;
    ov.label = first ? "fold curves (HBM, H = " + std::to_string(a.o.harmonics) + ")" : "";
    first = false;
    for (const FoldCurvePoint& q : c.points) {
      ov.x.push_back(x_omega ? q.omega : q.alpha), ov.y.push_back(x_omega ? q.alpha : q.omega);
      if (q.cusp) cusps.x.push_back(ov.x.back()), cusps.y.push_back(ov.y.back());
    }
    d.overlays.push_back(std::move(ov));
  }
  if (!cusps.x.empty()) d.overlays.push_back(std::move(cusps));
  d.title += " and fold curves of harmonic balance";
  return d;
}

// `hbm --json`: the branches (every point, with its well for a bistable model), the bifurcations, the settings,
// the truncation check and notes; with --fold-curve the fold curves.
nlohmann::json HbmJson(const HbmArgs& a, const HbmResult& r, const std::vector<FoldCurve>& curves) {
  nlohmann::json branches = nlohmann::json::array();
  for (const HbmBranch& b : r.branches) {
    nlohmann::json pts = nlohmann::json::array();
    for (const HbmPoint& p : b.points) {
      pts.push_back(PointJson(p));
      if (IsBistable(a.o.model)) pts.back()["well"] = OrbitWellName(WellOf(p));
    }
    branches.push_back({{"start", b.start}, {"period", b.period}, {"points", pts}});
  }
  nlohmann::json settings = {{"model", ModelName(a.o.model)},
                             {"continue", a.param},
                             {"from", a.o.from},
                             {"to", a.o.to},
                             {"alpha", a.o.alpha},
                             {"omega", a.o.omega},
                             {"harmonics", a.o.harmonics},
                             {"zero_mean", a.o.zero_mean},
                             {"eps", a.o.params.eps},
                             {"eta", a.o.params.eta},
                             {"switch_pd", a.o.switch_depth},
                             {"numerics_version", kNumericsVersion}};
  if (HasResonator(a.o.model))
    settings.update({{"eta_r", a.o.params.eta_r}, {"phi", a.o.params.phi}, {"lambda", a.o.params.lambda}});
  nlohmann::json out = {{"branches", branches},
                        {"bifurcations", BifurcationsJson(r)},
                        {"settings", settings},
                        {"truncation_change", r.truncation_change},
                        {"notes", r.notes}};
  if (a.fold_curve) {
    out["fold_curves"] = FoldCurvesJson(curves, IsBistable(a.o.model));
    out["settings"].update({{"alpha_range", a.alpha_range}, {"omega_range", a.omega_range}});
  }
  return out;
}

// hbm's summary on stdout (no --json, no figure): each branch, the period doublings and Neimark–Sacker points,
// and with --fold-curve each fold curve and its cusps.
void PrintHbmSummary(const HbmArgs& a, const HbmResult& r, const std::vector<FoldCurve>& curves) {
  const bool omega = a.o.param == ContinuationParam::kOmega;
  std::printf("%zu branches (truncation check: amplitude changes by %.2g%% with H+2 harmonics)\n", r.branches.size(),
              100 * r.truncation_change);
  for (const HbmBranch& b : r.branches) {
    int stable = 0, folds = 0, pds = 0, nss = 0;
    double lo = INFINITY, hi = 0;
    for (const HbmPoint& p : b.points)
      stable += p.stable, folds += p.fold, pds += p.period_doubling, nss += p.neimark_sacker,
          lo = std::min(lo, p.amplitude), hi = std::max(hi, p.amplitude);
    std::printf("  %-50s %4zu points, period %d, amplitude %.3f..%.3f, mean %+.3f, %d stable, %d folds, %d PD, %d NS\n",
                b.start.c_str(), b.points.size(), b.period, lo, hi, b.points.front().mean, stable, folds, pds, nss);
  }
  const char* pname = omega ? "Omega" : "alpha";
  for (const auto& j : BifurcationsJson(r)) {
    if (j["kind"] == "fold") continue;
    const double v = j[omega ? "omega" : "alpha"].is_null() ? NAN : j[omega ? "omega" : "alpha"].get<double>();
    std::printf("  %s on branch %d (period %d) at %s = %.10g, amplitude %.5g\n",
                j["kind"] == "period_doubling" ? "period doubling" : "Neimark-Sacker", j["branch"].get<int>(),
                j["period"].get<int>(), pname, v, j["amplitude"].is_null() ? NAN : j["amplitude"].get<double>());
  }
  if (a.fold_curve)
    for (const FoldCurve& c : curves) {
      int cusps = 0;
      double alo = INFINITY, ahi = 0;
      for (const FoldCurvePoint& p : c.points)
        cusps += p.cusp, alo = std::min(alo, p.alpha), ahi = std::max(ahi, p.alpha);
      std::printf("  fold curve from %s: %zu points, alpha %.4g..%.4g, %d cusps%s\n", c.start.c_str(), c.points.size(),
                  alo, ahi, cusps, c.converged ? "" : " (the corrector failed before it left the box)");
      for (const FoldCurvePoint& p : c.points)
        if (p.cusp) std::printf("    cusp near alpha = %.5g, Omega = %.5g\n", p.alpha, p.omega);
    }
}

int RunHbm(HbmArgs& a) {
  auto m = ParseModel(a.model);
  if (!m.ok()) return Fail(m.status());
  a.o.model = *m;
  if (a.param == "omega")
    a.o.param = ContinuationParam::kOmega;
  else if (a.param == "alpha")
    a.o.param = ContinuationParam::kAlpha;
  else
    return Fail(
        Status::InvalidArgument("continue", "continue = '" + a.param + "' violates continue in {omega, alpha}"));
  if (!a.format.empty() && a.format != "png" && a.format != "svg")
    return Fail(Status::InvalidArgument("format", "format = '" + a.format + "' violates format in {png, svg}"));
  FoldCurveOptions f;
  f.alpha_lo = a.alpha_range[0], f.alpha_hi = a.alpha_range[1];
  f.omega_lo = a.omega_range[0], f.omega_hi = a.omega_range[1];
  if (Status st = ValidateFoldCurveOptions(f); !st.ok()) return Fail(st);
  if (!a.fold_curve && (!a.over_map.empty() || !a.fold_out.empty()))
    return Fail(
        Status::InvalidArgument(a.over_map.empty() ? "fold_out" : "over_map", "draws fold curves: add --fold-curve"));
  const std::string why = "hbm's summary and --json use standard output";
  if (Status st = NotStdout(a.out, "out", "--out", why); !st.ok()) return Fail(st);
  if (Status st = NotStdout(a.fold_out, "fold_out", "--fold-out", why); !st.ok()) return Fail(st);
  InstallCancelSignalHandlers();  // Ctrl-C / SIGTERM: the continuation stops at its next point
  auto r = ContinueBranches(a.o);
  StatusOr<std::vector<FoldCurve>> curves = std::vector<FoldCurve>{};
  if (r.ok() && a.fold_curve) curves = ContinueFoldCurves(a.o, f, *r);
  RestoreDefaultSignalHandlers();
  if (CancelRequested()) {
    std::cerr << "interrupted: the continuation was not finished; nothing was printed or written\n";
    return CancelExitStatus();
  }
  if (!r.ok()) return Fail(r.status());
  if (!curves.ok()) return Fail(curves.status());
  const bool omega = a.o.param == ContinuationParam::kOmega;
  if (a.json) std::cout << DumpJson(HbmJson(a, *r, *curves), 1) << "\n";
  const std::string ext = a.format.empty() ? "png" : a.format;
  if (!a.format.empty() || !a.out.empty()) {
    BranchPlot d = HbmBranchPlot(*r, a.o.model, a.o.param, "Periodic orbits by harmonic balance");
    d.subtitle = {std::string(ModelName(a.o.model)) + " model", "H = " + std::to_string(a.o.harmonics),
                  omega ? ParameterItem("alpha", a.o.alpha, "") : ParameterItem("omega", a.o.omega, ""),
                  ParameterItem("eta", a.o.params.eta, "")};
    if (a.eq9) {
      d.extra_label = "one harmonic, zero mean (corrected Eq. 9)";
      for (int k = 0; k <= 600; ++k) {
        const double p = a.o.from + (a.o.to - a.o.from) * k / 600.0;
        for (double q : Eq9Amplitudes(a.o.model, a.o.params, omega ? a.o.alpha : p, omega ? p : a.o.omega))
          d.extra_x.push_back(p), d.extra_y.push_back(q);
      }
    }
    const std::string out = a.out.empty() ? "hbm_" + a.model + "." + ext : a.out;
    Status st = RenderBranches(d, out);
    if (!st.ok()) return Fail(st);
    if (!a.json) std::cout << out << "\n";
  }
  if (a.fold_curve && (!a.format.empty() || !a.out.empty() || !a.fold_out.empty() || !a.over_map.empty())) {
    const std::string out = a.fold_out.empty() ? "hbm_" + a.model + "_folds." + ext : a.fold_out;
    Status st;
    if (a.over_map.empty()) {
      st = curves->empty()
               ? Status::InvalidArgument("fold_curve", "no fold was found to continue: no fold curve to draw")
               : RenderBranches(FoldCurvePlot(*curves, a), out);
    } else {
      auto d = FoldsOverMap(a, *curves);
      st = d.ok() ? RenderPlot(*d, out) : d.status();
    }
    if (!st.ok()) return Fail(st);
    if (!a.json) std::cout << out << "\n";
  }
  if (!a.json)
    for (const std::string& n : r->notes) std::cerr << "note: " << n << "\n";
  if (!a.json && a.format.empty() && a.out.empty()) PrintHbmSummary(a, *r, *curves);
  return 0;
}

}  // namespace

BranchPlot HbmBranchPlot(const HbmResult& r, ModelKind model, ContinuationParam param, const std::string& title) {
  const bool omega = param == ContinuationParam::kOmega;
  BranchPlot d;
  d.title = title;
  d.x_name = omega ? "omega" : "alpha";
  d.x_unit = omega ? "omega0/omega_n" : "A0/delta_s";
  d.y_label = "max |y_m| over a period [\u03b4_s]";
  auto name_of = [&](const HbmPoint& p) {
    const std::string well = IsBistable(model) ? std::string(OrbitWellName(WellOf(p))) : std::string("periodic orbit");
    return p.period > 1 ? "period " + std::to_string(p.period) + ", " + well : well;
  };
  BranchPlot::Marker pd{"period doubling", 7, "#d7191c", {}, {}}, ns{"Neimark-Sacker", 5, "#7b3294", {}, {}};
  for (const HbmBranch& b : r.branches) {
    BranchPlot::Branch br;
    auto add = [&](const HbmPoint& p) {
      br.x.push_back(omega ? p.omega : p.alpha);
      br.y.push_back(p.amplitude);
      br.stable.push_back(p.stable);
    };
    for (const HbmPoint& p : b.points) {
      if (!p.converged) continue;
      const std::string name = name_of(p);
      if (!br.x.empty() && name != br.name) {  // the orbit changes well: the run ends at this point
        add(p);
        d.branches.push_back(std::move(br));
        br = BranchPlot::Branch{};
      }
      br.name = name;
      // A bifurcation located on the step ending here joins the curve twice, with the stability before
      // and after it (the stability changes there, not at a grid point), and is marked where located.
      auto located = [&](const HbmLocated& l, BranchPlot::Marker* mk) {
        const double x = omega ? l.omega : l.alpha;
        if (!br.x.empty()) br.x.push_back(x), br.y.push_back(l.amplitude), br.stable.push_back(br.stable.back());
        br.x.push_back(x), br.y.push_back(l.amplitude), br.stable.push_back(p.stable);
        if (mk)
          mk->x.push_back(x), mk->y.push_back(l.amplitude);
        else
          br.fold_x.push_back(x), br.fold_y.push_back(l.amplitude);
      };
      if (p.fold && p.fold_at.valid()) located(p.fold_at, nullptr);
      if (p.period_doubling && p.period_doubling_at.valid()) located(p.period_doubling_at, &pd);
      if (p.neimark_sacker && p.neimark_sacker_at.valid()) located(p.neimark_sacker_at, &ns);
      add(p);
      if (p.fold && !p.fold_at.valid()) br.fold_x.push_back(br.x.back()), br.fold_y.push_back(p.amplitude);
      if (p.period_doubling && !p.period_doubling_at.valid()) pd.x.push_back(br.x.back()), pd.y.push_back(p.amplitude);
      if (p.neimark_sacker && !p.neimark_sacker_at.valid()) ns.x.push_back(br.x.back()), ns.y.push_back(p.amplitude);
    }
    if (!br.x.empty()) d.branches.push_back(std::move(br));
  }
  d.markers.push_back(std::move(pd));
  d.markers.push_back(std::move(ns));
  // +well and -well orbits are mirror images (y -> -y) with the same max |y_m|: their curves coincide.
  // The +well ones are drawn first and wider, so both stay visible.
  auto ends = [](const std::string& s, const std::string& e) {
    return s.size() >= e.size() && s.compare(s.size() - e.size(), e.size(), e) == 0;
  };
  auto rank = [&](const BranchPlot::Branch& b) { return ends(b.name, "+well") ? 0 : ends(b.name, "-well") ? 2 : 1; };
  std::stable_sort(d.branches.begin(), d.branches.end(),
                   [&](const auto& x, const auto& y) { return rank(x) < rank(y); });
  // A -well run that coincides with a +well run (its mirror image) is drawn once, named "±well", so no
  // two colours stripe one curve; a -well run without its mirror keeps its own colour, the +well ones wider.
  auto same = [](const BranchPlot::Branch& p, const BranchPlot::Branch& m) {
    if (p.x.size() != m.x.size() || p.stable != m.stable) return false;
    for (size_t i = 0; i < p.x.size(); ++i)
      if (std::fabs(p.x[i] - m.x[i]) > 1e-6 * std::max(1.0, std::fabs(p.x[i])) ||
          std::fabs(p.y[i] - m.y[i]) > 1e-6 * std::max(1.0, std::fabs(p.y[i])))
        return false;
    return true;
  };
  std::vector<bool> drop(d.branches.size(), false);
  for (size_t i = 0; i < d.branches.size(); ++i) {
    if (!ends(d.branches[i].name, "+well")) continue;
    const std::string mirror = d.branches[i].name.substr(0, d.branches[i].name.size() - 5) + "-well";
    for (size_t j = 0; j < d.branches.size(); ++j)
      if (!drop[j] && d.branches[j].name == mirror && same(d.branches[i], d.branches[j])) {
        drop[j] = true;
        d.branches[i].name = mirror.substr(0, mirror.size() - 5) + "\u00b1well (mirror images)";
        break;
      }
  }
  std::vector<BranchPlot::Branch> kept;
  for (size_t i = 0; i < d.branches.size(); ++i)
    if (!drop[i]) kept.push_back(std::move(d.branches[i]));
  d.branches = std::move(kept);
  bool minus = false;
  for (const auto& b : d.branches) minus |= ends(b.name, "-well");
  for (auto& b : d.branches)
    if (minus && ends(b.name, "+well")) b.width = 5;  // an unpaired -well curve on top stays visible
  return d;
}

void AddHbmCommand(CLI::App& app, int* exit_code) {
  auto a = std::make_shared<HbmArgs>();
  HbmOptions& o = a->o;
  CLI::App* cmd = app.add_subcommand("hbm", "Harmonic balance with continuation and stability (periodic orbits)");
  AddNondimModelOptions(cmd, &a->model, &o.params);
  cmd->add_option("--continue", a->param, "parameter to continue: omega | alpha")->capture_default_str();
  cmd->add_option("--from", o.from, "start of the parameter range")->capture_default_str();
  cmd->add_option("--to", o.to, "end of the parameter range")->capture_default_str();
  cmd->add_option("--alpha", o.alpha, "alpha when continuing in omega")->capture_default_str();
  cmd->add_option("--omega", o.omega, "Omega when continuing in alpha")->capture_default_str();
  cmd->add_option("--harmonics", o.harmonics, "harmonics H per degree of freedom (plus the constant term)")
      ->capture_default_str();
  cmd->add_option("--ds", o.ds, "initial arclength step")->capture_default_str();
  cmd->add_flag("--zero-mean", o.zero_mean,
                "drop the constant terms (the paper's Eq. 9 ansatz; misses intrawell orbits)");
  cmd->add_option(
         "--switch-pd", o.switch_depth,
         "at period doublings switch onto the doubled branch (harmonics of Omega/2, 2H of them) and continue it, "
         "this many times (1: period 2; 2: also period 4; at most 3)")
      ->capture_default_str();
  cmd->add_flag("--fold-curve", a->fold_curve,
                "continue every fold of the period-1 branches in (alpha, Omega): the boundary of the bistable region");
  cmd->add_option("--alpha-range", a->alpha_range, "LO,HI: alpha range of the fold curves")
      ->delimiter(',')
      ->expected(2)
      ->capture_default_str();
  cmd->add_option("--omega-range", a->omega_range, "LO,HI: Omega range of the fold curves")
      ->delimiter(',')
      ->expected(2)
      ->capture_default_str();
  cmd->add_option("--fold-out", a->fold_out, "fold-curve figure (default hbm_<model>_folds.<format>)");
  cmd->add_option(
      "--over-map", a->over_map,
      "draw the fold curves over a map: a map file of `bistable run` (<data>/sweeps/<id>.h5) or a sweep id in --data");
  cmd->add_option("--map-metric", a->map_metric, "the map's metric under the fold curves")->capture_default_str();
  cmd->add_option("--at", a->at, "fix the map's other axes: eta=0.1,... (its free axes must be alpha and omega)");
  cmd->add_option("--data", a->data, "data directory for --over-map <sweep id>")->capture_default_str();
  cmd->add_flag("--eq9", a->eq9, "overlay the closed-form one-harmonic zero-mean balance on the plot");
  cmd->add_flag(
      "--json", a->json,
      "print {branches: [{start, period, points: [...]}], bifurcations: [...], settings, truncation_change, notes"
      "[, fold_curves: [...]]}");
  cmd->add_option("--format", a->format,
                  "png | svg: plot amplitude vs the parameter (and the fold curves with --fold-curve)");
  cmd->add_option("--out", a->out, "plot file (default hbm_<model>.<format>)");
  cmd->footer(
      "Branches are seeded from time integrations (both wells and a large-amplitude start) at five parameter\n"
      "values and continued both ways by pseudo-arclength; stability from Floquet multipliers of each orbit.\n"
      "Folds (a multiplier through +1), period doublings (through -1) and Neimark-Sacker points (a complex pair\n"
      "through |mu| = 1) are flagged and located by bisection on the arclength step. Fold curves pass through\n"
      "cusps, so one curve gives both edges of a hysteresis region. Example:\n"
      "  bistable hbm --continue alpha --omega 1.2 --eta 0.3 --from 0.1 --to 0.25 --harmonics 10 --switch-pd 1 "
      "--format png\n"
      "  bistable hbm --alpha 0.3 --fold-curve --over-map bistable-data/sweeps/<id>.h5 --fold-out folds.png");
  cmd->callback([a, exit_code]() { *exit_code = RunHbm(*a); });
}

}  // namespace bistable
