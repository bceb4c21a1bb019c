// SPDX-License-Identifier: GPL-3.0-or-later
// tests/oracle/graf_series.hpp -- an independent test oracle for the paper's series,
// eq. ave-K1-result, with R_n(a1, a2) from Graf's addition theorem instead of the paper's
// Bessel-derivative formula (which the library implements, src/engine/double_pendulum/README.md,
// 'Series').
//
// R_n(a1, a2) = (2 pi)^{-2} ∫∫ cos^{2n}(phi2 - phi1) e^{a1 cos phi1 + a2 cos phi2} d^2phi.
// Expanding cos^{2n} t = 2^{-2n} [ C(2n,n) + 2 sum_{k=1}^{n} C(2n,n-k) cos(2kt) ] and using
// (2 pi)^{-2} ∫∫ cos(2k(phi2 - phi1)) e^{a1 cos phi1 + a2 cos phi2} = I_2k(a1) I_2k(a2) gives
//
//     R_n = 2^{-2n} [ C(2n,n) I_0(a1) I_0(a2) + 2 sum_{k=1}^{n} C(2n,n-k) I_2k(a1) I_2k(a2) ].
//
// Bessel values come from boost::math::cyl_bessel_i, one call per order: slow, but it shares no
// code with the library's recurrences. When to use: tests only, small n (<= ~50) and moderate a
// (unscaled I_k overflows double near a ~ 700). The series value of beta<K1>, truncated after a
// given number of terms, follows eq. ave-K1-result with c_n = (2n-1)!!/(n! 2^n) and
// d_n = (2n-3)!!/(n! 2^n) (the Taylor coefficients of (1-x)^{-1/2} and -(1-x)^{1/2}).
#pragma once

#include <boost/math/special_functions/bessel.hpp>
#include <boost/multiprecision/mpfr.hpp>

#include <cmath>
#include <cstddef>
#include <vector>

namespace pendavg::oracle {

/// I_nu(a) for nu = 0, 2, 4, ..., 2 n_max (index k holds I_2k).
template <class Real>
std::vector<Real> even_order_bessel_i(int n_max, const Real& a) {
  std::vector<Real> out;
  out.reserve(static_cast<std::size_t>(n_max) + 1);
  for (int k = 0; k <= n_max; ++k) out.push_back(boost::math::cyl_bessel_i(Real(2 * k), a));
  return out;
}

/// Binomial coefficients C(2n, n-k) for k = 0..n, computed in Real by exact products.
template <class Real>
std::vector<Real> central_binomial_row(int n) {
  // C(2n, j) for j = 0..n via C(2n, j+1) = C(2n, j) (2n - j) / (j + 1).
  std::vector<Real> c(static_cast<std::size_t>(n) + 1);
  Real v = 1;
  for (int j = 0; j <= n; ++j) {
    c[static_cast<std::size_t>(j)] = v;
    v = v * Real(2 * n - j) / Real(j + 1);
  }
  std::vector<Real> out(static_cast<std::size_t>(n) + 1);
  for (int k = 0; k <= n; ++k) out[static_cast<std::size_t>(k)] = c[static_cast<std::size_t>(n - k)];
  return out;
}

/// R_n(a1, a2) by Graf's addition theorem, from precomputed I_2k tables (see above).
template <class Real>
Real graf_r_from_tables(int n, const std::vector<Real>& i_even_a1, const std::vector<Real>& i_even_a2) {
  using std::ldexp;
  const std::vector<Real> binom = central_binomial_row<Real>(n);
  Real sum = binom[0] * i_even_a1[0] * i_even_a2[0];
  for (int k = 1; k <= n; ++k) {
    const std::size_t kk = static_cast<std::size_t>(k);
    sum += Real(2) * binom[kk] * i_even_a1[kk] * i_even_a2[kk];
  }
  return ldexp(sum, -2 * n);
}

/// R_n(a1, a2) by Graf's addition theorem (unscaled).
template <class Real>
Real graf_r(int n, const Real& a1, const Real& a2) {
  return graf_r_from_tables<Real>(n, even_order_bessel_i<Real>(n, a1), even_order_bessel_i<Real>(n, a2));
}

/// All of R_0 .. R_{n_max} (unscaled).
template <class Real>
std::vector<Real> graf_r_all(int n_max, const Real& a1, const Real& a2) {
  const std::vector<Real> t1 = even_order_bessel_i<Real>(n_max, a1);
  const std::vector<Real> t2 = even_order_bessel_i<Real>(n_max, a2);
  std::vector<Real> out;
  for (int n = 0; n <= n_max; ++n) out.push_back(graf_r_from_tables<Real>(n, t1, t2));
  return out;
}

/// The paper's series for beta<K1> (eq. ave-K1-result) summed over n = 0 .. terms-1 in both
/// numerator and denominator, with R_n from Graf's theorem.
template <class Real>
Real graf_series_beta_kinetic1(const Real& mu1, const Real& mu2, const Real& a1, const Real& a2,
                               int terms) {
  const std::vector<Real> r = graf_r_all<Real>(terms - 1, a1, a2);
  Real numerator = 0;
  Real denominator = r[0];
  Real c = 1;        // c_n = (2n-1)!!/(n! 2^n), c_0 = 1
  Real mu2_pow = 1;  // mu2^n
  for (int n = 0; n < terms; ++n) {
    const std::size_t nn = static_cast<std::size_t>(n);
    numerator += c * mu2_pow * r[nn];
    if (n >= 1) {
      // d_n = (2n-3)!!/(n! 2^n) = c_n / (2n - 1)
      denominator -= c / Real(2 * n - 1) * mu2_pow * r[nn];
    }
    c = c * Real(2 * n + 1) / Real(2 * (n + 1));
    mu2_pow *= mu2;
  }
  return mu1 / Real(2) * numerator / denominator;
}

}  // namespace pendavg::oracle
