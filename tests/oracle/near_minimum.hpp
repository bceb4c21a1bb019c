// SPDX-License-Identifier: GPL-3.0-or-later
// tests/oracle/near_minimum.hpp -- an independent test oracle for microcanonical averages near
// the bottom of the well: the definition (src/engine/microcanonical/README.md) integrated directly
// over the N absolute angles, in the excitation form, by nested Gauss-Legendre rules.
//
// What it is. At excitation D = E - E_min the accessible angles are
//     {phi : sum_j 2 gamma_j sin^2(phi_j / 2) < D}      (U - U_min, no cancellation),
// and, per node, the weight sqrt(det A) (E - U)^{N/2 - 1} and the conditional moments
//     <K_i | phi> = tr X_i (E - U) / N,  <K_i^2 | phi> = (E - U)^2 [(tr X_i)^2 + 2 tr X_i^2] / (N (N+2)).
// A, X_i = A^(i) A^{-1} come from the dense oracle (dense_traces.hpp: Eigen, literally the
// paper's matrices), so neither the psi reduction, the shell integrals, the trace recurrences nor
// the cuts of the library are used.
// How. The angles are nested from the last outwards: with the budget R_N = D, phi_N ranges over
// |phi_N| < b_N, 2 gamma_N sin^2(b_N / 2) = R_N, and leaves R_{N-1} = R_N - 2 gamma_N
// sin^2(phi_N / 2) = 2 gamma_N sin((b_N - phi_N) / 2) sin((b_N + phi_N) / 2) for phi_{N-1}, and so
// on down to E - U = R_0 after phi_1. Every budget is a product of sines of b - phi and b + phi,
// so nothing cancels however small D is. The substitution phi_j = b_j sin t_j makes every level
// analytic in t_j (the square-root edges of the region become cos t_j factors), and a
// Gauss-Legendre rule in t_j converges geometrically.
// When to use it: ONLY as a test oracle, for small excitations (D < 2 min_j gamma_j, where no
// angle wraps around): cost n^N dense N x N evaluations. Run it in long double (or MPFR) so that
// its own rounding stays far below double's; check its convergence by comparing n with 3n/2.
#pragma once

#include "oracle/dense_traces.hpp"
#include "oracle/definition_2d.hpp"

#include <cmath>
#include <cstddef>
#include <stdexcept>
#include <vector>

namespace pendavg::oracle {

/// Microcanonical averages from near_minimum_average: <K_i>, <cos phi_i>, Var K_i.
template <class Real>
struct NearMinimumAverages {
  std::vector<Real> kinetic, cos_angle, kinetic_variance;
};

/// The definition integrated as described above, with n Gauss-Legendre nodes per angle. gamma_j =
/// g S_j l_j is formed here from masses, lengths and g in Real.
template <class Real>
NearMinimumAverages<Real> near_minimum_average(const std::vector<Real>& masses,
                                               const std::vector<Real>& lengths, const Real& g,
                                               const Real& excitation, int nodes) {
  using std::asin;
  using std::cos;
  using std::pow;
  using std::sin;
  using std::sqrt;
  const std::size_t n = masses.size();
  std::vector<Real> gamma(n);
  for (std::size_t j = 0; j < n; ++j) {
    Real tail = 0;
    for (std::size_t k = j; k < n; ++k) tail += masses[k];
    gamma[j] = g * tail * lengths[j];
    if (!(excitation < 2 * gamma[j])) {
      throw std::invalid_argument("near_minimum_average: D must stay below 2 min gamma_j");
    }
  }
  const GaussLegendreRule<Real> rule = gauss_legendre<Real>(nodes);
  const Real half_pi = boost::math::constants::half_pi<Real>();
  const Real nn = Real(static_cast<double>(n));
  // sums: weight, then per particle K, K^2, cos
  std::vector<Real> sums(1 + 3 * n, Real(0));
  std::vector<Real> phi(n);
  // recursive nesting over j = n-1 .. 0 (0-based) with the budget R and the Jacobian so far
  const auto level = [&](const auto& self, std::size_t j, const Real& budget,
                         const Real& jacobian) -> void {
    // 2 gamma_j sin^2(b / 2) = budget
    const Real b = 2 * asin(sqrt(budget / (2 * gamma[j])));
    for (int k = 0; k < nodes; ++k) {
      const Real t = half_pi * rule.nodes[static_cast<std::size_t>(k)];
      const Real st = sin(t), ct = cos(t);
      phi[j] = b * st;
      // b - phi = b (1 - sin t) = b cos^2 t / (1 + sin t); b + phi = b cos^2 t / (1 - sin t)
      const Real minus = st >= 0 ? Real(b * ct * ct / (1 + st)) : Real(b * (1 - st));
      const Real plus = st <= 0 ? Real(b * ct * ct / (1 - st)) : Real(b * (1 + st));
      const Real rest = 2 * gamma[j] * sin(minus / 2) * sin(plus / 2);
      const Real w = jacobian * half_pi * rule.weights[static_cast<std::size_t>(k)] * b * ct;
      if (j > 0) {
        self(self, j - 1, rest, w);
        continue;
      }
      // rest = E - U at this node
      const DenseTraces<Real> d = dense_traces<Real>(masses, lengths, phi);
      const Real weight = w * exp(d.log_sqrt_det_A) * pow(rest, nn / 2 - 1);
      sums[0] += weight;
      for (std::size_t i = 0; i < n; ++i) {
        const Real x = d.trace_X[i];
        sums[1 + i] += weight * x * rest / nn;
        sums[1 + n + i] += weight * rest * rest * (x * x + 2 * d.trace_X_squared[i]) /
                           (nn * (nn + 2));
        sums[1 + 2 * n + i] += weight * cos(phi[i]);
      }
    }
  };
  level(level, n - 1, excitation, Real(1));
  NearMinimumAverages<Real> out;
  for (std::size_t i = 0; i < n; ++i) {
    const Real k = sums[1 + i] / sums[0];
    out.kinetic.push_back(k);
    out.kinetic_variance.push_back(sums[1 + n + i] / sums[0] - k * k);
    out.cos_angle.push_back(sums[1 + 2 * n + i] / sums[0]);
  }
  return out;
}

}  // namespace pendavg::oracle
