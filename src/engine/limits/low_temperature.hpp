// SPDX-License-Identifier: GPL-3.0-or-later
// engine/limits/low_temperature.hpp -- the torus and qmc methods at large beta: the joints'
// stiffness, and the Richardson extrapolation in 1/beta towards the beta -> infinity limit
// (method low_temperature_extrapolation; src/average.cpp decides when to use it).
//
// Equations (src/engine/limits/README.md, 'Low-temperature extrapolation'):
//     kappa_i = H_i T_i / S                      (joint i: H_i, T_i the sums of alpha_j above
//                                                 and below it, S their total)
//     effective stiffness = min_i kappa_i min(1, m_i / S_{i+1}), and at most min_j alpha_j
//     V(beta) = V_inf + x y(x),  x = 1/beta,  y through (1/beta_k, (V(beta_k) - V_inf) beta_k),
//               beta_k = 2^k beta_1 (k = 0, 1, 2)     (Lagrange, quadratic)
//     error  = x (|y_quadratic - y_linear| + sum_k |L_k(x)| beta_k err_k) + 4 u |V|
//
// The Boltzmann weight is a peak in each relative angle delta_i of squared width 1/kappa_i,
// kappa_i = H_i T_i / S with H_i, T_i the sums of alpha_j = beta g S_j l_j above and below joint
// i and S their total (the torus' node maps, engine/torus/circle_rules.hpp). The torus and qmc methods resolve
// peaks down to kappa ~ 1e13 in double. When every joint is stiff the chain is near its beta ->
// infinity limit V_inf (beta<K_i> = 1/2, <cos phi_i> = 1, beta^2 Var K_i = tr X_i(0)^2 / 2), and
// every average is a series in 1/beta, V = V_inf + c/beta + d/beta^2 + e/beta^3 + ... (Laplace).
// The expansion's parameter at joint i is not 1/kappa_i alone. The weight sqrt(det A) and the
// traces tr X_i vary with the joint's angle on the scale delta_i^2 ~ rho_i = m_i / S_{i+1}, the
// mass at the joint over the tail beyond it: at the straight chain H^{-1} = (S_max(j,k)), so
// det H(delta_i) = det H(0) (1 + delta_i^2 / rho_i + ...). A light particle (rho_i << 1) makes the
// weight vary much faster than the Boltzmann peak's width 1/sqrt(kappa_i), and the chain is near
// its limit only once kappa_i min(1, rho_i) is large: the effective stiffness. (The double
// pendulum with mu1 -> 0 is the known case: beta<K_1> ~ 0.38 at beta = 100 for mu1 = 0.05.)
// The values at three lower temperatures beta_k = 2^k beta_1 (k = 0, 1, 2), where the smallest
// effective stiffness is 1e3 (fast, to ~1e-13), fix the polynomial y(x) = (V - V_inf)/x in x = 1/beta
// through them (Richardson), and V(beta) = V_inf + x y(x). Its error is estimated by the change
// from the two-point (linear) to the three-point (quadratic) fit, plus the references' errors
// carried by the extrapolation (sum_k |L_k(x)| x beta_k err_k, L_k the Lagrange basis) and
// rounding.
#pragma once

#include "engine/limits/limits.hpp"
#include "engine/numerics/estimates.hpp"
#include "engine/numerics/precision.hpp"
#include "pendavg/average.hpp"
#include "pendavg/chain.hpp"
#include "pendavg/result.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstddef>
#include <functional>
#include <limits>
#include <type_traits>
#include <vector>

namespace pendavg::detail::limits {

/// Smallest and largest kappa_i over the joints (for a single pendulum kappa = alpha_1 itself,
/// its peak's squared inverse width) and the smallest effective stiffness kappa_i min(1, m_i /
/// S_{i+1}) (see above), in long double: alpha_j = beta g S_j l_j and their products may leave
/// double's range, which is what the callers check for.
struct JointStiffness {
  long double smallest = 0, largest = 0;
  long double smallest_effective = 0;
};

template <class Real>
JointStiffness joint_stiffness(const Chain<Real>& chain, const Real& beta) {
  // In MPFR the products are formed in MPFR (converting beta = 1e400 to double gave inf, and
  // inf / inf a NaN that passed every comparison); in double, in long double, which holds
  // products of the doubles that domain::check_double_scales admits (alpha_j <= 1e300).
  using Wide = std::conditional_t<is_mpfr_v<Real>, Real, long double>;
  const auto narrow = [](const Wide& x) -> long double {
    if constexpr (is_mpfr_v<Real>) {
      // beyond long double's range the comparisons below need only "huge" (inf), never NaN
      return x > Wide(std::numeric_limits<long double>::max())
                 ? std::numeric_limits<long double>::infinity()
                 : x.template convert_to<long double>();
    } else {
      return x;
    }
  };
  const std::size_t n = chain.size();
  const Wide b = Wide(beta), g = Wide(chain.gravity());
  std::vector<Wide> alpha(n);
  Wide total = 0;
  for (std::size_t j = 0; j < n; ++j) {
    alpha[j] = b * g * Wide(chain.tail_mass(j)) * Wide(chain.length(j));
    total += alpha[j];
  }
  JointStiffness k;
  if (n == 1) {
    k.smallest = k.largest = k.smallest_effective = narrow(total);
    return k;
  }
  std::vector<Wide> below(n + 1, Wide(0));  // below[i] = sum of alpha_j for j >= i, summed directly
  for (std::size_t j = n; j-- > 0;) below[j] = below[j + 1] + alpha[j];
  k.smallest = k.smallest_effective = std::numeric_limits<long double>::infinity();
  Wide head = 0;
  for (std::size_t i = 0; i + 1 < n; ++i) {
    head += alpha[i];
    const long double kappa = narrow(total > 0 ? Wide(head * (below[i + 1] / total)) : Wide(0));
    const long double light = narrow(Wide(chain.mass(i)) / Wide(chain.tail_mass(i + 1)));
    // NaN-proof: a NaN kappa (never from checked inputs) would be kept by std::min/std::max
    if (std::isnan(kappa) || std::isnan(light))
      throw invalid_input("average: a joint's stiffness is not a number for this input");
    k.smallest = std::min(k.smallest, kappa);
    k.largest = std::max(k.largest, kappa);
    k.smallest_effective = std::min(k.smallest_effective, kappa * std::min(1.0L, light));
  }
  // A joint's kappa_i is the cost of bending that joint alone. Turning one link alone (two
  // joints bent oppositely) costs only that link's own alpha_j: a soft link between stiff ones
  // (lengths 1, 1e-9, 1e3 at beta = 1e7: alpha_2 = 0.02 while every kappa_i is ~3e7) stays free
  // however stiff the joints look, and extrapolating from the joints' stiffness printed
  // <cos phi_2> = 0.9995 +- 7e-5 for a true 0.0084. The chain's softest mode lies between
  // min_j alpha_j / 4 and min_j alpha_j, so the links' stiffness bounds the effective one too.
  for (std::size_t j = 0; j < n; ++j)
    k.smallest_effective = std::min(k.smallest_effective, narrow(alpha[j]));
  return k;
}

constexpr double stiffness_extrapolated = 1e7;  ///< every joint stiffer: extrapolate
constexpr double stiffness_reference = 1e3;     ///< the reference runs' smallest stiffness
constexpr double stiffness_resolved = 1e13;     ///< the torus and qmc resolve peaks to here
constexpr double stiffness_resolved_mpfr = 1e9;  ///< in MPFR (~1 minute at 30 digits and 1e8)

/// V(beta) from V at beta_k = 2^k beta_1 (k = 0, 1, 2) and V_inf (see above).
template <class Real>
Estimate<Real> extrapolated(const std::array<const Estimate<Real>*, 3>& v, const Real& limit,
                            const Real& beta1, const Real& beta, ErrorKind kind) {
  using std::abs;
  const Real x = 1 / beta;
  std::array<Real, 3> xs, ys;
  for (std::size_t k = 0; k < 3; ++k) {
    xs[k] = 1 / (beta1 * Real(1 << k));
    ys[k] = (v[k]->value - limit) / xs[k];
  }
  // Lagrange bases at x: linear through the last two points, quadratic through all three.
  const Real l1 = (x - xs[2]) / (xs[1] - xs[2]), l2 = (x - xs[1]) / (xs[2] - xs[1]);
  const Real linear = l1 * ys[1] + l2 * ys[2];
  std::array<Real, 3> lq;
  for (std::size_t k = 0; k < 3; ++k) {
    lq[k] = 1;
    for (std::size_t j = 0; j < 3; ++j)
      if (j != k) lq[k] *= (x - xs[j]) / (xs[k] - xs[j]);
  }
  const Real quadratic = lq[0] * ys[0] + lq[1] * ys[1] + lq[2] * ys[2];
  const Real value = limit + x * quadratic;
  Real carried = 0;
  for (std::size_t k = 0; k < 3; ++k) carried += abs(lq[k]) * v[k]->error / xs[k];
  const Real error = x * (abs(quadratic - linear) + carried) +
                     4 * std::numeric_limits<Real>::epsilon() * abs(value);
  return {value, error, kind};
}

template <class Real>
Averages<Real> low_temperature_extrapolation(const Chain<Real>& chain, const Real& beta,
                                             const JointStiffness& stiffness,
                                             const std::function<Averages<Real>(const Real&)>& run) {
  const Real beta1 =
      Real(static_cast<long double>(static_cast<double>(beta)) * stiffness_reference /
           stiffness.smallest_effective);
  const std::array<Averages<Real>, 3> a{run(beta1), run(2 * beta1), run(4 * beta1)};
  const Averages<Real> limit = low_temperature_limit_any(chain);
  Averages<Real> out;
  const ErrorKind kind = a[2].error_kind;
  const std::size_t n = chain.size();
  using Field = std::vector<Estimate<Real>> Averages<Real>::*;
  for (Field field : {&Averages<Real>::beta_kinetic, &Averages<Real>::cos_angle,
                      &Averages<Real>::beta2_kinetic_variance}) {
    (out.*field).resize(n);
    for (std::size_t i = 0; i < n; ++i)
      (out.*field)[i] = extrapolated<Real>({&(a[0].*field)[i], &(a[1].*field)[i], &(a[2].*field)[i]},
                                           (limit.*field)[i].value, beta1, beta, kind);
  }
  if (n >= 2) {
    out.ratio = kinetic_ratio(out.beta_kinetic[0], out.beta_kinetic[1],
                              Real(std::numeric_limits<Real>::epsilon()));
  }
  out.method = Method::low_temperature_extrapolation;
  out.error_kind = kind;
  out.work_unit = a[2].work_unit;
  out.evaluations = a[0].evaluations + a[1].evaluations + a[2].evaluations;
  out.converged = a[0].converged && a[1].converged && a[2].converged;
  out.interrupted = a[0].interrupted || a[1].interrupted || a[2].interrupted;
  out.torus = a[2].torus;
  out.qmc = a[2].qmc;
  add_chain_extras(out, chain);
  return out;
}

}  // namespace pendavg::detail::limits
