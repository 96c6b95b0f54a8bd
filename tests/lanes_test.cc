// Series chains and the dimensional rig in lanes (dynamics/ensemble_generic.h): a sweep's record of a
// point has the bits of the same point evaluated alone (EvaluateItem, the lane kernel at width 1) at
// every lane width and lane position, and the lane models agree with the independent per-point
// implementations (SeriesModel with its Jacobian, Dormand–Prince on DimensionalModel).
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <set>
#include <sstream>
#include <string>
#include <tuple>
#include <vector>

#include <gtest/gtest.h>

#include "base/cpus.h"
#include "dynamics/cancel.h"
#include "dynamics/dopri5.h"
#include "dynamics/ensemble_generic.h"
#include "dynamics/ensemble_rosenbrock.h"
#include "dynamics/friction.h"
#include "dynamics/generic_point.h"
#include "dynamics/host_lanes.h"
#include "dynamics/point.h"
#include "engine/evaluate.h"
#include "engine/sweep_spec.h"
#include "tests/spec_fixture.h"

namespace bistable {
namespace {

SweepSpec Parse(const std::string& toml) { return bistable_test::ParsedSpec(toml, "lanes_test.toml"); }

bool SameBits(const PointRecord& a, const PointRecord& b) {
  return a.v.size() == b.v.size() && std::memcmp(a.v.data(), b.v.data(), a.v.size() * sizeof(double)) == 0;
}

// Every item of the sweep, in an order that puts each point at another lane position at every width
// and leaves the last block partly filled.
std::vector<WorkItem> ShuffledItems(const SweepSpec& spec) {
  std::vector<WorkItem> items;
  const long n = spec.points();
  for (long i = 0; i < n; ++i) items.push_back({(i * 7 + 3) % n, 0});
  return items;
}

// The sweep at widths 1, 4 and 8, and through ComputeItems (the path of `bistable run` and workers),
// against each item evaluated alone.
void ExpectLanesEqualOnePointPath(const SweepSpec& spec) {
  ASSERT_TRUE(spec.UsesGenericLanes());
  const std::vector<WorkItem> items = ShuffledItems(spec);
  std::vector<PointRecord> alone;
  for (const WorkItem& it : items) alone.push_back(PointRecord::From(EvaluateItem(spec, it.point, it.ic)));
  int finite_lle = 0;
  for (const PointRecord& r : alone) finite_lle += std::isfinite(r.Get("lle"));
  EXPECT_EQ(finite_lle, static_cast<int>(items.size()));  // real results, not NaN = NaN
  for (int width : {1, 4, 8}) {
    auto lanes = EvaluateItemsInLanes(spec, items, width);
    ASSERT_TRUE(lanes.has_value());
    for (size_t i = 0; i < items.size(); ++i)
      EXPECT_TRUE(SameBits(PointRecord::From((*lanes)[i]), alone[i]))
          << "width " << width << " point " << items[i].point;
  }
  const std::vector<PointRecord> sweep = ComputeItems(spec, items);
  ASSERT_EQ(sweep.size(), items.size());
  for (size_t i = 0; i < items.size(); ++i) EXPECT_TRUE(SameBits(sweep[i], alone[i])) << "point " << items[i].point;
}

TEST(SeriesLanes, SweepRecordsHaveTheBitsOfOnePointAtAnyLaneWidth) {
  // Two cells with resonators (state 8), a grid with periodic and chaotic points.
  ExpectLanesEqualOnePointPath(Parse(R"(
model = "series"
[series]
cells = 2
[axes]
alpha = [0.2, 0.8, 1.5]
omega = [0.5, 0.9, 1.2, 1.6]
[integration]
t_end = 40.0
t_keep = 20.0
)"));
}

TEST(SeriesLanes, LongAndLinearChainsHaveTheBitsOfOnePoint) {
  // Five cells take the run-time layout; linear links without resonators the other model variant;
  // a swept per-lane coefficient (eta) checks that cells are loaded per lane.
  ExpectLanesEqualOnePointPath(Parse(R"(
model = "series"
[series]
cells = 5
cell = [{}, {lambda = 0.9}]
[axes]
alpha = [0.3, 1.1]
eta = [0.05, 0.1, 0.2]
[integration]
t_end = 30.0
t_keep = 15.0
)"));
  ExpectLanesEqualOnePointPath(Parse(R"(
model = "series"
[series]
cells = 3
resonators = false
bistable = false
[axes]
omega = [0.4, 0.8, 1.3, 1.7, 2.1]
[integration]
t_end = 30.0
t_keep = 15.0
)"));
}

// A 3 × 3 rig sweep from sticking (small A0) to sliding, in lanes with `integrator` (RK4 unless said);
// `dimensional` is its [dimensional] table's lines.
SweepSpec RigSweep(const std::string& dimensional, const std::string& integrator = "rk4") {
  return Parse(R"(
model = "dimensional"
[dimensional]
)" + dimensional +
               R"(
[axes]
a0_mm = [0.5, 3.0, 10.0]
f0_hz = [2.0, 3.5, 6.0]
[integration]
integrator = ")" +
               integrator + R"("
t_end = 1.0
t_keep = 0.5
dt = 0.001
)");
}

TEST(DimensionalLanes, SweepRecordsHaveTheBitsOfOnePointAtAnyLaneWidth) {
  // Table 2 rig with friction: sticking and sliding points side by side.
  ExpectLanesEqualOnePointPath(RigSweep(""));
}

// The same with a frictionless main mass (its law skipped) and the resonator's friction kept.
TEST(DimensionalLanes, FrictionlessMainMassHasTheBitsOfOnePointAtAnyLaneWidth) {
  const SweepSpec spec = RigSweep("fs_m = 0.0\nfc_m = 0.0");
  EXPECT_TRUE(Stribeck::Lanes(spec.dimensional.params.fric_m).off);
  EXPECT_FALSE(Stribeck::Lanes(spec.dimensional.params.fric_r).off);
  ExpectLanesEqualOnePointPath(spec);
}

// The lane model of a chain against SeriesModel (Eigen, its own Jacobian) through the generic RK4
// path: the same RK4 steps of the same equations, so the same orbit to rounding on periodic points.
TEST(SeriesLanes, AgreeWithTheEigenModelThroughTheGenericPath) {
  const SweepSpec spec = Parse(R"(
model = "series"
[series]
cells = 3
cell = [{eta = 0.15}, {}, {lambda = 0.9}]
[axes]
alpha = [0.1, 0.3]
omega = [0.4, 1.4]
[integration]
t_end = 100.0
t_keep = 50.0
)");
  for (long p = 0; p < spec.points(); ++p) {
    const PointResult lanes = EvaluateItem(spec, p, 0);
    const PointSpec ps = spec.PointAt(p, 0);
    SeriesModel m(spec.SeriesCells(ps), ps.alpha, ps.omega);
    GenericWindow w;
    w.t_end = ps.integration.t_end;
    w.t_keep = ps.integration.t_keep;
    w.dt = ps.integration.dt;
    w.amp = ps.alpha;
    w.omega = ps.omega;
    const int yl = m.MainIndex(2), yp = m.MainIndex(1);
    w.position = [=](const Eigen::VectorXd& x) { return x[yl] - x[yp]; };
    w.velocity = [=](const Eigen::VectorXd& x) { return x[yl + 1]; };
    PointSpec proxy = ps;
    proxy.model = ModelKind::kStandalone;
    const PointResult eigen = ComputePointMetrics(RunGenericWindow(m, m.WellState(), w), proxy);
    ASSERT_EQ(eigen.termination, Termination::kOk);
    EXPECT_NEAR(lanes.frf_db, eigen.frf_db, 1e-6) << p;
    EXPECT_NEAR(lanes.y_min, eigen.y_min, 1e-8) << p;
    EXPECT_NEAR(lanes.y_max, eigen.y_max, 1e-8) << p;
    // The tangents start along different directions; over a 50-τ window the estimates agree to ~1e-2.
    EXPECT_NEAR(lanes.lle, eigen.lle, 0.02) << p;
    EXPECT_EQ(lanes.motion, eigen.motion) << p;
  }
}

// The rig in lanes (fixed-step RK4, substeps set by the stiffness) against the default per-point
// Dormand–Prince (rtol 1e-8) on the same points: sticking and sliding.
TEST(DimensionalLanes, FixedStepAgreesWithDormandPrince) {
  const std::string grid = R"(
model = "dimensional"
[axes]
a0_mm = [1.0, 10.0]
f0_hz = [3.0, 5.0]
[integration]
t_end = 3.0
t_keep = 1.5
dt = 0.001
rtol = 1e-8
atol = 1e-11
)";
  const SweepSpec rk4 = Parse(grid + "integrator = \"rk4\"\n");
  const SweepSpec dp5 = Parse(grid + "integrator = \"adaptive\"\n");
  ASSERT_TRUE(rk4.UsesGenericLanes());
  ASSERT_FALSE(dp5.UsesGenericLanes());
  EXPECT_NE(rk4.ItemKey(0, 0), dp5.ItemKey(0, 0));
  for (long p = 0; p < rk4.points(); ++p) {
    const PointResult a = EvaluateItem(rk4, p, 0), b = EvaluateItem(dp5, p, 0);
    ASSERT_EQ(a.termination, Termination::kOk);
    ASSERT_EQ(b.termination, Termination::kOk);
    EXPECT_NEAR(a.frf_db, b.frf_db, 1e-3) << p;  // measured ≤ 6e-6 dB
    EXPECT_NEAR(a.y_max, b.y_max, 1e-6) << p;    // m; measured ≤ 2e-7 m
    EXPECT_NEAR(a.y_min, b.y_min, 1e-6) << p;
    EXPECT_EQ(a.motion, b.motion) << p;
  }
}

// The stiffness sets the step: substeps grow as the friction law stiffens (smaller v_t) and as dt grows.
TEST(DimensionalLanes, SubstepsFollowTheStiffness) {
  DimensionalParams p = DimensionalParams::BistableTable2();
  const int base = Rk4Substeps(p, 1e-3);
  EXPECT_GE(base, 2);  // ≈ 10³ N s/m friction slope on a 0.28 kg mass: h ≈ 1/3000 s at most
  EXPECT_GE(Rk4Substeps(p, 2e-3), 2 * base - 1);
  DimensionalParams stiff = p;
  stiff.fric_m.v_t = stiff.fric_r.v_t = 0.0002;
  EXPECT_GT(Rk4Substeps(stiff, 1e-3), base);
  DimensionalParams smooth = p;
  smooth.fric_m = smooth.fric_r = Stribeck{0, 0};
  EXPECT_EQ(Rk4Substeps(smooth, 1e-4), 1);
}

// The law in lanes (Stribeck::Lanes: the project's exp and tanh): a lane's force and slope have the
// bits of the same velocity at width 1, whatever its neighbours, and agree with the per-point law
// (glibc) to rounding.
TEST(DimensionalLanes, FrictionForceAndSlopeInLanesHaveTheBitsOfWidthOne) {
  const Stribeck f{1.2, 0.44};
  const Stribeck::Lanes fl(f);
  for (double v0 = -0.2; v0 <= 0.2; v0 += 0.000731) {
    Vec<8> v, force, slope;
    for (int l = 0; l < 8; ++l) v[l] = v0 * (1.0 + 0.37 * l);  // sticking to sliding across the lanes
    fl.ForceSlope<8>(v, &force, &slope);
    for (int l = 0; l < 8; ++l) {
      Vec<1> v1, force1, slope1;
      v1[0] = v[l];
      fl.ForceSlope<1>(v1, &force1, &slope1);
      const double lane_force = force[l], lane_slope = slope[l], alone_force = force1[0], alone_slope = slope1[0];
      EXPECT_EQ(std::memcmp(&lane_force, &alone_force, sizeof lane_force), 0) << v[l];
      EXPECT_EQ(std::memcmp(&lane_slope, &alone_slope, sizeof lane_slope), 0) << v[l];
      EXPECT_NEAR(lane_force, f.Force(v[l]), 1e-14 * (1 + std::fabs(f.Force(v[l])))) << v[l];
      EXPECT_NEAR(lane_slope, f.Slope(v[l]), 1e-12 * (1 + std::fabs(f.Slope(v[l])))) << v[l];
    }
  }
}

// A body without friction (F_s = F_c = +0) skips the law (no exp, no tanh) and keeps its bits: force
// and slope equal the law's own operations at every velocity, signed zeros and subnormals included;
// a non-finite velocity gives NaN both ways. A −0 force keeps the law.
TEST(DimensionalLanes, FrictionlessBodySkipsTheLawWithItsBits) {
  std::vector<double> vs = {0.0,    -0.0,  4.9e-324, -4.9e-324, 2.2e-308, -2.2e-308, 1e-300, -1e-300, 1e150,
                            -1e150, 1e152, -1e152,   1e300,     -1e300,   1e307,     -1e307, 1.7e308};
  for (double v = -0.3; v <= 0.3; v += 0.000617) vs.push_back(v);
  for (const Stribeck f : {Stribeck{0, 0}, Stribeck{0, 0, 0.01, 0.0003}, Stribeck{-0.0, 0}, Stribeck{0, -0.0}}) {
    const Stribeck::Lanes fl(f);
    EXPECT_EQ(fl.off, !std::signbit(f.f_s) && !std::signbit(f.f_c));
    for (double v0 : vs) {
      Vec<8> v, force, slope, law_force, law_slope;
      for (int l = 0; l < 8; ++l) v[l] = l % 2 ? -v0 : v0 * (1.0 + 0.37 * l);
      fl.ForceSlope<8>(v, &force, &slope);
      fl.Law<8>(v, &law_force, &law_slope);
      for (int l = 0; l < 8; ++l) {
        const double a[2] = {force[l], slope[l]}, b[2] = {law_force[l], law_slope[l]};
        if (std::isnan(b[1])) {  // |v| past the hump exponent's overflow: NaN both ways
          EXPECT_TRUE(std::isnan(a[1])) << "v = " << v[l];
          EXPECT_EQ(std::memcmp(a, b, sizeof a[0]), 0) << "v = " << v[l];
          continue;
        }
        EXPECT_EQ(std::memcmp(a, b, sizeof a), 0) << "v = " << v[l] << ": " << a[0] << " " << a[1];
      }
    }
    Vec<4> v, force, slope, law_force, law_slope;
    v[0] = INFINITY, v[1] = -INFINITY, v[2] = NAN, v[3] = -NAN;
    fl.ForceSlope<4>(v, &force, &slope);
    fl.Law<4>(v, &law_force, &law_slope);
    for (int l = 0; l < 4; ++l) {
      EXPECT_TRUE(std::isnan(force[l]) && std::isnan(slope[l])) << v[l];
      EXPECT_TRUE(std::isnan(law_force[l]) && std::isnan(law_slope[l])) << v[l];
    }
  }
  // The skip is taken only without friction.
  EXPECT_FALSE(Stribeck::Lanes(Stribeck{1e-300, 0}).off);
  EXPECT_FALSE(Stribeck::Lanes(Stribeck{0, 0.44}).off);
}

// The hump's exp skips libm below its underflow: the same bits as std::exp everywhere, also across
// the threshold and the subnormal band above it.
TEST(DimensionalLanes, HumpExpHasTheBitsOfStdExp) {
  for (double u = 0; u < 60; u += 0.0037) {
    const double mine = HumpExp(u), libm = std::exp(0.5 - 0.5 * u * u);
    EXPECT_EQ(std::memcmp(&mine, &libm, sizeof mine), 0) << u;
  }
}

// The call-free loop of ordinary steps (RunFast) and the general loop body give the same bits: a
// trace (keep_rows) takes the general loop at every step.
template <class Input, class RunFn>
void ExpectFastLoopEqualsGeneralLoop(const std::vector<Input>& in, KernelSettings ks, RunFn run) {
  std::vector<RawLane> fast(8), general(8);
  ks.keep_samples = true;
  ks.keep_rows = false;
  ASSERT_TRUE(run(in.data(), ks, fast.data()));
  ks.keep_rows = true;
  ASSERT_TRUE(run(in.data(), ks, general.data()));
  auto same = [](const auto& a, const auto& b) {
    return a.size() == b.size() && std::memcmp(a.data(), b.data(), a.size() * sizeof(a[0])) == 0;
  };
  for (int l = 0; l < 8; ++l) {
    const RawLane &f = fast[l], &g = general[l];
    EXPECT_EQ(std::memcmp(&f.vabs_max, &g.vabs_max, sizeof(double)), 0) << l;
    EXPECT_EQ(std::memcmp(&f.y_min, &g.y_min, sizeof(double)), 0) << l;
    EXPECT_EQ(std::memcmp(&f.y_max, &g.y_max, sizeof(double)), 0) << l;
    EXPECT_EQ(std::memcmp(&f.log_growth, &g.log_growth, sizeof(double)), 0) << l;
    EXPECT_TRUE(same(f.strobe_y, g.strobe_y) && same(f.strobe_v, g.strobe_v)) << l;
    EXPECT_TRUE(same(f.y_samples, g.y_samples)) << l;
    EXPECT_TRUE(same(f.turning_points, g.turning_points)) << l;
    EXPECT_FALSE(f.strobe_y.empty());
    EXPECT_FALSE(f.turning_points.empty());
  }
}

TEST(DimensionalLanes, FastLoopHasTheBitsOfTheGeneralLoop) {
  const DimensionalParams p = DimensionalParams::BistableTable2();
  std::vector<DimensionalLaneInput> in(8);
  for (int l = 0; l < 8; ++l) {
    in[l].params = p;
    in[l].base_amp = (0.5 + 1.5 * l) * 1e-3;
    in[l].omega = 2 * M_PI * (2.0 + 0.5 * l);
    in[l].amp = in[l].base_amp * in[l].omega * in[l].omega;
    in[l].x0[0] = std::sqrt(-p.k_lin / p.k3);
  }
  KernelSettings ks;
  ks.h = 1e-3, ks.n_total = 1500, ks.n_keep = 700;
  const int substeps = Rk4Substeps(p, ks.h);
  ExpectFastLoopEqualsGeneralLoop(in, ks, [&](const DimensionalLaneInput* i, const KernelSettings& k, RawLane* o) {
    return RunDimensionalLanes<8>(i, 8, k, substeps, o);
  });
}

TEST(SeriesLanes, FastLoopHasTheBitsOfTheGeneralLoop) {
  std::vector<SeriesLaneInput> in(8);
  for (int l = 0; l < 8; ++l) {
    in[l].cells.assign(2, SeriesCell{});
    in[l].omega = 0.5 + 0.1 * l;
    in[l].base_amp = 1.0;
    in[l].amp = in[l].omega * in[l].omega;
    const Eigen::VectorXd x0 = SeriesModel(in[l].cells, 1.0, in[l].omega).WellState();
    in[l].x0.assign(x0.data(), x0.data() + x0.size());
  }
  KernelSettings ks;
  ks.h = 0.01, ks.n_total = 6000, ks.n_keep = 2500;  // past several re-anchorings
  ExpectFastLoopEqualsGeneralLoop(in, ks, [](const SeriesLaneInput* i, const KernelSettings& k, RawLane* o) {
    return RunSeriesLanes<8>(i, 8, k, o);
  });
}

TEST(DimensionalLanes, CancelledRunHasNoResult) {
  const SweepSpec spec = Parse(R"(
model = "dimensional"
[axes]
a0_mm = [1.0, 2.0]
[integration]
integrator = "rk4"
t_end = 1.0
t_keep = 0.5
)");
  ScopedCancelReset reset;
  RequestCancel();
  EXPECT_FALSE(EvaluateItemsInLanes(spec, ShuffledItems(spec), 8).has_value());
  EXPECT_FALSE(ComputeItemsUnlessCancelled(spec, ShuffledItems(spec)).has_value());
}

// ---- The rig with ROS34PW2 in lanes (integrator = "rosenbrock", dynamics/ensemble_rosenbrock.h) ----

// A 3 × 3 rig map from sticking (small A0) to sliding with the linearly implicit lanes: 9 items, so at
// widths 4 and 8 lanes take further items as theirs finish.
SweepSpec RosenbrockRigSweep(const std::string& dimensional) { return RigSweep(dimensional, "rosenbrock"); }

// map == point at every width and lane position, for the Table 2 rig, a frictionless main mass (its
// law and curvature skipped) and the rig without a resonator.
TEST(RosenbrockLanes, MapRecordsHaveTheBitsOfOnePointAtAnyLaneWidth) {
  ExpectLanesEqualOnePointPath(RosenbrockRigSweep(""));
  ExpectLanesEqualOnePointPath(RosenbrockRigSweep("fs_m = 0\nfc_m = 0"));
  ExpectLanesEqualOnePointPath(RosenbrockRigSweep("resonator = false"));
}

// The spec: "rosenbrock" is the rig's, with its own default rtol (5e-6) unless one is given, its own
// content key, and f0 within the stage polynomials' range (2π f0 dt ≤ 0.8).
TEST(RosenbrockLanes, SpecDefaultsKeysAndLimits) {
  const SweepSpec ros = RosenbrockRigSweep("");
  EXPECT_TRUE(ros.UsesGenericLanes());
  EXPECT_EQ(ros.base.integration.integrator, IntegratorKind::kRosenbrock);
  EXPECT_EQ(ros.base.integration.rtol, 5e-6);
  const SweepSpec rk4 = RigSweep("");
  EXPECT_NE(ros.ItemKey(0, 0), rk4.ItemKey(0, 0));
  auto given = ParseSweepSpec(R"(
model = "dimensional"
[axes]
a0_mm = [1.0]
[integration]
integrator = "rosenbrock"
rtol = 1e-7
)",
                              "t.toml");
  ASSERT_TRUE(given.ok()) << given.status().ToString();
  EXPECT_EQ(given->base.integration.rtol, 1e-7);
  auto cell = ParseSweepSpec("model = \"coupled\"\n[axes]\nomega = [1.0]\n[integration]\nintegrator = \"rosenbrock\"\n",
                             "t.toml");
  ASSERT_FALSE(cell.ok());
  EXPECT_EQ(cell.status().field(), "integration.integrator") << cell.status().ToString();
  auto fast = ParseSweepSpec(R"(
model = "dimensional"
[axes]
f0_hz = [10.0, 150.0]
[integration]
integrator = "rosenbrock"
)",
                             "t.toml");
  ASSERT_FALSE(fast.ok());
  EXPECT_EQ(fast.status().field(), "axes.f0_hz[1]") << fast.status().ToString();
  PointSpec point;
  point.integration.integrator = IntegratorKind::kRosenbrock;
  EXPECT_FALSE(EvaluatePoint(point).ok());  // the cell models' points: rk4 or adaptive
  // Numerics 1.5.0: the rig's default is ROS34PW2 at rtol 5e-6 (with or without an [integration] table);
  // Dormand–Prince, asked for, keeps its rtol 1e-6; the f0 bound names the way out.
  const std::string rig = "model = \"dimensional\"\n[axes]\na0_mm = [1.0]\n[integration]\nt_end = 20.0\n";
  const SweepSpec named = Parse(rig + "integrator = \"rosenbrock\"\n");
  for (const std::string& text : {std::string("model = \"dimensional\"\n[axes]\na0_mm = [1.0]\n"), rig}) {
    const SweepSpec d = Parse(text);
    EXPECT_EQ(d.base.integration.integrator, IntegratorKind::kRosenbrock) << text;
    EXPECT_EQ(d.base.integration.rtol, 5e-6) << text;
    EXPECT_TRUE(d.UsesGenericLanes()) << text;
    EXPECT_EQ(d.ItemKey(0, 0), named.ItemKey(0, 0)) << "the default is the rosenbrock path, keys and all";
  }
  const SweepSpec dp5 =
      Parse("model = \"dimensional\"\n[axes]\na0_mm = [1.0]\n[integration]\nintegrator = \"adaptive\"\n");
  EXPECT_EQ(dp5.base.integration.rtol, 1e-6);
  EXPECT_FALSE(dp5.UsesGenericLanes());
  auto fast_default = ParseSweepSpec("model = \"dimensional\"\n[axes]\nf0_hz = [150.0]\n", "t.toml");
  ASSERT_FALSE(fast_default.ok());
  EXPECT_NE(fast_default.status().message().find("integrator = 'adaptive'"), std::string::npos)
      << fast_default.status().ToString();
}

// Fixed steps on a smooth problem (the rig without friction: cubic spring, c2 dampers, resonator):
// the state and the tangent converge at order 3 (Richardson: successive differences shrink by 2³).
TEST(RosenbrockLanes, ConvergesAtOrderThreeOnASmoothProblem) {
  DimensionalLaneInput in;
  in.params = DimensionalParams::BistableTable2();
  in.params.fric_m = in.params.fric_r = Stribeck{0, 0};
  in.base_amp = 5e-3;
  in.omega = 2 * M_PI * 6.0;
  in.amp = in.base_amp * in.omega * in.omega;
  in.x0 = {std::sqrt(-in.params.k_lin / in.params.k3), 0, 0, 0};
  KernelSettings ks;
  ks.h = 1e-3;
  ks.n_total = 400;
  ks.n_keep = 200;
  ks.renorm_every = 50;
  ks.sample_every = 5;
  std::vector<std::array<double, 8>> ends;
  for (int k : {1, 2, 4, 8, 16}) {
    RosenbrockTolerances tol;
    tol.fixed_step = ks.h / k;
    RawLane out;
    ASSERT_TRUE(RunDimensionalRosenbrock<1>(&in, 1, ks, tol, &out));
    ASSERT_FALSE(out.diverged);
    EXPECT_EQ(out.steps, 400L * k);
    std::array<double, 8> e;
    for (int d = 0; d < 4; ++d) e[d] = out.final_state[d], e[4 + d] = out.final_tangent[d];
    ends.push_back(e);
  }
  auto diff = [&](size_t i, int from, int to) {
    double m = 0;
    for (int d = from; d < to; ++d) m = std::max(m, std::fabs(ends[i][d] - ends[i + 1][d]) / (d % 2 ? 1.0 : 0.02));
    return m;  // positions over 20 mm, velocities (m/s) as they are
  };
  for (size_t i = 0; i + 2 < ends.size(); ++i) {
    const double order_x = std::log2(diff(i, 0, 4) / diff(i + 1, 0, 4));
    const double order_w = std::log2(diff(i, 4, 8) / diff(i + 1, 4, 8));
    std::printf("h = dt/%d: observed order %.3f (state), %.3f (tangent)\n", 1 << i, order_x, order_w);
    EXPECT_NEAR(order_x, 3.0, 0.3) << "h = dt/" << (1 << i);
    EXPECT_NEAR(order_w, 3.0, 0.3) << "h = dt/" << (1 << i);
  }
}

// Stick–slip (A0 1 mm at 10 Hz: both bodies stick and slip every period) against Dormand–Prince at
// rtol 1e-10 on DimensionalModel (the per-point model, glibc's exp and tanh): the state at 2 s.
TEST(RosenbrockLanes, StickSlipAgreesWithDormandPrince) {
  const DimensionalParams p = DimensionalParams::BistableTable2();
  DimensionalLaneInput in;
  in.params = p;
  in.base_amp = 1e-3;
  in.omega = 2 * M_PI * 10.0;
  in.amp = in.base_amp * in.omega * in.omega;
  in.x0 = {std::sqrt(-p.k_lin / p.k3), 0, 0, 0};
  KernelSettings ks;
  ks.h = 1e-3;
  ks.n_total = 2000;
  ks.n_keep = 1000;
  ks.renorm_every = 50;
  ks.sample_every = 5;
  AdaptiveOptions o;
  o.rtol = 1e-10;
  o.atol = 1e-13;
  const DimensionalModel model(p, SineBase(in.base_amp, 10.0));
  Dopri5<DimensionalModel> dp(model, o);
  DimensionalModel::State x;
  x << in.x0[0], 0, 0, 0;
  double slow_m = 0, slow_r = 0;  // time with |y'| and |z'| below v_t (1 mm/s) in the second second: sticking
  double t_prev = 0;
  ASSERT_EQ(dp.Integrate(0.0, x, 2.0,
                         [&](const Dopri5<DimensionalModel>& st) {
                           const double t = st.t(), dt = t - t_prev;
                           t_prev = t;
                           if (t < 1.0) return;
                           DimensionalModel::State xi;
                           st.Interpolate(t, xi);
                           if (std::fabs(xi[1]) < p.fric_m.v_t) slow_m += dt;
                           if (std::fabs(xi[3]) < p.fric_r.v_t) slow_r += dt;
                         }),
            OdeTermination::kOk);
  std::printf("time below v_t in [1, 2] s: main mass %.3f s, resonator %.3f s\n", slow_m, slow_r);
  EXPECT_GT(slow_m + slow_r, 0.02);
  // Measured: rtol 5e-6 |Δy| 6e-10 m, |Δy'| 2.4e-7 m/s; rtol 1e-8 |Δy| 1.1e-12 m, |Δy'| 1.8e-9 m/s.
  for (const auto& [rtol, tol_y, tol_v] : {std::tuple{5e-6, 1e-8, 3e-6}, std::tuple{1e-8, 5e-11, 2e-8}}) {
    RosenbrockTolerances tol;
    tol.rtol = rtol;
    RawLane out;
    ASSERT_TRUE(RunDimensionalRosenbrock<1>(&in, 1, ks, tol, &out));
    EXPECT_NEAR(out.final_state[0], x[0], tol_y) << rtol;
    EXPECT_NEAR(out.final_state[1], x[1], tol_v) << rtol;
    EXPECT_NEAR(out.final_state[2], x[2], tol_y) << rtol;
    EXPECT_NEAR(out.final_state[3], x[3], tol_v) << rtol;
    std::printf("rtol %g: |dy| %.2e m |dy'| %.2e m/s |dz| %.2e m |dz'| %.2e m/s, %ld steps\n", rtol,
                std::fabs(out.final_state[0] - x[0]), std::fabs(out.final_state[1] - x[1]),
                std::fabs(out.final_state[2] - x[2]), std::fabs(out.final_state[3] - x[3]), out.steps);
  }
}

// A point's metrics against the Dormand–Prince path at rtol 1e-10 (the issue's converged reference):
// sticking, stick–slip and sliding, intrawell and interwell.
TEST(RosenbrockLanes, MetricsAgreeWithTheConvergedReference) {
  const std::string grid = R"(
model = "dimensional"
[axes]
a0_mm = [1.0, 5.0, 15.0]
f0_hz = [3.0, 8.0]
[integration]
t_end = 4.0
t_keep = 2.0
dt = 0.001
)";
  const SweepSpec ros = Parse(grid + "integrator = \"rosenbrock\"\n");
  const SweepSpec ref = Parse(grid + "rtol = 1e-10\natol = 1e-13\n");
  for (long p = 0; p < ros.points(); ++p) {
    const PointResult a = EvaluateItem(ros, p, 0), b = EvaluateItem(ref, p, 0);
    ASSERT_EQ(a.termination, Termination::kOk);
    ASSERT_EQ(b.termination, Termination::kOk);
    EXPECT_NEAR(a.frf_db, b.frf_db, 0.01) << p;
    EXPECT_NEAR(a.y_max, b.y_max, 1e-5) << p;  // m
    EXPECT_NEAR(a.y_min, b.y_min, 1e-5) << p;
    EXPECT_NEAR(a.lle, b.lle, 0.05) << p;  // 1/s
    EXPECT_EQ(a.motion, b.motion) << p;
    EXPECT_EQ(a.period, b.period) << p;
  }
}

// The law's curvature (for the tangent's coupling block): force and slope with the bits of the law
// itself, and d²F/dv² against central differences of the slope.
TEST(RosenbrockLanes, FrictionCurvatureMatchesTheSlopesDifferences) {
  const Stribeck f{1.2, 0.44};
  const Stribeck::Lanes fl(f);
  for (double v0 = -0.02; v0 <= 0.02; v0 += 0.0000731) {
    Vec<4> v, force, slope, curv, lf, ls;
    for (int l = 0; l < 4; ++l) v[l] = v0 * (1.0 + 0.5 * l);
    fl.ForceSlopeCurvature<4>(v, &force, &slope, &curv);
    fl.Law<4>(v, &lf, &ls);
    for (int l = 0; l < 4; ++l) {
      const double a[2] = {force[l], slope[l]}, b[2] = {lf[l], ls[l]};
      EXPECT_EQ(std::memcmp(a, b, sizeof a), 0) << v[l];
      const double dv = 1e-7;
      const double fd = (f.Slope(v[l] + dv) - f.Slope(v[l] - dv)) / (2 * dv);
      EXPECT_NEAR(curv[l], fd, 1e-5 * (std::fabs(fd) + 1e3)) << v[l];
    }
  }
  Vec<1> v{0.01}, force, slope, curv;
  Stribeck::Lanes(Stribeck{0, 0}).ForceSlopeCurvature<1>(v, &force, &slope, &curv);
  EXPECT_EQ(curv[0], 0.0);
}

TEST(RosenbrockLanes, CancelledRunHasNoResult) {
  const SweepSpec spec = RosenbrockRigSweep("");
  ScopedCancelReset reset;
  RequestCancel();
  EXPECT_FALSE(EvaluateItemsInLanes(spec, ShuffledItems(spec), 8).has_value());
  EXPECT_FALSE(ComputeItemsUnlessCancelled(spec, ShuffledItems(spec)).has_value());
}

// The lanes every benchmark says and every map records (dynamics/host_lanes.h) are the engine's own, and
// the CPU's unit (cpuid) agrees with the flags the kernel lists in /proc/cpuinfo.
TEST(HostLanes, SayTheEnginesWidthAndTheCpusUnit) {
  const HostLanes h = ThisHostLanes();
  EXPECT_EQ(h.lanes, kSweepLanes);
  EXPECT_EQ(h.isa, kLaneIsa);
  EXPECT_EQ(h.lanes, h.isa == std::string("AVX-512") ? 8 : 4);
  EXPECT_FALSE(h.cpu_model.empty());
  std::ifstream f("/proc/cpuinfo");
  std::stringstream text;
  text << f.rdbuf();
  const std::string info = text.str();
  std::set<std::string> flags;  // the first CPU's "flags" line, word by word
  if (const size_t at = info.find("\nflags"); at != std::string::npos) {
    std::istringstream words(info.substr(at + 1, info.find('\n', at + 1) - at - 1));
    for (std::string w; words >> w;) flags.insert(w);
  }
  if (!flags.empty()) {
    const bool avx512 = flags.count("avx512f") > 0;
    const bool avx2_fma = flags.count("avx2") > 0 && flags.count("fma") > 0;
    EXPECT_EQ(h.cpu_isa, avx512 ? "AVX-512" : avx2_fma ? "AVX2+FMA" : "scalar");
    if (!avx512) {
      EXPECT_NE(h.lanes, 8) << "an AVX-512 build runs only on a CPU with AVX-512";
    }
  }
  const std::string model = CpuModelFromCpuinfo(info);
  if (!model.empty()) {
    EXPECT_EQ(h.cpu_model, model);
  }
  const std::string line = HostLanesLine(h);
  EXPECT_NE(line.find("cpu: " + h.cpu_model + " | isa: " + h.isa), std::string::npos) << line;
  EXPECT_NE(line.find("| lanes: " + std::to_string(kSweepLanes) + " (fixed at compile time: -march="),
            std::string::npos)
      << line;
}

TEST(HostLanes, LineSaysAWiderCpuAndTheCpuinfoNameIsTrimmed) {
  HostLanes h;
  h.cpu_model = "AMD EPYC 7R13 Processor";
  h.isa = "AVX2+FMA";
  h.cpu_isa = "AVX-512";
  h.march = "x86-64-v3";
  h.lanes = 4;
  EXPECT_EQ(HostLanesLine(h),
            "cpu: AMD EPYC 7R13 Processor | isa: AVX2+FMA (the CPU has AVX-512) | lanes: 4 (fixed at compile time: "
            "-march=x86-64-v3)");
  h.isa = h.cpu_isa = "AVX-512", h.march = "native", h.lanes = 8;
  EXPECT_EQ(HostLanesLine(h),
            "cpu: AMD EPYC 7R13 Processor | isa: AVX-512 | lanes: 8 (fixed at compile time: -march=native)");
  EXPECT_EQ(
      CpuModelFromCpuinfo("processor\t: 0\nvendor_id\t: AuthenticAMD\nmodel name\t: AMD EPYC 9R14 \r\nflags\t: fpu\n"),
      "AMD EPYC 9R14");
  EXPECT_EQ(CpuModelFromCpuinfo("processor\t: 0\nBogoMIPS\t: 50.00\n"), "");
}

}  // namespace
}  // namespace bistable
