// Lane packs: W doubles processed side by side (structure of arrays, one grid point per lane).
// Vec<W> is a GCC/Clang vector extension; + - * / and comparisons act per lane with plain IEEE
// semantics. Built with -ffp-contract=off, every lane computes exactly the operations a scalar
// run would, so a point's result does not depend on the lane width or on its neighbours.
#ifndef BISTABLE_DYNAMICS_LANES_H_
#define BISTABLE_DYNAMICS_LANES_H_

// Hot-path helpers of the kernel must be inlined into the step loop: with the state, tangent and
// quadratures live at once, an out-of-line call forces every lane vector through memory (measured: the
// window phase ran at half speed until these were forced).
#define BISTABLE_INLINE inline __attribute__((always_inline))
#define BISTABLE_INLINE_LAMBDA __attribute__((always_inline))

#include <cstring>
#include <type_traits>

#if defined(__x86_64__) || defined(__i386__)
#include <immintrin.h>
#endif

namespace bistable {

template <int W>
struct VecType {
  static_assert(W >= 1 && (W & (W - 1)) == 0, "lane width must be a power of two");
  typedef double type __attribute__((vector_size(8 * W)));
};
template <int W>
using Vec = typename VecType<W>::type;

// v in every lane, as one broadcast (an element loop over a run-time value compiles to one masked
// broadcast per lane). v − (+0) is v exactly (−0 and NaN included).
template <int W>
BISTABLE_INLINE Vec<W> Splat(double v) {
  return v - Vec<W>{};
}
// Lane-wise operations through the vector instructions of the widest unit the target has, on
// 8-lane (AVX-512) or 4-lane (AVX) chunks of a pack, and the scalar operation otherwise.
// Chunk i of a pack (lanes i .. i + sizeof(C)/8) as the vector register type C, and back.
template <class C, class T>
BISTABLE_INLINE C LoadChunk(const T& v, int i) {
  C c;
  std::memcpy(&c, reinterpret_cast<const char*>(&v) + 8 * i, sizeof(C));
  return c;
}
template <class C, class T>
BISTABLE_INLINE void StoreChunk(T* v, int i, const C& c) {
  std::memcpy(reinterpret_cast<char*>(v) + 8 * i, &c, sizeof(C));
}

template <class C, class T, class Op, class... Ts>
BISTABLE_INLINE T MapChunks(Op op, const T& a, const Ts&... more) {
  constexpr int n = static_cast<int>(sizeof(T) / sizeof(double)), k = static_cast<int>(sizeof(C) / sizeof(double));
  T r;
  for (int i = 0; i < n; i += k) StoreChunk(&r, i, C(op(LoadChunk<C>(a, i), LoadChunk<C>(more, i)...)));
  return r;
}

// op512 / op256 take and return __m512d / __m256d (generic lambdas: instantiated only where the target
// has the unit), op1 doubles; all three must compute exactly the same thing. A target without the unit
// leaves op512 (or op256) unused.
template <class Op512, class Op256, class Op1, class T, class... Ts>
BISTABLE_INLINE T LaneOp([[maybe_unused]] Op512 op512, [[maybe_unused]] Op256 op256, Op1 op1, const T& a,
                         const Ts&... more) {
  constexpr int n = static_cast<int>(sizeof(T) / sizeof(double));
#if defined(__AVX512F__)
  if constexpr (n % 8 == 0) return MapChunks<__m512d>(op512, a, more...);
#endif
#if defined(__AVX__)
  if constexpr (n % 4 == 0) return MapChunks<__m256d>(op256, a, more...);
#endif
  T r;
  for (int l = 0; l < n; ++l) r[l] = op1(static_cast<double>(a[l]), static_cast<double>(more[l])...);
  return r;
}

#if defined(__AVX__) && !defined(__FMA__)
#error "AVX without FMA: build for x86-64-v3 or newer (the kernel's fused multiply-adds need FMA)"
#endif

// Lanes per kernel call in sweeps: one vector register per lane vector — 8 on AVX-512, 4 on AVX2
// (x86-64-v3, the portable build: 8 lanes there run at an eighth of 4; bench/kernel_ratio.sh,
// docs/numerics.md), 4 emulated lane by lane where the build has no vector unit. A property of the
// build (its -march), not asked of the CPU at run time. Results do not depend on it: a lane's bits are
// the same at every width. The engine (engine/evaluate.h) and every benchmark run this width;
// dynamics/host_lanes.h says it, with the CPU, for benchmark headers and map provenance.
// kLaneIsa: the vector unit the lanes use, by the same test as LaneOp.
#if defined(__AVX512F__)
inline constexpr int kSweepLanes = 8;
inline constexpr const char* kLaneIsa = "AVX-512";
#elif defined(__AVX2__)
inline constexpr int kSweepLanes = 4;
inline constexpr const char* kLaneIsa = "AVX2+FMA";
#elif defined(__AVX__)
inline constexpr int kSweepLanes = 4;
inline constexpr const char* kLaneIsa = "AVX+FMA";
#else
inline constexpr int kSweepLanes = 4;
inline constexpr const char* kLaneIsa = "scalar";
#endif

// a·b + c rounded once (IEEE 754 fusedMultiplyAdd), lane by lane. Exact and deterministic, so a lane
// gets the same bits at every width and in the one-point path (W = 1). The kernel's arithmetic is
// written with it explicitly; the compiler never contracts on its own (-ffp-contract=off). (GCC does
// not reliably vectorise an element loop of __builtin_fma inside the big step functions, hence the
// explicit instructions.)
template <class T>
BISTABLE_INLINE T Fma(T a, T b, T c) {
  return LaneOp([](auto x, auto y, auto z) BISTABLE_INLINE_LAMBDA { return _mm512_fmadd_pd(x, y, z); },
                [](auto x, auto y, auto z) BISTABLE_INLINE_LAMBDA { return _mm256_fmadd_pd(x, y, z); },
                [](double x, double y, double z) BISTABLE_INLINE_LAMBDA { return __builtin_fma(x, y, z); }, a, b, c);
}
template <class T>
BISTABLE_INLINE T Fma(double a, T b, T c) {
  return Fma(a - T{}, b, c);  // a in every lane as one broadcast (see Splat)
}

// Bit l set when lane l of a is > 0 (clear for NaN), for packs of up to 64 lanes: one compare into a
// mask per chunk (a lane-by-lane loop over a vector compare compiles to extracts).
template <class T>
BISTABLE_INLINE unsigned long PositiveMask(const T& a) {
  constexpr int n = static_cast<int>(sizeof(T) / sizeof(double));
  static_assert(n <= 64, "at most 64 lanes");
  unsigned long m = 0;
  // One compare per chunk; `bits` turns it into the chunk's lane bits.
  auto chunks = [&a, &m](auto zero, auto bits) BISTABLE_INLINE_LAMBDA {
    using C = decltype(zero);
    for (int i = 0; i < n; i += static_cast<int>(sizeof(C) / sizeof(double)))
      m |= static_cast<unsigned long>(bits(LoadChunk<C>(a, i), zero)) << i;
    return m;
  };
#if defined(__AVX512F__)
  if constexpr (n % 8 == 0)
    return chunks(_mm512_setzero_pd(), [](__m512d c, __m512d z) { return _mm512_cmp_pd_mask(c, z, _CMP_GT_OQ); });
#endif
#if defined(__AVX__)
  if constexpr (n % 4 == 0)
    return chunks(_mm256_setzero_pd(),
                  [](__m256d c, __m256d z) { return _mm256_movemask_pd(_mm256_cmp_pd(c, z, _CMP_GT_OQ)); });
#endif
  for (int l = 0; l < n; ++l) m |= static_cast<unsigned long>(a[l] > 0.0) << l;
  return m;
}

// a > b ? a : b and a < b ? a : b per lane — exactly (MAXPD/MINPD return their first
// operand only when it compares greater/less, as the expressions do; zeros and NaNs alike). Written
// with the instructions because GCC turns the vector ?: into compares, mask moves and blends.
template <int W>
BISTABLE_INLINE Vec<W> Max(Vec<W> a, Vec<W> b) {
  return LaneOp([](auto x, auto y) BISTABLE_INLINE_LAMBDA { return _mm512_max_pd(x, y); },
                [](auto x, auto y) BISTABLE_INLINE_LAMBDA { return _mm256_max_pd(x, y); },
                [](double x, double y) BISTABLE_INLINE_LAMBDA { return x > y ? x : y; }, a, b);
}
template <int W>
BISTABLE_INLINE Vec<W> Min(Vec<W> a, Vec<W> b) {
  return LaneOp([](auto x, auto y) BISTABLE_INLINE_LAMBDA { return _mm512_min_pd(x, y); },
                [](auto x, auto y) BISTABLE_INLINE_LAMBDA { return _mm256_min_pd(x, y); },
                [](double x, double y) BISTABLE_INLINE_LAMBDA { return x < y ? x : y; }, a, b);
}
// √a per lane, correctly rounded (IEEE 754) like std::sqrt.
template <int W>
BISTABLE_INLINE Vec<W> Sqrt(Vec<W> a) {
  return LaneOp([](auto x) BISTABLE_INLINE_LAMBDA { return _mm512_sqrt_pd(x); },
                [](auto x) BISTABLE_INLINE_LAMBDA { return _mm256_sqrt_pd(x); },
                [](double x) BISTABLE_INLINE_LAMBDA { return __builtin_sqrt(x); }, a);
}
// |a| per lane: the sign bit cleared (IEEE 754 abs; |−0| = +0).
template <int W>
BISTABLE_INLINE Vec<W> Abs(Vec<W> a) {
  return LaneOp([](auto x) BISTABLE_INLINE_LAMBDA { return _mm512_abs_pd(x); },
                [](auto x) BISTABLE_INLINE_LAMBDA { return _mm256_andnot_pd(-decltype(x){}, x); },
                [](double x) BISTABLE_INLINE_LAMBDA { return __builtin_fabs(x); }, a);
}

// a < b ? x : y per lane (false for NaN): one compare into a mask and a blend per chunk.
template <int W>
BISTABLE_INLINE Vec<W> SelectLess(Vec<W> a, Vec<W> b, Vec<W> x, Vec<W> y) {
  return LaneOp([](auto a, auto b, auto x, auto y)
                    BISTABLE_INLINE_LAMBDA { return _mm512_mask_blend_pd(_mm512_cmp_pd_mask(a, b, _CMP_LT_OQ), y, x); },
                [](auto a, auto b, auto x, auto y)
                    BISTABLE_INLINE_LAMBDA { return _mm256_blendv_pd(y, x, _mm256_cmp_pd(a, b, _CMP_LT_OQ)); },
                [](double a, double b, double x, double y) BISTABLE_INLINE_LAMBDA { return a < b ? x : y; }, a, b, x,
                y);
}

// Scalar overloads so that models written for T = Vec<W> also compile for T = double.
inline double Max(double a, double b) { return a > b ? a : b; }
inline double Min(double a, double b) { return a < b ? a : b; }
// |a| for T = double or a lane pack (the lane width from the type).
template <class T>
BISTABLE_INLINE T AbsOf(T a) {
  if constexpr (std::is_floating_point_v<T>)
    return __builtin_fabs(a);
  else
    return Abs<static_cast<int>(sizeof(T) / sizeof(double))>(a);
}

}  // namespace bistable

#endif  // BISTABLE_DYNAMICS_LANES_H_
