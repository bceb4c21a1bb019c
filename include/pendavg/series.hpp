// SPDX-License-Identifier: GPL-3.0-or-later
// pendavg/series.hpp -- the paper's series for the double pendulum, term by term (eq.
// ave-K1-result; src/engine/double_pendulum/README.md, 'Series'): the convergence table that proves
// the value.
//
// beta<K1> = (mu1/2) sum_n c_n mu2^n R_n / (R_0 - sum_{n>=1} d_n mu2^n R_n), with
// R_n(a1, a2) = (1/pi) int_0^pi cos^{2n} t I0(R(t)) dt from the closed-form Bessel derivatives
// (src/engine/double_pendulum/README.md, 'Series'). After n terms both tails are bounded by c_{n+1}
// R_{n+1} mu2^{n+1} / (1 - mu2), which gives each row a rigorous bound on |beta<K1> - partial
// value|. Convergence is geometric with ratio mu2 = m2/M: when mu1 = m1/M is small prefer average()
// (the reduced integral), which has no such slowdown. The sums run in MPFR (their coefficients
// leave double's range); the double instantiation runs them at 16 + guard digits and rounds the
// rows. For the value itself with all observables, call average() with AverageMethod::series.
#pragma once

#include "pendavg/export.hpp"
#include "pendavg/result.hpp"
#include "pendavg/chain.hpp"

#include <cstddef>
#include <vector>

namespace pendavg {

/// One row of the series convergence check.
template <class Real>
struct SeriesRow {
  std::size_t n = 0;
  Real R_n;            ///< R_n(a1, a2), scaled by exp(-(a1 + a2))
  Real term;           ///< c_n mu2^n R_n, the n-th numerator term (scaled)
  Real numerator;      ///< partial sum  sum_{k<=n} c_k mu2^k R_k  (scaled)
  Real denominator;    ///< partial sum  R_0 - sum_{1<=k<=n} d_k mu2^k R_k  (scaled)
  Real beta_kinetic1;  ///< (mu1/2) numerator / denominator
  Real bound;          ///< rigorous bound on |beta<K1> - beta_kinetic1| from the tails
};

/// The most terms series_convergence takes when they are given explicitly (work grows like
/// terms^2: 200,000 terms are hours).
inline constexpr std::size_t max_series_terms = 200000;

/// The series, term by term, up to `terms` terms (0: until the requested digits are certified;
/// refused before any work when that needs more than the automatic cap of 6000 terms, or when
/// `terms` exceeds max_series_terms). N = 2
/// only; throws invalid_input otherwise. `control` reports the Bessel table's progress and may
/// stop it (throws `interrupted`: no row exists before the table is complete).
template <class Real>
PENDAVG_EXPORT std::vector<SeriesRow<Real>> series_convergence(const Chain<Real>& chain,
                                                               const Real& beta, int digits = 16,
                                                               std::size_t terms = 0,
                                                               const RunControl& control = {});

}  // namespace pendavg
