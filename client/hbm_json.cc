#include "client/hbm_json.h"

#include "engine/json_shapes.h"

namespace bistable {

const char* FoldWellName(const FoldCurvePoint& p) { return p.y_min > 0 ? "+well" : p.y_max < 0 ? "-well" : "interwell"; }

nlohmann::json FoldCurvePointJson(const FoldCurvePoint& p, bool bistable) {
  nlohmann::json j = {{"alpha", p.alpha}, {"omega", p.omega}, {"amplitude", JsonNumber(p.amplitude)}, {"mean", JsonNumber(p.mean)},
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

}  // namespace bistable
