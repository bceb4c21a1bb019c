// SPDX-License-Identifier: GPL-3.0-or-later
// engine/numerics/legendre.hpp -- the Legendre polynomial P_n and its derivative at one point, for
// the Newton steps that place Gauss-Legendre nodes (the torus' rule in MPFR, the transfer
// operator's panels).
#pragma once

#include <cstddef>

namespace pendavg::detail {

template <class Real>
struct LegendreAt {
  Real value;       ///< P_n(x)
  Real derivative;  ///< P_n'(x)
};

/// P_n(x) by the three-term recurrence P_{j+1} = ((2j+1) x P_j - j P_{j-1}) / (j+1), and
/// P_n'(x) = n (x P_n - P_{n-1}) / (x^2 - 1); n >= 1, |x| < 1.
template <class Real>
LegendreAt<Real> legendre_at(std::size_t n, const Real& x) {
  Real p_prev = 1, p = x;
  for (std::size_t j = 1; j < n; ++j) {
    const Real jj = Real(static_cast<double>(j));
    const Real p_next = ((2 * jj + 1) * x * p - jj * p_prev) / (jj + 1);
    p_prev = p;
    p = p_next;
  }
  const Real derivative = Real(static_cast<double>(n)) * (x * p - p_prev) / (x * x - 1);
  return {p, derivative};
}

}  // namespace pendavg::detail
