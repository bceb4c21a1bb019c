// SPDX-License-Identifier: GPL-3.0-or-later
// engine/numerics/compensated_sum.hpp -- Neumaier's compensated summation, shared by the torus,
// qmc and microcanonical sums: a sum of up to 1e9 node contributions in double keeps the rounding
// of a few additions instead of growing with the node count.
#pragma once

#include <cmath>
#include <type_traits>

namespace pendavg::detail {

/// Sum with a running compensation (Neumaier) for built-in floating types; plain for MPFR,
/// whose guard digits absorb summation rounding.
template <class Real>
struct CompensatedSum {
  Real sum{0}, compensation{0};
  void add(const Real& x) {
    if constexpr (std::is_floating_point_v<Real>) {
      const Real t = sum + x;
      if (std::abs(sum) >= std::abs(x)) {
        compensation += (sum - t) + x;
      } else {
        compensation += (x - t) + sum;
      }
      sum = t;
    } else {
      sum += x;
    }
  }
  Real value() const { return sum + compensation; }
};

}  // namespace pendavg::detail
