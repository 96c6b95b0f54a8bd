#include "worker/block_worker.h"

#include <array>

#include "dynamics/cancel.h"
#include "dynamics/point.h"

namespace bistable {

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
      const PointResult res = r.ok() ? *r : PointResult{Termination::kDiverged};
      last = res.final_state;
      out[i] = PointRecord::From(res, turning);
    }
  } else if (!spec.UsesKernel()) {  // series, dimensional, adaptive: one point at a time
    for (size_t i = 0; i < items.size(); ++i) {
      if (CancelRequested()) return std::nullopt;
      // A cancelled evaluation comes back as a diverged record; the check below discards the job.
      out[i] = PointRecord::From(spec.EvaluateItem(items[i].point, items[i].ic), turning);
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
      if (!RunKernel<kSweepLanes>(spec.model, lanes.data(), n, ks, raw.data())) return std::nullopt;
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

}  // namespace bistable
