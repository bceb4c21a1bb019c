// SPDX-License-Identifier: GPL-3.0-or-later
// engine/qmc/qmc.hpp -- qmc_average: the canonical averages of chains too long for a tensor grid,
// by randomized rank-1 lattice quasi-Monte Carlo over the N absolute angles. The math, the error
// bar and when to prefer another method: src/engine/qmc/README.md.
//
// Equations. Target density over phi (N angles), alpha_j = beta g S_j l_j, z = sum_j alpha_j e^{i phi_j}:
//     p(phi)          proportional to sqrt(det A) prod_j exp(alpha_j cos phi_j)
//     beta <K_i>      = (1/2) E_p[tr X_i]
//     beta^2 Var K_i  = E_p[(tr X_i)^2 + 2 tr X_i^2] / 4 - (beta<K_i>)^2           (Isserlis)
//     <cos phi_j>     = E_p[(I1/I0)(R) cos(phi_j - arg z)]     (Rao-Blackwellized over psi)
// Each ratio is estimated as sum_k W_k f(phi_k) / sum_k W_k over lattice points x_k =
// frac(k z / n + Delta) mapped to angles by a proposal q, with importance weight W = p / q:
//     pivot_sequential (default beyond N = 4): sqrt(det A) = prod_j l_j sqrt(m_j (1 + u_j)),
//         u_1 = 0, u_{j+1} = (m_{j+1}/m_j) (u_j + sin^2(phi_{j+1} - phi_j)) / (u_j + 1);
//         angle j+1 is drawn root to tail from a tabulated law that includes its von Mises factor
//         and its pivot factor sqrt(1 + u_{j+1}) (qmc/pivot_sampler.hpp);
//     von_mises: independent von Mises laws, all of sqrt(det A) in the weight.
// Error bar: R independent random shifts Delta give R estimates; the value is the ratio of the
// totals and its standard error the delete-one-shift jackknife,
//     SE^2 = (R - 1)/R sum_r (theta_(r) - mean)^2,
// reported as `sigmas` standard errors (default: the 99.9% two-sided Student-t quantile for
// R - 1 degrees of freedom, 4.07 for R = 16) plus the rounding budget. A statistical bar, not a
// bound (error kind statistical; include/pendavg/result.hpp says what that promises).
//
// Layout: qmc/options.hpp (QmcOptions), qmc/lattice_rules.hpp (the CBC constructions of the
// generating vectors), qmc/lattice_table.hpp (the built-in vectors), qmc/pivot_sampler.hpp (the
// proposal laws), qmc/shifted_lattice.hpp (the sums of one shifted lattice), qmc/shifts.hpp (the
// shifts, their partition over processes, and the jackknife).
//
// Weights are kept as exp(log W - log_scale) per shift: a log-sum-exp with a finite reference
// (the shift's first finite log W, raised whenever a later one exceeds it by 256), so no weight
// overflows for any N and none underflows into a NaN at any beta: a product of factors that
// would leave the normal range is carried as a sum of logs instead (only there, so runs whose
// products stay normal keep every bit), and a point whose weight is exactly zero never becomes
// the reference. Deterministic for a given seed and bitwise independent of the thread count
// (each shift is summed by one thread, in point order).
//
// When to use it: N >= 5 or so (a tensor grid needs n^(N-1) nodes); for N <= 4 torus_average is
// exact to 1e-13 and much cheaper, and the transfer operator (engine/transfer/) is the
// deterministic choice for long chains. Cost per point: linear in N. The bar is trustworthy while
// effective_sample_fraction stays above ~0.1. The lattices beyond 256 particles must be passed in
// generating_vector (fast_cbc_generating_vector builds one).
#pragma once

#include "engine/numerics/estimates.hpp"
#include "engine/numerics/precision.hpp"
#include "engine/qmc/lattice_rules.hpp"
#include "engine/qmc/lattice_table.hpp"
#include "engine/qmc/options.hpp"
#include "engine/qmc/pivot_sampler.hpp"
#include "engine/qmc/shifted_lattice.hpp"
#include "engine/qmc/shifts.hpp"
#include "engine/torus/reduced_weight.hpp"
#include "pendavg/average.hpp"
#include "pendavg/chain.hpp"
#include "pendavg/result.hpp"

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <vector>

namespace pendavg {

/// Randomized lattice QMC estimate of the averages (see the header comment).
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
  // Nor one whose positive quantity (beta<K_i>, beta^2 Var K_i) has a bar as wide as itself:
  // the points did not resolve it. The Var K of a particle ~1e-12 of its neighbours is heavy-
  // tailed; its shift means are skewed, and such bars missed the exact value by 2-70x.
  const auto unresolved = [](const std::vector<Estimate<Real>>& v) {
    return std::any_of(v.begin(), v.end(),
                       [](const Estimate<Real>& e) { return !(e.error < abs(e.value)); });
  };
  if (unresolved(a.beta_kinetic) || unresolved(a.beta2_kinetic_variance)) a.converged = false;
  return a;
}

// Explicit instantiations live in src/engine/qmc/qmc.cpp (double, long double, mpfr_real).
#define PENDAVG_QMC_EXTERN(Real)                                                            \
  extern template Averages<Real> qmc_average<Real>(const Chain<Real>&, const Real&,          \
                                                   const QmcOptions&);
PENDAVG_QMC_EXTERN(double)
PENDAVG_QMC_EXTERN(long double)
PENDAVG_QMC_EXTERN(mpfr_real)
#undef PENDAVG_QMC_EXTERN

}  // namespace pendavg
