// SPDX-License-Identifier: GPL-3.0-or-later
// engine/torus/torus.hpp -- exact canonical averages for any N by tensor quadrature on the
// reduced (N-1)-torus (paper eq. ave-Ki-linear-pi-trace-varphi). The math, the error estimate
// and when to prefer another method: src/engine/torus/README.md.
//
// Equations. For an N-link chain at inverse temperature beta, alpha_j = beta g S_j l_j (S_j the
// tail masses), relative angles delta_i = phi_{i+1} - phi_i, theta_1 = 0,
// theta_{j+1} = theta_j + delta_j, z = sum_j alpha_j e^{i theta_j}, R = |z|:
//     w(delta)           = sqrt(det A) I0(R)                (psi = phi_1 integrated in closed form)
//     beta <K_i>         = (1/2) <tr X_i>_w                 (trace formula)
//     beta^2 Var K_i     = <(tr X_i)^2 + 2 tr X_i^2>_w / 4 - (beta<K_i>)^2     (Isserlis)
//     <cos phi_j>        = < (I1(R)/I0(R)) cos(theta_j - arg z) >_w
//     beta <K_i^(c)>     = 1/2 exactly (reported as the built-in check it is)
// and the paper's diagonal approximation (eq. ke-linear-tave-1) next to the exact values. The map
// delta -> theta has unit Jacobian on the torus, and every delta_i is uniform on one period.
//
// How. w is evaluated as exp(log sqrt(det A) - log_hadamard - (S - R)) e^{-R} I0(R) with
// S = sum_j alpha_j and log_hadamard = sum_j log(l_j sqrt(S_j)) >= log sqrt(det A) (Hadamard):
// every factor is <= 1, so nothing overflows at any beta or N (torus/reduced_weight.hpp). Per
// node the traces come from the O(N) trace formula (pendavg/trace_formula.hpp). The rules per
// dimension -- the trapezoid (default; the Gaussian rule on the circle, levels n0, 2 n0, ...
// nest) and Gauss-Legendre (the comparison rule, levels do not nest) -- and the automatic node
// maps live in torus/circle_rules.hpp; the walk over the grid with the mirror halving
// (delta -> -delta) in torus/level_sums.hpp.
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
//     of a few dozen ulps of the quantity's scale (rounding_ulps). Not a proof: an integrand whose
//     aliasing error vanished at n/2 and n but not at 2n would fool it. converged = false when
//     max_points_per_dim or max_grid_points stopped the refinement first; the values are then the
//     last level's, and every ratio's error is raised to at least Z's relative difference times
//     the ratio's scale, so the bars stay valid when a narrow peak was seen by one node only.
// When to prefer something else. N = 2: reduced_integral_average (double_pendulum/) is faster
// (and it is the reference the tests hold this engine to). Large N: n^{N-1} nodes (the guard
// refuses more than max_grid_points, default 1e9; N = 5 at 1e-10 takes ~2 s) -- use qmc_average
// (engine/qmc/) or the transfer operator (engine/transfer/).
//
// Result type. Averages<Real> carries the common fields (method torus_trapezoid or
// torus_gauss_legendre) and the any-N extras; Averages::torus describes the run.
//
// Precision: generic over Real (double, long double, mpfr_real). With options.digits > 0 (MPFR:
// 16..1000) the call runs at digits + guard_digits and the tolerance becomes 10^-digits. The
// double path is thread-parallel over the outermost dimension when options.threads > 1 (results
// are bitwise independent of the thread count: partial sums are combined in a fixed order);
// MPFR always runs on the calling thread.
#pragma once

#include "engine/numerics/estimates.hpp"
#include "engine/numerics/precision.hpp"
#include "engine/torus/circle_rules.hpp"
#include "engine/torus/level_sums.hpp"
#include "engine/torus/reduced_weight.hpp"
#include "pendavg/average.hpp"
#include "pendavg/chain.hpp"
#include "pendavg/result.hpp"
#include "pendavg/trace_formula.hpp"

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <limits>
#include <optional>
#include <string>
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

/// n^dims: the nodes of a level with n nodes per dimension (before the mirror halving).
inline double grid_size(std::size_t n, std::size_t dims) {
  return std::pow(static_cast<double>(n), static_cast<double>(dims));
}

/// The options torus_average refuses (invalid_input), before any node: the level sizes, the
/// tolerance, and a first level beyond options.max_grid_points.
inline void check_torus_options(const TorusOptions& options, std::size_t n_particles) {
  const std::size_t dims = n_particles - 1;
  if (options.min_points_per_dim < 2 || options.max_points_per_dim < options.min_points_per_dim) {
    throw invalid_input("torus quadrature needs 2 <= min_points_per_dim <= max_points_per_dim");
  }
  if (!(options.tolerance > 0) && options.digits == 0) {
    throw invalid_input("torus quadrature needs a positive tolerance");
  }
  if (grid_size(options.min_points_per_dim, dims) > options.max_grid_points) {
    throw invalid_input("torus quadrature: " + std::to_string(options.min_points_per_dim) + "^" +
                        std::to_string(dims) + " nodes exceed the cap of " +
                        std::to_string(options.max_grid_points) + "; use qmc_average for N = " +
                        std::to_string(n_particles));
  }
}

/// The rule of every dimension at one level: the base rule (trapezoid, nested on the previous
/// level after the first, or Gauss-Legendre) through each dimension's node map.
template <class Real>
std::vector<CircleRule<Real>> level_rules(TorusRule rule, std::size_t n, std::size_t level,
                                          const std::vector<NodeMap<Real>>& maps,
                                          std::size_t dims) {
  const bool trapezoid = rule == TorusRule::trapezoid;
  const CircleRule<Real> base =
      trapezoid ? trapezoid_rule<Real>(n, level > 0) : gauss_legendre_rule<Real>(n);
  std::vector<CircleRule<Real>> rules;
  for (std::size_t d = 0; d < std::max<std::size_t>(dims, 1); ++d) {
    rules.push_back(d < maps.size() ? mapped_rule(base, maps[d]) : base);
  }
  return rules;
}

/// The reported quantities of the refinement in one flat vector -- Z, then beta<K_i>,
/// beta^2 Var K_i, <cos phi_i> (i = 1..N) -- with the scales of the stopping test (Z, beta<K_i>,
/// beta^2 <K_i^2>, <|I1/I0 cos(theta_i - arg z)|>_w), the previous level's values and the
/// successive differences behind the error estimates (see the header comment).
template <class Real>
struct RefinementQuantities {
  std::size_t n_particles, count;
  std::vector<Real> value, scale, previous, difference, previous_difference, estimate;

  explicit RefinementQuantities(std::size_t particles)
      : n_particles(particles), count(1 + 3 * particles), value(count), scale(count),
        previous(count), difference(count), previous_difference(count), estimate(count) {}

  void flatten(const LevelValues<Real>& v) {
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
  }

  /// The error estimates after `level` (0-based) and whether every one is within `tolerance`
  /// of its scale. Level 0 has no difference yet: the whole scale is its (placeholder) estimate.
  bool refine(std::size_t level, bool extrapolate_error, const Real& tolerance) {
    using std::abs;
    if (level == 0) {
      estimate = scale;
      return false;
    }
    bool done = true;
    for (std::size_t q = 0; q < count; ++q) {
      difference[q] = abs(value[q] - previous[q]);
      estimate[q] = difference[q];
      // Geometric convergence e_n = C rho^n gives e_2n = e_n (e_n / e_{n/2})^2: once the last
      // contraction d_n / d_{n/2} is <= 1/10, e_2n <= d_n (d_n / d_{n/2}) with room to spare.
      if (extrapolate_error && level >= 2 && previous_difference[q] > 0 &&
          difference[q] <= previous_difference[q] / 10) {
        estimate[q] = difference[q] * (difference[q] / previous_difference[q]);
      }
      done = done && estimate[q] <= tolerance * scale[q];
    }
    previous_difference = difference;
    return done;
  }

  /// Stopped early: an unresolved weight (e.g. a peak narrower than the grid spacing) leaves
  /// the ratios frozen at the nodes that see it while Z still moves. Every ratio's error is
  /// then at least Z's relative error times the ratio's scale, so the estimates stay valid.
  /// Nor is the geometric extrapolation of the error trusted before convergence: a light
  /// particle's refinement contracts by 10 per level long before its asymptotic rate (masses
  /// 1.27, 1e-6, 0.986 at 8194 nodes: beta<K_2> off by 5.7e-11, extrapolated error 6.9e-14), so
  /// a stopped run reports the last difference itself.
  void widen_unconverged() {
    for (std::size_t q = 0; q < count; ++q) estimate[q] = std::max(estimate[q], difference[q]);
    const Real z_relative = scale[0] > 0 ? Real(estimate[0] / scale[0]) : Real(1);
    for (std::size_t q = 1; q < count; ++q) {
      estimate[q] = std::max(estimate[q], Real(z_relative * scale[q]));
    }
  }
};

/// The observables of the last level with their errors: the refinement estimate plus the
/// rounding budget (`rounding`, relative to each quantity's scale; twice that for the variance).
template <class Real>
void fill_torus_estimates(Averages<Real>& a, const LevelValues<Real>& current,
                          const RefinementQuantities<Real>& q, const Real& rounding) {
  const std::size_t n_particles = q.n_particles;
  const std::vector<Real>& estimate = q.estimate;
  const std::vector<Real>& scale = q.scale;
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
  check_torus_options(options, n_particles);
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
  RefinementQuantities<Real> q(n_particles);

  std::size_t n = options.min_points_per_dim;
  TorusSums<Real> cumulative(n_particles);  // trapezoid: sums over every node of the level
  TorusSums<Real> fresh_last(n_particles);  // Gauss-Legendre: the last level's sums
  LevelValues<Real> current;
  for (std::size_t level = 0;; ++level) {
    const bool trapezoid = options.rule == TorusRule::trapezoid;
    const std::vector<CircleRule<Real>> rules = level_rules(options.rule, n, level, maps, dims);
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
      current = level_values(cumulative, Real(grid_size(n, dims)));
    } else {
      current = level_values(fresh, Real(1));
    }
    diagnostics.levels = level + 1;
    diagnostics.points_per_dim = n;
    diagnostics.grid_points = grid_size(n, dims);
    q.flatten(current);
    if (dims == 0) {  // one node: exact up to rounding
      std::fill(q.estimate.begin(), q.estimate.end(), Real(0));
      a.converged = true;
      break;
    }
    if (q.refine(level, options.extrapolate_error, tolerance)) {
      a.converged = true;
      break;
    }
    const std::size_t next = 2 * n;
    if (next > options.max_points_per_dim || grid_size(next, dims) > options.max_grid_points) break;
    // Each level has about 2^(N-1) times the previous level's fresh nodes (nested or not).
    if (static_cast<double>(a.evaluations) +
            static_cast<double>(fresh.evaluations) * std::ldexp(1.0, static_cast<int>(dims)) >
        options.max_evaluations)
      break;
    q.previous = q.value;
    n = next;
  }

  if (!a.converged) q.widen_unconverged();

  const TorusSums<Real>& last = options.rule == TorusRule::trapezoid ? cumulative : fresh_last;
  const Real lever = last.weight.value() > 0 ? Real(last.exponent_lever.value() / last.weight.value())
                                            : Real(sqrt(constants.alpha_sum));
  const Real rounding = rounding_ulps(constants, n_particles, lever) * u;
  fill_torus_estimates(a, current, q, rounding);
  if (n_particles >= 2) a.ratio = kinetic_ratio(a.beta_kinetic[0], a.beta_kinetic[1], u);
  diagnostics.mean_weight = {current.mean_weight, q.estimate[0] + rounding * q.scale[0],
                             ErrorKind::estimate};
  add_chain_extras(a, chain);
  return a;
}

// Explicit instantiations live in src/engine/torus/torus.cpp (double, long double, mpfr_real).
#define PENDAVG_TORUS_EXTERN(Real)                                                          \
  extern template Averages<Real> torus_average<Real>(const Chain<Real>&, const Real&,        \
                                                     const TorusOptions&);
PENDAVG_TORUS_EXTERN(double)
PENDAVG_TORUS_EXTERN(long double)
PENDAVG_TORUS_EXTERN(mpfr_real)
#undef PENDAVG_TORUS_EXTERN

}  // namespace pendavg
