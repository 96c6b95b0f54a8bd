// Invariants of a chaotic attractor: what a model of a chaotic record must reproduce when a
// sample-by-sample match is not to be expected (two chaotic trajectories from nearly the same state
// part after a few forcing periods). Each compares the measured output of a record with the output
// simulated from the same input and initial state, through the same processing:
//
//  * Poincaré section: the main body's state (y, y') sampled once per forcing period at a fixed
//    phase of the measured input (its fundamental at its positive peak), forcing frequency from the
//    input's spectrum. Distance between the measured and the simulated point clouds: the energy
//    coefficient H = D² / (2 E|X − Y|), D² = 2 E|X − Y| − E|X − X'| − E|Y − Y'| (Székely & Rizzo's
//    energy distance, V-statistics), each coordinate divided by the two clouds' pooled standard
//    deviation. Dimensionless, in [0, 1]: 0 for identical clouds (exactly), → 1 for clouds far apart.
//  * Well occupancy and switching rate [1/s], by forcing period (WellsOf): y averaged over each
//    whole forcing period; the period means split into two wells by exact 1-D two-means, a period
//    joins a well when its mean lies beyond the split by a quarter of the wells' distance (hysteresis:
//    between, the period stays in the last well). Measured and simulated y each by their own split:
//    a velocity sensor's integral is zero-mean, which shifts the period means by the occupancy-weighted
//    centre, so only each series' own clusters are where its wells are. A switch is a change of well;
//    an orbit inside one well, however wide, moves the period mean little and does not count, nor does
//    a large orbit across both wells (no two clusters). Compared as |rate_sim − rate_meas| / rate_meas,
//    and by the share of well periods in the right well (undefined for a series in one well).
//  * Velocity histogram: Hellinger distance sqrt(1 − Σ sqrt(p_k q_k)) between the histograms of y'
//    on common bins (40 over the measured range widened by 10 %, one overflow bin each side).
//    Dimensionless, in [0, 1].
//  * Spectrum: the normalised Eq. 20 error of fit.h (Errors::fft), %.
//  * Per output (velocity and voltage, displacement and resonator): the histogram distance of the
//    output's own samples and its spectral error — a second output's statistics are invariants of the
//    attractor too.
// y is the relative displacement: the output itself (displacement outputs; minus the base for an
// absolute one under base displacement) or, for velocity outputs, the FFT integral of the relative
// velocity (IntegrateFft; zero-mean, so the barrier at 0 assumes the motion visits both wells alike).
//
// Which records are chaotic (ChaosCheck): those fitted with the spectral objective, and those whose
// input is periodic (≥ 90 % of its power within 3 bins of the harmonics of its strongest line)
// while the output is not: its broadband share — the power farther than 3 bins from every harmonic
// of the forcing (HarmonicDiffusionIndex) — is ≥ kBroadbandChaotic. A cheap stand-in for a positive
// Lyapunov exponent: it marks any response not locked to the forcing period (sub-harmonic,
// quasi-periodic, chaotic), and all of those need invariants rather than a sample-by-sample match.
#ifndef BISTABLE_IDENTIFY_INVARIANTS_H_
#define BISTABLE_IDENTIFY_INVARIANTS_H_

#include <cmath>
#include <string>
#include <vector>

#include <Eigen/Dense>

#include "identify/fit.h"

namespace bistable {

inline constexpr double kBroadbandChaotic = 0.2;  // output broadband share marking a record chaotic
inline constexpr double kPeriodicInput = 0.1;     // input broadband share at most this: periodic forcing

// The strongest line of a sampled signal [Hz], refined to the maximum of its Hann-weighted projection;
// NaN for a signal without one (< 16 samples, constant).
double ForcingFrequency(const std::vector<double>& input, double dt);

// The main body's relative displacement y and velocity y' from an output in the record's compared
// form (measured or simulated), as described above.
void MainBodyMotion(const std::vector<double>& out, const PreparedRecord& r, const Setup& setup, std::vector<double>* y,
                    std::vector<double>* yd);

// Stroboscopic section: rows (y, y') at t_k = (2πk − φ)/ω inside the record (spline-interpolated),
// where the input's fundamental is A cos(ωt + φ), ω = 2π f_hz.
Eigen::MatrixXd StroboscopicSection(const std::vector<double>& y, const std::vector<double>& yd,
                                    const std::vector<double>& input, double dt, double f_hz);

// Energy coefficient H of two point clouds (rows are points, same number of columns), coordinates
// scaled by their pooled within-cloud standard deviations; clouds over 2000 points are thinned evenly.
// NaN when a cloud is empty or holds a non-finite value.
double EnergyCoefficient(const Eigen::MatrixXd& a, const Eigen::MatrixXd& b);
// The raw energy distance D² (V-statistics, no scaling) of the same clouds.
double EnergyDistanceSquared(const Eigen::MatrixXd& a, const Eigen::MatrixXd& b);

// Barrier crossings of y at `barrier` with hysteresis ±h (y goes from below barrier − h to above
// barrier + h or back).
int CountSwitches(const std::vector<double>& y, double barrier, double h);

// y over whole forcing periods from t = 0 (period k: samples with t in [k/f, (k+1)/f)): each period's
// mean and standard deviation. Empty without a forcing frequency or a whole period.
struct PeriodMotion {
  std::vector<double> mean, spread;
};
PeriodMotion PeriodsOf(const std::vector<double>& y, double dt, double f_hz);

// Two wells in the period means: the split of the sorted means that minimises the within-cluster sum of
// squares (exact 1-D two-means), centres the clusters' means. `two_wells` when the centres lie farther
// apart than the median within-period spread: a change of well moves the period mean by more than the
// orbit's own size, while the means of a record in one well cluster only by their scatter. band is a
// quarter of the centres' distance.
struct WellSplit {
  bool two_wells = false;
  double split = NAN, band = NAN, centre_left = NAN, centre_right = NAN;
};
WellSplit SplitWells(const PeriodMotion& p);

// Period means classified by a split: left below split − band, right above split + band, otherwise
// the last well (none before the first classified period). Switches: changes of well.
struct WellCount {
  int switches = 0, left = 0, right = 0;
  double sum_left = 0, sum_right = 0;  // of the classified period means
  void Add(const WellCount& o) {       // another record's periods
    switches += o.switches, left += o.left, right += o.right, sum_left += o.sum_left, sum_right += o.sum_right;
  }
};
WellCount CountWells(const std::vector<double>& means, const WellSplit& s);

// The measured and the simulated y of one record, each by its own split (no switches for a series
// without two wells).
struct WellSwitching {
  WellSplit measured_split, simulated_split;
  WellCount measured, simulated;
  double seconds = 0;  // whole forcing periods
  bool finite = true;  // every period mean of both series finite; otherwise the counts mean nothing
};
WellSwitching WellsOf(const std::vector<double>& y_meas, const std::vector<double>& y_sim, double dt, double f_hz);

// Hellinger distance between the histograms of `sim` and `meas` on `bins` common bins over meas's range
// widened by 10 % (plus one overflow bin each side). NaN when either is empty or non-finite.
double HistogramHellinger(const std::vector<double>& meas, const std::vector<double>& sim, int bins = 40);

// The invariants of one model against the records (means over chaotic records; switching rates are
// total switches over total time).
struct Invariants {
  double poincare = NAN;        // energy coefficient H of the sections, dimensionless [0, 1]
  double poincare_floor = NAN;  // H between the first and second half of the measured section: what
                                // another stretch of the same measurement gives (a model cannot do better)
  int section_points = 0;       // measured section points, all records
  double switching_rate = NAN;  // simulated, 1/s (changes of well by forcing period)
  double switching_rate_measured = NAN;
  double switching_error = NAN;      // |sim − meas| / meas
  double right_well_fraction = NAN;  // simulated periods in the right well / periods in a well
  double right_well_fraction_measured = NAN;
  double well_centres[2] = {NAN, NAN};           // simulated: mean period mean in the left, right well, m
  double well_centres_measured[2] = {NAN, NAN};  // (y zero-mean for velocity outputs: relative positions)
  double velocity_hellinger = NAN;               // dimensionless [0, 1]
  double spectral_error = NAN;                   // % (Errors::fft)
  // Every measured output (main first): the Hellinger distance of its measured and simulated sample
  // histograms (as for the velocity) and its spectral error (OutputErrors::fft, all records).
  struct Output {
    std::string name;
    double hellinger = NAN;
    double spectral_error = NAN;
  };
  std::vector<Output> by_output;
};

// Per record: the forcing and the rule's inputs.
struct ChaosCheck {
  bool chaotic = false;  // invariants are computed (any record marked)
  std::vector<char> record_chaotic;
  std::vector<double> forcing_hz;        // NaN where the input has no line
  std::vector<double> input_broadband;   // input's broadband share about its own line
  std::vector<double> output_broadband;  // output's broadband share about the forcing
  std::string rule;                      // how it was decided, for reports
};

ChaosCheck CheckChaos(const std::vector<PreparedRecord>& recs, const Setup& setup, Objective objective);

// Simulates every marked record with (m, th) and compares; `errors` supplies the spectral error.
Invariants ComputeInvariants(const IdentModel& m, const std::vector<double>& th,
                             const std::vector<PreparedRecord>& recs, const Setup& setup, const ChaosCheck& check,
                             const Errors& errors);

}  // namespace bistable

#endif  // BISTABLE_IDENTIFY_INVARIANTS_H_
