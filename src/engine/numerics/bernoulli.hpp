// SPDX-License-Identifier: GPL-3.0-or-later
// engine/numerics/bernoulli.hpp -- the coefficients B_{2j} / (2j) of the asymptotic series of the digamma
// function in MPFR, tabulated once per precision (the Fourier moments
// of q^s do, through psi: engine/double_pendulum/fourier_moments.hpp).
//
// Why not Boost.Math's bernoulli_b2n: its cache for a variable-precision type is process-wide and
// keeps the highest precision any call ever asked for, so a 30-digit result would depend on
// whether a 60-digit call ran before it (and would mix precisions inside single operations). Here
// B_{2j} = (-1)^{j+1} 2 (2j)! zeta(2j) / (2 pi)^{2j}, each factor correctly rounded by MPFR with
// 64 extra bits, so a table depends on its precision alone.
#pragma once

#include "pendavg/mpfr.hpp"

#include <memory>
#include <vector>

namespace pendavg {

/// c[j] = B_{2j} / (2j), j = 1 .. c.size() - 1 (c[0] = 0), at the working precision: enough
/// terms for the digamma series at arguments x >= 1.2 ln(1/u) / (2 pi) + 2 (u the unit roundoff),
/// where the terms fall below u before they start to grow (j <= pi x).
std::shared_ptr<const std::vector<mpfr_real>> digamma_series_coefficients();

}  // namespace pendavg
