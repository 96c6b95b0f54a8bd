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

namespace bistable {

template <int W>
struct VecType {
  static_assert(W >= 1 && (W & (W - 1)) == 0, "lane width must be a power of two");
  typedef double type __attribute__((vector_size(8 * W)));
};
template <int W>
using Vec = typename VecType<W>::type;

template <int W>
inline Vec<W> Broadcast(double v) {
  Vec<W> r;
  for (int i = 0; i < W; ++i) r[i] = v;
  return r;
}
template <int W>
inline Vec<W> Max(Vec<W> a, Vec<W> b) { return a > b ? a : b; }
template <int W>
inline Vec<W> Min(Vec<W> a, Vec<W> b) { return a < b ? a : b; }
template <int W>
inline Vec<W> Abs(Vec<W> a) { return a < 0.0 ? -a : a; }

// Scalar overloads so that models written for T = Vec<W> also compile for T = double.
inline double Max(double a, double b) { return a > b ? a : b; }
inline double Min(double a, double b) { return a < b ? a : b; }

}  // namespace bistable

#endif  // BISTABLE_DYNAMICS_LANES_H_
