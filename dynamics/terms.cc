#include "dynamics/terms.h"

#include <cmath>
#include <set>

#include "base/names.h"

namespace bistable {
namespace {

TermDef Def(std::string id, Body body, TermKind kind, std::string formula, std::string meaning,
            std::vector<TermParam> params, std::string output = "") {
  TermDef t;
  t.id = std::move(id), t.body = body, t.kind = kind, t.formula = std::move(formula), t.meaning = std::move(meaning);
  t.params = std::move(params), t.output = std::move(output);
  return t;
}

std::vector<TermDef> BuildLibrary() {
  std::vector<TermDef> lib;
  for (Body body : {Body::kMain, Body::kResonator}) {
    const bool main = body == Body::kMain;
    const std::string p = main ? "main." : "res.";
    const std::string q = main ? "y" : "z";
    const std::string v = q + "'";
    const std::string where = main ? "main body (y = x - x0)" : "resonator (z = xr - x)";
    lib.push_back(Def(p + "linear", body, TermKind::kLinear, "k_lin " + q, "linear stiffness of the " + where,
                      {{"k_lin", "N/m", Sign::kEither}}));
    lib.push_back(Def(p + "stiffness_" + q + "2", body, TermKind::kStiffness2, "k2 " + q + "^2",
                      "quadratic (asymmetric) stiffness of the " + where, {{"k2", "N/m^2", Sign::kEither}}));
    lib.push_back(Def(p + "stiffness_" + q + "3", body, TermKind::kStiffness3, "k3 " + q + "^3",
                      "cubic stiffness of the " + where, {{"k3", "N/m^3", Sign::kEither}}));
    lib.push_back(Def(p + "stiffness_" + q + "5", body, TermKind::kStiffness5, "k5 " + q + "^5",
                      "quintic stiffness of the " + where, {{"k5", "N/m^5", Sign::kEither}}));
    lib.push_back(Def(p + "viscous", body, TermKind::kViscous, "c0 " + v, "viscous damping of the " + where,
                      {{"c0", "N s/m", Sign::kNonNegative}}));
    lib.push_back(Def(p + "damping_" + q + "2", body, TermKind::kDamping2, "c2 " + q + "^2 " + v,
                      "displacement-dependent damping (c2 " + q + "^2) of the " + where,
                      {{"c2", "N s/m^3", Sign::kNonNegative}}));
    lib.push_back(Def(p + "damping_v3", body, TermKind::kDampingV3, "c3 " + v + "^3",
                      "cubic velocity damping of the " + where, {{"c3", "N s^3/m^3", Sign::kNonNegative}}));
    lib.push_back(Def(p + "drag", body, TermKind::kDrag, "cq " + v + " |" + v + "|",
                      "quadratic (air) drag of the " + where, {{"cq", "N s^2/m^2", Sign::kNonNegative}}));
    lib.push_back(Def(
        p + "friction", body, TermKind::kFriction,
        "(F_s - F_c tanh(v_sp/v_t)) g(" + v + ") + F_c tanh(" + v + "/v_t), g(v) = (v/v_sp) exp(1/2 - v^2/(2 v_sp^2))",
        "Stribeck friction of the " + where + " (F_s static peak at v_sp, F_c Coulomb level)",
        {{"F_s", "N", Sign::kNonNegative}, {"F_c", "N", Sign::kNonNegative}}));
    lib.push_back(
        Def(p + "bias", body, TermKind::kBias, "f_b", "constant force on the " + where, {{"f_b", "N", Sign::kEither}}));
    if (main)
      lib.push_back(Def(
          "main.piezo", body, TermKind::kPiezo, "-a w on the beam; w' = -b w - c y' (voltage state w)",
          "piezoelectric coupling: back-force -theta w, circuit C_p w' + w/R + theta y' = 0 (a = theta, b = 1/(R C_p), "
          "c = theta/C_p; a coupling that damps the beam has a c > 0)",
          {{"a", "N/V", Sign::kEither}, {"b", "1/s", Sign::kNonNegative}, {"c", "V/m", Sign::kEither}}));
  }
  // Output-side effects, one pair per output kind.
  for (const auto& [name, unit] : std::vector<std::pair<std::string, std::string>>{
           {"displacement", "m"}, {"velocity", "m/s"}, {"analogue", "1"}, {"resonator", "m"}, {"voltage", "V"}}) {
    lib.push_back(Def("out." + name + ".offset", Body::kOutput, TermKind::kOutputOffset, name + " = model + d",
                      "offset of the measured " + name + " output (sensor zero)", {{"d", unit, Sign::kEither}}, name));
    lib.push_back(Def("out." + name + ".scale", Body::kOutput, TermKind::kOutputScale, name + " = (1 + g) model",
                      "gain error of the measured " + name + " output (sensor sensitivity)",
                      {{"g", "1", Sign::kEither}}, name));
  }
  return lib;
}

}  // namespace

const std::vector<TermDef>& EffectLibrary() {
  static const std::vector<TermDef> lib = BuildLibrary();
  return lib;
}

StatusOr<const TermDef*> FindTerm(const std::string& id) {
  std::vector<std::string> ids;
  for (const TermDef& t : EffectLibrary()) {
    if (t.id == id) return &t;
    ids.push_back(t.id);
  }
  return Status::InvalidArgument(
      "terms", UnknownNameMessage("term", id, ids) + "; `bistable identify --list-terms` explains them");
}

StatusOr<std::vector<const TermDef*>> ParseTerms(const std::string& list) {
  std::vector<const TermDef*> out;
  std::set<std::string> seen;
  size_t start = 0;
  while (start <= list.size()) {
    size_t end = list.find(',', start);
    if (end == std::string::npos) end = list.size();
    std::string id = list.substr(start, end - start);
    while (!id.empty() && std::isspace(static_cast<unsigned char>(id.front()))) id.erase(id.begin());
    while (!id.empty() && std::isspace(static_cast<unsigned char>(id.back()))) id.pop_back();
    if (!id.empty()) {
      auto t = FindTerm(id);
      if (!t.ok()) return t.status();
      if (!seen.insert(id).second) return Status::InvalidArgument("terms", "term '" + id + "' is listed twice");
      out.push_back(*t);
    }
    start = end + 1;
  }
  if (out.empty()) return Status::InvalidArgument("terms", "no terms declared (give at least one, e.g. main.linear)");
  return out;
}

void TermBasis(const TermDef& t, double q, double v, const FrictionConstants& fc, double* out) {
  TermBasisSlopes<double>(t, q, v, FrictionBasis(fc), out, nullptr, nullptr);
}

void TermSlopes(const TermDef& t, const double* th, double q, double v, const FrictionConstants& fc, double* dfdq,
                double* dfdv) {
  double phi[kMaxTermParams], pq[kMaxTermParams], pv[kMaxTermParams];
  TermBasisSlopes(t, q, v, FrictionBasis(fc), phi, pq, pv);
  *dfdq = 0;
  *dfdv = 0;
  for (size_t j = 0; j < t.params.size(); ++j) *dfdq += th[j] * pq[j], *dfdv += th[j] * pv[j];
}

}  // namespace bistable
