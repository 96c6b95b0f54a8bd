// JSON shapes of `bistable hbm --json` that the Python module's hbm() gives too: bifurcations and fold curves.
#ifndef BISTABLE_CLIENT_HBM_JSON_H_
#define BISTABLE_CLIENT_HBM_JSON_H_

#include <complex>
#include <vector>

#include <nlohmann/json.hpp>

#include "dynamics/hbm.h"

namespace bistable {

// The well of the orbit at a fold-curve point, by its y_m range: "+well", "-well", "interwell".
const char* FoldWellName(const FoldCurvePoint& p);

// One point of a fold curve: alpha, omega, amplitude, mean (null when not finite), cusp, and well
// when the model is bistable (it has two wells).
nlohmann::json FoldCurvePointJson(const FoldCurvePoint& p, bool bistable);

// A Floquet multiplier as [re, im] (null parts when not finite).
nlohmann::json ComplexJson(std::complex<double> m);

// A located bifurcation: omega, alpha, amplitude (null when the bisection's corrector failed) and the
// critical multiplier.
nlohmann::json LocatedJson(const HbmLocated& l);

// `bifurcations`: every flagged fold, period doubling and Neimark–Sacker point of the branches, in branch
// order — LocatedJson plus kind, branch and point index, and the branch's period.
nlohmann::json BifurcationsJson(const HbmResult& r);

// `fold_curves`: [{start, converged, points: [FoldCurvePointJson...]}].
nlohmann::json FoldCurvesJson(const std::vector<FoldCurve>& curves, bool bistable);

}  // namespace bistable

#endif  // BISTABLE_CLIENT_HBM_JSON_H_
