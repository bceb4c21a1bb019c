// SPDX-License-Identifier: GPL-3.0-or-later
// engine/double_pendulum/inner_panel_series.hpp -- product integration of the double pendulum's
// reduced integrals over the inner panel t in [0, t1] (src/engine/double_pendulum/README.md,
// 'Reduced integral').
//
// WHAT. With z = sin^2(t/2) on [0, z1], z1 = sin^2(t1/2), and W = e^{-A} I0(R), g =
// e^{-A} I1(R)/R, R^2 = A^2 - P z (A = a1 + a2, P = 4 a1 a2), the five unfolded integrals
//   v0 = int q^{1/2} W dt,  v1 = int q^{-1/2} W dt,
//   v2 = int [q^{1/2} W + mu2 sin^2 t cos t q^{-1/2} (P/4) g] dt / mu1   (J_{-3/2} by parts),
//   v3 = int q^{1/2} g (a1 + a2 cos t) dt,  v4 = int q^{1/2} g (a2 + a1 cos t) dt
// (the integrands of double_pendulum.cpp's cut-range quadrature, same order).
//
// METHOD. q = mu1 + 4 mu2 z (1 - z) = 4 mu2 (z + eps^2)(E - z), E = 1 + eps^2, eps^2 (1 + eps^2)
// = mu1 / (4 mu2), and dt = z^{-1/2} (1 - z)^{-1/2} dz, so
//   q^{+-1/2} dt = (4 mu2)^{+-1/2} (z + eps^2)^{+-1/2} z^{-1/2}
//                  x [(E - z)^{+-1/2} (1 - z)^{-1/2}] dz.
// Only (z + eps^2)^{+-1/2} z^{-1/2} (q's branch point at distance eps^2 from the end point) is
// kept exact: with z = z1 x, e = eps^2 / z1, the moments
//   a_j = int_0^1 x^{j-1/2} (x + e)^{-1/2} dx,   b_j = int_0^1 x^{j-1/2} (x + e)^{1/2} dx
// obey a_0 = 2 asinh(e^{-1/2}), a_{j+1} = [(1 + e)^{1/2} - (j + 1/2) e a_j] / (j + 1) (damped
// by e < 1: stable) and b_j = a_{j+1} + e a_j. Everything else is a power series in x:
//   W = sum_k (-P z1/2)^k e^{-A} f_k(A) x^k / k!,
//   g = sum_k (-P z1/2)^k e^{-A} f_{k+1}(A) x^k / k!
// (f_k = I_k / a^k, (d/d(a^2))^k I0(a) = f_k / 2^k: the coefficients are exact); they decay like
// y1^k / k!, y1 = P z1 / (2 A) = 2 a1 a2 z1 / (a1 + a2); and the factors
// (E - z)^{+-1/2} (1 - z)^{-1/2}, whose series converge like z1^j.
//
// ERROR. |w_k| <= w_0 y1^k / k! and |g_k| <= g_0 y1^k / k! (I_k <= I_0, I_{k+1} <= I_1), so the
// cut tail is bounded by w_0 sum_{k>=N} y1^k/k! times int |q^{+-1/2}| dt (bounded from a_0, b_0);
// the (E - z), (1 - z) series are cut (per power of x, a triangle) below u times the terms,
// each dropped part bounded and reported; rounding: a few ulps per term
// and coefficient, times the L1 norm of the terms (the alternating sum loses ~e^{2 y1}).
//
// WHEN. Only where y1 is a few units (so N ~ 50-120 terms) and e << 1: the caller keeps the
// panel quadrature otherwise (ok == false).
#pragma once

#include "engine/numerics/bessel.hpp"
#include "engine/numerics/precision.hpp"

#include <array>
#include <cmath>
#include <cstddef>
#include <vector>

namespace pendavg::detail {

template <class Real>
struct InnerPanelSeries {
  std::array<Real, 5> value{}, error{};
  std::size_t terms = 0;  // length N of the weight's series
  bool ok = false;        // false: the series would be too long; nothing computed
};

/// The inner panel's end s1 = sin(t1/2) for the peak's choice s_peak = sin(w) (t1 = 2 w):
/// moved out to eps / 0.45^{1/2} when q's zero is at or beyond the peak's width, so that
/// e = eps^2 / z1 <= 0.45 (the moments' recurrence damps by e; the series checks e < 1/2).
/// The weight's series then grows (y1 = 2 h z1 up to ~9, N ~ 90-135 at 77 digits), still far
/// cheaper than the single long panel of nodes it replaces.
template <class Real>
Real inner_panel_end(const Real& s_peak, const Real& eps) {
  constexpr double e_max = 0.45;
  if (eps * eps > e_max * s_peak * s_peak) return eps / sqrt(Real(e_max));
  return s_peak;
}

namespace inner_panel {

/// The series' lengths: N terms of the weight's series (w_0 y1^N / N! (1 - y1/(N+1))^{-1} below
/// u e^{-2 y1} w_0: the cancellation of the alternating sum is ~e^{2 y1}, the tail stays below
/// its rounding) and J of the (E - z), (1 - z) factors (|coefficient_j| <= E^{1/2} (j + 1) z1^j).
/// False when either would pass its cap.
inline bool series_lengths(double y1, double z1, double ln_inv_u, std::size_t max_terms,
                           std::size_t& N, std::size_t& J) {
  const double target = -ln_inv_u - 2.0 * y1 - 2.0;
  N = 1;
  double ln_tail = 0.0;  // ln(y1^N / N!)
  const double ln_y1 = std::log(y1);
  for (;; ++N) {
    ln_tail += ln_y1 - std::log(static_cast<double>(N));
    if (static_cast<double>(N + 1) > 2.0 * y1 && ln_tail + std::log(2.0) < target) break;
    if (N > max_terms) return false;
  }
  J = 1;
  const double ln_z1 = std::log(z1);
  while (static_cast<double>(J) * ln_z1 + std::log(double(J + 1)) - std::log1p(-z1) >
         -ln_inv_u - 2.0 * y1 - 4.0) {
    ++J;
    if (J > 400) return false;
  }
  return true;
}

/// The weight's coefficients w_k = (-P z1/2)^k e^{-A} f_k(A) / k! and g_k (f_{k+1}), k <= N,
/// zero up to K.
template <class Real>
void weight_series(const std::vector<Real>& f, const Real& half_P_z1, std::size_t N,
                   std::size_t K, std::vector<Real>& w, std::vector<Real>& g) {
  w.assign(K, Real(0));
  g.assign(K, Real(0));
  Real scale = 1;  // (-P z1 / 2)^k / k!
  const Real step = -half_P_z1;
  for (std::size_t k = 0; k <= N; ++k) {
    w[k] = scale;
    w[k] *= f[k];
    g[k] = scale;
    g[k] *= f[k + 1];
    scale *= step;
    scale /= static_cast<unsigned long>(k + 1);
  }
}

/// The series in x of U = (E - z)^{1/2} (1 - z)^{-1/2} and V = (E - z)^{-1/2} (1 - z)^{-1/2},
/// J coefficients each (in-place arithmetic throughout: no multiprecision temporaries).
template <class Real>
void factor_series(const Real& z1, const Real& E, std::size_t J, std::vector<Real>& U,
                   std::vector<Real>& V) {
  using std::sqrt;
  U.assign(J, Real(0));
  V.assign(J, Real(0));
  const Real r = z1 / E;
  std::vector<Real> cp(J), cm(J), d(J);  // (1 - r x)^{1/2}, (1 - r x)^{-1/2}, (1 - z1 x)^{-1/2}
  cp[0] = 1;
  cm[0] = 1;
  d[0] = 1;
  for (std::size_t j = 1; j < J; ++j) {
    const long jj = static_cast<long>(j);
    cp[j] = cp[j - 1];
    cp[j] *= r;
    cp[j] *= 2 * jj - 3;
    cp[j] /= 2 * jj;  // (j - 3/2) / j
    cm[j] = cm[j - 1];
    cm[j] *= r;
    cm[j] *= 2 * jj - 1;
    cm[j] /= 2 * jj;
    d[j] = d[j - 1];
    d[j] *= z1;
    d[j] *= 2 * jj - 1;
    d[j] /= 2 * jj;
  }
  const Real sE = sqrt(E);
  Real su, sv, t;
  for (std::size_t j = 0; j < J; ++j) {
    su = 0;
    sv = 0;
    for (std::size_t i = 0; i <= j; ++i) {
      t = cp[i];
      t *= d[j - i];
      su += t;
      t = cm[i];
      t *= d[j - i];
      sv += t;
    }
    U[j] = su;
    U[j] *= sE;
    V[j] = sv;
    V[j] /= sE;
  }
}

/// The moments a_j = int_0^1 x^{j-1/2} (x + e)^{-1/2} dx (j <= M) and b_j = a_{j+1} + e a_j
/// (j < M) by the forward recurrence, damped by e < 1.
template <class Real>
void moments(const Real& e, std::size_t M, std::vector<Real>& a, std::vector<Real>& b) {
  using std::asinh;
  using std::sqrt;
  a.assign(M + 1, Real(0));
  b.assign(M, Real(0));
  a[0] = 2 * asinh(1 / sqrt(e));
  const Real s1e = sqrt(1 + e);
  Real t;
  for (std::size_t j = 0; j < M; ++j) {
    t = a[j];
    t *= e;
    t *= static_cast<unsigned long>(2 * j + 1);
    t /= 2;  // (j + 1/2) e a_j
    a[j + 1] = s1e;
    a[j + 1] -= t;
    a[j + 1] /= static_cast<unsigned long>(j + 1);
  }
  for (std::size_t j = 0; j < M; ++j) {
    b[j] = a[j];
    b[j] *= e;
    b[j] += a[j + 1];
  }
}

/// The modified moments int_0^{z1} (z/z1)^k q^{+-1/2} dt = Mp_k, Mm_k (k < K) and the bounds
/// cut_p, cut_m of what they drop per unit coefficient. Term j of Mp_k meets a coefficient
/// below ~y1^k / k!: it is dropped once y1^k / k! (j + 1) z1^j falls below the same target as
/// J (a triangle instead of K x J); the dropped terms j >= J_k are bounded by E^{1/2} (J_k + 1)
/// z1^{J_k} / (1 - z1)^2 times b_k (q^{1/2}) or a_k (q^{-1/2}), b_k <= b_0, a_k <= a_0.
template <class Real>
struct ModifiedMoments {
  std::vector<Real> Mp, Mm, cut_p, cut_m;
};

template <class Real>
ModifiedMoments<Real> modified_moments(const std::vector<Real>& U, const std::vector<Real>& V,
                                       const std::vector<Real>& a, const std::vector<Real>& b,
                                       const Real& mu2, const Real& z1, const Real& E, double y1,
                                       double ln_inv_u, std::size_t K, std::size_t J) {
  using std::sqrt;
  const double z1_d = static_cast<double>(z1);
  std::vector<std::size_t> J_k(K, J);
  {
    const double ln_z1 = std::log(z1_d), ln_y1 = std::log(y1);
    double ln_coef = 0.0;  // ln(y1^k / k!)
    for (std::size_t k = 0; k < K; ++k) {
      if (k > 0) ln_coef += ln_y1 - std::log(static_cast<double>(k));
      std::size_t j = 1;
      while (j < J && ln_coef + static_cast<double>(j) * ln_z1 + std::log(double(j + 1)) -
                              std::log1p(-z1_d) > -ln_inv_u - 2.0 * y1 - 4.0) {
        ++j;
      }
      J_k[k] = j;
    }
  }
  const Real root = sqrt(4 * mu2);
  const Real root_z1 = root * z1;
  ModifiedMoments<Real> m;
  m.Mp.resize(K);
  m.Mm.resize(K);
  Real sp, sm, t;
  for (std::size_t k = 0; k < K; ++k) {
    sp = 0;
    sm = 0;
    for (std::size_t j = 0; j < J_k[k]; ++j) {
      if constexpr (is_mpfr_v<Real>) {
        mpfr_mul(t.backend().data(), U[j].backend().data(), b[k + j].backend().data(), MPFR_RNDN);
        mpfr_add(sp.backend().data(), sp.backend().data(), t.backend().data(), MPFR_RNDN);
        mpfr_mul(t.backend().data(), V[j].backend().data(), a[k + j].backend().data(), MPFR_RNDN);
        mpfr_add(sm.backend().data(), sm.backend().data(), t.backend().data(), MPFR_RNDN);
      } else {
        sp += U[j] * b[k + j];
        sm += V[j] * a[k + j];
      }
    }
    m.Mp[k] = sp;
    m.Mp[k] *= root_z1;
    m.Mm[k] = sm;
    m.Mm[k] /= root;
  }
  m.cut_p.resize(K);
  m.cut_m.resize(K);
  std::vector<Real> z1_pow(J + 1);
  z1_pow[0] = 1;
  for (std::size_t j = 1; j <= J; ++j) z1_pow[j] = z1_pow[j - 1] * z1;
  const Real c = sqrt(E) / ((1 - z1) * (1 - z1));
  Real tail;
  for (std::size_t k = 0; k < K; ++k) {
    tail = c;
    tail *= z1_pow[J_k[k]];
    tail *= static_cast<unsigned long>(J_k[k] + 1);
    m.cut_p[k] = tail;
    m.cut_p[k] *= b[k];
    m.cut_p[k] *= root_z1;
    m.cut_m[k] = tail;
    m.cut_m[k] *= a[k];
    m.cut_m[k] /= root;
  }
  return m;
}

/// The x-power coefficients of the integrands of v3, v4 (q^{1/2} g (a1 + a2 cos t), with
/// a1 + a2 cos t = A - 2 a2 z) and of v2's second term (mu2 (P/4) sin^2 t cos t q^{-1/2} g,
/// sin^2 t cos t = 4 z - 12 z^2 + 8 z^3).
template <class Real>
void integrand_coefficients(const std::vector<Real>& g, const Real& A, const Real& a1,
                            const Real& a2, const Real& z1, const Real& pm, std::size_t K,
                            std::vector<Real>& c3, std::vector<Real>& c4, std::vector<Real>& c2m) {
  c3.assign(K, Real(0));
  c4.assign(K, Real(0));
  c2m.assign(K, Real(0));
  const Real two_z1_a2 = 2 * z1 * a2, two_z1_a1 = 2 * z1 * a1;
  const Real p1 = 4 * z1 * pm, p2 = -12 * z1 * z1 * pm, p3 = 8 * z1 * z1 * z1 * pm;
  Real t;
  for (std::size_t k = 0; k < K; ++k) {
    c3[k] = g[k];
    c3[k] *= A;
    c4[k] = c3[k];
    if (k >= 1) {
      t = g[k - 1];
      t *= two_z1_a2;
      c3[k] -= t;
      t = g[k - 1];
      t *= two_z1_a1;
      c4[k] -= t;
      c2m[k] = g[k - 1];
      c2m[k] *= p1;
    }
    if (k >= 2) {
      t = g[k - 2];
      t *= p2;
      c2m[k] += t;
    }
    if (k >= 3) {
      t = g[k - 3];
      t *= p3;
      c2m[k] += t;
    }
  }
}

/// sum_k c_k m_k, with its rounding norm sum_k |c_k m_k| (8 + 8k + K + J) (each coefficient
/// carries ~(8 + 8k) ulps from the Bessel table and powers, each term ~(K + J) more from the
/// sums) and the dropped part sum_k |c_k| cut_k.
template <class Real>
void coefficient_dot(const std::vector<Real>& c, const std::vector<Real>& m,
                     const std::vector<Real>& cut_k, std::size_t K, std::size_t J, Real& sum,
                     Real& norm, Real& dropped) {
  sum = 0;
  norm = 0;
  dropped = 0;
  Real t;
  for (std::size_t k = 0; k < K; ++k) {
    t = c[k];
    t *= m[k];
    sum += t;
    if (t < 0) t = -t;
    t *= static_cast<unsigned long>(8 + 8 * k + K + J);
    norm += t;
    t = c[k];
    if (t < 0) t = -t;
    t *= cut_k[k];
    dropped += t;
  }
}

}  // namespace inner_panel

/// The five inner-panel integrals over sin(t/2) in [0, s1] (see above); max_terms caps N.
template <class Real>
InnerPanelSeries<Real> inner_panel_series(const Real& mu1, const Real& mu2, const Real& a1,
                                          const Real& a2, const Real& s1,
                                          std::size_t max_terms = 160) {
  using std::abs;
  using std::exp;
  using std::log;
  using std::sqrt;
  InnerPanelSeries<Real> out;
  const Real u = unit_roundoff<Real>();
  const double ln_inv_u = -static_cast<double>(log(u));
  const Real A = a1 + a2, P = 4 * a1 * a2;
  const Real z1 = s1 * s1;
  const Real c2 = mu1 / mu2;
  const Real eps2 = c2 / (2 * (1 + sqrt(1 + c2)));  // eps^2 (1 + eps^2) = mu1 / (4 mu2)
  const Real e = eps2 / z1;
  const Real E = 1 + eps2;
  const Real half_P_z1 = P * z1 / 2;
  const Real y1 = half_P_z1 / A;  // 2 a1 a2 z1 / (a1 + a2): the series' decay scale
  const double y1_d = static_cast<double>(y1), z1_d = static_cast<double>(z1);
  if (!(z1_d < 0.25) || !(static_cast<double>(e) < 0.5) || !(y1_d > 0)) return out;
  std::size_t N = 0, J = 0;
  if (!inner_panel::series_lengths(y1_d, z1_d, ln_inv_u, max_terms, N, J)) return out;
  const std::size_t K = N + 4;  // coefficients 0..K-1 (the polynomial factors add up to 3)
  const auto f = reduced_bessel_table(A, N + 2);  // e^{-A} f_k(A), k = 0..N+1
  std::vector<Real> w, g, U, V, a, b, c3, c4, c2m;
  inner_panel::weight_series(f, half_P_z1, N, K, w, g);
  inner_panel::factor_series(z1, E, J, U, V);
  inner_panel::moments(e, K + J + 1, a, b);  // a_j, b_j, j = 0 .. K + J
  const auto mm = inner_panel::modified_moments(U, V, a, b, mu2, z1, E, y1_d, ln_inv_u, K, J);
  const Real pm = mu2 * P / 4;
  inner_panel::integrand_coefficients(g, A, a1, a2, z1, pm, K, c3, c4, c2m);
  std::array<Real, 5> l1{}, cut{};
  Real v2m = 0, l1_2m = 0, cut_2m = 0;
  inner_panel::coefficient_dot(w, mm.Mp, mm.cut_p, K, J, out.value[0], l1[0], cut[0]);
  inner_panel::coefficient_dot(w, mm.Mm, mm.cut_m, K, J, out.value[1], l1[1], cut[1]);
  inner_panel::coefficient_dot(c3, mm.Mp, mm.cut_p, K, J, out.value[3], l1[3], cut[3]);
  inner_panel::coefficient_dot(c4, mm.Mp, mm.cut_p, K, J, out.value[4], l1[4], cut[4]);
  inner_panel::coefficient_dot(c2m, mm.Mm, mm.cut_m, K, J, v2m, l1_2m, cut_2m);
  out.value[2] = (out.value[0] + v2m) / mu1;
  // Cut tails. tau = sum_{k>N} y1^k / k! (terms N+1.. of the weights' series).
  Real tau = 0;
  {
    Real term = 1;
    for (std::size_t k = 1; k <= N + 1; ++k) term *= y1 / static_cast<unsigned long>(k);
    tau = term * 2;  // y1 / (N + 2) <= 1/2: geometric bound
  }
  // int_0^{t1} q^{1/2} dt <= (4 mu2)^{1/2} z1 (E / (1 - z1))^{1/2} b_0; q^{-1/2}: a_0 / (1 - z1).
  const Real root = sqrt(4 * mu2);
  const Real Bp = root * z1 * sqrt(E / (1 - z1)) * b[0];
  const Real Bm = a[0] / root / (1 - z1);
  const Real w0 = f[0], g0 = f[1];
  const Real bessel_amp =
      exp(Real(std::min(static_cast<double>(K * K) / static_cast<double>(A), 14.0)));
  out.error[0] = w0 * tau * Bp + cut[0] + u * bessel_amp * l1[0];
  out.error[1] = w0 * tau * Bm + cut[1] + u * bessel_amp * l1[1];
  out.error[3] = A * g0 * tau * Bp + cut[3] + u * bessel_amp * l1[3];
  out.error[4] = A * g0 * tau * Bp + cut[4] + u * bessel_amp * l1[4];
  out.error[2] = (out.error[0] + pm * 4 * z1 * g0 * tau * Bm + cut_2m + u * bessel_amp * l1_2m) /
                     mu1 + 4 * u * abs(out.value[2]);
  out.terms = N;
  out.ok = true;
  return out;
}

}  // namespace pendavg::detail
