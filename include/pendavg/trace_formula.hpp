// SPDX-License-Identifier: GPL-3.0-or-later
// pendavg/trace_formula.hpp -- the trace formula at one angle node, in O(N) (src/engine/README.md,
// 'Trace formula', 'Traces in O(N)', 'Isserlis').
//
// What it computes. For one configuration phi of an N-link chain (paper eq. a-ij):
//   * log sqrt(det A(phi))                      -- the weight of the node (eq. ave-Ki-linear-pi-
//                                                  trace-varphi), as a log so that N = 10^4 does
//                                                  not overflow;
//   * tr X_i = tr(A^(i) A^{-1}), i = 1..N       -- 2 beta <K_i | phi>  (trace formula);
//   * tr(X_i X_i), i = 1..N                     -- with the above, beta^2 <K_i^2 | phi>
//                                                  = [(tr X_i)^2 + 2 tr(X_i^2)] / 4
//                                                  (Isserlis).
// The canonical kinetic energies need no node work: (A^{-1} A)_ii = 1, so
// beta <K_i^(c) | phi> = 1/2 at every node (src/engine/README.md, 'Equipartition'; paper eq.
// ke-canonical-i).
//
// How. Given the angles the momenta are Gaussian, and so are the Cartesian velocities v_i. The
// chain is a tree: v_i = v_{i-1} + l_i phidot_i t_i with t_i = (cos phi_i, sin phi_i). Eliminating
// the joint rates one at a time gives two sweeps of scalar recurrences (Featherstone's
// articulated-body inertias, in the plane each reduces to one number per link):
//   backward (tail to root), k_{N+1} = 0:
//       d_i = m_i + k_{i+1} sin^2(phi_{i+1} - phi_i),   k_i = m_i (m_i + k_{i+1}) / d_i,
//   forward  (root to tail), the root-side compliance r_1 = 0 (link 1 is pinned):
//       r_{i+1} = (m_i r_i + sin^2(phi_{i+1} - phi_i)) / (m_i (m_i r_i + 1)).
// With u = m_i r_i, w = k_{i+1} r_i, D = u + w + d_i/m_i and c = cos(phi_{i+1} - phi_i),
//       det A    = prod_i l_i^2 d_i                (the pivots of a tail-first LDL^T of A),
//       tr X_i   = (2u + 1 + w) / D,
//       tr X_i^2 = (2u^2 + 2u + 1 + w^2 + 2uw + 2w c^2) / D^2.
// Every quantity is a ratio of sums of non-negative terms, so nothing cancels: each trace is
// accurate to a few ulps relative, even when it is tiny (a light particle between heavy ones).
// The recurrences are contractions (d log k_i / d log k_{i+1} and d log r_{i+1} / d log r_i are
// c^2-weighted fractions in [0, 1)), so rounding errors are damped, not amplified, along the
// chain. The recurrences are carried in mass ratios (k_{i+1}/m_i and m_i r_i), so they neither
// overflow nor underflow for any N; the determinant is a product renormalized by powers of two
// and its log is taken once. sin^2 is formed from sin, never as 1 - cos^2.
//
// The same quantities follow from src/engine/README.md, 'Traces in O(N)' (G = H^{-1}, H = C M^{-1}
// C^T tridiagonal); that form is kept in tests/oracle/dense_traces.hpp as a check. Its trace
// formula 2 - [G_ii + G_{i+1,i+1} - 2 c G_{i,i+1}] / m_i cancels when tr X_i << 1, losing about
// log10(1 / tr X_i) digits, which is why the library uses the articulated-body sweeps instead.
//
// Accuracy (tests/engine/numerics/test_trace_formula.cpp, against the dense oracle in 50-digit MPFR): traces,
// squared traces and log sqrt(det A) within ~8 ulps for random chains (masses over 1e-3..1e3,
// N <= 12) when the relative angles are given exactly. At N = 10^4 the traces sum to N within
// ~1e-17 relative and log sqrt(det A) ~ 1e4 is off by ~5e-13 absolute. From absolute angles
// the rounding of phi_{i+1} - phi_i adds a relative error of about
// eps |phi| / |phi_{i+1} - phi_i| (observed up to ~4e-14); use node_traces_relative when the
// quadrature variables are the relative angles. Only mass ratios and relative angles enter
// the traces; the lengths enter det A only.
//
// When to use it: at every angle node of a torus quadrature or (Q)MC sample of the N-link chain.
// Cost: N - 1 sincos calls and 3N divisions per node (about 20-30 ns per particle in double),
// no allocation in double (all buffers live in the TraceWorkspace). For N = 2 the closed forms of
// double_pendulum.hpp are cheaper. long double is instantiated here, but model.cpp must also
// instantiate Chain<long double> before a caller can build such a chain.
#pragma once

#include "pendavg/export.hpp"
#include "pendavg/chain.hpp"

#include <cstddef>
#include <vector>

namespace pendavg {

/// The node quantities. Index i (0-based) is particle i + 1 of the paper.
template <class Real>
struct NodeTraces {
  Real log_sqrt_det_A{};              ///< log sqrt(det A(phi)), A from eq. a-ij (lengths included)
  std::vector<Real> trace_X;          ///< tr(A^(i) A^{-1}) = 2 beta <K_i | phi>; sums to N
  std::vector<Real> trace_X_squared;  ///< tr(A^(i) A^{-1} A^(i) A^{-1})
};

/// Every buffer node_traces needs, sized once for chains of N particles (Pinocchio's Data).
/// Not thread-safe: use one workspace per thread.
template <class Real>
class PENDAVG_EXPORT TraceWorkspace {
 public:
  explicit TraceWorkspace(std::size_t n);
  explicit TraceWorkspace(const Chain<Real>& chain) : TraceWorkspace(chain.size()) {}

  std::size_t size() const { return n_; }
  /// The result of the last node_traces call.
  const NodeTraces<Real>& result() const { return out_; }

 private:
  template <class R>
  friend const NodeTraces<R>& node_traces(const Chain<R>&, const R*, TraceWorkspace<R>&);
  template <class R>
  friend const NodeTraces<R>& node_traces_relative(const Chain<R>&, const R*, TraceWorkspace<R>&);
  template <class R>
  friend const NodeTraces<R>& node_traces_sincos(const Chain<R>&, const R*, const R*,
                                                 TraceWorkspace<R>&);

  std::size_t n_;
  NodeTraces<Real> out_;
  std::vector<Real> sin2_;      ///< sin^2(phi_{i+1} - phi_i), N - 1 entries
  std::vector<Real> cos2_;      ///< cos^2(phi_{i+1} - phi_i)
  std::vector<Real> root_u_;    ///< u_i = m_i r_i (forward sweep), N entries
  std::vector<Real> delta_;     ///< phi_{i+1} - phi_i, for the phi overload
  Real scale_hi_, scale_lo_;    ///< renormalization bounds of the determinant product
};

/// The node quantities at the configuration phi (N absolute angles from the downward vertical).
/// Returns a reference into `ws`, valid until its next use. Throws invalid_input if the
/// workspace was sized for another N.
template <class Real>
PENDAVG_EXPORT const NodeTraces<Real>& node_traces(const Chain<Real>& chain, const Real* phi,
                                                   TraceWorkspace<Real>& ws);

/// The same from the N - 1 relative angles delta_i = phi_{i+1} - phi_i (A depends on nothing
/// else). Use it when the quadrature runs over relative angles (src/engine/README.md, 'Reduction').
template <class Real>
PENDAVG_EXPORT const NodeTraces<Real>& node_traces_relative(const Chain<Real>& chain,
                                                            const Real* delta,
                                                            TraceWorkspace<Real>& ws);

/// The same from sin delta_i and cos delta_i (N - 1 each). The traces need only these, and a
/// quadrature can form them more accurately than from a rounded angle: at delta = pi - eps the
/// angle's rounding (u pi) is a relative error u pi / eps in sin delta, which a light particle
/// (traces varying on sin^2 delta ~ m_i / S_{i+1}) turns into ~1e-12 relative in its average.
template <class Real>
PENDAVG_EXPORT const NodeTraces<Real>& node_traces_sincos(const Chain<Real>& chain,
                                                          const Real* sin_delta,
                                                          const Real* cos_delta,
                                                          TraceWorkspace<Real>& ws);

/// The paper's diagonal approximation, eq. ke-linear-tave-1
/// (src/engine/README.md, 'Diagonal approximation'):
///     beta <K_i>  ~  (m_i / 2) sum_{j <= i} 1 / S_j.
/// It is exact in no limit; report it next to an exact value, never instead of it.
template <class Real>
PENDAVG_EXPORT std::vector<Real> diagonal_approximation(const Chain<Real>& chain);

}  // namespace pendavg
