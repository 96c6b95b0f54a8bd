// The non-dimensional model's flags that `bistable point` and `bistable hbm` share: one definition of each
// name, its bound and its help text (model.md §1; the values are validated where the spec is).
#ifndef BISTABLE_CLIENT_MODEL_FLAGS_H_
#define BISTABLE_CLIENT_MODEL_FLAGS_H_

#include <string>

#include <CLI/CLI.hpp>

#include "dynamics/point_spec.h"

namespace bistable {

// --model and the parameters ε, η, η_r, φ, λ, with their defaults shown in --help.
inline void AddNondimModelOptions(CLI::App* cmd, std::string* model, NondimParams* p) {
  cmd->add_option("--model", *model, "standalone | coupled | linear | linear-coupled")->capture_default_str();
  cmd->add_option("--eps", p->eps, "cubic stiffness epsilon (> 0)")->capture_default_str();
  cmd->add_option("--eta", p->eta, "main damping eta = c/(m_m omega_n) (>= 0)")->capture_default_str();
  cmd->add_option("--eta-r", p->eta_r, "resonator damping eta_r = c_r/(m_r omega_n) (>= 0)")->capture_default_str();
  cmd->add_option("--phi", p->phi, "mass ratio phi = m_r/m_m (> 0)")->capture_default_str();
  cmd->add_option("--lambda", p->lambda, "tuning lambda = omega_r/omega_n (> 0)")->capture_default_str();
}

}  // namespace bistable

#endif  // BISTABLE_CLIENT_MODEL_FLAGS_H_
