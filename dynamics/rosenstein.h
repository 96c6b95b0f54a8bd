// Largest Lyapunov exponent from a sampled scalar series (Rosenstein, Collins & De Luca,
// Physica D 65, 1993) — the paper's method, for measured or sampled data:
//  1. delay-embed the series (lag J from the autocorrelation's drop to 1 − 1/e, dimension m);
//  2. for every embedded point find its nearest neighbour farther apart in time than the mean
//     period (Theiler window) with a k-d tree (nanoflann), not an N×N distance matrix;
//  3. average ln(distance) of the pairs as they evolve: y(i) = ⟨ln d_j(i)⟩;
//  4. the LLE is the slope of y against time over the initial linear region.
// Fit region (automatic unless given): y(i) rises from y(0) to a plateau (its max over a horizon of
// 6 mean periods). The fit covers the band where y has made between `fit_lo` and `fit_hi` of that
// rise: below it the pair separations are still aligning with the unstable direction, above it they
// saturate at the attractor's size. (On Lorenz x(t) the band 0.1–0.7 is straight; see lyapunov_test.)
// Periodic data give ≈ 0, not the (negative) exponent of the orbit — a known limit of the method.
#ifndef BISTABLE_DYNAMICS_ROSENSTEIN_H_
#define BISTABLE_DYNAMICS_ROSENSTEIN_H_

#include <vector>

namespace bistable {

struct RosensteinOptions {
  int dim = 4;         // embedding dimension m
  int lag = 0;         // delay J in samples; 0 = autocorrelation rule
  int theiler = 0;     // temporal exclusion in samples; 0 = mean period from the spectrum
  int horizon = 0;     // steps of divergence followed; 0 = 6 mean periods (≤ N/4)
  int fit_begin = -1;  // fit region in steps; -1 = automatic
  int fit_end = -1;
  double fit_lo = 0.1;  // automatic fit band, as fractions of the rise to the plateau
  double fit_hi = 0.7;
};

struct RosensteinResult {
  bool ok = false;  // false when the series is too short or degenerate
  double lle = 0;   // per unit time
  int lag = 0, dim = 0, theiler = 0, fit_begin = 0, fit_end = 0, pairs = 0;
  std::vector<double> divergence;  // y(i), i = 0..horizon
};

// series sampled every dt (time units of the result).
RosensteinResult RosensteinLle(const std::vector<double>& series, double dt, const RosensteinOptions& opt = {});

}  // namespace bistable

#endif  // BISTABLE_DYNAMICS_ROSENSTEIN_H_
