// SPDX-License-Identifier: GPL-3.0-or-later
// The O(N) trace formula per angle node (src/engine/README.md, 'Trace formula', 'Traces in O(N)',
// 'Isserlis'). The recurrences and why they are stable are described in
// include/pendavg/trace_formula.hpp.
#include "pendavg/trace_formula.hpp"

#include "engine/numerics/precision.hpp"

#include <cmath>
#include <string>

namespace pendavg {

template <class Real>
TraceWorkspace<Real>::TraceWorkspace(std::size_t n)
    : n_(n),
      sin2_(n > 0 ? n - 1 : 0),
      cos2_(n > 0 ? n - 1 : 0),
      root_u_(n),
      delta_(n > 0 ? n - 1 : 0) {
  using std::ldexp;
  if (n == 0) throw invalid_input("a trace workspace needs at least one particle");
  out_.trace_X.assign(n, Real(0));
  out_.trace_X_squared.assign(n, Real(0));
  // The determinant product is kept in [2^-256, 2^256]; one factor (l_i^2 d_i, also bounded to
  // that range before it is applied) then cannot push it out of double's exponent range.
  scale_hi_ = ldexp(Real(1), 256);
  scale_lo_ = ldexp(Real(1), -256);
}

template <class Real>
const NodeTraces<Real>& node_traces_relative(const Chain<Real>& chain, const Real* delta,
                                             TraceWorkspace<Real>& ws) {
  using std::cos;
  using std::sin;
  const std::size_t n = chain.size();
  if (ws.n_ != n) {
    throw invalid_input("trace workspace sized for " + std::to_string(ws.n_) +
                        " particles used with a chain of " + std::to_string(n));
  }
  for (std::size_t i = 0; i + 1 < n; ++i) {
    Real s, c;
    if constexpr (is_mpfr_v<Real>) {  // one MPFR call for both (Boost has no sincos)
      mpfr_sin_cos(s.backend().data(), c.backend().data(), delta[i].backend().data(), MPFR_RNDN);
    } else {
      s = sin(delta[i]);
      c = cos(delta[i]);
    }
    ws.sin2_[i] = s;  // squared in place by node_traces_sincos
    ws.cos2_[i] = c;
  }
  return node_traces_sincos(chain, ws.sin2_.data(), ws.cos2_.data(), ws);
}

template <class Real>
const NodeTraces<Real>& node_traces_sincos(const Chain<Real>& chain, const Real* sin_delta,
                                           const Real* cos_delta, TraceWorkspace<Real>& ws) {
  const std::size_t n = chain.size();
  if (ws.n_ != n) {
    throw invalid_input("trace workspace sized for " + std::to_string(ws.n_) +
                        " particles used with a chain of " + std::to_string(n));
  }
  for (std::size_t i = 0; i + 1 < n; ++i) {  // (sin_delta may be ws.sin2_ itself: in place)
    ws.sin2_[i] = sin_delta[i] * sin_delta[i];
    ws.cos2_[i] = cos_delta[i] * cos_delta[i];
  }
  using std::frexp;
  using std::log;
  const std::vector<Real>& m = chain.masses();
  const std::vector<Real>& l = chain.lengths();
  const Real* sin2 = ws.sin2_.data();
  const Real* cos2 = ws.cos2_.data();
  Real* root_u = ws.root_u_.data();
  Real* tr = ws.out_.trace_X.data();
  Real* tr2 = ws.out_.trace_X_squared.data();

  // Forward sweep, root to tail: u_i = m_i r_i, r the root-side compliance seen by particle i
  // along its link direction. Link 1 is pinned, so u_1 = 0.
  //   u_{i+1} = m_{i+1} (u_i + sin^2 delta_i) / (m_i (u_i + 1)).
  root_u[0] = 0;
  for (std::size_t i = 0; i + 1 < n; ++i)
    root_u[i + 1] = m[i + 1] * (root_u[i] + sin2[i]) / (m[i] * (root_u[i] + 1));

  // Backward sweep, tail to root: kappa = k_{i+1} / m_i, k the articulated inertia of the links
  // beyond i seen along link i+1 (k_{N+1} = 0). d_i / m_i = 1 + kappa sin^2 delta_i is the pivot
  // of a tail-first LDL^T of A (over l_i^2 m_i), and k_i = m_i (1 + kappa) / (d_i / m_i).
  Real kappa = 0;
  Real det_product = 1;  // prod l_i^2 d_i = det A, times 2^(-det_exponent)
  long det_exponent = 0;
  int e = 0;
  for (std::size_t i = n; i-- > 0;) {
    const Real u = root_u[i];
    Real pivot_ratio = 1;  // d_i / m_i
    Real w = 0;            // k_{i+1} r_i = kappa u
    Real w_cos2 = 0;
    if (i + 1 < n) {
      pivot_ratio += kappa * sin2[i];
      w = kappa * u;
      w_cos2 = w * cos2[i];
    }
    const Real one_plus_u = 1 + u;
    const Real u_plus_w = u + w;
    const Real inv_d = 1 / (u_plus_w + pivot_ratio);
    tr[i] = (one_plus_u + u_plus_w) * inv_d;
    tr2[i] = (one_plus_u * one_plus_u + u_plus_w * u_plus_w + 2 * w_cos2) * (inv_d * inv_d);

    Real factor = l[i] * l[i] * m[i] * pivot_ratio;
    if (!(factor <= ws.scale_hi_ && factor >= ws.scale_lo_)) {
      // Rare: extreme units. The product may have left the range (l_i^2 underflows for
      // l_i < 1e-154): take it apart into mantissas and a binary exponent.
      int el = 0, em = 0, ep = 0;
      const Real ml = frexp(l[i], &el), mm = frexp(m[i], &em), mp = frexp(pivot_ratio, &ep);
      factor = frexp(ml * ml * mm * mp, &e);
      det_exponent += e + 2L * el + em + ep;
    }
    det_product *= factor;
    if (!(det_product <= ws.scale_hi_ && det_product >= ws.scale_lo_)) {
      det_product = frexp(det_product, &e);
      det_exponent += e;
    }
    if (i > 0) kappa = m[i] * (1 + kappa) / (m[i - 1] * pivot_ratio);
  }
  ws.out_.log_sqrt_det_A = (log(det_product) + Real(det_exponent) * log(Real(2))) / 2;
  return ws.out_;
}

template <class Real>
const NodeTraces<Real>& node_traces(const Chain<Real>& chain, const Real* phi,
                                    TraceWorkspace<Real>& ws) {
  const std::size_t n = chain.size();
  if (ws.n_ != n) {
    throw invalid_input("trace workspace sized for " + std::to_string(ws.n_) +
                        " particles used with a chain of " + std::to_string(n));
  }
  Real* delta = ws.delta_.data();
  for (std::size_t i = 0; i + 1 < n; ++i) delta[i] = phi[i + 1] - phi[i];
  return node_traces_relative(chain, delta, ws);
}

template <class Real>
std::vector<Real> diagonal_approximation(const Chain<Real>& chain) {
  using std::isfinite;
  const std::size_t n = chain.size();
  std::vector<Real> beta_kinetic(n);
  Real inverse_tail_sum = 0;  // sum_{j <= i} 1 / S_j
  for (std::size_t i = 0; i < n; ++i) {
    inverse_tail_sum += 1 / chain.tail_mass(i);
    beta_kinetic[i] = chain.mass(i) * inverse_tail_sum / 2;
    if (!isfinite(beta_kinetic[i])) {
      // Tail masses near the bottom of the range (1/S_j overflows): the same sum as mass
      // ratios m_i / S_j <= 1 (S_j >= m_i for j <= i), which cannot overflow.
      Real ratios = 0;
      for (std::size_t j = 0; j <= i; ++j) ratios += chain.mass(i) / chain.tail_mass(j);
      beta_kinetic[i] = ratios / 2;
    }
  }
  return beta_kinetic;
}

#define PENDAVG_INSTANTIATE_TRACE_FORMULA(Real)                               \
  template class PENDAVG_EXPORT TraceWorkspace<Real>;                         \
  template PENDAVG_EXPORT const NodeTraces<Real>& node_traces<Real>(          \
      const Chain<Real>&, const Real*, TraceWorkspace<Real>&);                \
  template PENDAVG_EXPORT const NodeTraces<Real>& node_traces_relative<Real>( \
      const Chain<Real>&, const Real*, TraceWorkspace<Real>&);                \
  template PENDAVG_EXPORT const NodeTraces<Real>& node_traces_sincos<Real>(   \
      const Chain<Real>&, const Real*, const Real*, TraceWorkspace<Real>&);   \
  template PENDAVG_EXPORT std::vector<Real> diagonal_approximation<Real>(const Chain<Real>&);

PENDAVG_INSTANTIATE_TRACE_FORMULA(double)
PENDAVG_INSTANTIATE_TRACE_FORMULA(long double)
PENDAVG_INSTANTIATE_TRACE_FORMULA(mpfr_real)

#undef PENDAVG_INSTANTIATE_TRACE_FORMULA

}  // namespace pendavg
