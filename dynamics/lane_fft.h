// Mixed-radix FFT over lane vectors: W independent transforms side by side, one per lane, so a
// sweep's block of W points gets its W response spectra in one pass instead of W scalar transforms.
// Every lane runs the same sequence of IEEE operations at any W (no FMA contraction in dynamics/), so
// a spectrum computed in a block of 8 equals the one-point spectrum bit for bit (map == point).
//
// Algorithm: self-sorting Stockham, decimation in frequency. A stage of radix r on sub-transforms of
// length len = r·m at stride s maps
//     y[q + s(r p + k)] = ω_len^{p k} · Σ_j x[q + s(p + j m)] ω_r^{j k}     (p < m, q < s, k < r)
// and the next stage works on length m at stride r·s; after the last stage the output is in natural
// order. Radices 4, 2, 3, 5 have hand-written butterflies, any other prime factor a direct DFT.
// Real input of even length n = 2m is packed as z_j = x_2j + i x_2j+1, transformed at length m and
// split into the n/2 + 1 bins of the real transform.
#ifndef BISTABLE_DYNAMICS_LANE_FFT_H_
#define BISTABLE_DYNAMICS_LANE_FFT_H_

#include <cmath>
#include <cstddef>
#include <vector>

#include "dynamics/lanes.h"

namespace bistable {

// ω_n^k = e^{-2πik/n} as (cos, sin) of the angle reduced to the first octant's neighbourhood, so
// twiddles are exact to the last bit wherever the symmetry makes them so (ω^{n/4} = −i exactly).
inline void Twiddle(size_t k, size_t n, double* re, double* im) {
  k %= n;
  // Quadrant by integer arithmetic: 4k/n, then the remaining angle < π/2.
  const size_t q = (4 * k) / n;
  const size_t rem = 4 * k - q * n;  // angle = (q + rem/n) · π/2
  const double a = (M_PI / 2) * static_cast<double>(rem) / static_cast<double>(n);
  const double c = std::cos(a), s = std::sin(a);
  // e^{-iθ} with θ = qπ/2 + a: rotate (cos a, −sin a) by −q·π/2.
  double x = c, y = -s;
  for (size_t i = 0; i < q; ++i) {  // multiply by −i: (x, y) → (y, −x)
    const double t = x;
    x = y;
    y = -t;
  }
  *re = x;
  *im = y;
}

template <int W>
class LaneFft {
 public:
  using V = Vec<W>;

  // Complex transform of length m ≥ 1.
  explicit LaneFft(size_t m) : m_(m) {
    size_t rest = m;
    auto take = [&](size_t r) {
      while (rest % r == 0 && rest > 1) {
        stages_.push_back({static_cast<int>(r), 0, 0, 0});
        rest /= r;
      }
    };
    take(4);
    take(2);
    take(3);
    take(5);
    for (size_t p = 7; rest > 1; p += 2) take(p);
    size_t len = m, stride = 1;
    for (Stage& st : stages_) {
      st.len = len;
      st.stride = stride;
      st.tw = twiddles_.size();
      const size_t mm = len / st.radix;
      if (mm > 1)
        for (size_t p = 0; p < mm; ++p)
          for (int k = 1; k < st.radix; ++k) {
            double re, im;
            Twiddle(p * k, len, &re, &im);
            twiddles_.push_back(re);
            twiddles_.push_back(im);
          }
      if (st.radix > 5) {  // the direct DFT's roots ω_r^k
        st.roots = roots_.size();
        for (int k = 0; k < st.radix; ++k) {
          double re, im;
          Twiddle(k, st.radix, &re, &im);
          roots_.push_back(re);
          roots_.push_back(im);
        }
      }
      len = mm;
      stride *= st.radix;
    }
  }

  size_t size() const { return m_; }

  // Forward transform (e^{-2πi jk/m}) of (re, im), m vectors each; the result is left in (re, im).
  // wre, wim: m vectors of work space.
  void Forward(V* re, V* im, V* wre, V* wim) const {
    V *xr = re, *xi = im, *yr = wre, *yi = wim;
    for (const Stage& st : stages_) {
      Pass(st, xr, xi, yr, yi);
      std::swap(xr, yr);
      std::swap(xi, yi);
    }
    if (xr != re)
      for (size_t i = 0; i < m_; ++i) re[i] = xr[i], im[i] = xi[i];
  }

 private:
  struct Stage {
    int radix;
    size_t len, stride, tw;
    size_t roots = 0;
  };

  static BISTABLE_INLINE void Rot(const double* tw, V& r, V& i) {  // (r, i) · (tw[0] + i tw[1])
    const V c = Splat<W>(tw[0]), s = Splat<W>(tw[1]);
    const V nr = r * c - i * s;
    i = r * s + i * c;
    r = nr;
  }

  void Pass(const Stage& st, const V* xr, const V* xi, V* yr, V* yi) const {
    const size_t s = st.stride, mm = st.len / st.radix;
    const double* tw = twiddles_.data() + st.tw;
    const bool twiddled = mm > 1;
    switch (st.radix) {
      case 2:
        for (size_t p = 0; p < mm; ++p)
          for (size_t q = 0; q < s; ++q) {
            const size_t i0 = q + s * p, i1 = i0 + s * mm, o = q + s * 2 * p;
            V br = xr[i0] - xr[i1], bi = xi[i0] - xi[i1];
            yr[o] = xr[i0] + xr[i1];
            yi[o] = xi[i0] + xi[i1];
            if (twiddled) Rot(tw + 2 * p, br, bi);
            yr[o + s] = br;
            yi[o + s] = bi;
          }
        break;
      case 3: {
        const V c = Splat<W>(-0.5), sn = Splat<W>(0.86602540378443864676);  // sin(2π/3)
        for (size_t p = 0; p < mm; ++p)
          for (size_t q = 0; q < s; ++q) {
            const size_t i0 = q + s * p, st_ = s * mm, o = q + s * 3 * p;
            const V t1r = xr[i0 + st_] + xr[i0 + 2 * st_], t1i = xi[i0 + st_] + xi[i0 + 2 * st_];
            const V t2r = xr[i0 + st_] - xr[i0 + 2 * st_], t2i = xi[i0 + st_] - xi[i0 + 2 * st_];
            const V mr = xr[i0] + c * t1r, mi = xi[i0] + c * t1i;
            const V nr = sn * t2i, ni = -(sn * t2r);  // −i·sin·t2
            yr[o] = xr[i0] + t1r;
            yi[o] = xi[i0] + t1i;
            V b1r = mr + nr, b1i = mi + ni, b2r = mr - nr, b2i = mi - ni;
            if (twiddled) Rot(tw + 4 * p, b1r, b1i), Rot(tw + 4 * p + 2, b2r, b2i);
            yr[o + s] = b1r, yi[o + s] = b1i;
            yr[o + 2 * s] = b2r, yi[o + 2 * s] = b2i;
          }
        break;
      }
      case 4:
        for (size_t p = 0; p < mm; ++p)
          for (size_t q = 0; q < s; ++q) {
            const size_t i0 = q + s * p, d = s * mm, o = q + s * 4 * p;
            const V t0r = xr[i0] + xr[i0 + 2 * d], t0i = xi[i0] + xi[i0 + 2 * d];
            const V t1r = xr[i0] - xr[i0 + 2 * d], t1i = xi[i0] - xi[i0 + 2 * d];
            const V t2r = xr[i0 + d] + xr[i0 + 3 * d], t2i = xi[i0 + d] + xi[i0 + 3 * d];
            const V t3r = xr[i0 + d] - xr[i0 + 3 * d], t3i = xi[i0 + d] - xi[i0 + 3 * d];
            yr[o] = t0r + t2r;
            yi[o] = t0i + t2i;
            V b1r = t1r + t3i, b1i = t1i - t3r;  // t1 − i t3
            V b2r = t0r - t2r, b2i = t0i - t2i;
            V b3r = t1r - t3i, b3i = t1i + t3r;  // t1 + i t3
            if (twiddled) Rot(tw + 6 * p, b1r, b1i), Rot(tw + 6 * p + 2, b2r, b2i), Rot(tw + 6 * p + 4, b3r, b3i);
            yr[o + s] = b1r, yi[o + s] = b1i;
            yr[o + 2 * s] = b2r, yi[o + 2 * s] = b2i;
            yr[o + 3 * s] = b3r, yi[o + 3 * s] = b3i;
          }
        break;
      case 5: {
        const V c1 = Splat<W>(0.30901699437494742410), c2 = Splat<W>(-0.80901699437494742410);
        const V s1 = Splat<W>(0.95105651629515357212), s2 = Splat<W>(0.58778525229247312917);
        for (size_t p = 0; p < mm; ++p)
          for (size_t q = 0; q < s; ++q) {
            const size_t i0 = q + s * p, d = s * mm, o = q + s * 5 * p;
            const V ar = xr[i0], ai = xi[i0];
            const V t1r = xr[i0 + d] + xr[i0 + 4 * d], t1i = xi[i0 + d] + xi[i0 + 4 * d];
            const V t2r = xr[i0 + 2 * d] + xr[i0 + 3 * d], t2i = xi[i0 + 2 * d] + xi[i0 + 3 * d];
            const V t3r = xr[i0 + d] - xr[i0 + 4 * d], t3i = xi[i0 + d] - xi[i0 + 4 * d];
            const V t4r = xr[i0 + 2 * d] - xr[i0 + 3 * d], t4i = xi[i0 + 2 * d] - xi[i0 + 3 * d];
            yr[o] = ar + t1r + t2r;
            yi[o] = ai + t1i + t2i;
            const V r1r = ar + c1 * t1r + c2 * t2r, r1i = ai + c1 * t1i + c2 * t2i;
            const V r2r = ar + c2 * t1r + c1 * t2r, r2i = ai + c2 * t1i + c1 * t2i;
            const V u1r = s1 * t3r + s2 * t4r, u1i = s1 * t3i + s2 * t4i;  // b1 = r1 − i u1
            const V u2r = s2 * t3r - s1 * t4r, u2i = s2 * t3i - s1 * t4i;  // b2 = r2 − i u2
            V b1r = r1r + u1i, b1i = r1i - u1r, b4r = r1r - u1i, b4i = r1i + u1r;
            V b2r = r2r + u2i, b2i = r2i - u2r, b3r = r2r - u2i, b3i = r2i + u2r;
            if (twiddled)
              Rot(tw + 8 * p, b1r, b1i), Rot(tw + 8 * p + 2, b2r, b2i), Rot(tw + 8 * p + 4, b3r, b3i),
                  Rot(tw + 8 * p + 6, b4r, b4i);
            yr[o + s] = b1r, yi[o + s] = b1i;
            yr[o + 2 * s] = b2r, yi[o + 2 * s] = b2i;
            yr[o + 3 * s] = b3r, yi[o + 3 * s] = b3i;
            yr[o + 4 * s] = b4r, yi[o + 4 * s] = b4i;
          }
        break;
      }
      default: {  // a prime r > 5: the direct DFT of the r inputs
        const int r = st.radix;
        const double* w = roots_.data() + st.roots;
        for (size_t p = 0; p < mm; ++p)
          for (size_t q = 0; q < s; ++q) {
            const size_t i0 = q + s * p, d = s * mm, o = q + s * r * p;
            for (int k = 0; k < r; ++k) {
              V br = xr[i0], bi = xi[i0];
              for (int j = 1; j < r; ++j) {
                const size_t jk = (static_cast<size_t>(j) * k) % r;
                const V c = Splat<W>(w[2 * jk]), sn = Splat<W>(w[2 * jk + 1]);
                const V ur = xr[i0 + j * d], ui = xi[i0 + j * d];
                br = br + (ur * c - ui * sn);
                bi = bi + (ur * sn + ui * c);
              }
              if (twiddled && k > 0) Rot(tw + 2 * ((r - 1) * p + (k - 1)), br, bi);
              yr[o + k * s] = br;
              yi[o + k * s] = bi;
            }
          }
      }
    }
  }

  size_t m_;
  std::vector<Stage> stages_;
  std::vector<double> twiddles_;  // per stage, per p < len/r, k = 1..r−1: ω_len^{pk} as (re, im)
  std::vector<double> roots_;     // the direct DFT's ω_r^k
};

// Real transform of length n ≥ 2, n/2 + 1 bins out (the half spectrum; bins k and n − k of a real
// series are conjugate).
template <int W>
class LaneRealFft {
 public:
  using V = Vec<W>;

  explicit LaneRealFft(size_t n) : n_(n), even_(n % 2 == 0), fft_(even_ ? n / 2 : n) {
    const size_t m = fft_.size();
    if (even_) {
      split_.resize(2 * (m + 1));
      for (size_t k = 0; k <= m; ++k) Twiddle(k, n, &split_[2 * k], &split_[2 * k + 1]);
    }
    zr_.resize(m), zi_.resize(m), wr_.resize(m), wi_.resize(m);
  }

  size_t size() const { return n_; }
  size_t bins() const { return n_ / 2 + 1; }

  // x: n lane vectors (sample i of lane l in x[i][l]). re, im: bins() vectors out.
  void Forward(const V* x, V* re, V* im) {
    const size_t m = fft_.size();
    if (!even_) {
      const V zero = Splat<W>(0.0);
      for (size_t j = 0; j < m; ++j) zr_[j] = x[j], zi_[j] = zero;
      fft_.Forward(zr_.data(), zi_.data(), wr_.data(), wi_.data());
      for (size_t k = 0; k < bins(); ++k) re[k] = zr_[k], im[k] = zi_[k];
      return;
    }
    for (size_t j = 0; j < m; ++j) zr_[j] = x[2 * j], zi_[j] = x[2 * j + 1];
    fft_.Forward(zr_.data(), zi_.data(), wr_.data(), wi_.data());
    // X_k = E_k + ω_n^k O_k with E_k = (Z_k + conj Z_{m−k})/2, O_k = −i (Z_k − conj Z_{m−k})/2.
    const V half = Splat<W>(0.5);
    for (size_t k = 0; k <= m; ++k) {
      const size_t a = k % m, b = (m - k) % m;
      const V er = half * (zr_[a] + zr_[b]), ei = half * (zi_[a] - zi_[b]);
      const V or_ = half * (zi_[a] + zi_[b]), oi = half * (zr_[b] - zr_[a]);
      const V c = Splat<W>(split_[2 * k]), s = Splat<W>(split_[2 * k + 1]);
      re[k] = er + (or_ * c - oi * s);
      im[k] = ei + (or_ * s + oi * c);
    }
  }

 private:
  size_t n_;
  bool even_;
  LaneFft<W> fft_;
  std::vector<double> split_;  // ω_n^k, k ≤ n/2
  std::vector<V> zr_, zi_, wr_, wi_;
};

}  // namespace bistable

#endif  // BISTABLE_DYNAMICS_LANE_FFT_H_
