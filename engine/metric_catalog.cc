#include "engine/metric_catalog.h"

#define XXH_INLINE_ALL
#include <xxhash.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <limits>
#include <string_view>

#include "base/limits.h"

namespace bistable {
namespace {
constexpr double kMaxPeakOrTurningValue = 1e150;  // |peak frequency|, |amplitude|, |turning point|

// A (non-NaN) value within its metric's domain: in [lo, hi] and, for codes and counts, whole.
bool InDomain(const MetricInfo& m, double x) { return x >= m.lo && x <= m.hi && (!m.integer || x == std::floor(x)); }
}  // namespace

const std::vector<MetricInfo>& MetricCatalog() {
  static const std::vector<MetricInfo> kCatalog = {
      {"frf_db", "dB", "20 log10(max|x_m'| / (alpha Omega)) over the window, absolute velocity of the main mass", false,
       -1000, 1000, true, "frequency response of the main mass (peak absolute velocity over alpha Omega), in decibels"},
      {"lle", "1/tau", "largest Lyapunov exponent, Benettin tangent-linear method over the window", false, -1e6, 1e6,
       true, "largest Lyapunov exponent (Benettin)"},
      {"lle_rosenstein", "1/tau", "largest Lyapunov exponent, Rosenstein (1993) on sampled y_m; NaN unless requested",
       false, -1e6, 1e6, true, "largest Lyapunov exponent (Rosenstein, from sampled y_m)"},
      {"motion", "code",
       "0 intrawell, 1 interwell, 2 chaotic (lle > chaos_threshold), 3 quasi-periodic/marginal, 4 unresolved (settled "
       "labels), -1 undefined (diverged)",
       true, -1, 4, false, "type of steady-state motion"},
      {"period", "forcing periods", "stroboscopic period n of (y_m, y_m'); 0 when none in the window", true, 0,
       limits::kMaxPeriod, false, "stroboscopic period in forcing periods (0: none found)"},
      {"hd_index", "fraction", "fraction of y_m spectral power farther than 3 bins from every multiple of Omega", false,
       0, 1, true, "harmonic diffusion index (fraction of spectral power off the forcing harmonics)"},
      {"edr_b", "%", "100 W_m / W_in, W_in = integral of max(P, 0) over the window (gross injected energy)", false, 0,
       1e12, true, "energy dissipation ratio of the main damper"},
      {"edr_r", "%", "100 W_r / W_in", false, 0, 1e12, true, "energy dissipation ratio of the resonator damper"},
      {"edr_t", "%", "100 (W_m + W_r) / W_in", false, 0, 1e12, true, "total energy dissipation ratio"},
      {"energy_balance_residual", "fraction", "|integral P - W_m - W_r - Delta E| / W_in", false, 0, 1e12, true,
       "relative residual of the energy balance over the window"},
      {"y_min", "delta_s", "minimum of y_m over the window", false, -1e150, 1e150, true,
       "minimum displacement of the main mass relative to the base"},
      {"y_max", "delta_s", "maximum of y_m over the window", false, -1e150, 1e150, true,
       "maximum displacement of the main mass relative to the base"},
      {"termination", "code", "0 ok, 1 diverged, 2 step size underflow, 3 max steps", true, 0, 3, false,
       "how the integration ended"},
      {"strobe_y", "delta_s",
       "y_m at a stroboscopic sample (Omega tau a multiple of 2 pi) of the window: of the last `period` samples the "
       "one with the smallest y_m; the last sample when no period was found",
       false, -1e150, 1e150, true, "displacement of the main mass at a point of the attractor's Poincare section"},
      {"strobe_v", "delta_s/tau", "y_m' at the same stroboscopic sample as strobe_y", false, -1e150, 1e150, true,
       "velocity of the main mass at a point of the attractor's Poincare section"},
      {"settle_time", "tau", "settled labels: tau at which the label settled (the run's end); NaN in the paper's mode",
       false, 0, 1e12, true, "time at which the label settled"},
      {"lle_sigma", "1/tau", "settled labels: block-average standard error of lle; NaN in the paper's mode", false, 0,
       1e12, true, "standard error of the largest Lyapunov exponent"},
      {"label_confidence", "fraction",
       "settled labels: Phi(|lle - chaos_threshold| / lle_sigma), 0 when unresolved; NaN in the paper's mode", false, 0,
       1, true, "confidence of the motion label"},
      {"chaos_01", "",
       "settled labels: K of the 0-1 test for chaos (Gottwald-Melbourne, median over 16 c) on the strobes y_m of [T/2, "
       "T] (at least the latest 64), for chaotic, quasi-periodic and unresolved labels; near 1 chaotic, near 0 "
       "regular; NaN for a periodic label, with fewer than 64 strobes, or in the paper's mode",
       false, -1, 1, true, "0-1 test for chaos, K"},
  };
  return kCatalog;
}

uint64_t CatalogHash() {
  static const uint64_t kHash = [] {
    std::string text = std::string("numerics=") + kNumericsVersion + ";peaks=" + std::to_string(kHdPeaksStored) +
                       ";turning=" + std::to_string(kTurningPointsStored) +
                       ";poincare<=" + std::to_string(limits::kMaxPoincarePointsStored) + "x2;metrics=";
    for (const MetricInfo& m : MetricCatalog()) text += std::string(m.name) + (m.integer ? ":i," : ":f,");
    return XXH3_64bits(text.data(), text.size());
  }();
  return kHash;
}

size_t MetricIndex(const char* name) {
  const auto& catalog = MetricCatalog();
  for (size_t i = 0; i < catalog.size(); ++i)
    if (std::string_view(catalog[i].name) == name) return i;
  std::fprintf(stderr, "MetricIndex: '%s' is not a metric of the catalog\n", name);
  std::abort();
}

const MetricInfo* FindMetric(const std::string& name) {
  for (const MetricInfo& m : MetricCatalog())
    if (name == m.name) return &m;
  return nullptr;
}

std::vector<std::string> MetricNames() {
  std::vector<std::string> names;
  for (const MetricInfo& m : MetricCatalog()) names.push_back(m.name);
  names.push_back("hd_peaks");
  names.push_back("turning_points");
  names.push_back("poincare");
  return names;
}

int MotionCode(Motion m) {
  switch (m) {
    case Motion::kIntrawell:
      return 0;
    case Motion::kInterwell:
      return 1;
    case Motion::kChaotic:
      return 2;
    case Motion::kUndefined:
      return kMotionUndefined;
    case Motion::kQuasiPeriodic:
      return 3;
    case Motion::kUnresolved:
      return 4;
  }
  return kMotionUndefined;
}

const std::vector<Category>& MetricCategories(const std::string& metric) {
  static const std::vector<Category> kMotion = [] {
    std::vector<Category> c;
    for (Motion m : {Motion::kUndefined, Motion::kIntrawell, Motion::kInterwell, Motion::kChaotic,
                     Motion::kQuasiPeriodic, Motion::kUnresolved})
      c.push_back({MotionCode(m), MotionName(m)});
    return c;
  }();
  static const std::vector<Category> kTermination = [] {
    std::vector<Category> c;
    for (Termination t :
         {Termination::kOk, Termination::kDiverged, Termination::kStepSizeUnderflow, Termination::kMaxSteps})
      c.push_back({static_cast<int>(t), TerminationName(t)});
    return c;
  }();
  static const std::vector<Category> kNone;
  return metric == "motion" ? kMotion : metric == "termination" ? kTermination : kNone;
}

const char* MotionCodesText() {
  return "0 intrawell, 1 interwell, 2 chaotic, 3 quasi-periodic, 4 unresolved, -1 undefined (diverged)";
}

bool MotionCodeOfName(const std::string& name, int* code) {
  for (const Category& c : MetricCategories("motion"))
    if (name == c.name) return *code = c.code, true;
  return false;
}

bool IsCategoryMetric(const std::string& metric) { return !MetricCategories(metric).empty(); }

const char* CategoryColour(const std::string& name) {
  if (name == "undefined" || name == "none found") return "#bdbdbd";
  if (name == "intrawell") return "#2c7bb6";
  if (name == "interwell") return "#fdae61";
  if (name == "chaotic") return "#d7191c";
  if (name == "quasi-periodic") return "#7b3294";  // settled labels: a torus or marginal orbit, purple
  if (name == "unresolved") return "#636363";  // settled labels: no label within the cap, a darker grey than undefined
  if (name == "ok") return "#1a9850";
  return "";
}

bool DivergesAboutZero(const std::string& metric) { return metric == "frf_db" || metric == "lle"; }

const char* CategoryName(const std::string& metric, double code) {
  for (const Category& c : MetricCategories(metric))
    if (code == c.code) return c.name;
  return nullptr;
}

size_t PointRecord::Size(bool turning_points, int poincare_points) {
  return MetricCatalog().size() + 2 * kHdPeaksStored + (turning_points ? kTurningPointsStored : 0) +
         2 * static_cast<size_t>(std::max(poincare_points, 0));
}

double PointRecord::TurningPoint(int k) const { return v[MetricCatalog().size() + 2 * kHdPeaksStored + k]; }

double PointRecord::Poincare(int k, int component, bool turning_points, int poincare_points) const {
  return v[Size(turning_points) + static_cast<size_t>(component) * poincare_points + k];
}

namespace {
// The last n values of xs in order, NaN-filled to n.
void AppendLast(const std::vector<double>& xs, int n, std::vector<double>* out) {
  const size_t have = xs.size(), first = have > static_cast<size_t>(n) ? have - n : 0;
  for (int k = 0; k < n; ++k)
    out->push_back(first + k < have ? xs[first + k] : std::numeric_limits<double>::quiet_NaN());
}
}  // namespace

PointRecord PointRecord::From(const PointResult& r, bool turning_points, int poincare_points) {
  PointRecord p;
  p.v = {r.frf_db,
         r.lle,
         r.lle_rosenstein,
         static_cast<double>(MotionCode(r.motion)),
         static_cast<double>(r.period),
         r.hd_index,
         r.edr_b,
         r.edr_r,
         r.edr_t,
         r.energy_balance_residual,
         r.y_min,
         r.y_max,
         static_cast<double>(static_cast<int>(r.termination)),
         r.strobe_y,
         r.strobe_v,
         r.settle_time,
         r.lle_sigma,
         r.label_confidence,
         r.chaos_01};
  const double nan = std::numeric_limits<double>::quiet_NaN();
  // A float outside its metric's domain is not a measurement (an overflow in a degenerate run): NaN.
  const auto& catalog = MetricCatalog();
  for (size_t i = 0; i < catalog.size(); ++i)
    if (!catalog[i].integer && !InDomain(catalog[i], p.v[i])) p.v[i] = nan;
  for (int k = 0; k < kHdPeaksStored; ++k)
    p.v.push_back(k < static_cast<int>(r.hd_peaks.size()) ? r.hd_peaks[k].freq : nan);
  for (int k = 0; k < kHdPeaksStored; ++k)
    p.v.push_back(k < static_cast<int>(r.hd_peaks.size()) ? r.hd_peaks[k].amp : nan);
  if (turning_points) AppendLast(r.turning_points, kTurningPointsStored, &p.v);
  if (poincare_points > 0) {  // y_m and y_m' of the same strobes (a diverged run has none: NaN)
    AppendLast(r.section_y, poincare_points, &p.v);
    AppendLast(r.section_v, poincare_points, &p.v);
  }
  for (size_t i = catalog.size(); i < p.v.size(); ++i)
    if (!(std::fabs(p.v[i]) <= kMaxPeakOrTurningValue)) p.v[i] = nan;
  return p;
}

namespace {

// Every metric's domain in v[0, width); values after the peaks belong to the optional tails (turning
// points, section values), all bounded alike and named by tail_name(i) in a message.
template <class TailName>
Status CheckDomains(const double* v, size_t width, TailName tail_name) {
  const auto& catalog = MetricCatalog();
  auto bad = [&](size_t i, const std::string& what, const std::string& bound) {
    char b[40];
    std::snprintf(b, sizeof b, "%.17g", v[i]);
    return Status::InvalidArgument("records", what + " = " + b + " violates " + bound);
  };
  for (size_t i = 0; i < catalog.size(); ++i) {
    const MetricInfo& m = catalog[i];
    const double x = v[i];
    if (std::isnan(x)) {
      if (!m.nan_ok) return bad(i, m.name, std::string(m.name) + " is a number (codes are never NaN)");
      continue;
    }
    if (!InDomain(m, x)) {
      char b[80];
      std::snprintf(b, sizeof b, "%s in [%.6g, %.6g]", m.integer ? "a whole number" : "a value", m.lo, m.hi);
      return bad(i, m.name, b);
    }
  }
  for (int k = 0; k < kHdPeaksStored; ++k) {
    const double f = v[catalog.size() + k], a = v[catalog.size() + kHdPeaksStored + k];
    if (!std::isnan(f) && !(f >= 0 && f <= kMaxPeakOrTurningValue))
      return bad(catalog.size() + k, "hd_peak_freq", "NaN or in [0, 1e150]");
    if (!std::isnan(a) && !(a >= 0 && a <= kMaxPeakOrTurningValue))
      return bad(catalog.size() + kHdPeaksStored + k, "hd_peak_amp", "NaN or in [0, 1e150]");
  }
  for (size_t i = catalog.size() + 2 * kHdPeaksStored; i < width; ++i)
    if (!std::isnan(v[i]) && !(std::fabs(v[i]) <= kMaxPeakOrTurningValue))
      return bad(i, tail_name(i), "NaN or |y| <= 1e150");
  return Status::Ok();
}

}  // namespace

Status CheckRecord(const double* v, size_t width, bool turning_points, int poincare_points) {
  const size_t expected = PointRecord::Size(turning_points, poincare_points);
  if (width != expected)
    return Status::InvalidArgument("record_width", "record_width = " + std::to_string(width) +
                                                       " violates record_width = " + std::to_string(expected) +
                                                       " (the sweep's layout)");
  const size_t section_from = PointRecord::Size(turning_points);
  return CheckDomains(v, width, [&](size_t i) {
    if (i < section_from) return "turning_points";
    return i < section_from + static_cast<size_t>(poincare_points) ? "poincare_y" : "poincare_v";
  });
}

Status CheckAnyRecordWidth(size_t width) {
  const size_t lo = PointRecord::Size(false), hi = PointRecord::Size(true, limits::kMaxPoincarePointsStored);
  if (width < lo || width > hi)
    return Status::InvalidArgument("record_width", "record_width = " + std::to_string(width) +
                                                       " violates record_width in [" + std::to_string(lo) + ", " +
                                                       std::to_string(hi) + "]");
  return Status::Ok();
}

Status CheckAnyRecord(const double* v, size_t width) {
  BISTABLE_RETURN_IF_ERROR(CheckAnyRecordWidth(width));
  return CheckDomains(v, width, [](size_t) { return "turning_points or poincare"; });
}

double PointRecord::PeakFreq(int k) const { return v[MetricCatalog().size() + k]; }
double PointRecord::PeakAmp(int k) const { return v[MetricCatalog().size() + kHdPeaksStored + k]; }

}  // namespace bistable
