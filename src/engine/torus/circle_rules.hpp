// SPDX-License-Identifier: GPL-3.0-or-later
// engine/torus/circle_rules.hpp -- the one-dimensional rules of the torus quadrature (one per
// relative angle delta_i, nodes in (-pi, pi]) and the node maps that cluster them.
//
// Equations (src/engine/torus/README.md, 'Circle rules' and 'Node maps'):
//     trapezoid:       delta_k = 2 pi k / n, weight 1; exact for trigonometric polynomials of
//                      degree < n, so geometric convergence for periodic analytic integrands;
//                      level 2n contains level n (nested refinement)
//     Gauss-Legendre:  delta_k = pi (1 + x_k) folded into (-pi, pi], weight w_k / 2 (x_k, w_k
//                      the rule on [-1, 1]); the comparison rule, not nested
//     node map:        delta = t - (a/p) sin(p t), p in {1, 2}, Jacobian 1 - a cos(p t), with
//                      1 - a = eps^(2/3) from the mass scale sqrt(m_i / S_i) and the Boltzmann
//                      width sqrt(S / (H T))
// Every rule is symmetric under delta -> -delta with mirrored nodes stored bitwise negated, so the
// grid walk (torus/level_sums.hpp) evaluates each mirror pair once.
#pragma once

#include "engine/numerics/legendre.hpp"
#include "engine/numerics/precision.hpp"
#include "pendavg/average.hpp"
#include "pendavg/chain.hpp"

#include <gsl/gsl_integration.h>

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <type_traits>
#include <utility>
#include <vector>

namespace pendavg::detail::torus {

using std::abs;
using std::exp;
using std::log;
using std::sqrt;

/// One circle rule: nodes delta_k in (-pi, pi], their cosines and sines, weights, and the
/// action of the reflection delta -> -delta on the node indices.
template <class Real>
struct CircleRule {
  std::size_t n = 0;
  std::vector<Real> angle, cos_angle, sin_angle, weight;
  /// pi - |angle|, formed without the angle's rounding (sin_angle and cos_angle of the nodes past
  /// pi/2 are taken from it: sin(pi - tau) from a rounded angle near pi would be off by u pi).
  std::vector<Real> from_pi;
  /// +1: k < mirror(k), evaluated and counted twice; 0: k = mirror(k); -1: mirror of a +1 node.
  std::vector<signed char> orbit;
  /// Nested rules: the node is also a node of the previous level (its sums are reused).
  std::vector<unsigned char> inherited;
  /// Index of the node at the negated angle.
  std::vector<std::size_t> mirror;
  /// Weights: the trapezoid's are 1 (times the node map's Jacobian), summing to n per dimension,
  /// so the full grid's product weights sum to n^D; Gauss-Legendre's sum to 1 per dimension.
  /// nested: the rule's level reuses the previous level's sums (trapezoid levels after the first).
  bool nested = false;
};

/// n equispaced nodes, weight 1, node k at 2 pi k / n folded into (-pi, pi]. Node n - k holds
/// the bitwise negated angle and sine of node k, so mirrored nodes evaluate identically.
template <class Real>
CircleRule<Real> trapezoid_rule(std::size_t n, bool nested_on_previous) {
  using std::cos;
  using std::sin;
  CircleRule<Real> r;
  r.n = n;
  r.nested = nested_on_previous;
  r.angle.resize(n);
  r.cos_angle.resize(n);
  r.sin_angle.resize(n);
  r.from_pi.resize(n);
  r.weight.assign(n, Real(1));
  r.orbit.resize(n);
  r.inherited.resize(n);
  r.mirror.resize(n);
  for (std::size_t k = 0; k < n; ++k) r.mirror[k] = (n - k) % n;
  const Real two_pi = 2 * pi<Real>();
  for (std::size_t k = 0; 2 * k <= n; ++k) {
    Real a = two_pi * Real(static_cast<double>(k)) / Real(static_cast<double>(n));
    // pi (n - 2k) / n: the distance to pi, exact up to one rounding
    const Real tau = pi<Real>() * Real(static_cast<double>(n - 2 * k)) / Real(static_cast<double>(n));
    Real c = cos(a), s = sin(a);
    if (4 * k > n) {  // past pi/2: from the distance to pi
      c = -cos(tau);
      s = sin(tau);
    }
    if (k == 0) {
      a = 0;
      c = 1;
      s = 0;
    } else if (2 * k == n) {
      a = pi<Real>();
      c = -1;
      s = 0;
    }
    r.angle[k] = a;
    r.cos_angle[k] = c;
    r.sin_angle[k] = s;
    r.from_pi[k] = 2 * k == n ? Real(0) : tau;
    r.orbit[k] = (k == 0 || 2 * k == n) ? 0 : 1;
    if (k != 0 && 2 * k != n) {
      r.angle[n - k] = -a;
      r.cos_angle[n - k] = c;
      r.sin_angle[n - k] = -s;
      r.from_pi[n - k] = tau;
      r.orbit[n - k] = -1;
    }
  }
  for (std::size_t k = 0; k < n; ++k) r.inherited[k] = nested_on_previous && (k % 2 == 0);
  return r;
}

/// Gauss-Legendre nodes x_k and weights on [-1, 1] (weights sum to 2), ascending, with
/// x_{n-1-k} = -x_k exactly. double: GSL's table; other types: Newton on P_n from GSL's nodes.
template <class Real>
void gauss_legendre_nodes(std::size_t n, std::vector<Real>& x, std::vector<Real>& w,
                          std::vector<Real>& one_plus_x) {
  gsl_integration_glfixed_table* table = gsl_integration_glfixed_table_alloc(n);
  if (table == nullptr) throw invalid_input("cannot build a Gauss-Legendre table");
  std::vector<std::pair<double, double>> seed(n);
  for (std::size_t i = 0; i < n; ++i) {
    gsl_integration_glfixed_point(-1.0, 1.0, i, &seed[i].first, &seed[i].second, table);
  }
  gsl_integration_glfixed_table_free(table);
  std::sort(seed.begin(), seed.end());
  x.assign(n, Real(0));
  w.assign(n, Real(0));
  one_plus_x.assign(n, Real(1));
  for (std::size_t k = 0; 2 * k < n; ++k) {  // the non-positive half, then mirror
    Real xk = seed[k].first, wk = seed[k].second;
    Real yk = 1 + xk;
    if (2 * k + 1 == n) {
      xk = 0;
      yk = 1;
    }
    if constexpr (std::is_same_v<Real, double>) {
      // Near x = -1 the node is y = 1 + x, which x itself carries only to ~u absolute (a
      // relative error u / y, ~3e-9 for n = 8192: the circle's nodes near angle 0 would be off by
      // that much against their weights). Newton on P_n(-1 + y) in y, never forming x: the
      // recurrence's x P_j is y P_j - P_j. Each step's rounding moves the root by ~u / n.
      if (2 * xk < -1) {
        Real derivative = 0;
        for (int iteration = 0; iteration < 3; ++iteration) {
          Real p_prev = 1, p = yk - 1;
          for (std::size_t j = 1; j < n; ++j) {
            const Real jj = static_cast<Real>(j);
            const Real p_next = ((2 * jj + 1) * (yk * p - p) - jj * p_prev) / (jj + 1);
            p_prev = p;
            p = p_next;
          }
          derivative = static_cast<Real>(n) * ((yk * p - p) - p_prev) / (yk * (yk - 2));
          yk -= p / derivative;
        }
        wk = 2 / (yk * (2 - yk) * derivative * derivative);
        xk = yk - 1;
      }
    }
    if constexpr (!std::is_same_v<Real, double>) {
      // Newton on P_n: P_{j+1} = ((2j+1) x P_j - j P_{j-1}) / (j+1), P'_n = n (x P_n - P_{n-1}) /
      // (x^2 - 1). Quadratic convergence from a double seed: ~log2(digits/16) + 2 steps.
      const Real tiny = 4 * unit_roundoff<Real>();
      Real derivative = 0;
      for (int iteration = 0; iteration < 64; ++iteration) {
        const detail::LegendreAt<Real> legendre = detail::legendre_at(n, xk);
        derivative = legendre.derivative;
        const Real step = legendre.value / derivative;
        if (2 * k + 1 != n) xk -= step;
        if (abs(step) <= tiny) break;
      }
      wk = 2 / ((1 - xk * xk) * derivative * derivative);
    }
    if constexpr (!std::is_same_v<Real, double>) yk = 1 + xk;  // after the Newton steps above
    x[k] = xk;
    w[k] = wk;
    one_plus_x[k] = yk;
    x[n - 1 - k] = -xk;
    w[n - 1 - k] = wk;
  }
}

/// n Gauss-Legendre nodes on [0, 2 pi) (weights sum to 1), folded into (-pi, pi]: the node
/// pi (1 + x_k) for x_k <= 0 and pi (x_k - 1) for x_k > 0, so node n-1-k is the mirror of node k.
template <class Real>
CircleRule<Real> gauss_legendre_rule(std::size_t n) {
  using std::cos;
  using std::sin;
  std::vector<Real> x, w, one_plus_x;
  gauss_legendre_nodes<Real>(n, x, w, one_plus_x);
  CircleRule<Real> r;
  r.n = n;
  r.nested = false;
  r.angle.resize(n);
  r.cos_angle.resize(n);
  r.sin_angle.resize(n);
  r.from_pi.resize(n);
  r.weight.resize(n);
  r.orbit.resize(n);
  r.inherited.assign(n, 0);
  r.mirror.resize(n);
  for (std::size_t k = 0; k < n; ++k) r.mirror[k] = n - 1 - k;
  const Real p = pi<Real>();
  for (std::size_t k = 0; 2 * k < n; ++k) {
    const Real a = p * one_plus_x[k];  // in (0, pi]; its mirror -a is node n-1-k
    const Real tau = -p * x[k];     // pi - a, exact up to one rounding (x <= 0)
    Real c = cos(a), s = sin(a);
    if (2 * x[k] > -1) {  // past pi/2: from the distance to pi
      c = -cos(tau);
      s = sin(tau);
    }
    if (2 * k + 1 == n) {
      c = -1;
      s = 0;
    }
    r.angle[k] = a;
    r.cos_angle[k] = c;
    r.sin_angle[k] = s;
    r.from_pi[k] = 2 * k + 1 == n ? Real(0) : tau;
    r.weight[k] = w[k] / 2;
    r.orbit[k] = (2 * k + 1 == n) ? 0 : 1;
    if (2 * k + 1 != n) {
      r.angle[n - 1 - k] = -a;
      r.cos_angle[n - 1 - k] = c;
      r.sin_angle[n - 1 - k] = -s;
      r.from_pi[n - 1 - k] = tau;
      r.weight[n - 1 - k] = w[k] / 2;
      r.orbit[n - 1 - k] = -1;
    }
  }
  return r;
}

/// A periodic, odd change of variable delta = t - (a/p) sin(p t), 0 <= a < 1, p in {1, 2}, with
/// Jacobian 1 - a cos(p t) > 0. It clusters nodes at delta = 0 (p = 1) or at 0 and pi (p = 2):
/// near 0, delta ~ (1 - a) t + (a p^2 / 6) t^3, so a near-real singularity or a peak of width
/// eps in delta is seen at distance ~ eps / (1 - a) or ~ eps^(1/3) in t. The integrand stays
/// periodic and analytic in t (sin is entire), so the trapezoid keeps converging geometrically
/// and its levels still nest; the map commutes with delta -> -delta, so the halving stays exact.
template <class Real>
struct NodeMap {
  /// 1 - a, the Jacobian's minimum (kept rather than a: the map's node positions and Jacobian
  /// near t = 0 are formed from it without cancellation; 1 - a rounded from a stored a near 1
  /// would carry a relative error u / (1 - a), ~1e-12 for a light mass of 1e-12).
  Real gap{1};
  int p = 1;
  bool identity() const { return gap == 1; }
};

/// x - sin x, without the cancellation of the direct difference for small |x| (its Taylor
/// series there: x^3/6 - x^5/120 + ..., each term smaller by x^2 / 20 or more).
template <class Real>
Real x_minus_sin(const Real& x) {
  using std::abs;
  using std::sin;
  if (!(abs(x) < Real(0.5))) return x - sin(x);
  const Real x2 = x * x;
  Real term = x * x2 / 6, sum = term;
  for (int k = 2; k < 400; ++k) {
    term = -term * x2 / Real((2 * k) * (2 * k + 1));
    const Real next = sum + term;
    if (next == sum) break;
    sum = next;
  }
  return sum;
}

/// The rule `base` (nodes t, weights) after the map: nodes delta(t), weights times the Jacobian.
/// Nodes at t = 0 and t = pi stay exactly there; mirrored nodes stay bitwise negated.
template <class Real>
CircleRule<Real> mapped_rule(const CircleRule<Real>& base, const NodeMap<Real>& map) {
  using std::abs;
  using std::cos;
  using std::sin;
  if (map.identity()) return base;
  CircleRule<Real> r = base;
  const Real pp = Real(map.p);
  const Real a = 1 - map.gap;
  for (std::size_t k = 0; k < base.n; ++k) {
    if (base.orbit[k] < 0) continue;  // set from its mirror below
    const Real& t = base.angle[k];
    const bool at_pi = (base.cos_angle[k] == -1 && base.sin_angle[k] == 0);
    Real delta = t, c = base.cos_angle[k], s = base.sin_angle[k], from_pi = base.from_pi[k];
    Real jacobian;
    if (base.cos_angle[k] >= 0) {
      const Real pt = pp * t;
      if (t != 0) {
        // delta = t - a sin(pt) / p = (pt - sin pt) / p + gap sin(pt) / p: two terms of one
        // sign near t = 0, where the direct form cancels to ~gap t.
        delta = (x_minus_sin<Real>(pt) + map.gap * sin(pt)) / pp;
        c = cos(delta);
        s = sin(delta);
        from_pi = pi<Real>() - abs(delta);
      }
      // 1 - a cos(pt) = 2 sin^2(pt / 2) + gap cos(pt), without the cancellation at t ~ 0.
      const Real half_sine = sin(pt / 2);
      jacobian = 2 * half_sine * half_sine + map.gap * cos(pt);
    } else {
      // Past pi/2, from tau = pi - |t| (the base rule's, unrounded by the angle): the map is
      // odd about pi as well, pi - |delta| = eps(tau) with eps = tau + a sin(tau) (p = 1) or
      // (2 tau - sin 2 tau) / 2 + gap sin(2 tau) / 2 (p = 2); the Jacobian 1 + a cos(tau) or
      // 2 sin^2(tau) + gap cos(2 tau). sin and cos of delta then come from eps, accurately
      // even where eps is tiny (the light-mass features at delta = pi, p = 2).
      const Real& tau = base.from_pi[k];
      Real eps = tau;
      if (map.p == 1) {
        eps = tau + a * sin(tau);
        jacobian = 1 + a * cos(tau);
      } else {
        eps = (x_minus_sin<Real>(2 * tau) + map.gap * sin(2 * tau)) / 2;
        const Real sine = sin(tau);
        jacobian = 2 * sine * sine + map.gap * cos(2 * tau);
      }
      if (!at_pi) {
        delta = t > 0 ? Real(pi<Real>() - eps) : Real(eps - pi<Real>());
        c = -cos(eps);
        s = t > 0 ? Real(sin(eps)) : Real(-sin(eps));
        from_pi = eps;
      }
    }
    r.angle[k] = delta;
    r.cos_angle[k] = c;
    r.sin_angle[k] = s;
    r.from_pi[k] = from_pi;
    r.weight[k] = base.weight[k] * jacobian;
    const std::size_t m = base.mirror[k];
    if (m != k) {
      r.angle[m] = -delta;
      r.cos_angle[m] = c;
      r.sin_angle[m] = -s;
      r.from_pi[m] = from_pi;
      r.weight[m] = r.weight[k];
    }
  }
  return r;
}

/// The automatic map of each relative angle delta_i (0-based i < N - 1), from two scales:
///  * the mass scale eps_m = sqrt(m_i / S_i): sqrt(det A) and the traces carry the factor
///    1 + kappa sin^2 delta_i with kappa <= S_{i+1} / m_i (trace_formula.hpp), whose zeros lie at
///    distance ~ 1/sqrt(1 + kappa) from the real axis, at delta_i = 0 and pi (p = 2);
///  * the Boltzmann width sigma = sqrt(S / (H T)), with H and T the sums of alpha_j over the
///    particles above and below the joint: S - R ~ H T delta_i^2 / (2 S) near 0 (p = 1).
/// eps = min of the two; no map while eps >= 0.3 (smooth integrands: the map would only thin
/// the nodes elsewhere), otherwise 1 - a = eps^(2/3), which puts the singularity at distance
/// ~ eps^(1/3) in t from both the linear and the cubic term.
template <class Real>
std::vector<NodeMap<Real>> automatic_node_maps(const Chain<Real>& chain,
                                               const std::vector<Real>& alpha) {
  const std::size_t n = chain.size();
  std::vector<NodeMap<Real>> maps(n > 0 ? n - 1 : 0);
  // Tail sums summed directly (total - head cancels when a root link dominates), and the width
  // as sqrt((S / H) / T), which cannot overflow.
  std::vector<Real> below(n + 1, Real(0));
  for (std::size_t j = n; j-- > 0;) below[j] = below[j + 1] + alpha[j];
  const Real& total = below[0];
  Real head = 0;
  for (std::size_t i = 0; i + 1 < n; ++i) {
    head += alpha[i];
    const Real& tail = below[i + 1];
    const Real mass_scale = sqrt(chain.mass(i) / chain.tail_mass(i));
    Real eps = mass_scale;
    int p = 2;
    if (head > 0 && tail > 0) {
      const Real width = sqrt(total / head / tail);
      if (width < eps) {
        eps = width;
        p = 1;
      }
    }
    if (eps < Real(0.3)) {
      maps[i].gap = exp(2 * log(eps) / 3);  // 1 - a = eps^(2/3)
      maps[i].p = p;
    }
  }
  return maps;
}

}  // namespace pendavg::detail::torus
