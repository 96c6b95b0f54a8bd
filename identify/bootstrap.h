// The fit's uncertainty by a parametric bootstrap (`identify --bootstrap N`): the final model's twin records
// (TwinRecords: simulated from the measured start, driven by the measured input, recorded again with the
// record's own input and output noise levels) are fitted again, each from the final parameters with the final
// objective, and the spread of those fits is the covariance.
//
// Why, beside the Gauss–Newton covariance s²(JᵀJ)⁻¹ τ (fit.cc): that one is the curvature at the solution. Where
// the response depends on a parameter through events — the static friction peak F_s through the moments a
// sticking body breaks away — the curvature is enormous and says nothing about a step of 1 %: on 21 synthetic
// snap-through records (bench/fit_then_map.py) the fitted F_s was up to 700 Gauss–Newton σ from the truth, and
// c2 (biased by the noise on the input) 3–6 σ. The bootstrap's fits step over such events, and its σ is what
// refitting another noise draw moves a parameter by.
#ifndef BISTABLE_IDENTIFY_BOOTSTRAP_H_
#define BISTABLE_IDENTIFY_BOOTSTRAP_H_

#include <string>
#include <vector>

#include <Eigen/Dense>

#include "identify/fit.h"
#include "identify/model.h"

namespace bistable {

inline constexpr int kMinBootstrapTwins = 8;
inline constexpr int kMaxBootstrapTwins = 256;

struct BootstrapResult {
  int twins = 0;                           // asked for
  int fitted = 0;                          // fits that ended finite and physical (the covariance is over these)
  std::vector<double> mean;                // of the fitted parameters
  Eigen::MatrixXd covariance;              // sample covariance (fitted − 1), empty when fewer than 3 fitted
  std::vector<double> gauss_newton_sigma;  // the final fit's own σ, for comparison
  double seconds = 0;
  std::string note;  // why there is none (a force input, a relative velocity output, simulations diverged)
  bool ok() const { return covariance.size() > 0; }
};

// `fo`: the final fit's options (its objective, horizon); the refits run its local stage only. `twins` in
// [kMinBootstrapTwins, kMaxBootstrapTwins]; two fits side by side (each on one thread).
BootstrapResult BootstrapFit(const IdentModel& m, const FitResult& fit, const std::vector<PreparedRecord>& recs,
                             const Setup& setup, FitOptions fo, int twins);

}  // namespace bistable

#endif  // BISTABLE_IDENTIFY_BOOTSTRAP_H_
