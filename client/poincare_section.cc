#include "client/poincare_section.h"

#include <algorithm>
#include <cmath>

#include "base/limits.h"
#include "base/validate.h"

namespace bistable {

Status SetPoincareWindow(long n, const std::string& field, PointSpec* spec) {
  if (n < 1 || n > limits::kMaxPoincarePeriods)
    return Violates(field, static_cast<double>(n), "in [1, " + std::to_string(limits::kMaxPoincarePeriods) + "]");
  IntegrationSettings& in = spec->integration;
  BISTABLE_RETURN_IF_ERROR(CheckPositive("omega", spec->omega));
  BISTABLE_RETURN_IF_ERROR(CheckPositive("dt", in.dt));
  BISTABLE_RETURN_IF_ERROR(CheckNonNegative("t_keep", in.t_keep));
  const double period = 2 * M_PI / spec->omega;
  if (!(in.t_keep / in.dt <= limits::kMaxStepsPerPoint))  // before StepsFor: lround of a huge ratio is unspecified
    return Violates("t_keep", in.t_keep,
                    "<= " + FormatNumber(limits::kMaxStepsPerPoint * in.dt) + " (the limit of " +
                        FormatNumber(limits::kMaxStepsPerPoint) + " steps per point at dt = " + FormatNumber(in.dt) +
                        ")");
  const long n_keep = StepsFor(in.t_keep, in.dt);
  const double window_steps = std::ceil(static_cast<double>(n + 1) * period / in.dt);
  if (static_cast<double>(n_keep) + window_steps > limits::kMaxStepsPerPoint) {
    const double most = std::floor((limits::kMaxStepsPerPoint - static_cast<double>(n_keep)) * in.dt / period) - 1;
    return Violates(field, static_cast<double>(n),
                    "<= " + FormatNumber(std::max(most, 0.0)) + " (the limit of " +
                        FormatNumber(limits::kMaxStepsPerPoint) + " steps per point at dt = " + FormatNumber(in.dt) +
                        ", Omega = " + FormatNumber(spec->omega) + ", t_keep = " + FormatNumber(in.t_keep) + ")");
  }
  in.t_end = static_cast<double>(n_keep + static_cast<long>(window_steps)) * in.dt;
  return Status::Ok();
}

std::vector<std::pair<std::string, std::string>> SectionColumns(const PointSpec& spec) {
  std::vector<std::pair<std::string, std::string>> c = {
      {"k", ""}, {"tau", "1/omega_n"}, {"y_m", "delta_s"}, {"dy_m", "delta_s/tau"}};
  if (HasResonator(spec.model)) c.push_back({"y_r", "delta_s"}), c.push_back({"dy_r", "delta_s/tau"});
  return c;
}

size_t SectionCount(const PointResult& r, long limit) {
  return limit > 0 ? std::min(r.section_y.size(), static_cast<size_t>(limit)) : r.section_y.size();
}

std::vector<double> SectionRow(const PointSpec& spec, const PointResult& r, size_t i) {
  const long k = r.section_k0 + static_cast<long>(i);
  const double tau = static_cast<double>(k) * (2.0 * M_PI / spec.omega) + spec.metrics.poincare_phase / spec.omega;
  std::vector<double> row = {static_cast<double>(k), tau, r.section_y[i], r.section_v[i]};
  if (HasResonator(spec.model)) row.push_back(r.section_yr[i]), row.push_back(r.section_vr[i]);
  return row;
}

nlohmann::json SectionJson(const PointSpec& spec, const PointResult& r, long limit, const std::string& file) {
  const size_t n = SectionCount(r, limit);
  nlohmann::json columns = nlohmann::json::array(), units = nlohmann::json::array();
  for (const auto& [name, unit] : SectionColumns(spec)) columns.push_back(name), units.push_back(unit);
  nlohmann::json j = {{"phase", spec.metrics.poincare_phase},
                      {"count", n},
                      {"k0", r.section_k0},
                      {"columns", columns},
                      {"units", units}};
  if (file == "-") {
    nlohmann::json pts = nlohmann::json::array();
    for (size_t i = 0; i < n; ++i) pts.push_back(SectionRow(spec, r, i));
    j["points"] = std::move(pts);
  } else if (!file.empty()) {
    j["file"] = file;
  }
  return j;
}

}  // namespace bistable
