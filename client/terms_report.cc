#include "client/terms_report.h"

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <sstream>
#include <vector>

#include <toml++/toml.h>
#include <nlohmann/json.hpp>

#include "base/file.h"
#include "base/json_text.h"
#include "base/limits.h"
#include "base/names.h"
#include "base/validate.h"
#include "dynamics/terms.h"
#include "engine/spec_toml.h"

namespace bistable {
namespace {

// An identify result is a few hundred kB at most (records, errors, a covariance of ≤ 64² numbers).
constexpr size_t kMaxReportBytes = 16u << 20;

Status Bad(const std::string& key, const std::string& why) {
  return Status::InvalidArgument("terms.report." + key, "terms.report: " + key + " " + why);
}

StatusOr<double> JsonNumberAt(const nlohmann::json& j, const std::string& key, const std::string& field) {
  if (!j.is_object() || !j.contains(key) || !j[key].is_number()) return Bad(field, "is missing or not a number");
  const double v = j[key].get<double>();
  if (!std::isfinite(v)) return Bad(field, "is not finite");
  return v;
}

// The submatrix of a fit's covariance ({"names", "matrix"}) over `names`, flattened row by row, or an error naming
// terms.report.covariance. A covariance, or refused: variances > 0, symmetric but for rounding, correlations within
// [-1, 1] — a fit whose Gauss–Newton inverse broke down (an ill-conditioned Jacobian) can report |ρ| > 1, and its σ
// cannot be drawn from.
StatusOr<toml::array> CovarianceOf(const nlohmann::json& c, const std::vector<std::string>& names) {
  if (!c.contains("names") || !c["names"].is_array() || !c.contains("matrix") || !c["matrix"].is_array())
    return Bad("covariance", "must hold names and matrix");
  const size_t n = c["names"].size();
  std::vector<size_t> at;
  for (const std::string& want : names) {
    size_t k = 0;
    while (k < n && !(c["names"][k].is_string() && c["names"][k].get<std::string>() == want)) ++k;
    if (k == n) return Bad("covariance.names", "lacks " + want);
    at.push_back(k);
  }
  if (c["matrix"].size() != n) return Bad("covariance.matrix", "is not " + std::to_string(n) + " rows");
  for (size_t a = 0; a < n; ++a) {
    const nlohmann::json& row = c["matrix"][a];
    if (!row.is_array() || row.size() != n) return Bad("covariance.matrix", "is not square");
    for (size_t b = 0; b < n; ++b)
      if (!row[b].is_number()) return Bad("covariance.matrix", "holds a value that is not a number");
  }
  auto at_ab = [&](size_t a, size_t b) { return c["matrix"][a][b].get<double>(); };
  for (size_t a : at) {
    if (!(at_ab(a, a) > 0) || !std::isfinite(at_ab(a, a)))
      return Bad("covariance", "has variance " + FormatNumber(at_ab(a, a)) + " for " +
                                   c["names"][a].get<std::string>() + "; a variance is > 0 and finite");
    for (size_t b : at) {
      const double scale = std::sqrt(at_ab(a, a) * at_ab(b, b));
      if (!std::isfinite(at_ab(a, b)) || std::fabs(at_ab(a, b) - at_ab(b, a)) > 1e-9 * scale ||
          std::fabs(at_ab(a, b)) > (1 + 1e-9) * scale)
        return Bad("covariance", "is not a covariance between " + c["names"][a].get<std::string>() + " and " +
                                     c["names"][b].get<std::string>() + " (correlation " +
                                     FormatNumber(at_ab(a, b) / scale) + " vs " + FormatNumber(at_ab(b, a) / scale) +
                                     "): the fit's uncertainty broke down; map without [robustness] covariance, or "
                                     "refit with records that separate the parameters");
    }
  }
  // Symmetric to the bit (a Gauss–Newton inverse is symmetric only to rounding): the mean of both triangles.
  toml::array flat;
  for (size_t a : at)
    for (size_t b : at) flat.push_back(0.5 * (at_ab(a, b) + at_ab(b, a)));
  return flat;
}

}  // namespace

StatusOr<std::string> InlineTermsReport(const std::string& spec_text, const std::string& spec_path) {
  auto parsed = ParseSpecToml(spec_text, spec_path);
  if (!parsed.ok()) return parsed.status();
  toml::table root = std::move(parsed).value();
  toml::table* terms = root["terms"].as_table();
  if (!terms || !terms->get("report")) return spec_text;
  auto name = String(*terms->get("report"), "terms.report");
  if (!name.ok()) return name.status();
  for (const char* k : {"list", "theta", "m_main", "m_res", "v_sp", "v_t", "drive", "covariance"})
    if (terms->get(k))
      return Status::InvalidArgument("terms." + std::string(k), std::string("terms.") + k +
                                                                    " comes from the report; give either "
                                                                    "terms.report or the model inline, not both");
  std::filesystem::path path(*name);
  if (path.is_relative()) path = std::filesystem::path(spec_path).parent_path() / path;
  auto text = ReadTextFile(path.string(), "terms.report", kMaxReportBytes);
  if (!text.ok()) return text.status();
  if (JsonNestingDepth(*text) > limits::kMaxModelJsonDepth)
    return Status::InvalidArgument("terms.report", "terms.report: " + Printable(path.string()) + " nests deeper than " +
                                                       std::to_string(limits::kMaxModelJsonDepth) + " levels");
  nlohmann::json j = nlohmann::json::parse(*text, nullptr, /*allow_exceptions=*/false);
  if (j.is_discarded() || !j.is_object())
    return Status::InvalidArgument("terms.report", "terms.report: " + path.string() +
                                                       " is not JSON of an identify result (bistable identify "
                                                       "--report DIR writes DIR/report.json)");
  if (!j.contains("final_terms") || !j["final_terms"].is_array())
    return Bad("final_terms",
               "is missing (a result of bistable identify before 0.1.0 does not list its final "
               "model's terms; fit again)");
  const nlohmann::json& settings = j.contains("settings") ? j["settings"] : nlohmann::json::object();
  const nlohmann::json& params = j.contains("params") ? j["params"] : nlohmann::json::object();
  // The input: the swept model is driven through its base, or by a force on its main body.
  const std::string input = settings.contains("input_kind") && settings["input_kind"].is_string()
                                ? settings["input_kind"].get<std::string>()
                                : "";
  if (input != "base_displacement" && input != "base_acceleration" && input != "force")
    return Bad("settings.input_kind", "is '" + Printable(input) +
                                          "'; a sweep drives the model through its base (base_displacement, "
                                          "base_acceleration) or by a force (force)");
  // The dynamics: the force terms; the sensors' terms (out.*) and the per-record offsets stay behind.
  toml::array list;
  std::vector<std::string> names;
  for (size_t i = 0; i < j["final_terms"].size(); ++i) {
    const nlohmann::json& id = j["final_terms"][i];
    if (!id.is_string()) return Bad("final_terms[" + std::to_string(i) + "]", "is not a term id");
    auto t = FindTerm(id.get<std::string>());
    if (!t.ok()) return Bad("final_terms[" + std::to_string(i) + "]", t.status().message());
    if ((*t)->kind == TermKind::kPiezo)
      return Bad("final_terms",
                 "holds main.piezo: the swept term model has no voltage state yet (fit without "
                 "the piezo, or sweep the mechanical model by listing its terms inline)");
    if (!(*t)->IsForce()) continue;
    list.push_back((*t)->id);
    for (const TermParam& p : (*t)->params) names.push_back((*t)->id + "." + p.name);
  }
  if (list.empty()) return Bad("final_terms", "holds no force term");
  toml::array theta;
  for (const std::string& n : names) {
    auto v = JsonNumberAt(params, n, "params." + n);
    if (!v.ok()) return v.status();
    theta.push_back(*v);
  }
  auto m_main = JsonNumberAt(settings, "m_main", "settings.m_main");
  if (!m_main.ok()) return m_main.status();
  double mass = *m_main;
  if (!(mass > 0)) {  // a fitted mass (force inputs): its value; its σ is not swept (the mass is not a term)
    auto fitted = JsonNumberAt(params, "m_main", "params.m_main");
    if (!fitted.ok()) return fitted.status();
    mass = *fitted;
  }
  StatusOr<double> m_res = 0.0;  // absent without a resonator (a truth.json of identify --make-synthetic)
  if (settings.contains("m_res")) m_res = JsonNumberAt(settings, "m_res", "settings.m_res");
  auto v_sp = JsonNumberAt(settings, "v_sp", "settings.v_sp");
  auto v_t = JsonNumberAt(settings, "v_t", "settings.v_t");
  for (const auto* s : {&m_res, &v_sp, &v_t})
    if (!s->ok()) return s->status();
  toml::table out;
  out.insert("list", list);
  out.insert("theta", theta);
  out.insert("m_main", mass);
  if (*m_res > 0) out.insert("m_res", *m_res);
  out.insert("v_sp", *v_sp);
  out.insert("v_t", *v_t);
  out.insert("drive", input == "base_acceleration" ? "acceleration" : input == "force" ? "force" : "displacement");
  out.insert("origin", Printable(path.string(), limits::kMaxNameBytes / 2));
  // The covariance of these parameters: the rows and columns of the fit's matrix that name them. A broken one is
  // refused when the spec draws from it ([robustness] covariance = true), else left out with a warning.
  if (j.contains("covariance") && j["covariance"].is_object()) {
    auto cov = CovarianceOf(j["covariance"], names);
    const toml::node* want = root["robustness"]["covariance"].node();
    if (cov.ok())
      out.insert("covariance", *cov);
    else if (want && want->value<bool>().value_or(false))
      return cov.status();
    else
      std::fprintf(stderr, "bistable: %s; left out of the map's spec\n", cov.status().message().c_str());
  }
  root.insert_or_assign("terms", out);
  std::ostringstream os;
  os << "# [terms] inlined by bistable from " << Printable(path.string()) << " (terms.origin)\n" << root << "\n";
  return os.str();
}

StatusOr<SweepSpec> LoadClientSweepSpec(const std::string& path) {
  auto text = ReadTextFile(path, "spec", limits::kMaxSpecBytes);
  if (!text.ok()) return text.status();
  auto inlined = InlineTermsReport(*text, path);
  if (!inlined.ok()) return inlined.status();
  return ParseSweepSpec(*inlined, path);
}

}  // namespace bistable
