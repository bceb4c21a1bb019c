// SPDX-License-Identifier: GPL-3.0-or-later
// engine/qmc/pivot_sampler.hpp -- the proposal laws of qmc_average: how a lattice coordinate
// v in [0, 1) becomes an angle, and the tables of the pivot law.
//
// Equations (src/engine/qmc/README.md, 'Proposal laws'):
//     Best-Fisher map:  x = 2 atan(tan(pi (v - 1/2)) (1 - rho)/(1 + rho)),
//                       rho = 2 alpha / (tau + sqrt(2 tau)),  tau = 1 + sqrt(1 + 4 alpha^2)
//     acceptance ratio: exp(alpha (cos x - 1)) (1 + rho^2 - 2 rho cos x) / (1 - rho)^2
//     pivot factor:     sqrt(1 + u_{j+1}),  u_{j+1} = (m_{j+1}/m_j)(u_j + sin^2(phi_{j+1} - phi_j))/(u_j + 1)
//     conditional law:  the periodic piecewise-linear interpolant of ratio * pivot factor on
//                       `grid` equispaced nodes in v, normalized and inverted exactly
#pragma once

#include "engine/numerics/precision.hpp"
#include "pendavg/chain.hpp"

#include <cmath>
#include <cstddef>
#include <vector>

namespace pendavg::detail::qmc {

using std::abs;
using std::exp;
using std::log;
using std::sqrt;

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
    const Real t = tan(detail::pi<Real>() * (u - Real(0.5)));
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
  const Real w = tan(detail::pi<Real>() * (v - Real(0.5))) * map.contraction;
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

}  // namespace pendavg::detail::qmc
