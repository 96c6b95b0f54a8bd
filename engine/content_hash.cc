#include "engine/content_hash.h"

#include <cstdio>

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

std::string PointKey(const PointSpec& p) {
  const auto ic = InitialState(p);
  char buf[1024];
  const IntegrationSettings& in = p.integration;
  const MetricSettings& m = p.metrics;
  std::snprintf(buf, sizeof buf,
                "v=%s|model=%s|alpha=%.17g|omega=%.17g|eps=%.17g|eta=%.17g|eta_r=%.17g|phi=%.17g|lambda=%.17g|"
                "integ=%s|dt=%.17g|t_end=%.17g|t_keep=%.17g|rtol=%.17g|atol=%.17g|renorm=%d|chaos=%.17g|"
                "sample=%d|ptol=%.17g|pmax=%d|hdl=%.17g|hdk=%d|ros=%d|tp=%d|ic=%.17g,%.17g,%.17g,%.17g",
                kNumericsVersion, ModelName(p.model), p.alpha, p.omega, p.params.eps, p.params.eta, p.params.eta_r,
                p.params.phi, p.params.lambda, IntegratorName(in.integrator), in.dt, in.t_end, in.t_keep, in.rtol,
                in.atol, m.renorm_every, m.chaos_threshold, m.sample_every, m.period_tol, m.max_period, m.hd_level,
                m.hd_top_k, m.rosenstein ? 1 : 0, m.turning_points ? 1 : 0, ic[0], ic[1], ic[2], ic[3]);
  return ContentHashHex(buf);
}

}  // namespace bistable
