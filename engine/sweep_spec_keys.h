// Internal to engine/sweep_spec.cc and engine/sweep_spec_read.cc (the spec's model and its TOML reader): the key
// lists both use and where a named parameter lives in a point spec. Not part of the engine's interface.
#ifndef BISTABLE_ENGINE_SWEEP_SPEC_KEYS_H_
#define BISTABLE_ENGINE_SWEEP_SPEC_KEYS_H_

#include <string>
#include <vector>

#include "engine/sweep_spec.h"

namespace bistable::spec_keys {

inline const std::vector<std::string> kRefineCriteria = {"frf_0db", "motion", "lle_sign", "period"};
inline const std::vector<std::string> kToleranceKeys = {"eps", "eta", "eta_r", "phi", "lambda", "alpha", "omega"};
inline const std::vector<std::string> kParamKeys = {"eps", "eta", "eta_r", "phi", "lambda", "alpha", "omega"};

// For dimensional sweeps the point spec's alpha and omega carry A0 [mm] and f0 [Hz]; EvaluateItem (engine/evaluate.cc)
// converts them. Everything else about a point spec (settings, validation, keys) applies unchanged.
inline double* ParamSlot(PointSpec& s, const std::string& name) {
  if (name == "alpha" || name == "a0_mm") return &s.alpha;
  if (name == "omega" || name == "f0_hz") return &s.omega;
  if (name == "eps") return &s.params.eps;
  if (name == "eta") return &s.params.eta;
  if (name == "eta_r") return &s.params.eta_r;
  if (name == "phi") return &s.params.phi;
  if (name == "lambda") return &s.params.lambda;
  for (int k = 0; k < 4; ++k)
    if (name == InitialStateAxisNames()[k]) return &s.ic[k];
  return nullptr;
}

}  // namespace bistable::spec_keys

#endif  // BISTABLE_ENGINE_SWEEP_SPEC_KEYS_H_
