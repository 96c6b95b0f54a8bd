#include "client/map_slice.h"

#include "client/cli_common.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
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

StatusOr<std::vector<std::string>> SnapAtToGrid(const MapArray& m, std::map<std::string, double>* at) {
  std::vector<std::string> notes;
  for (auto& [name, value] : *at) {
    size_t k = 0;
    while (k < m.axes.size() && m.dim_names[k] != name) ++k;
    if (k == m.axes.size() || m.axes[k].values.empty()) continue;  // not an axis: SliceMap says what it is
    const std::vector<double>& vals = m.axes[k].values;
    size_t best = 0;
    for (size_t i = 1; i < vals.size(); ++i)
      if (std::fabs(vals[i] - value) < std::fabs(vals[best] - value)) best = i;
    if (std::fabs(vals[best] - value) <= 1e-9 * std::max(1.0, std::fabs(value))) continue;  // on the grid
    std::vector<double> sorted = vals;
    std::sort(sorted.begin(), sorted.end());
    const size_t n = sorted.size();
    const double half_lo = n > 1 ? (sorted[1] - sorted[0]) / 2 : 0;
    const double half_hi = n > 1 ? (sorted[n - 1] - sorted[n - 2]) / 2 : 0;
    if (value < sorted.front() - half_lo || value > sorted.back() + half_hi)
      return Status::InvalidArgument(
          "at", "--at " + name + "=" + FormatNumber(value) + " is outside the axis: " + name +
                    (n > 1 ? " runs from " + FormatNumber(sorted.front()) + " to " + FormatNumber(sorted.back()) +
                                 " (" + std::to_string(n) +
                                 " values; a value within half a grid step of that range takes the nearest)"
                           : " holds the single value " + FormatNumber(sorted.front())));
    notes.push_back("--at " + name + "=" + FormatNumber(value) + " \u2192 nearest grid value " +
                    FormatNumber(vals[best]));
    value = vals[best];
  }
  return notes;
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

namespace {

struct MetricText {
  const char* metric;
  const char* title;   // enhanced text
  const char* symbol;  // enhanced text; the unit is appended from the map
};
// One table of what figures call each metric (docs/figures.md).
const MetricText kMetricTexts[] = {
    {"frf_db", "Frequency response of the main mass, FRF", "FRF  max|x_m'|/(\u03b1\u03a9)"},
    {"lle", "Largest Lyapunov exponent, LLE", "LLE"},
    {"lle_rosenstein", "Largest Lyapunov exponent, LLE (Rosenstein, from sampled y_m)", "LLE"},
    {"motion", "Type of steady-state motion", ""},
    {"period", "Stroboscopic period n", "period (forcing periods)"},
    {"hd_index", "Harmonic diffusion index, HD", "HD  (power fraction of y_m off the harmonics n\u03a9)"},
    {"edr_b", "Energy dissipation ratio of the main damper, EDR_B", "EDR_B = W_m/W_{in}"},
    {"edr_r", "Energy dissipation ratio of the resonator damper, EDR_R", "EDR_R = W_r/W_{in}"},
    {"edr_t", "Total energy dissipation ratio, EDR_T", "EDR_T = (W_m + W_r)/W_{in}"},
    {"energy_balance_residual", "Energy balance residual",
     "|\u222bP d\u03c4 - W_m - W_r - \u0394E| / W_{in}  (fraction)"},
    {"y_min", "Minimum displacement of the main mass", "min y_m"},
    {"y_max", "Maximum displacement of the main mass", "max y_m"},
    {"termination", "How the integration ended", ""},
    {"strobe_y", "Displacement of the main mass at a stroboscopic sample", "y_m(\u03c4_k)"},
    {"strobe_v", "Velocity of the main mass at a stroboscopic sample", "y_m'(\u03c4_k)"},
    {"settle_time", "Time at which the motion label settled", "\u03c4_{settle}"},
    {"lle_sigma", "Standard error of the largest Lyapunov exponent", "\u03c3_{LLE}"},
    {"label_confidence", "Confidence of the motion label", "confidence  (0 to 1)"},
    {"chaos_01", "0-1 test for chaos", "K  (near 1 chaotic, near 0 regular)"},
    {"attractor", "Basins of attraction", "attractor  (basin fraction)"},
    {"refine_level", "Refinement level of the adaptive map", "level  (0 = coarse grid)"},
    {"refine_fill", "How each point of the adaptive map was obtained", ""},
    {"frac_intrawell", "Fraction of the starts in intrawell motion", "fraction intrawell"},
    {"frac_interwell", "Fraction of the starts in interwell motion", "fraction interwell"},
    {"frac_chaotic", "Fraction of the starts in chaotic motion", "fraction chaotic"},
};

const MetricText* FindText(const std::string& metric) {
  for (const MetricText& t : kMetricTexts)
    if (metric == t.metric) return &t;
  return nullptr;
}

}  // namespace

std::string MetricTitle(const std::string& metric) {
  if (const MetricText* t = FindText(metric)) return t->title;
  if (metric.size() > 7 && metric.compare(metric.size() - 7, 7, "_stderr") == 0)
    return "Standard error of " + MetricTitle(metric.substr(0, metric.size() - 7));
  std::string words;
  if (const MetricInfo* info = FindMetric(metric)) words = info->long_name;
  if (words.empty()) return EnhancedText(metric);
  words[0] = static_cast<char>(std::toupper(static_cast<unsigned char>(words[0])));
  return EnhancedText(words);
}

std::string MetricValueLabel(const std::string& metric, const std::string& unit) {
  const MetricText* t = FindText(metric);
  if (t && *t->symbol == '\0') return "";
  const std::string symbol = t ? t->symbol : EnhancedText(metric);
  // Units that are words (fractions, counts) are said in the symbol's text, not in brackets.
  const bool worded = unit == "fraction" || unit == "forcing periods" || unit == "code";
  const std::string u = worded ? "" : UnitMarkup(unit);
  return u.empty() ? symbol : symbol + " [" + u + "]";
}

std::string AttractorName(const std::string& label) {
  std::vector<std::string> parts;
  std::stringstream in(label);
  for (std::string part; std::getline(in, part, '_');) parts.push_back(part);
  if (parts.size() >= 3 && parts[0].size() > 1 && parts[0][0] == 'A') {
    if (parts[1].size() > 1 && parts[1][0] == 'P' && std::isdigit(static_cast<unsigned char>(parts[1][1])))
      return "period-" + parts[1].substr(1) + ", " + parts[2];
    if (parts[1] == "chaotic" || parts[1] == "aperiodic") return parts[1] + ", " + parts[2];
    if (parts[1] == "other") {
      std::string rest = label.substr(label.find("other"));
      std::replace(rest.begin(), rest.end(), '_', ' ');
      return rest;
    }
  }
  std::string words = label;
  std::replace(words.begin(), words.end(), '_', ' ');
  return words;
}

std::vector<BasinShare> BasinShares(const MapArray& attractor) {
  std::map<int, long> cells;
  long total = 0;
  for (double v : attractor.values)
    if (std::isfinite(v)) ++cells[static_cast<int>(v)], ++total;
  std::vector<BasinShare> out;
  if (total == 0) return out;
  for (const auto& [id, label] : attractor.categories)
    out.push_back({id, AttractorName(label), static_cast<double>(cells[id]) / static_cast<double>(total)});
  if (cells.count(-1)) out.push_back({-1, "diverged", static_cast<double>(cells[-1]) / static_cast<double>(total)});
  std::stable_sort(out.begin(), out.end(),
                   [](const BasinShare& a, const BasinShare& b) { return a.fraction > b.fraction; });
  return out;
}

MapContext MapContextOf(const SweepSpec& spec) {
  MapContext c;
  c.name = spec.name;
  c.id = spec.Id();
  c.fixed = spec.FixedParameters();
  c.chaos_threshold = spec.base.metrics.chaos_threshold;
  if (spec.robustness.enabled()) c.items = spec.robustness.covariance ? "covariance samples" : "tolerance samples";
  return c;
}

MapContext MapContextOfFile(const std::string& map_path) {
  MapContext c;
  if (auto id = ReadMapAttribute(map_path, "sweep_id"); id.ok()) c.id = *id;
  if (auto name = ReadMapAttribute(map_path, "name"); name.ok()) c.name = *name;
  auto text = ReadMapAttribute(map_path, "spec");
  if (!text.ok() || text->empty()) return c;
  auto spec = ParseSweepSpec(*text, map_path);
  if (!spec.ok()) return c;
  MapContext full = MapContextOf(*spec);
  if (!c.id.empty()) full.id = c.id;
  if (!c.name.empty()) full.name = c.name;
  return full;
}

std::vector<PlotData::Code> MetricCodes(const std::string& metric, const std::vector<double>& values,
                                        const std::vector<std::pair<int, std::string>>& file_categories) {
  const MetricInfo* info = FindMetric(metric);
  std::set<double> present;
  for (double v : values)
    if (std::isfinite(v)) present.insert(v);
  if ((!info || !info->integer) && !file_categories.empty()) {  // codes named by the file (a basin map's attractors)
    std::vector<PlotData::Code> codes;
    if (present.count(-1) &&
        std::none_of(file_categories.begin(), file_categories.end(), [](const auto& c) { return c.first == -1; }))
      codes.push_back({-1, "diverged", "#bdbdbd"});
    for (const auto& [value, name] : file_categories) {
      // flag_meanings are one word each: a basin map's attractor labels in words, others with spaces.
      std::string label = metric == "attractor" ? AttractorName(name) : name;
      std::replace(label.begin(), label.end(), '_', ' ');
      const char* colour = CategoryColour(label);
      codes.push_back({static_cast<double>(value), label, colour ? colour : ""});
    }
    if (codes.size() > 16) return {};
    return codes;
  }
  if (metric == "refine_level") {  // levels are ordered: light to dark blue, spread over the levels present
    const char* blues[] = {"#c6dbef", "#9ecae1", "#6baed6", "#4292c6", "#2171b5", "#08519c", "#08306b"};
    std::vector<double> levels;
    for (double v : present)
      if (v >= 0 && v == std::floor(v)) levels.push_back(v);
    if (levels.size() > 16) return {};
    std::vector<PlotData::Code> codes;
    for (size_t k = 0; k < levels.size(); ++k)
      codes.push_back({levels[k], FormatNumber(levels[k]),
                       blues[levels.size() == 1 ? 0 : (k * 6 + (levels.size() - 1) / 2) / (levels.size() - 1)]});
    return codes;
  }
  if (!info || !info->integer) return {};
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
  std::sort(codes.begin(), codes.end(),
            [](const PlotData::Code& a, const PlotData::Code& b) { return a.value < b.value; });
  // Many values (periods up to 16 and more): the 11 smallest each, the rest as one class "≥ n".
  constexpr size_t kMaxCodes = 12;
  if (codes.size() > kMaxCodes) {
    codes.resize(kMaxCodes);
    PlotData::Code& tail = codes.back();
    tail.name = "\u2265 " + FormatNumber(tail.value);
    tail.at_least = true;
    tail.colour = "#444444";
  }
  return codes;
}

StatusOr<PlotData> MapFigure(const MapArray& m, std::map<std::string, double> at, const MapContext& ctx) {
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
  d.title = MetricTitle(s->metric);
  // A robustness map's fractions are over its samples (parameters and start drawn per point), not starts alone.
  if (const size_t at = d.title.find("the starts"); at != std::string::npos && ctx.items != "starts")
    d.title.replace(at, 10, "the " + ctx.items);
  d.title_markup = true;
  d.value_label = MetricValueLabel(s->metric, s->unit);
  // Subtitle: the sweep's fixed parameters, then the slice's fixed axes (the figure's own values).
  for (const FixedParameter& p : ctx.fixed) d.subtitle.push_back(ParameterItem(p.name, p.value, p.unit));
  for (const auto& [name, value] : fixed) {
    const size_t k = std::find(m.dim_names.begin(), m.dim_names.end(), name) - m.dim_names.begin();
    if (k >= m.dims.size()) continue;
    if (k < m.axes.size())
      d.subtitle.push_back(ParameterItem(name, value, AxisUnit(name)));
    else if (name == "direction" && m.dims[k] >= 2)
      d.subtitle.push_back(value == 0 ? "sweep up" : "sweep down");
    else if (m.dims[k] >= 2)
      d.subtitle.push_back(EnhancedText(name) + " " + FormatNumber(value + 1) + " of " + std::to_string(m.dims[k]));
  }
  d.footer = ctx.name.empty() ? (ctx.id.empty() ? "" : "sweep " + ctx.id)
                              : ctx.name + (ctx.id.empty() ? "" : "  \xc2\xb7  sweep " + ctx.id);
  // Marked levels: where the FRF changes sign (amplification vs attenuation), the chaos threshold.
  if (d.metric == "frf_db") d.contours.push_back({0.0, "FRF = 0 dB", "#000000", false});
  if ((d.metric == "lle" || d.metric == "lle_rosenstein") && std::isfinite(ctx.chaos_threshold))
    d.contours.push_back({ctx.chaos_threshold,
                          "chaos threshold LLE = " + PlotNumber(ctx.chaos_threshold) + " (chaotic above)", "#000000",
                          true});
  if (d.metric.rfind("edr_", 0) == 0)
    d.clip_reason =
        "an EDR passes 100 % where the stored energy fell over the window (EDR_T \u2264 100 (1 - \u0394E/W_{in}))";
  // A basin map: each attractor's share of the starts in the slice, in its legend entry.
  if (d.metric == "attractor" && !d.codes.empty()) {
    std::map<double, long> cells;
    long total = 0;
    for (double v : d.values)
      if (std::isfinite(v)) ++cells[v], ++total;
    std::map<std::string, int> uses;
    for (const auto& c : d.codes) ++uses[c.name];
    for (size_t i = 0; i < d.codes.size(); ++i) {
      PlotData::Code& c = d.codes[i];
      if (uses[c.name] > 1) {  // two attractors of one kind: tell them apart by their Poincaré point
        for (const auto& [value, label] : m.categories)
          if (value == c.value) {
            const size_t y = label.find("_y");
            if (y != std::string::npos) c.name += ", y_m = " + label.substr(y + 2, label.find("_v", y) - y - 2);
          }
      }
      char pct[32];
      std::snprintf(pct, sizeof pct, " (%.1f %%)", total ? 100.0 * cells[c.value] / total : 0.0);
      c.name += pct;
    }
  }
  return d;
}

}  // namespace bistable
