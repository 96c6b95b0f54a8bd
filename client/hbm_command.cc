// `bistable hbm`: harmonic balance with continuation and stability (model.md §4).
#include <algorithm>
#include <iostream>
#include <memory>

#include <nlohmann/json.hpp>

#include "client/cli_common.h"
#include "client/hbm_command.h"
#include "client/plot.h"
#include "dynamics/cancel.h"
#include "dynamics/hbm.h"

namespace bistable {
namespace {

struct HbmArgs {
  std::string model = "standalone", param = "omega", format, out;
  bool json = false, eq9 = false;
  HbmOptions o;
};

nlohmann::json PointJson(const HbmPoint& p) {
  auto num = [](double v) { return std::isfinite(v) ? nlohmann::json(v) : nlohmann::json(nullptr); };
  return {{"omega", p.omega},       {"alpha", p.alpha},   {"amplitude", num(p.amplitude)}, {"mean", num(p.mean)},
          {"stable", p.stable},     {"max_multiplier", num(p.max_multiplier)},  {"converged", p.converged},
          {"fold", p.fold},         {"branch_point", p.branch_point},           {"harmonics", p.harmonics},
          {"y_min", num(p.y_min)},  {"y_max", num(p.y_max)}};
}

int RunHbm(HbmArgs& a) {
  auto m = ParseModel(a.model);
  if (!m.ok()) return Fail(m.status());
  a.o.model = *m;
  if (a.param == "omega") a.o.param = ContinuationParam::kOmega;
  else if (a.param == "alpha") a.o.param = ContinuationParam::kAlpha;
  else return Fail(Status::InvalidArgument("continue", "continue = '" + a.param + "' violates continue in {omega, alpha}"));
  if (!a.format.empty() && a.format != "png" && a.format != "svg")
    return Fail(Status::InvalidArgument("format", "format = '" + a.format + "' violates format in {png, svg}"));
  InstallCancelSignalHandlers();  // Ctrl-C / SIGTERM: the continuation stops at its next point
  auto r = ContinueBranches(a.o);
  RestoreDefaultSignalHandlers();
  if (CancelRequested()) {
    std::cerr << "interrupted: the continuation was not finished; nothing was printed or written\n";
    return CancelExitStatus();
  }
  if (!r.ok()) return Fail(r.status());
  const bool omega = a.o.param == ContinuationParam::kOmega;
  if (a.json) {
    nlohmann::json branches = nlohmann::json::array();
    for (const HbmBranch& b : r->branches) {
      nlohmann::json pts = nlohmann::json::array();
      for (const HbmPoint& p : b.points) {
        pts.push_back(PointJson(p));
        if (IsBistable(a.o.model)) pts.back()["well"] = OrbitWellName(WellOf(p));
      }
      branches.push_back({{"start", b.start}, {"points", pts}});
    }
    nlohmann::json settings = {{"model", ModelName(a.o.model)}, {"continue", a.param}, {"from", a.o.from}, {"to", a.o.to},
                               {"alpha", a.o.alpha}, {"omega", a.o.omega}, {"harmonics", a.o.harmonics},
                               {"zero_mean", a.o.zero_mean}, {"eps", a.o.params.eps}, {"eta", a.o.params.eta},
                               {"numerics_version", kNumericsVersion}};
    if (HasResonator(a.o.model)) settings.update({{"eta_r", a.o.params.eta_r}, {"phi", a.o.params.phi}, {"lambda", a.o.params.lambda}});
    std::cout << nlohmann::json({{"branches", branches}, {"settings", settings},
                                 {"truncation_change", r->truncation_change}}).dump(1) << "\n";
  }
  if (!a.format.empty() || !a.out.empty()) {
    BranchPlot d = HbmBranchPlot(*r, a.o.model, a.o.param,
                                 std::string("harmonic balance, ") + ModelName(a.o.model) + " (H = " + std::to_string(a.o.harmonics) +
                                     "), " + (omega ? "alpha = " + PlotNumber(a.o.alpha) : "Omega = " + PlotNumber(a.o.omega)));
    if (a.eq9) {
      d.extra_label = "one harmonic, zero mean (corrected Eq. 9)";
      for (int k = 0; k <= 600; ++k) {
        const double p = a.o.from + (a.o.to - a.o.from) * k / 600.0;
        for (double q : Eq9Amplitudes(a.o.model, a.o.params, omega ? a.o.alpha : p, omega ? p : a.o.omega))
          d.extra_x.push_back(p), d.extra_y.push_back(q);
      }
    }
    const std::string out = a.out.empty() ? "hbm_" + a.model + "." + (a.format.empty() ? "png" : a.format) : a.out;
    Status st = RenderBranches(d, out);
    if (!st.ok()) return Fail(st);
    if (!a.json) std::cout << out << "\n";
  }
  if (!a.json && a.format.empty() && a.out.empty()) {
    std::printf("%zu branches (truncation check: amplitude changes by %.2g%% with H+2 harmonics)\n", r->branches.size(),
                100 * r->truncation_change);
    for (const HbmBranch& b : r->branches) {
      int stable = 0, folds = 0;
      double lo = INFINITY, hi = 0;
      for (const HbmPoint& p : b.points) stable += p.stable, folds += p.fold, lo = std::min(lo, p.amplitude), hi = std::max(hi, p.amplitude);
      std::printf("  %-50s %4zu points, amplitude %.3f..%.3f, mean %+.3f, %d stable, %d folds\n", b.start.c_str(),
                  b.points.size(), lo, hi, b.points.front().mean, stable, folds);
    }
  }
  return 0;
}

}  // namespace

BranchPlot HbmBranchPlot(const HbmResult& r, ModelKind model, ContinuationParam param, const std::string& title) {
  const bool omega = param == ContinuationParam::kOmega;
  BranchPlot d;
  d.title = title;
  d.x_name = omega ? "omega" : "alpha";
  d.x_unit = omega ? "omega0/omega_n" : "A0/delta_s";
  d.y_label = "max |y_m| over a period [{/Symbol d}_s]";
  auto name_of = [&](const HbmPoint& p) { return IsBistable(model) ? std::string(OrbitWellName(WellOf(p))) : std::string("periodic orbit"); };
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
      add(p);
      if (p.fold) br.fold_x.push_back(br.x.back()), br.fold_y.push_back(p.amplitude);
    }
    if (!br.x.empty()) d.branches.push_back(std::move(br));
  }
  // +well and -well orbits are mirror images (y -> -y) with the same max |y_m|: their curves coincide.
  // The +well ones are drawn first and wider, so both stay visible.
  auto rank = [](const BranchPlot::Branch& b) { return b.name == "+well" ? 0 : b.name == "-well" ? 2 : 1; };
  std::stable_sort(d.branches.begin(), d.branches.end(), [&](const auto& x, const auto& y) { return rank(x) < rank(y); });
  bool plus = false, minus = false;
  for (auto& b : d.branches) {
    if (b.name == "+well") b.width = 5, plus = true;
    minus |= b.name == "-well";
  }
  if (plus && minus) d.title += "\n(+well, -well: mirror images with equal max |y_m|; the wider +well curves lie beneath)";
  return d;
}

void AddHbmCommand(CLI::App& app, int* exit_code) {
  auto a = std::make_shared<HbmArgs>();
  HbmOptions& o = a->o;
  CLI::App* cmd = app.add_subcommand("hbm", "Harmonic balance with continuation and stability (periodic orbits)");
  cmd->add_option("--model", a->model, "standalone | coupled | linear | linear-coupled")->capture_default_str();
  cmd->add_option("--continue", a->param, "parameter to continue: omega | alpha")->capture_default_str();
  cmd->add_option("--from", o.from, "start of the parameter range")->capture_default_str();
  cmd->add_option("--to", o.to, "end of the parameter range")->capture_default_str();
  cmd->add_option("--alpha", o.alpha, "alpha when continuing in omega")->capture_default_str();
  cmd->add_option("--omega", o.omega, "Omega when continuing in alpha")->capture_default_str();
  cmd->add_option("--harmonics", o.harmonics, "harmonics H per degree of freedom (plus the constant term)")->capture_default_str();
  cmd->add_option("--eps", o.params.eps, "cubic stiffness epsilon")->capture_default_str();
  cmd->add_option("--eta", o.params.eta, "main damping eta")->capture_default_str();
  cmd->add_option("--eta-r", o.params.eta_r, "resonator damping eta_r")->capture_default_str();
  cmd->add_option("--phi", o.params.phi, "mass ratio phi")->capture_default_str();
  cmd->add_option("--lambda", o.params.lambda, "tuning lambda")->capture_default_str();
  cmd->add_option("--ds", o.ds, "initial arclength step")->capture_default_str();
  cmd->add_flag("--zero-mean", o.zero_mean, "drop the constant terms (the paper's Eq. 9 ansatz; misses intrawell orbits)");
  cmd->add_flag("--eq9", a->eq9, "overlay the closed-form one-harmonic zero-mean balance on the plot");
  cmd->add_flag("--json", a->json, "print {branches: [{start, points: [...]}], settings, truncation_change}");
  cmd->add_option("--format", a->format, "png | svg: plot amplitude vs the parameter");
  cmd->add_option("--out", a->out, "plot file (default hbm_<model>.<format>)");
  cmd->footer(
      "Branches are seeded from time integrations (both wells and a large-amplitude start) at five parameter\n"
      "values and continued both ways by pseudo-arclength; stability from Floquet multipliers of each orbit.");
  cmd->callback([a, exit_code]() { *exit_code = RunHbm(*a); });
}

}  // namespace bistable
