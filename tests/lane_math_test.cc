// Lane exp and tanh (dynamics/lane_math.h): accuracy against glibc's std::exp / std::tanh over the
// range the friction law feeds them and beyond, the special cases, and the same bits at every lane
// width (what keeps the rig's lanes bit-identical to its one-point path).
#include "dynamics/lane_math.h"

#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <vector>

#include <gtest/gtest.h>

namespace bistable {
namespace {

// Distance in units in the last place between two finite doubles (ordered bit patterns).
double Ulps(double a, double b) {
  auto key = [](double v) {
    std::int64_t i;
    std::memcpy(&i, &v, sizeof i);
    return i < 0 ? std::numeric_limits<std::int64_t>::min() - i : i;
  };
  return std::fabs(static_cast<double>(key(a) - key(b)));
}

bool SameBits(double a, double b) { return std::memcmp(&a, &b, sizeof a) == 0; }

template <int W>
Vec<W> ApplyLanes(bool tanh, const std::vector<double>& x, size_t i) {
  Vec<W> v;
  for (int l = 0; l < W; ++l) v[l] = x[(i + l) % x.size()];
  return tanh ? Tanh<W>(v) : Exp<W>(v);
}

double Lane1(bool tanh, double x) { return ApplyLanes<1>(tanh, {x}, 0)[0]; }

// x evenly spaced over [lo, hi] (n points) plus a jitter that reaches the low mantissa bits.
std::vector<double> Samples(double lo, double hi, long n) {
  std::vector<double> x;
  for (long i = 0; i < n; ++i)
    x.push_back(lo + (hi - lo) * ((static_cast<double>(i) + 0.318309886 * ((i * 7919) % 1000) / 1000.0) / n));
  return x;
}

double MaxUlps(bool tanh, const std::vector<double>& xs, double* worst_x) {
  double worst = 0;
  for (double x : xs) {
    const double mine = Lane1(tanh, x), libm = tanh ? std::tanh(x) : std::exp(x);
    if (libm == 0 || !std::isnormal(libm)) continue;  // subnormal results: checked absolutely below
    const double u = Ulps(mine, libm);
    if (u > worst) worst = u, *worst_x = x;
  }
  return worst;
}

TEST(LaneMath, ExpWithinOneUlpOfLibm) {
  double at = 0;
  // The hump's exponent 1/2 − u²/2 (u = v/v_sp): 0.5 down to the underflow, densely near 0.
  EXPECT_LE(MaxUlps(false, Samples(-5, 0.5, 2000000), &at), 1) << at;
  EXPECT_LE(MaxUlps(false, Samples(-746, 0.5, 2000000), &at), 1) << at;
  // The whole finite range (the tanh's e^{2|x|} included).
  EXPECT_LE(MaxUlps(false, Samples(-708, 709.78, 2000000), &at), 1) << at;
  EXPECT_LE(MaxUlps(false, Samples(-1e-6, 1e-6, 200000), &at), 1) << at;
}

TEST(LaneMath, ExpSubnormalResultsAndLimits) {
  // Subnormal results: one rounding of the scaled value, so within one subnormal step of libm's.
  for (double x : Samples(-745.2, -708.3, 200000)) {
    const double mine = Lane1(false, x), libm = std::exp(x);
    EXPECT_LE(std::fabs(mine - libm), 4.9406564584124654e-324) << x;
  }
  const double inf = std::numeric_limits<double>::infinity();
  EXPECT_TRUE(SameBits(Lane1(false, -746.0), 0.0));
  EXPECT_TRUE(SameBits(Lane1(false, -1e5), 0.0));
  EXPECT_TRUE(SameBits(Lane1(false, -inf), 0.0));
  EXPECT_EQ(Lane1(false, 709.78), std::exp(709.78));
  EXPECT_EQ(Lane1(false, 709.8), inf);
  EXPECT_EQ(Lane1(false, 1e5), inf);
  EXPECT_EQ(Lane1(false, inf), inf);
  EXPECT_TRUE(std::isnan(Lane1(false, std::numeric_limits<double>::quiet_NaN())));
  EXPECT_EQ(Lane1(false, 0.0), 1.0);
  EXPECT_EQ(Lane1(false, -0.0), 1.0);
  EXPECT_EQ(Lane1(false, 1.0), std::exp(1.0));
}

// glibc's tanh is itself up to ~2 ulp off (at 0.5193… by 1.87 ulp against mpmath, where the lane
// tanh is 0.13 ulp off): 2 ulp against glibc, 1 ulp against correctly rounded values (below).
TEST(LaneMath, TanhWithinTwoUlpOfLibm) {
  double at = 0;
  // v/v_t: sticking (|x| ≲ 1, densely around the branch switch at 0.55) to sliding (|x| in the hundreds).
  EXPECT_LE(MaxUlps(true, Samples(-2, 2, 2000000), &at), 2) << at;
  EXPECT_LE(MaxUlps(true, Samples(0.5, 0.6, 200000), &at), 2) << at;
  EXPECT_LE(MaxUlps(true, Samples(-25, 25, 2000000), &at), 2) << at;
  EXPECT_LE(MaxUlps(true, Samples(-2000, 2000, 200000), &at), 2) << at;
  EXPECT_LE(MaxUlps(true, Samples(-1e-5, 1e-5, 200000), &at), 2) << at;
  std::vector<double> tiny;
  for (double x = 1e-300; x < 1e-3; x *= 1.37) tiny.push_back(x), tiny.push_back(-x);
  EXPECT_LE(MaxUlps(true, tiny, &at), 2) << at;
}

// Correctly rounded references (mpmath, 50 digits): within 1 ulp, also where glibc is not.
TEST(LaneMath, WithinOneUlpOfCorrectlyRoundedValues) {
  const double tanh_ref[][2] = {
      {0x1.0000987132b2fp-1, 0x1.d9362d3bd64cfp-2},   {-0x1.fff532083ca44p-1, -0x1.85eb219bf28b1p-1},
      {-0x1.ffd469f1a0460p-1, -0x1.85dd5c088dcc1p-1}, {-0x1.09e4fd8a4e800p-1, -0x1.e8a19ddf7ce96p-2},
      {0x1.1916872b020c5p-1, 0x1.ffc3cce48227ep-2},   {0x1.1a1cac083126fp-1, 0x1.00a65f294439ep-1},
      {0x1.3333333333333p-2, 0x1.2a4dda7d914fap-2},   {0x1.5798ee2308c3ap-27, 0x1.5798ee2308c3ap-27},
      {0x1.4000000000000p+1, 0x1.f9258260a71c2p-1},   {0x1.c000000000000p+2, 0x1.ffffc832750f2p-1},
      {0x1.2800000000000p+4, 0x1.ffffffffffffep-1},   {-0x1.999999999999ap-5, -0x1.99424e535f6f9p-5},
      {0x1.0000000000000p-3, 0x1.fd5992bc4b835p-4},   {0x1.8000000000000p-1, 0x1.45323e552f228p-1},
      {0x1.8000000000000p+0, 0x1.cf6f9786df577p-1},   {0x1.e000000000000p+1, 0x1.ff6f17a754772p-1}};
  for (const auto& [x, t] : tanh_ref) EXPECT_LE(Ulps(Lane1(true, x), t), 1) << x;
  const double exp_ref[][2] = {
      {-0x1.7480000000000p+9, 0x0.0000000000001p-1022}, {-0x1.5e40000000000p+9, 0x1.4ff475c68ca02p-1011},
      {-0x1.2c40000000000p+8, 0x1.c758233102acep-434},  {-0x1.4000000000000p+4, 0x1.1b48655f37267p-29},
      {-0x1.0000000000000p+0, 0x1.78b56362cef38p-2},    {-0x1.3333333333333p-2, 0x1.7b4c869c37c05p-1},
      {0x1.999999999999ap-4, 0x1.1aec7b35a00d4p+0},     {0x1.0000000000000p-1, 0x1.a61298e1e069cp+0},
      {0x1.62eb1c432ca58p-2, 0x1.6a0c5906bc779p+0},     {-0x1.62eb1c432ca58p-2, 0x1.6a0773cd678a4p-1},
      {0x1.b7cdfd9d7bdbbp-34, 0x1.000000006df38p+0},    {0x1.62ccccccccccdp+6, 0x1.f4705bbffae5cp+127},
      {0x1.62d999999999ap+9, 0x1.d75ae7a50ee14p+1023}};
  for (const auto& [x, e] : exp_ref) EXPECT_LE(Ulps(Lane1(false, x), e), 1) << x;
}

TEST(LaneMath, TanhSpecialCases) {
  const double inf = std::numeric_limits<double>::infinity();
  EXPECT_TRUE(SameBits(Lane1(true, 0.0), 0.0));
  EXPECT_TRUE(SameBits(Lane1(true, -0.0), -0.0));
  EXPECT_EQ(Lane1(true, inf), 1.0);
  EXPECT_EQ(Lane1(true, -inf), -1.0);
  EXPECT_EQ(Lane1(true, 400.0), 1.0);
  EXPECT_EQ(Lane1(true, -1e300), -1.0);
  EXPECT_TRUE(std::isnan(Lane1(true, std::numeric_limits<double>::quiet_NaN())));
  EXPECT_TRUE(SameBits(Lane1(true, 4.9406564584124654e-324), 4.9406564584124654e-324));
  EXPECT_TRUE(SameBits(Lane1(true, -1e-310), -1e-310));
}

// The same bits at widths 1, 4 and 8 and at every lane position (mixed branches in one pack).
TEST(LaneMath, SameBitsAtEveryWidth) {
  std::vector<double> x = Samples(-30, 30, 20011);
  // The one-lane tanh takes only its branch, and returns ±1 from |x| ≥ 20 on: both edges.
  for (double v : {0.0, -0.0, 1e-310, -800.0, 709.9, 0.55, -0.55, 0.5499999999999999, 19.06, 19.5, 19.999999999999996,
                   20.0, -20.0})
    x.push_back(v);
  // Subnormal results and the overflow edge: the 2^n scaling (VSCALEFPD in 8-lane chunks on AVX-512,
  // two multiplications in the one-point path) must round the same.
  for (double v : Samples(-745.2, -708.3, 4001)) x.push_back(v);
  for (double v : Samples(709.0, 709.9, 401)) x.push_back(v);
  for (bool tanh : {false, true}) {
    for (size_t i = 0; i < x.size(); ++i) {
      const double one = Lane1(tanh, x[i]);
      const Vec<4> v4 = ApplyLanes<4>(tanh, x, i);
      const Vec<8> v8 = ApplyLanes<8>(tanh, x, i + x.size() - 3);  // x[i] in lane 3
      EXPECT_TRUE(SameBits(v4[0], one)) << x[i];
      EXPECT_TRUE(SameBits(v8[3], one)) << x[i];
    }
  }
}

}  // namespace
}  // namespace bistable
