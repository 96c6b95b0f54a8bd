// A model to identify (declared terms over the effect library, known constants, a parameter vector)
// and its simulation driven by a measured record's input.
//
// Three input forms (record.h), one state (p, p', r, r') — and a voltage w when the model has main.piezo
// (w' = −b w − c y', back-force −a w on the main body; dynamics/terms.h):
//   base displacement x0 [m]   p = x (absolute main mass), r = x_r: needs x0 and x0' (cubic spline of the samples)
//       m_m x'' = −F(y, y') + G(z, z'),  y = x − x0,  m_r x_r'' = −G(z, z'),  z = x_r − x
//   base acceleration a0 [m/s²] p = y (relative), r = z:  y'' = (−F + G)/m_m − a0,  z'' = −G/m_r − (−F + G)/m_m
//   force u [N]                 p = y, r = z:              y'' = (u − F + G)/m_m,   z'' = −G/m_r − y''
// Integration: classical RK4 (dynamics/rk4.h) with the input interpolated by a natural cubic spline, substeps per
// sample chosen from the model's stiffness along the measured range (friction makes it stiff: the
// substep count grows as F_c / (m v_t)); a run that leaves 100× the measured range is reported as
// diverged.
#ifndef BISTABLE_IDENTIFY_MODEL_H_
#define BISTABLE_IDENTIFY_MODEL_H_

#include <algorithm>
#include <array>
#include <cmath>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include <Eigen/Dense>

#include "base/status.h"
#include "dynamics/terms.h"
#include "identify/record.h"
#include "identify/signals.h"

namespace bistable {

enum class OutputFrame { kAbsolute, kRelative };

// How records relate to the model.
struct Setup {
  InputKind input = InputKind::kBaseDisplacement;
  OutputKind output = OutputKind::kDisplacement;
  OutputFrame frame = OutputFrame::kAbsolute;  // velocity or displacement measured absolute or relative to the base
  FrictionConstants fc;
  // Velocity outputs: the displacement integrated from the (relative) velocity loses its content below this
  // frequency [Hz] (0: only its mean). Below a record's slowest motion that content is the sensor's drift
  // integrated (on 32 s intrawell records of the harvester 1.6–2.2 times the orbit); on records that change well it is
  // the switching itself, so leave 0 there. Used by the regression start, the shooting position scan, the plots.
  double drift_cutoff_hz = 0;
};

Status ValidateSetup(const Setup& s);

// The name of an output (its kind: displacement, velocity or analogue for the main body's; resonator;
// voltage): keys of errors_by_output and the <output> of out.<output>.offset / .scale.
std::string OutputName(const Setup& s, OutputSlot slot);
// The slot an output term acts on in this setup, or −1 (a term of an output kind the setup lacks).
int OutputSlotOf(const TermDef& t, const Setup& s);

struct IdentModel {
  std::vector<const TermDef*> terms;  // main body and resonator terms, in declaration order
  double m_main = 0;                  // kg; 0 = fitted (force input only), parameter "m_main"
  double m_res = 0;                   // kg; needed when any res.* term is declared
  FrictionConstants fc;
  std::vector<double> theta;  // parameters, ParamNames() order: terms, [m_main], [offsets]
  // Velocity outputs: the static displacement (which well, where) is not observable from the
  // velocity, so each record's displacement offset [m] is a parameter ("offset.k", one per record,
  // added after the terms and the mass). PreparedRecord::index picks a record's offset.
  int offsets = 0;

  bool FitsMass() const { return m_main <= 0; }
  int NumTermParams() const;
  int OffsetIndex(int record) const { return NumTermParams() + (FitsMass() ? 1 : 0) + record; }
  double Offset(const std::vector<double>& th, int record) const {
    return offsets > 0 && record >= 0 && record<offsets&& static_cast<int>(th.size())> OffsetIndex(record)
               ? th[OffsetIndex(record)]
               : 0.0;
  }
  bool HasResonator() const;
  // Index of main.piezo's first parameter (a; then b, c), −1 without it.
  int PiezoIndex() const;
  int NumParams() const;
  std::vector<std::string> ParamNames() const;  // "main.stiffness_y3.k3", ..., "m_main"
  std::vector<std::string> ParamUnits() const;
  std::vector<Sign> ParamSigns() const;
  int Offset(const TermDef* t) const;  // index of the term's first parameter, −1 if absent
  double Mass(const std::vector<double>& th) const { return FitsMass() ? th[NumTermParams()] : m_main; }
  // F_main or G_res at (q, v) for parameters th.
  double Force(Body body, const std::vector<double>& th, double q, double v) const;
  // The model with one more term, its parameters appended after the other terms' (before m_main and
  // the offsets; initial values given).
  IdentModel With(const TermDef* t, const std::vector<double>& initial) const;
};

// A record prepared for one setup: slices, derived signals and the spline of its input.
struct PreparedRecord {
  std::string name;
  int index = 0;  // position among the records fitted together (offset parameter)
  double t0 = 0, dt = 0;
  std::vector<double> input;     // SI
  std::vector<double> meas;      // the measured output in the compared form (see Setup)
  std::vector<double> meas_res;  // measured resonator absolute displacement, or empty
  // Measured piezo voltage [V] (output 2), or empty; its band-limited value and derivative (regression)
  // and local cubic fit (initial and restart states of the voltage).
  std::vector<double> volt, w, wd, ic_w;
  double volt_scale = 1;  // RMS of volt about its mean
  // Per output slot (OutputSlot): the noise level σ (NoiseLevel) and the weight λ of the output's NRMSE²
  // in a joint fit (main output 1; SetOutputWeights), for the outputs the record has.
  double noise[kOutputSlots] = {NAN, NAN, NAN};
  double weight[kOutputSlots] = {1, 1, 1};
  bool Has(OutputSlot s) const {
    return s == OutputSlot::kMain || (s == OutputSlot::kResonator ? !meas_res.empty() : !volt.empty());
  }
  const std::vector<double>& Measured(OutputSlot s) const {
    return s == OutputSlot::kMain ? meas : s == OutputSlot::kResonator ? meas_res : volt;
  }
  double Scale(OutputSlot s) const;  // RMS about the mean of the measured output
  std::vector<double> base_v;        // base velocity at samples (acceleration input, absolute velocity output)
  std::vector<double> base_x;        // base displacement at samples (displacement input)
  // The body's coordinate p and its derivatives from the measurement (smoothed), for initial states
  // and restoring-force residuals: p = x (displacement input) or y.
  std::vector<double> p, pd, pdd, r, rd, rdd;
  // States to start (and restart, for multiple shooting) simulations from: local cubic fits (Savitzky–
  // Golay, 9 samples), which are accurate at every sample including the ends.
  std::vector<double> ic_p, ic_pd, ic_r, ic_rd;
  // Relative coordinates along the measured trajectory: y, y', z, z' (z empty without resonator data).
  std::vector<double> y, yd, z, zd;
  // The simulation's drive: the measured input low-passed at f_drive (DriveSpline). Noise on the input
  // outside its band acts on the model through the input's derivative — the base velocity of a displacement
  // input gains 2πf, at 120 Hz sampling 0.05 mm of noise is ≈ 9 mm/s — and through friction's narrow
  // transition (v_t 1 mm/s) it kept the simulated bodies from sticking: the fits raised the static friction
  // (1.47 and 1.85 N for 1.2 on two snap-through records) to hold them. The raw samples stay in `input`
  // (noise levels, twins).
  UniformSpline in_spline;
  double f_drive = 0;               // the drive's band edge [Hz] (DriveCutoff), 0: the input as measured
  double meas_scale = 1;            // RMS of meas about its mean (NRMSE denominator)
  double p_range = 1, v_range = 1;  // max |y|, max |y'| along the record
  double f_cut = 0;                 // derivative cutoff used [Hz]
  // The record's own horizon under the time objective (identify/predictability.h): 0 — its whole simulation is
  // compared; > 0 — the simulation is restarted from the measured state every horizon_s (a record whose long
  // simulation is chaos, not model error). A horizon asked for by a fit stage (FitOptions::shooting_horizon_s)
  // takes precedence.
  double horizon_s = 0;
  // --objective auto found the record's long simulation to be chaos (identify/predictability.h): it is fitted
  // under multiple shooting, and the trace and the whiteness test are calibrated on the model's twins.
  bool chaotic = false;
  // The measured record changes well at least twice (identify/predictability.h): even where its long
  // simulation is meaningful, the residual of a snap-through record is not white for the true model (the
  // input's noise acts through the hump), so the trace and the whiteness test are calibrated on twins.
  bool snaps = false;
  size_t n() const { return meas.size(); }
};

// The spline of an input series of record r (its own samples, or a twin's) for the simulation: band-limited
// at r.f_drive when that is set.
UniformSpline DriveSpline(const PreparedRecord& r, const std::vector<double>& input);

// Prepares a record (or its sample range [begin, end)) for a setup. `f_cut_hz`: low-pass cutoff of
// the measured derivatives (0: AutoCutoff of the output). Errors: unsupported input/output
// combinations, too-short records.
StatusOr<PreparedRecord> PrepareRecord(const Record& rec, const Setup& setup, size_t begin, size_t end, double f_cut_hz,
                                       const std::string& name);

// Restart states from the band-limited coordinate and derivative (p, p', r, r': unbiased inside the band) in
// the record's interior, the local cubic ones kept at its ends (16 samples, where the mirrored transform is
// distorted). For records fitted on short horizons (PreparedRecord::horizon_s > 0): a 9-sample local cubic
// lags the fast crossings of a snap-through (the true model restarted from it missed a 0.22 s horizon by 28 %
// on a record that changes well 15 times in 30 s; from these states, 1.3 % at 0.066 s). Idempotent.
void BandLimitedRestarts(PreparedRecord* r);

// Joint fits of several outputs: the weight of output o's NRMSE² is λ_o = (ν_main / ν_o)², ν = σ / RMS the
// relative noise level (pooled over records: RMS of σ/RMS), clipped to [0.01, 100]; the main output's is 1
// (a single output fits as before). Sets PreparedRecord::weight of every record.
void SetOutputWeights(std::vector<PreparedRecord>* recs);
inline constexpr double kMinOutputWeight = 0.01, kMaxOutputWeight = 100.0;
// Per output slot: the relative noise level ν = σ / RMS pooled over records (NaN for an output no record has).
std::array<double, kOutputSlots> RelativeNoise(const std::vector<PreparedRecord>& recs);
// λ_o = (level_main / level_o)², clipped to [kMinOutputWeight, kMaxOutputWeight] (1 where not finite), for
// any relative error level per output: the noise (SetOutputWeights) or a fit's error (loop.cc).
void SetOutputWeightsFrom(const std::array<double, kOutputSlots>& level, std::vector<PreparedRecord>* recs);

// Simulates one record from its measured initial state; `out` receives the output in the compared
// form at every sample, `out_res` the resonator displacement when measured. False on divergence.
// `substeps` > 0 fixes the RK4 substeps per sample (fits hold it fixed so that the objective is a
// smooth function of the parameters); 0 chooses them from the parameters (SubstepsFor).
// Early stop of a hopeless simulation (a fit's global stage): Σ ((out − meas)·w)² over the samples so far
// is kept in `sse`; once it exceeds `budget` the simulation stops (Simulate returns false, `stopped` set),
// since the candidate cannot beat the point the budget came from.
struct EarlyStop {
  const std::vector<double>* meas = nullptr;
  double w = 1, budget = INFINITY;
  double sse = 0;
  bool stopped = false;
};
// Every output of a simulation, by slot (empty where the record lacks that output), and with
// sensitivities their derivatives (n × P; as SimulateSensitivities).
struct SimOutputs {
  std::vector<double> out[kOutputSlots];
  Eigen::MatrixXd d[kOutputSlots];
  // With SegmentStates::sensitivities: each output's derivative by the start state of its own segment
  // (n × kStateDim, state order p, p', r, r', w).
  Eigen::MatrixXd ds[kOutputSlots];
};
// The simulation state (p, p', r, r', w): the main body's coordinate and velocity, the resonator's, and
// the piezo's voltage.
inline constexpr int kStateDim = 5;
// Multiple shooting with re-estimated states (restart_every > 0): segment k starts at sample k·restart_every
// from states[kStateDim k …] instead of the measured state (the voltage only when the record measures it);
// it emits samples k·restart_every + 1 … (k + 1)·restart_every (segment 0 also sample 0). With
// `sensitivities`, SimOutputs::ds; `parameters` false leaves out the parameters' columns (d stays empty).
struct SegmentStates {
  const std::vector<double>* states = nullptr;  // NumSegments × kStateDim, or null: the measured states
  bool sensitivities = false;
  bool parameters = true;
  // Segments simulated (1) or skipped (0: their samples are left NaN), or null: all.
  const std::vector<char>* active = nullptr;
};
// Segments of a record of n samples cut every `every` samples, and the segment that emits sample i.
inline size_t NumSegments(size_t n, int every) { return n <= 1 ? 1 : (n - 2) / static_cast<size_t>(every) + 1; }
inline size_t SegmentOf(size_t i, int every) { return i == 0 ? 0 : (i - 1) / static_cast<size_t>(every); }
// The measured (smoothed) state at sample i in state order, offset included: what a restart sets.
std::array<double, kStateDim> MeasuredState(const IdentModel& m, const std::vector<double>& th, const PreparedRecord& r,
                                            const Setup& setup, size_t i);
bool SimulateOutputs(const IdentModel& m, const std::vector<double>& th, const std::vector<const TermDef*>& extra,
                     const PreparedRecord& r, const Setup& setup, int substeps, int restart_every, bool sensitivities,
                     SimOutputs* out, EarlyStop* stop = nullptr, const SegmentStates* segments = nullptr);

// Plain simulations of up to kMaxSimLanes parameter vectors side by side in SIMD lanes (the spectral
// objective's forward-difference columns): (*outs)[l] is, to the bit, what SimulateOutputs(m, *ths[l], {}, r,
// setup, substeps, 0, false, …) gives — whole records, no sensitivities, `substeps` > 0 for every lane. False
// when any lane's simulation fails (its outputs are then meaningless).
inline constexpr int kMaxSimLanes = 8;
bool SimulateOutputsLanes(const IdentModel& m, const std::vector<const std::vector<double>*>& ths,
                          const PreparedRecord& r, const Setup& setup, int substeps, std::vector<SimOutputs>* outs);
bool Simulate(const IdentModel& m, const std::vector<double>& th, const PreparedRecord& r, const Setup& setup,
              std::vector<double>* out, std::vector<double>* out_res = nullptr, int substeps = 0, int restart_every = 0,
              EarlyStop* stop = nullptr);
// Simulate, and the output's sensitivities: column j of `dout` (n × P) is ∂out/∂θ_j for the model's
// parameters (ParamNames order), then for the parameters of the `extra` terms at value 0 (the trace's
// candidates); `dres` likewise for the resonator output. From the variational equations integrated with
// the state by the same RK4 steps: the exact derivative of the discrete simulation (fixed substeps), for
// every parameter in one pass, where finite differences cost a simulation per parameter (or two).
bool SimulateSensitivities(const IdentModel& m, const std::vector<double>& th, const std::vector<const TermDef*>& extra,
                           const PreparedRecord& r, const Setup& setup, int substeps, int restart_every,
                           std::vector<double>* out, Eigen::MatrixXd* dout, std::vector<double>* out_res = nullptr,
                           Eigen::MatrixXd* dres = nullptr);
// restart_every > 0: the state is reset to the measured (smoothed) one every so many samples —
// short-horizon simulation error (multiple shooting), whose minimum lies where the long-horizon one
// does but whose basin is far wider (no accumulated phase drift); fits use it as a first stage.

// RK4 substeps per sample for these parameters along this record (stable with a margin, and accurate).
int SubstepsFor(const IdentModel& m, const std::vector<double>& th, const PreparedRecord& r);
// The fewest RK4 substeps per sample that keep the simulation stable for these parameters (SubstepsFor's
// rate bounds against RK4's stability limits, without its accuracy margin). Below it, RK4 on a sticking
// friction law chatters: the state stays bounded by the law's saturation while its sensitivities grow
// without bound.
int StableSubsteps(const IdentModel& m, const std::vector<double>& th, const PreparedRecord& r);
// The fewest RK4 substeps per sample that keep it stable on the damping rates (StableSubsteps' bound) and accurate
// on the oscillations (SubstepsFor's): without SubstepsFor's stability margin. On the coupled snap-through rig
// with sticking friction (bench/bench_identify_steps) RK4 at StableSubsteps is within 0.005 % of the output's RMS
// of RK4 at 8× the steps over the shooting horizon, 50× below the record's noise.
int AccurateSubsteps(const IdentModel& m, const std::vector<double>& th, const PreparedRecord& r);
// RK4 substeps per sample for accuracy on the oscillations alone (SubstepsFor's bound h ω ≤ 0.5, no damping rate).
int OscillationSubsteps(const IdentModel& m, const std::vector<double>& th, const PreparedRecord& r);

}  // namespace bistable

#endif  // BISTABLE_IDENTIFY_MODEL_H_
