// SPDX-License-Identifier: GPL-3.0-or-later
// engine/double_pendulum/double_pendulum.hpp -- exact thermal averages of the double pendulum
// (N = 2); the public entry point is average() (pendavg/average.hpp). The math of both engines:
// src/engine/double_pendulum/README.md.
//
// Equations. mu_i = m_i / M, a1 = beta M g l1, a2 = beta m2 g l2, t = phi2 - phi1,
// q(t) = mu1 + mu2 sin^2 t, R(t)^2 = a1^2 + a2^2 + 2 a1 a2 cos t, J_s = int_0^pi q^s I0(R) dt:
//     beta<K1> = (mu1/2) J_{-1/2} / J_{1/2},   beta<K2> = 1 - beta<K1>,   (tr X_1 = mu1 / q)
//     beta^2 Var K1 = (3/4) <x^2> - <x>^2 / 4,  x = mu1 / q  (X_1 has rank one: Isserlis)
//     beta<K1> = (mu1/2) sum_n c_n mu2^n R_n / (R_0 - sum_{n>=1} d_n mu2^n R_n)   (the series),
//       R_n = (1/pi) int_0^pi cos^{2n} t I0(R(t)) dt, c_n = (2n-1)!!/(n! 2^n), d_n = c_{n-1}/(2n)
//
// Two engines, one result type (Averages<Real>):
//  * reduced_integral_average -- the exact 1-D integral over t = phi2 - phi1 (src/engine/README.md,
//      'Reduction'), folded onto [0, pi/2]. The default engine, in double and in MPFR. Two
//      evaluations:
//      - exact finite sums: Graf's addition theorem expands the Boltzmann weight
//        I0(R(t)) e^{-(a1+a2)} in cos(2kt) with coefficients from one Miller table of
//        e^{-a} I_m(a) per argument, and the Fourier moments of q(t)^s = (mu1 + mu2 sin^2 t)^s
//        follow from K(k), E(k) by a three-term recurrence. No nodes; O(terms) work. The
//        double engine runs these sums in long double. In MPFR the rows also stop where the
//        moments alone make the tail negligible (|Q_k| <= (k + 1) r^k Q_0, r = e^{-2d}: at large
//        beta the coefficients stay large for ~sqrt(a1 a2 / (a1 + a2)) rows, the moments of a
//        mu1 not small decay long before). Used when the terms are few and the
//        recurrence and cancellation leave the requested accuracy (checked, not assumed);
//      - otherwise nested Clenshaw-Curtis quadrature with nodes placed by a sinh map at t = 0,
//        where q nearly vanishes (distance asinh(sqrt(mu1/mu2)) from the real axis) and the
//        Boltzmann weight peaks, on a range cut where the weight has decayed; per-node weights
//        from Graf sums or scaled Bessel functions (nothing overflows at any beta). The error
//        estimate combines the top Chebyshev coefficients with successive levels. On cut
//        ranges the map acts on sin(t/2) (no sine per node), q^{-3/2} W is integrated by parts
//        (only q^{-1/2}'s branch point remains), and in MPFR, when q's zero lies far inside
//        the weight's peak, [0, T] is split in two sinh-mapped panels. MPFR takes the nodes
//        instead of Graf rows longer than ~10 ln(1/tol) orders, less a tenth of the Bessel
//        tables' Miller steps beyond the rows (cheaper there: ~920 orders at 38 digits, ~1820
//        at 77; the nodes' count grows with the digits, the sums' cost per order not).
//  * series_average -- the paper's series, eq. ave-K1-result, with R_n from the closed-form
//      Bessel derivatives (src/engine/double_pendulum/README.md, 'Series') and a rigorous
//      truncation bound that decides when to stop. Converges geometrically with ratio mu2: prefer
//      the integral when mu1 is small. Evaluated in MPFR (its coefficients leave double's range);
//      gives beta<K_i> only, and takes <cos phi_i>, Var K_i from the integral. O(M^2) work for M
//      terms.
//  * elliptic_high_temperature_limit -- beta -> 0: beta<K1> = (mu1/2) K(k)/E(k), k^2 = mu2
//      (paper eq. aveK1-beta0), declared with every other limit (beta -> 0 and beta -> infinity,
//      N = 2 and any N) in engine/limits/limits.hpp.
//
// Observables: beta<K_i> (K_2 from beta<K1> + beta<K2> = 1), <cos phi_i>, beta^2 Var K_i
// (src/engine/README.md, 'Isserlis': for N = 2 X_1 has rank one, so <K1^2|phi> = 3 <K1|phi>^2).
//
// `digits` is the number of correct significant decimal digits requested (16..1000). For
// Real = double it must be 16 (the double path aims at ~2e-15 relative error). For
// Real = mpfr_real the computation runs at digits + guard_digits.
#pragma once

#include "pendavg/chain.hpp"
#include "engine/numerics/precision.hpp"
#include "pendavg/result.hpp"
#include "pendavg/series.hpp"

#include <array>
#include <cstddef>
#include <vector>

namespace pendavg {

/// The double pendulum's dimensionless parameters (paper eqs. alpha-g, alpha-ell).
template <class Real>
struct DoublePendulumParameters {
  Real mu1, mu2;  ///< m1/M and m2/M, each computed directly from the masses
  Real a1, a2;    ///< alpha_1 = beta M g l1, alpha_2 = beta m2 g l2
};

/// Validates that the chain has two particles and beta > 0 and finite; throws invalid_input.
template <class Real>
DoublePendulumParameters<Real> double_pendulum_parameters(const Chain<Real>& chain,
                                                          const Real& beta);

/// How the reduced integral is evaluated. `automatic`: when a1, a2 are moderate (few Graf
/// terms), exactly, as a finite sum of Graf coefficients times the Fourier moments of q^s
/// (three-term recurrence from K and E; no nodes at all); otherwise by sinh-mapped nested
/// Clenshaw-Curtis quadrature with per-node scaled Bessel functions. A cost model decides
/// (MPFR: the sums while the Graf orders stay below ~10 ln(1/tol), where the nodes get dearer).
/// `quadrature` forces the nodes everywhere (an independent check of the moment path);
/// `graf_sums` forces the exact sums whatever their length (a check of the nodes, and of the
/// cost model), except where they miss the tolerance (cancellation), where the nodes run.
enum class IntegralEvaluation { automatic, quadrature, graf_sums };
struct IntegralOptions {
  IntegralEvaluation evaluation = IntegralEvaluation::automatic;
};

/// The five integrals of the reduced form (t = phi2 - phi1 folded onto [0, pi/2], q(t) = mu1 +
/// mu2 sin^2 t, W(t) = e^{-(a1+a2)} I0(R(t)) + the same at pi - t):
namespace integral {
enum Index : std::size_t {
  J_half,                ///< int q^{1/2} W          (the normalizer)
  J_minus_half,          ///< int q^{-1/2} W         (beta<K1> = (mu1/2) J_{-1/2} / J_{1/2})
  J_minus_three_halves,  ///< int q^{-3/2} W         (<(tr X_1)^2>, the variances)
  C_1,                   ///< int q^{1/2} dW/da_1    (<cos phi_1> = C_1 / J_{1/2})
  C_2,                   ///< int q^{1/2} dW/da_2    (<cos phi_2> = C_2 / J_{1/2})
  count
};
}  // namespace integral

/// Buffers of reduced_integral_average, reused from call to call (one per thread).
template <class Real>
struct IntegralWorkspace {
  /// The integrands at the nodes of this level ([0]) and of the previous one ([1]).
  std::vector<std::vector<std::array<Real, integral::count>>> values;
};

/// The cost model of reduced_integral_average (pure; README "The N = 2 cost model" has the
/// measurements behind its thresholds): whether the exact finite sums run first, and in which
/// number type, and which per-node weights the quadrature uses when they do not (or are
/// rejected: their own error bound decides).
template <class Real>
struct IntegralPlan {
  double ln_inv_tol = 0;  ///< ln(1/tol), tol = the integrals' relative tolerance
  double L_graf = 0;      ///< Graf rows are cut below e^{-L_graf} of their leading term
  double graf_terms = 0;  ///< double's estimate of the Graf terms of a row
  double harmonic = 0;    ///< a1 a2 / (a1 + a2): how sharp the Boltzmann peak at t = 0 is
  Real zero_distance{};   ///< asinh(sqrt(mu1/mu2)): distance of q's zero from the real axis
  /// The exact sums: not tried; in double and, if rejected, in long double; in long double;
  /// at the working precision (MPFR).
  enum class Sums { none, double_then_long_double, long_double, working } sums = Sums::none;
  /// The nodes' weights: per-node Graf rows (short rows) or scaled Bessel functions.
  bool graf_nodes = false;
  std::size_t max_level = 7;  ///< Clenshaw-Curtis levels n = 8 .. 8 2^max_level
};

template <class Real>
IntegralPlan<Real> plan_reduced_integral(const DoublePendulumParameters<Real>& p, int digits,
                                         IntegralEvaluation evaluation);

/// Where the nodes go when they run (pure): the range [0, T] (pi/2 with the reflected node
/// pi - t folded in, or cut where the weight has decayed), the sinh map clustering nodes at
/// t = 0, the level base, and in MPFR the split of [0, T] at t1 (twice the peak's width) into
/// an inner panel by product integration (or nodes) and an outer panel by nodes.
template <class Real>
struct NodePlan {
  Real T{};                   ///< upper end of t
  bool fold = true;           ///< add the reflected node pi - t (T = pi/2)
  bool use_sinh = false;      ///< t = eps sinh(sigma x) (or sin(t/2), half_angle); else t = T x
  bool half_angle = false;    ///< the map acts on sin(t/2) (cut ranges)
  Real eps{}, sigma{};
  bool base12 = false;        ///< levels of 12 2^L intervals instead of 8 2^L
  bool inner_series = false;  ///< MPFR: try product integration over the inner panel first
  bool two_panels = false;    ///< MPFR: otherwise two sinh-mapped panels
  double t1 = 0;              ///< where the panels meet
};

template <class Real>
NodePlan<Real> plan_nodes(const DoublePendulumParameters<Real>& p, const IntegralPlan<Real>& plan);

/// The exact 1-D reduced integral (src/engine/README.md, 'Reduction', 'Isserlis'): beta<K_i>, <cos
/// phi_i>, beta^2 Var K_i. `digits`: 16 for double, 16..1000 for MPFR (computed at digits +
/// guard_digits).
template <class Real>
Averages<Real> reduced_integral_average(const Chain<Real>& chain, const Real& beta, int digits,
                                        const IntegralOptions& options,
                                        IntegralWorkspace<Real>& workspace);
template <class Real>
Averages<Real> reduced_integral_average(const Chain<Real>& chain, const Real& beta,
                                        int digits = 16, const IntegralOptions& options = {});

/// The paper's series (eq. ave-K1-result) for beta<K_i> with its certified truncation bound
/// (error kind bound); <cos phi_i> and Var K_i from the reduced integral. max_terms = 0: no cap.
template <class Real>
Averages<Real> series_average(const Chain<Real>& chain, const Real& beta, int digits = 16,
                              std::size_t max_terms = 0);

}  // namespace pendavg
