#include "engine/content_hash.h"

#include <algorithm>
#include <charconv>
#include <cstdio>
#include <cstring>

#define XXH_INLINE_ALL
#include <xxhash.h>

namespace bistable {

std::string ContentHashHex(const std::string& text) {
  const XXH128_hash_t h = XXH3_128bits(text.data(), text.size());
  char buf[33];
  std::snprintf(buf, sizeof buf, "%016llx%016llx", static_cast<unsigned long long>(h.high64),
                static_cast<unsigned long long>(h.low64));
  return buf;
}

namespace {

// The canonical text of a point: name=value fields, doubles in the shortest form that reads back to
// the same bits (std::to_chars; printf's %.17g cost ~5 µs per point, most of a plan).
class KeyText {
 public:
  KeyText& Field(const char* name, double v) {
    Name(name);
    const auto r = std::to_chars(buf_ + n_, buf_ + sizeof buf_, v);
    n_ = static_cast<size_t>(r.ptr - buf_);
    return *this;
  }
  KeyText& Field(const char* name, long v) {
    Name(name);
    const auto r = std::to_chars(buf_ + n_, buf_ + sizeof buf_, v);
    n_ = static_cast<size_t>(r.ptr - buf_);
    return *this;
  }
  KeyText& Field(const char* name, const char* v) {
    Name(name);
    Append(v, std::strlen(v));
    return *this;
  }
  std::string Hash() const { return ContentHashHex(std::string(buf_, n_)); }

 private:
  void Name(const char* name) {
    if (n_ > 0) Append("|", 1);
    Append(name, std::strlen(name));
    Append("=", 1);
  }
  void Append(const char* s, size_t len) {
    len = std::min(len, sizeof buf_ - 32 - n_);  // the fields are a fixed, short list: never reached
    std::memcpy(buf_ + n_, s, len);
    n_ += len;
  }
  char buf_[1024];
  size_t n_ = 0;
};

}  // namespace

std::string PointKey(const PointSpec& p) {
  const auto ic = InitialState(p);
  const IntegrationSettings& in = p.integration;
  const MetricSettings& m = p.metrics;
  KeyText t;
  t.Field("v", kNumericsVersion).Field("model", ModelName(p.model)).Field("alpha", p.alpha).Field("omega", p.omega);
  t.Field("eps", p.params.eps).Field("eta", p.params.eta).Field("eta_r", p.params.eta_r).Field("phi", p.params.phi);
  t.Field("lambda", p.params.lambda).Field("integ", IntegratorName(in.integrator)).Field("dt", in.dt);
  t.Field("t_end", in.t_end).Field("t_keep", in.t_keep).Field("rtol", in.rtol).Field("atol", in.atol);
  t.Field("renorm", static_cast<long>(m.renorm_every)).Field("chaos", m.chaos_threshold);
  t.Field("sample", static_cast<long>(m.sample_every)).Field("ptol", m.period_tol);
  t.Field("pmax", static_cast<long>(m.max_period)).Field("hdl", m.hd_level).Field("hdk", static_cast<long>(m.hd_top_k));
  t.Field("ros", static_cast<long>(m.rosenstein ? 1 : 0)).Field("tp", static_cast<long>(m.turning_points ? 1 : 0));
  t.Field("ic0", ic[0]).Field("ic1", ic[1]).Field("ic2", ic[2]).Field("ic3", ic[3]);
  // The section changes the record (its phase also the period's strobes): keyed only when set, so the
  // keys of points without one stay those already cached.
  if (m.poincare_points > 0 || m.poincare_phase != 0)
    t.Field("pc_n", static_cast<long>(m.poincare_points)).Field("pc_phase", m.poincare_phase);
  // A term model's parameters (issue 42), keyed only when there are some: no other point's key changes.
  for (size_t k = 0; k < p.theta.size(); ++k) t.Field("th", p.theta[k]);
  return t.Hash();
}

}  // namespace bistable
