#include "engine/basins.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <numeric>

#include "base/limits.h"

namespace bistable {

BasinMap ClassifyAttractors(const SweepSpec& spec, const std::vector<PointRecord>& records, double tol) {
  const size_t motion_i = MetricIndex("motion"), period_i = MetricIndex("period"), ymin_i = MetricIndex("y_min"),
               ymax_i = MetricIndex("y_max"), sy_i = MetricIndex("strobe_y"), sv_i = MetricIndex("strobe_v");
  BasinMap out;
  out.ids.assign(records.size(), -1);
  std::vector<Attractor> found;  // in order of discovery; renumbered by basin size below
  int other = -1;                // the class of starts past limits::kMaxAttractors kinds
  for (size_t i = 0; i < records.size(); ++i) {
    const PointRecord& r = records[i];
    const double motion = r.Get(motion_i);
    if (!(motion >= 0)) continue;  // undefined (diverged)
    const int period = static_cast<int>(r.Get(period_i));
    const double lo = r.Get(ymin_i), hi = r.Get(ymax_i);
    const std::string well = lo > 0 ? "+well" : hi < 0 ? "-well" : "interwell";
    const bool periodic =
        period > 0 && static_cast<int>(motion) != 2 && std::isfinite(r.Get(sy_i)) && std::isfinite(r.Get(sv_i));
    const double y = periodic ? r.Get(sy_i) : NAN, v = periodic ? r.Get(sv_i) : NAN;
    int hit = -1;
    for (size_t a = 0; a < found.size() && hit < 0; ++a) {
      const Attractor& at = found[a];
      if (static_cast<int>(a) == other) continue;
      if (at.motion != static_cast<int>(motion) || at.period != (periodic ? period : 0)) continue;
      if (periodic ? (std::fabs(at.strobe_y - y) <= tol && std::fabs(at.strobe_v - v) <= tol) : at.well == well)
        hit = static_cast<int>(a);
    }
    if (hit < 0 && static_cast<int>(found.size()) >= limits::kMaxAttractors) {
      // Past the limit: one class for every further kind (its label says so).
      if (other < 0) {
        Attractor at;
        at.motion = -2;
        at.well = "other";
        at.strobe_y = at.strobe_v = NAN;
        found.push_back(at);
        other = static_cast<int>(found.size()) - 1;
      }
      hit = other;
    }
    if (hit < 0) {
      Attractor at;
      at.motion = static_cast<int>(motion);
      at.period = periodic ? period : 0;
      at.well = well;
      at.strobe_y = y;
      at.strobe_v = v;
      found.push_back(at);
      hit = static_cast<int>(found.size()) - 1;
    }
    ++found[hit].cells;
    out.ids[i] = hit;
  }
  // Ids by basin size (largest first; ties by discovery order, which is the grid's).
  std::vector<int> order(found.size());
  std::iota(order.begin(), order.end(), 0);
  std::stable_sort(order.begin(), order.end(), [&](int a, int b) { return found[a].cells > found[b].cells; });
  std::vector<int> rank(found.size());
  for (size_t k = 0; k < order.size(); ++k) rank[order[k]] = static_cast<int>(k);
  for (int& id : out.ids)
    if (id >= 0) id = rank[id];
  for (size_t k = 0; k < order.size(); ++k) {
    Attractor at = found[order[k]];
    at.id = static_cast<int>(k);
    char buf[96];
    if (at.motion == -2)
      std::snprintf(buf, sizeof buf, "A%d_other_(more_than_%d_kinds)", at.id, limits::kMaxAttractors);
    else if (at.period > 0)
      std::snprintf(buf, sizeof buf, "A%d_P%d_%s_y%.3f_v%.3f", at.id, at.period, at.well.c_str(), at.strobe_y,
                    at.strobe_v);
    else
      std::snprintf(buf, sizeof buf, "A%d_%s_%s", at.id, at.motion == 2 ? "chaotic" : "aperiodic", at.well.c_str());
    at.label = buf;
    out.attractors.push_back(at);
  }
  // Boundaries: a start with a neighbour (±1 along any axis) on another attractor.
  const size_t n = records.size(), nic = static_cast<size_t>(spec.ic_count());
  std::vector<long> stride(spec.axes.size(), 1);
  for (int k = static_cast<int>(spec.axes.size()) - 2; k >= 0; --k)
    stride[k] = stride[k + 1] * static_cast<long>(spec.axes[k + 1].values.size());
  std::vector<long> boundary(out.attractors.size(), 0);
  long on_boundary = 0, defined = 0;
  for (size_t i = 0; i < n; ++i) {
    const int id = out.ids[i];
    if (id < 0) continue;
    ++defined;
    const long point = static_cast<long>(i / nic), ic = static_cast<long>(i % nic);
    const std::vector<int> idx = spec.AxisIndices(point);
    bool edge = false;
    for (size_t k = 0; k < spec.axes.size() && !edge; ++k)
      for (int d : {-1, 1}) {
        const long j = idx[k] + d;
        if (j < 0 || j >= static_cast<long>(spec.axes[k].values.size())) continue;
        const int other = out.ids[static_cast<size_t>((point + d * stride[k]) * static_cast<long>(nic) + ic)];
        if (other >= 0 && other != id) edge = true;
      }
    if (edge) ++boundary[id], ++on_boundary;
  }
  for (Attractor& at : out.attractors) {
    at.basin_fraction = static_cast<double>(at.cells) / static_cast<double>(n);
    at.boundary_fraction = at.cells > 0 ? static_cast<double>(boundary[at.id]) / static_cast<double>(at.cells) : 0.0;
  }
  out.boundary_fraction = defined > 0 ? static_cast<double>(on_boundary) / static_cast<double>(defined) : 0.0;
  return out;
}

}  // namespace bistable
