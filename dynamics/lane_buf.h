// Lane storage whose size is a compile-time constant (stack) or known only at run time (heap), so
// one lane-model source serves a fixed layout (a chain of 2 cells) and any other (a chain of 40).
#ifndef BISTABLE_DYNAMICS_LANE_BUF_H_
#define BISTABLE_DYNAMICS_LANE_BUF_H_

#include <vector>

#include "dynamics/lanes.h"

namespace bistable {

// N lane vectors: on the stack when N is known at compile time, on the heap when N = 0 (run time).
template <class V, int N>
struct LaneBuf {
  explicit LaneBuf(int) {}
  V v[N];
  BISTABLE_INLINE V& operator[](int i) { return v[i]; }
  BISTABLE_INLINE const V& operator[](int i) const { return v[i]; }
  V* data() { return v; }
  const V* data() const { return v; }
};
template <class V>
struct LaneBuf<V, 0> {
  explicit LaneBuf(int n) : v(n) {}
  std::vector<V> v;
  V& operator[](int i) { return v[i]; }
  const V& operator[](int i) const { return v[i]; }
  V* data() { return v.data(); }
  const V* data() const { return v.data(); }
};

}  // namespace bistable

#endif  // BISTABLE_DYNAMICS_LANE_BUF_H_
