// Region queries over a map: `frf_db < -3 and lle < 0.01`, `motion == chaotic or (alpha > 1 and
// not edr_t < 20)`. Grammar: expr := and ('or' and)*; and := unary ('and' unary)*;
// unary := 'not' unary | '(' expr ')' | operand op operand; op ∈ < <= > >= == !=;
// operand := name | number | a motion name: intrawell | interwell | chaotic | undefined (the motion
// codes 0, 1, 2, -1; MotionCodeOfName).
// Comparisons with NaN are false. A query is at most limits::kMaxQueryBytes long and nests parentheses
// and `not` at most limits::kMaxQueryDepth deep (the parser and the evaluation recurse).
#ifndef BISTABLE_ENGINE_QUERY_H_
#define BISTABLE_ENGINE_QUERY_H_

#include <cstddef>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "base/limits.h"
#include "base/status.h"

namespace bistable {

// Bounds on a query expression (a client's text; errors name field "query" and the bound).

class Query {
 public:
  // `names` are the variables the query may use (metrics and axes); the message of a bad query names
  // the position and, for an unknown name, the nearest known one.
  static StatusOr<Query> Parse(const std::string& text, const std::vector<std::string>& names);
  // Variables the query reads, as indices into `names`.
  const std::vector<int>& used() const { return used_; }
  // value(i) returns variable i (index into `names`) at the point being tested.
  bool Eval(const std::function<double(int)>& value) const;

  struct Node;

 private:
  std::shared_ptr<const Node> root_;
  std::vector<int> used_;
};

struct Axis;

// A query evaluated over every item of a map (items = points in row-major order over `axes`, last axis
// fastest, × per_point items each). Variable v < axes.size() is axis v's value; any other variable the
// query uses is read from column(v): one value per item, or one per point (then shared by its items).
// on_match(item, axis indices) is called for every item where the query holds (may be empty).
// Area: each item weighs the product of its cells' widths (midpoint rule), for area_fraction.
struct QueryScan {
  long count = 0;
  size_t total = 0;
  double fraction = 0, area_fraction = 0;
};
QueryScan ScanQuery(const Query& q, const std::vector<Axis>& axes, size_t per_point,
                    const std::function<const std::vector<double>&(int)>& column,
                    const std::function<void(size_t, const std::vector<size_t>&)>& on_match);

}  // namespace bistable

#endif  // BISTABLE_ENGINE_QUERY_H_
