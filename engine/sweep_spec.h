// A sweep: a model, fixed parameters, axes over (α, Ω, η, η_r, λ, φ, ε), integration and metric
// settings and one or several initial conditions per point. Parsed from TOML (see
// examples/*.toml and docs/sweep-spec.md); validated once, up front, with the offending field named.
#ifndef BISTABLE_ENGINE_SWEEP_SPEC_H_
#define BISTABLE_ENGINE_SWEEP_SPEC_H_

#include <array>
#include <cmath>
#include <cstdint>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "base/status.h"
#include "dynamics/dimensional_model.h"
#include "dynamics/point_spec.h"
#include "dynamics/series_model.h"
#include "dynamics/term_model.h"

namespace bistable {

struct Axis {
  std::string name;            // alpha | omega | eta | eta_r | lambda | phi | eps
  std::vector<double> values;  // strictly increasing
};

// N cells in series: identical cells from [params] and the axes, with optional per-cell overrides.
struct SeriesConfig {
  int cells = 2;
  bool resonators = true;                                              // every cell carries a resonator
  bool bistable = true;                                                // bistable links (else linear)
  std::vector<std::vector<std::pair<std::string, double>>> overrides;  // per cell: name → value
};

// The dimensional model: a Table 2 preset with overrides; base amplitude A0 [mm] and frequency f0 [Hz].
struct DimensionalConfig {
  DimensionalParams params = DimensionalParams::BistableTable2();
  bool bistable = true;
  double a0_mm = 10.0, f0_hz = 5.0;
};

// A rig point's drive in SI (SweepSpec::DriveAt). A dimensional sweep's PointSpec holds its axes' own units —
// A0 in mm (or, for a term model driven by acceleration, the base acceleration amplitude in g) in `alpha`,
// f0 in Hz in `omega` (the content keys hash those, so stored points keep their keys) — and code reads a rig
// point's drive only through DriveAt, never from alpha/omega.
struct RigDrive {
  double a0_m = 0;         // base displacement amplitude A0 [m]; a force's: F0/(m_main ω²), the metrics' scale
  double f0_hz = 0;        // excitation frequency f0 [Hz]
  double omega_rad_s = 0;  // 2 pi f0 [rad/s]
  double force_n = 0;      // a force input's amplitude F0 [N] on the main body (the base then stands still), else 0
};
inline constexpr double kStandardGravity = 9.80665;  // m/s² per g

// A model of effect-library terms (model = "terms", issue 42): the model `bistable identify` fits, swept in lanes
// (dynamics/term_model.h). Given inline in [terms] (list, theta, m_main, m_res, v_sp, v_t, covariance) — a
// client resolves `report = "DIR/report.json"` into that before a spec is parsed (client/terms_report.h), so a
// spec that travels to a coordinator or a worker carries its model and no path. Its points are dimensional (SI);
// the drive is the base's displacement amplitude (axis a0_mm), for a model fitted to a base-acceleration
// input its acceleration amplitude in g (axis acc0_g), or for a force input the amplitude of a force on the main
// body in N (axis force0_n), at f0_hz; any term parameter can be an axis by its name ("main.viscous.c0").
struct TermsConfig {
  TermModel model;                 // terms, nominal parameters, masses, friction constants
  std::vector<double> covariance;  // model.NumParams()² row-major (the fit's), or empty
  enum class Drive { kDisplacement, kAcceleration, kForce };
  Drive drive = Drive::kDisplacement;  // the base's displacement (a0_mm), its acceleration (acc0_g), a force (force0_n)
  std::string origin;                  // where the model came from (free text for humans: a report's path)
  const char* DriveAxis() const {
    return drive == Drive::kAcceleration ? "acc0_g" : drive == Drive::kForce ? "force0_n" : "a0_mm";
  }
};

// Continuation of the initial condition along one axis (bifurcation diagrams): each point starts
// from the previous point's final state, sweeping up, down or both, so hysteresis shows.
struct ContinuationConfig {
  std::string axis;  // "" = off; else one of the sweep's axes
  bool up = true, down = true;
  bool enabled() const { return !axis.empty(); }
  int directions() const { return (up ? 1 : 0) + (down ? 1 : 0); }
};

// Robustness maps (issue 17): every grid point is run `samples` times with its parameters scattered
// within relative tolerances and its start within a disc in (y_m, y_m'), by a seeded, shifted Halton
// sequence (reproducible on any machine); the map holds the fractions of motion types per point and
// their Monte-Carlo standard errors. Samples are the point's items (the `ic` slot), so they run in lanes.
struct RobustnessConfig {
  int samples = 0;  // 0 = off
  uint64_t seed = 1;
  // Term models (model = "terms"): each sample's parameters drawn from N(θ, Σ) with the fit's covariance Σ
  // ([terms] covariance), correlated as fitted (ApplyCovarianceSample), instead of independent tolerances.
  bool covariance = false;
  std::map<std::string, double> tolerance;  // parameter -> relative half-width (x (1 + tol (2u - 1)))
  double ic_radius = 0;                     // radius of the start disc in (y_m, y_m'), delta_s
  bool enabled() const { return samples > 0; }
};

// Adaptive maps (issue 17; engine/refine.h): the axes give the finest grid; the sweep first computes
// the coarse grid of every 2^levels-th value along each axis, then splits only the cells whose corners
// disagree on `criterion`, level by level, down to the finest spacing. Cells that stay mixed in every
// child for `mixed_after` levels in a row (chaotic speckle, not a boundary line) stop refining and are
// marked chaotic-mixed. The map is stored at the finest grid with refine_level / refine_fill datasets.
enum class RefineCriterion { kFrf0db, kMotion, kLleSign, kPeriod };
struct RefineConfig {
  int levels = 0;  // 0 = off
  RefineCriterion criterion = RefineCriterion::kMotion;
  int mixed_after = 2;  // 0 = never stop refining a mixed region
  bool enabled() const { return levels > 0; }
};
const char* RefineCriterionName(RefineCriterion c);  // "frf_0db", "motion", "lle_sign", "period"

// Sample k (0-based) of a robustness map applied to a point: each toleranced parameter times
// 1 + tol (2u − 1), the start moved within the disc of radius ic_radius (uniform in area); u from a
// seeded, shifted Halton sequence, one coordinate per toleranced parameter (canonical order), two for the disc.
void ApplyRobustnessSample(const RobustnessConfig& r, int k, PointSpec* p);
// Sample k of a covariance robustness map of a term model: p->theta (the point's parameters, axes applied)
// plus L z, L the Cholesky factor of the covariance (eigenvalues clipped at 0 when it is not positive
// definite) and z standard normal by Box–Muller from a seeded counter generator (splitmix64 of seed, k, and
// the coordinate): reproducible on any machine with the same libm; then the start disc as above.
void ApplyCovarianceSample(const TermsConfig& t, const RobustnessConfig& r, int k, PointSpec* p);

// Axis names in the canonical order used for enumeration and for the map datasets.
const std::vector<std::string>& CanonicalAxisNames();
// Axes over the start state (y_m, y_m', y_r, y_r')(0): basin maps. Unswept components come from the one
// [initial_conditions] state, or the model's default start.
const std::vector<std::string>& InitialStateAxisNames();
bool IsInitialStateAxis(const std::string& name);
const std::vector<std::string>& DimensionalAxisNames();  // a0_mm, f0_hz
// The unit of a parameter or axis by name ("alpha" → "A0/delta_s", "k_lin" → "N/m"; "" for an unknown name):
// the one table of parameter units, used by axes, fixed parameters, plots, the wire and the dashboard.
std::string AxisUnit(const std::string& name);
// What the quantity behind an axis or parameter name is, in words, for map metadata (CF long_name).
std::string AxisLongName(const std::string& name);

// A model parameter held fixed in a sweep (not one of its axes): what a map file records as a scalar
// coordinate. unit is AxisUnit's form ("A0/delta_s", "kg", "N/m").
struct FixedParameter {
  std::string name;
  double value;
  std::string unit, long_name;
};

// One unit of work in a sweep: a grid point with one of its initial conditions.
struct WorkItem {
  long point = 0;  // row-major grid index
  int ic = 0;      // the item's slot at its point: an initial state, a continuation direction or a tolerance
                   // sample — what it is, is the sweep kind's (engine/sweep_kind.h: SweepKind::Dimension)
};

struct SweepSpec {
  std::string name;                       // free text, for humans
  ModelKind model = ModelKind::kCoupled;  // any of the six; base.model is the cell a point runs (for
                                          // series and dimensional sweeps the cell proxy that classifies motion)
  SeriesConfig series;
  DimensionalConfig dimensional;
  std::optional<TermsConfig> terms;  // model = "terms" (then model is kDimensional: SI points, rig metrics)
  ContinuationConfig continuation;
  RobustnessConfig robustness;
  RefineConfig refine;
  PointSpec base;                                     // fixed parameters and settings; alpha/omega used when not swept
  std::vector<Axis> axes;                             // in canonical order, only the swept ones
  std::vector<std::array<double, 4>> initial_states;  // empty: the model's default start
  std::vector<std::string> metrics;                   // stored metrics (names from MetricCatalog)
  std::vector<std::string> plots;                     // metrics rendered after `bistable run`
  std::string source;                                 // the TOML text as given (stored with the maps)
  std::string canonical_hash;  // ContentHashHex(CanonicalText()), set by ParseSweepSpec ("" = compute)

  long points() const;  // product of axis lengths (1 with no axes)
  // Item slots per point (a WorkItem's `ic`): what a slot is — an initial state, a continuation direction,
  // a tolerance sample — is the sweep kind's (engine/sweep_kind.h: KindOf(spec).Slots, .Dimension).
  int ic_count() const;
  // With continuation: whether item slot ic sweeps downward (the chains are the kind's: SweepKind::Chains).
  bool ChainGoesDown(int ic) const { return continuation.enabled() && (!continuation.up || ic == 1); }
  // Canonical text of everything that determines the numbers (not name/plots/source): its hash is the sweep id.
  std::string CanonicalText() const;
  std::string Id() const;  // 12 hex digits of the canonical text's hash
  bool HasInitialStateAxes() const;
  // Every axis is an initial-state axis: the map is a basin map (attractor ids, fractions; map_file).
  bool IsBasinSweep() const;
  // The point spec of grid point `index` (row-major over axes, last axis fastest), item slot ic: the
  // kind's (SweepKind::PointAt).
  PointSpec PointAt(long index, int ic) const;
  // Axis indices of a point.
  std::vector<int> AxisIndices(long index) const;

  // True when items run through the SIMD ensemble kernel (cell models with RK4).
  bool UsesKernel() const { return IsCellModel(model) && base.integration.integrator == IntegratorKind::kRk4; }
  // True when items run through the lane kernels of series chains and the rig: RK4 (ensemble_generic.h)
  // or, for the rig, ROS34PW2 (ensemble_rosenbrock.h).
  bool UsesGenericLanes() const {
    return !IsCellModel(model) && (base.integration.integrator == IntegratorKind::kRk4 ||
                                   base.integration.integrator == IntegratorKind::kRosenbrock);
  }
  // Content key of an item: model configuration, parameters, settings, initial state, numerics version
  // (the kind's: SweepKind::ItemKey).
  std::string ItemKey(long index, int ic) const;
  // The canonical lines of the model's configuration (series cells, the rig's table; "" for cell models).
  std::string ModelConfigText() const;
  // The cells of a series chain at a point: [params] and the axis values for all, then each cell's overrides.
  std::vector<SeriesCell> SeriesCells(const PointSpec& p) const;
  // Display name of the model ("coupled", "series", "dimensional", "terms").
  std::string ModelLabel() const;
  // Where a named parameter or axis lives in a point: the PointSpec field, or a term model's parameter in
  // p.theta; nullptr for a name the model does not have.
  double* Slot(PointSpec& p, const std::string& name) const;
  // AxisUnit / AxisLongName, and a term model's parameters (their library units and meanings).
  std::string UnitOf(const std::string& name) const;
  std::string LongNameOf(const std::string& name) const;
  // The drive of a dimensional point in SI.
  RigDrive DriveAt(const PointSpec& p) const;
  // RK4 substeps per dt of a term-model sweep (1 otherwise): the stiffest parameter set it holds — nominal, each
  // swept parameter at its axis's ends, ±4σ with covariance samples — by TermRk4Substeps. One count for the sweep,
  // so a lane's bits do not depend on its neighbours; at most limits::kMaxRk4Substeps (the spec is refused beyond).
  int TermSubsteps() const;
  // The model's scalar parameters that no axis sweeps, in canonical order: the non-dimensional ones
  // of cell and series models (eps only for bistable cells), the rig's table for the dimensional model.
  std::vector<FixedParameter> FixedParameters() const;
};

// Parses and validates. `origin` names the source in messages (a file name).
StatusOr<SweepSpec> ParseSweepSpec(const std::string& toml_text, const std::string& origin);
StatusOr<SweepSpec> LoadSweepSpec(const std::string& path);

}  // namespace bistable

#endif  // BISTABLE_ENGINE_SWEEP_SPEC_H_
