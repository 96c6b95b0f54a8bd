#include "engine/evaluate.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>

#include "base/limits.h"
#include "dynamics/cancel.h"
#include "dynamics/ensemble_generic.h"
#include "dynamics/ensemble_rosenbrock.h"
#include "dynamics/generic_point.h"
#include "dynamics/point.h"
#include "dynamics/settle.h"
#include "engine/sweep_kind.h"

namespace bistable {
namespace {

// An item the numerics refused (the spec was validated, so this is a degenerate point, not bad input):
// stored as diverged (termination 1, metrics NaN) — and said so on stderr, with the reason.
PointResult Unevaluated(const SweepSpec& spec, long index, int ic, const Status& why) {
  if (!CancelRequested())
    std::fprintf(stderr, "evaluate: sweep %s point %ld ic %d could not be evaluated (%s); stored as diverged\n",
                 spec.Id().c_str(), index, ic, why.ToString().c_str());
  return DivergedResult();
}

// The metrics' view of a series or dimensional item: its window and metric settings, the cell kind
// whose motion classification applies (bistable or linear links/beam), and for the rig SI units —
// A0 in m, ω in rad/s, period_tol in m (units of δs, or of A0 for a linear beam).
PointSpec MetricProxy(const SweepSpec& spec, const PointSpec& p) {
  PointSpec proxy = p;
  if (spec.model == ModelKind::kSeries) {
    proxy.model = spec.series.bistable ? ModelKind::kStandalone : ModelKind::kLinear;
    return proxy;
  }
  const DimensionalParams& dp = spec.dimensional.params;
  const RigDrive drive = spec.DriveAt(p);
  const double delta_s = spec.terms                  ? TermWell(spec.terms->model, p.theta.data())
                         : spec.dimensional.bistable ? std::sqrt(-dp.k_lin / dp.k3)
                                                     : 0.0;
  const double a0 = drive.a0_m;
  proxy.model = (spec.terms ? delta_s > 0 : spec.dimensional.bistable) ? ModelKind::kStandalone : ModelKind::kLinear;
  proxy.alpha = a0;
  proxy.omega = drive.omega_rad_s;
  proxy.metrics.period_tol = p.metrics.period_tol * (delta_s > 0 ? delta_s : a0);
  return proxy;
}

// A chain at its point: the cells, at rest in every link's positive well.
SeriesLaneInput SeriesInputFor(const SweepSpec& spec, const PointSpec& p) {
  SeriesLaneInput in;
  in.cells = spec.SeriesCells(p);
  in.amp = p.alpha * p.omega * p.omega;
  in.omega = p.omega;
  in.base_amp = p.alpha;
  const Eigen::VectorXd x0 = SeriesModel(in.cells, p.alpha, p.omega).WellState();
  in.x0.assign(x0.data(), x0.data() + x0.size());
  return in;
}

// A two-body lane's sine base at the point's drive (SI), and its start when one is given: what the rig's and a
// term model's lane inputs share.
template <class Input>
bool SetBaseDrive(const SweepSpec& spec, const PointSpec& p, Input* in) {
  const RigDrive drive = spec.DriveAt(p);
  in->base_amp = drive.a0_m;
  in->omega = drive.omega_rad_s;
  in->amp = in->base_amp * in->omega * in->omega;
  if (p.ic_given) in->x0 = p.ic;
  return p.ic_given;
}

// The rig at its point (a0_mm, f0_hz): a sine base, at rest in the positive well (a linear beam at
// the origin) unless initial states are given.
DimensionalLaneInput DimensionalInputFor(const SweepSpec& spec, const PointSpec& p) {
  DimensionalLaneInput in;
  in.params = spec.dimensional.params;
  if (!SetBaseDrive(spec, p, &in) && spec.dimensional.bistable) in.x0[0] = std::sqrt(-in.params.k_lin / in.params.k3);
  return in;
}

// A term model at its point (model = "terms"): the point's own parameters (p.theta, which must outlive the
// run), a sine base, at rest in the positive well (the origin for a monostable model) unless a start is given.
TermLaneInput TermInputFor(const SweepSpec& spec, const PointSpec& p) {
  TermLaneInput in;
  in.model = &spec.terms->model;
  in.theta = p.theta.data();
  const bool started = SetBaseDrive(spec, p, &in);
  if (spec.terms->drive == TermsConfig::Drive::kForce) {  // F0 sin(ω t) on the main body; the base stands still
    in.base_amp = 0;
    in.amp = spec.DriveAt(p).force_n / spec.terms->model.m_main;
    in.force = true;
  }
  if (!started) in.x0[0] = TermWell(spec.terms->model, p.theta.data());
  return in;
}

// Items of a series or dimensional RK4 sweep through the lane kernel, W side by side. Every item of a
// sweep has the same window, step and (for the rig) substeps — they depend on the sweep's settings and
// rig parameters, never on the swept a0_mm, f0_hz — so any W items share a block.
template <int W>
std::optional<std::vector<PointResult>> ItemsInLanes(const SweepSpec& spec, const std::vector<WorkItem>& items) {
  std::vector<PointResult> out(items.size());
  std::array<PointSpec, W> specs;
  std::array<RawLane, W> raw;
  const PointSpec first = spec.PointAt(0, 0);
  KernelSettings ks = KernelSettingsFor(first);
  ks.keep_rows = false;
  const bool rosenbrock = first.integration.integrator == IntegratorKind::kRosenbrock;
  const int substeps = spec.terms ? spec.TermSubsteps()
                       : spec.model == ModelKind::kDimensional && !rosenbrock
                           ? Rk4Substeps(spec.dimensional.params, first.integration.dt)
                           : 1;
  RosenbrockTolerances tol;
  tol.rtol = first.integration.rtol;
  tol.atol = first.integration.atol;
  if (rosenbrock) {  // the whole job through W lanes at once: a lane takes the next item when its own is done
    std::vector<DimensionalLaneInput> in(items.size());
    std::vector<RawLane> raws(items.size());
    std::vector<PointSpec> all(items.size());
    for (size_t i = 0; i < items.size(); ++i) {
      all[i] = spec.PointAt(items[i].point, items[i].ic);
      in[i] = DimensionalInputFor(spec, all[i]);
    }
    if (!RunDimensionalRosenbrock<W>(in.data(), static_cast<int>(in.size()), ks, tol, raws.data())) return std::nullopt;
    for (size_t start = 0; start < items.size(); start += W) {
      const int n = static_cast<int>(std::min<size_t>(W, items.size() - start));
      std::array<PointSpec, W> proxies;
      for (int l = 0; l < n; ++l) proxies[l] = MetricProxy(spec, all[start + l]);
      ComputeBlockMetrics<W>(&raws[start], proxies.data(), n, &out[start]);
    }
    return out;
  }
  for (size_t start = 0; start < items.size(); start += W) {
    const int n = static_cast<int>(std::min<size_t>(W, items.size() - start));
    for (int l = 0; l < n; ++l) specs[l] = spec.PointAt(items[start + l].point, items[start + l].ic);
    bool done;
    if (spec.model == ModelKind::kSeries) {
      std::array<SeriesLaneInput, W> in;
      for (int l = 0; l < n; ++l) in[l] = SeriesInputFor(spec, specs[l]);
      done = RunSeriesLanes<W>(in.data(), n, ks, raw.data());
    } else if (spec.terms) {
      std::array<TermLaneInput, W> in;
      for (int l = 0; l < n; ++l) in[l] = TermInputFor(spec, specs[l]);
      done = RunTermLanes<W>(in.data(), n, ks, substeps, raw.data());
    } else {
      std::array<DimensionalLaneInput, W> in;
      for (int l = 0; l < n; ++l) in[l] = DimensionalInputFor(spec, specs[l]);
      done = RunDimensionalLanes<W>(in.data(), n, ks, substeps, raw.data());
    }
    if (!done) return std::nullopt;
    std::array<PointSpec, W> proxies;
    for (int l = 0; l < n; ++l) proxies[l] = MetricProxy(spec, specs[l]);
    ComputeBlockMetrics<W>(raw.data(), proxies.data(), n, &out[start]);
  }
  return out;
}

}  // namespace

Status CheckItems(const SweepSpec& spec, const std::vector<WorkItem>& items, const std::string& field) {
  const long n = static_cast<long>(items.size());
  if (n < 1 || n > limits::kMaxLeaseItems)
    return Status::InvalidArgument(field, field + " of " + std::to_string(n) + " items violates items in [1, " +
                                              std::to_string(limits::kMaxLeaseItems) + "]");
  const long points = spec.points();
  const int slots = spec.ic_count();
  for (long i = 0; i < n; ++i) {
    const WorkItem& w = items[i];
    const std::string at = field + ".items[" + std::to_string(i) + "]";
    if (w.point < 0 || w.point >= points)
      return Status::InvalidArgument(field, at + ": point = " + std::to_string(w.point) + " violates point in [0, " +
                                                std::to_string(points - 1) + "] (the sweep's grid points)");
    if (w.ic < 0 || w.ic >= slots)
      return Status::InvalidArgument(field, at + ": ic = " + std::to_string(w.ic) + " violates ic in [0, " +
                                                std::to_string(slots - 1) + "] (the sweep's initial-condition slots)");
  }
  return Status::Ok();
}

std::optional<std::vector<PointRecord>> ComputeItemsUnlessCancelled(const SweepSpec& spec,
                                                                    const std::vector<WorkItem>& items) {
  std::vector<PointRecord> out(items.size());
  const bool turning = spec.base.metrics.turning_points;
  const int section = spec.base.metrics.poincare_points;
  const SweepKind& kind = KindOf(spec);
  if (kind.Chained()) {
    // Chains in order: a point that continues the previous item's chain (same line and direction,
    // next index along the axis) starts from that item's final state; a chain's first point from the
    // spec's start state. One lane: the same kernel code as everywhere, so the bits are those of
    // `bistable point --ic <previous final state>`.
    std::array<double, 4> last = {0, 0, 0, 0};
    for (size_t i = 0; i < items.size(); ++i) {
      if (CancelRequested()) return std::nullopt;
      PointSpec p = spec.PointAt(items[i].point, items[i].ic);
      if (i > 0 && kind.Continues(spec, items[i - 1], items[i])) {
        p.ic_given = true;
        p.ic = last;
      }
      auto r = EvaluatePoint(p);
      if (!r.ok() && CancelRequested()) return std::nullopt;  // cancelled: no result, not "diverged"
      const PointResult res = r.ok() ? *r : Unevaluated(spec, items[i].point, items[i].ic, r.status());
      last = res.final_state;
      out[i] = PointRecord::From(res, turning, section);
    }
  } else if (spec.UsesGenericLanes()) {  // series and dimensional RK4: the lane kernel
    auto results = EvaluateItemsInLanes(spec, items, kSweepLanes);
    if (!results) return std::nullopt;
    for (size_t i = 0; i < items.size(); ++i) out[i] = PointRecord::From((*results)[i], turning, section);
  } else if (!spec.UsesKernel()) {  // adaptive: one point at a time
    for (size_t i = 0; i < items.size(); ++i) {
      if (CancelRequested()) return std::nullopt;
      // A cancelled evaluation comes back as a diverged record; the check below discards the job.
      out[i] = PointRecord::From(EvaluateItem(spec, items[i].point, items[i].ic), turning, section);
    }
  } else if (spec.base.integration.labels == LabelMode::kSettled) {  // chains of windows (settle.h)
    std::vector<PointSpec> specs(items.size());
    for (size_t i = 0; i < items.size(); ++i) specs[i] = spec.PointAt(items[i].point, items[i].ic);
    std::vector<PointResult> results(items.size());
    if (!EvaluateSettled<kSweepLanes>(specs.data(), specs.size(), results.data())) return std::nullopt;
    for (size_t i = 0; i < items.size(); ++i) out[i] = PointRecord::From(std::move(results[i]), turning, section);
  } else {
    const PointSpec first = spec.PointAt(0, 0);
    const KernelSettings ks = KernelSettingsFor(first);
    std::array<PointSpec, kSweepLanes> specs;
    std::array<LaneInput, kSweepLanes> lanes;
    std::array<RawLane, kSweepLanes> raw;
    std::array<PointResult, kSweepLanes> results;
    for (size_t start = 0; start < items.size(); start += kSweepLanes) {
      const int n = static_cast<int>(std::min<size_t>(kSweepLanes, items.size() - start));
      for (int l = 0; l < n; ++l) {
        specs[l] = spec.PointAt(items[start + l].point, items[start + l].ic);
        lanes[l] = LaneFor(specs[l]);
      }
      if (!RunKernel<kSweepLanes>(spec.base.model, lanes.data(), n, ks, raw.data())) return std::nullopt;
      ComputeBlockMetrics<kSweepLanes>(raw.data(), specs.data(), n, results.data());
      for (int l = 0; l < n; ++l) out[start + l] = PointRecord::From(std::move(results[l]), turning, section);
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
  if (spec.UsesGenericLanes()) {  // the lane kernel at width 1: the bits of the same item in a sweep
    auto r = EvaluateItemsInLanes(spec, {WorkItem{index, ic}}, 1);
    return r ? (*r)[0] : DivergedResult();  // cancelled: the caller discards the job
  }
  GenericWindow w;  // adaptive (Dormand–Prince), one point at a time
  w.t_end = p.integration.t_end;
  w.t_keep = p.integration.t_keep;
  w.dt = p.integration.dt;
  w.adaptive = true;
  w.tol.rtol = p.integration.rtol;
  w.tol.atol = p.integration.atol;
  w.renorm_every = p.metrics.renorm_every;
  w.sample_every = p.metrics.sample_every;
  w.strobe_phase = p.metrics.poincare_phase;
  RawLane raw;
  if (spec.model == ModelKind::kSeries) {
    const SeriesLaneInput in = SeriesInputFor(spec, p);
    SeriesModel m(in.cells, p.alpha, p.omega);
    const int last = m.cells() - 1;
    const int yl = m.MainIndex(last), yp = last > 0 ? m.MainIndex(last - 1) : -1;
    w.position = [yl, yp](const Eigen::VectorXd& x) { return x[yl] - (yp >= 0 ? x[yp] : 0.0); };
    w.velocity = [yl](const Eigen::VectorXd& x) { return x[yl + 1]; };
    w.amp = in.base_amp;
    w.omega = in.omega;
    raw = RunGenericWindow(m, Eigen::Map<const Eigen::VectorXd>(in.x0.data(), m.dim()), w);
  } else {
    const DimensionalLaneInput in = DimensionalInputFor(spec, p);
    DimensionalModel m(in.params, SineBase(in.base_amp, p.omega));
    w.position = [](const Eigen::VectorXd& x) { return x[0]; };
    w.velocity = [](const Eigen::VectorXd& x) { return x[1]; };
    w.amp = in.base_amp;
    w.omega = in.omega;
    raw = RunGenericWindow(m, Eigen::Map<const Eigen::Vector4d>(in.x0.data()), w);
  }
  return ComputePointMetrics(std::move(raw), MetricProxy(spec, p));
}

std::optional<std::vector<PointResult>> EvaluateItemsInLanes(const SweepSpec& spec, const std::vector<WorkItem>& items,
                                                             int width) {
  switch (width) {
    case 1:
      return ItemsInLanes<1>(spec, items);
    case 4:
      return ItemsInLanes<4>(spec, items);
    default:
      return ItemsInLanes<kSweepLanes>(spec, items);
  }
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
