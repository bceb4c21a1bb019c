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
// -- use qmc_average, also in this header (randomized lattice QMC over the von Mises law,
// MATH.md Sec. 6; see the comment above QmcOptions).
//
// Result type. Averages<Real> carries the common fields (method torus_trapezoid,
// torus_gauss_legendre or qmc); the any-N extras come back in TorusAverages / QmcAverages.
//
// Precision: generic over Real (double, long double, mpfr_real). With options.digits > 0 (MPFR:
// 16..1000) the call runs at digits + guard_digits and the tolerance becomes 10^-digits. The
// double path is thread-parallel over the outermost dimension when options.threads > 1 (results
// are bitwise independent of the thread count: partial sums are combined in a fixed order);
// MPFR always runs on the calling thread.
#pragma once

#include "pendavg/bessel.hpp"
#include "pendavg/chain.hpp"
#include "pendavg/precision.hpp"
#include "pendavg/result.hpp"
#include "pendavg/trace_formula.hpp"

#include <boost/math/constants/constants.hpp>
#include <gsl/gsl_integration.h>

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <optional>
#include <random>
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
  int threads = 1;                        ///< OpenMP threads (double/long double only)
  /// true: once the successive differences contract by >= 10 per level, the error of the last
  /// level is estimated as d_n (d_n / d_{n/2}) (geometric convergence); false: d_n itself.
  bool extrapolate_error = true;
};

/// The any-N fields that Averages<Real> has no room for.
template <class Real>
struct TorusAverages {
  Averages<Real> averages;  ///< method = torus_trapezoid or torus_gauss_legendre
  /// beta <K_i^(c)> = <p_i phidot_i>/2 beta: 1/2 at every node, so 1/2 exactly (MATH.md Sec. 4).
  std::vector<Real> beta_kinetic_canonical;
  /// The paper's eq. ke-linear-tave-1 (MATH.md Sec. 8), beside the exact beta <K_i>.
  std::vector<Real> diagonal_approximation;
  /// |sum_i beta<K_i> - N/2|: the trace identity sum_i tr X_i = N after quadrature (rounding).
  Real equipartition_residual{};
  /// Z = <exp(log sqrt det A - log_hadamard - S) I0(R)> over the uniform torus, with its error.
  Real mean_weight{}, mean_weight_error{};
  TorusRule rule = TorusRule::trapezoid;
  std::size_t points_per_dim = 0;  ///< n of the final level
  double grid_points = 0;          ///< n^(N-1) of the final level (before the mirror halving)
  std::size_t levels = 0;          ///< refinement levels evaluated
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
  r.weight.assign(n, Real(1));
  r.orbit.resize(n);
  r.inherited.resize(n);
  r.mirror.resize(n);
  for (std::size_t k = 0; k < n; ++k) r.mirror[k] = (n - k) % n;
  const Real two_pi = 2 * pi<Real>();
  for (std::size_t k = 0; 2 * k <= n; ++k) {
    Real a = two_pi * Real(static_cast<double>(k)) / Real(static_cast<double>(n));
    Real c = cos(a), s = sin(a);
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
    r.orbit[k] = (k == 0 || 2 * k == n) ? 0 : 1;
    if (k != 0 && 2 * k != n) {
      r.angle[n - k] = -a;
      r.cos_angle[n - k] = c;
      r.sin_angle[n - k] = -s;
      r.orbit[n - k] = -1;
    }
  }
  for (std::size_t k = 0; k < n; ++k) r.inherited[k] = nested_on_previous && (k % 2 == 0);
  return r;
}

/// Gauss-Legendre nodes x_k and weights on [-1, 1] (weights sum to 2), ascending, with
/// x_{n-1-k} = -x_k exactly. double: GSL's table; other types: Newton on P_n from GSL's nodes.
template <class Real>
void gauss_legendre_nodes(std::size_t n, std::vector<Real>& x, std::vector<Real>& w) {
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
  for (std::size_t k = 0; 2 * k < n; ++k) {  // the non-positive half, then mirror
    Real xk = seed[k].first, wk = seed[k].second;
    if (2 * k + 1 == n) {
      xk = 0;
    }
    if constexpr (!std::is_same_v<Real, double>) {
      // Newton on P_n: P_{j+1} = ((2j+1) x P_j - j P_{j-1}) / (j+1), P'_n = n (x P_n - P_{n-1}) /
      // (x^2 - 1). Quadratic convergence from a double seed: ~log2(digits/16) + 2 steps.
      const Real tiny = 4 * unit_roundoff<Real>();
      Real derivative = 0;
      for (int iteration = 0; iteration < 64; ++iteration) {
        Real p_prev = 1, p = xk;
        for (std::size_t j = 1; j < n; ++j) {
          const Real jj = Real(static_cast<double>(j));
          const Real p_next = ((2 * jj + 1) * xk * p - jj * p_prev) / (jj + 1);
          p_prev = p;
          p = p_next;
        }
        derivative = Real(static_cast<double>(n)) * (xk * p - p_prev) / (xk * xk - 1);
        const Real step = p / derivative;
        if (2 * k + 1 != n) xk -= step;
        if (abs(step) <= tiny) break;
      }
      wk = 2 / ((1 - xk * xk) * derivative * derivative);
    }
    x[k] = xk;
    w[k] = wk;
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
  std::vector<Real> x, w;
  gauss_legendre_nodes<Real>(n, x, w);
  CircleRule<Real> r;
  r.n = n;
  r.nested = false;
  r.angle.resize(n);
  r.cos_angle.resize(n);
  r.sin_angle.resize(n);
  r.weight.resize(n);
  r.orbit.resize(n);
  r.inherited.assign(n, 0);
  r.mirror.resize(n);
  for (std::size_t k = 0; k < n; ++k) r.mirror[k] = n - 1 - k;
  const Real p = pi<Real>();
  for (std::size_t k = 0; 2 * k < n; ++k) {
    const Real a = p * (1 + x[k]);  // in (0, pi]; its mirror -a is node n-1-k
    Real c = cos(a), s = sin(a);
    if (2 * k + 1 == n) {
      c = -1;
      s = 0;
    }
    r.angle[k] = a;
    r.cos_angle[k] = c;
    r.sin_angle[k] = s;
    r.weight[k] = w[k] / 2;
    r.orbit[k] = (2 * k + 1 == n) ? 0 : 1;
    if (2 * k + 1 != n) {
      r.angle[n - 1 - k] = -a;
      r.cos_angle[n - 1 - k] = c;
      r.sin_angle[n - 1 - k] = -s;
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
  Real a{0};
  int p = 1;
  bool identity() const { return a == 0; }
};

/// The rule `base` (nodes t, weights) after the map: nodes delta(t), weights times the Jacobian.
/// Nodes at t = 0 and t = pi stay exactly there; mirrored nodes stay bitwise negated.
template <class Real>
CircleRule<Real> mapped_rule(const CircleRule<Real>& base, const NodeMap<Real>& map) {
  using std::cos;
  using std::sin;
  if (map.identity()) return base;
  CircleRule<Real> r = base;
  const Real pp = Real(map.p);
  for (std::size_t k = 0; k < base.n; ++k) {
    if (base.orbit[k] < 0) continue;  // set from its mirror below
    const Real& t = base.angle[k];
    const bool at_pi = (base.cos_angle[k] == -1 && base.sin_angle[k] == 0);
    Real delta = t, c = base.cos_angle[k], s = base.sin_angle[k];
    if (t != 0 && !at_pi) {
      delta = t - map.a * sin(pp * t) / pp;
      c = cos(delta);
      s = sin(delta);
    }
    const Real jacobian = 1 - map.a * cos(pp * t);
    r.angle[k] = delta;
    r.cos_angle[k] = c;
    r.sin_angle[k] = s;
    r.weight[k] = base.weight[k] * jacobian;
    const std::size_t m = base.mirror[k];
    if (m != k) {
      r.angle[m] = -delta;
      r.cos_angle[m] = c;
      r.sin_angle[m] = -s;
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
  Real total = 0;
  for (const Real& x : alpha) total += x;
  Real head = 0;
  for (std::size_t i = 0; i + 1 < n; ++i) {
    head += alpha[i];
    const Real tail = total - head;
    const Real mass_scale = sqrt(chain.mass(i) / chain.tail_mass(i));
    Real eps = mass_scale;
    int p = 2;
    if (head > 0 && tail > 0) {
      const Real width = sqrt(total / (head * tail));
      if (width < eps) {
        eps = width;
        p = 1;
      }
    }
    if (eps < Real(0.3)) {
      maps[i].a = 1 - exp(2 * log(eps) / 3);  // 1 - eps^(2/3)
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
  std::vector<CompensatedSum<Real>> trace, second_moment, cosine, cosine_abs;
  std::size_t evaluations = 0;
  explicit TorusSums(std::size_t n = 0)
      : trace(n), second_moment(n), cosine(n), cosine_abs(n) {}
  void merge(const TorusSums& other) {
    weight.add(other.weight.value());
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
  void accumulate(const Real* delta, const Real* cd, const Real* sd, const Real& node_weight,
                  TorusSums<Real>& sums) {
    const std::size_t n = chain_.size();
    const NodeTraces<Real>& traces = node_traces_relative(chain_, delta, workspace_);
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
    Real radius = 0, s_minus_r = k_.alpha_sum;
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
      }
    } else {
      for (std::size_t j = 0; j < n; ++j) cos_offset_[j] = 0;
    }
    const ScaledBesselI01<Real> bessel = scaled_bessel_i01(radius);
    const Real w =
        node_weight * exp(traces.log_sqrt_det_A - k_.log_hadamard - s_minus_r) * bessel.i0e;
    const Real bessel_ratio_w = w * (bessel.i1e / bessel.i0e);
    sums.weight.add(w);
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
  GridWalker(const std::vector<CircleRule<Real>>& rules, std::size_t dims,
             ReducedIntegrand<Real>& integrand)
      : rules_(rules), dims_(dims), integrand_(integrand), delta_(dims), cd_(dims), sd_(dims),
        weight_(dims + 1) {}

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
    const CircleRule<Real>& rule = rules_[d];
    for (std::size_t k = 0; k < rule.n; ++k) {
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
  std::vector<Real> delta_, cd_, sd_, weight_;
};

/// Sums of one level over every node (or, for a nested level, every node not on the previous
/// level). Deterministic: one partial sum per outermost index, combined in index order.
template <class Real>
TorusSums<Real> level_sums(const Chain<Real>& chain, const WeightConstants<Real>& constants,
                           const std::vector<CircleRule<Real>>& rules, std::size_t dims,
                           int threads) {
  const std::size_t n_particles = chain.size();
  const std::size_t outer = dims == 0 ? 1 : rules[0].n;
  std::vector<TorusSums<Real>> partial(outer, TorusSums<Real>(n_particles));
  int team = 1;
  if constexpr (std::is_floating_point_v<Real>) team = std::max(threads, 1);
#if defined(_OPENMP)
#pragma omp parallel num_threads(team) if (team > 1)
#endif
  {
    ReducedIntegrand<Real> integrand(chain, constants);
    GridWalker<Real> walker(rules, dims, integrand);
    TorusSums<Real> local(n_particles);  // per thread: no false sharing between tasks
#if defined(_OPENMP)
#pragma omp for schedule(dynamic, 1)
#endif
    for (std::ptrdiff_t k0 = 0; k0 < static_cast<std::ptrdiff_t>(outer); ++k0) {
      local = TorusSums<Real>(n_particles);
      walker.walk_outer(static_cast<std::size_t>(k0), local);
      partial[static_cast<std::size_t>(k0)] = local;
    }
  }
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
/// log_hadamard + sqrt(alpha)), and the N-term rotation products ~N ulps; compensated summation
/// adds nothing that grows with the node count.
template <class Real>
Real rounding_ulps(const WeightConstants<Real>& k, std::size_t n) {
  using std::sqrt;
  return Real(32) + Real(4 * static_cast<double>(n)) + 2 * abs(k.log_hadamard) +
         2 * sqrt(k.alpha_sum);
}

}  // namespace detail::torus

/// The averages and the any-N extras (canonical kinetic energies, diagonal approximation,
/// equipartition residual, mean weight, final grid). Throws invalid_input for a bad beta,
/// digits or options, or when the first level would exceed options.max_grid_points nodes.
template <class Real>
TorusAverages<Real> torus_average_full(const Chain<Real>& chain, const Real& beta,
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
  const Real rounding = rounding_ulps(constants, n_particles) * u;
  std::vector<NodeMap<Real>> maps(dims);
  if (options.node_map == TorusNodeMap::automatic) {
    maps = automatic_node_maps(chain, constants.alpha);
  }

  TorusAverages<Real> out;
  out.rule = options.rule;
  Averages<Real>& a = out.averages;
  a.method = options.rule == TorusRule::gauss_legendre ? Method::torus_gauss_legendre
                                                       : Method::torus_trapezoid;
  a.converged = false;

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
  LevelValues<Real> current;
  for (std::size_t level = 0;; ++level) {
    const bool trapezoid = options.rule == TorusRule::trapezoid;
    const CircleRule<Real> base =
        trapezoid ? trapezoid_rule<Real>(n, level > 0) : gauss_legendre_rule<Real>(n);
    std::vector<CircleRule<Real>> rules;
    for (std::size_t d = 0; d < std::max<std::size_t>(dims, 1); ++d) {
      rules.push_back(d < maps.size() ? mapped_rule(base, maps[d]) : base);
    }
    const TorusSums<Real> fresh = level_sums(chain, constants, rules, dims, options.threads);
    a.evaluations += fresh.evaluations;
    if (trapezoid) {
      cumulative.merge(fresh);
      current = level_values(cumulative, Real(grid_size(n)));
    } else {
      current = level_values(fresh, Real(1));
    }
    out.levels = level + 1;
    out.points_per_dim = n;
    out.grid_points = grid_size(n);
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
    previous = value;
    n = next;
  }

  if (!a.converged) {
    // Stopped early: an unresolved weight (e.g. a peak narrower than the grid spacing) leaves
    // the ratios frozen at the nodes that see it while Z still moves. Every ratio's error is
    // then at least Z's relative error times the ratio's scale, so the estimates stay valid.
    const Real z_relative = scale[0] > 0 ? Real(estimate[0] / scale[0]) : Real(1);
    for (std::size_t q = 1; q < count; ++q) {
      estimate[q] = std::max(estimate[q], Real(z_relative * scale[q]));
    }
  }

  a.beta_kinetic = current.beta_kinetic;
  a.cos_angle = current.cosine;
  a.beta2_kinetic_variance = current.variance;
  a.beta_kinetic_error.resize(n_particles);
  a.cos_angle_error.resize(n_particles);
  a.beta2_kinetic_variance_error.resize(n_particles);
  Real kinetic_sum = 0;
  for (std::size_t i = 0; i < n_particles; ++i) {
    a.beta_kinetic_error[i] = estimate[1 + i] + rounding * scale[1 + i];
    a.beta2_kinetic_variance_error[i] =
        estimate[1 + n_particles + i] + 2 * rounding * scale[1 + n_particles + i];
    a.cos_angle_error[i] = estimate[1 + 2 * n_particles + i] + rounding * scale[1 + 2 * n_particles + i];
    kinetic_sum += current.beta_kinetic[i];
  }
  if (n_particles >= 2) {
    a.ratio = a.beta_kinetic[0] / a.beta_kinetic[1];
    a.ratio_error = a.beta_kinetic_error[0] / a.beta_kinetic[1] +
                    a.ratio * (a.beta_kinetic_error[1] / a.beta_kinetic[1] + 4 * u);
  }
  out.mean_weight = current.mean_weight;
  out.mean_weight_error = estimate[0] + rounding * scale[0];
  out.beta_kinetic_canonical.assign(n_particles, Real(1) / 2);
  out.diagonal_approximation = diagonal_approximation(chain);
  out.equipartition_residual = abs(kinetic_sum - Real(static_cast<double>(n_particles)) / 2);
  return out;
}

/// The averages only (Averages<Real>; method = reduced_integral, evaluations = nodes evaluated
/// after the mirror halving, summed over the levels). See torus_average_full.
template <class Real>
Averages<Real> torus_average(const Chain<Real>& chain, const Real& beta,
                             const TorusOptions& options = {}) {
  return torus_average_full(chain, beta, options).averages;
}

// ============================================================================ randomized QMC
//
// qmc_average: the same averages for chains too long for a tensor grid (MATH.md Sec. 6).
// Method. The N absolute angles are drawn from the product of the laws exp(alpha_j cos phi_j)
// and each draw is weighted by sqrt(det A); the ratio estimators are the same as on the torus,
// with <cos phi_j> Rao-Blackwellized over psi to (I1/I0)(R) cos(phi_j - arg z) (MATH.md Sec. 2).
// Points: a rank-1 lattice rule with n = 2^m points, x_k = frac(k z / n + Delta), randomized by
// independent uniform shifts Delta. The generating vectors z are our own CBC constructions
// (cbc_generating_vector below; tabulated for n = 2^10..2^16, N <= 32). Published embedded
// sequences optimized for order-2 weights (e.g. Cools-Kuo-Nuyens 2006) were tried and rejected:
// their 3-D projections carry short dual vectors such as (-1, -11, -2) for every n >= 2^13,
// which froze the error at ~3e-7 for N = 3 from 2^13 to 2^16 points; this integrand couples
// all angles through det A.
// From the unit cube to the angles, per coordinate, the exact inverse CDF of the wrapped Cauchy
// law that Best and Fisher (1979) use as the envelope of their von Mises sampler: x = 2 atan(
// tan(pi (u - 1/2)) (1 - rho)/(1 + rho)). Their rejection step would break the lattice structure;
// the acceptance ratio exp(alpha (cos x - 1)) (1 + rho^2 - 2 rho cos x)/(1 - rho)^2 is kept as an
// importance weight instead, so the estimate is exactly that of von Mises sampling (same
// integrals), the integrand on the unit cube stays periodic and analytic (what lattice rules
// need), and the weight never exceeds ~1.5 times its mean, for every alpha (Best-Fisher's
// acceptance rate is >= 0.66). No Bessel series, tables or rejection: closed form at any alpha.
// Error bar: the R shifted lattices give R independent, unbiased estimates of every numerator
// and denominator; the value is the ratio of the totals and its standard error the jackknife
// over shifts (delete-one-shift). The reported error is `sigmas` standard errors (default 3:
// ~99% two-sided coverage for Student's t with R - 1 = 15 degrees of freedom) plus the rounding
// budget. A statistical bar, not a bound. Deterministic for a given seed and any thread count.
// When to use it: N >= 5 or so (a tensor grid needs n^(N-1) nodes); for N <= 4 torus_average is
// exact to 1e-13 in milliseconds. Large beta needs no special care here (the sampler follows
// the concentration). Limitation: the sampler ignores sqrt(det A), whose spread grows with N at
// moderate beta; the pooled-weight efficiency (effective_sample_fraction) for unit chains at
// beta = 1 is 0.70 (N = 3), 0.23 (N = 8), 0.03 (N = 16), ~0 (N = 32), and the error bars grow
// accordingly (3-sigma bar on beta<K_1> with 2^14 x 16 points: 4e-9, 2e-4, 1e-3, 2e-2). Watch
// that fraction: below ~0.01 the jackknife bar itself becomes unreliable.
// Measured (tests/test_torus.cpp): with 2^10 points x 16 shifts the 3-sigma bars cover the exact
// N = 3 values for 97..100 of 100 seeds, per quantity and particle.

/// Options of qmc_average.
struct QmcOptions {
  std::size_t points = std::size_t(1) << 14;  ///< lattice points per shift: 2^m, 2^10 <= . <= 2^20
  std::size_t shifts = 16;                    ///< independent random shifts (>= 4)
  std::uint64_t seed = 1;                     ///< the shifts come from std::mt19937_64(seed)
  double sigmas = 3;                          ///< error = sigmas * jackknife standard error
  int threads = 1;                            ///< OpenMP threads over shifts (double/long double)
  /// Optional generating vector for `points` points (one odd entry per particle); empty: the
  /// built-in table.
  std::vector<std::uint32_t> generating_vector;
};

/// qmc_average's result: the averages (errors = sigmas standard errors + rounding) and extras.
template <class Real>
struct QmcAverages {
  Averages<Real> averages;  ///< evaluations = points * shifts
  std::vector<Real> beta_kinetic_standard_error, cos_angle_standard_error,
      beta2_kinetic_variance_standard_error;
  std::vector<Real> beta_kinetic_canonical;  ///< 1/2 exactly (MATH.md Sec. 4)
  std::vector<Real> diagonal_approximation;  ///< eq. ke-linear-tave-1 (MATH.md Sec. 8)
  Real equipartition_residual{};             ///< |sum_i beta<K_i> - N/2|
  /// Kish's effective sample size of the pooled weights over (points * shifts): near the total
  /// when sqrt(det A) and the Best-Fisher ratio vary little.
  Real effective_sample_fraction{};
  std::size_t points = 0, shifts = 0;
};

namespace detail::qmc {

using std::abs;
using std::exp;
using std::log;
using std::sqrt;

/// Built-in generating vectors: row m - 10 holds z for n = 2^m points (m = 10..16) in up to 32
/// dimensions (take the first N entries: CBC vectors are extensible in dimension). Output of
/// cbc_generating_vector(m, 32, gamma_j = 1/j, alpha = 2) below (run offline, ~1 min in all;
/// a test recomputes the rows m = 10, 11). Product weights 1/j keep the criterion finite and
/// meaningful in 32 dimensions; equal weights make it overflow to ties (repeated components).
/// Every z_j is odd, so each one-dimensional projection is the full grid {k / n}.
inline constexpr std::uint32_t lattice_table[7][32] = {
    {// m = 10
     1, 283, 157, 385, 401, 419, 207, 367, 13, 37,
     215, 115, 47, 275, 495, 21, 309, 317, 343, 173,
     487, 89, 131, 359, 55, 453, 241, 351, 165, 123,
     97, 199,
    },
    {// m = 11
     1, 857, 269, 949, 493, 309, 197, 1019, 907, 249,
     127, 655, 87, 645, 543, 117, 775, 715, 329, 15,
     137, 755, 299, 187, 157, 147, 279, 989, 877, 431,
     887, 421,
    },
    {// m = 12
     1, 1557, 1087, 701, 89, 1499, 1163, 901, 1279, 2035,
     851, 1255, 1827, 1523, 21, 1213, 1977, 205, 1775, 911,
     1439, 953, 625, 223, 785, 1515, 331, 1935, 793, 415,
     1733, 1389,
    },
    {// m = 13
     1, 3457, 559, 1925, 2125, 1161, 2707, 921, 1751, 997,
     3005, 1583, 3519, 1287, 1499, 3143, 1411, 1637, 345, 2277,
     2905, 1387, 521, 1625, 1975, 3041, 2327, 1663, 3857, 2841,
     3933, 2679,
    },
    {// m = 14
     1, 6229, 2691, 7621, 4417, 2821, 183, 3259, 3579, 6291,
     5429, 4307, 1241, 5495, 4441, 3495, 7019, 7893, 4367, 77,
     2007, 7197, 373, 821, 6689, 5981, 5911, 4709, 4951, 3919,
     7609, 3837,
    },
    {// m = 15
     1, 12031, 14297, 677, 10515, 413, 3479, 10875, 13233, 15981,
     16087, 4425, 7585, 11391, 8837, 243, 2815, 3521, 8455, 2449,
     13855, 737, 3249, 13727, 2577, 5609, 6375, 6001, 8531, 11571,
     2875, 16367,
    },
    {// m = 16
     1, 19463, 8279, 15259, 9471, 27489, 14621, 2807, 8141, 24773,
     9705, 15109, 7897, 29825, 21467, 18787, 21023, 6643, 11535, 27169,
     31263, 10823, 22487, 609, 20803, 23863, 19635, 23949, 399, 31999,
     21159, 10527,
    },
};
inline constexpr unsigned lattice_table_min_log2 = 10, lattice_table_max_log2 = 16;
inline constexpr std::size_t lattice_max_dimension = 32;

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
  const double two_pi2 = 2 * 9.869604401089358;  // 2 pi^2
  std::vector<double> omega(n);
  for (std::uint64_t k = 0; k < n; ++k) {
    const double x = static_cast<double>(k) / static_cast<double>(n);
    omega[k] = alpha == 4 ? -(two_pi2 * 9.869604401089358 / 3) *
                                (x * x * x * x - 2 * x * x * x + x * x - 1.0 / 30.0)
                          : two_pi2 * (x * x - x + 1.0 / 6.0);
  }
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

/// Sums of one shifted lattice: W, W tr X_i, W ((tr X_i)^2 + 2 tr X_i^2), W cos-factor_i, W^2.
template <class Real>
struct ShiftSums {
  detail::torus::CompensatedSum<Real> weight, weight_squared;
  std::vector<detail::torus::CompensatedSum<Real>> trace, second_moment, cosine;
  explicit ShiftSums(std::size_t n = 0) : trace(n), second_moment(n), cosine(n) {}
};

template <class Real>
ShiftSums<Real> shifted_lattice_sums(const Chain<Real>& chain,
                                     const detail::torus::WeightConstants<Real>& k,
                                     const std::vector<BestFisherMap<Real>>& maps,
                                     const std::vector<Real>& shift, std::size_t points,
                                     const std::vector<std::uint32_t>& generator) {
  const std::size_t n = chain.size();
  ShiftSums<Real> sums(n);
  TraceWorkspace<Real> ws(chain);
  std::vector<Real> phi(n), sphi(n), cphi(n), delta(n > 1 ? n - 1 : 1);
  const std::uint64_t mask = points - 1;  // points is a power of two
  const Real inv_points = Real(1) / Real(static_cast<double>(points));
  for (std::uint64_t p = 0; p < points; ++p) {
    Real log_w = 0;
    for (std::size_t j = 0; j < n; ++j) {
      const std::uint64_t kz = (p * generator[j]) & mask;  // k z_j mod 2^m, exact
      Real u = Real(static_cast<double>(kz)) * inv_points + shift[j];
      if (u >= 1) u -= 1;
      Real log_ratio;
      maps[j].map(u, phi[j], sphi[j], cphi[j], log_ratio);
      log_w += log_ratio;
    }
    for (std::size_t i = 0; i + 1 < n; ++i) delta[i] = phi[i + 1] - phi[i];
    const NodeTraces<Real>& t = node_traces_relative(chain, delta.data(), ws);
    const Real w = exp(log_w + t.log_sqrt_det_A - k.log_hadamard);
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
      ratio_w = w * (b.i1e / b.i0e) / radius;
    }
    sums.weight.add(w);
    sums.weight_squared.add(w * w);
    for (std::size_t i = 0; i < n; ++i) {
      const Real& tr = t.trace_X[i];
      sums.trace[i].add(w * tr);
      sums.second_moment[i].add(w * (tr * tr + 2 * t.trace_X_squared[i]));
      sums.cosine[i].add(ratio_w * (cphi[i] * zx + sphi[i] * zy));
    }
  }
  return sums;
}

}  // namespace detail::qmc

/// Randomized lattice QMC estimate of the averages (see the comment above QmcOptions).
/// Throws invalid_input for a bad beta or options, or N > 250 (the generating vector's length).
template <class Real>
QmcAverages<Real> qmc_average(const Chain<Real>& chain, const Real& beta,
                              const QmcOptions& options = {}) {
  using namespace detail::qmc;
  check_beta(beta);
  const std::size_t n = chain.size();
  const std::size_t points = options.points;
  if (points < 1024 || points > (std::size_t(1) << 20) || (points & (points - 1)) != 0) {
    throw invalid_input("qmc_average: points must be a power of two in [2^10, 2^20]");
  }
  if (options.shifts < 4) throw invalid_input("qmc_average: at least 4 random shifts");
  if (!(options.sigmas > 0)) throw invalid_input("qmc_average: sigmas must be positive");
  std::vector<std::uint32_t> generator = options.generating_vector;
  if (generator.empty()) {
    unsigned log2_points = 0;
    while ((std::size_t(1) << log2_points) < points) ++log2_points;
    if (n > lattice_max_dimension || log2_points > lattice_table_max_log2) {
      throw invalid_input(
          "qmc_average: the built-in lattices cover N <= 32 and 2^10..2^16 points; pass "
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
  const detail::torus::WeightConstants<Real> constants(chain, beta);
  std::vector<BestFisherMap<Real>> maps;
  for (std::size_t j = 0; j < n; ++j) maps.emplace_back(constants.alpha[j]);

  // Shifts: 53 random bits per coordinate, drawn in a fixed order from the seed.
  const std::size_t shifts = options.shifts;
  std::vector<std::vector<Real>> shift(shifts, std::vector<Real>(n));
  std::mt19937_64 rng(options.seed);
  for (auto& s : shift) {
    for (auto& v : s) v = Real(static_cast<double>(rng() >> 11) * 0x1.0p-53);
  }
  std::vector<ShiftSums<Real>> sums(shifts, ShiftSums<Real>(n));
  int team = 1;
  if constexpr (std::is_floating_point_v<Real>) team = std::max(options.threads, 1);
#if defined(_OPENMP)
#pragma omp parallel for num_threads(team) schedule(dynamic, 1) if (team > 1)
#endif
  for (std::ptrdiff_t r = 0; r < static_cast<std::ptrdiff_t>(shifts); ++r) {
    sums[static_cast<std::size_t>(r)] =
        shifted_lattice_sums(chain, constants, maps, shift[static_cast<std::size_t>(r)], points,
                             generator);
  }
  (void)team;

  // Totals and delete-one-shift totals; every quantity is a function of sums, so the jackknife
  // applies to each: Var_jack = (R - 1)/R sum_r (theta_(r) - mean)^2.
  const std::size_t count = 3 * n;  // beta<K_i>, beta^2 Var K_i, <cos phi_i>
  const auto quantities = [&](const std::vector<Real>& s_weight,
                              const std::vector<std::vector<Real>>& s_trace,
                              const std::vector<std::vector<Real>>& s_second,
                              const std::vector<std::vector<Real>>& s_cos, std::size_t skip) {
    Real w = 0;
    std::vector<Real> tr(n, Real(0)), m2(n, Real(0)), c(n, Real(0)), out(count);
    for (std::size_t r = 0; r < shifts; ++r) {
      if (r == skip) continue;
      w += s_weight[r];
      for (std::size_t i = 0; i < n; ++i) {
        tr[i] += s_trace[r][i];
        m2[i] += s_second[r][i];
        c[i] += s_cos[r][i];
      }
    }
    for (std::size_t i = 0; i < n; ++i) {
      const Real k = tr[i] / (2 * w);
      out[i] = k;
      out[n + i] = m2[i] / (4 * w) - k * k;
      out[2 * n + i] = c[i] / w;
    }
    return out;
  };
  std::vector<Real> s_weight(shifts);
  std::vector<std::vector<Real>> s_trace(shifts, std::vector<Real>(n)),
      s_second(shifts, std::vector<Real>(n)), s_cos(shifts, std::vector<Real>(n));
  Real total_w = 0, total_w2 = 0;
  for (std::size_t r = 0; r < shifts; ++r) {
    s_weight[r] = sums[r].weight.value();
    total_w += s_weight[r];
    total_w2 += sums[r].weight_squared.value();
    for (std::size_t i = 0; i < n; ++i) {
      s_trace[r][i] = sums[r].trace[i].value();
      s_second[r][i] = sums[r].second_moment[i].value();
      s_cos[r][i] = sums[r].cosine[i].value();
    }
  }
  const std::vector<Real> value = quantities(s_weight, s_trace, s_second, s_cos, shifts);
  std::vector<std::vector<Real>> leave_out(shifts);
  for (std::size_t r = 0; r < shifts; ++r) {
    leave_out[r] = quantities(s_weight, s_trace, s_second, s_cos, r);
  }
  std::vector<Real> standard_error(count);
  const Real R = Real(static_cast<double>(shifts));
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

  const Real u = unit_roundoff<Real>();
  const Real rounding = detail::torus::rounding_ulps(constants, n) * u;
  const Real sigmas = Real(options.sigmas);
  QmcAverages<Real> out;
  out.points = points;
  out.shifts = shifts;
  Averages<Real>& a = out.averages;
  a.method = Method::qmc;
  a.evaluations = points * shifts;
  a.converged = true;
  a.beta_kinetic.assign(value.begin(), value.begin() + n);
  a.beta2_kinetic_variance.assign(value.begin() + n, value.begin() + 2 * n);
  a.cos_angle.assign(value.begin() + 2 * n, value.end());
  out.beta_kinetic_standard_error.assign(standard_error.begin(), standard_error.begin() + n);
  out.beta2_kinetic_variance_standard_error.assign(standard_error.begin() + n,
                                                   standard_error.begin() + 2 * n);
  out.cos_angle_standard_error.assign(standard_error.begin() + 2 * n, standard_error.end());
  a.beta_kinetic_error.resize(n);
  a.beta2_kinetic_variance_error.resize(n);
  a.cos_angle_error.resize(n);
  Real kinetic_sum = 0;
  for (std::size_t i = 0; i < n; ++i) {
    a.beta_kinetic_error[i] = sigmas * standard_error[i] + rounding * abs(value[i]);
    a.beta2_kinetic_variance_error[i] = sigmas * standard_error[n + i] + rounding;
    a.cos_angle_error[i] = sigmas * standard_error[2 * n + i] + rounding;
    kinetic_sum += value[i];
  }
  if (n >= 2) {
    a.ratio = a.beta_kinetic[0] / a.beta_kinetic[1];
    a.ratio_error = a.beta_kinetic_error[0] / a.beta_kinetic[1] +
                    a.ratio * (a.beta_kinetic_error[1] / a.beta_kinetic[1] + 4 * u);
  }
  out.beta_kinetic_canonical.assign(n, Real(1) / 2);
  out.diagonal_approximation = diagonal_approximation(chain);
  out.equipartition_residual = abs(kinetic_sum - Real(static_cast<double>(n)) / 2);
  out.effective_sample_fraction =
      total_w * total_w / (total_w2 * Real(static_cast<double>(points * shifts)));
  return out;
}

// Explicit instantiations live in src/torus.cpp (double, long double, mpfr_real).
#define PENDAVG_TORUS_EXTERN(Real)                                                          \
  extern template TorusAverages<Real> torus_average_full<Real>(const Chain<Real>&, const Real&, \
                                                               const TorusOptions&);        \
  extern template Averages<Real> torus_average<Real>(const Chain<Real>&, const Real&,        \
                                                     const TorusOptions&);                  \
  extern template QmcAverages<Real> qmc_average<Real>(const Chain<Real>&, const Real&,       \
                                                      const QmcOptions&);
PENDAVG_TORUS_EXTERN(double)
PENDAVG_TORUS_EXTERN(long double)
PENDAVG_TORUS_EXTERN(mpfr_real)
#undef PENDAVG_TORUS_EXTERN

}  // namespace pendavg
