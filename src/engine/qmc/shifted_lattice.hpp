// SPDX-License-Identifier: GPL-3.0-or-later
// engine/qmc/shifted_lattice.hpp -- the sums of one randomly shifted lattice of qmc_average.
//
// Equations (src/engine/qmc/README.md, 'Estimators' and 'Overflow'): over the points
// x_k = frac(k z / n + Delta), k = 0 .. n-1, mapped to angles phi_k by the proposal,
//     W_k = exp(log W_k - log_scale),  log W_k = log(target / proposal) at phi_k,
//     sums  W,  W^2,  W tr X_i,  W ((tr X_i)^2 + 2 tr X_i^2),  W (I1/I0)(R) cos(phi_i - arg z),
// with the traces from the O(N) forward and backward sweeps of the trace formula.
#pragma once

#include "engine/numerics/bessel.hpp"
#include "engine/numerics/compensated_sum.hpp"
#include "engine/qmc/pivot_sampler.hpp"
#include "engine/torus/reduced_weight.hpp"
#include "pendavg/chain.hpp"

#include <boost/math/special_functions/log1p.hpp>

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <limits>
#include <vector>

namespace pendavg::detail::qmc {

using std::abs;
using std::exp;
using std::log;
using std::sqrt;

/// Sums of one shifted lattice: W, W tr X_i, W ((tr X_i)^2 + 2 tr X_i^2), W cos-factor_i, W^2,
/// all scaled by exp(-log_scale) (W = exp(log W - log_scale) stays finite for any N).
template <class Real>
struct ShiftSums {
  detail::CompensatedSum<Real> weight, weight_squared;
  std::vector<detail::CompensatedSum<Real>> trace, second_moment, cosine;
  Real log_scale{0};
  bool scaled = false;  ///< log_scale is set: some point had a finite log W
  explicit ShiftSums(std::size_t n = 0) : trace(n), second_moment(n), cosine(n) {}
  void rescale(const Real& factor) {
    const auto scale = [&](detail::CompensatedSum<Real>& s, const Real& f) {
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

/// The points between two calls of a shift's `poll` (shifted_lattice_sums).
inline constexpr std::size_t lattice_poll_points = 4096;

/// The buffers of one lattice point: the angles' cosines and sines, the pivots u_j of the
/// forward sweep, sin^2 and cos^2 of the relative angles, the traces tr X_i and tr X_i^2, and
/// the conditional law's node values g (grid + 1, the last repeating the first).
template <class Real>
struct LatticePoint {
  std::vector<Real> cphi, sphi, root_u, sin2, cos2, tr, tr2, g;
  LatticePoint(std::size_t n, std::size_t grid)
      : cphi(n), sphi(n), root_u(n), sin2(n), cos2(n), tr(n), tr2(n), g(grid + 1) {}
};

/// The pivot law's draw of angle j (sampler.sequential): the conditional law of v given the
/// angles already drawn, the interpolant of ratio * pivot factor on the grid, inverted exactly at
/// the lattice coordinate u. Returns v; `relative_density` is the law's density at v over its mean.
template <class Real>
Real draw_conditional(const PivotSampler<Real>& sampler, std::size_t j, const Real& u,
                      const Real& u_prev, const Real& inv_grid, LatticePoint<Real>& x,
                      Real& relative_density) {
  const std::size_t grid = sampler.grid;
  std::vector<Real>& g = x.g;
  const Real* ratio = &sampler.node_ratio[j * grid];
  Real* gg = g.data();
  if (j == 0) {
    for (std::size_t q = 0; q < grid; ++q) gg[q] = ratio[q];
  } else {
    const Real* nc = &sampler.node_cos[j * grid];
    const Real* ns = &sampler.node_sin[j * grid];
    const Real a = sampler.mass_ratio[j] / (u_prev + 1), b = a * u_prev + 1;
    const Real cp = x.cphi[j - 1], sp = x.sphi[j - 1];
    for (std::size_t q = 0; q < grid; ++q) {  // vectorizes (qmc.cpp: no errno)
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
  Real v = (Real(static_cast<double>(q)) + tau) * inv_grid;
  if (v >= 1) v -= 1;
  relative_density = (gq + slope * tau) / (total * inv_grid);
  return v;
}

/// The forward sweep of lattice point p: each angle from its lattice coordinate (through the
/// proposal), the pivots u_j, and log W, the log of the importance weight target / proposal.
template <class Real>
Real point_log_weight(const PivotSampler<Real>& sampler, const std::vector<Real>& shift,
                      std::uint64_t p, const std::vector<std::uint32_t>& generator,
                      std::uint64_t mask, const Real& inv_points, const Real& inv_grid,
                      LatticePoint<Real>& x) {
  const std::size_t n = shift.size();
  const Real min_normal = std::numeric_limits<Real>::min();
  const Real max_normal = std::numeric_limits<Real>::max();
  std::vector<Real>& cphi = x.cphi;
  std::vector<Real>& sphi = x.sphi;
  std::vector<Real>& root_u = x.root_u;
  Real log_w = 0, product = 1;
  for (std::size_t j = 0; j < n; ++j) {
    const std::uint64_t kz = (p * generator[j]) & mask;  // k z_j mod 2^m, exact
    Real u = Real(static_cast<double>(kz)) * inv_points + shift[j];
    if (u >= 1) u -= 1;
    Real v = u, relative_density = 1;  // the proposal's density of v over its mean
    const Real u_prev = j > 0 ? root_u[j - 1] : Real(0);
    if (sampler.sequential) v = draw_conditional(sampler, j, u, u_prev, inv_grid, x, relative_density);
    Real one_minus_cos;
    wrapped_cauchy_point(sampler.maps[j], v, cphi[j], sphi[j], one_minus_cos);
    Real factor = best_fisher_ratio(sampler.maps[j], one_minus_cos) / relative_density;
    if (j > 0) {
      const Real sd = sphi[j] * cphi[j - 1] - cphi[j] * sphi[j - 1];  // sin(phi_j - phi_{j-1})
      const Real cd = cphi[j] * cphi[j - 1] + sphi[j] * sphi[j - 1];
      x.sin2[j - 1] = sd * sd;
      x.cos2[j - 1] = cd * cd;
      root_u[j] = sampler.mass_ratio[j] * (u_prev + x.sin2[j - 1]) / (u_prev + 1);
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
  return log_w;
}

/// The backward sweep of the trace formula (pendavg/trace_formula.hpp, node_traces_relative)
/// from the forward sweep's u_j: tr X_i and tr X_i^2 of every particle.
template <class Real>
void point_traces(const std::vector<Real>& m, LatticePoint<Real>& x) {
  const std::size_t n = m.size();
  Real kappa = 0;
  for (std::size_t i = n; i-- > 0;) {
    const Real uu = x.root_u[i];
    Real pivot_ratio = 1, w = 0, w_cos2 = 0;
    if (i + 1 < n) {
      pivot_ratio += kappa * x.sin2[i];
      w = kappa * uu;
      w_cos2 = w * x.cos2[i];
    }
    const Real one_plus_u = 1 + uu, u_plus_w = uu + w;
    const Real inv_d = 1 / (u_plus_w + pivot_ratio);
    x.tr[i] = (one_plus_u + u_plus_w) * inv_d;
    x.tr2[i] = (one_plus_u * one_plus_u + u_plus_w * u_plus_w + 2 * w_cos2) * (inv_d * inv_d);
    if (i > 0) kappa = m[i] * (1 + kappa) / (m[i - 1] * pivot_ratio);
  }
}

/// Adds one point of weight exp(log_w) to the shift's sums. Log-sum-exp with a finite reference:
/// the first finite log W of the shift (`first` until then), raised when a later one exceeds it
/// by 256. A zero weight (log W = -inf) never becomes the reference, and a point of zero
/// proposal density (log W = +inf or NaN, never drawn in exact arithmetic) is left out.
template <class Real>
void add_lattice_point(const detail::torus::WeightConstants<Real>& k, const Real& log_w,
                       const LatticePoint<Real>& x, bool& first, ShiftSums<Real>& sums) {
  const std::size_t n = x.cphi.size();
  const Real infinity = std::numeric_limits<Real>::infinity();
  if (!(log_w > -infinity && log_w < infinity)) return;  // +-inf or NaN: adds nothing
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
    zx += k.alpha[j] * x.cphi[j];
    zy += k.alpha[j] * x.sphi[j];
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
    sums.trace[i].add(weight * x.tr[i]);
    sums.second_moment[i].add(weight * (x.tr[i] * x.tr[i] + 2 * x.tr2[i]));
    sums.cosine[i].add(ratio_w * (x.cphi[i] * zx + x.sphi[i] * zy));
  }
}

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
  LatticePoint<Real> x(n, grid);
  const std::uint64_t mask = points - 1;  // points is a power of two
  const Real inv_points = Real(1) / Real(static_cast<double>(points));
  const Real inv_grid = Real(1) / Real(static_cast<double>(grid));
  const std::vector<Real>& m = chain.masses();
  bool first = true;
  if (complete != nullptr) *complete = true;
  for (std::uint64_t p = 0; p < points; ++p) {
    if (poll != nullptr && p > 0 && p % lattice_poll_points == 0 && !(*poll)(lattice_poll_points)) {
      if (complete != nullptr) *complete = false;
      break;
    }
    const Real log_w = point_log_weight(sampler, shift, p, generator, mask, inv_points, inv_grid, x);
    point_traces(m, x);
    add_lattice_point(k, log_w, x, first, sums);
  }
  return sums;
}

}  // namespace pendavg::detail::qmc
