#include "engine/query.h"

#include <cctype>
#include <cmath>
#include <cstdlib>
#include <set>

#include "base/names.h"
#include "engine/metric_catalog.h"
#include "engine/sweep_spec.h"

namespace bistable {

struct Query::Node {
  enum Kind { kOr, kAnd, kNot, kCmp } kind;
  std::shared_ptr<const Node> a, b;
  // kCmp: operands are variables (var ≥ 0) or constants.
  int var_l = -1, var_r = -1;
  double c_l = 0, c_r = 0;
  std::string op{};
};

namespace {

struct Token {
  enum Kind { kName, kNumber, kOp, kLParen, kRParen, kEnd } kind;
  std::string text;
  double number = 0;
  size_t pos = 0;
};

class Parser {
 public:
  Parser(const std::string& text, const std::vector<std::string>& names) : text_(text), names_(names) {}

  StatusOr<std::shared_ptr<const Query::Node>> Run(std::vector<int>* used) {
    if (text_.size() > limits::kMaxQueryBytes)
      return Status::InvalidArgument(
          "query", "query of " + std::to_string(text_.size()) +
                       " bytes violates length <= " + std::to_string(limits::kMaxQueryBytes) + " bytes");
    Status st = Tokenize();
    if (!st.ok()) return st;
    auto e = Or();
    if (!e.ok()) return e;
    if (Peek().kind != Token::kEnd) return Error("unexpected '" + Peek().text + "'");
    *used = std::vector<int>(used_.begin(), used_.end());
    return e;
  }

 private:
  Status Error(const std::string& what) {
    return Status::InvalidArgument("query",
                                   "query '" + Shown() + "' at " + std::to_string(Peek().pos + 1) + ": " + what);
  }
  // The query as quoted in messages: long ones cut to their start.
  std::string Shown() const { return text_.size() <= 200 ? text_ : text_.substr(0, 200) + "..."; }
  const Token& Peek() const { return toks_[i_]; }
  Token Next() { return toks_[i_ < toks_.size() - 1 ? i_++ : i_]; }
  bool IsWord(const char* w) const { return Peek().kind == Token::kName && Peek().text == w; }

  Status Tokenize() {
    size_t p = 0;
    while (p < text_.size()) {
      const char c = text_[p];
      if (std::isspace(static_cast<unsigned char>(c))) {
        ++p;
      } else if (std::isalpha(static_cast<unsigned char>(c)) || c == '_') {
        size_t q = p;
        while (q < text_.size() && (std::isalnum(static_cast<unsigned char>(text_[q])) || text_[q] == '_')) ++q;
        toks_.push_back({Token::kName, text_.substr(p, q - p), 0, p});
        p = q;
      } else if (std::isdigit(static_cast<unsigned char>(c)) || c == '.' || c == '-' || c == '+') {
        char* end = nullptr;
        const double v = std::strtod(text_.c_str() + p, &end);
        if (end == text_.c_str() + p)
          return Status::InvalidArgument("query",
                                         "query '" + Shown() + "' at " + std::to_string(p + 1) + ": bad number");
        toks_.push_back({Token::kNumber, text_.substr(p, end - (text_.c_str() + p)), v, p});
        p = end - text_.c_str();
      } else if (c == '(' || c == ')') {
        toks_.push_back({c == '(' ? Token::kLParen : Token::kRParen, std::string(1, c), 0, p});
        ++p;
      } else if (c == '<' || c == '>' || c == '=' || c == '!') {
        std::string op(1, c);
        if (p + 1 < text_.size() && text_[p + 1] == '=') op += '=';
        if (op == "!")
          return Status::InvalidArgument("query",
                                         "query '" + Shown() + "' at " + std::to_string(p + 1) + ": '!' must be '!='");
        if (op == "=") op = "==";
        toks_.push_back({Token::kOp, op, 0, p});
        p += (p + 1 < text_.size() && text_[p + 1] == '=') ? 2 : 1;
      } else {
        return Status::InvalidArgument("query", "query '" + Shown() + "' at " + std::to_string(p + 1) +
                                                    ": unexpected '" + std::string(1, c) + "'");
      }
    }
    toks_.push_back({Token::kEnd, "end of query", 0, text_.size()});
    return Status::Ok();
  }

  StatusOr<std::shared_ptr<const Query::Node>> Or() {
    auto l = And();
    if (!l.ok()) return l;
    std::shared_ptr<const Query::Node> node = *l;
    while (IsWord("or")) {
      Next();
      auto r = And();
      if (!r.ok()) return r;
      node = std::make_shared<Query::Node>(Query::Node{Query::Node::kOr, node, *r});
    }
    return node;
  }
  StatusOr<std::shared_ptr<const Query::Node>> And() {
    auto l = Unary();
    if (!l.ok()) return l;
    std::shared_ptr<const Query::Node> node = *l;
    while (IsWord("and")) {
      Next();
      auto r = Unary();
      if (!r.ok()) return r;
      node = std::make_shared<Query::Node>(Query::Node{Query::Node::kAnd, node, *r});
    }
    return node;
  }
  // Nesting of '(' and 'not' (the recursion of Unary/Or and of the evaluation), bounded.
  struct DepthGuard {
    int* d;
    explicit DepthGuard(int* depth) : d(depth) { ++*d; }
    ~DepthGuard() { --*d; }
  };
  StatusOr<std::shared_ptr<const Query::Node>> Unary() {
    if (IsWord("not") || Peek().kind == Token::kLParen) {
      if (depth_ >= limits::kMaxQueryDepth)
        return Error("nesting of '(' and 'not' violates depth <= " + std::to_string(limits::kMaxQueryDepth));
    }
    DepthGuard guard(&depth_);
    if (IsWord("not")) {
      Next();
      auto e = Unary();
      if (!e.ok()) return e;
      return std::shared_ptr<const Query::Node>(
          std::make_shared<Query::Node>(Query::Node{Query::Node::kNot, *e, nullptr}));
    }
    if (Peek().kind == Token::kLParen) {
      Next();
      auto e = Or();
      if (!e.ok()) return e;
      if (Peek().kind != Token::kRParen) return Error("expected ')'");
      Next();
      return e;
    }
    auto node = std::make_shared<Query::Node>(Query::Node{Query::Node::kCmp, nullptr, nullptr});
    const size_t left = i_;
    Status st = Operand(&node->var_l, &node->c_l);
    if (!st.ok()) return st;
    if (Peek().kind != Token::kOp)
      return Error("expected a comparison (< <= > >= == !=) after '" + toks_[i_ - 1].text + "'");
    node->op = Next().text;
    const size_t right = i_;
    st = Operand(&node->var_r, &node->c_r);
    if (!st.ok()) return st;
    // A word that is not a variable names a code of the other side's category metric: motion == chaotic,
    // termination == diverged (the names JSON prints), either way round.
    st = ResolveWord(left, &node->var_l, &node->c_l, node->var_r);
    if (!st.ok()) return st;
    st = ResolveWord(right, &node->var_r, &node->c_r, node->var_l);
    if (!st.ok()) return st;
    return std::shared_ptr<const Query::Node>(node);
  }
  static constexpr int kWord = -2;  // an operand that is a word, resolved once both sides are known
  Status Operand(int* var, double* constant) {
    const Token t = Peek();
    if (t.kind == Token::kNumber) {
      Next();
      *constant = t.number;
      return Status::Ok();
    }
    if (t.kind != Token::kName) return Error("expected a name or a number, got '" + t.text + "'");
    Next();
    for (size_t k = 0; k < names_.size(); ++k)
      if (names_[k] == t.text) {
        *var = static_cast<int>(k);
        used_.insert(static_cast<int>(k));
        return Status::Ok();
      }
    *var = kWord;
    return Status::Ok();
  }
  // Resolves the word at token `at` (when *var is kWord) against the other operand `other`.
  Status ResolveWord(size_t at, int* var, double* constant, int other) {
    if (*var != kWord) return Status::Ok();
    const Token& t = toks_[at];
    *var = -1;
    const std::string metric = other >= 0 ? names_[other] : "";
    const std::vector<bistable::Category>& cats = MetricCategories(metric);
    for (const bistable::Category& c : cats)
      if (t.text == c.name) return *constant = c.code, Status::Ok();
    if (int code = 0; cats.empty() && MotionCodeOfName(t.text, &code)) return *constant = code, Status::Ok();
    i_ = at;
    if (!cats.empty()) {
      std::vector<std::string> names;
      for (const bistable::Category& c : cats) names.push_back(c.name);
      return Error(UnknownNameMessage(metric + " value", t.text, names));
    }
    return Error(UnknownNameMessage("name", t.text, names_));
  }

  std::string text_;
  const std::vector<std::string>& names_;
  std::vector<Token> toks_;
  size_t i_ = 0;
  int depth_ = 0;
  std::set<int> used_;
};

bool EvalNode(const Query::Node& n, const std::function<double(int)>& value) {
  switch (n.kind) {
    case Query::Node::kOr:
      return EvalNode(*n.a, value) || EvalNode(*n.b, value);
    case Query::Node::kAnd:
      return EvalNode(*n.a, value) && EvalNode(*n.b, value);
    case Query::Node::kNot:
      return !EvalNode(*n.a, value);
    case Query::Node::kCmp: {
      const double l = n.var_l >= 0 ? value(n.var_l) : n.c_l;
      const double r = n.var_r >= 0 ? value(n.var_r) : n.c_r;
      if (std::isnan(l) || std::isnan(r)) return false;
      if (n.op == "<") return l < r;
      if (n.op == "<=") return l <= r;
      if (n.op == ">") return l > r;
      if (n.op == ">=") return l >= r;
      if (n.op == "==") return l == r;
      return l != r;
    }
  }
  return false;
}

}  // namespace

StatusOr<Query> Query::Parse(const std::string& text, const std::vector<std::string>& names) {
  Parser p(text, names);
  Query q;
  auto root = p.Run(&q.used_);
  if (!root.ok()) return root.status();
  q.root_ = *root;
  return q;
}

bool Query::Eval(const std::function<double(int)>& value) const { return EvalNode(*root_, value); }

QueryScan ScanQuery(const Query& q, const std::vector<Axis>& axes, size_t per_point,
                    const std::function<const std::vector<double>&(int)>& column,
                    const std::function<void(size_t, const std::vector<size_t>&)>& on_match) {
  size_t n_points = 1;
  for (const Axis& ax : axes) n_points *= ax.values.size();
  const size_t n_items = n_points * per_point;
  const int n_axes = static_cast<int>(axes.size());
  // Cell weights: product of each axis's cell width (midpoint rule), for the area fraction.
  auto width = [](const std::vector<double>& v, size_t i) {
    if (v.size() == 1) return 1.0;
    const double lo = i == 0 ? v[0] : 0.5 * (v[i - 1] + v[i]);
    const double hi = i + 1 == v.size() ? v.back() : 0.5 * (v[i] + v[i + 1]);
    return hi - lo;
  };
  QueryScan scan;
  scan.total = n_items;
  double area = 0, area_total = 0;
  std::vector<size_t> idx(axes.size());
  for (size_t item = 0; item < n_items; ++item) {
    size_t p = item / per_point, rest = p;
    double w = 1;
    for (long k = static_cast<long>(axes.size()) - 1; k >= 0; --k) {
      idx[k] = rest % axes[k].values.size();
      rest /= axes[k].values.size();
      w *= width(axes[k].values, idx[k]);
    }
    area_total += w;
    auto value = [&](int v) -> double {
      if (v < n_axes) return axes[v].values[idx[v]];
      const std::vector<double>& m = column(v);
      return m.size() == n_items ? m[item] : m[p];
    };
    if (!q.Eval(value)) continue;
    ++scan.count;
    area += w;
    if (on_match) on_match(item, idx);
  }
  scan.fraction = n_items ? static_cast<double>(scan.count) / static_cast<double>(n_items) : 0.0;
  scan.area_fraction = area_total > 0 ? area / area_total : 0.0;
  return scan;
}

}  // namespace bistable
