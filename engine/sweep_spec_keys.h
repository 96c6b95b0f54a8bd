// Internal to engine/sweep_spec.cc and engine/sweep_spec_read.cc (the spec's model and its TOML reader): the key
// lists both use and where a named parameter lives in a point spec. Not part of the engine's interface.
#ifndef BISTABLE_ENGINE_SWEEP_SPEC_KEYS_H_
#define BISTABLE_ENGINE_SWEEP_SPEC_KEYS_H_

#include <cstdint>
#include <string>
#include <vector>

#include "engine/spec_toml.h"
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

// model = "terms" (sweep_spec_terms.cc): the axes a term model may sweep (its drive, f0_hz, every parameter by
// name), its [params] keys, the [terms] reader (after the model is read; sets the points' defaults), the checks
// once the whole spec is read, its canonical lines, and the counter generator of its covariance samples.
std::vector<std::string> TermAxisNames(const SweepSpec& spec);
std::vector<std::string> TermParamKeys(const SweepSpec& spec);
Status ReadTerms(const toml::table& root, SweepSpec& spec);
Status CheckTerms(const SweepSpec& spec);
std::string TermsText(const TermsConfig& c);
uint64_t Mix(uint64_t z);
double Uniform(uint64_t seed, uint64_t k, uint64_t d);  // in (0, 1)

}  // namespace bistable::spec_keys

#endif  // BISTABLE_ENGINE_SWEEP_SPEC_KEYS_H_
