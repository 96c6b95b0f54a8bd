// The sweep-kind seam (engine/sweep_kind.h, issue 40): each kind's items, chains, rounds and map part,
// on specs parsed from TOML, with records made up where the map part is a reduction of them.
#include "engine/sweep_kind.h"

#include <cmath>
#include <set>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "tests/spec_fixture.h"

namespace bistable {
namespace {

using bistable_test::ParsedSpec;

constexpr const char* kAxes = "model = \"coupled\"\n[axes]\nalpha = [0.2, 0.6, 1.0]\nomega = [0.8, 1.2]\n";

std::string WithStates(int n) {
  std::string s = std::string(kAxes) + "[initial_conditions]\nstates = [";
  for (int i = 0; i < n; ++i) s += (i ? ", " : "") + std::string("[") + std::to_string(0.5 * (i + 1)) + ", 0, 0, 0]";
  return s + "]\n";
}

const std::string kRobust =
    std::string(kAxes) + "[robustness]\nsamples = 8\nseed = 3\ntolerance = { eta = 0.2 }\nic_radius = 0.05\n";
const std::string kChains = std::string(kAxes) + "[continuation]\naxis = \"alpha\"\ndirection = \"both\"\n";
const std::string kBasins =
    "model = \"standalone\"\n[axes]\nvm0 = [-1.0, 0.0, 1.0]\nym0 = [-1.0, 1.0]\n"
    "[metrics]\nstore = [\"motion\", \"period\", \"y_min\", \"y_max\", \"strobe_y\", \"strobe_v\"]\n";
const std::string kRefined = std::string("model = \"coupled\"\n[axes]\nalpha = { linspace = [0.1, 1.0, 5] }\n") +
                             "omega = { linspace = [0.5, 2.0, 5] }\n[refine]\nlevels = 1\n";

// A record of NaNs (nothing measured).
PointRecord Empty() {
  PointRecord r;
  r.v.assign(PointRecord::Size(), NAN);
  return r;
}

void Set(PointRecord* r, const char* metric, double value) { r->v[MetricIndex(metric)] = value; }

// Records whose motion code is `code(item)` and nothing else.
std::vector<PointRecord> Motions(long n, int (*code)(long)) {
  std::vector<PointRecord> out(n, Empty());
  for (long i = 0; i < n; ++i) Set(&out[i], "motion", code(i));
  return out;
}

TEST(SweepKind, EachSpecTableMakesItsKindWithItsSlots) {
  struct Case {
    std::string toml;
    const char* kind;
    int slots;
    const char* dimension;
  } cases[] = {{kAxes, "grid", 1, "ic"},         {WithStates(3), "grid", 3, "ic"},
               {kRobust, "robustness", 8, "ic"}, {kChains, "continuation", 2, "direction"},
               {kBasins, "basins", 1, "ic"},     {kRefined, "refined", 1, "ic"}};
  for (const Case& c : cases) {
    const SweepSpec spec = ParsedSpec(c.toml);
    const SweepKind& kind = KindOf(spec);
    EXPECT_STREQ(kind.Name(), c.kind) << c.toml;
    EXPECT_EQ(kind.Slots(spec), c.slots) << c.kind;
    EXPECT_EQ(spec.ic_count(), c.slots) << c.kind;
    EXPECT_EQ(kind.Dimension(spec).name, c.dimension) << c.kind;
    EXPECT_EQ(kind.InRounds(), std::string(c.kind) == "refined") << c.kind;
    EXPECT_EQ(kind.Chained(), std::string(c.kind) == "continuation") << c.kind;
  }
}

TEST(SweepKind, AGridSlotStartsFromItsStateAndARobustnessSlotIsASample) {
  const SweepSpec grid = ParsedSpec(WithStates(3));
  for (int slot = 0; slot < 3; ++slot) {
    const PointSpec p = grid.PointAt(4, slot);
    EXPECT_TRUE(p.ic_given);
    EXPECT_EQ(p.ic[0], 0.5 * (slot + 1));
    EXPECT_EQ(p.params.eta, grid.base.params.eta);
  }
  const SweepSpec robust = ParsedSpec(kRobust);
  std::set<double> etas;
  for (int slot = 0; slot < 8; ++slot) {
    const PointSpec p = robust.PointAt(4, slot);
    const double rel = p.params.eta / robust.base.params.eta - 1.0;
    EXPECT_LE(std::fabs(rel), 0.2) << slot;  // within the tolerance
    EXPECT_EQ(p.alpha, 1.0);                 // the axes are not scattered
    etas.insert(p.params.eta);
    const PointSpec start = KindOf(robust).Start(robust, slot);  // before the sample and the axes
    EXPECT_EQ(start.params.eta, robust.base.params.eta);
  }
  EXPECT_EQ(etas.size(), 8u);  // every sample its own
  EXPECT_NE(robust.ItemKey(4, 0), robust.ItemKey(4, 1));
}

TEST(SweepKind, ContinuationChainsCoverEveryItemOnceAndContinueOnlyWithinAChain) {
  const SweepSpec spec = ParsedSpec(kChains);
  const SweepKind& kind = KindOf(spec);
  const auto chains = kind.Chains(spec);
  ASSERT_EQ(chains.size(), 4u);  // 2 lines (omega) x 2 directions
  std::set<std::pair<long, int>> seen;
  for (const auto& chain : chains) {
    ASSERT_EQ(chain.size(), 3u);
    for (size_t i = 0; i < chain.size(); ++i) {
      EXPECT_TRUE(seen.insert({chain[i].point, chain[i].ic}).second);
      if (i > 0) {
        EXPECT_TRUE(kind.Continues(spec, chain[i - 1], chain[i]));
      }
    }
    const double first = spec.PointAt(chain.front().point, chain.front().ic).alpha;
    EXPECT_EQ(first, spec.ChainGoesDown(chain.front().ic) ? 1.0 : 0.2);
  }
  EXPECT_EQ(seen.size(), static_cast<size_t>(spec.points() * kind.Slots(spec)));
  EXPECT_FALSE(kind.Continues(spec, chains[0].back(), chains[1].front()));  // the next chain starts afresh
  EXPECT_FALSE(kind.Continues(spec, chains[0][1], chains[0][0]));           // backwards is not a continuation
  const SweepSpec grid = ParsedSpec(kAxes);
  EXPECT_TRUE(KindOf(grid).Chains(grid).empty());
  EXPECT_FALSE(KindOf(grid).Continues(grid, {0, 0}, {1, 0}));
}

TEST(SweepKind, SeveralStatesAndSamplesMapTheFractionsOfEachMotion) {
  const SweepSpec grid = ParsedSpec(WithStates(4));
  // Point p's states: intrawell, interwell, chaotic, and chaotic again on even points, intrawell on odd.
  const auto records = Motions(grid.points() * 4, [](long i) {
    const int s = static_cast<int>(i % 4);
    return s < 3 ? s : ((i / 4) % 2 ? 0 : 2);
  });
  const KindMapPart part = KindOf(grid).MapPart(grid, records, nullptr);
  ASSERT_EQ(part.variables.size(), 3u);
  EXPECT_EQ(part.variables[0].name, "frac_intrawell");
  EXPECT_EQ(part.variables[2].name, "frac_chaotic");
  for (long p = 0; p < grid.points(); ++p) {
    double sum = 0;
    for (const KindVariable& v : part.variables) sum += v.values[p];
    EXPECT_EQ(sum, 1.0);
    EXPECT_EQ(part.variables[2].values[p], p % 2 ? 0.25 : 0.5);
  }
  EXPECT_TRUE(KindOf(ParsedSpec(kAxes))
                  .MapPart(ParsedSpec(kAxes), Motions(6, [](long) { return 0; }), nullptr)
                  .variables.empty());  // one start per point: no fractions

  const SweepSpec robust = ParsedSpec(kRobust);
  const auto sampled = Motions(robust.points() * 8, [](long i) { return i % 8 < 2 ? 2 : 0; });
  const KindMapPart rp = KindOf(robust).MapPart(robust, sampled, nullptr);
  ASSERT_EQ(rp.variables.size(), 6u);  // each fraction followed by its standard error
  EXPECT_EQ(rp.variables[5].name, "frac_chaotic_stderr");
  EXPECT_EQ(rp.variables[4].values[0], 0.25);
  EXPECT_DOUBLE_EQ(rp.variables[5].values[0], std::sqrt(0.25 * 0.75 / 8));
}

TEST(SweepKind, ABasinMapAddsTheAttractorOfEachStartAndTheTableOfAttractors) {
  const SweepSpec spec = ParsedSpec(kBasins);
  std::vector<PointRecord> records(spec.points(), Empty());
  for (long i = 0; i < spec.points(); ++i) {  // +well period 1 on ym0 > 0, -well on ym0 < 0
    const bool plus = spec.PointAt(i, 0).ic[0] > 0;
    Set(&records[i], "motion", 0);
    Set(&records[i], "period", 1);
    Set(&records[i], "y_min", plus ? 0.5 : -1.5);
    Set(&records[i], "y_max", plus ? 1.5 : -0.5);
    Set(&records[i], "strobe_y", plus ? 1.0 : -1.0);
    Set(&records[i], "strobe_v", 0.0);
  }
  const KindMapPart part = KindOf(spec).MapPart(spec, records, nullptr);
  ASSERT_EQ(part.variables.size(), 1u);
  EXPECT_EQ(part.variables[0].name, "attractor");
  EXPECT_EQ(part.variables[0].labels.size(), 2u);
  ASSERT_TRUE(part.table.has_value());
  EXPECT_EQ(part.table->group, "attractors");
  EXPECT_EQ(part.table->size, 2);
  ASSERT_FALSE(part.table_variables.empty());
  EXPECT_EQ(part.table_variables[0].name, "basin_fraction");
  EXPECT_EQ(part.table_variables[0].values[0] + part.table_variables[0].values[1], 1.0);
  ASSERT_EQ(part.attributes.size(), 1u);
  EXPECT_EQ(part.attributes[0].name, "basin_boundary_fraction");
  EXPECT_EQ(part.attributes[0].number, 1.0);  // every start has a neighbour across ym0 = 0
}

TEST(SweepKind, OnlyASweepInRoundsCanBeFilled) {
  const SweepSpec grid = ParsedSpec(kAxes);
  const auto filled = KindOf(grid).Fill(grid, {}, {});
  EXPECT_FALSE(filled.ok());
  EXPECT_EQ(filled.status().code(), Status::Code::kInternal);
  const SweepSpec refined = ParsedSpec(kRefined);
  const auto missing = KindOf(refined).Fill(refined, {0}, {Empty()});  // the coarse corners are missing
  EXPECT_FALSE(missing.ok());
  EXPECT_TRUE(KindOf(refined).MapPart(refined, {}, nullptr).variables.empty());  // nothing before it is filled
}

}  // namespace
}  // namespace bistable
