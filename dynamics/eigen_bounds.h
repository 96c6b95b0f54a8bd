// A GCC 12 false positive around Eigen, suppressed where it fires: an assignment to or from an Eigen block
// of run-time size over a small fixed-size vector (z.segment(D, D) /= n, v.tail(n) = J * w, VectorXd x =
// Vector4d) instantiates Eigen's loop over whole AVX-512 packets of 8 doubles, which never runs for blocks
// shorter than a packet; GCC 12 still checks that loop's loads and stores against the smaller object and
// warns "array subscript '__m512d[0]' is partly outside array bounds of 'Matrix<double, 4, 1>'"
// (-Warray-bounds, -Wstringop-overread). Code between BISTABLE_EIGEN_BOUNDS_BEGIN and _END is compiled
// exactly the same; only those two warnings are not reported there.
#ifndef BISTABLE_DYNAMICS_EIGEN_BOUNDS_H_
#define BISTABLE_DYNAMICS_EIGEN_BOUNDS_H_

#if defined(__GNUC__) && !defined(__clang__) && __GNUC__ >= 11
#define BISTABLE_EIGEN_BOUNDS_BEGIN                                                   \
  _Pragma("GCC diagnostic push") _Pragma("GCC diagnostic ignored \"-Warray-bounds\"") \
      _Pragma("GCC diagnostic ignored \"-Wstringop-overread\"")
#define BISTABLE_EIGEN_BOUNDS_END _Pragma("GCC diagnostic pop")
#else
#define BISTABLE_EIGEN_BOUNDS_BEGIN
#define BISTABLE_EIGEN_BOUNDS_END
#endif

#endif  // BISTABLE_DYNAMICS_EIGEN_BOUNDS_H_
