// exp and tanh for lane packs (dynamics/lanes.h), written out in the project so that a lane's bits do
// not depend on the width: the same operations (IEEE + − × ÷, exact fused multiply-adds, bit
// manipulation, compare-and-select) at every W, W = 1 included — no libm, no libmvec, no -ffast-math.
// Accuracy (tests/lane_math_test.cc, dense samples and the extremes): Exp within 1 ulp of glibc's
// std::exp over the whole range; Tanh within 2 ulp of glibc's std::tanh, which is itself up to ~2 ulp
// off — within 1 ulp of correctly rounded values where glibc's is 1.9 ulp off.
//
//   Exp(x):  n = round(x/ln 2) (a shift constant), r = x − n·ln 2 (Cody–Waite in two parts with fused
//            multiply-adds: the first part is exact), exp(r) = 1 + r·P(r) with P a degree-10
//            Chebyshev fit of (e^r − 1)/r on |r| ≤ ln 2 / 2 (fit error 2e-17; evaluated as two
//            interleaved Horner chains in r², see ExpP), scaled by 2^n with one rounding also for
//            subnormal results (VSCALEFPD on AVX-512, else (e^r · 2^⌊n/2⌋) · 2^(n − ⌊n/2⌋), both
//            factors normal: the same bits). x is clamped to [−746, 710] first: exp(−746) rounds
//            to +0 and exp(710) to +inf, so the clamp keeps both limits (no slow underflow path);
//            NaN passes the clamp and propagates.
//   Tanh(x): for |x| < 0.55 (tanh < 0.5), |x| + |x|³·T(x²) with T a degree-10 Chebyshev fit of
//            (tanh t − t)/t³ in t² (fit error 8e-18; relative accuracy down to subnormals);
//            otherwise 1 − 2/(e^{2|x|} + 1) (no cancellation: the result is ≥ 0.5) with e^{2|x|} + 1 =
//            2^n (1 + r P(r)) + 1 as above, one fused multiply-add of the unrounded parts; the sign of
//            x copied onto the result (tanh(−0) = −0). Both branches are computed and one selected
//            per lane; at W = 1 only the taken one, and ±1 from |x| ≥ 20 on (the same bits).
#ifndef BISTABLE_DYNAMICS_LANE_MATH_H_
#define BISTABLE_DYNAMICS_LANE_MATH_H_

#include <cstdint>

#include "dynamics/lanes.h"

namespace bistable {
namespace lane_math {

template <int W>
struct BitsType {
  typedef std::int64_t type __attribute__((vector_size(8 * W)));
};
template <int W>
using Bits = typename BitsType<W>::type;  // a lane pack's bit patterns

template <int W>
BISTABLE_INLINE Bits<W> ToBits(Vec<W> v) {
  return __builtin_bit_cast(Bits<W>, v);
}
template <int W>
BISTABLE_INLINE Vec<W> FromBits(Bits<W> b) {
  return __builtin_bit_cast(Vec<W>, b);
}
template <int W>
BISTABLE_INLINE Bits<W> BroadcastBits(std::int64_t v) {
  Bits<W> r;
  for (int i = 0; i < W; ++i) r[i] = v;
  return r;
}

// Polynomial c[0] + c[1] x + … + c[N−1] x^{N−1} by Horner's rule with fused multiply-adds.
template <int W, int N>
BISTABLE_INLINE Vec<W> Horner(Vec<W> x, const double (&c)[N]) {
  Vec<W> p = Splat<W>(c[N - 1]);
  for (int i = N - 2; i >= 0; --i) p = Fma(p, x, Splat<W>(c[i]));
  return p;
}

// (e^r − 1)/r on |r| ≤ ln 2 / 2, lowest degree first.
inline constexpr double kExpP[11] = {0x1.0000000000000p+0,  0x1.0000000000005p-1,  0x1.5555555555557p-3,
                                     0x1.5555555552043p-5,  0x1.11111111100bep-7,  0x1.6c16c17f6130bp-10,
                                     0x1.a01a01abf85abp-13, 0x1.a019a60cd99d3p-16, 0x1.71de01fdbf9cap-19,
                                     0x1.28a321f9f0475p-22, 0x1.af4e554377204p-26};
// (tanh t − t)/t³ as a polynomial in s = t², 0 ≤ s ≤ 0.55², lowest degree first.
inline constexpr double kTanhT[11] = {-0x1.5555555555555p-2,  0x1.1111111111032p-3,  -0x1.ba1ba1b9fec84p-5,
                                      0x1.664f487713373p-6,   -0x1.226e32f00cf0cp-7, 0x1.d6d339333f329p-9,
                                      -0x1.7d97cfd138c28p-10, 0x1.34c5a8a996cd4p-11, -0x1.ec1091436eb2ap-13,
                                      0x1.64fd88e9900a5p-14,  -0x1.59a834187ce22p-16};
inline constexpr double kTanhSmall = 0.55;

}  // namespace lane_math

namespace lane_math {

// x = n·ln 2 + r, |r| ≤ ln 2/2 (for |x| < 2^51): *n as a double, *ni as an integer.
template <int W>
BISTABLE_INLINE Vec<W> Reduce(Vec<W> x, Vec<W>* n, Bits<W>* ni) {
  constexpr double kLog2e = 0x1.71547652b82fep+0, kLn2Hi = 0x1.62e42fefa39efp-1, kLn2Lo = 0x1.abc9e3b39803fp-56;
  constexpr double kShift = 0x1.8p52;  // t = x/ln 2 + 1.5·2^52 holds round(x/ln 2) in its low mantissa bits
  const Vec<W> t = Fma(x, Splat<W>(kLog2e), Splat<W>(kShift));
  *n = t - Splat<W>(kShift);
  *ni = ToBits<W>(t) - ToBits<W>(Splat<W>(kShift));
  const Vec<W> r = Fma(-*n, Splat<W>(kLn2Hi), x);  // exact: |x − n·ln2_hi| < 0.35 needs ≤ 53 bits
  return Fma(-*n, Splat<W>(kLn2Lo), r);
}

// 2^n for integer n in [−1022, 1023].
template <int W>
BISTABLE_INLINE Vec<W> Pow2(Bits<W> n) {
  return FromBits<W>((n + BroadcastBits<W>(1023)) << 52);
}

// P(r) = (e^r − 1)/r = Σ kExpP[i] r^i for |r| ≤ ln 2/2 (a reduced argument), as 1 + r·(E(r²) + r·O(r²)):
// the odd- and even-indexed coefficients of kExpP[1..10] by Horner's rule in r², two independent
// chains of 4 fused multiply-adds, then the last two steps of Horner's rule in r (so E and O's roundings
// are scaled by r² ≤ 0.12 in e^r = 1 + r·P(r): as accurate as Horner's rule throughout). Dependency
// depth 7 instead of 10 for one more multiplication (r²): the rig's step waits on these chains.
template <int W>
BISTABLE_INLINE Vec<W> ExpP(Vec<W> r) {
  const Vec<W> r2 = r * r;
  Vec<W> e = Splat<W>(kExpP[9]), o = Splat<W>(kExpP[10]);
#pragma GCC unroll 4
  for (int i = 7; i >= 1; i -= 2) e = Fma(e, r2, Splat<W>(kExpP[i])), o = Fma(o, r2, Splat<W>(kExpP[i + 1]));
  return Fma(Fma(o, r, e), r, Splat<W>(kExpP[0]));
}

// v · 2^n for v in [1/2, 2) and n in [−1076, 1025], given as a double (n) and as an integer (ni):
// rounded once (also to a subnormal or to ±inf). AVX-512's VSCALEFPD where the unit has it;
// elsewhere (v · 2^⌊n/2⌋) · 2^(n − ⌊n/2⌋), the first product exact (both factors and the product
// normal), so the same bits.
template <int W>
BISTABLE_INLINE Vec<W> ScaleByPow2(Vec<W> v, [[maybe_unused]] Vec<W> n, Bits<W> ni) {
#if defined(__AVX512F__)
  if constexpr (W % 8 == 0)
    return MapChunks<__m512d>([](__m512d v, __m512d n) BISTABLE_INLINE_LAMBDA { return _mm512_scalef_pd(v, n); }, v, n);
#endif
#if defined(__AVX512VL__)
  if constexpr (W % 4 == 0)
    return MapChunks<__m256d>([](__m256d v, __m256d n) BISTABLE_INLINE_LAMBDA { return _mm256_scalef_pd(v, n); }, v, n);
#endif
  const Bits<W> n1 = ni >> 1;
  return (v * Pow2<W>(n1)) * Pow2<W>(ni - n1);
}

}  // namespace lane_math

// e^x per lane.
template <int W>
BISTABLE_INLINE Vec<W> Exp(Vec<W> x) {
  using namespace lane_math;
  x = Max<W>(Splat<W>(-746.0), Min<W>(Splat<W>(710.0), x));  // NaN stays NaN (MINPD/MAXPD order)
  Vec<W> n;                                                  // −1076 … 1025
  Bits<W> ni;
  const Vec<W> r = Reduce<W>(x, &n, &ni);
  return ScaleByPow2<W>(Fma(r, ExpP<W>(r), Splat<W>(1.0)), n, ni);
}

// tanh x per lane.
template <int W>
BISTABLE_INLINE Vec<W> Tanh(Vec<W> x) {
  using namespace lane_math;
  const Vec<W> a = Abs<W>(x), s = a * a;
  if constexpr (W == 1) {
    // One lane: only the branch the select below would take (the same operations, so the same bits).
    const Bits<W> sign = ToBits<W>(x) & BroadcastBits<W>(INT64_MIN);
    if (a[0] < kTanhSmall) return FromBits<W>(ToBits<W>(Fma(a * s, Horner<W>(s, kTanhT), a)) | sign);
    if (a[0] >= 20.0) return FromBits<W>(ToBits<W>(Splat<W>(1.0)) | sign);  // 1 − 2/(e^40 + 1) rounds to 1
  }
  // Horner's rule here: this branch is off the critical path (the other one waits on a division).
  const Vec<W> small = Fma(a * s, Horner<W>(s, kTanhT), a);
  // 1 − 2/(e^{2a} + 1) with e^{2a} = 2^n (1 + r P(r)): the denominator one fused multiply-add of the
  // unrounded parts (2^n + 1 exact for n ≤ 52; the clamp at 2a = 40, n ≤ 58, where tanh rounds to 1).
  Vec<W> n;
  Bits<W> ni;
  const Vec<W> r = Reduce<W>(Min<W>(Splat<W>(40.0), a + a), &n, &ni);
  const Vec<W> p2 = Pow2<W>(ni);
  const Vec<W> large = Splat<W>(1.0) - Splat<W>(2.0) / Fma(p2 * r, ExpP<W>(r), p2 + Splat<W>(1.0));
  const Vec<W> t = SelectLess<W>(a, Splat<W>(kTanhSmall), small, large);  // NaN: large, NaN
  const Bits<W> sign = ToBits<W>(x) & BroadcastBits<W>(INT64_MIN);
  return FromBits<W>(ToBits<W>(t) | sign);
}

}  // namespace bistable

#endif  // BISTABLE_DYNAMICS_LANE_MATH_H_
