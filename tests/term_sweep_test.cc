// Sweeps of term models (model = "terms", issue 42): the spec's [terms] table and its refusals, a report of
// `bistable identify` inlined by the client, parameter axes and covariance samples, and the paper's rig written
// as terms mapping the rig's labels.
#include <cmath>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <Eigen/Dense>

#include "client/terms_report.h"
#include "engine/evaluate.h"
#include "engine/sweep_kind.h"
#include "engine/sweep_spec.h"
#include "tests/spec_fixture.h"

namespace bistable {
namespace {

using bistable_test::ParsedSpec;

const std::string kRigTerms = R"(
model = "terms"
[terms]
list = ["main.linear", "main.stiffness_y3", "main.viscous", "main.damping_y2", "main.friction",
        "res.linear", "res.viscous", "res.damping_z2", "res.friction"]
theta = [-1135.7, 2.15e6, 1.5, 8.6e3, 1.2, 0.44, 636.6, 4.6, 38.7e3, 1.4, 0.59]
m_main = 0.282
m_res = 0.620
)";
const std::string kGrid = R"(
[axes]
a0_mm = [2.0, 6.0, 10.0, 14.0]
f0_hz = [1.5, 3.0, 4.5, 6.0, 7.5]
[integration]
t_end = 8.0
t_keep = 4.0
[metrics]
store = ["frf_db", "lle", "motion", "period"]
)";

std::vector<PointRecord> Map(const SweepSpec& spec) {
  std::vector<WorkItem> items;
  for (long p = 0; p < spec.points(); ++p) items.push_back({p, 0});
  return ComputeItems(spec, items);
}

TEST(TermSweep, ThePapersRigWrittenAsTermsMapsTheRigsLabels) {
  const SweepSpec terms = ParsedSpec(kRigTerms + kGrid);
  std::string grid = kGrid;  // the rig under the same integrator, RK4 in lanes at the same substeps
  grid.replace(grid.find("[integration]\n"), 14, "[integration]\nintegrator = \"rk4\"\n");
  const SweepSpec rig = ParsedSpec("model = \"dimensional\"\n" + grid);
  ASSERT_EQ(rig.points(), terms.points());
  EXPECT_EQ(terms.ModelLabel(), "terms");
  EXPECT_NE(terms.Id(), rig.Id());
  const auto a = Map(terms), b = Map(rig);
  const size_t motion = MetricIndex("motion"), lle = MetricIndex("lle"), frf = MetricIndex("frf_db");
  int regular = 0;
  for (size_t i = 0; i < a.size(); ++i) {
    EXPECT_EQ(a[i].Get(motion), b[i].Get(motion)) << i;
    if (a[i].Get(lle) < 0.01 && b[i].Get(lle) < 0.01) {  // regular: the two sums' rounding stays small
      ++regular;
      EXPECT_NEAR(a[i].Get(frf), b[i].Get(frf), 1e-6) << i;
    }
  }
  EXPECT_GT(regular, 10);
}

TEST(TermSweep, SpecErrorsNameTheField) {
  struct Case {
    std::string toml, field;
  } cases[] = {
      {"model = \"terms\"\n[terms]\nreport = \"fit/report.json\"\n", "terms.report"},
      {"model = \"terms\"\n[terms]\nlist = [\"main.linear\"]\ntheta = [1, 2]\nm_main = 1\n", "terms.theta"},
      {"model = \"terms\"\n[terms]\nlist = [\"main.linear\", \"main.stifness_y3\"]\ntheta = [1, 2]\nm_main = 1\n",
       "terms.list[1]"},
      {"model = \"terms\"\n[terms]\nlist = [\"main.linear\"]\ntheta = [1]\nm_main = 0\n", "terms.m_main"},
      {"model = \"terms\"\n[terms]\nlist = [\"main.linear\", \"main.viscous\"]\ntheta = [1, nan]\nm_main = 1\n",
       "terms.theta[1]"},
      {"model = \"terms\"\n[terms]\nlist = [\"main.linear\", \"main.viscous\"]\ntheta = [1, 1]\nm_main = 1\n"
       "covariance = [1, 0.5, 0.4, 1]\n",
       "terms.covariance"},
      {"model = \"terms\"\n[terms]\nlist = [\"main.linear\"]\ntheta = [1]\nm_main = 1\n[robustness]\nsamples = 4\n",
       "robustness.covariance"},
      {"model = \"terms\"\n[terms]\nlist = [\"main.linear\"]\ntheta = [1]\nm_main = 1\n[integration]\n"
       "integrator = \"rosenbrock\"\n",
       "integration.integrator"},
      {"model = \"terms\"\n[terms]\nlist = [\"main.linear\"]\ntheta = [1]\nm_main = 1\n[axes]\n"
       "\"main.viscous.c0\" = [1, 2]\n",
       "axes.main.viscous.c0"},
      {"model = \"coupled\"\n[terms]\nlist = [\"main.linear\"]\n", "terms"},
      {"model = \"coupled\"\n[robustness]\nsamples = 4\ncovariance = true\n", "robustness.covariance"},
      // A friction transition so fast that RK4 would take millions of steps per dt: refused, not run for days.
      {"model = \"terms\"\n[terms]\nlist = [\"main.linear\", \"main.friction\"]\ntheta = [100, 1, 1]\nm_main = 1\n"
       "v_t = 1e-12\n",
       "terms.theta"},
      {"model = \"dimensional\"\n[dimensional]\nv_t = 1e-12\n[integration]\nintegrator = \"rk4\"\n", "dimensional.v_t"},
  };
  for (const Case& c : cases) {
    auto s = ParseSweepSpec(c.toml, "t.toml");
    ASSERT_FALSE(s.ok()) << c.toml;
    EXPECT_EQ(s.status().field(), c.field) << s.status().ToString();
  }
}

TEST(TermSweep, AParameterAxisAndCovarianceSamplesReachThePoint) {
  const SweepSpec axis = ParsedSpec(kRigTerms + "[axes]\n\"main.viscous.c0\" = [1.0, 2.0]\nf0_hz = [3.0, 4.0]\n");
  EXPECT_EQ(axis.PointAt(0, 0).theta[2], 1.0);
  EXPECT_EQ(axis.PointAt(3, 0).theta[2], 2.0);
  EXPECT_EQ(axis.PointAt(3, 0).omega, 4.0);
  EXPECT_EQ(axis.UnitOf("main.viscous.c0"), "N s/m");
  EXPECT_NE(axis.ItemKey(0, 0), axis.ItemKey(2, 0));  // the parameter is in the key

  // Two correlated parameters: samples with the covariance's mean and correlation, the same bits every time.
  const SweepSpec cov = ParsedSpec(
      "model = \"terms\"\n[terms]\nlist = [\"main.linear\", \"main.stiffness_y3\", \"main.viscous\"]\n"
      "theta = [-1000, 2e6, 1.5]\nm_main = 0.3\ncovariance = [100, -1.6e4, 0, -1.6e4, 4e6, 0, 0, 0, 0.01]\n"
      "[robustness]\nsamples = 2000\ncovariance = true\n");
  ASSERT_STREQ(KindOf(cov).Name(), "robustness");
  Eigen::MatrixXd x(2000, 3);
  for (int k = 0; k < 2000; ++k) {
    const PointSpec p = cov.PointAt(0, k);
    for (int i = 0; i < 3; ++i) x(k, i) = p.theta[i];
  }
  EXPECT_EQ(cov.PointAt(0, 7).theta, cov.PointAt(0, 7).theta);
  EXPECT_NE(cov.ItemKey(0, 7), cov.ItemKey(0, 8));
  const Eigen::RowVectorXd mean = x.colwise().mean();
  const Eigen::MatrixXd c = (x.rowwise() - mean).transpose() * (x.rowwise() - mean) / 1999.0;
  EXPECT_NEAR(mean[0], -1000, 4 * 10 / std::sqrt(2000.0));
  EXPECT_NEAR(std::sqrt(c(0, 0)), 10, 0.5);
  EXPECT_NEAR(std::sqrt(c(1, 1)), 2000, 100);
  EXPECT_NEAR(c(0, 1) / std::sqrt(c(0, 0) * c(1, 1)), -0.8, 0.03);  // the fit's correlation, kept
  EXPECT_NEAR(std::sqrt(c(2, 2)), 0.1, 0.005);
}

// The paper's cells are term models (TermModel::FromCell): the coupled cell and the standalone beam, written as
// terms and swept at a0_mm = 1000 α, f0_hz = Ω/2π, give the cell kernel's labels and, where the motion is regular,
// its FRF (the same RK4 steps, the forces summed in another order) and its LLE to the estimators' difference. (This
// test found two faults: a term model without a resonator started its tangent on the resonator's dead components, so
// a regular orbit's LLE read 0 — the rig without a resonator too, under every integrator; and the wells were sought
// up to |q| = 1 m only, so a cell's well at 1 was missed and its lanes started at the saddle.)
TEST(TermSweep, ThePapersCellsWrittenAsTermsMapTheCellsNumbers) {
  for (ModelKind kind : {ModelKind::kCoupled, ModelKind::kStandalone}) {
    NondimParams p;  // the paper's defaults: ε 1, η 0.1, η_r 0.075, φ 2, λ 0.8
    auto m = TermModel::FromCell(kind, p);
    ASSERT_TRUE(m.ok()) << m.status().ToString();
    std::string list, theta;
    const auto names = m->ParamNames();
    for (size_t k = 0; k < m->terms.size(); ++k) {
      list += std::string(k ? ", " : "") + "\"" + m->terms[k]->id + "\"";
      theta += std::string(k ? ", " : "") + std::to_string(m->theta[k]);
    }
    const std::string integration =
        "[integration]\nt_end = 300.0\nt_keep = 100.0\ndt = 0.05\n[metrics]\nstore = [\"frf_db\", \"lle\", "
        "\"motion\"]\n";
    const SweepSpec cell = ParsedSpec("model = \"" + std::string(ModelName(kind)) +
                                      "\"\n[axes]\nalpha = [0.05, 0.3, 0.6]\nomega = [0.5, 0.9, 1.4]\n" + integration);
    const SweepSpec terms =
        ParsedSpec("model = \"terms\"\n[terms]\nlist = [" + list + "]\ntheta = [" + theta + "]\nm_main = 1.0\n" +
                   (m->m_res > 0 ? "m_res = " + std::to_string(m->m_res) + "\n" : "") +
                   "[axes]\na0_mm = [50.0, 300.0, 600.0]\nf0_hz = [" + std::to_string(0.5 / (2 * M_PI)) + ", " +
                   std::to_string(0.9 / (2 * M_PI)) + ", " + std::to_string(1.4 / (2 * M_PI)) + "]\n" + integration);
    ASSERT_EQ(terms.TermSubsteps(), 1);  // the cell's step
    const auto a = Map(cell), b = Map(terms);
    ASSERT_EQ(a.size(), b.size());
    const size_t motion = MetricIndex("motion"), lle = MetricIndex("lle"), frf = MetricIndex("frf_db");
    int regular = 0, labels = 0;
    for (size_t i = 0; i < a.size(); ++i) {
      labels += a[i].Get(motion) == b[i].Get(motion);
      if (a[i].Get(lle) < -0.005 && b[i].Get(lle) < -0.005) {  // clearly regular in both: the same orbit
        ++regular;
        EXPECT_NEAR(a[i].Get(frf), b[i].Get(frf), 0.01) << ModelName(kind) << " " << i;
        // The two kernels' LLE estimators differ in their renormalisation (every 50 steps, every output step):
        // finite-window estimates of the same exponent, measured 0.0002-0.0043 apart here.
        EXPECT_NEAR(a[i].Get(lle), b[i].Get(lle), 0.005) << ModelName(kind) << " " << i;
      }
    }
    EXPECT_GE(labels, 8) << ModelName(kind);  // of 9; a chaotic point's label may differ by rounding
    EXPECT_GE(regular, 4) << ModelName(kind);
  }
  EXPECT_FALSE(TermModel::FromCell(ModelKind::kSeries, NondimParams{}).ok());
}

// The rig without its resonator: a regular orbit's LLE is negative under each of the three integrators (its tangent
// starts on (y, y') only; it read exactly 0 while the dead resonator components held a floor under |w|), and the
// three agree on it.
TEST(TermSweep, TheRigWithoutItsResonatorHasANegativeLyapunovExponent) {
  double lle[3];
  int k = 0;
  for (const char* integrator : {"rk4", "rosenbrock", "adaptive"}) {
    const SweepSpec rig = ParsedSpec(std::string("model = \"dimensional\"\n[dimensional]\nresonator = false\n") +
                                     "[axes]\na0_mm = [2.0]\nf0_hz = [3.0]\n[integration]\nintegrator = \"" +
                                     integrator + "\"\nt_end = 20.0\nt_keep = 10.0\n[metrics]\nstore = [\"lle\"]\n");
    lle[k] = Map(rig)[0].Get(MetricIndex("lle"));
    EXPECT_LT(lle[k], -0.5) << integrator;
    ++k;
  }
  EXPECT_NEAR(lle[0], lle[2], 0.05 * std::fabs(lle[2]));
  EXPECT_NEAR(lle[1], lle[2], 0.05 * std::fabs(lle[2]));
}

// drive = "force" (a model fitted to a force input, e.g. Silverbox): F0 sin(ω t) on the main body, the base at
// rest. A linear oscillator's steady state is known: |v| = F0 ω / sqrt((k − m ω²)² + (c ω)²), and the FRF's scale
// is the free mass's displacement under F0 (F0/(m ω²)), so frf_db = 20 log10(m ω² / sqrt(...)). With a resonator
// on it (a tuned absorber at the drive frequency) the main body nearly stands still: the resonator feels the
// force through y''.
TEST(TermSweep, AForceDriveMovesTheMainBodyAsTheLinearOscillatorsAnswer) {
  const SweepSpec spec = ParsedSpec(R"(
model = "terms"
[terms]
list = ["main.linear", "main.viscous"]
theta = [400.0, 2.0]
m_main = 0.5
drive = "force"
[axes]
force0_n = [0.5, 2.0]
f0_hz = [2.0, 4.5, 7.0]
[integration]
t_end = 30.0
t_keep = 5.0
[metrics]
store = ["frf_db", "motion"]
)");
  ASSERT_EQ(spec.terms->DriveAxis(), std::string("force0_n"));
  const auto r = Map(spec);
  ASSERT_EQ(r.size(), 6u);
  const size_t frf = MetricIndex("frf_db");
  for (long p = 0; p < spec.points(); ++p) {
    const PointSpec pt = spec.PointAt(p, 0);
    const RigDrive d = spec.DriveAt(pt);
    EXPECT_EQ(d.force_n, pt.alpha);
    const double w = d.omega_rad_s, k = 400, c = 2, m = 0.5;
    const double want = 20 * std::log10(m * w * w / std::hypot(k - m * w * w, c * w));
    EXPECT_NEAR(r[p].Get(frf), want, 0.02) << "F0 " << pt.alpha << " N, f0 " << d.f0_hz << " Hz";
  }
  // The tuned absorber: k_r/m_r = k/m at f0 = sqrt(k/m)/2π; the main body's response drops by far.
  auto at_resonance = [](const std::string& terms) {
    return ParsedSpec("model = \"terms\"\n[terms]\n" + terms +
                      "m_main = 0.5\ndrive = \"force\"\n[axes]\nforce0_n = [1.0]\nf0_hz = [4.5016]\n"
                      "[integration]\nt_end = 60.0\nt_keep = 5.0\n[metrics]\nstore = [\"frf_db\"]\n");
  };
  const SweepSpec alone = at_resonance("list = [\"main.linear\", \"main.viscous\"]\ntheta = [400.0, 2.0]\n");
  const SweepSpec absorber = at_resonance(
      "list = [\"main.linear\", \"main.viscous\", \"res.linear\", \"res.viscous\"]\ntheta = [400.0, 2.0, 40.0, "
      "0.02]\nm_res = 0.05\n");
  EXPECT_LT(Map(absorber)[0].Get(frf), Map(alone)[0].Get(frf) - 20);
}

class TermsReport : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = std::filesystem::temp_directory_path() /
           ("terms_report_" + std::to_string(::testing::UnitTest::GetInstance()->random_seed()) + "_" +
            ::testing::UnitTest::GetInstance()->current_test_info()->name());
    std::filesystem::create_directories(dir_);
  }
  void TearDown() override { std::filesystem::remove_all(dir_); }
  // A result as `bistable identify --json` prints it: a beam fitted to a base acceleration with a velocity
  // offset per record and a sensor gain.
  std::string Report(const std::string& input = "base_acceleration", const std::string& extra_term = "") const {
    return R"({"final_terms": ["main.linear", "main.stiffness_y3", "main.viscous", "out.velocity.scale")" + extra_term +
           R"(],
      "params": {"main.linear.k_lin": -1100, "main.stiffness_y3.k3": 3.5e6, "main.viscous.c0": 0.5,
                 "out.velocity.scale.g": 0.01, "offset.0": 1e-4},
      "settings": {"input_kind": ")" +
           input + R"(", "m_main": 1.0, "m_res": 0.0, "v_sp": 0.002, "v_t": 0.001},
      "covariance": {"names": ["main.linear.k_lin", "main.stiffness_y3.k3", "main.viscous.c0", "out.velocity.scale.g",
                               "offset.0"],
                     "matrix": [[25, -100, 0, 0, 1], [-100.0000000001, 1e8, 0, 0, 0], [0, 0, 1e-4, 0, 0],
                                [0, 0, 0, 1, 0], [1, 0, 0, 0, 1]]}})";
  }
  std::string Write(const std::string& name, const std::string& text) const {
    const auto p = dir_ / name;
    std::ofstream(p) << text;
    return p.string();
  }
  std::filesystem::path dir_;
};

TEST_F(TermsReport, InlinesTheFinalModelsForcesWithTheirCovariance) {
  Write("report.json", Report());
  const std::string spec_path = Write("map.toml",
                                      "model = \"terms\"\n[terms]\nreport = \"report.json\"\n[axes]\n"
                                      "acc0_g = [0.1, 0.4]\nf0_hz = [6.5]\n");
  auto spec = LoadClientSweepSpec(spec_path);
  ASSERT_TRUE(spec.ok()) << spec.status().ToString();
  ASSERT_TRUE(spec->terms.has_value());
  const TermsConfig& t = *spec->terms;
  ASSERT_EQ(t.model.terms.size(), 3u);  // the sensor's gain and the offsets stay behind
  EXPECT_EQ(t.model.theta, (std::vector<double>{-1100, 3.5e6, 0.5}));
  EXPECT_EQ(t.drive, TermsConfig::Drive::kAcceleration);
  ASSERT_EQ(t.covariance.size(), 9u);
  EXPECT_EQ(t.covariance[1], t.covariance[3]);  // symmetric to the bit
  EXPECT_EQ(t.covariance[8], 1e-4);
  EXPECT_NE(spec->source.find("origin"), std::string::npos);  // the stored spec says where the model came from
  EXPECT_EQ(spec->source.find("report ="), std::string::npos);
  // 0.4 g at 6.5 Hz is A0 = 0.4 g / ω².
  const double w = 2 * M_PI * 6.5;
  EXPECT_DOUBLE_EQ(spec->DriveAt(spec->PointAt(1, 0)).a0_m, 0.4 * kStandardGravity / (w * w));
}

TEST_F(TermsReport, RefusesWhatItCannotSweepByName) {
  Write("force.json", Report("force"));
  Write("pressure.json", Report("pressure"));
  Write("piezo.json", Report("base_acceleration", ", \"main.piezo\""));
  Write("bad.json", "{not json");
  Write("deep.json", std::string(100000, '[') + std::string(100000, ']'));
  std::string broken = Report();  // a correlation of 1.5: the fit's uncertainty broke down (seen on real fits)
  broken.replace(broken.find("[25, -100,"), 10, "[25, -75000,");
  broken.replace(broken.find("[-100.0000000001,"), 17, "[-75000,");
  Write("broken.json", broken);
  struct Case {
    std::string terms, field;
  } cases[] = {{"report = \"pressure.json\"", "terms.report.settings.input_kind"},
               {"report = \"piezo.json\"", "terms.report.final_terms"},
               {"report = \"bad.json\"", "terms.report"},
               {"report = \"deep.json\"", "terms.report"},
               {"report = \"broken.json\"\n[robustness]\nsamples = 4\ncovariance = true", "terms.report.covariance"},
               {"report = \"missing.json\"", "terms.report"},
               {"report = \"force.json\"\nlist = [\"main.linear\"]", "terms.list"}};
  for (const Case& c : cases) {
    const std::string path = Write("s.toml", "model = \"terms\"\n[terms]\n" + c.terms + "\n");
    auto spec = LoadClientSweepSpec(path);
    ASSERT_FALSE(spec.ok()) << c.terms;
    EXPECT_EQ(spec.status().field(), c.field) << spec.status().ToString();
  }
  // A broken covariance is left out when nothing draws from it: the map of the fitted values still runs.
  auto nominal = LoadClientSweepSpec(Write("n.toml", "model = \"terms\"\n[terms]\nreport = \"broken.json\"\n"));
  ASSERT_TRUE(nominal.ok()) << nominal.status().ToString();
  EXPECT_TRUE(nominal->terms->covariance.empty());
  // A spec without a report is left as it is.
  auto same = InlineTermsReport("model = \"coupled\"\n", (dir_ / "x.toml").string());
  ASSERT_TRUE(same.ok());
  EXPECT_EQ(*same, "model = \"coupled\"\n");
}

}  // namespace
}  // namespace bistable
