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

}  // namespace bistable

#endif  // BISTABLE_ENGINE_QUERY_H_
