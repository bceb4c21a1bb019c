// SPDX-License-Identifier: GPL-3.0-or-later
// engine/limits/limits.hpp -- the beta -> 0 and beta -> infinity limits of the canonical averages,
// for N = 2 and for any N, in one place. The math and when each applies:
// src/engine/limits/README.md. (The low-temperature extrapolation towards the beta -> infinity
// limit, used by the torus and qmc methods at large beta, is engine/limits/low_temperature.hpp.)
//
// Equations.
//   beta -> 0, N = 2 (paper eq. aveK1-beta0), t = phi2 - phi1 uniform, q = 1 - mu2 cos^2 t,
//   k^2 = mu2, k'^2 = mu1:
//       int_0^pi q^{1/2} = 2 E(k),  int_0^pi q^{-1/2} = 2 K(k),  int_0^pi q^{-3/2} = 2 E(k)/mu1,
//       beta<K1> = (mu1/2) K/E,  <tr X_1> = mu1 K/E,  <(tr X_1)^2> = mu1,  <cos phi_i> = 0,
//       beta^2 Var K1 = (3/4) <(tr X_1)^2> - <tr X_1>^2 / 4
//   beta -> 0, any N: exp(-beta U) -> 1, so the angles are distributed as sqrt(det A) on the torus:
//       beta<K_i> -> <tr X_i>_{sqrt det A} / 2,  <cos phi_i> -> 0,
//     which is the torus average of the same chain at g = 0 (at any beta): the tensor trapezoid
//     for N <= max_tensor_particles, qmc beyond. For N = 2 it reproduces the elliptic formula.
//   beta -> infinity, any N: the chain hangs, tr X_i(0) = 1 for every i, so
//       beta<K_i> -> 1/2,  <cos phi_i> -> 1,  beta^2 Var K_i -> tr(X_i(0)^2) / 2   (Isserlis)
//     (1/2 for N = 2: X_1 has rank one). Closed form.
#pragma once

#include "engine/numerics/estimates.hpp"
#include "engine/qmc/qmc.hpp"
#include "engine/torus/torus.hpp"
#include "pendavg/chain.hpp"
#include "pendavg/result.hpp"
#include "pendavg/trace_formula.hpp"

#include <cstddef>
#include <limits>
#include <vector>

namespace pendavg {

/// beta -> 0 for N = 2: beta<K1> = (mu1/2) K(k)/E(k), k^2 = mu2 (paper eq. aveK1-beta0), with K and
/// E from Carlson's forms of the complementary parameter mu1 (numerics/elliptic.hpp), so nothing
/// is lost as mu1 -> 0. Every error a bound (rounding of the elliptic integrals only).
template <class Real>
Averages<Real> elliptic_high_temperature_limit(const Chain<Real>& chain, int digits = 16);

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

// Explicit instantiations live in src/engine/limits/limits.cpp (double, long double, mpfr_real).
#define PENDAVG_LIMITS_EXTERN(Real)                                                         \
  extern template Averages<Real> high_temperature_limit_any<Real>(                          \
      const Chain<Real>&, const TorusOptions&, const QmcOptions&, std::size_t);             \
  extern template Averages<Real> low_temperature_limit_any<Real>(const Chain<Real>&);
PENDAVG_LIMITS_EXTERN(double)
PENDAVG_LIMITS_EXTERN(long double)
PENDAVG_LIMITS_EXTERN(mpfr_real)
#undef PENDAVG_LIMITS_EXTERN

}  // namespace pendavg
