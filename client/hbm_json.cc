#include "client/hbm_json.h"

#include "engine/json_shapes.h"

namespace bistable {

const char* FoldWellName(const FoldCurvePoint& p) {
  return p.y_min > 0 ? "+well" : p.y_max < 0 ? "-well" : "interwell";
}

nlohmann::json FoldCurvePointJson(const FoldCurvePoint& p, bool bistable) {
  nlohmann::json j = {{"alpha", p.alpha},
                      {"omega", p.omega},
                      {"amplitude", JsonNumber(p.amplitude)},
                      {"mean", JsonNumber(p.mean)},
                      {"cusp", p.cusp}};
  if (bistable) j["well"] = FoldWellName(p);
  return j;
}

nlohmann::json FoldCurvesJson(const std::vector<FoldCurve>& curves, bool bistable) {
  nlohmann::json out = nlohmann::json::array();
  for (const FoldCurve& c : curves) {
    nlohmann::json pts = nlohmann::json::array();
    for (const FoldCurvePoint& p : c.points) pts.push_back(FoldCurvePointJson(p, bistable));
    out.push_back({{"start", c.start}, {"converged", c.converged}, {"points", pts}});
  }
  return out;
}

nlohmann::json ComplexJson(std::complex<double> m) {
  return nlohmann::json::array({JsonNumber(m.real()), JsonNumber(m.imag())});
}

nlohmann::json LocatedJson(const HbmLocated& l) {
  return {{"omega", JsonNumber(l.omega)},
          {"alpha", JsonNumber(l.alpha)},
          {"amplitude", JsonNumber(l.amplitude)},
          {"multiplier", ComplexJson(l.multiplier)}};
}

nlohmann::json BifurcationsJson(const HbmResult& r) {
  nlohmann::json out = nlohmann::json::array();
  for (size_t b = 0; b < r.branches.size(); ++b)
    for (size_t i = 0; i < r.branches[b].points.size(); ++i) {
      const HbmPoint& p = r.branches[b].points[i];
      auto add = [&](const char* kind, const HbmLocated& l) {
        nlohmann::json j = LocatedJson(l);
        j.update({{"kind", kind}, {"branch", b}, {"point", i}, {"period", p.period}});
        out.push_back(j);
      };
      if (p.fold) add("fold", p.fold_at);
      if (p.period_doubling) add("period_doubling", p.period_doubling_at);
      if (p.neimark_sacker) add("neimark_sacker", p.neimark_sacker_at);
    }
  return out;
}

}  // namespace bistable
