// SPDX-License-Identifier: GPL-3.0-or-later
// engine/numerics/double_word.hpp -- double-word ("double-double") arithmetic: a value carried as
// an unevaluated sum hi + lo of two numbers of the working type, from the error-free
// transformations
//     two_sum(a, b):     a + b = s + e exactly        (Knuth)
//     two_product(a, b): a b   = p + e exactly        (fused multiply-add)
// Used where a sum must keep the digits of its small terms: the microcanonical excitation
// D = E - E_min near the bottom of the well (engine/microcanonical/shell.hpp).
#pragma once

#include <cmath>

namespace pendavg::detail {

/// Error-free transformations for the compensated excitation (built-in floating types).
template <class Real>
struct DoubleWord {
  Real hi{0}, lo{0};
};

template <class Real>
DoubleWord<Real> two_sum(const Real& a, const Real& b) {
  const Real s = a + b, bb = s - a;
  return {s, (a - (s - bb)) + (b - bb)};
}

template <class Real>
DoubleWord<Real> two_product(const Real& a, const Real& b) {
  const Real p = a * b;
  return {p, std::fma(a, b, -p)};
}

/// x + y for double words (relative error ~ u^2).
template <class Real>
DoubleWord<Real> add(const DoubleWord<Real>& x, const DoubleWord<Real>& y) {
  DoubleWord<Real> s = two_sum(x.hi, y.hi);
  s.lo += x.lo + y.lo;
  return two_sum(s.hi, s.lo);
}

}  // namespace pendavg::detail
