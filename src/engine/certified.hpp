// SPDX-License-Identifier: GPL-3.0-or-later
// engine/certified.hpp -- certified enclosures of the double pendulum's averages (N = 2):
// every observable with an error of kind `bound`, a proof that the exact average for the given
// inputs lies within value +- error. The method and every bound are derived in
// engine/certified.md; the evaluation runs in Arb's ball arithmetic (Debian libflint-arb-dev),
// a feature present when the build found Arb (certified_available()).
//
// The 1-D reduction and the finite Graf sums are those of engine/double_pendulum.hpp:
//   J_s = sum_k c_k Q_k(s),  C_j = sum_k c^(j)_k Q_k(1/2),
// with the Graf coefficients c_k from tables of e^{-a} I_m(a) (Miller's backward recurrence,
// enclosed by the mediant of two start vectors, or Arb's Bessel function at the top and the
// stable backward recurrence), the Fourier moments Q_k(s) of q^s by the cancellation-free
// difference recurrence from Arb's 2F1 at the top row, and the truncated tails bounded with
// the exact sums of the coefficients (Graf's theorem at t = 0 and pi) and the moments' decay.
// With double inputs and results the same computation runs first in double-word balls
// (engine/detail/certified_fast.hpp, certified.md Sec. 10); Arb's balls where that declines.
#pragma once

#include "pendavg/average.hpp"
#include "pendavg/chain.hpp"
#include "pendavg/result.hpp"

#include <cstddef>

namespace pendavg {

// certified_available() (pendavg/average.hpp): whether this build has the engine.

/// What the build says when the certified engine is missing (for messages and --version).
const char* certified_unavailable_reason();

/// Work limit of the certified N = 2 engine: Graf rows (each row costs two Bessel orders and
/// three moments). Beyond it the result carries the proven bound of the truncated sum, with
/// converged = false.
inline constexpr std::size_t certified_max_rows = 40000;

/// The certified averages of a double pendulum at inverse temperature beta: beta<K_i>,
/// <K1>/<K2>, <cos phi_i>, beta^2 Var K_i, each with error kind `bound`, method
/// certified_integral. The inputs (masses, lengths, g, beta) are taken as the exact binary
/// numbers they are. `digits`: 16 (Real = double) or 17..1000 (mpfr_real; the values are
/// rounded to the current working precision, and the rounding is part of the error).
/// converged = false when the requested relative accuracy 10^-digits (double: 2^-52) was not
/// reached within the work limit; the errors are still proven bounds.
template <class Real>
Averages<Real> certified_double_pendulum_average(const Chain<Real>& chain, const Real& beta,
                                                 int digits);

/// The certified beta -> 0 limit of N = 2: beta<K1> = (mu1/2) K(mu2)/E(mu2), <cos phi_i> = 0,
/// beta^2 Var K_i from <x> = mu1 K/E, <x^2> = mu1 (kind bound, method certified-integral: the
/// certified engine at W = 1).
template <class Real>
Averages<Real> certified_high_temperature_limit(const Chain<Real>& chain, int digits);

}  // namespace pendavg
