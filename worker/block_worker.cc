#include "worker/block_worker.h"

#include <array>

#include "dynamics/point.h"

namespace bistable {

std::vector<PointRecord> ComputeItems(const SweepSpec& spec, const std::vector<WorkItem>& items) {
  std::vector<PointRecord> out(items.size());
  if (!spec.UsesKernel()) {  // series, dimensional, adaptive: one point at a time
    for (size_t i = 0; i < items.size(); ++i) out[i] = PointRecord::From(spec.EvaluateItem(items[i].point, items[i].ic));
    return out;
  }
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
    RunKernel<kSweepLanes>(spec.model, lanes.data(), n, ks, raw.data());
    for (int l = 0; l < n; ++l) out[start + l] = PointRecord::From(ComputePointMetrics(std::move(raw[l]), specs[l]));
  }
  return out;
}

}  // namespace bistable
