// The library entry point of identification (issue 40): identify::Options and their validation
// (identify/options.h), Identify(options, records) (identify/identify.h) on a small synthetic record.
#include <cmath>
#include <functional>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "base/limits.h"
#include "identify/identify.h"
#include "identify/options.h"
#include "identify/synthetic.h"

namespace bistable {
namespace {

using identify::Options;

// A valid fit of the linear rig: base displacement in, displacement out, per the Table 2 mass.
Options Valid() {
  Options o;
  o.terms = {"main.linear", "main.viscous", "main.damping_y2", "main.friction"};
  o.m_main = 0.282;
  return o;
}

TEST(IdentifyOptions, TheDefaultsWithTermsAndAMassAreValid) {
  EXPECT_TRUE(identify::Validate(Valid()).ok()) << identify::Validate(Valid()).ToString();
  Options force;  // a force input may fit its mass (m_main 0: unknown)
  force.terms = {"main.linear"};
  force.input_kind = InputKind::kForce;
  force.output_kind = OutputKind::kAnalogue;
  EXPECT_TRUE(identify::Validate(force).ok()) << identify::Validate(force).ToString();
  const auto plan = identify::MakePlan(Valid());
  ASSERT_TRUE(plan.ok());
  EXPECT_EQ(plan->model.terms.size(), 4u);
  EXPECT_EQ(plan->model.m_main, 0.282);
  EXPECT_EQ(plan->loop.fit.global_evals, 150);
  EXPECT_EQ(plan->loop.fit.lm_iterations, 60);
  EXPECT_TRUE(plan->loop.choose_objective);  // objective auto
  EXPECT_EQ(plan->columns.input, "x0");
  EXPECT_EQ(plan->columns.output, "x");
}

// Every option out of its bounds: an InvalidArgument naming the option (its flag's name) and the bound.
TEST(IdentifyOptions, EachBadFieldIsNamedWithItsBound) {
  struct Case {
    std::string what;
    std::function<void(Options*)> set;
    std::string field, bound;
  };
  const Case cases[] = {
      {"no terms", [](Options* o) { o->terms.clear(); }, "terms", "declare the model"},
      {"unknown term",
       [](Options* o) {
         o->terms = {"main.linear", "main.stifness_y3"};
       },
       "terms", "did you mean 'main.stiffness_y3'"},
      {"term twice",
       [](Options* o) {
         o->terms = {"main.linear", "main.linear"};
       },
       "terms", "listed twice"},
      {"negative mass", [](Options* o) { o->m_main = -1; }, "known.m_main", "m_main = -1 violates m_main > 0"},
      {"no mass, base input", [](Options* o) { o->m_main = 0; }, "known.m_main",
       "the main mass is needed with a base input"},
      {"NaN mass", [](Options* o) { o->m_main = NAN; }, "known.m_main", "violates m_main > 0"},
      {"v_sp 0", [](Options* o) { o->v_sp = 0; }, "known.v_sp", "v_sp = 0 violates v_sp > 0"},
      {"v_t negative", [](Options* o) { o->v_t = -0.5; }, "known.v_t", "v_t = -0.5 violates v_t > 0"},
      {"resonator without mass", [](Options* o) { o->terms.push_back("res.linear"); }, "known.m_res", "give its mass"},
      {"input scale 0", [](Options* o) { o->input_scale = 0; }, "input-scale", "finite non-zero"},
      {"output scale inf", [](Options* o) { o->output_scale = INFINITY; }, "output-scale", "finite non-zero"},
      {"output2 scale NaN", [](Options* o) { o->output2_scale = NAN; }, "output2-scale", "finite non-zero"},
      {"frame auto, displacement", [](Options* o) { o->output_frame = identify::FrameMode::kAuto; }, "output-frame",
       "needs --output-kind velocity and --input-kind base_acceleration"},
      {"drift cutoff negative", [](Options* o) { o->drift_cutoff = -0.5; }, "drift-cutoff",
       "drift-cutoff = -0.5 violates drift-cutoff >= 0 Hz"},
      {"drift cutoff, displacement", [](Options* o) { o->drift_cutoff = 0.5; }, "drift-cutoff",
       "needs --output-kind velocity"},
      {"velocity with base displacement", [](Options* o) { o->output_kind = OutputKind::kVelocity; }, "output",
       "with a base displacement input the output must be a displacement"},
      {"output term of a missing output", [](Options* o) { o->terms.push_back("out.voltage.offset"); }, "terms",
       "acts on a voltage output; this run's outputs are displacement"},
      {"guess of no parameter", [](Options* o) { o->guesses["main.linear.k"] = 1; }, "guess",
       "did you mean 'main.linear.k_lin'"},
      {"guess not finite", [](Options* o) { o->guesses["main.linear.k_lin"] = INFINITY; }, "guess.main.linear.k_lin",
       "violates a finite number"},
      {"global evals negative", [](Options* o) { o->global_evals = -1; }, "global-evals", "must be in [0, 100000]"},
      {"lm iterations 0", [](Options* o) { o->lm_iterations = 0; }, "lm-iterations", "must be in [1, 10000]"},
      {"max added 11", [](Options* o) { o->max_added = 11; }, "max-added", "must be in [0, 10]"},
      {"bootstrap 5", [](Options* o) { o->bootstrap = 5; }, "bootstrap", "violates bootstrap = 0 or 8 <= bootstrap"},
      {"bootstrap 257", [](Options* o) { o->bootstrap = 257; }, "bootstrap", "<= bootstrap <= 256"},
      {"deriv cutoff negative", [](Options* o) { o->deriv_cutoff = -1; }, "deriv-cutoff",
       "deriv-cutoff = -1 violates deriv-cutoff >= 0 Hz"},
      {"decimate 0", [](Options* o) { o->decimate = 0; }, "decimate", "must be in [1, 1000]"},
      {"horizon an hour and more", [](Options* o) { o->horizon = 4000; }, "horizon",
       "horizon = 4000 violates 0 <= horizon <= 3600 s"},
      {"horizon NaN", [](Options* o) { o->horizon = NAN; }, "horizon", "violates 0 <= horizon <= 3600 s"},
      {"shooting without horizon",
       [](Options* o) { o->objective = identify::ObjectiveMode::kShooting, o->horizon = 0; }, "horizon",
       "horizon = 0 violates horizon > 0 s"},
      {"max seconds negative", [](Options* o) { o->max_seconds = -5; }, "max-seconds",
       "max-seconds = -5 violates 0 <= max-seconds <= 1e6 s"},
      {"threads beyond", [](Options* o) { o->threads = 2000; }, "threads",
       "threads = 2000 violates threads in [0, 1024]"},
      {"unknown candidate", [](Options* o) { o->candidates = {"main.dragg"}; }, "candidates",
       "did you mean 'main.drag'"},
      {"candidate on a missing output", [](Options* o) { o->candidates = {"out.voltage.scale"}; }, "candidates",
       "acts on a voltage output"},
      {"empty range",
       [](Options* o) {
         o->range = {5, 5};
       },
       "range", "range = 5:5 is empty"},
      {"range beyond the rows",
       [](Options* o) {
         o->range = {0, static_cast<size_t>(limits::kMaxDataRows) + 1};
       },
       "range", "each <= " + std::to_string(limits::kMaxDataRows)},
      {"test range backwards",
       [](Options* o) {
         o->test_ranges = {{0, 100}, {300, 200}};
       },
       "test-range", "test-range = 300:200 is empty"},
  };
  for (const Case& c : cases) {
    Options o = Valid();
    c.set(&o);
    const Status st = identify::Validate(o);
    EXPECT_EQ(st.code(), Status::Code::kInvalidArgument) << c.what << ": " << st.ToString();
    EXPECT_EQ(st.field(), c.field) << c.what << ": " << st.ToString();
    EXPECT_NE(st.message().find(c.bound), std::string::npos) << c.what << ": " << st.ToString();
  }
}

TEST(IdentifyOptions, NamesReadBackAndBadNamesListTheChoices) {
  for (const char* n : {"base_displacement", "base_acceleration", "force"})
    EXPECT_STREQ(identify::Name(*identify::ParseInputKind(n)), n);
  for (const char* n : {"displacement", "velocity", "analogue"})
    EXPECT_STREQ(identify::Name(*identify::ParseOutputKind(n)), n);
  for (const char* n : {"absolute", "relative", "auto"}) EXPECT_STREQ(identify::Name(*identify::ParseFrameMode(n)), n);
  for (const char* n : {"auto", "time", "fft", "shooting"})
    EXPECT_STREQ(identify::Name(*identify::ParseObjectiveMode(n)), n);
  for (const char* n : {"residual", "noise"}) EXPECT_STREQ(identify::Name(*identify::ParseOutputWeights(n)), n);
  EXPECT_EQ(identify::ParseObjectiveMode("phase").status().ToString(),
            "invalid argument (objective: 'phase' violates objective in {auto, time, fft, shooting})");
  EXPECT_EQ(identify::ParseInputKind("x").status().field(), "input-kind");
  EXPECT_EQ(identify::ParseOutputWeights("equal").status().field(), "output-weights");
  EXPECT_FALSE(identify::CheckOutput2Kind("resonator").ok());
  // Ranges as --range takes them.
  EXPECT_EQ(*identify::ParseRange("10:20", "range"), identify::SampleRange(10, 20));
  EXPECT_EQ(*identify::ParseRange(":20", "range"), identify::SampleRange(0, 20));
  EXPECT_EQ(*identify::ParseRange("10:", "range"), identify::SampleRange(10, SIZE_MAX));
  EXPECT_NE(identify::ParseRange("1e3:2000", "test-range").status().message().find("violates test-range = A:B"),
            std::string::npos);
  // Columns and constants by name.
  Options o;
  EXPECT_TRUE(identify::SetColumn("group", "a;b", &o).ok());
  EXPECT_EQ(o.group_columns, (std::vector<std::string>{"a", "b"}));
  EXPECT_NE(identify::SetColumn("outptu", "x", &o).message().find("did you mean 'output'"), std::string::npos);
  EXPECT_TRUE(identify::SetKnown("m_res", 0.62, &o).ok());
  EXPECT_EQ(o.m_res, 0.62);
  EXPECT_EQ(identify::SetKnown("m_mian", 1, &o).field(), "known");
  // Term lists: split at every comma and joined back to the same text.
  for (const std::string s : {"main.linear,main.viscous", "main.linear, main.viscous", "main.linear,,", ","})
    EXPECT_EQ(identify::JoinTerms(identify::SplitTerms(s)), s);
  EXPECT_TRUE(identify::SplitTerms("").empty());
}

// One 6 mm chirp of the linear rig, 10 s (120 Hz, 0.05 mm noise).
std::vector<Record> OneChirp() {
  DimensionalParams p = DimensionalParams::LinearTable2();
  p.has_resonator = false;
  SyntheticOptions s;
  s.a0_m = 0.006;
  s.duration_s = 10;
  s.seed = 5;
  auto r = MakeSyntheticRecord(p, s, "chirp 6 mm");
  EXPECT_TRUE(r.ok()) << r.status().ToString();
  return {*r};
}

// Identify(options, records) is the plan's loop on the prepared records: the same fit to the bit, the test
// range simulated with both models, the records cut and decimated as asked.
TEST(IdentifyEntryPoint, FitsASyntheticRecordAsTheLoopDoes) {
  const std::vector<Record> records = OneChirp();
  Options o = Valid();
  o.objective = identify::ObjectiveMode::kTime;
  o.global_evals = 0;
  o.max_added = 0;
  o.max_seconds = 6;
  o.test_ranges = {{720, 1200}};
  const auto s = Identify(o, records);
  ASSERT_TRUE(s.ok()) << s.status().ToString();
  ASSERT_EQ(s->records.size(), 1u);
  EXPECT_EQ(s->records[0].n(), 720u);  // 6 s at 120 Hz
  EXPECT_TRUE(s->result.added.empty());
  EXPECT_LT(s->result.after.errors.nrmse, 2.0);  // all four terms declared: near the noise floor
  EXPECT_GT(s->simulations, 0);
  ASSERT_EQ(s->tests.size(), 1u);
  EXPECT_EQ(s->tests[0].begin, 720u);
  EXPECT_EQ(s->tests[0].end, 1200u);
  EXPECT_LT(s->tests[0].after.nrmse, 5.0);
  EXPECT_FALSE(s->frame.made);
  // The same loop called directly on the plan and the prepared records.
  const auto plan = identify::MakePlan(o);
  ASSERT_TRUE(plan.ok());
  const auto prepared = identify::PrepareFitted(records, o, plan->setup);
  ASSERT_TRUE(prepared.ok());
  const IdentifyResult direct = Identify(plan->model, *prepared, plan->setup, plan->loop);
  EXPECT_EQ(direct.after.theta, s->result.after.theta);
  EXPECT_EQ(direct.after.errors.nrmse, s->result.after.errors.nrmse);

  // Decimated by 2: every other sample, 6 s are then 360 samples.
  o.decimate = 2;
  o.test_ranges.clear();
  const auto d = Identify(o, records);
  ASSERT_TRUE(d.ok()) << d.status().ToString();
  EXPECT_EQ(d->records[0].n(), 360u);
  EXPECT_DOUBLE_EQ(d->records[0].dt, 2.0 / 120);
}

TEST(IdentifyEntryPoint, RefusesBadOptionsAndNoRecordsBeforeFitting) {
  Options o = Valid();
  o.lm_iterations = 0;
  const auto bad = Identify(o, OneChirp());
  ASSERT_FALSE(bad.ok());
  EXPECT_EQ(bad.status().field(), "lm-iterations");
  const auto none = Identify(Valid(), {});
  ASSERT_FALSE(none.ok());
  EXPECT_EQ(none.status().field(), "data");
  o = Valid();
  o.objective = identify::ObjectiveMode::kShooting;
  o.horizon = 0.02;  // < 4 samples at 120 Hz
  const auto shooting = Identify(o, OneChirp());
  ASSERT_FALSE(shooting.ok());
  EXPECT_NE(shooting.status().message().find("violates horizon >= 4 samples of chirp 6 mm"), std::string::npos)
      << shooting.status().ToString();
}

}  // namespace
}  // namespace bistable
