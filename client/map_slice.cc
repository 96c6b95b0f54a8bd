#include "client/map_slice.h"

#include "client/cli_common.h"

#include <algorithm>
#include <cmath>
#include <set>
#include <sstream>

#include "base/validate.h"
#include "engine/metric_catalog.h"
#include "engine/sweep_spec.h"

namespace bistable {

StatusOr<std::map<std::string, double>> ParseAt(const std::string& text) {
  auto pairs = ParseNameValues(text, "at");
  if (!pairs.ok()) return pairs.status();
  std::map<std::string, double> at;
  for (const auto& [name, value] : *pairs) {
    auto x = ParseFiniteNumber(value, "at." + name);
    if (!x.ok()) return x.status();
    at[name] = *x;
  }
  return at;
}

StatusOr<Slice> SliceMap(const MapArray& m, const std::map<std::string, double>& at, int max_free) {
  Slice s;
  s.metric = m.metric;
  s.unit = m.unit;
  const size_t rank = m.dims.size();
  std::vector<long> fixed_index(rank, -1);
  for (const auto& [name, value] : at) {
    size_t k = 0;
    while (k < rank && m.dim_names[k] != name) ++k;
    if (k == rank) {
      std::string dims;
      for (const auto& d : m.dim_names) dims += (dims.empty() ? "" : ", ") + d;
      return Status::InvalidArgument(
          "at", "--at " + name + ": not a dimension of " + m.metric + " (dimensions: " + dims + ")");
    }
    if (k < m.axes.size()) {
      const auto& vals = m.axes[k].values;
      long best = -1;
      for (size_t i = 0; i < vals.size(); ++i)
        if (std::fabs(vals[i] - value) <= 1e-9 * std::max(1.0, std::fabs(value))) best = static_cast<long>(i);
      if (best < 0) {
        std::string near;
        double bd = INFINITY;
        for (double v : vals)
          if (std::fabs(v - value) < bd) bd = std::fabs(v - value), near = FormatNumber(v);
        return Status::InvalidArgument("at", "--at " + name + " = " + FormatNumber(value) +
                                                 " is not on the axis (nearest " + near + "; " +
                                                 std::to_string(vals.size()) + " values from " +
                                                 FormatNumber(vals.front()) + " to " + FormatNumber(vals.back()) + ")");
      }
      fixed_index[k] = best;
    } else {
      if (value < 0 || value >= static_cast<double>(m.dims[k]) || value != std::floor(value))
        return Violates("at", value, "an index in [0, " + std::to_string(m.dims[k] - 1) + "] for " + m.dim_names[k]);
      fixed_index[k] = static_cast<long>(value);
    }
    s.fixed[name] = value;
  }
  std::vector<size_t> free_dims;
  for (size_t k = 0; k < rank; ++k) {
    if (fixed_index[k] >= 0) continue;
    if (k >= m.axes.size()) {
      if (m.dim_names[k] == "peak")
        return Status::InvalidArgument("metric",
                                       m.metric + " has a peak dimension; use `bistable map ID --metric hd_scatter`");
      fixed_index[k] = 0;  // ic defaults to the first initial condition
      s.fixed[m.dim_names[k]] = 0;
    } else if (m.dims[k] == 1) {
      fixed_index[k] = 0;
      s.fixed[m.dim_names[k]] = m.axes[k].values[0];
    } else {
      free_dims.push_back(k);
      s.free.push_back(m.axes[k]);
    }
  }
  if (free_dims.empty() || static_cast<int>(free_dims.size()) > max_free) {
    std::string names;
    for (size_t k : free_dims) names += (names.empty() ? "" : ", ") + m.dim_names[k];
    return Status::InvalidArgument("at", "a map needs 1 to " + std::to_string(max_free) + " free axes, this leaves " +
                                             std::to_string(free_dims.size()) +
                                             (names.empty() ? "" : " (" + names + ")") +
                                             "; fix the others with --at name=value");
  }
  // Gather.
  std::vector<size_t> stride(rank, 1);
  for (long k = static_cast<long>(rank) - 2; k >= 0; --k) stride[k] = stride[k + 1] * m.dims[k + 1];
  size_t base = 0;
  for (size_t k = 0; k < rank; ++k)
    if (fixed_index[k] >= 0) base += static_cast<size_t>(fixed_index[k]) * stride[k];
  if (free_dims.size() == 1) {
    for (size_t i = 0; i < m.dims[free_dims[0]]; ++i) s.values.push_back(m.values[base + i * stride[free_dims[0]]]);
  } else {
    for (size_t i = 0; i < m.dims[free_dims[0]]; ++i)
      for (size_t j = 0; j < m.dims[free_dims[1]]; ++j)
        s.values.push_back(m.values[base + i * stride[free_dims[0]] + j * stride[free_dims[1]]]);
  }
  return s;
}

std::vector<PlotData::Code> MetricCodes(const std::string& metric, const std::vector<double>& values,
                                        const std::vector<std::pair<int, std::string>>& file_categories) {
  const MetricInfo* info = FindMetric(metric);
  if ((!info || !info->integer) && !file_categories.empty()) {  // codes named by the file (a basin map's attractors)
    std::vector<PlotData::Code> codes;
    for (const auto& [value, name] : file_categories) {
      std::string label = name;  // flag_meanings are one word each; the legend reads better with spaces
      std::replace(label.begin(), label.end(), '_', ' ');
      codes.push_back({static_cast<double>(value), label, ""});
    }
    if (codes.size() > 16) return {};
    return codes;
  }
  if (!info || !info->integer) return {};
  std::set<double> present;
  for (double v : values)
    if (std::isfinite(v)) present.insert(v);
  std::vector<PlotData::Code> codes;
  std::vector<std::pair<int, std::string>> named;
  for (const Category& c : MetricCategories(metric)) named.emplace_back(c.code, c.name);
  if (metric == "period") named.emplace_back(0, "none found");  // a count whose 0 means "no period"
  for (const auto& [value, name] : named) {
    // Motion: the paper's three kinds always (their colours stay put when one is absent); undefined and the settled
    // labels' quasi-periodic (3) and unresolved (4) when present.
    const bool shown = metric == "period" || (metric == "motion" && value >= 0 && value <= 2) || present.count(value);
    if (!shown) continue;
    codes.push_back({static_cast<double>(value), name, CategoryColour(name)});  // the named codes' fixed colours
  }
  for (double v : present)
    if (std::none_of(codes.begin(), codes.end(), [&](const PlotData::Code& c) { return c.value == v; }))
      codes.push_back({v, FormatNumber(v), ""});
  if (codes.size() > 16) return {};
  std::sort(codes.begin(), codes.end(),
            [](const PlotData::Code& a, const PlotData::Code& b) { return a.value < b.value; });
  return codes;
}

StatusOr<PlotData> MapFigure(const MapArray& m, std::map<std::string, double> at, const std::string& title_prefix) {
  const auto dir_dim = std::find(m.dim_names.begin(), m.dim_names.end(), "direction");
  const bool both_directions =
      dir_dim != m.dim_names.end() && m.dims[dir_dim - m.dim_names.begin()] == 2 && !at.count("direction");
  if (both_directions) at["direction"] = 0;
  auto s = SliceMap(m, at, 2);
  if (!s.ok()) return s.status();
  PlotData d;
  d.metric = s->metric;
  d.unit = s->unit;
  for (const Axis& a : s->free)
    d.axis_names.push_back(a.name), d.axis_units.push_back(AxisUnit(a.name)), d.axis_values.push_back(a.values);
  d.values = s->values;
  std::map<std::string, double> fixed = s->fixed;
  if (both_directions && s->free.size() == 1) {
    at["direction"] = 1;
    auto down = SliceMap(m, at, 2);
    if (!down.ok()) return down.status();
    d.values.insert(d.values.end(), down->values.begin(), down->values.end());
    d.series = {"sweep up", "sweep down"};
    fixed.erase("direction");
  }
  d.codes = MetricCodes(d.metric, d.values, m.categories);
  d.title = title_prefix + ": " + s->metric;
  for (const auto& [name, value] : fixed) {
    const size_t k = std::find(m.dim_names.begin(), m.dim_names.end(), name) - m.dim_names.begin();
    if (k >= m.dims.size() || m.dims[k] < 2) continue;  // no choice: nothing to say
    if (name == "direction")
      d.title += value == 0 ? ", sweep up" : ", sweep down";
    else
      d.title += ", " + name + " = " + PlotNumber(value);
  }
  return d;
}

}  // namespace bistable
