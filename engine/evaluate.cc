#include "engine/evaluate.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>

#include "base/limits.h"
#include "dynamics/cancel.h"
#include "dynamics/generic_point.h"
#include "dynamics/point.h"

namespace bistable {
namespace {

// An item the numerics refused (the spec was validated, so this is a degenerate point, not bad input):
// stored as diverged (termination 1, metrics NaN) — and said so on stderr, with the reason.
PointResult Unevaluated(const SweepSpec& spec, long index, int ic, const Status& why) {
  if (!CancelRequested())
    std::fprintf(stderr, "evaluate: sweep %s point %ld ic %d could not be evaluated (%s); stored as diverged\n",
                 spec.Id().c_str(), index, ic, why.ToString().c_str());
  return PointResult{Termination::kDiverged};
}

}  // namespace


std::optional<std::vector<PointRecord>> ComputeItemsUnlessCancelled(const SweepSpec& spec,
                                                                    const std::vector<WorkItem>& items) {
  std::vector<PointRecord> out(items.size());
  const bool turning = spec.base.metrics.turning_points;
  if (spec.continuation.enabled()) {
    // Chains in order: a point that continues the previous item's chain (same line and direction,
    // next index along the axis) starts from that item's final state; a chain's first point from the
    // spec's start state. One lane: the same kernel code as everywhere, so the bits are those of
    // `bistable point --ic <previous final state>`.
    std::array<double, 4> last = {0, 0, 0, 0};
    for (size_t i = 0; i < items.size(); ++i) {
      if (CancelRequested()) return std::nullopt;
      PointSpec p = spec.PointAt(items[i].point, items[i].ic);
      if (i > 0) {
        const WorkItem& prev = items[i - 1];
        const int step = spec.ChainGoesDown(items[i].ic) ? -1 : 1;
        if (prev.ic == items[i].ic && spec.ContinuationLine(prev.point) == spec.ContinuationLine(items[i].point) &&
            spec.ContinuationIndex(items[i].point) == spec.ContinuationIndex(prev.point) + step) {
          p.ic_given = true;
          p.ic = last;
        }
      }
      auto r = EvaluatePoint(p);
      if (!r.ok() && CancelRequested()) return std::nullopt;  // cancelled: no result, not "diverged"
      const PointResult res = r.ok() ? *r : Unevaluated(spec, items[i].point, items[i].ic, r.status());
      last = res.final_state;
      out[i] = PointRecord::From(res, turning);
    }
  } else if (!spec.UsesKernel()) {  // series, dimensional, adaptive: one point at a time
    for (size_t i = 0; i < items.size(); ++i) {
      if (CancelRequested()) return std::nullopt;
      // A cancelled evaluation comes back as a diverged record; the check below discards the job.
      out[i] = PointRecord::From(EvaluateItem(spec, items[i].point, items[i].ic), turning);
    }
  } else {
    const PointSpec first = spec.PointAt(0, 0);
    const KernelSettings ks = KernelSettingsFor(first);
    std::array<PointSpec, kSweepLanes> specs;
    std::array<LaneInput, kSweepLanes> lanes;
    std::array<RawLane, kSweepLanes> raw;
    for (size_t start = 0; start < items.size(); start += kSweepLanes) {
      const int n = static_cast<int>(std::min<size_t>(kSweepLanes, items.size() - start));
      for (int l = 0; l < n; ++l) {
        specs[l] = spec.PointAt(items[start + l].point, items[start + l].ic);
        lanes[l] = LaneFor(specs[l]);
      }
      if (!RunKernel<kSweepLanes>(spec.base.model, lanes.data(), n, ks, raw.data())) return std::nullopt;
      for (int l = 0; l < n; ++l) out[start + l] = PointRecord::From(ComputePointMetrics(std::move(raw[l]), specs[l]), turning);
    }
  }
  // The flag is sticky: clear now means no integration of this job saw it, so every record is whole.
  if (CancelRequested()) return std::nullopt;
  return out;
}

std::vector<PointRecord> ComputeItems(const SweepSpec& spec, const std::vector<WorkItem>& items) {
  auto records = ComputeItemsUnlessCancelled(spec, items);
  return records ? std::move(*records) : std::vector<PointRecord>{};
}


PointResult EvaluateItem(const SweepSpec& spec, long index, int ic) {
  const PointSpec p = spec.PointAt(index, ic);
  if (IsCellModel(spec.model)) {
    auto r = EvaluatePoint(p);
    return r.ok() ? *r : Unevaluated(spec, index, ic, r.status());
  }
  PointSpec proxy = p;  // carries window, metric settings and the motion classification's model kind
  GenericWindow w;
  w.t_end = p.integration.t_end;
  w.t_keep = p.integration.t_keep;
  w.dt = p.integration.dt;
  w.adaptive = p.integration.integrator == IntegratorKind::kAdaptive;
  w.tol.rtol = p.integration.rtol;
  w.tol.atol = p.integration.atol;
  w.renorm_every = p.metrics.renorm_every;
  w.sample_every = p.metrics.sample_every;
  RawLane raw;
  if (spec.model == ModelKind::kSeries) {
    const std::vector<SeriesCell> cells = spec.SeriesCells(p);
    SeriesModel m(cells, p.alpha, p.omega);
    const int last = m.cells() - 1;
    const int yl = m.MainIndex(last), yp = last > 0 ? m.MainIndex(last - 1) : -1;
    w.position = [yl, yp](const Eigen::VectorXd& x) { return x[yl] - (yp >= 0 ? x[yp] : 0.0); };
    w.velocity = [yl](const Eigen::VectorXd& x) { return x[yl + 1]; };
    w.amp = p.alpha;
    w.omega = p.omega;
    proxy.model = spec.series.bistable ? ModelKind::kStandalone : ModelKind::kLinear;
    raw = RunGenericWindow(m, m.WellState(), w);
  } else {
    const DimensionalParams& dp = spec.dimensional.params;
    const double a0 = p.alpha * 1e-3, f0 = p.omega, omega = 2.0 * M_PI * f0;
    DimensionalModel m(dp, SineBase(a0, f0));
    const double delta_s = spec.dimensional.bistable ? std::sqrt(-dp.k_lin / dp.k3) : 0.0;
    Eigen::VectorXd x0 = Eigen::VectorXd::Zero(4);
    if (p.ic_given) {
      for (int i = 0; i < 4; ++i) x0[i] = p.ic[i];
    } else {
      x0[0] = delta_s;  // at rest in the positive well (linear beam: at rest at the origin)
    }
    w.position = [](const Eigen::VectorXd& x) { return x[0]; };
    w.velocity = [](const Eigen::VectorXd& x) { return x[1]; };
    w.amp = a0;
    w.omega = omega;
    w.adaptive = true;
    proxy.model = spec.dimensional.bistable ? ModelKind::kStandalone : ModelKind::kLinear;
    proxy.alpha = a0;
    proxy.omega = omega;
    // Stroboscopic repetition tolerance in metres (and m/s): period_tol in units of δs (or of A0).
    proxy.metrics.period_tol = p.metrics.period_tol * (delta_s > 0 ? delta_s : a0);
    raw = RunGenericWindow(m, x0, w);
  }
  return ComputePointMetrics(std::move(raw), proxy);
}

long JobItems(const SweepSpec& spec, double seconds, long min_jobs) {
  const double steps = spec.base.integration.t_end / spec.base.integration.dt;
  const double per_item = steps / 1.5e7 * (spec.UsesKernel() ? 1.0 : 8.0);
  long n = static_cast<long>(std::min(seconds / std::max(per_item, 1e-9), 1e9));
  if (min_jobs > 0) n = std::min(n, (spec.points() * spec.ic_count() + min_jobs - 1) / min_jobs);
  n = std::clamp<long>(n, kSweepLanes, limits::kMaxJobItems);
  return n / kSweepLanes * kSweepLanes;
}

}  // namespace bistable
