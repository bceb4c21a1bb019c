// SPDX-License-Identifier: GPL-3.0-or-later
// engine/torus/reduced_weight.hpp -- the constants of the reduced Boltzmann weight shared by the
// torus and qmc methods, and their rounding budget.
//
// Equation (src/engine/torus/README.md, 'Reduced weight'):
//     w(delta) = sqrt(det A) I0(R)
//              = e^{S} prod_j l_j sqrt(S_j) * exp(log sqrt(det A) - log_hadamard - (S - R)) e^{-R} I0(R),
//     alpha_j = beta g S_j l_j,  S = sum_j alpha_j,  log_hadamard = sum_j log(l_j sqrt(S_j)),
// where every factor of the second line is <= 1 (Hadamard: sqrt(det A) <= prod_j l_j sqrt(S_j);
// R <= S), so no weight overflows at any beta or N. The constant prefactor cancels in every ratio.
#pragma once

#include "pendavg/chain.hpp"

#include <cmath>
#include <cstddef>
#include <vector>

namespace pendavg::detail::torus {

using std::abs;
using std::log;

/// Chain constants of the reduced weight: alpha_j, S = sum alpha_j, log_hadamard.
template <class Real>
struct WeightConstants {
  std::vector<Real> alpha;
  Real alpha_sum{0};
  Real log_hadamard{0};  ///< sum_j log(l_j sqrt(S_j)) >= log sqrt(det A) (Hadamard)
  WeightConstants(const Chain<Real>& chain, const Real& beta) {
    const std::size_t n = chain.size();
    alpha.resize(n);
    for (std::size_t j = 0; j < n; ++j) {
      alpha[j] = beta * chain.potential_coefficient(j);
      alpha_sum += alpha[j];
      log_hadamard += log(chain.length(j)) + log(chain.tail_mass(j)) / 2;
    }
  }
};

/// Rounding budget, in ulps of each quantity's scale: per node, the traces carry ~8 ulps
/// (trace_formula.hpp), the weight's exponent an absolute error of ~u (|log sqrt det A| +
/// log_hadamard + lever), and the N-term rotation products ~N ulps; compensated summation adds
/// nothing that grows with the node count. The lever is sum_j alpha_j |sin(theta_j - arg z)|
/// (the angles' rounding times the exponent's slope), typically ~ sum_j sqrt(alpha_j) at the
/// nodes that carry the weight: the torus measures its weighted mean, qmc passes sqrt(S). A link
/// much stiffer than the rest (a root link 1e300 times longer) is aligned with z to within
/// the others' share, so its lever stays small where the typical sqrt(alpha) would be absurd.
template <class Real>
Real rounding_ulps(const WeightConstants<Real>& k, std::size_t n, const Real& lever) {
  return Real(32) + Real(4 * static_cast<double>(n)) + 2 * abs(k.log_hadamard) + 2 * lever;
}

}  // namespace pendavg::detail::torus
