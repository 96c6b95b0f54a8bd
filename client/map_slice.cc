#include "client/map_slice.h"

#include "client/cli_common.h"

#include <cmath>
#include <sstream>

#include "base/validate.h"

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
      return Status::InvalidArgument("at", "--at " + name + ": not a dimension of " + m.metric + " (dimensions: " + dims + ")");
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
        return Status::InvalidArgument("at", "--at " + name + " = " + FormatNumber(value) + " is not on the axis (nearest " +
                                                 near + "; " + std::to_string(vals.size()) + " values from " +
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
        return Status::InvalidArgument("metric", m.metric + " has a peak dimension; use `bistable map ID --metric hd_scatter`");
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
                                             std::to_string(free_dims.size()) + (names.empty() ? "" : " (" + names + ")") +
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

}  // namespace bistable
