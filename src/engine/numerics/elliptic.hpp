// SPDX-License-Identifier: GPL-3.0-or-later
// engine/numerics/elliptic.hpp -- complete elliptic integrals from the complementary parameter.
//
// K(k) and E(k) with k^2 = mu2 are taken as Carlson's symmetric forms of k'^2 = mu1, passed
// directly: K = R_F(0, mu1, 1), E = 2 R_G(0, mu1, 1). As mu1 -> 0 this loses nothing, where
// k = sqrt(1 - mu1) would round mu1 away and E = R_F - (mu2/3) R_D would cancel. Boost.Math's
// Carlson functions are generic over Real (double and MPFR alike).
#pragma once

#include <boost/math/special_functions/ellint_rf.hpp>
#include <boost/math/special_functions/ellint_rg.hpp>

namespace pendavg::detail {

template <class Real>
struct CompleteElliptic {
  Real K, E;
};

template <class Real>
CompleteElliptic<Real> complete_elliptic_from_complement(const Real& mu1) {
  return {boost::math::ellint_rf(Real(0), mu1, Real(1)),
          2 * boost::math::ellint_rg(Real(0), mu1, Real(1))};
}

}  // namespace pendavg::detail
