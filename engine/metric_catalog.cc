#include "engine/metric_catalog.h"

#include <cmath>
#include <limits>

namespace bistable {

const std::vector<MetricInfo>& MetricCatalog() {
  static const std::vector<MetricInfo> kCatalog = {
      {"frf_db", "dB", "20 log10(max|x_m'| / (alpha Omega)) over the window, absolute velocity of the main mass", false},
      {"lle", "1/tau", "largest Lyapunov exponent, Benettin tangent-linear method over the window", false},
      {"lle_rosenstein", "1/tau", "largest Lyapunov exponent, Rosenstein (1993) on sampled y_m; NaN unless requested", false},
      {"motion", "code", "0 intrawell, 1 interwell, 2 chaotic (lle > chaos_threshold), -1 undefined (diverged)", true},
      {"period", "forcing periods", "stroboscopic period n of (y_m, y_m'); 0 when none in the window", true},
      {"hd_index", "fraction", "fraction of y_m spectral power farther than 3 bins from every multiple of Omega", false},
      {"edr_b", "%", "100 W_m / W_in, W_in = integral of max(P, 0) over the window (gross injected energy)", false},
      {"edr_r", "%", "100 W_r / W_in", false},
      {"edr_t", "%", "100 (W_m + W_r) / W_in", false},
      {"energy_balance_residual", "fraction", "|integral P - W_m - W_r - Delta E| / W_in", false},
      {"y_min", "delta_s", "minimum of y_m over the window", false},
      {"y_max", "delta_s", "maximum of y_m over the window", false},
      {"termination", "code", "0 ok, 1 diverged, 2 step size underflow, 3 max steps", true},
  };
  return kCatalog;
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
  return names;
}

int MotionCode(Motion m) {
  switch (m) {
    case Motion::kIntrawell: return 0;
    case Motion::kInterwell: return 1;
    case Motion::kChaotic: return 2;
    case Motion::kUndefined: return kMotionUndefined;
  }
  return kMotionUndefined;
}

const char* MotionCodesText() { return "0 intrawell, 1 interwell, 2 chaotic, -1 undefined (diverged)"; }

size_t PointRecord::Size(bool turning_points) {
  return MetricCatalog().size() + 2 * kHdPeaksStored + (turning_points ? kTurningPointsStored : 0);
}

double PointRecord::TurningPoint(int k) const { return v[MetricCatalog().size() + 2 * kHdPeaksStored + k]; }

PointRecord PointRecord::From(const PointResult& r, bool turning_points) {
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
         static_cast<double>(static_cast<int>(r.termination))};
  const double nan = std::numeric_limits<double>::quiet_NaN();
  for (int k = 0; k < kHdPeaksStored; ++k) p.v.push_back(k < static_cast<int>(r.hd_peaks.size()) ? r.hd_peaks[k].freq : nan);
  for (int k = 0; k < kHdPeaksStored; ++k) p.v.push_back(k < static_cast<int>(r.hd_peaks.size()) ? r.hd_peaks[k].amp : nan);
  if (turning_points) {
    const size_t n = r.turning_points.size(), first = n > kTurningPointsStored ? n - kTurningPointsStored : 0;
    for (int k = 0; k < kTurningPointsStored; ++k) p.v.push_back(first + k < n ? r.turning_points[first + k] : nan);
  }
  return p;
}

double PointRecord::PeakFreq(int k) const { return v[MetricCatalog().size() + k]; }
double PointRecord::PeakAmp(int k) const { return v[MetricCatalog().size() + kHdPeaksStored + k]; }

}  // namespace bistable
