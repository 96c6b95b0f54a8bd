#include "design/design_search.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <numeric>

#include <nlopt.hpp>

#include "dynamics/cancel.h"

namespace bistable {
namespace {

constexpr double kMotionChaotic = 2, kMotionUndefined = -1;

// Length of [a, b] where the linear interpolant between ga (at a) and gb (at b) is < 0.
double NegativeLength(double a, double b, double ga, double gb) {
  const bool na = ga < 0, nb = gb < 0;
  if (na && nb) return b - a;
  if (!na && !nb) return 0;
  if (!std::isfinite(ga) || !std::isfinite(gb)) return 0;  // a NaN end: no crossing to interpolate
  const double t = ga / (ga - gb);                         // the zero crossing, as a fraction of the cell
  return (na ? t : 1 - t) * (b - a);
}

// NLopt's C-style objective calling a std::function<double(x)>.
double Trampoline(const std::vector<double>& x, std::vector<double>&, void* data) {
  return (*static_cast<std::function<double(const std::vector<double>&)>*>(data))(x);
}

}  // namespace

DesignScore ScoreDesign(const std::vector<double>& omega, size_t n_alpha, const std::vector<double>& frf_db,
                        const std::vector<double>& motion, const std::vector<double>& lle, double chaos_threshold) {
  const size_t n = omega.size();
  std::vector<double> g(n, -INFINITY);
  std::vector<bool> chaotic(n, false), unsafe(n, false);
  for (size_t a = 0; a < n_alpha; ++a)
    for (size_t i = 0; i < n; ++i) {
      const size_t k = a * n + i;
      const double f = frf_db[k];
      g[i] = std::isnan(f) || std::isnan(g[i]) ? NAN : std::max(g[i], f);
      const bool c = motion[k] == kMotionChaotic || lle[k] > chaos_threshold;
      chaotic[i] = chaotic[i] || c;
      unsafe[i] = unsafe[i] || c || motion[k] == kMotionUndefined || std::isnan(f);
    }
  DesignScore s;
  long chaotic_points = 0;
  for (size_t i = 0; i < n; ++i) {
    chaotic_points += chaotic[i];
    if (!(g[i] < 0)) continue;
    ++s.band_points;
    s.chaotic_in_band += chaotic[i];
    s.unsafe_in_band += unsafe[i];
  }
  for (size_t i = 0; i + 1 < n; ++i) {
    const double len = NegativeLength(omega[i], omega[i + 1], g[i], g[i + 1]);
    if (len <= 0) continue;
    s.band_width += len;
    const bool bad = (g[i] < 0 && unsafe[i]) || (g[i + 1] < 0 && unsafe[i + 1]);
    if (!bad) s.safe_band_width += len;
    const double lo = g[i] < 0 ? omega[i] : omega[i + 1] - len, hi = g[i + 1] < 0 ? omega[i + 1] : omega[i] + len;
    s.band_lo = std::isnan(s.band_lo) ? lo : std::min(s.band_lo, lo);
    s.band_hi = std::isnan(s.band_hi) ? hi : std::max(s.band_hi, hi);
  }
  if (n == 1 && g[0] < 0) s.band_lo = s.band_hi = omega[0];
  s.chaotic_share_band =
      s.band_points ? static_cast<double>(s.chaotic_in_band) / static_cast<double>(s.band_points) : 0;
  s.unsafe_share_band = s.band_points ? static_cast<double>(s.unsafe_in_band) / static_cast<double>(s.band_points) : 0;
  s.chaotic_share = n ? static_cast<double>(chaotic_points) / static_cast<double>(n) : 0;
  return s;
}

bool Dominates(const Candidate& a, const Candidate& b) {
  const double wa = a.score.band_width, wb = b.score.band_width;
  const double sa = a.score.unsafe_share_band, sb = b.score.unsafe_share_band;  // chaotic or diverged
  if (!(wa >= wb && sa <= sb && a.cost <= b.cost)) return false;
  return wa > wb || sa < sb || a.cost < b.cost;
}

std::vector<int> ParetoFront(const std::vector<Candidate>& c) {
  std::vector<int> front;
  for (size_t i = 0; i < c.size(); ++i) {
    bool dominated = false;
    for (size_t j = 0; j < c.size() && !dominated; ++j) dominated = j != i && Dominates(c[j], c[i]);
    // The optimiser may propose a design twice: the front lists each design once (its first evaluation).
    const bool repeat = std::any_of(front.begin(), front.end(), [&](int f) { return c[f].x == c[i].x; });
    if (!dominated && !repeat) front.push_back(static_cast<int>(i));
  }
  std::stable_sort(front.begin(), front.end(),
                   [&](int a, int b) { return c[a].score.band_width > c[b].score.band_width; });
  return front;
}

std::vector<int> BestCandidates(const std::vector<Candidate>& c, int k) {
  std::vector<int> order;
  for (size_t i = 0; i < c.size(); ++i)
    if (c[i].score.feasible()) order.push_back(static_cast<int>(i));
  std::stable_sort(order.begin(), order.end(), [&](int a, int b) {
    if (c[a].score.band_width != c[b].score.band_width) return c[a].score.band_width > c[b].score.band_width;
    return c[a].cost < c[b].cost;
  });
  std::vector<int> out;
  for (int i : order) {
    if (static_cast<int>(out.size()) >= k) break;
    if (std::none_of(out.begin(), out.end(), [&](int j) { return c[j].x == c[i].x; })) out.push_back(i);
  }
  return out;
}

int BestCandidate(const std::vector<Candidate>& c) {
  const auto b = BestCandidates(c, 1);
  return b.empty() ? -1 : b[0];
}

StatusOr<SearchResult> RunDesignSearch(const DesignSpec& spec, const SweepRunner& run,
                                       const std::function<void(const Candidate&)>& on_candidate) {
  const auto t0 = std::chrono::steady_clock::now();
  std::vector<int> free;
  for (int k = 0; k < 3; ++k)
    if (spec.Free(k)) free.push_back(k);
  SearchResult r;
  Status error;
  // The objective NLopt minimises: minus the safe band width of the candidate's sub-sweep.
  auto evaluate = [&](const std::vector<double>& u) -> double {
    if (CancelRequested()) {
      r.interrupted = true;
      throw nlopt::forced_stop();
    }
    DesignPoint x = spec.lo;
    for (size_t i = 0; i < free.size(); ++i) x[free[i]] = std::clamp(u[i], spec.lo[free[i]], spec.hi[free[i]]);
    auto out = run(spec.CandidateToml(x));
    if (!out.ok()) {
      if (CancelRequested())
        r.interrupted = true;
      else
        error = out.status();
      throw nlopt::forced_stop();
    }
    Candidate c;
    c.index = static_cast<int>(r.candidates.size());
    c.x = x;
    c.cost = x[spec.CostIndex()];
    c.score = ScoreDesign(spec.omega, spec.alphas.size(), out->frf_db, out->motion, out->lle, spec.chaos_threshold);
    c.sweep_id = out->sweep_id;
    c.items = out->items;
    c.computed = out->items - out->cached;
    c.seconds = out->seconds;
    r.items += c.items;
    r.computed += c.computed;
    r.candidates.push_back(c);
    if (on_candidate) on_candidate(c);
    return -c.score.safe_band_width;
  };
  std::function<double(const std::vector<double>&)> f = evaluate;
  nlopt::srand(spec.seed);  // CRS2's population (DIRECT-L uses no random numbers)
  nlopt::opt opt(spec.optimizer == "crs2" ? nlopt::GN_CRS2_LM : nlopt::GN_DIRECT_L, static_cast<unsigned>(free.size()));
  std::vector<double> lo, hi, u;
  for (int k : free) lo.push_back(spec.lo[k]), hi.push_back(spec.hi[k]), u.push_back(0.5 * (spec.lo[k] + spec.hi[k]));
  opt.set_lower_bounds(lo);
  opt.set_upper_bounds(hi);
  opt.set_min_objective(Trampoline, &f);
  // Global stage (two thirds of the budget), then a local stage from the best design so far (the rest):
  // DIRECT samples box centres and never reaches the bounds, where the widest band often lies (a heavier,
  // more damped resonator); the local simplex walks there.
  const int global_evals = spec.budget < 6 ? spec.budget : (2 * spec.budget + 2) / 3;
  opt.set_maxeval(global_evals);
  auto run_stage = [&](nlopt::opt& o, std::vector<double>& start) {
    double value = 0;
    try {
      o.optimize(start, value);
    } catch (const nlopt::forced_stop&) {
    } catch (const std::exception& e) {
      // NLopt's own stop (roundoff) ends the stage with what was evaluated; anything else is an error.
      if (error.ok() && !r.interrupted && r.candidates.empty())
        error = Status::Internal(std::string("optimiser: ") + e.what());
    }
  };
  run_stage(opt, u);
  const int left = spec.budget - static_cast<int>(r.candidates.size());
  if (error.ok() && !r.interrupted && left > 0 && !r.candidates.empty()) {
    int from = 0;
    for (const Candidate& c : r.candidates)
      if (c.score.safe_band_width > r.candidates[from].score.safe_band_width) from = c.index;
    nlopt::opt local(nlopt::LN_SBPLX, static_cast<unsigned>(free.size()));
    local.set_lower_bounds(lo);
    local.set_upper_bounds(hi);
    local.set_maxeval(left);
    std::vector<double> step;
    for (size_t i = 0; i < free.size(); ++i) step.push_back(0.1 * (hi[i] - lo[i]));
    local.set_initial_step(step);
    local.set_min_objective(Trampoline, &f);
    std::vector<double> v;
    for (int k : free) v.push_back(r.candidates[from].x[k]);
    run_stage(local, v);
  }
  if (!error.ok()) return error;
  r.front = ParetoFront(r.candidates);
  r.best = BestCandidate(r.candidates);
  r.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return r;
}

std::vector<Candidate> ScoreBruteForce(const DesignSpec& spec, const std::vector<std::string>& dim_names,
                                       const std::vector<size_t>& dims, const std::vector<double>& frf_db,
                                       const std::vector<double>& motion, const std::vector<double>& lle,
                                       const std::vector<std::vector<double>>& axis_values) {
  // Strides of the row-major array, and which dimension holds each design parameter, alpha, omega.
  const size_t nd = dims.size();
  std::vector<size_t> stride(nd, 1);
  for (size_t d = nd; d-- > 1;) stride[d - 1] = stride[d] * dims[d];
  auto dim_of = [&](const std::string& name) -> int {
    for (size_t d = 0; d < nd; ++d)
      if (dim_names[d] == name) return static_cast<int>(d);
    return -1;
  };
  const int d_omega = dim_of("omega"), d_alpha = dim_of("alpha");
  std::array<int, 3> d_par{};
  for (int k = 0; k < 3; ++k) d_par[k] = dim_of(kDesignParameters[k]);
  const size_t n_alpha = d_alpha >= 0 ? dims[d_alpha] : 1, n_omega = d_omega >= 0 ? dims[d_omega] : 1;
  std::array<size_t, 3> n{};
  for (int k = 0; k < 3; ++k) n[k] = d_par[k] >= 0 ? dims[d_par[k]] : 1;
  std::vector<Candidate> out;
  std::vector<double> f(n_alpha * n_omega), m(f.size()), l(f.size());
  for (size_t i0 = 0; i0 < n[0]; ++i0)
    for (size_t i1 = 0; i1 < n[1]; ++i1)
      for (size_t i2 = 0; i2 < n[2]; ++i2) {
        const std::array<size_t, 3> idx = {i0, i1, i2};
        size_t base = 0;
        Candidate c;
        c.index = static_cast<int>(out.size());
        c.x = spec.lo;
        for (int k = 0; k < 3; ++k)
          if (d_par[k] >= 0) base += idx[k] * stride[d_par[k]], c.x[k] = axis_values[d_par[k]][idx[k]];
        for (size_t a = 0; a < n_alpha; ++a)
          for (size_t w = 0; w < n_omega; ++w) {
            const size_t at =
                base + (d_alpha >= 0 ? a * stride[d_alpha] : 0) + (d_omega >= 0 ? w * stride[d_omega] : 0);
            f[a * n_omega + w] = frf_db[at], m[a * n_omega + w] = motion[at], l[a * n_omega + w] = lle[at];
          }
        c.cost = c.x[spec.CostIndex()];
        c.score = ScoreDesign(spec.omega, n_alpha, f, m, l, spec.chaos_threshold);
        c.items = static_cast<long>(n_alpha * n_omega);
        out.push_back(c);
      }
  return out;
}

}  // namespace bistable
