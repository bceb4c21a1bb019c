// SPDX-License-Identifier: GPL-3.0-or-later
// pendavg/torus.hpp -- exact canonical averages for any N by tensor quadrature on the reduced
// (N-1)-torus (MATH.md Secs. 1-4 and 6; paper eq. ave-Ki-linear-pi-trace-varphi).
//
// What it computes. For an N-link chain at inverse temperature beta:
//   * beta <K_i>          = (1/2) <tr X_i>_w                               (MATH.md Sec. 1),
//   * beta^2 Var K_i      = <(tr X_i)^2 + 2 tr X_i^2>_w / 4 - (beta<K_i>)^2 (Isserlis, Sec. 4),
//   * <cos phi_j>         = < (I1(R)/I0(R)) cos(theta_j - arg z) >_w       (Sec. 2),
//   * beta <K_i^(c)>      = 1/2 exactly (Sec. 4; reported as the built-in check it is), and
//   * the paper's diagonal approximation, eq. ke-linear-tave-1 (Sec. 8), next to the exact values.
// The psi = phi_1 integral is done in closed form (Sec. 2), so the weight on the torus of the
// N - 1 relative angles delta_i = phi_{i+1} - phi_i is
//     w(delta) = sqrt(det A) I0(R),   R = |z|,   z = sum_j alpha_j e^{i theta_j},
// with theta_1 = 0, theta_{j+1} = theta_j + delta_j and alpha_j = beta g S_j l_j. The map
// delta -> theta has unit Jacobian on the torus, and every delta_i is uniform on one period.
//
// How. w is evaluated as exp(log sqrt(det A) - log_hadamard - (S - R)) e^{-R} I0(R), S = sum_j
// alpha_j, log_hadamard = sum_j log(l_j sqrt(S_j)) (Hadamard: sqrt(det A) <= prod_j l_j sqrt(S_j)
// where S_j are the tail masses). Every factor is <= 1, so nothing overflows at any beta or N,
// and sums of at most 1e9 of them stay finite. S - R >= 0 is formed without cancellation as
// sum_j alpha_j (1 - cos(theta_j - arg z)) (Re(z e^{-i arg z}) = R), with 1 - cos x =
// sin^2 x / (1 + cos x) for cos x >= 0: its rounding error stays ~ u sqrt(alpha) instead of
// u alpha. Per node the traces come from node_traces_relative (O(N), trace_formula.hpp).
//   * Rule `trapezoid` (the default): n equispaced nodes per dimension, the Gaussian rule on the
//     circle (exact for trigonometric polynomials of degree < n), so for this periodic analytic
//     integrand it converges geometrically (MATH.md Sec. 6). Levels n0, 2 n0, 4 n0, ... nest:
//     level L+1 evaluates only the nodes with at least one odd index and reuses every earlier sum.
//   * Rule `gauss_legendre`: n Gauss-Legendre nodes per dimension on [0, 2 pi), the comparison
//     rule (GSL's table in double; Newton-polished from GSL's nodes in MPFR). Its levels do not
//     nest, so each level is evaluated afresh. It needs more nodes than the trapezoid for the
//     same accuracy: use it as an independent check only.
//   * Node map (node_map = automatic, the default): per relative angle, the periodic odd map
//     delta = t - (a/p) sin(p t) clusters nodes where a light particle (m_i / S_i small: the
//     zeros of 1 + kappa sin^2 delta near 0 and pi) or a narrow Boltzmann peak (large beta, at
//     0) needs them (MATH.md Sec. 6); the rule then runs in t. Off (a = 0) for moderate chains,
//     so the unit-mass cases are unaffected. Effect, nodes per dimension for 1e-13: N = 2 with
//     m1/M = 1e-6: 512 (equispaced: 65536); N = 3 with m_1 = 1e-3: 256 (equispaced: > 1024);
//     N = 3 at beta = 1e4: 256 (> 1024); N = 4 with m_1 = m_2 = 1e-2 at 1e-11: 0.2 s (13 s).
//   * Symmetry: every integrand is invariant under delta -> -delta (reflection phi -> -phi).
//     Both node sets are mapped onto themselves by it, with nodes stored so that mirrored nodes
//     have bitwise negated angles and sines; each mirror pair is evaluated once and counted
//     twice. This halves the work exactly (the fixed points, all delta_i in {0, pi}, once).
//   * Stopping: refine n -> 2n until every reported quantity's error estimate (below) is at most
//     `tolerance` relative to its scale (beta<K_i>: itself; Var K_i: beta^2 <K_i^2>; <cos phi_j>: the
//     weighted L1 norm <|I1/I0 cos(theta_j - arg z)|>_w), and so is the mean weight Z's (the
//     partition function up to constants). The test on Z guards against a false convergence
//     when the weight is a peak narrower than the grid spacing: the ratios then freeze at the
//     node at the peak (delta = 0, the hanging chain, is always a node) but Z does not.
//   * Error estimate: from the successive-refinement differences d_L = |Q_L - Q_{L-1}|. For
//     geometric convergence, e_n = C rho^n, the error of the returned level 2n is e_n rho^n =
//     e_n (e_n / e_{n/2})^2; once the differences contract by at least 10 per level (so that
//     d ~ e), the estimate is d_L (d_L / d_{L-1}), which exceeds that by e_{n/2}/e_n >= 10.
//     Before that (or with extrapolate_error = false) it is d_L itself. Plus a rounding budget
//     of a few dozen ulps of the quantity's scale (rounding_ulps below). Observed: for N = 2 over
//     90 (beta, masses, lengths) cases the torus and the 1-D integral differ by <= 0.1 of the
//     summed error bars; the bars are ~3e-15 relative, the differences ~3e-16.
//     Not a proof: an integrand whose aliasing error vanished at n/2 and n but not at 2n would
//     fool it. converged = false when max_points_per_dim or max_grid_points stopped the
//     refinement first; the values are then the last level's, and every ratio's error is raised
//     to at least Z's relative difference times the ratio's scale, so the bars stay valid when a
//     narrow peak was seen by one node only (tested at beta = 1e4 with n <= 64).
// When to prefer something else. N = 2: reduced_integral_average (double_pendulum.hpp) is
// faster (and it is the reference the tests hold this engine to). Large N: n^{N-1} nodes (the
// guard refuses more than max_grid_points, default 1e9; N = 5 at 1e-10 takes ~2 s)
// -- use qmc_average, also in this header (randomized lattice QMC over a law that includes the
// pivot factors of det A,
// MATH.md Sec. 6; see the comment above QmcOptions).
//
// Result type. Averages<Real> carries the common fields (method torus_trapezoid,
// torus_gauss_legendre or qmc) and the any-N extras; Averages::torus / ::qmc describe the run.
//
// Precision: generic over Real (double, long double, mpfr_real). With options.digits > 0 (MPFR:
// 16..1000) the call runs at digits + guard_digits and the tolerance becomes 10^-digits. The
// double path is thread-parallel over the outermost dimension when options.threads > 1 (results
// are bitwise independent of the thread count: partial sums are combined in a fixed order);
// MPFR always runs on the calling thread.
#pragma once

#include "engine/bessel.hpp"
#include "engine/estimates.hpp"
#include "pendavg/average.hpp"
#include "pendavg/chain.hpp"
#include "engine/detail/legendre.hpp"
#include "engine/detail/qmc_lattices.hpp"
#include "engine/precision.hpp"
#include "engine/parallel.hpp"
#include "pendavg/result.hpp"
#include "pendavg/trace_formula.hpp"

#include <boost/math/constants/constants.hpp>
#include <boost/math/special_functions/log1p.hpp>
#include <gsl/gsl_integration.h>

#include <algorithm>
#include <cmath>
#include <complex>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <limits>
#include <optional>
#include <random>
#include <stdexcept>
#include <string>
#include <type_traits>
#include <vector>

namespace pendavg {

/// The per-dimension rule of torus_average.
enum class TorusRule {
  trapezoid,       ///< n equispaced nodes: the Gaussian rule on the circle (default)
  gauss_legendre,  ///< n Gauss-Legendre nodes on [0, 2 pi): the comparison rule
};

inline const char* torus_rule_name(TorusRule rule) {
  return rule == TorusRule::trapezoid ? "trapezoid" : "gauss-legendre";
}

/// Node placement per relative angle: `automatic` clusters nodes by a periodic map where a
/// light particle (small m_i / S_i) or a narrow Boltzmann peak (large beta) needs them; `none`
/// keeps the plain rule (equispaced for the trapezoid).
enum class TorusNodeMap { automatic, none };

struct TorusOptions {
  TorusRule rule = TorusRule::trapezoid;
  TorusNodeMap node_map = TorusNodeMap::automatic;
  /// Relative tolerance on every reported quantity (see the header comment for the scales).
  /// Ignored when digits > 0.
  double tolerance = 1e-13;
  /// 0: run at the caller's precision with `tolerance`. > 0: check_digits<Real>(digits) (16 for
  /// double; 16..1000 for MPFR, run at digits + guard_digits, tolerance 10^-digits).
  int digits = 0;
  std::size_t min_points_per_dim = 8;     ///< n of the first level (>= 2)
  std::size_t max_points_per_dim = 8192;  ///< refinement stops (converged = false) beyond it
  double max_grid_points = 1e9;           ///< n^(N-1) cap: refused if the first level exceeds it
  /// Work cap: refinement stops (converged = false, the errors of the last level reported)
  /// before a level whose evaluations would bring the run's total beyond it.
  double max_evaluations = std::numeric_limits<double>::infinity();
  int threads = 1;                        ///< OpenMP threads (double/long double only)
  /// true: once the successive differences contract by >= 10 per level, the error of the last
  /// level is estimated as d_n (d_n / d_{n/2}) (geometric convergence); false: d_n itself.
  bool extrapolate_error = true;
  /// Progress within each level and a stop request (may be null): a stopped level is discarded
  /// and the previous one reported (interrupted = true); none finished throws `interrupted`.
  const RunControl* control = nullptr;
};

namespace detail::torus {

using std::abs;
using std::exp;
using std::log;
using std::sqrt;

template <class Real>
Real pi() {
  return boost::math::constants::pi<Real>();
}

/// Sum with a running compensation (Neumaier) for built-in floating types; plain for MPFR,
/// whose guard digits absorb summation rounding.
template <class Real>
struct CompensatedSum {
  Real sum{0}, compensation{0};
  void add(const Real& x) {
    if constexpr (std::is_floating_point_v<Real>) {
      const Real t = sum + x;
      if (abs(sum) >= abs(x)) {
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

/// Weighted sums over the nodes of one level: the weight and, per particle, the weighted
/// tr X_i, (tr X_i)^2 + 2 tr X_i^2, I1/I0 cos(theta_i - arg z) and its absolute value.
template <class Real>
struct TorusSums {
  CompensatedSum<Real> weight;
  /// sum of w sum_j alpha_j |sin(theta_j - arg z)|: the weight's exponent S - R carries a
  /// rounding error of a few u times that lever at each node (see rounding_ulps).
  CompensatedSum<Real> exponent_lever;
  std::vector<CompensatedSum<Real>> trace, second_moment, cosine, cosine_abs;
  std::size_t evaluations = 0;
  explicit TorusSums(std::size_t n = 0)
      : trace(n), second_moment(n), cosine(n), cosine_abs(n) {}
  void merge(const TorusSums& other) {
    weight.add(other.weight.value());
    exponent_lever.add(other.exponent_lever.value());
    for (std::size_t i = 0; i < trace.size(); ++i) {
      trace[i].add(other.trace[i].value());
      second_moment[i].add(other.second_moment[i].value());
      cosine[i].add(other.cosine[i].value());
      cosine_abs[i].add(other.cosine_abs[i].value());
    }
    evaluations += other.evaluations;
  }
};

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

/// The reduced integrand at one node: the weight w(delta) (scaled as in the header comment),
/// the traces, and the angle factors. Holds every per-thread buffer.
template <class Real>
class ReducedIntegrand {
 public:
  ReducedIntegrand(const Chain<Real>& chain, const WeightConstants<Real>& constants)
      : chain_(chain), k_(constants), workspace_(chain.size()), unit_cos_(chain.size()),
        unit_sin_(chain.size()), cos_offset_(chain.size()) {}

  /// Evaluates the node with relative angles delta (cosines cd, sines sd; N - 1 each) and adds
  /// weight * multiplicity * (its contributions) to `sums`.
  void accumulate(const Real* /*delta: see cd, sd*/, const Real* cd, const Real* sd, const Real& node_weight,
                  TorusSums<Real>& sums) {
    const std::size_t n = chain_.size();
    // from sines and cosines: the rules form them accurately near pi (CircleRule::from_pi)
    const NodeTraces<Real>& traces = node_traces_sincos(chain_, sd, cd, workspace_);
    // Unit vectors e^{i theta_j} by rotation products, and z = sum_j alpha_j e^{i theta_j}.
    unit_cos_[0] = 1;
    unit_sin_[0] = 0;
    Real zx = k_.alpha[0], zy = 0;
    for (std::size_t j = 1; j < n; ++j) {
      unit_cos_[j] = unit_cos_[j - 1] * cd[j - 1] - unit_sin_[j - 1] * sd[j - 1];
      unit_sin_[j] = unit_sin_[j - 1] * cd[j - 1] + unit_cos_[j - 1] * sd[j - 1];
      zx += k_.alpha[j] * unit_cos_[j];
      zy += k_.alpha[j] * unit_sin_[j];
    }
    Real radius = 0, s_minus_r = k_.alpha_sum, lever = 0;
    if (k_.alpha_sum > 0) {
      const Real sx = zx / k_.alpha_sum, sy = zy / k_.alpha_sum;  // |.| <= 1: no overflow
      radius = k_.alpha_sum * sqrt(sx * sx + sy * sy);
    }
    if (radius > 0) {
      // cos/sin of theta_j - arg z, and S - R = sum_j alpha_j (1 - cos(theta_j - arg z)).
      const Real ux = zx / radius, uy = zy / radius;
      s_minus_r = 0;
      for (std::size_t j = 0; j < n; ++j) {
        const Real c = unit_cos_[j] * ux + unit_sin_[j] * uy;
        const Real s = unit_sin_[j] * ux - unit_cos_[j] * uy;
        cos_offset_[j] = c;
        s_minus_r += k_.alpha[j] * (c >= 0 ? Real(s * s / (1 + c)) : Real(1 - c));
        lever += k_.alpha[j] * abs(s);
      }
    } else {
      for (std::size_t j = 0; j < n; ++j) cos_offset_[j] = 0;
    }
    const ScaledBesselI01<Real> bessel = scaled_bessel_i01(radius);
    const Real w =
        node_weight * exp(traces.log_sqrt_det_A - k_.log_hadamard - s_minus_r) * bessel.i0e;
    const Real bessel_ratio_w = w * (bessel.i1e / bessel.i0e);
    sums.weight.add(w);
    sums.exponent_lever.add(w * lever);
    for (std::size_t i = 0; i < n; ++i) {
      const Real& t = traces.trace_X[i];
      sums.trace[i].add(w * t);
      sums.second_moment[i].add(w * (t * t + 2 * traces.trace_X_squared[i]));
      const Real cw = bessel_ratio_w * cos_offset_[i];
      sums.cosine[i].add(cw);
      sums.cosine_abs[i].add(abs(cw));
    }
    ++sums.evaluations;
  }

 private:
  const Chain<Real>& chain_;
  const WeightConstants<Real>& k_;
  TraceWorkspace<Real> workspace_;
  std::vector<Real> unit_cos_, unit_sin_, cos_offset_;
};

/// Walks the grid of one level below the outermost dimension, visiting each mirror orbit of the
/// nodes not inherited from the previous level once, with its multiplicity (1 or 2).
template <class Real>
class GridWalker {
 public:
  /// `control` (or null) is polled before each innermost row of nodes: a stop request abandons
  /// the walk (abandoned(); the level is then discarded), so that a level of seconds (N = 8)
  /// stops within milliseconds, not at the end of its outermost slice.
  GridWalker(const std::vector<CircleRule<Real>>& rules, std::size_t dims,
             ReducedIntegrand<Real>& integrand, const RunControl* control = nullptr)
      : rules_(rules), dims_(dims), integrand_(integrand), control_(control), delta_(dims),
        cd_(dims), sd_(dims), weight_(dims + 1) {}

  bool abandoned() const { return abandoned_; }

  /// Every node with outermost index k0 (dims >= 1), or the single node (dims = 0).
  void walk_outer(std::size_t k0, TorusSums<Real>& sums) {
    weight_[0] = 1;
    if (dims_ == 0) {
      integrand_.accumulate(nullptr, nullptr, nullptr, weight_[0], sums);
      return;
    }
    const int orbit = rules_[0].orbit[k0];
    if (orbit < 0) return;
    set(0, k0);
    walk(1, orbit == 0, rules_[0].inherited[k0] != 0, orbit == 0 ? 1 : 2, sums);
  }

 private:
  void set(std::size_t d, std::size_t k) {
    const CircleRule<Real>& rule = rules_[d];
    delta_[d] = rule.angle[k];
    cd_[d] = rule.cos_angle[k];
    sd_[d] = rule.sin_angle[k];
    weight_[d + 1] = weight_[d] * rule.weight[k];
  }

  void walk(std::size_t d, bool constrained, bool all_inherited, int multiplicity,
            TorusSums<Real>& sums) {
    if (d == dims_) {
      if (rules_[0].nested && all_inherited) return;  // counted at the previous level
      integrand_.accumulate(delta_.data(), cd_.data(), sd_.data(),
                            multiplicity == 1 ? weight_[d] : Real(2 * weight_[d]), sums);
      return;
    }
    if (d + 1 == dims_ && control_ != nullptr && control_->stop_requested()) abandoned_ = true;
    if (abandoned_) return;
    const CircleRule<Real>& rule = rules_[d];
    for (std::size_t k = 0; k < rule.n && !abandoned_; ++k) {
      int orbit = 1;
      if (constrained) {
        orbit = rule.orbit[k];
        if (orbit < 0) continue;
      }
      set(d, k);
      walk(d + 1, constrained && orbit == 0, all_inherited && rule.inherited[k] != 0,
           constrained && orbit == 1 ? 2 : multiplicity, sums);
    }
  }

  const std::vector<CircleRule<Real>>& rules_;  // one per dimension, same n and orbits
  std::size_t dims_;
  ReducedIntegrand<Real>& integrand_;
  const RunControl* control_;
  bool abandoned_ = false;
  std::vector<Real> delta_, cd_, sd_, weight_;
};

/// Sums of one level over every node (or, for a nested level, every node not on the previous
/// level). Deterministic: one partial sum per outermost index, combined in index order.
template <class Real>
TorusSums<Real> level_sums(const Chain<Real>& chain, const WeightConstants<Real>& constants,
                           const std::vector<CircleRule<Real>>& rules, std::size_t dims,
                           int threads, const RunControl* control, bool& stopped) {
  std::atomic<bool> stop_seen{false};
  std::size_t done = 0;
  const std::size_t n_particles = chain.size();
  const std::size_t outer = dims == 0 ? 1 : rules[0].n;
  std::vector<TorusSums<Real>> partial(outer, TorusSums<Real>(n_particles));
  ParallelErrors errors;  // an exception may not leave the parallel region
  int team = 1;
  if constexpr (std::is_floating_point_v<Real>) team = std::max(threads, 1);
#if defined(_OPENMP)
#pragma omp parallel num_threads(team) if (team > 1)
#endif
  {
    std::optional<ReducedIntegrand<Real>> integrand;
    std::optional<GridWalker<Real>> walker;
    TorusSums<Real> local(n_particles);  // per thread: no false sharing between tasks
    errors.capture([&] {
      integrand.emplace(chain, constants);
      walker.emplace(rules, dims, *integrand, control);
    });
#if defined(_OPENMP)
#pragma omp for schedule(dynamic, 1)
#endif
    for (std::ptrdiff_t k0 = 0; k0 < static_cast<std::ptrdiff_t>(outer); ++k0) {
      errors.capture([&] {
        if (!walker || stop_seen.load(std::memory_order_relaxed)) return;
        local = TorusSums<Real>(n_particles);
        walker->walk_outer(static_cast<std::size_t>(k0), local);
        if (walker->abandoned()) {  // a stop request inside the slice: the level is discarded
          stop_seen.store(true, std::memory_order_relaxed);
          return;
        }
        partial[static_cast<std::size_t>(k0)] = local;
        if (control != nullptr) {
#if defined(_OPENMP)
#pragma omp critical(pendavg_torus_progress)
#endif
          control->report(static_cast<double>(++done) / static_cast<double>(outer));
          if (control->stop_requested()) stop_seen.store(true, std::memory_order_relaxed);
        }
      });
    }
  }
  errors.rethrow();
  stopped = stop_seen.load();
  (void)team;
  TorusSums<Real> total(n_particles);
  for (const auto& p : partial) total.merge(p);
  return total;
}

/// The reported quantities of one level, and their scales for the stopping test.
template <class Real>
struct LevelValues {
  Real mean_weight;
  std::vector<Real> beta_kinetic, beta2_second_moment, variance, cosine, cosine_l1;
};

template <class Real>
LevelValues<Real> level_values(const TorusSums<Real>& s, const Real& normalization) {
  const std::size_t n = s.trace.size();
  LevelValues<Real> v;
  const Real w = s.weight.value();
  v.mean_weight = w / normalization;
  v.beta_kinetic.resize(n);
  v.beta2_second_moment.resize(n);
  v.variance.resize(n);
  v.cosine.resize(n);
  v.cosine_l1.resize(n);
  for (std::size_t i = 0; i < n; ++i) {
    v.beta_kinetic[i] = s.trace[i].value() / (2 * w);
    v.beta2_second_moment[i] = s.second_moment[i].value() / (4 * w);
    v.variance[i] = v.beta2_second_moment[i] - v.beta_kinetic[i] * v.beta_kinetic[i];
    v.cosine[i] = s.cosine[i].value() / w;
    v.cosine_l1[i] = s.cosine_abs[i].value() / w;
  }
  return v;
}

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

}  // namespace detail::torus

/// The averages, the any-N extras (canonical kinetic energies, diagonal approximation,
/// equipartition residual) and the refinement (Averages::torus: mean weight, final grid).
/// Throws invalid_input for a bad beta, digits or options, or when the first level would exceed
/// options.max_grid_points nodes.
template <class Real>
Averages<Real> torus_average(const Chain<Real>& chain, const Real& beta,
                             const TorusOptions& options = {}) {
  using namespace detail::torus;
  check_beta(beta);
  if (options.digits != 0) check_digits<Real>(options.digits);
  std::optional<precision_guard<Real>> guard;
  if (options.digits != 0) guard.emplace(options.digits + guard_digits);
  const std::size_t n_particles = chain.size();
  const std::size_t dims = n_particles - 1;
  if (options.min_points_per_dim < 2 || options.max_points_per_dim < options.min_points_per_dim) {
    throw invalid_input("torus quadrature needs 2 <= min_points_per_dim <= max_points_per_dim");
  }
  if (!(options.tolerance > 0) && options.digits == 0) {
    throw invalid_input("torus quadrature needs a positive tolerance");
  }
  const auto grid_size = [&](std::size_t n) {
    return std::pow(static_cast<double>(n), static_cast<double>(dims));
  };
  if (grid_size(options.min_points_per_dim) > options.max_grid_points) {
    throw invalid_input("torus quadrature: " + std::to_string(options.min_points_per_dim) + "^" +
                        std::to_string(dims) + " nodes exceed the cap of " +
                        std::to_string(options.max_grid_points) + "; use qmc_average for N = " +
                        std::to_string(n_particles));
  }
  using std::pow;
  Real tolerance = Real(options.tolerance);
  if (options.digits != 0) tolerance = pow(Real(10), -options.digits);
  const Real u = unit_roundoff<Real>();

  const WeightConstants<Real> constants(chain, beta);
  std::vector<NodeMap<Real>> maps(dims);
  if (options.node_map == TorusNodeMap::automatic) {
    maps = automatic_node_maps(chain, constants.alpha);
  }

  Averages<Real> a;
  a.method = options.rule == TorusRule::gauss_legendre ? Method::torus_gauss_legendre
                                                       : Method::torus_trapezoid;
  a.error_kind = ErrorKind::estimate;
  a.work_unit = WorkUnit::nodes;
  a.converged = false;
  TorusDiagnostics<Real>& diagnostics = a.torus.emplace();

  // Quantities in one flat vector: Z, then beta<K_i>, beta^2 Var K_i, <cos phi_i> (i = 1..N).
  // Scales of the stopping test: Z, beta<K_i>, beta^2 <K_i^2>, <|I1/I0 cos(theta_i - arg z)|>_w.
  const std::size_t count = 1 + 3 * n_particles;
  std::vector<Real> value(count), scale(count), previous(count), difference(count),
      previous_difference(count), estimate(count);
  const auto flatten = [&](const LevelValues<Real>& v) {
    value[0] = v.mean_weight;
    scale[0] = v.mean_weight;
    for (std::size_t i = 0; i < n_particles; ++i) {
      value[1 + i] = v.beta_kinetic[i];
      scale[1 + i] = v.beta_kinetic[i];
      value[1 + n_particles + i] = v.variance[i];
      scale[1 + n_particles + i] = v.beta2_second_moment[i];
      value[1 + 2 * n_particles + i] = v.cosine[i];
      scale[1 + 2 * n_particles + i] = v.cosine_l1[i];
    }
  };

  std::size_t n = options.min_points_per_dim;
  TorusSums<Real> cumulative(n_particles);  // trapezoid: sums over every node of the level
  TorusSums<Real> fresh_last(n_particles);  // Gauss-Legendre: the last level's sums
  LevelValues<Real> current;
  for (std::size_t level = 0;; ++level) {
    const bool trapezoid = options.rule == TorusRule::trapezoid;
    const CircleRule<Real> base =
        trapezoid ? trapezoid_rule<Real>(n, level > 0) : gauss_legendre_rule<Real>(n);
    std::vector<CircleRule<Real>> rules;
    for (std::size_t d = 0; d < std::max<std::size_t>(dims, 1); ++d) {
      rules.push_back(d < maps.size() ? mapped_rule(base, maps[d]) : base);
    }
    bool stopped = options.control != nullptr && level > 0 && options.control->stop_requested();
    const TorusSums<Real> fresh =
        stopped ? TorusSums<Real>(n_particles)
                : level_sums(chain, constants, rules, dims, options.threads, options.control,
                             stopped);
    if (stopped) {  // the unfinished level is discarded: report the previous one
      if (level == 0) throw interrupted("torus: stopped during the first level (nothing finished)");
      a.interrupted = true;
      break;
    }
    a.evaluations += fresh.evaluations;
    fresh_last = fresh;
    if (trapezoid) {
      cumulative.merge(fresh);
      current = level_values(cumulative, Real(grid_size(n)));
    } else {
      current = level_values(fresh, Real(1));
    }
    diagnostics.levels = level + 1;
    diagnostics.points_per_dim = n;
    diagnostics.grid_points = grid_size(n);
    flatten(current);
    if (dims == 0) {  // one node: exact up to rounding
      std::fill(estimate.begin(), estimate.end(), Real(0));
      a.converged = true;
      break;
    }
    if (level == 0) {
      // No difference yet: the whole scale is the (placeholder) error estimate.
      estimate = scale;
    } else {
      bool done = true;
      for (std::size_t q = 0; q < count; ++q) {
        difference[q] = abs(value[q] - previous[q]);
        estimate[q] = difference[q];
        // Geometric convergence e_n = C rho^n gives e_2n = e_n (e_n / e_{n/2})^2: once the last
        // contraction d_n / d_{n/2} is <= 1/10, e_2n <= d_n (d_n / d_{n/2}) with room to spare.
        if (options.extrapolate_error && level >= 2 && previous_difference[q] > 0 &&
            difference[q] <= previous_difference[q] / 10) {
          estimate[q] = difference[q] * (difference[q] / previous_difference[q]);
        }
        done = done && estimate[q] <= tolerance * scale[q];
      }
      previous_difference = difference;
      if (done) {
        a.converged = true;
        break;
      }
    }
    const std::size_t next = 2 * n;
    if (next > options.max_points_per_dim || grid_size(next) > options.max_grid_points) break;
    // Each level has about 2^(N-1) times the previous level's fresh nodes (nested or not).
    if (static_cast<double>(a.evaluations) +
            static_cast<double>(fresh.evaluations) * std::ldexp(1.0, static_cast<int>(dims)) >
        options.max_evaluations)
      break;
    previous = value;
    n = next;
  }

  if (!a.converged) {
    // Stopped early: an unresolved weight (e.g. a peak narrower than the grid spacing) leaves
    // the ratios frozen at the nodes that see it while Z still moves. Every ratio's error is
    // then at least Z's relative error times the ratio's scale, so the estimates stay valid.
    // Nor is the geometric extrapolation of the error trusted before convergence: a light
    // particle's refinement contracts by 10 per level long before its asymptotic rate (masses
    // 1.27, 1e-6, 0.986 at 8194 nodes: beta<K_2> off by 5.7e-11, extrapolated error 6.9e-14), so
    // a stopped run reports the last difference itself.
    for (std::size_t q = 0; q < count; ++q) estimate[q] = std::max(estimate[q], difference[q]);
    const Real z_relative = scale[0] > 0 ? Real(estimate[0] / scale[0]) : Real(1);
    for (std::size_t q = 1; q < count; ++q) {
      estimate[q] = std::max(estimate[q], Real(z_relative * scale[q]));
    }
  }

  const TorusSums<Real>& last = options.rule == TorusRule::trapezoid ? cumulative : fresh_last;
  const Real lever = last.weight.value() > 0 ? Real(last.exponent_lever.value() / last.weight.value())
                                            : Real(sqrt(constants.alpha_sum));
  const Real rounding = rounding_ulps(constants, n_particles, lever) * u;
  a.beta_kinetic.resize(n_particles);
  a.cos_angle.resize(n_particles);
  a.beta2_kinetic_variance.resize(n_particles);
  constexpr ErrorKind kind = ErrorKind::estimate;
  for (std::size_t i = 0; i < n_particles; ++i) {
    a.beta_kinetic[i] = {current.beta_kinetic[i], estimate[1 + i] + rounding * scale[1 + i], kind};
    a.beta2_kinetic_variance[i] = {
        current.variance[i],
        estimate[1 + n_particles + i] + 2 * rounding * scale[1 + n_particles + i], kind};
    a.cos_angle[i] = {current.cosine[i],
                      estimate[1 + 2 * n_particles + i] + rounding * scale[1 + 2 * n_particles + i],
                      kind};
  }
  if (n_particles >= 2) a.ratio = kinetic_ratio(a.beta_kinetic[0], a.beta_kinetic[1], u);
  diagnostics.mean_weight = {current.mean_weight, estimate[0] + rounding * scale[0], kind};
  add_chain_extras(a, chain);
  return a;
}

// ============================================================================ randomized QMC
//
// qmc_average: the same averages for chains too long for a tensor grid (MATH.md Sec. 6).
// Target. The ratio estimators are the same as on the torus, over the N absolute angles with
// density sqrt(det A) prod_j exp(alpha_j cos phi_j); <cos phi_j> is Rao-Blackwellized over psi
// to (I1/I0)(R) cos(phi_j - arg z) (MATH.md Sec. 2).
// Proposal (QmcProposal::pivot_sequential, the default; PivotSampler below). sqrt(det A)
// factorizes root to tail as prod_j l_j sqrt(m_j (1 + u_j)) with trace_formula.hpp's forward
// sweep u_{j+1} = (m_{j+1}/m_j)(u_j + sin^2(phi_{j+1} - phi_j))/(u_j + 1), u_1 = 0. The angles
// are drawn root to tail, angle j+1 from a law that includes its von Mises factor and its pivot
// factor sqrt(1 + u_{j+1}) given the angles already drawn. Per angle, the variable is v in [0, 1)
// of the Best-Fisher wrapped Cauchy map x = 2 atan(tan(pi (v - 1/2)) (1 - rho)/(1 + rho)) (the
// envelope of their von Mises sampler, 1979), in which the von Mises factor is the smooth
// acceptance ratio exp(alpha (cos x - 1)) (1 + rho^2 - 2 rho cos x)/(1 - rho)^2 (within [0.66,
// 1.5] of its mean for every alpha); the conditional law of v is the periodic piecewise-linear
// interpolant of ratio * pivot on `proposal_grid` (32) equispaced nodes, normalized exactly and
// inverted exactly (a quadratic per cell). The weight, target over proposal, is exact: only what
// the interpolant and the root-to-tail order miss remains in it. The lattice coordinate u_j of
// each point feeds the inverse CDF of angle j; the integrand on the unit cube stays periodic and
// continuous (piecewise smooth). The old proposal, independent von Mises laws with all of
// sqrt(det A) in the weight (QmcProposal::von_mises), is kept for comparison: its weights
// degenerate as N grows (effective sample fraction at beta = 1, unit chains: 0.23 at N = 8,
// 0.03 at N = 16, ~1e-5 at N = 64), while the pivot proposal keeps 0.97, 0.94, 0.89, 0.80 at
// N = 8, 16, 32, 64. Tabulated grids of 16 (64) nodes give 0.54 (0.83) at N = 64; 32 is the
// balance of cost and weight spread.
// Points: a rank-1 lattice rule with n = 2^m points, x_k = frac(k z / n + Delta), randomized by
// independent uniform shifts Delta. The generating vectors z are our own CBC constructions for
// the Korobov space (alpha = 2) with equal product weights gamma_j = 0.01 (lattice_table,
// computed by fast_cbc_generating_vector; n = 2^10..2^20, up to 256 dimensions). Equal weights
// suit this integrand: each tr X_i depends mostly on the angles next to particle i, so every
// low-order projection of nearby coordinates matters, wherever it sits in the chain. Measured at
// N = 64, beta = 1, 2^16 x 16 points: largest 3-sigma bar over the beta<K_i> 8e-5 (gamma = 0.01,
// 0.003), 9.5e-5 (0.2), 1.5e-4 (0.05: one poor projection), 1.7e-4 (random odd z), 2e-4
// (the earlier weights gamma_j = 1/j, which neglect the tail). Published embedded sequences
// optimized for order-2 weights (e.g. Cools-Kuo-Nuyens 2006) were tried and rejected: their 3-D
// projections carry short dual vectors such as (-1, -11, -2) for every n >= 2^13, which froze
// the error at ~3e-7 for N = 3 from 2^13 to 2^16 points.
// Error bar: the R shifted lattices give R independent, unbiased estimates of every numerator
// and denominator; the value is the ratio of the totals and its standard error the jackknife
// over shifts (delete-one-shift). The reported error is `sigmas` standard errors plus the
// rounding budget; by default sigmas is the 99.9% two-sided Student-t quantile for R - 1 degrees
// of freedom (qmc_default_sigmas: 4.07 for R = 16, 3.29 as R -> infinity). Not 3 (the 99%
// quantile for normal shift errors): a lattice rule's error as a function of the shift is
// dominated by a few dual vectors, so it is close to A cos(2 pi h.Delta) -- arcsine-distributed,
// with its mass at +-A -- and the t statistic of 16 such samples has heavier tails than
// Student's (|t| > 3 in 1.1% of draws, > 4 in 0.22%). Measured over seeds 1..400 at 2^16 x 16
// points (N = 3, unit chain at beta = 1; lengths 0.01, 10, 1 at g = 9.81, beta = 0.1): 3 SE
// missed the tensor-torus value in 1.3-2.3% of the seeds per component, 4.07 SE in <= 0.25%.
// A statistical bar, not a bound. Deterministic for a given seed and bitwise independent of
// the thread count (each shift is summed by one thread, in point order).
// Weights are kept as exp(log W - log_scale) per shift: a log-sum-exp with a finite reference
// (the shift's first finite log W, raised whenever a later one exceeds it by 256), so no weight
// overflows for any N and none underflows into a NaN at any beta: a product of factors that
// would leave the normal range is carried as a sum of logs instead (only there, so runs whose
// products stay normal keep every bit), and a point whose weight is exactly zero never becomes
// the reference.
// When to use it: N >= 5 or so (a tensor grid needs n^(N-1) nodes); for N <= 4 torus_average is
// exact to 1e-13 and much cheaper. Cost per point: linear in N (the 32-node table of each
// conditional law, one tan and one exp per angle, the backward trace sweep).
// Why: README, Design notes, 'Measurements behind the design choices' (qmc
// cost to a 1e-4 bar, N = 8..64; tests/bench/bench_any_n.cpp BM_qmc_to_target).
// Coverage (tests/test_torus.cpp): the bars cover the tensor-torus values for >= 95 of 100
// seeds, per quantity and particle, at N = 3 (both laws) and N = 4 (unequal masses and lengths,
// beta = 2, pivot law), 2^10 x 16 points; and for >= 99 of 100 at 2^16 x 16 on the hard case
// above (slow test).
// Limitations: the bar is statistical (the 99.9% Student-t quantile of the jackknife standard
// error); it is trustworthy while effective_sample_fraction stays above ~0.1. Mass ratios
// m_{j+1}/m_j far from 1 make the pivot factors, and so the tables, steeper (not measured beyond
// the tests' random chains). The lattices beyond 256 particles must be passed in generating_vector
// (fast_cbc_generating_vector builds one for 2^16 points).

/// The law qmc_average maps the lattice points to (see the comment above QmcOptions).
enum class QmcProposal {
  automatic,         ///< von_mises for N <= 4, pivot_sequential beyond
  pivot_sequential,  ///< root to tail, each angle's law includes its pivot factor of det A
  von_mises,         ///< independent von Mises laws; all of sqrt(det A) in the weight
};

/// Options of qmc_average.
struct QmcOptions {
  std::size_t points = std::size_t(1) << 14;  ///< lattice points per shift: 2^m, 2^10 <= . <= 2^20
  std::size_t shifts = 16;                    ///< independent random shifts (>= 4)
  std::uint64_t seed = 1;                     ///< the shifts come from std::mt19937_64(seed)
  /// error = sigmas * jackknife standard error; 0 (default): qmc_default_sigmas(shifts), the
  /// 99.9% two-sided Student-t quantile for shifts - 1 degrees of freedom (4.07 for 16 shifts).
  double sigmas = 0;
  int threads = 1;                            ///< OpenMP threads over shifts (double/long double)
  /// Optional generating vector for `points` points (one odd entry per particle); empty: the
  /// built-in table.
  std::vector<std::uint32_t> generating_vector;
  /// The law the points are mapped to: automatic (default), pivot_sequential or von_mises (the
  /// product of von Mises laws, sqrt(det A) left entirely to the weight).
  QmcProposal proposal = QmcProposal::automatic;
  /// Nodes of the tabulated conditional law per angle (pivot_sequential), >= 4.
  std::size_t proposal_grid = 32;
  /// Shares the shifts with other processes (pendavg/average.hpp, ShiftPartition; double only).
  const ShiftPartition* partition = nullptr;
  /// Progress (the fraction of shifts finished) and stop. A stop ends the run after the shifts
  /// running finish: with at least 2 shifts done their average is returned (interrupted = true,
  /// converged = false, the bars from the shifts done), otherwise `interrupted` is thrown. Not
  /// used with a partition (the parts must agree on the shifts).
  const RunControl* control = nullptr;
};

/// The 99.9% two-sided Student-t quantile for shifts - 1 degrees of freedom: the default error
/// multiplier of the QMC bars (see the comment above QmcOptions). 4.0728 for 16 shifts.
double qmc_default_sigmas(std::size_t shifts);

namespace detail::qmc {

using std::abs;
using std::exp;
using std::log;
using std::sqrt;

// Built-in generating vectors: lattice_table[m - 10] for n = 2^m points, m = 10..20, in up to
// lattice_max_dimension = 256 dimensions (pendavg/detail/qmc_lattices.hpp).

/// The Korobov-space kernel omega(k / n), k = 0..n-1, of smoothness alpha = 2 (2 pi^2 B_2(x))
/// or 4 (-(4 pi^4 / 3) B_4(x)): the one-dimensional factor of the CBC criterion.
inline std::vector<double> korobov_kernel(std::uint64_t n, int alpha) {
  const double two_pi2 = 2 * 9.869604401089358;  // 2 pi^2
  std::vector<double> omega(n);
  for (std::uint64_t k = 0; k < n; ++k) {
    const double x = static_cast<double>(k) / static_cast<double>(n);
    omega[k] = alpha == 4 ? -(two_pi2 * 9.869604401089358 / 3) *
                                (x * x * x * x - 2 * x * x * x + x * x - 1.0 / 30.0)
                          : two_pi2 * (x * x - x + 1.0 / 6.0);
  }
  return omega;
}

/// Delete-one jackknife standard errors: leave_out[r][q] is quantity q estimated without shift r
/// (R shifts); SE_q = sqrt((R - 1)/R sum_r (leave_out[r][q] - mean_q)^2).
template <class Real>
std::vector<Real> jackknife_standard_errors(const std::vector<std::vector<Real>>& leave_out,
                                            std::size_t count) {
  using std::sqrt;
  const std::size_t shifts = leave_out.size();
  const Real R = Real(static_cast<double>(shifts));
  std::vector<Real> standard_error(count);
  for (std::size_t q = 0; q < count; ++q) {
    Real mean = 0;
    for (std::size_t r = 0; r < shifts; ++r) mean += leave_out[r][q];
    mean /= R;
    Real ss = 0;
    for (std::size_t r = 0; r < shifts; ++r) {
      const Real d = leave_out[r][q] - mean;
      ss += d * d;
    }
    standard_error[q] = sqrt((R - 1) / R * ss);
  }
  return standard_error;
}

/// Random shifts of a lattice rule: `shifts` vectors of `n` coordinates in [0, 1), 53 random
/// bits each, drawn in a fixed order from std::mt19937_64(seed) (so results depend on the seed
/// only, never on the thread count).
template <class Real>
std::vector<std::vector<Real>> random_shifts(std::size_t shifts, std::size_t n, std::uint64_t seed) {
  std::vector<std::vector<Real>> shift(shifts, std::vector<Real>(n));
  std::mt19937_64 rng(seed);
  for (auto& s : shift) {
    for (auto& v : s) v = Real(static_cast<double>(rng() >> 11) * 0x1.0p-53);
  }
  return shift;
}

/// Component-by-component construction (Sloan-Reztsov; Nuyens-Cools) of a rank-1 lattice rule
/// with n = 2^m points in d dimensions for the Korobov space of smoothness alpha = 2 with product
/// weights gamma_j: z_1 = 1, then each z_j in {1, 3, ..., n/2 - 1} minimizes the squared worst-case
/// error  P(z) = -1 + (1/n) sum_k prod_j (1 + gamma_j 2 pi^2 B_2({k z_j / n})),
/// B_2(x) = x^2 - x + 1/6, ties to the smaller z. Cost O(d n^2 / 4) (plain, not the FFT version):
/// use it offline or for n <= 2^12.
inline std::vector<std::uint32_t> cbc_generating_vector(unsigned m, std::size_t d,
                                                        const std::vector<double>& gamma,
                                                        int alpha = 2) {
  const std::uint64_t n = std::uint64_t(1) << m;
  const std::vector<double> omega = korobov_kernel(n, alpha);
  std::vector<double> product(n, 1.0);
  std::vector<std::uint32_t> z;
  for (std::size_t j = 0; j < d; ++j) {
    const double g = j < gamma.size() ? gamma[j] : gamma.back();
    std::uint64_t best = 1;
    if (j > 0) {
      double best_value = std::numeric_limits<double>::infinity();
      for (std::uint64_t c = 1; c < n / 2; c += 2) {
        double sum = 0;
        // k = 0 adds the same prod_j (1 + gamma_j omega(0)) for every c: left out.
        for (std::uint64_t k = 1; k < n; ++k) sum += product[k] * (1 + g * omega[(k * c) & (n - 1)]);
        if (sum < best_value) {
          best_value = sum;
          best = c;
        }
      }
    }
    z.push_back(static_cast<std::uint32_t>(best));
    for (std::uint64_t k = 0; k < n; ++k) product[k] *= 1 + g * omega[(k * best) & (n - 1)];
  }
  return z;
}

/// In-place radix-2 complex FFT (sign -1: forward, +1: inverse without the 1/n), size 2^k.
inline void lattice_fft(std::vector<std::complex<double>>& a, int sign) {
  const std::size_t n = a.size();
  for (std::size_t i = 1, j = 0; i < n; ++i) {
    std::size_t bit = n >> 1;
    for (; j & bit; bit >>= 1) j ^= bit;
    j ^= bit;
    if (i < j) std::swap(a[i], a[j]);
  }
  std::vector<std::complex<double>> twiddle(n / 2 + 1);
  for (std::size_t len = 2; len <= n; len <<= 1) {
    const double angle = sign * 2 * 3.141592653589793238462643 / static_cast<double>(len);
    for (std::size_t k = 0; k < len / 2; ++k) twiddle[k] = std::polar(1.0, angle * static_cast<double>(k));
    for (std::size_t i = 0; i < n; i += len) {
      for (std::size_t k = 0; k < len / 2; ++k) {
        const std::complex<double> w = twiddle[k];
        const std::complex<double> x = a[i + k], y = a[i + k + len / 2] * w;
        a[i + k] = x + y;
        a[i + k + len / 2] = x - y;
      }
    }
  }
}

/// The same construction and criterion as cbc_generating_vector, in O(d n log n) (Nuyens-Cools
/// fast CBC, for n = 2^m): the odd residues mod 2^r (r >= 3) are {+-5^a}, the kernel is even
/// (omega(1 - x) = omega(x)), so for the k with 2-adic valuation s the criterion of the
/// candidate 5^a is a cyclic correlation of length 2^(m-s-2), done by FFT. Candidates z and
/// n - z are equivalent; the one below n/2 is returned. Picks the same z as the plain version
/// up to ties within rounding (~1e-13 relative). m <= 24; n = 2^20 in 256 dimensions: ~10 s.
inline std::vector<std::uint32_t> fast_cbc_generating_vector(unsigned m, std::size_t d,
                                                             const std::vector<double>& gamma,
                                                             int alpha = 2) {
  if (m < 3 || m > 24) throw invalid_input("fast_cbc_generating_vector: 3 <= m <= 24");
  const std::uint64_t n = std::uint64_t(1) << m;
  const std::vector<double> omega = korobov_kernel(n, alpha);
  // Per valuation s (modulus n_s = 2^(m-s) >= 8, L_s = n_s / 4): the powers of 5 mod n_s and
  // the transformed kernel W_s[t] = omega(2^s (5^t mod n_s)).
  struct Level {
    unsigned s;
    std::size_t length;
    std::vector<std::uint64_t> power;  // 5^t mod n_s
    std::vector<std::complex<double>> kernel_hat;
  };
  std::vector<Level> levels;
  for (unsigned s = 0; s + 3 <= m; ++s) {
    Level lv;
    lv.s = s;
    const std::uint64_t ns = n >> s;
    lv.length = static_cast<std::size_t>(ns / 4);
    lv.power.resize(lv.length);
    std::vector<std::complex<double>> w(lv.length);
    std::uint64_t p = 1;
    for (std::size_t t = 0; t < lv.length; ++t) {
      lv.power[t] = p;
      w[t] = omega[(p << s) & (n - 1)];
      p = (p * 5) & (ns - 1);
    }
    lattice_fft(w, -1);
    lv.kernel_hat = std::move(w);
    levels.push_back(std::move(lv));
  }
  const std::size_t candidates = static_cast<std::size_t>(n / 4);  // a = 0 .. n/4 - 1
  std::vector<double> product(n, 1.0), criterion(candidates);
  std::vector<std::uint32_t> z;
  for (std::size_t j = 0; j < d; ++j) {
    const double g = j < gamma.size() ? gamma[j] : gamma.back();
    std::uint64_t best = 1;
    if (j > 0) {
      std::fill(criterion.begin(), criterion.end(), 0.0);
      for (const Level& lv : levels) {
        const std::uint64_t ns = n >> lv.s;
        std::vector<std::complex<double>> q(lv.length);
        for (std::size_t b = 0; b < lv.length; ++b) {
          const std::uint64_t o = lv.power[b];
          q[b] = product[(o << lv.s) & (n - 1)] + product[((ns - o) << lv.s) & (n - 1)];
        }
        lattice_fft(q, -1);
        // Correlation S[a] = sum_b Q[b] W[a + b]: inverse FFT of conj(Q^) W^.
        for (std::size_t t = 0; t < lv.length; ++t) q[t] = std::conj(q[t]) * lv.kernel_hat[t];
        lattice_fft(q, +1);
        const double inv = 1.0 / static_cast<double>(lv.length);
        for (std::size_t a = 0; a < candidates; ++a) criterion[a] += q[a % lv.length].real() * inv;
      }
      double best_value = std::numeric_limits<double>::infinity();
      std::uint64_t p = 1;
      for (std::size_t a = 0; a < candidates; ++a) {
        const std::uint64_t c = p < n / 2 ? p : n - p;
        // Ties (within rounding) to the smaller z, as in the plain construction.
        const double tol = 1e-13 * std::abs(criterion[a]);
        if (criterion[a] < best_value - tol ||
            (criterion[a] <= best_value + tol && c < best)) {
          if (criterion[a] < best_value) best_value = criterion[a];
          best = c;
        }
        p = (p * 5) & (n - 1);
      }
    }
    z.push_back(static_cast<std::uint32_t>(best));
    for (std::uint64_t k = 0; k < n; ++k) product[k] *= 1 + g * omega[(k * best) & (n - 1)];
  }
  return z;
}

/// Per angle: the wrapped Cauchy (Best-Fisher envelope) inverse CDF and the acceptance ratio.
template <class Real>
struct BestFisherMap {
  Real alpha{0}, rho{0}, contraction{1};  ///< contraction = (1 - rho) / (1 + rho)
  Real log_norm{0};                       ///< log (1 - rho)^2: the ratio is 1 at x = 0

  explicit BestFisherMap(const Real& a) : alpha(a) {
    if (alpha > 0) {
      // Best & Fisher (1979): tau = 1 + sqrt(1 + 4 a^2), rho = (tau - sqrt(2 tau)) / (2 a),
      // = 2 a / (tau + sqrt(2 tau)) since tau^2 - 2 tau = 4 a^2 (no cancellation as a -> 0).
      const Real tau = 1 + sqrt(1 + 4 * alpha * alpha);
      rho = 2 * alpha / (tau + sqrt(2 * tau));
    }
    contraction = (1 - rho) / (1 + rho);
    log_norm = 2 * log(1 - rho);
  }

  /// The angle for u in [0, 1), and the log of the acceptance ratio at it (<= log 1.6 or so).
  void map(const Real& u, Real& x, Real& sin_x, Real& cos_x, Real& log_ratio) const {
    using std::atan;
    using std::cos;
    using std::sin;
    using std::tan;
    const Real t = tan(detail::torus::pi<Real>() * (u - Real(0.5)));
    x = 2 * atan(t * contraction);
    sin_x = sin(x);
    cos_x = cos(x);
    const Real half_sin = sin(x / 2);
    const Real one_minus_cos = 2 * half_sin * half_sin;
    log_ratio = -alpha * one_minus_cos +
                log((1 - rho) * (1 - rho) + 2 * rho * one_minus_cos) - log_norm;
  }
};

/// QmcProposal::automatic uses the von Mises law up to this N: its integrand is smooth (lattice
/// errors fall fast) and its weights still even; the pivot law's piecewise-linear tables cost it
/// the lattice's higher-order convergence (N = 4, beta = 1, 2^14 x 16 points: largest bar 4e-7
/// against 8e-6), which its even weights outweigh from N ~ 5 on (N = 6: 2.4e-5 against 1e-4).
inline constexpr std::size_t automatic_von_mises_max_particles = 4;

/// The angle of the wrapped Cauchy law (Best-Fisher envelope) at v in [0, 1), returned as
/// cos x, sin x and 1 - cos x (no cancellation), from w = tan(x / 2) = tan(pi (v - 1/2)) (1 - rho)
/// / (1 + rho): no atan, sin or cos. The same map as BestFisherMap::map.
template <class Real>
void wrapped_cauchy_point(const BestFisherMap<Real>& map, const Real& v, Real& cos_x, Real& sin_x,
                          Real& one_minus_cos) {
  using std::isfinite;
  using std::tan;
  const Real w = tan(detail::torus::pi<Real>() * (v - Real(0.5))) * map.contraction;
  const Real w2 = w * w;
  if (!isfinite(w2)) {  // v = 0: x = -pi
    cos_x = -1;
    sin_x = 0;
    one_minus_cos = 2;
    return;
  }
  const Real inv = 1 / (1 + w2);
  one_minus_cos = 2 * w2 * inv;
  cos_x = 1 - one_minus_cos;
  sin_x = 2 * w * inv;
}

/// The Best-Fisher acceptance ratio exp(alpha (cos x - 1)) (1 + rho^2 - 2 rho cos x) / (1 - rho)^2
/// from 1 - cos x: the von Mises density over the wrapped Cauchy density, up to a constant.
template <class Real>
Real best_fisher_ratio(const BestFisherMap<Real>& map, const Real& one_minus_cos) {
  const Real one_minus_rho = 1 - map.rho;
  return exp(-map.alpha * one_minus_cos) *
         (1 + 2 * map.rho * one_minus_cos / (one_minus_rho * one_minus_rho));
}

/// The proposal law of qmc_average and its tables (see the comment above QmcOptions).
/// Root-to-tail factorization of the target (trace_formula.hpp's forward sweep):
///     sqrt(det A) = prod_j l_j sqrt(m_j (1 + u_j)),   u_1 = 0,
///     u_{j+1} = (m_{j+1} / m_j) (u_j + sin^2(phi_{j+1} - phi_j)) / (u_j + 1),
/// so given phi_1..phi_j the factor of angle j+1 is e^{alpha_{j+1} cos phi_{j+1}} sqrt(1 + u_{j+1}).
/// In the variable v of the Best-Fisher map of angle j+1 that factor is g(v) = ratio(x(v))
/// sqrt(1 + u_{j+1}(x(v))) (ratio: best_fisher_ratio), smooth and of bounded spread. The
/// proposal density of v is the periodic piecewise-linear interpolant of g on `grid` equispaced
/// nodes v_k = k / grid, normalized exactly (its integral is the mean of the node values), and
/// sampled by its exact inverse CDF (a quadratic per cell). The importance weight keeps the rest:
/// prod_j g_j(v_j) / q_j(v_j), exactly the target over the proposal.
template <class Real>
struct PivotSampler {
  std::size_t n = 0, grid = 0;
  bool sequential = true;
  std::vector<BestFisherMap<Real>> maps;
  std::vector<Real> node_ratio, node_cos, node_sin;  ///< per angle, `grid` nodes each
  std::vector<Real> mass_ratio;                      ///< m_j / m_{j-1} (entry 0 unused)

  PivotSampler(const Chain<Real>& chain, const std::vector<Real>& alpha, std::size_t grid_nodes,
               bool sequential_proposal)
      : n(chain.size()), grid(grid_nodes), sequential(sequential_proposal) {
    mass_ratio.assign(n, Real(1));
    for (std::size_t j = 0; j < n; ++j) {
      maps.emplace_back(alpha[j]);
      if (j > 0) mass_ratio[j] = chain.mass(j) / chain.mass(j - 1);
    }
    if (!sequential) return;
    node_ratio.resize(n * grid);
    node_cos.resize(n * grid);
    node_sin.resize(n * grid);
    for (std::size_t j = 0; j < n; ++j) {
      for (std::size_t k = 0; k < grid; ++k) {
        Real c, s, omc;
        wrapped_cauchy_point(maps[j], Real(static_cast<double>(k)) / Real(static_cast<double>(grid)),
                             c, s, omc);
        node_cos[j * grid + k] = c;
        node_sin[j * grid + k] = s;
        node_ratio[j * grid + k] = best_fisher_ratio(maps[j], omc);
      }
    }
  }
};

/// Sums of one shifted lattice: W, W tr X_i, W ((tr X_i)^2 + 2 tr X_i^2), W cos-factor_i, W^2,
/// all scaled by exp(-log_scale) (W = exp(log W - log_scale) stays finite for any N).
template <class Real>
struct ShiftSums {
  detail::torus::CompensatedSum<Real> weight, weight_squared;
  std::vector<detail::torus::CompensatedSum<Real>> trace, second_moment, cosine;
  Real log_scale{0};
  bool scaled = false;  ///< log_scale is set: some point had a finite log W
  explicit ShiftSums(std::size_t n = 0) : trace(n), second_moment(n), cosine(n) {}
  void rescale(const Real& factor) {
    const auto scale = [&](detail::torus::CompensatedSum<Real>& s, const Real& f) {
      s.sum *= f;
      s.compensation *= f;
    };
    scale(weight, factor);
    scale(weight_squared, factor * factor);
    for (auto& s : trace) scale(s, factor);
    for (auto& s : second_moment) scale(s, factor);
    for (auto& s : cosine) scale(s, factor);
  }
};

/// The points between two calls of a shift's `poll` (lattice_sums_poll).
inline constexpr std::size_t lattice_poll_points = 4096;

/// The sums of one shifted lattice. `poll` (optional) is called after every lattice_poll_points
/// points with their number and returns false to abandon the shift (a stop request): the sums
/// are then incomplete and `*complete` is set to false.
template <class Real>
ShiftSums<Real> shifted_lattice_sums(const Chain<Real>& chain,
                                     const detail::torus::WeightConstants<Real>& k,
                                     const PivotSampler<Real>& sampler,
                                     const std::vector<Real>& shift, std::size_t points,
                                     const std::vector<std::uint32_t>& generator,
                                     const std::function<bool(std::size_t)>* poll = nullptr,
                                     bool* complete = nullptr) {
  const std::size_t n = chain.size();
  const std::size_t grid = sampler.grid;
  ShiftSums<Real> sums(n);
  std::vector<Real> cphi(n), sphi(n), root_u(n), sin2(n), cos2(n), tr(n), tr2(n), g(grid + 1);
  const std::uint64_t mask = points - 1;  // points is a power of two
  const Real inv_points = Real(1) / Real(static_cast<double>(points));
  const Real inv_grid = Real(1) / Real(static_cast<double>(grid));
  const std::vector<Real>& m = chain.masses();
  const Real min_normal = std::numeric_limits<Real>::min();
  const Real max_normal = std::numeric_limits<Real>::max();
  const Real infinity = std::numeric_limits<Real>::infinity();
  bool first = true;
  if (complete != nullptr) *complete = true;
  for (std::uint64_t p = 0; p < points; ++p) {
    if (poll != nullptr && p > 0 && p % lattice_poll_points == 0 && !(*poll)(lattice_poll_points)) {
      if (complete != nullptr) *complete = false;
      break;
    }
    Real log_w = 0, product = 1;
    for (std::size_t j = 0; j < n; ++j) {
      const std::uint64_t kz = (p * generator[j]) & mask;  // k z_j mod 2^m, exact
      Real u = Real(static_cast<double>(kz)) * inv_points + shift[j];
      if (u >= 1) u -= 1;
      Real v = u, relative_density = 1;  // the proposal's density of v over its mean
      const Real u_prev = j > 0 ? root_u[j - 1] : Real(0);
      if (sampler.sequential) {
        const Real* ratio = &sampler.node_ratio[j * grid];
        Real* gg = g.data();
        if (j == 0) {
          for (std::size_t q = 0; q < grid; ++q) gg[q] = ratio[q];
        } else {
          const Real* nc = &sampler.node_cos[j * grid];
          const Real* ns = &sampler.node_sin[j * grid];
          const Real a = sampler.mass_ratio[j] / (u_prev + 1), b = a * u_prev + 1;
          const Real cp = cphi[j - 1], sp = sphi[j - 1];
          for (std::size_t q = 0; q < grid; ++q) {  // vectorizes (src/torus.cpp: no errno)
            const Real s = ns[q] * cp - nc[q] * sp;  // sin(x_q - phi_{j-1})
            gg[q] = ratio[q] * sqrt(b + a * (s * s));
          }
        }
        gg[grid] = gg[0];
        // Four partial sums in a fixed order (grid is a multiple of 4).
        Real t0 = 0, t1 = 0, t2 = 0, t3 = 0;
        for (std::size_t q = 0; q < grid; q += 4) {
          t0 += gg[q];
          t1 += gg[q + 1];
          t2 += gg[q + 2];
          t3 += gg[q + 3];
        }
        const Real total = (t0 + t1) + (t2 + t3);
        // Cell q holds mass (g_q + g_{q+1}) / 2 in units of 1 / grid; find the cell of u total.
        const Real target = u * total;
        Real accumulated = 0;
        std::size_t q = 0;
        for (; q + 1 < grid; ++q) {
          const Real h = (g[q] + g[q + 1]) / 2;
          if (accumulated + h > target) break;
          accumulated += h;
        }
        const Real r = target - accumulated, gq = g[q], slope = g[q + 1] - gq;
        // g_q tau + slope tau^2 / 2 = r, the root in [0, 1] without cancellation.
        const Real disc = gq * gq + 2 * slope * r;
        Real tau = 2 * r / (gq + sqrt(disc > 0 ? disc : Real(0)));
        if (!(tau >= 0)) tau = 0;
        if (tau > 1) tau = 1;
        v = (Real(static_cast<double>(q)) + tau) * inv_grid;
        if (v >= 1) v -= 1;
        relative_density = (gq + slope * tau) / (total * inv_grid);
      }
      Real one_minus_cos;
      wrapped_cauchy_point(sampler.maps[j], v, cphi[j], sphi[j], one_minus_cos);
      Real factor = best_fisher_ratio(sampler.maps[j], one_minus_cos) / relative_density;
      if (j > 0) {
        const Real sd = sphi[j] * cphi[j - 1] - cphi[j] * sphi[j - 1];  // sin(phi_j - phi_{j-1})
        const Real cd = cphi[j] * cphi[j - 1] + sphi[j] * sphi[j - 1];
        sin2[j - 1] = sd * sd;
        cos2[j - 1] = cd * cd;
        root_u[j] = sampler.mass_ratio[j] * (u_prev + sin2[j - 1]) / (u_prev + 1);
        factor *= sqrt(1 + root_u[j]);
      } else {
        root_u[0] = 0;
      }
      const Real next = product * factor;
      if (next >= min_normal && next <= max_normal) {
        product = next;
      } else {
        // The product would leave the normal range (a point deep in a proposal tail at large
        // beta, where a factor underflows): carry it and this factor as logs, the factor from
        // its parts if it left the range itself. Points whose product stays normal take the
        // branch above, bit for bit as before.
        Real log_factor;
        if (factor >= min_normal && factor <= max_normal) {
          log_factor = log(factor);
        } else {
          const Real one_minus_rho = 1 - sampler.maps[j].rho;
          log_factor = -sampler.maps[j].alpha * one_minus_cos +
                       boost::math::log1p(Real(2 * sampler.maps[j].rho * one_minus_cos /
                                               (one_minus_rho * one_minus_rho))) -
                       log(relative_density);
          if (j > 0) log_factor += boost::math::log1p(root_u[j]) / 2;
        }
        log_w += log(product) + log_factor;
        product = 1;
      }
      if ((j & 31) == 31) {  // keep the running product far from overflow for any N
        log_w += log(product);
        product = 1;
      }
    }
    log_w += log(product);

    // Backward sweep (trace_formula.hpp, node_traces_relative) from the forward sweep's u_j.
    Real kappa = 0;
    for (std::size_t i = n; i-- > 0;) {
      const Real uu = root_u[i];
      Real pivot_ratio = 1, w = 0, w_cos2 = 0;
      if (i + 1 < n) {
        pivot_ratio += kappa * sin2[i];
        w = kappa * uu;
        w_cos2 = w * cos2[i];
      }
      const Real one_plus_u = 1 + uu, u_plus_w = uu + w;
      const Real inv_d = 1 / (u_plus_w + pivot_ratio);
      tr[i] = (one_plus_u + u_plus_w) * inv_d;
      tr2[i] = (one_plus_u * one_plus_u + u_plus_w * u_plus_w + 2 * w_cos2) * (inv_d * inv_d);
      if (i > 0) kappa = m[i] * (1 + kappa) / (m[i - 1] * pivot_ratio);
    }

    // Log-sum-exp with a finite reference: the first finite log W of the shift, raised when a
    // later one exceeds it by 256. A zero weight (log W = -inf) never becomes the reference, and
    // a point of zero proposal density (log W = +inf or NaN, never drawn in exact arithmetic) is
    // left out.
    if (!(log_w > -infinity && log_w < infinity)) continue;  // +-inf or NaN: adds nothing
    if (first) {
      sums.log_scale = log_w;
      sums.scaled = true;
      first = false;
    } else if (log_w > sums.log_scale + 256) {
      sums.rescale(exp(sums.log_scale - log_w));
      sums.log_scale = log_w;
    }
    const Real weight = exp(log_w - sums.log_scale);
    // Rao-Blackwellized cos phi_j: (I1/I0)(R) cos(phi_j - arg z), z = sum_j alpha_j e^{i phi_j}.
    Real zx = 0, zy = 0;
    for (std::size_t j = 0; j < n; ++j) {
      zx += k.alpha[j] * cphi[j];
      zy += k.alpha[j] * sphi[j];
    }
    Real radius = 0;
    if (k.alpha_sum > 0) {
      const Real sx = zx / k.alpha_sum, sy = zy / k.alpha_sum;
      radius = k.alpha_sum * sqrt(sx * sx + sy * sy);
    }
    Real ratio_w = 0;
    if (radius > 0) {
      const ScaledBesselI01<Real> b = scaled_bessel_i01(radius);
      ratio_w = weight * (b.i1e / b.i0e) / radius;
    }
    sums.weight.add(weight);
    sums.weight_squared.add(weight * weight);
    for (std::size_t i = 0; i < n; ++i) {
      sums.trace[i].add(weight * tr[i]);
      sums.second_moment[i].add(weight * (tr[i] * tr[i] + 2 * tr2[i]));
      sums.cosine[i].add(ratio_w * (cphi[i] * zx + sphi[i] * zy));
    }
  }
  return sums;
}

/// The shifts [first, last) that this part of a ShiftPartition computes (all without one).
struct ShiftRange {
  std::size_t first = 0, last = 0;
};
inline ShiftRange shift_range(const ShiftPartition* partition, std::size_t shifts) {
  if (!partition) return {0, shifts};
  const auto part = static_cast<std::size_t>(partition->part());
  const auto parts = static_cast<std::size_t>(partition->parts());
  return {shifts * part / parts, shifts * (part + 1) / parts};
}

/// Hands every part the sums of all shifts: each part packs its own shifts' sums (both words of
/// every compensated sum, the scale and whether it is set), all_gather concatenates them in part order, which is
/// shift order, and they are unpacked exactly.
template <class Real>
void gather_shift_sums(const ShiftPartition& partition, std::vector<ShiftSums<Real>>& sums) {
  if constexpr (!std::is_same_v<Real, double>) {
    throw invalid_input("qmc_average: a shift partition is for double runs");
  } else {
    const std::size_t shifts = sums.size();
    const ShiftRange mine = shift_range(&partition, shifts);
    const std::size_t n = sums.empty() ? 0 : sums[0].trace.size();
    const std::size_t width = 6 + 6 * n;  // doubles per shift
    std::vector<double> local;
    local.reserve((mine.last - mine.first) * width);
    for (std::size_t r = mine.first; r < mine.last; ++r) {
      const ShiftSums<double>& s = sums[r];
      const auto put = [&](const detail::torus::CompensatedSum<double>& c) {
        local.push_back(c.sum);
        local.push_back(c.compensation);
      };
      put(s.weight);
      put(s.weight_squared);
      for (std::size_t i = 0; i < n; ++i) {
        put(s.trace[i]);
        put(s.second_moment[i]);
        put(s.cosine[i]);
      }
      local.push_back(s.log_scale);
      local.push_back(s.scaled ? 1.0 : 0.0);
    }
    const std::vector<double> all = partition.all_gather(local);
    if (all.size() != shifts * width)
      throw std::logic_error("qmc_average: the shift partition gathered " +
                             std::to_string(all.size()) + " values, expected " +
                             std::to_string(shifts * width));
    std::size_t k = 0;
    for (ShiftSums<double>& s : sums) {
      const auto get = [&](detail::torus::CompensatedSum<double>& c) {
        c.sum = all[k++];
        c.compensation = all[k++];
      };
      get(s.weight);
      get(s.weight_squared);
      for (std::size_t i = 0; i < n; ++i) {
        get(s.trace[i]);
        get(s.second_moment[i]);
        get(s.cosine[i]);
      }
      s.log_scale = all[k++];
      s.scaled = all[k++] != 0;
    }
  }
}

/// The generating vector of a qmc run: options.generating_vector, checked, or the built-in
/// lattice row for n particles and `points` points. Throws invalid_input.
inline std::vector<std::uint32_t> qmc_generating_vector(const QmcOptions& options, std::size_t n) {
  const std::size_t points = options.points;
  std::vector<std::uint32_t> generator = options.generating_vector;
  if (generator.empty()) {
    unsigned log2_points = 0;
    while ((std::size_t(1) << log2_points) < points) ++log2_points;
    if (n > lattice_max_dimension || log2_points > lattice_rows_max_log2) {
      throw invalid_input(
          "qmc_average: the built-in lattices cover N <= 256 and 2^10..2^20 points; pass "
          "options.generating_vector (e.g. from cbc_generating_vector) for N = " +
          std::to_string(n) + " with " + std::to_string(points) + " points");
    }
    const auto& row = lattice_table[log2_points - lattice_table_min_log2];
    generator.assign(row, row + n);
  } else if (generator.size() != n) {
    throw invalid_input("qmc_average: the generating vector needs one entry per particle");
  } else {
    for (std::uint32_t zj : generator) {
      if (zj % 2 == 0) throw invalid_input("qmc_average: generating vector entries must be odd");
    }
  }
  return generator;
}

/// The sums of every random shift this process runs (options.partition: its share), in
/// parallel over the shifts; finished[r] marks the shifts that ran to the end (a stop request
/// through options.control leaves the others unfinished).
template <class Real>
std::vector<ShiftSums<Real>> run_shifts(const Chain<Real>& chain,
                                        const detail::torus::WeightConstants<Real>& constants,
                                        const PivotSampler<Real>& sampler,
                                        const std::vector<std::uint32_t>& generator,
                                        const QmcOptions& options, std::vector<char>& finished) {
  const std::size_t n = chain.size();
  const std::size_t points = options.points;
  const std::size_t shifts = options.shifts;
  const std::vector<std::vector<Real>> shift = random_shifts<Real>(shifts, n, options.seed);
  std::vector<ShiftSums<Real>> sums(shifts, ShiftSums<Real>(n));
  ParallelErrors errors;  // an exception may not leave the parallel region
  const ShiftRange mine = shift_range(options.partition, shifts);
  const RunControl* control = options.partition ? nullptr : options.control;
  finished.assign(shifts, 0);
  // Progress over every point of every shift, and a stop request, polled every
  // lattice_poll_points points inside each shift (a big point stops within a fraction of a
  // second; the unfinished shifts are dropped).
  std::size_t points_done = 0;
  const double all_points = static_cast<double>(points) * static_cast<double>(shifts);
  const std::function<bool(std::size_t)> poll = [&](std::size_t count) {
    if (control->stop_requested()) return false;
#if defined(_OPENMP)
#pragma omp critical(pendavg_qmc_progress)
#endif
    {
      points_done += count;
      control->report(static_cast<double>(points_done) / all_points);
    }
    return true;
  };
  int team = 1;
  if constexpr (std::is_floating_point_v<Real>) team = std::max(options.threads, 1);
#if defined(_OPENMP)
#pragma omp parallel for num_threads(team) schedule(dynamic, 1) if (team > 1)
#endif
  for (std::ptrdiff_t r = static_cast<std::ptrdiff_t>(mine.first);
       r < static_cast<std::ptrdiff_t>(mine.last); ++r) {
    errors.capture([&] {
      const auto rr = static_cast<std::size_t>(r);
      if (control != nullptr && control->stop_requested()) return;
      bool complete = true;
      sums[rr] = shifted_lattice_sums(chain, constants, sampler, shift[rr], points, generator,
                                      control != nullptr ? &poll : nullptr, &complete);
      if (!complete) return;
      finished[rr] = 1;
      if (control != nullptr) poll(points % lattice_poll_points ? points % lattice_poll_points
                                                                : lattice_poll_points);
    });
  }
  errors.rethrow();
  (void)team;
  if (options.partition) gather_shift_sums(*options.partition, sums);
  return sums;
}

/// Every shift's sums at one common scale (the weights are exp(log W - log_scale); a shift
/// without a finite weight has all sums zero), and the totals of W and W^2.
template <class Real>
struct ScaledShiftSums {
  std::vector<Real> weight;
  std::vector<std::vector<Real>> trace, second_moment, cosine;
  Real total_weight{0}, total_weight_squared{0};
};

template <class Real>
ScaledShiftSums<Real> common_scale(const std::vector<ShiftSums<Real>>& sums, std::size_t n) {
  using std::exp;
  const std::size_t shifts = sums.size();
  ScaledShiftSums<Real> s;
  s.weight.resize(shifts);
  s.trace.assign(shifts, std::vector<Real>(n));
  s.second_moment.assign(shifts, std::vector<Real>(n));
  s.cosine.assign(shifts, std::vector<Real>(n));
  bool any_scaled = false;
  Real log_scale = 0;
  for (std::size_t r = 0; r < shifts; ++r) {
    if (!sums[r].scaled) continue;
    log_scale = any_scaled ? std::max(log_scale, sums[r].log_scale) : sums[r].log_scale;
    any_scaled = true;
  }
  if (!any_scaled) {
    throw invalid_input("qmc_average: every importance weight vanished (use torus_average)");
  }
  Real total_w = 0, total_w2 = 0;
  for (std::size_t r = 0; r < shifts; ++r) {
    const Real f = sums[r].scaled ? Real(exp(sums[r].log_scale - log_scale)) : Real(0);
    s.weight[r] = f * sums[r].weight.value();
    total_w += s.weight[r];
    total_w2 += f * f * sums[r].weight_squared.value();
    for (std::size_t i = 0; i < n; ++i) {
      s.trace[r][i] = f * sums[r].trace[i].value();
      s.second_moment[r][i] = f * sums[r].second_moment[i].value();
      s.cosine[r][i] = f * sums[r].cosine[i].value();
    }
  }
  s.total_weight = total_w;
  s.total_weight_squared = total_w2;
  return s;
}

/// beta<K_i>, beta^2 Var K_i, <cos phi_i> (3n values) from the totals over the shifts except
/// `skip` (skip >= shifts: all of them), the ratio of the totals.
template <class Real>
std::vector<Real> shift_ratio_quantities(const ScaledShiftSums<Real>& s, std::size_t n,
                                         std::size_t skip) {
  const std::size_t shifts = s.weight.size();
  Real w = 0;
  std::vector<Real> tr(n, Real(0)), m2(n, Real(0)), c(n, Real(0)), out(3 * n);
  for (std::size_t r = 0; r < shifts; ++r) {
    if (r == skip) continue;
    w += s.weight[r];
    for (std::size_t i = 0; i < n; ++i) {
      tr[i] += s.trace[r][i];
      m2[i] += s.second_moment[r][i];
      c[i] += s.cosine[r][i];
    }
  }
  for (std::size_t i = 0; i < n; ++i) {
    const Real k = tr[i] / (2 * w);
    out[i] = k;
    out[n + i] = m2[i] / (4 * w) - k * k;
    out[2 * n + i] = c[i] / w;
  }
  return out;
}

}  // namespace detail::qmc

/// Randomized lattice QMC estimate of the averages (see the comment above QmcOptions).
/// Throws invalid_input for a bad beta or options, or N > 256 without options.generating_vector.
template <class Real>
Averages<Real> qmc_average(const Chain<Real>& chain, const Real& beta,
                           const QmcOptions& options = {}) {
  using namespace detail::qmc;
  check_beta(beta);
  const std::size_t n = chain.size();
  const std::size_t points = options.points;
  if (points < 1024 || points > (std::size_t(1) << 20) || (points & (points - 1)) != 0) {
    throw invalid_input("qmc_average: points must be a power of two in [2^10, 2^20]");
  }
  if (options.shifts < 4) throw invalid_input("qmc_average: at least 4 random shifts");
  if (!(options.sigmas >= 0) || !std::isfinite(options.sigmas)) {
    throw invalid_input("qmc_average: sigmas must be positive (or 0: automatic)");
  }
  const std::vector<std::uint32_t> generator = qmc_generating_vector(options, n);
  if (options.proposal_grid < 4 || options.proposal_grid % 4 != 0) {
    throw invalid_input("qmc_average: proposal_grid must be a multiple of 4, >= 4");
  }
  const bool sequential =
      options.proposal == QmcProposal::pivot_sequential ||
      (options.proposal == QmcProposal::automatic && n > automatic_von_mises_max_particles);
  const detail::torus::WeightConstants<Real> constants(chain, beta);
  const PivotSampler<Real> sampler(chain, constants.alpha, options.proposal_grid, sequential);

  std::vector<char> finished;
  std::vector<ShiftSums<Real>> sums =
      run_shifts(chain, constants, sampler, generator, options, finished);
  std::size_t shifts = options.shifts;
  // Stopped (RunControl): the shifts that finished are an estimate of their own (fewer shifts).
  const RunControl* control = options.partition ? nullptr : options.control;
  const bool stopped =
      control != nullptr && std::count(finished.begin(), finished.end(), char(1)) <
                                static_cast<std::ptrdiff_t>(shifts);
  if (stopped) {
    std::vector<ShiftSums<Real>> kept;
    for (std::size_t r = 0; r < shifts; ++r)
      if (finished[r]) kept.push_back(std::move(sums[r]));
    if (kept.size() < 2)
      throw interrupted("qmc_average: stopped before two random shifts finished");
    sums = std::move(kept);
    shifts = sums.size();
  }

  // Totals and delete-one-shift totals; every quantity is a function of sums, so the jackknife
  // applies to each: Var_jack = (R - 1)/R sum_r (theta_(r) - mean)^2.
  const std::size_t count = 3 * n;  // beta<K_i>, beta^2 Var K_i, <cos phi_i>
  const ScaledShiftSums<Real> scaled = common_scale(sums, n);
  const std::vector<Real> value = shift_ratio_quantities(scaled, n, shifts);
  std::vector<std::vector<Real>> leave_out(shifts);
  for (std::size_t r = 0; r < shifts; ++r) leave_out[r] = shift_ratio_quantities(scaled, n, r);
  const std::vector<Real> standard_error = jackknife_standard_errors(leave_out, count);
  const Real total_w = scaled.total_weight, total_w2 = scaled.total_weight_squared;

  const Real u = unit_roundoff<Real>();
  const Real rounding =
      detail::torus::rounding_ulps(constants, n, Real(sqrt(constants.alpha_sum))) * u;
  const double sigma_multiplier =
      options.sigmas > 0 ? options.sigmas : qmc_default_sigmas(shifts);
  const Real sigmas = Real(sigma_multiplier);
  Averages<Real> a;
  QmcDiagnostics<Real>& diagnostics = a.qmc.emplace();
  diagnostics.points = points;
  diagnostics.shifts = shifts;
  diagnostics.sigmas = sigma_multiplier;
  a.method = Method::qmc;
  a.error_kind = ErrorKind::statistical;
  a.work_unit = WorkUnit::samples;
  a.evaluations = points * shifts;
  a.converged = !stopped;
  a.interrupted = stopped;
  diagnostics.beta_kinetic_standard_error.assign(standard_error.begin(), standard_error.begin() + n);
  diagnostics.beta2_kinetic_variance_standard_error.assign(standard_error.begin() + n,
                                                           standard_error.begin() + 2 * n);
  diagnostics.cos_angle_standard_error.assign(standard_error.begin() + 2 * n, standard_error.end());
  a.beta_kinetic.resize(n);
  a.beta2_kinetic_variance.resize(n);
  a.cos_angle.resize(n);
  constexpr ErrorKind kind = ErrorKind::statistical;
  for (std::size_t i = 0; i < n; ++i) {
    a.beta_kinetic[i] = {value[i], sigmas * standard_error[i] + rounding * abs(value[i]), kind};
    a.beta2_kinetic_variance[i] = {value[n + i], sigmas * standard_error[n + i] + rounding, kind};
    a.cos_angle[i] = {value[2 * n + i], sigmas * standard_error[2 * n + i] + rounding, kind};
  }
  if (n >= 2) a.ratio = kinetic_ratio(a.beta_kinetic[0], a.beta_kinetic[1], u);
  add_chain_extras(a, chain);
  diagnostics.effective_sample_fraction =
      total_w * total_w / (total_w2 * Real(static_cast<double>(points * shifts)));
  // Never a non-finite value reported as converged.
  using std::isfinite;
  const auto finite = [](const std::vector<Estimate<Real>>& v) {
    return std::all_of(v.begin(), v.end(), [](const Estimate<Real>& e) {
      return isfinite(e.value) && isfinite(e.error);
    });
  };
  if (!finite(a.beta_kinetic) || !finite(a.beta2_kinetic_variance) || !finite(a.cos_angle)) {
    a.converged = false;
  }
  return a;
}

// ============================================================================ limits, any N
//
// beta -> 0 (MATH.md Sec. 2): exp(-beta U) -> 1, so the angles are distributed as sqrt(det A)
// on the torus and beta<K_i> -> <tr X_i>_{sqrt det A} / 2, Var likewise, <cos phi_i> -> 0. That
// is exactly the torus average of the same chain with g = 0 (at any beta), evaluated here by
// the tensor trapezoid for N <= max_tensor_particles (to options.tolerance) and by QMC beyond
// (statistical bars). For N = 2 it reproduces the elliptic K/E limit (tested).
// beta -> infinity: the chain hangs, tr X_i(0) = 1 for every i (MATH.md Sec. 2), so
// beta<K_i> -> 1/2, <cos phi_i> -> 1 and, from Isserlis (Sec. 4) at phi = 0,
// beta^2 Var K_i -> tr(X_i(0)^2) / 2 (1/2 for N = 2: X_1 has rank one). Closed form.

/// The beta -> 0 limit for any N (see above). method = torus_trapezoid or qmc.
template <class Real>
Averages<Real> high_temperature_limit_any(const Chain<Real>& chain, const TorusOptions& torus = {},
                                          const QmcOptions& qmc = {},
                                          std::size_t max_tensor_particles = 5) {
  const Chain<Real> free(chain.masses(), chain.lengths(), Real(0));
  Averages<Real> out = chain.size() <= max_tensor_particles
                           ? torus_average(free, Real(1), torus)
                           : qmc_average(free, Real(1), qmc);
  // At g = 0 the cosine averages vanish by symmetry (phi -> phi + const); report exact zeros.
  for (std::size_t i = 0; i < chain.size(); ++i) {
    out.cos_angle[i] = {Real(0), Real(0), ErrorKind::bound};
  }
  out.diagonal_approximation = diagonal_approximation(chain);
  return out;
}

/// The beta -> infinity limit for any N (see above): exact, method low_temperature_limit.
template <class Real>
Averages<Real> low_temperature_limit_any(const Chain<Real>& chain) {
  const std::size_t n = chain.size();
  TraceWorkspace<Real> ws(chain);
  const std::vector<Real> zero(n > 1 ? n - 1 : 1, Real(0));
  const NodeTraces<Real>& t = node_traces_relative(chain, zero.data(), ws);
  constexpr ErrorKind bound = ErrorKind::bound;
  Averages<Real> out;
  out.beta_kinetic.assign(n, Estimate<Real>{Real(1) / 2, Real(0), bound});
  out.cos_angle.assign(n, Estimate<Real>{Real(1), Real(0), bound});
  out.beta2_kinetic_variance.resize(n);
  for (std::size_t i = 0; i < n; ++i) {
    const Real variance = t.trace_X_squared[i] / 2;
    // tr X_i^2 from the O(N) sweeps is accurate to a few ulps (trace_formula.hpp).
    out.beta2_kinetic_variance[i] = {variance,
                                     16 * std::numeric_limits<Real>::epsilon() * variance, bound};
  }
  if (n >= 2) out.ratio = Estimate<Real>{Real(1), Real(0), bound};
  out.method = Method::low_temperature_limit;
  out.error_kind = bound;
  out.work_unit = WorkUnit::nodes;
  out.evaluations = 1;
  add_chain_extras(out, chain);
  return out;
}

// Explicit instantiations live in src/engine/torus.cpp (double, long double, mpfr_real).
#define PENDAVG_TORUS_EXTERN(Real)                                                          \
  extern template Averages<Real> torus_average<Real>(const Chain<Real>&, const Real&,        \
                                                     const TorusOptions&);                  \
  extern template Averages<Real> qmc_average<Real>(const Chain<Real>&, const Real&,          \
                                                   const QmcOptions&);                      \
  extern template Averages<Real> high_temperature_limit_any<Real>(                          \
      const Chain<Real>&, const TorusOptions&, const QmcOptions&, std::size_t);             \
  extern template Averages<Real> low_temperature_limit_any<Real>(const Chain<Real>&);
PENDAVG_TORUS_EXTERN(double)
PENDAVG_TORUS_EXTERN(long double)
PENDAVG_TORUS_EXTERN(mpfr_real)
#undef PENDAVG_TORUS_EXTERN

}  // namespace pendavg
