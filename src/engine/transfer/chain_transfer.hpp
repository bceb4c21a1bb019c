// SPDX-License-Identifier: GPL-3.0-or-later
// engine/transfer/chain_transfer.hpp -- near-exact canonical averages of long chains (N = 5..1024 and
// beyond) by a transfer operator along the chain (src/engine/README.md, 'Trace formula',
// 'Isserlis'; README "Large N"; paper eq. ave-Ki-linear-pi-trace-varphi). The public entry point is
// average() with method transfer (pendavg/average.hpp), which automatic picks for N >= 5.
//
// What it computes. For an N-link chain at inverse temperature beta, per particle i:
//   * beta <K_i>      = (1/2) <tr X_i>_w                                (trace formula),
//   * beta^2 Var K_i  = <(tr X_i)^2 + 2 tr X_i^2>_w / 4 - (beta<K_i>)^2 (Isserlis),
//   * <cos phi_i>,
// over the N-torus of absolute angles with the weight
// w = sqrt(det A) prod_j exp(alpha_j cos phi_j), alpha_j = beta g S_j l_j, each with an error
// estimate from refinement (kind estimate).
//
// Why it works (README, "Large N"): the weight is a Markov chain in one extra number. The
// root-first elimination of the joint rates (trace_formula.hpp, forward sweep) gives
//     sqrt(det A) = prod_j l_j sqrt(m_j (1 + u_j)),   u_1 = 0,
//     u_{j+1} = (m_{j+1} / m_j) (u_j + sin^2(phi_{j+1} - phi_j)) / (u_j + 1),
// so w is a product of factors that each depend on the state (phi_j, u_j) and the next angle.
// Every average then follows from messages on that two-number state:
//   * backward messages (tail to root), functions of (phi_j, u_j):
//       M0_j = E[W_j | phi_j, u_j],  M1_j = E[W_j d_u log W_j],  M2_j = E[W_j (d_u log W_j)^2],
//       M3_j = E[W_j d_u^2 log W_j],  W_j = the weight of particles j..N given (phi_j, u_j);
//     each is an integral over phi_{j+1} of the next messages at u_{j+1}(u_j, phi_{j+1} - phi_j);
//   * forward measures (root to tail): F_j = the weight of particles 1..j as a measure in
//     (phi_j, u_j), pushed forward link by link (the transpose of the backward recursion).
// The node quantities are mass derivatives: with u_i = m_i r_i, the kinetic masses enter W only
// through the factor sqrt(m_i (1 + u_i)) and the step u_i -> u_{i+1}, so
//     tr X_i     = d log det A / d log m_i
//                = 1 + u_i/(1 + u_i) + 2 Q_i d_{u_{i+1}} log W_{i+1},
//     tr X_i^2   = tr X_i - d^2 log det A / d (log m_i)^2,
//     Q_i        = d u_{i+1} / d log m_i = -(m_{i+1}/m_i) (u_i^2 + s_i^2 (1 + 2 u_i)) / (1 + u_i)^2,
// (s_i = sin(phi_{i+1} - phi_i)), so <tr X_i>, <(tr X_i)^2> and <tr X_i^2> are pairings of F_i
// with the messages at i + 1. A forward and a backward sweep give every particle's averages.
// The messages are carried with the u-derivative of the factor sqrt(m (1 + u)) split off (M1..M3
// become N1 = E[W (1+u) rho], N2 = E[W (1+u)^2 rho^2], N3 = E[W (1+u)^2 d_u rho], rho the
// u-derivative of log W less that factor's): for a very light particle Q_i ~ -u_{i+1} ~ -1/m_i
// and the form above cancels 1 against ~-1 to leave tr X_i ~ m_i log(1/m_i) (all digits lost at
// m_i ~ 1e-12); split, tr X_i = p + 2 (Q_i/(1 + u_{i+1})) (1 + u_{i+1}) rho_{i+1} with p > 0 a sum
// of positive terms (chain_transfer.cpp, LinkSums).
//
// Discretization. phi_j: n nodes per angle, the periodic trapezoid rule (the Gaussian rule on
// the circle) when alpha_j is moderate, else the trapezoid on the window |phi_j| <= L_j outside
// which exp(alpha_j (cos phi_j - 1)) is below the roundoff (the marginal of phi_j is bounded by a
// constant times that factor: the conditional factor sqrt(D_j) of phi_j varies by at most
// sqrt((1 + m_j/m_{j-1}) S_j/m_j)). u_j in [0, m_j / m_{j-1}]: m Chebyshev-Lobatto nodes in
// v = log(u + eps_j), eps_j = m_j / S_j. The messages are analytic in u off the cut
// [-1, -eps_j], which the log maps to the lines Im v = +-pi, so Chebyshev interpolation in v
// converges geometrically with a rate that degrades only like log(S_j / m_{j-1}). Where
// m_j / m_{j-1} > 4 (up to 1e12 after a very light particle) the coordinate is instead
// v = log((u + eps_j) / (1 + u)): the messages over their envelopes are analytic in 1/(1 + u) at
// u = infinity, the cut still maps to Im v = +-pi, and the range log(S_j / m_j) no longer grows
// with m_j / m_{j-1}. The forward measures are only ever paired with the (smooth) messages, so
// their nodal weights are the transposed interpolation. Links j -> j+1 after which a heavy mass
// follows ((m_{j+1} + 2 m_{j+2}) / m_j > 4) couple phi_j and phi_{j+1} through a kink of width
// w = (m_j / S_{j+1})^1/2 along delta = phi_{j+1} - phi_j = 0 (and pi): there the integral runs
// over delta on nodes clustered at 0 and pi, and the next messages times
// exp(alpha_{j+1} cos phi_{j+1}) are interpolated trigonometrically at phi_j + delta. The nodes:
// an entire map of the trapezoid for w >= 1e-2; below, Gauss-Legendre panels in s with
// |delta| (or pi - |delta|) = w sinh(s), which see every singularity of the kink (at imaginary
// distances w..1) at Im s = pi/2, so their count grows like log(1/w): a particle of mass 1e-12
// among unit masses costs ~4x the nodes of an ordinary link, not ~1e6 x.
// Cost: O(n^2 m^2) per link and sweep (O(n^2 n_delta m) for a relative-angle link, n_delta = n
// or ~ 8 n log10(1/w) / 4 for the panels), O(N) in all.
// Large beta needs nothing special: the windows shrink like alpha_j^-1/2 with the Boltzmann
// peaks, so the same n resolves any beta up to the double range of alpha_j.
//
// Refinement and error estimate (ErrorKind::estimate, not a bound), per quantity:
//   * levels (n_k, m_k), n_k = 16, 24, 32, 40, 56, 72, ... (~1.25x); m_k from the predicted
//     Chebyshev rate of the slowest pivot range, so that the pivot error stays far below the
//     angle error and follows it down the ladder, and at least m_{k-1} + 1;
//   * the reported value is the last level but one, v_{L-1}, verified by the last: its error is
//     f d, d = |v_L - v_{L-1}| (at least 1% of the largest difference of the same observable
//     nearby: a sign change of one quantity's error cannot hide it), f = 1 / (1 - rho) in [2, 10],
//     rho = D_L / D_{L-1} the last contraction of the largest differences, over the whole chain
//     and over the particles near the quantity's own (the larger); the run stops once the
//     errors are within the tolerance and the ladder contracts (rho <= 1/2 measured over three
//     levels at least);
//   * plus a rounding budget from the sums of |terms| of each node pairing: the pairings cancel
//     for light particles (tr X_i = 1 + u/(1+u) + 2 Q S with 2 Q S ~ -1), so there the rounding,
//     not the discretization, limits the relative accuracy of beta<K_i> and Var K_i;
//     converged = false when an error exceeds the tolerance (e.g. that budget does).
// Progress and stop (TransferOptions::control) are polled between links: a run stopped after two
// levels reports the first of them, verified by the second (interrupted, not converged).
// Measured coverage and pessimism: README "Large N"; tests/engine/transfer/test_transfer.cpp.
//
// When to prefer something else. N = 2: the 1-D integral (double_pendulum.hpp) is faster and
// exact. N = 3, 4: torus_average is exact to 1e-13 in milliseconds to a fraction of a second,
// robust for light particles, and is the independent check; the transfer operator's rounding
// budget stops it near 1e-13. The microcanonical weight (E - U)_+^{N/2-1} is not a product over the links: use
// microcanonical.hpp. A very light particle (m_j down to 1e-12 of its neighbours, at the root,
// inside or at the tail) converges in about the work of an ordinary chain (tests/engine/transfer/test_transfer.cpp,
// bench_large_n light); its beta<K_j> ~ m_j log(1/m_j) keeps ~1e-12 relative accuracy, but the
// pairings still cancel by up to S_{j+1}/m_{j+1} (the tail's inertia over the next particle's,
// squared for the variance): at N = 64 a light root's Var K carries ~1e-10 relative rounding,
// which the budget reports (converged = false at a tighter tolerance). Two adjacent light
// particles widen the next pivot range again (log(S_j / m_j) with m_j light): slow, not wrong.
//
// Precision: generic over Real (double and long double instantiated). Thread-parallel over the
// angle nodes of each link (options.threads; a link is split only when its work is large enough
// to pay for the fork); the results are bitwise independent of the thread count (every sum is
// taken in a fixed order).
#pragma once

#include "pendavg/chain.hpp"
#include "pendavg/result.hpp"

#include <cstddef>
#include <limits>
#include <vector>

namespace pendavg {

/// Options of chain_transfer_average.
struct TransferOptions {
  /// Target: every quantity's error estimate at most `tolerance` (beta<K_i>: relative to itself;
  /// beta^2 Var K_i: relative to beta^2 <K_i^2>; <cos phi_i>: absolute).
  double tolerance = 1e-10;
  std::size_t angle_nodes = 0;        ///< n of the first level; 0: automatic (16)
  std::size_t pivot_nodes = 0;        ///< fixed m at every level; 0: automatic (see the .cpp)
  std::size_t max_angle_nodes = 512;  ///< refinement stops (converged = false) beyond it
  std::size_t max_pivot_nodes = 96;   ///< m never exceeds it
  /// Work cap: once a level is verified, refinement stops (converged = false unless within the
  /// tolerance) before a level whose kernel evaluations would bring the run's total beyond it.
  double max_kernel_evaluations = std::numeric_limits<double>::infinity();
  int threads = 1;                    ///< OpenMP threads (results independent of it)
  /// Progress (the fraction of the current level's two sweeps) and stop, polled between links:
  /// stopped after two finished levels, the run returns the last of them with its ladder error
  /// (interrupted, not converged); before, it throws `interrupted`. Null: neither.
  const RunControl* control = nullptr;
};

/// One resolution, no error estimate: the building block of chain_transfer_average and of the
/// convergence studies (tests/bench/bench_large_n.cpp). angle_nodes >= 4 (even), pivot_nodes >= 3.
template <class Real>
struct TransferLevel {
  std::vector<Real> beta_kinetic, cos_angle, beta2_kinetic_variance, beta2_kinetic_second_moment;
  /// Per quantity, the sum of the absolute values of the terms it is made of (the node
  /// pairings cancel for light particles): its rounding error is ~ the roundoff times this.
  std::vector<Real> beta_kinetic_rounding_scale, cos_angle_rounding_scale,
      beta2_kinetic_variance_rounding_scale;
  double kernel_evaluations = 0;  ///< (phi_j, u_j, phi_{j+1}) triples of both sweeps
};

/// `control` (optional): progress over the two sweeps, and a stop request polled between links
/// (throws `interrupted`).
template <class Real>
TransferLevel<Real> chain_transfer_level(const Chain<Real>& chain, const Real& beta,
                                         std::size_t angle_nodes, std::size_t pivot_nodes,
                                         int threads = 1, const RunControl* control = nullptr);

/// The pivot nodes m the refinement takes for a level whose expected relative error is
/// `expected_error`: the predicted pivot error rho^-m (Chebyshev rate of the slowest pivot range)
/// a tenth of it, plus a margin (chain_transfer.cpp); before the cap max_pivot_nodes; 3 for N = 1.
template <class Real>
std::size_t transfer_pivot_nodes(const Chain<Real>& chain, double expected_error);

/// The transfer operator's domain: beta valid and every alpha_j = beta g S_j l_j finite (any
/// beta within the double range works; there is no stiffness limit). Throws invalid_input
/// otherwise. chain_transfer_level checks it; check_average (pendavg/average.hpp) calls it to
/// refuse a sweep's row before any work.
template <class Real>
void check_transfer_domain(const Chain<Real>& chain, const Real& beta);

/// The averages to options.tolerance by refinement (see the header comment): method transfer,
/// work unit nodes (kernel evaluations over all levels), Averages::transfer the final
/// resolution. Throws invalid_input for a bad beta or options.
template <class Real>
Averages<Real> chain_transfer_average(const Chain<Real>& chain, const Real& beta,
                                      const TransferOptions& options = {});

}  // namespace pendavg
