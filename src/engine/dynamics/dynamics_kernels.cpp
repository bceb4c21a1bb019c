// SPDX-License-Identifier: GPL-3.0-or-later
// The constrained-dynamics kernels (states, observables, RATTLE stages, compositions, BAOAB,
// runs, the Poincare section); see include/pendavg/dynamics.hpp. This file is compiled once per
// instruction set (CMake: PENDAVG_DYNAMICS_ISA names the namespace, e.g. dynamics_base for
// baseline x86-64 and dynamics_x86_64_v3 for AVX2 + FMA); src/engine/dynamics/dynamics.cpp picks one at
// run time.
//
// The wider instruction set is switched on by a pragma after the includes, not by -march for the
// whole file: the library templates this file instantiates (std::vector, Eigen, ...) are then
// compiled for baseline x86-64 in every object, so whichever copy the linker keeps is safe to run
// on any CPU; only the functions of this file's own namespace use AVX2 and FMA (checked by
// tests/consumer/isa.sh).
#include "engine/dynamics/dynamics_kernels.hpp"

#include "domain.hpp"
#include "engine/numerics/parallel.hpp"
#include "engine/numerics/text.hpp"

#include <Eigen/Dense>
#include <boost/math/constants/constants.hpp>

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstddef>
#include <limits>
#include <random>
#include <string>

#ifndef PENDAVG_DYNAMICS_ISA
#error "compile with -DPENDAVG_DYNAMICS_ISA=<namespace> (see CMakeLists.txt)"
#endif
#if defined(PENDAVG_DYNAMICS_TARGET_X86_64_V3)
#pragma GCC target("arch=x86-64-v3")
#endif

// The blocking averager, in this instruction set's namespace (it runs at every step).
#define PENDAVG_BLOCKING_NAMESPACE PENDAVG_DYNAMICS_ISA
#include "engine/dynamics/blocking.hpp"

namespace pendavg::PENDAVG_DYNAMICS_ISA {


namespace {

using std::abs;
using std::atan2;
using std::cos;
using std::sin;
using std::sqrt;

template <class Real>
void check_finite_vector(const std::vector<Real>& v, const char* what) {
  for (const Real& x : v)
    if (!std::isfinite(static_cast<double>(x)))
      throw invalid_input(std::string(what) + " must be finite");
}

// ---------------------------------------------------------------- the link frame
//
// The kernels work on the links r_i = x_i - x_{i-1} and the link velocities u_i = v_i - v_{i-1}
// (x_{-1} = v_{-1} = 0, the pivot), kept in the workspace as separate x and y arrays with one
// zero pad at each end (link i at index i + 1). Every neighbour access is then branch-free and
// the loops vectorize; only the two tridiagonal sweeps are serial. Gravity is uniform, so its
// kick changes u_0 alone. simulate() keeps the frame across steps; the public step functions
// load it from the state and store it back.

/// Pointers to the padded link frame: index -1 and n are the zero pads. A loop that reads
/// index i - 1 counts with a signed i: with std::size_t, p[i - 1] at i = 0 is p + SIZE_MAX, an
/// overflowing (undefined) pointer, where p[-1] is the pad.
template <class Real>
struct LinkFrame {
  Real* rx;
  Real* ry;
  Real* ux;
  Real* uy;
  const Real* im;  // 1/m_i, im[-1] = im[n] = 0
  Real* s;         // multipliers, s[-1] = s[n] = 0
  explicit LinkFrame(DynamicsWorkspace<Real>& ws)
      : rx(ws.link_x.data() + 1),
        ry(ws.link_y.data() + 1),
        ux(ws.rate_x.data() + 1),
        uy(ws.rate_y.data() + 1),
        im(ws.inv_mass_padded.data() + 1),
        s(ws.multiplier.data() + 1) {}
};

template <class Real>
void load_links(const ChainState<Real>& st, DynamicsWorkspace<Real>& ws) {
  const std::size_t n = ws.size();
  LinkFrame<Real> lf(ws);
  const Real* x = st.position.data();
  const Real* p = st.momentum.data();
  Real xprev = 0, yprev = 0, vxprev = 0, vyprev = 0;
  for (std::size_t i = 0; i < n; ++i) {
    lf.rx[i] = x[2 * i] - xprev;
    lf.ry[i] = x[2 * i + 1] - yprev;
    const Real vx = p[2 * i] * lf.im[i], vy = p[2 * i + 1] * lf.im[i];
    lf.ux[i] = vx - vxprev;
    lf.uy[i] = vy - vyprev;
    xprev = x[2 * i];
    yprev = x[2 * i + 1];
    vxprev = vx;
    vyprev = vy;
  }
}

template <class Real>
void store_links(DynamicsWorkspace<Real>& ws, ChainState<Real>& st) {
  const std::size_t n = ws.size();
  LinkFrame<Real> lf(ws);
  st.position.resize(2 * n);
  st.momentum.resize(2 * n);
  Real x = 0, y = 0, vx = 0, vy = 0;
  for (std::size_t i = 0; i < n; ++i) {
    x += lf.rx[i];
    y += lf.ry[i];
    vx += lf.ux[i];
    vy += lf.uy[i];
    st.position[2 * i] = x;
    st.position[2 * i + 1] = y;
    st.momentum[2 * i] = ws.mass[i] * vx;
    st.momentum[2 * i + 1] = ws.mass[i] * vy;
  }
}

/// Continuants are renormalized when they leave [1/limit, limit] (a power of two far inside
/// the exponent range of Real).
template <class Real>
constexpr Real continuant_limit() {
  return Real(1.157920892373162e77);  // 2^256
}

/// u_0 -= tau g y-hat: the kick of uniform gravity (every v_k changes by the same amount). The
/// constraint impulse that belongs to it (tau mu, mu the multiplier) is left to the next
/// position or velocity stage, which absorbs every normal momentum component; the workspace
/// counts that pending kick time to guess the next stage's multipliers.
template <class Real>
void gravity_kick(const Chain<Real>& chain, DynamicsWorkspace<Real>& ws, const Real& tau) {
  ws.pending_kick_time += tau;
  ws.rate_y[1] -= tau * chain.gravity();
}

/// One direction of the twisted elimination below: the continuants theta and the scaled
/// right-hand side z of the rows eliminated so far (see solve_tridiagonal_twisted).
template <class Real>
struct EliminationSweep {
  Real theta1 = 1, theta2 = 0, z = 0, away_prev = 0;
  /// Eliminates a row with diagonal d, coupling `toward` to the row eliminated before it and
  /// `away` to the next one, right-hand side r: x = rhs - coef x_next.
  void row(const Real& d, const Real& toward, const Real& away, const Real& r, Real& coef,
           Real& rhs) {
    Real theta = d * theta1 - (toward * away_prev) * theta2;
    z = r * theta1 - toward * z;
    const Real inv = 1 / theta;
    coef = away * theta1 * inv;
    rhs = z * inv;
    away_prev = away;
    if (abs(theta) > continuant_limit<Real>() || abs(theta) < 1 / continuant_limit<Real>()) {
      const Real scale = 1 / abs(theta);  // any scale works: only ratios are used
      theta *= scale;
      theta1 *= scale;
      z *= scale;
    }
    theta2 = theta1;
    theta1 = theta;
  }
};

/// Solves the tridiagonal system a_i x_{i-1} + d_i x_i + c_i x_{i+1} = r_i (a_0 = c_{n-1} = 0)
/// and adds x to `out` (out[i] += x_i), in O(n) with a twisted factorization: elimination
/// runs down from the top to the middle row k = n/2 and up from the bottom to it at the same
/// time (two independent serial chains, so the latency is halved), row k is solved, and the
/// back substitution runs outwards from k. The pivots are ratios of continuants,
///   top:    theta_i = d_i theta_{i-1} - a_i c_{i-1} theta_{i-2},  pivot_i = theta_i/theta_{i-1},
///   bottom: phi_i   = d_i phi_{i+1}   - c_i a_{i+1} phi_{i+2},    pivot_i = phi_i/phi_{i+1},
/// and the eliminated right-hand sides are z_i / theta_i (z_i = r_i theta_{i-1} - a_i z_{i-1})
/// and v_i / phi_i (v_i = r_i phi_{i+1} - c_i v_{i+1}), so each serial chain holds a single
/// multiply-add per row and the divisions run beside the chains, off their critical path.
/// Continuants are renormalized when they leave [2^-256, 2^256]. No pivoting: for the RATTLE
/// systems (+-H plus O(tau) terms, H = G M^{-1} G^T symmetric positive definite) it is not
/// needed at any usable step. Scratch: num_c, num_r (n each).
template <class Real>
[[gnu::always_inline]] inline void solve_tridiagonal_twisted(
    std::size_t n, const Real* __restrict a, const Real* __restrict d, const Real* __restrict c,
    const Real* __restrict r, Real* __restrict out, Real* __restrict num_c,
    Real* __restrict num_r) {
  const std::size_t k = n / 2;  // the twist row
  // Top rows 0..k-1 and bottom rows n-1..k+1, interleaved.
  EliminationSweep<Real> from_top, from_bottom;
  const std::size_t top = k, bottom = n - 1 - k;
  const std::size_t both = std::min(top, bottom);
  auto top_row = [&](std::size_t i) {
    from_top.row(d[i], a[i], c[i], r[i], num_c[i], num_r[i]);
  };
  auto bottom_row = [&](std::size_t i) {
    from_bottom.row(d[i], c[i], a[i], r[i], num_c[i], num_r[i]);
  };
  for (std::size_t j = 0; j < both; ++j) {
    top_row(j);
    bottom_row(n - 1 - j);
  }
  for (std::size_t j = both; j < top; ++j) top_row(j);
  for (std::size_t j = both; j < bottom; ++j) bottom_row(n - 1 - j);
  // Row k with x_{k-1} = y_{k-1} - cp_{k-1} x_k and x_{k+1} = w_{k+1} - aq_{k+1} x_k.
  Real pivot = d[k], rhs = r[k];
  if (k > 0) {
    pivot -= a[k] * num_c[k - 1];
    rhs -= a[k] * num_r[k - 1];
  }
  if (k + 1 < n) {
    pivot -= c[k] * num_c[k + 1];
    rhs -= c[k] * num_r[k + 1];
  }
  const Real xk = rhs / pivot;
  out[k] += xk;
  Real up = xk, down = xk;
  for (std::size_t j = 1; j <= both; ++j) {
    up = num_r[k - j] - num_c[k - j] * up;
    down = num_r[k + j] - num_c[k + j] * down;
    out[k - j] += up;
    out[k + j] += down;
  }
  for (std::size_t j = both + 1; j <= top; ++j) {
    up = num_r[k - j] - num_c[k - j] * up;
    out[k - j] += up;
  }
  for (std::size_t j = both + 1; j <= bottom; ++j) {
    down = num_r[k + j] - num_c[k + j] * down;
    out[k + j] += down;
  }
}

/// The position stage's first pass at the guess s: trial links rt = r + tau u, the trial
/// r'(s) = rt + c(s) (see constrained_drift), the negated residuals -f(s) and the Jacobian
/// df/ds at r'(s) (diagonal jd, sub ja, super jc). Returns max_i |f_i| / l_i^2.
template <int Extrapolate, class Real>
[[gnu::always_inline]] inline Real first_pass(std::size_t n, const Real& tau, Real* __restrict s,
                const Real* __restrict last, const Real* __restrict before,
                const Real* __restrict oldest,
                const Real* __restrict w, const Real* __restrict im, const Real* __restrict rx,
                const Real* __restrict ry, const Real* __restrict ux, const Real* __restrict uy,
                const Real* __restrict half_l2, const Real* __restrict inv_l2,
                Real* __restrict rtx, Real* __restrict rty, Real* __restrict neg_f,
                Real* __restrict jd, Real* __restrict ja, Real* __restrict jc) {
  Real worst = 0;
#pragma omp simd reduction(max : worst)
  for (std::ptrdiff_t i = 0; i < static_cast<std::ptrdiff_t>(n); ++i) {
    const Real tx0 = rx[i] + tau * ux[i], ty0 = ry[i] + tau * uy[i];
    rtx[i] = tx0;
    rty[i] = ty0;
    Real s0, s_next, s_prev;
    if constexpr (Extrapolate == 2) {
      // The guess 3 (last - before) + oldest, formed here rather than loaded from a just-
      // written s (shifted loads of fresh stores stall the store forwarding).
      s0 = 3 * (last[i] - before[i]) + oldest[i];
      s_next = 3 * (last[i + 1] - before[i + 1]) + oldest[i + 1];
      s_prev = 3 * (last[i - 1] - before[i - 1]) + oldest[i - 1];
      s[i] = s0;
    } else if constexpr (Extrapolate == 1) {
      s0 = 2 * last[i] - before[i];
      s_next = 2 * last[i + 1] - before[i + 1];
      s_prev = 2 * last[i - 1] - before[i - 1];
      s[i] = s0;
    } else {
      s0 = s[i];
      s_next = s[i + 1];
      s_prev = s[i - 1];
    }
    const Real sig = s0 * w[i], alp = s_next * im[i], bet = s_prev * im[i - 1];
    const Real lx = tx0 + (alp * rx[i + 1] + bet * rx[i - 1] - sig * rx[i]);
    const Real ly = ty0 + (alp * ry[i + 1] + bet * ry[i - 1] - sig * ry[i]);
    // (l^2 - |r'|^2)/2 as a difference of squares is accurate to ~ulp(l^2): all we ask.
    const Real g = half_l2[i] - (lx * lx + ly * ly) / 2;
    neg_f[i] = g;
    worst = std::max(worst, abs(g) * inv_l2[i]);
    jd[i] = -w[i] * (lx * rx[i] + ly * ry[i]);
    ja[i] = im[i - 1] * (lx * rx[i - 1] + ly * ry[i - 1]);  // 0 at i = 0
    jc[i] = im[i] * (lx * rx[i + 1] + ly * ry[i + 1]);      // 0 at i = n - 1
  }
  return worst;
}

/// The position stage's pass at the current s: the new links r' = rt + c(s) and link
/// velocities u + c(s)/tau into the next-frame arrays, -f(s), and max_i |f_i| / l_i^2.
template <class Real>
[[gnu::always_inline]] inline Real final_pass(std::size_t n, const Real& inv_tau, const Real* __restrict s,
                const Real* __restrict w, const Real* __restrict im, const Real* __restrict rx,
                const Real* __restrict ry, const Real* __restrict ux, const Real* __restrict uy,
                const Real* __restrict rtx, const Real* __restrict rty,
                const Real* __restrict half_l2, const Real* __restrict inv_l2,
                Real* __restrict next_rx, Real* __restrict next_ry, Real* __restrict next_ux,
                Real* __restrict next_uy, Real* __restrict neg_f) {
  Real worst = 0;
#pragma omp simd reduction(max : worst)
  for (std::ptrdiff_t i = 0; i < static_cast<std::ptrdiff_t>(n); ++i) {
    const Real sig = s[i] * w[i], alp = s[i + 1] * im[i], bet = s[i - 1] * im[i - 1];
    const Real dx = alp * rx[i + 1] + bet * rx[i - 1] - sig * rx[i];
    const Real dy = alp * ry[i + 1] + bet * ry[i - 1] - sig * ry[i];
    const Real lx = rtx[i] + dx, ly = rty[i] + dy;
    next_rx[i] = lx;
    next_ry[i] = ly;
    next_ux[i] = ux[i] + dx * inv_tau;  // the impulse from s: no cancellation
    next_uy[i] = uy[i] + dy * inv_tau;
    const Real g = half_l2[i] - (lx * lx + ly * ly) / 2;
    neg_f[i] = g;
    worst = std::max(worst, abs(g) * inv_l2[i]);
  }
  return worst;
}

/// The Jacobian df/ds at the links t (a further Newton iteration; rare).
template <class Real>
void link_jacobian(std::size_t n, const Real* __restrict w, const Real* __restrict im,
                   const Real* __restrict rx, const Real* __restrict ry,
                   const Real* __restrict tx, const Real* __restrict ty, Real* __restrict jd,
                   Real* __restrict ja, Real* __restrict jc) {
#pragma omp simd
  for (std::ptrdiff_t i = 0; i < static_cast<std::ptrdiff_t>(n); ++i) {
    jd[i] = -w[i] * (tx[i] * rx[i] + ty[i] * ry[i]);
    ja[i] = im[i - 1] * (tx[i] * rx[i - 1] + ty[i] * ry[i - 1]);
    jc[i] = im[i] * (tx[i] * rx[i + 1] + ty[i] * ry[i + 1]);
  }
}

/// Position stage: x_k <- x_k + tau p_k / m_k + (s_{k+1} r_{k+1} - s_k r_k) / m_k with the N
/// scaled multipliers s chosen so that every link has its length at the new positions; p
/// receives the matching impulse (s_{k+1} r_{k+1} - s_k r_k) / tau. In the link frame,
///   r'_i(s) = rt_i + c_i(s),  rt_i = r_i + tau u_i,
///   c_i(s) = s_{i+1} r_{i+1} / m_i - s_i w_i r_i + s_{i-1} r_{i-1} / m_{i-1},
///   w_i = 1/m_i + 1/m_{i-1} (1/m_{-1} = 0, s_N = 0),  f_i(s) = (|r'_i|^2 - l_i^2) / 2 = 0,
/// and then r_i <- r'_i, u_i <- u_i + c_i / tau (the impulse, computed from s: no cancellation).
/// f is quadratic in s, so Newton converges quadratically from a good guess; its Jacobian
/// df_i/ds_j = r'_i . dr'_i/ds_j is tridiagonal (-H at tau = 0, H = G M^{-1} G^T) and each
/// iteration is one O(N) twisted solve. `slot` >= 0 names the stage's place in its
/// composition: the guess is then the linear extrapolation of that slot's multipliers over
/// the last two steps (error O(h^2), so one Newton solve usually suffices); otherwise (or for
/// the first two steps) s = tau (pending kick time) mu from the last velocity stage. The
/// stage stops when every |f_i| / l_i^2 is at most newton_tolerance_ulps ulps, evaluated at
/// the final s by the same pass that writes the new frame.
template <class Real>
void constrained_drift(DynamicsWorkspace<Real>& ws, const Real& tau, int slot = -1) {
  const std::size_t n = ws.size();
  LinkFrame<Real> lf(ws);
  Real* s = lf.s;
  // The guess: the quadratic extrapolation of this slot's last three multipliers (error
  // O(h^3); formed inside the first pass), the linear one after two, else tau (pending kick
  // time) mu.
  typename DynamicsWorkspace<Real>::StageHistory* history =
      slot >= 0 ? &ws.stage_history(static_cast<std::size_t>(slot)) : nullptr;
  if (history != nullptr && history->last.size() != n + 2) {
    for (auto* v : {&history->last, &history->before, &history->oldest}) v->assign(n + 2, Real(0));
    history->count = 0;
  }
  const int order = history == nullptr ? 0 : history->count >= 3 ? 2 : history->count >= 2 ? 1 : 0;
  if (order == 0) {
    const Real guess_scale = tau * ws.pending_kick_time;
    const Real* estimate = ws.multiplier_estimate.data();
    for (std::size_t i = 0; i < n; ++i) s[i] = guess_scale * estimate[i];
  }
  const Real* w = ws.joint_compliance.data();
  const Real* half_l2 = ws.half_length_squared.data();
  const Real* inv_l2 = ws.inv_length_squared.data();
  Real* rtx = ws.trial_link_x.data();
  Real* rty = ws.trial_link_y.data();
  Real* neg_f = ws.residual.data();
  Real* jd = ws.diagonal.data();
  Real* ja = ws.sub.data();
  Real* jc = ws.super.data();
  Real* nrx = ws.next_link_x.data() + 1;
  Real* nry = ws.next_link_y.data() + 1;
  Real* nux = ws.next_rate_x.data() + 1;
  Real* nuy = ws.next_rate_y.data() + 1;
  const Real inv_tau = Real(1) / tau;
  const Real tolerance =
      Real(ws.newton_tolerance_ulps) * std::numeric_limits<Real>::epsilon();

  const Real* none = nullptr;
  Real worst = 0;
  if (order == 2) {
    worst = first_pass<2>(n, tau, s, history->last.data() + 1, history->before.data() + 1,
                          history->oldest.data() + 1, w, lf.im, lf.rx, lf.ry, lf.ux, lf.uy,
                          half_l2, inv_l2, rtx, rty, neg_f, jd, ja, jc);
  } else if (order == 1) {
    worst = first_pass<1>(n, tau, s, history->last.data() + 1, history->before.data() + 1, none,
                          w, lf.im, lf.rx, lf.ry, lf.ux, lf.uy, half_l2, inv_l2, rtx, rty, neg_f,
                          jd, ja, jc);
  } else {
    worst = first_pass<0>(n, tau, s, none, none, none, w, lf.im, lf.rx, lf.ry, lf.ux, lf.uy,
                          half_l2, inv_l2, rtx, rty, neg_f, jd, ja, jc);
  }
  bool written = false;
  for (int iteration = 0; worst > tolerance; ++iteration) {
    if (iteration >= ws.max_newton_iterations) {
      ++ws.unconverged_stages;
      break;
    }
    if (iteration > 0) link_jacobian(n, w, lf.im, lf.rx, lf.ry, nrx, nry, jd, ja, jc);
    solve_tridiagonal_twisted(n, ja, jd, jc, neg_f, s, ws.pivot.data(), ws.rhs.data());
    ++ws.newton_solves;
    worst = final_pass(n, inv_tau, s, w, lf.im, lf.rx, lf.ry, lf.ux, lf.uy, rtx, rty, half_l2,
                       inv_l2, nrx, nry, nux, nuy, neg_f);
    written = true;
  }
  if (!written) {
    // Converged at the guess: the new frame is still to be written.
    worst = final_pass(n, inv_tau, s, w, lf.im, lf.rx, lf.ry, lf.ux, lf.uy, rtx, rty, half_l2,
                       inv_l2, nrx, nry, nux, nuy, neg_f);
  }
  ++ws.position_stages;
  ws.pending_kick_time = 0;
  ws.largest_stage_residual = std::max(ws.largest_stage_residual, worst);
  if (history != nullptr) {
    // Rotate: oldest <- before <- last <- s; the multiplier buffer takes the old `oldest`
    // (every buffer is padded with zeros at both ends, and the next stage overwrites it).
    history->oldest.swap(history->before);
    history->before.swap(history->last);
    history->last.swap(ws.multiplier);
    ++history->count;
  }
  ws.link_x.swap(ws.next_link_x);
  ws.link_y.swap(ws.next_link_y);
  ws.rate_x.swap(ws.next_rate_x);
  ws.rate_y.swap(ws.next_rate_y);
}

/// Velocity stage: H t = b, b_i = r_i . u_i, H_ii = w_i |r_i|^2, H_{i,i-1} = -r_i . r_{i-1} /
/// m_{i-1}; then p_k += t_{k+1} r_{k+1} - t_k r_k, i.e. u_i += c_i(t) (the same stencil as the
/// position stage's displacement). With learn = true (a stage that closes kicks, not noise)
/// mu = t / (pending kick time) becomes the guess of the next position stages.
template <class Real>
void velocity_stage(DynamicsWorkspace<Real>& ws, bool learn = true) {
  const std::size_t n = ws.size();
  LinkFrame<Real> lf(ws);
  const Real* __restrict rx = lf.rx;
  const Real* __restrict ry = lf.ry;
  Real* __restrict ux = lf.ux;
  Real* __restrict uy = lf.uy;
  Real* __restrict t = lf.s;
  const Real* __restrict im = lf.im;
  const Real* __restrict w = ws.joint_compliance.data();
  Real* __restrict b = ws.residual.data();
  Real* __restrict hd = ws.diagonal.data();
  Real* __restrict ha = ws.sub.data();
  Real* __restrict hc = ws.super.data();
#pragma omp simd
  for (std::ptrdiff_t i = 0; i < static_cast<std::ptrdiff_t>(n); ++i) {
    b[i] = rx[i] * ux[i] + ry[i] * uy[i];
    hd[i] = w[i] * (rx[i] * rx[i] + ry[i] * ry[i]);
    ha[i] = -im[i - 1] * (rx[i] * rx[i - 1] + ry[i] * ry[i - 1]);  // 0 at i = 0
    hc[i] = -im[i] * (rx[i] * rx[i + 1] + ry[i] * ry[i + 1]);      // 0 at i = n - 1
    t[i] = 0;
  }
  solve_tridiagonal_twisted(n, ha, hd, hc, b, t, ws.pivot.data(), ws.rhs.data());
#pragma omp simd
  for (std::ptrdiff_t i = 0; i < static_cast<std::ptrdiff_t>(n); ++i) {
    const Real sig = t[i] * w[i], alp = t[i + 1] * im[i], bet = t[i - 1] * im[i - 1];
    ux[i] += alp * rx[i + 1] + bet * rx[i - 1] - sig * rx[i];
    uy[i] += alp * ry[i + 1] + bet * ry[i - 1] - sig * ry[i];
  }
  if (learn && ws.pending_kick_time != 0) {
    const Real inv = Real(1) / ws.pending_kick_time;
    for (std::size_t i = 0; i < n; ++i) ws.multiplier_estimate[i] = t[i] * inv;
  }
  ws.pending_kick_time = 0;
}

/// Weights of the symmetric compositions of RATTLE (each sums to 1).
template <class Real>
std::vector<Real> composition_weights(Integrator integrator) {
  using std::cbrt;
  switch (integrator) {
    case Integrator::rattle2:
      return {Real(1)};
    case Integrator::yoshida4: {
      // Yoshida (1990) / Forest-Ruth: w1 = 1 / (2 - 2^{1/3}), w0 = 1 - 2 w1.
      const Real w1 = Real(1) / (Real(2) - cbrt(Real(2)));
      return {w1, Real(1) - 2 * w1, w1};
    }
    case Integrator::suzuki4: {
      // Suzuki (1990): p = 1 / (4 - 4^{1/3}); p p (1 - 4p) p p. Smaller error constants.
      const Real p = Real(1) / (Real(4) - cbrt(Real(4)));
      return {p, p, Real(1) - 4 * p, p, p};
    }
    case Integrator::kahan_li6: {
      // Kahan and Li (1997), s9odr6a: 9 stages, sixth order.
      const Real g[5] = {Real(0.39216144400731413927925056L), Real(0.33259913678935943859974864L),
                         Real(-0.70624617255763935980996482L), Real(0.08221359629355080023149045L),
                         Real(0.79854399093482996339895035L)};
      return {g[0], g[1], g[2], g[3], g[4], g[3], g[2], g[1], g[0]};
    }
    case Integrator::yoshida6: {
      // Yoshida (1990), Phys. Lett. A 150, 262, Table 1, solution A: w3 w2 w1 w0 w1 w2 w3.
      const Real w1 = Real(-1.17767998417887L), w2 = Real(0.235573213359357L),
                 w3 = Real(0.784513610477560L);
      const Real w0 = 1 - 2 * (w1 + w2 + w3);
      return {w3, w2, w1, w0, w1, w2, w3};
    }
  }
  return {Real(1)};
}


/// One step of a composition on the link frame (see composition_step).
template <class Real>
void advance_composition(const Chain<Real>& chain, DynamicsWorkspace<Real>& ws, const Real& h,
                         Integrator integrator) {
  const std::vector<Real>& w = ws.composition(integrator, composition_weights<Real>);
  // kick(w_1 h/2) drift(w_1 h) kick((w_1 + w_2) h/2) drift(w_2 h) ... drift(w_s h)
  // kick(w_s h/2) project. The position stages absorb the normal momentum components, so the
  // skipped intermediate velocity stages would change nothing but the multipliers.
  const std::size_t stages = w.size();
  if (integrator == Integrator::rattle2) {
    gravity_kick(chain, ws, h / 2);
    constrained_drift(ws, h, 0);
    gravity_kick(chain, ws, h / 2);
  } else {
    gravity_kick(chain, ws, w[0] * h / 2);
    for (std::size_t j = 0; j < stages; ++j) {
      constrained_drift(ws, w[j] * h, static_cast<int>(8 + j));
      const Real next = j + 1 < stages ? w[j + 1] : Real(0);
      gravity_kick(chain, ws, (w[j] + next) * h / 2);
    }
  }
  velocity_stage(ws);
}

/// One constrained BAOAB step on the link frame (see baoab_step).
/// Standard normal deviates from a 64-bit engine by Marsaglia's polar method (pairs), uniform
/// variates u = k / 2^64 (k the engine's output, below 1): the textbook algorithm, written here so
/// that a seed gives the same trajectory with any C++ standard library (std::normal_distribution
/// is implementation-defined) and so that it is compiled with this file's instruction set. Not
/// inlined: every deviate is then rounded the same way whatever code surrounds the call.
class StandardNormal {
 public:
  [[gnu::noinline]] double operator()(std::mt19937_64& engine) {
    double value;
    if (saved_available_) {
      saved_available_ = false;
      value = saved_;
    } else {
      double x, y, r2;
      do {
        x = 2.0 * uniform(engine) - 1.0;
        y = 2.0 * uniform(engine) - 1.0;
        r2 = x * x + y * y;
      } while (r2 > 1.0 || r2 == 0.0);
      const double mult = std::sqrt(-2 * std::log(r2) / r2);
      saved_ = x * mult;
      saved_available_ = true;
      value = y * mult;
    }
    return value * stddev_ + mean_;  // as a general N(mean, stddev) sampler computes it
  }

 private:
  static double uniform(std::mt19937_64& engine) {
    const double u = static_cast<double>(engine() - std::mt19937_64::min()) / 0x1p64;
    return u < 1.0 ? u : std::nextafter(1.0, 0.0);
  }
  double saved_ = 0;
  bool saved_available_ = false;
  double mean_ = 0, stddev_ = 1;
};

template <class Real>
void advance_baoab(const Chain<Real>& chain, DynamicsWorkspace<Real>& ws, const Real& h,
                   const Real& beta, const Real& friction, std::mt19937_64& rng) {
  using std::exp;
  using std::expm1;
  const std::size_t n = ws.size();
  const Real half = h / 2;
  gravity_kick(chain, ws, half);   // B
  constrained_drift(ws, half, 4);  // A (its end projection is folded into O's)
  // O: v <- c1 v + sqrt((1 - c1^2) / (m beta)) xi on the particle velocities, then back to the
  // cotangent space.
  const Real c1 = exp(-friction * h);
  const Real noise = sqrt(-expm1(-2 * friction * h) / beta);
  StandardNormal normal;
  LinkFrame<Real> lf(ws);
  Real vx = 0, vy = 0, vx_new_prev = 0, vy_new_prev = 0;
  for (std::size_t k = 0; k < n; ++k) {
    vx += lf.ux[k];
    vy += lf.uy[k];
    const Real sm = noise * ws.inv_sqrt_mass[k];
    const Real vx_new = c1 * vx + sm * Real(normal(rng));
    const Real vy_new = c1 * vy + sm * Real(normal(rng));
    lf.ux[k] = vx_new - vx_new_prev;
    lf.uy[k] = vy_new - vy_new_prev;
    vx_new_prev = vx_new;
    vy_new_prev = vy_new;
  }
  velocity_stage(ws, /*learn=*/false);
  constrained_drift(ws, half, 5);  // A
  gravity_kick(chain, ws, half);   // B
  velocity_stage(ws);
}

/// Per-particle observables and energies of the link frame in two O(N) passes: K_i, K_i^(c),
/// cos phi_i into sample[0..3N), and the kinetic and potential energy.
template <class Real>
void link_observables(const Chain<Real>& chain, DynamicsWorkspace<Real>& ws, Real* sample,
                      Real& kinetic, Real& potential) {
  const std::size_t n = ws.size();
  LinkFrame<Real> lf(ws);
  Real* vxs = ws.velocity_x.data();
  Real* vys = ws.velocity_y.data();
  Real vx = 0, vy = 0, k_sum = 0;
  for (std::size_t i = 0; i < n; ++i) {
    vx += lf.ux[i];
    vy += lf.uy[i];
    vxs[i] = vx;
    vys[i] = vy;
    const Real k = ws.mass[i] * (vx * vx + vy * vy) / 2;
    sample[i] = k;
    k_sum += k;
  }
  // Tail momenta P_i = sum_{k >= i} p_k: p_phi_i = r_i x P_i; phidot_i = r_i x u_i / l_i^2;
  // U = g sum_k m_k y_k = g sum_i S_i r_iy (S_i the tail mass).
  Real px = 0, py = 0, height = 0;
  for (std::size_t i = n; i-- > 0;) {
    px += ws.mass[i] * vxs[i];
    py += ws.mass[i] * vys[i];
    const Real rx = lf.rx[i], ry = lf.ry[i];
    const Real p_phi = rx * py - ry * px;
    const Real phidot = (rx * lf.uy[i] - ry * lf.ux[i]) * ws.inv_length_squared[i];
    sample[n + i] = p_phi * phidot / 2;
    sample[2 * n + i] = -ry * ws.inv_length[i];  // cos phi_i
    height += ws.tail_mass[i] * ry;
  }
  kinetic = k_sum;
  potential = height * chain.gravity();
}

/// max_i | |r_i| - l_i | / l_i of the link frame.
template <class Real>
Real link_constraint_residual(DynamicsWorkspace<Real>& ws) {
  using std::hypot;
  LinkFrame<Real> lf(ws);
  Real worst = 0;
  for (std::size_t i = 0; i < ws.size(); ++i)
    worst = std::max(worst, abs(hypot(lf.rx[i], lf.ry[i]) - ws.length[i]) * ws.inv_length[i]);
  return worst;
}

}  // namespace

// ---------------------------------------------------------------- states

template <class Real>
ChainState<Real> state_from_angles_kernel(const Chain<Real>& chain, const std::vector<Real>& phi,
                                   const std::vector<Real>& phidot) {
  const std::size_t n = chain.size();
  if (phi.size() != n) throw invalid_input("need one angle per particle");
  if (phidot.size() != n) throw invalid_input("need one angular velocity per particle");
  check_finite_vector(phi, "angles");
  check_finite_vector(phidot, "angular velocities");
  ChainState<Real> st;
  st.position.assign(2 * n, Real(0));
  st.momentum.assign(2 * n, Real(0));
  Real x = 0, y = 0, vx = 0, vy = 0;
  for (std::size_t i = 0; i < n; ++i) {
    const Real l = chain.length(i), s = sin(phi[i]), c = cos(phi[i]);
    x += l * s;
    y -= l * c;
    vx += l * c * phidot[i];
    vy += l * s * phidot[i];
    st.position[2 * i] = x;
    st.position[2 * i + 1] = y;
    st.momentum[2 * i] = chain.mass(i) * vx;
    st.momentum[2 * i + 1] = chain.mass(i) * vy;
  }
  return st;
}

template <class Real>
ChainState<Real> state_from_canonical_kernel(const Chain<Real>& chain, const std::vector<Real>& phi,
                                      const std::vector<Real>& p_phi) {
  const std::size_t n = chain.size();
  if (phi.size() != n || p_phi.size() != n)
    throw invalid_input("need one angle and one momentum per particle");
  check_finite_vector(phi, "angles");
  check_finite_vector(p_phi, "momenta");
  // A_jk = S_max(j,k) l_j l_k cos(phi_j - phi_k) (paper eq. a-ij); dense solve (setup only).
  using Matrix = Eigen::Matrix<Real, Eigen::Dynamic, Eigen::Dynamic>;
  using Vector = Eigen::Matrix<Real, Eigen::Dynamic, 1>;
  Matrix a(n, n);
  Vector rhs(n);
  for (std::size_t j = 0; j < n; ++j) {
    rhs(j) = p_phi[j];
    for (std::size_t k = 0; k < n; ++k)
      a(j, k) = chain.tail_mass(std::max(j, k)) * chain.length(j) * chain.length(k) *
                cos(phi[j] - phi[k]);
  }
  const Vector phidot = a.ldlt().solve(rhs);
  std::vector<Real> rates(n);
  for (std::size_t j = 0; j < n; ++j) rates[j] = phidot(j);
  return state_from_angles_kernel(chain, phi, rates);
}

template <class Real>
ChainObservables<Real> observables_kernel(const Chain<Real>& chain, const ChainState<Real>& st) {
  const std::size_t n = chain.size();
  ChainObservables<Real> o;
  o.phi.resize(n);
  o.phidot.resize(n);
  o.p_phi.resize(n);
  o.kinetic.resize(n);
  o.kinetic_canonical.resize(n);
  const std::vector<Real>& x = st.position;
  const std::vector<Real>& p = st.momentum;
  // Tail momenta P_i = sum_{k >= i} p_k: p_phi_i = l_i e_i . P_i, e_i = (cos phi_i, sin phi_i).
  Real px = 0, py = 0;
  std::vector<Real> tail_x(n), tail_y(n);
  for (std::size_t i = n; i-- > 0;) {
    px += p[2 * i];
    py += p[2 * i + 1];
    tail_x[i] = px;
    tail_y[i] = py;
  }
  Real xprev = 0, yprev = 0, vxprev = 0, vyprev = 0;
  o.kinetic_total = 0;
  o.potential = 0;
  for (std::size_t i = 0; i < n; ++i) {
    const Real m = chain.mass(i);
    const Real rx = x[2 * i] - xprev, ry = x[2 * i + 1] - yprev;
    const Real vx = p[2 * i] / m, vy = p[2 * i + 1] / m;
    o.phi[i] = atan2(rx, -ry);
    // l e_i = (-r_y, r_x)
    const Real ex = -ry, ey = rx;
    const Real l2 = rx * rx + ry * ry;
    o.p_phi[i] = ex * tail_x[i] + ey * tail_y[i];
    o.phidot[i] = (ex * (vx - vxprev) + ey * (vy - vyprev)) / l2;
    o.kinetic[i] = (p[2 * i] * p[2 * i] + p[2 * i + 1] * p[2 * i + 1]) / (2 * m);
    o.kinetic_canonical[i] = o.p_phi[i] * o.phidot[i] / 2;
    o.kinetic_total += o.kinetic[i];
    o.potential += m * chain.gravity() * x[2 * i + 1];
    xprev = x[2 * i];
    yprev = x[2 * i + 1];
    vxprev = vx;
    vyprev = vy;
  }
  o.energy = o.kinetic_total + o.potential;
  return o;
}

template <class Real>
Real potential_energy_kernel(const Chain<Real>& chain, const ChainState<Real>& st) {
  Real u = 0;
  for (std::size_t k = 0; k < chain.size(); ++k) u += chain.mass(k) * st.position[2 * k + 1];
  return u * chain.gravity();
}

template <class Real>
Real total_energy_kernel(const Chain<Real>& chain, const ChainState<Real>& st) {
  Real kinetic = 0;
  for (std::size_t k = 0; k < chain.size(); ++k)
    kinetic += (st.momentum[2 * k] * st.momentum[2 * k] +
                st.momentum[2 * k + 1] * st.momentum[2 * k + 1]) /
               (2 * chain.mass(k));
  return kinetic + potential_energy_kernel(chain, st);
}

template <class Real>
Real constraint_residual_kernel(const Chain<Real>& chain, const ChainState<Real>& st) {
  Real worst = 0, xprev = 0, yprev = 0;
  for (std::size_t i = 0; i < chain.size(); ++i) {
    const Real rx = st.position[2 * i] - xprev, ry = st.position[2 * i + 1] - yprev;
    using std::hypot;
    worst = std::max(worst, abs(hypot(rx, ry) - chain.length(i)) / chain.length(i));
    xprev = st.position[2 * i];
    yprev = st.position[2 * i + 1];
  }
  return worst;
}

template <class Real>
Real velocity_constraint_residual_kernel(const Chain<Real>& chain, const ChainState<Real>& st) {
  Real worst = 0, scale = 0, xprev = 0, yprev = 0, vxprev = 0, vyprev = 0;
  std::vector<Real> dots(chain.size());
  for (std::size_t i = 0; i < chain.size(); ++i) {
    const Real m = chain.mass(i);
    const Real rx = st.position[2 * i] - xprev, ry = st.position[2 * i + 1] - yprev;
    const Real ux = st.momentum[2 * i] / m - vxprev, uy = st.momentum[2 * i + 1] / m - vyprev;
    dots[i] = abs(rx * ux + ry * uy) / chain.length(i);
    using std::hypot;
    scale = std::max(scale, hypot(ux, uy));
    xprev = st.position[2 * i];
    yprev = st.position[2 * i + 1];
    vxprev = st.momentum[2 * i] / m;
    vyprev = st.momentum[2 * i + 1] / m;
  }
  for (const Real& d : dots) worst = std::max(worst, d);
  return scale > 0 ? worst / scale : worst;
}

// ---------------------------------------------------------------- steps

template <class Real>
void project_momenta_kernel(const Chain<Real>&, ChainState<Real>& state, DynamicsWorkspace<Real>& ws) {
  load_links(state, ws);
  velocity_stage(ws, /*learn=*/false);
  store_links(ws, state);
}

template <class Real>
void rattle_step_kernel(const Chain<Real>& chain, ChainState<Real>& state, const Real& h,
                 DynamicsWorkspace<Real>& ws) {
  load_links(state, ws);
  advance_composition(chain, ws, h, Integrator::rattle2);
  store_links(ws, state);
  state.time += h;
}

template <class Real>
void composition_step_kernel(const Chain<Real>& chain, ChainState<Real>& state, const Real& h,
                      Integrator integrator, DynamicsWorkspace<Real>& ws) {
  load_links(state, ws);
  advance_composition(chain, ws, h, integrator);
  store_links(ws, state);
  state.time += h;
}

template <class Real>
void yoshida4_step_kernel(const Chain<Real>& chain, ChainState<Real>& state, const Real& h,
                   DynamicsWorkspace<Real>& ws) {
  composition_step_kernel(chain, state, h, Integrator::yoshida4, ws);
}

template <class Real>
void baoab_step_kernel(const Chain<Real>& chain, ChainState<Real>& state, const Real& h,
                const Real& beta, const Real& friction, std::mt19937_64& rng,
                DynamicsWorkspace<Real>& ws) {
  load_links(state, ws);
  advance_baoab(chain, ws, h, beta, friction, rng);
  store_links(ws, state);
  state.time += h;
}

// ---------------------------------------------------------------- runs

/// The start of a run (simulate_kernel): the initial energy and the scale the energy errors are
/// relative to, the constraint residual at the start, and the time step against the fastest
/// motion the run can reach (refused in one line). Inlined: one body with the run, as before
/// the split (the kernels' fused multiply-adds stay where they were).
template <class Real>
[[gnu::always_inline]] inline void begin_run(const Chain<Real>& chain,
                                             const SimulationOptions& options, bool langevin,
                                             DynamicsWorkspace<Real>& ws, std::vector<Real>& sample,
                                             SimulationResult<Real>& out) {
  const std::size_t n = chain.size();
  Real mass_sum = 0, length_sum = 0;
  for (std::size_t i = 0; i < n; ++i) {
    mass_sum += chain.mass(i);
    length_sum += chain.length(i);
  }
  {
    Real k0 = 0, u0 = 0;
    link_observables(chain, ws, sample.data(), k0, u0);
    out.initial_energy = k0 + u0;
    out.energy_scale = chain.gravity() > 0 ? mass_sum * chain.gravity() * length_sum
                                           : abs(out.initial_energy) + k0;
    if (!(out.energy_scale > 0)) out.energy_scale = 1;
  }
  out.constraint_residual = link_constraint_residual(ws);
  {
    // Kinetic energy the motion can reach: E - U_min for NVE; for Langevin also ~ N/beta
    // (thermal), with a wide margin (20 N / beta).
    const long double u_min = -static_cast<long double>(chain.gravity()) * static_cast<long double>(mass_sum) *
                        static_cast<long double>(length_sum);
    long double kinetic = static_cast<long double>(out.initial_energy) - u_min;
    if (langevin)
      kinetic = std::max(kinetic, 20 * static_cast<long double>(n) / static_cast<long double>(*options.beta));
    domain::check_stable_time_step(chain, options.time_step, kinetic, "simulate",
                                   options.duration + options.burn_in, max_simulation_steps);
  }
}

/// The end of a run (simulate_kernel): the final constraint residual and energy, the energy
/// errors relative to the scale, the work done, and the time averages with their blocking error
/// bars. Inlined, as begin_run.
template <class Real>
[[gnu::always_inline]] inline void finish_run(
    const Chain<Real>& chain, const SimulationOptions& options, bool langevin,
    DynamicsWorkspace<Real>& ws, const BlockAverager<Real>& blocks, std::vector<Real>& sample,
    std::size_t done, const Real& energy_error_max, const Real& energy_error_squares,
    SimulationResult<Real>& out) {
  const std::size_t n = chain.size();
  out.constraint_residual = std::max(out.constraint_residual, link_constraint_residual(ws));
  // The position stages' own residual |sigma|/l^2 ~ relative length error: include it.
  out.constraint_residual = std::max(out.constraint_residual, ws.largest_stage_residual);
  {
    Real k1 = 0, u1 = 0;
    link_observables(chain, ws, sample.data(), k1, u1);
    out.final_energy = k1 + u1;
  }
  out.energy_drift = (out.final_energy - out.initial_energy) / out.energy_scale;
  out.energy_error_max = energy_error_max / out.energy_scale;
  if (done > 0)
    out.energy_error_rms = sqrt(energy_error_squares / Real(static_cast<double>(done))) / out.energy_scale;
  out.steps = done;
  out.samples = blocks.samples();
  out.simulated_time = static_cast<double>(done) * options.time_step;
  out.newton_solves = ws.newton_solves;
  out.unconverged_stages = ws.unconverged_stages;

  const Real sample_time(options.time_step);
  out.kinetic.resize(n);
  out.kinetic_canonical.resize(n);
  for (std::size_t i = 0; i < n; ++i) {
    out.kinetic[i] = blocks.time_average(i, sample_time);
    out.kinetic_canonical[i] = blocks.time_average(n + i, sample_time);
  }
  out.cos_angle.resize(n);
  for (std::size_t i = 0; i < n; ++i) out.cos_angle[i] = blocks.time_average(2 * n + i, sample_time);
  out.kinetic_total = blocks.time_average(3 * n, sample_time);
  out.potential = blocks.time_average(3 * n + 1, sample_time);
  if (!langevin) out.energy_trend = blocks.trend(3 * n + 2) / out.energy_scale;
}

template <class Real>
SimulationResult<Real> simulate_kernel(const Chain<Real>& chain, ChainState<Real> state,
                                const SimulationOptions& options,
                                const DynamicsObserver<Real>& observer) {
  const std::size_t n = chain.size();
  if (state.position.size() != 2 * n || state.momentum.size() != 2 * n)
    throw invalid_input("simulate: the state does not match the chain");
  // The options are checked by simulate() (check_simulation_options) before it gets here.
  const bool langevin = options.thermostat == Thermostat::langevin;
  const auto steps = static_cast<std::size_t>(std::round(options.duration / options.time_step));
  const auto burn_steps = static_cast<std::size_t>(std::round(options.burn_in / options.time_step));

  DynamicsWorkspace<Real> ws(chain);
  // The run lives in the link frame; the state is written back for observers and at the end.
  load_links(state, ws);
  velocity_stage(ws, false);  // the initial momenta onto the cotangent space
  const Real h(options.time_step);
  const Real beta(options.beta.value_or(1)), friction(options.friction.value_or(1));
  std::mt19937_64 rng(options.seed.value_or(1));
  const Real start_time = state.time;

  // Observables per sample: K_i (n), K_i^(c) (n), cos phi_i (n), K, U, E.
  const std::size_t width = 3 * n + 3;
  std::vector<Real> sample(width);
  SimulationResult<Real> out;
  out.method = langevin ? Method::dynamics_langevin : Method::dynamics_nve;
  begin_run(chain, options, langevin, ws, sample, out);

  auto advance = [&]() {
    if (langevin) {
      advance_baoab(chain, ws, h, beta, friction, rng);
    } else {
      advance_composition(chain, ws, h, options.integrator.value_or(default_integrator));
    }
  };
  const std::size_t total_steps = burn_steps + steps;
  // Every 1% or every 1024 steps, whichever comes first: a long run (1e9 steps) reports within
  // a fraction of a second, and a front end throttles what it prints.
  const std::size_t progress_every =
      std::clamp<std::size_t>(total_steps / 100, 1, 1024);
  // The stop flag is read after about 65536 link updates, at most every 1024 steps: 1024 steps
  // of a long chain take seconds, and a signal must end a run well within the 1 s that mpirun
  // leaves before it kills the ranks. (A power of two: a mask per step, not a division.)
  const std::size_t stop_mask =
      std::bit_floor(std::clamp<std::size_t>(65536 / chain.size(), 1, 1024)) - 1;
  auto export_state = [&](std::size_t step) {
    store_links(ws, state);
    state.time = start_time + Real(static_cast<double>(step)) * h;
  };

  // Finest blocks: as short as max_blocks allows for the planned samples (>= block_samples).
  const std::size_t block_length =
      std::max(options.block_samples, (steps + options.max_blocks - 1) / options.max_blocks);
  BlockAverager<Real> blocks(width, block_length, options.max_blocks);
  Real energy_error_max = 0, energy_error_squares = 0;
  std::size_t done = 0;
  if (observer.trajectory) {
    export_state(0);
    observer.trajectory(state);
  }
  for (std::size_t step = 1; step <= total_steps; ++step) {
    advance();
    ++done;
    Real kinetic = 0, potential = 0;
    link_observables(chain, ws, sample.data(), kinetic, potential);
    const Real energy = kinetic + potential;
    if (!langevin) {
      const Real e = energy - out.initial_energy;
      energy_error_max = std::max(energy_error_max, abs(e));
      energy_error_squares += e * e;
    }
    if (step > burn_steps) {
      sample[3 * n] = kinetic;
      sample[3 * n + 1] = potential;
      sample[3 * n + 2] = energy;
      blocks.add(sample.data());
    }
    if (observer.trajectory && observer.trajectory_every > 0 &&
        step % observer.trajectory_every == 0) {
      export_state(step);
      observer.trajectory(state);
    }
    if (observer.progress && step % progress_every == 0)
      observer.report(static_cast<double>(step) / static_cast<double>(total_steps));
    if ((step & 1023) == 0)
      out.constraint_residual = std::max(out.constraint_residual, link_constraint_residual(ws));
    if ((step & stop_mask) == 0 && observer.stop_requested()) {
      out.interrupted = step < total_steps;
      break;
    }
  }
  finish_run(chain, options, langevin, ws, blocks, sample, done, energy_error_max,
             energy_error_squares, out);
  return out;
}

// ---------------------------------------------------------------- Poincare section

namespace {

/// x_1 of the state and its rate (the first particle's horizontal coordinate and velocity).
template <class Real>
struct SectionCoordinate {
  Real x, xdot, y;
};

template <class Real>
SectionCoordinate<Real> section_coordinate(const Chain<Real>& chain, const ChainState<Real>& s) {
  return {s.position[0], s.momentum[0] / chain.mass(0), s.position[1]};
}

/// The root in [0, h] of the cubic Hermite interpolant of x(t) with x(0) = x0 < 0 <= x(h) = x1.
template <class Real>
Real hermite_crossing(const Real& x0, const Real& v0, const Real& x1, const Real& v1,
                      const Real& h) {
  auto value = [&](const Real& s) {  // s in [0, 1]
    const Real s2 = s * s, s3 = s2 * s;
    return (2 * s3 - 3 * s2 + 1) * x0 + (s3 - 2 * s2 + s) * h * v0 + (-2 * s3 + 3 * s2) * x1 +
           (s3 - s2) * h * v1;
  };
  Real lo = 0, hi = 1;
  for (int it = 0; it < 60; ++it) {
    const Real mid = (lo + hi) / 2;
    if (value(mid) < 0) {
      lo = mid;
    } else {
      hi = mid;
    }
  }
  return (lo + hi) / 2 * h;
}

}  // namespace

/// The request of a section, checked before any step (invalid_input in one line): N = 2, a finite
/// energy above the minimum -(gamma_1 + gamma_2), g > 0, a positive time step, orbits, points.
template <class Real>
void check_section_request(const Chain<Real>& chain, const Real& energy,
                           const PoincareOptions& options) {
  if (chain.size() != 2) throw invalid_input("poincare: the section is defined for N = 2");
  if (!std::isfinite(static_cast<double>(energy))) throw invalid_input("poincare: energy must be finite");
  if (!(chain.gravity() > 0)) throw invalid_input("poincare: needs g > 0");
  const Real g1 = chain.potential_coefficient(0), g2 = chain.potential_coefficient(1);
  if (!(energy > -(g1 + g2)))
    throw invalid_input("poincare: the energy must exceed the minimum -(gamma_1 + gamma_2) = " +
                        fixed_decimal(static_cast<double>(-(g1 + g2))));
  if (!(options.time_step > 0) || !std::isfinite(options.time_step))
    throw invalid_input("poincare: the time step must be positive and finite");
  if (options.orbits == 0 || options.points == 0)
    throw invalid_input("poincare: orbits and points must be positive");
}

/// The orbits' starting points on the section (phi1 = 0): even orbits on p2 = 0 over phi2 in
/// [0, phi2_max), odd ones on phi2 = 0 over |p2| < p2_max, p2_max^2 = 2 A_3 (E + g1 + g2).
template <class Real>
[[gnu::always_inline]] inline void section_starts(const Real& energy, const Real& g1,
                                                  const Real& g2, const Real& phi2_max,
                                                  const Real& a3, PoincareSection<Real>& out) {
  const std::size_t orbits = out.start_phi2.size();
  for (std::size_t k = 0; k < orbits; ++k) {
    // Even orbits on p2 = 0 over phi2 in [0, phi2_max), odd ones on phi2 = 0 over |p2| < p2_max.
    const std::size_t half = (orbits + 1) / 2;
    if (k % 2 == 0) {
      const Real f = (Real(k / 2) + Real(0.5)) / Real(half);
      out.start_phi2[k] = f * phi2_max * Real(0.98);
      out.start_p2[k] = 0;
    } else {
      const std::size_t odd = orbits / 2;
      const Real f = (Real(k / 2) + Real(0.5)) / Real(odd);  // (0, 1)
      const Real p2_max = sqrt(2 * a3 * (energy + g1 + g2));
      out.start_phi2[k] = 0;
      out.start_p2[k] = (2 * f - 1) * p2_max * Real(0.98);
    }
  }
}

/// The work of each orbit, bounded before any step, and the energy scale M g L the errors are
/// relative to (refused when the scales overflow double or the time step is unstable).
template <class Real>
struct SectionBudget {
  double max_time = 0;
  std::size_t max_steps = 0;
  Real scale{};
};

template <class Real>
[[gnu::always_inline]] inline SectionBudget<Real> section_budget(const Chain<Real>& chain,
                                                                 const Real& energy,
                                                                 const PoincareOptions& options) {
  SectionBudget<Real> budget;
  const double max_time =
      options.max_time > 0 ? options.max_time : 200.0 * static_cast<double>(options.points);
  // Bounded work, decided before any: at most 1e12 steps per orbit.
  const double steps_needed = std::ceil(max_time / options.time_step);
  if (!(steps_needed <= 1e12))
    throw invalid_input("poincare: a time step of " + short_decimal(options.time_step) +
                        " needs " + short_decimal(steps_needed) + " steps per orbit (over 1e12)"
                        "; use a larger --dt or a shorter --max-time");
  budget.max_time = max_time;
  budget.max_steps = static_cast<std::size_t>(steps_needed);
  Real mass_sum = chain.mass(0) + chain.mass(1), length_sum = chain.length(0) + chain.length(1);
  const Real scale = mass_sum * chain.gravity() * length_sum;
  using std::isfinite;
  if (!isfinite(scale) || !isfinite(energy * mass_sum * length_sum * length_sum))
    throw invalid_input("poincare: the energy and inertia scales (M g L = " +
                        short_decimal(static_cast<long double>(mass_sum) * static_cast<long double>(chain.gravity()) *
                                      static_cast<long double>(length_sum)) + ", E M L^2 = " +
                        short_decimal(static_cast<long double>(energy) * static_cast<long double>(mass_sum) *
                                      static_cast<long double>(length_sum) * static_cast<long double>(length_sum)) +
                        ") overflow double; choose units nearer 1");
  // Then the time step (its frequency estimate needs finite scales).
  domain::check_stable_time_step(chain, options.time_step,
                                 static_cast<long double>(energy) + static_cast<long double>(scale),
                                 "poincare", max_time, 1e12);
  budget.scale = scale;
  return budget;
}

/// The crossing of the section (phi1 = 0 upwards) between `previous` and the step after it:
/// the cubic Hermite guess of the time, refined by Newton steps on a partial step from
/// `previous`; returns the state on the section.
template <class Real>
[[gnu::always_inline]] inline ChainState<Real> section_crossing(
    const Chain<Real>& chain, const ChainState<Real>& previous, const SectionCoordinate<Real>& a,
    const SectionCoordinate<Real>& b, const Real& h, const DynamicsWorkspace<Real>& ws) {
  Real tau = hermite_crossing(a.x, a.xdot, b.x, b.xdot, h);
  ChainState<Real> on;
  DynamicsWorkspace<Real> ws_partial = ws;
  for (int refine = 0; refine < 4; ++refine) {
    on = previous;
    ws_partial = ws;
    if (tau > 0) yoshida4_step_kernel(chain, on, tau, ws_partial);
    const SectionCoordinate<Real> c = section_coordinate(chain, on);
    if (c.xdot == 0) break;
    const Real correction = -c.x / c.xdot;
    tau += correction;
    if (abs(correction) <= 4 * std::numeric_limits<Real>::epsilon() * h) break;
  }
  return on;
}

template <class Real>
PoincareSection<Real> poincare_section_kernel(const Chain<Real>& chain, const Real& energy,
                                       const PoincareOptions& options,
                                       const DynamicsObserver<Real>& observer) {
  check_section_request(chain, energy, options);
  const Real g1 = chain.potential_coefficient(0), g2 = chain.potential_coefficient(1);
  const Real pi = boost::math::constants::pi<Real>();
  const Real m2 = chain.mass(1), l2 = chain.length(1);
  // On the section (phi1 = 0): U = -g1 - g2 cos phi2 and p2^2 <= 2 A_3 (E - U), A_3 = m2 l2^2
  // (paper Appendix E). Allowed phi2: cos phi2 > -(E + g1)/g2.
  const Real cmin = -(energy + g1) / g2;
  const Real phi2_max = cmin <= -1 ? pi : std::acos(static_cast<double>(cmin)) * Real(1);
  const Real a3 = m2 * l2 * l2;
  const std::size_t orbits = options.orbits;
  PoincareSection<Real> out;
  out.energy = energy;
  out.start_phi2.resize(orbits);
  out.start_p2.resize(orbits);
  section_starts(energy, g1, g2, phi2_max, a3, out);
  const SectionBudget<Real> budget = section_budget(chain, energy, options);
  const std::size_t max_steps = budget.max_steps;
  const Real& scale = budget.scale;
  const Real h(options.time_step);

  std::vector<std::vector<SectionPoint<Real>>> per_orbit(orbits);
  std::vector<Real> energy_error(orbits, Real(0));
  std::vector<std::size_t> steps_taken(orbits, 0);
  std::vector<char> interrupted(orbits, 0);
  // Progress in section points: an orbit adds one unit per point and the rest of its
  // options.points when it ends (at max_steps or stopped), so a long orbit shows progress too.
  const double total_units = static_cast<double>(orbits) * static_cast<double>(options.points);
  std::atomic<std::size_t> units{0};
  std::atomic<std::size_t> reported{0};  // units at the last report (every 1/200th at most)
  const auto report = [&](bool last) {
    if (!observer.progress) return;
    const std::size_t now = units.load(std::memory_order_relaxed);
    std::size_t before = reported.load(std::memory_order_relaxed);
    if (!last && static_cast<double>(now - std::min(now, before)) * 200 < total_units) return;
    if (!reported.compare_exchange_strong(before, now)) return;
#pragma omp critical(pendavg_poincare_progress)
    observer.report(static_cast<double>(now) / total_units);
  };
  ParallelErrors errors;  // an exception may not leave the parallel region
#pragma omp parallel for schedule(dynamic, 1) num_threads(options.threads) if (options.threads > 1)
  for (std::size_t k = 0; k < orbits; ++k) errors.capture([&] {
    const Real phi2 = out.start_phi2[k], p2 = out.start_p2[k];
    // p1 from (A_3 p1 - A_2 p2)^2 = det A (2 A_3 (E - U) - p2^2), positive root (Appendix E).
    const Real u = -g1 - g2 * cos(phi2);
    const Real a1 = chain.total_mass() * chain.length(0) * chain.length(0);
    const Real a2 = m2 * chain.length(0) * l2 * cos(phi2);
    const Real det = a1 * a3 - a2 * a2;
    Real disc = det * (2 * a3 * (energy - u) - p2 * p2);
    if (disc < 0) disc = 0;
    const Real p1 = (a2 * p2 + sqrt(disc)) / a3;
    ChainState<Real> st = state_from_canonical_kernel(chain, {Real(0), phi2}, {p1, p2});
    DynamicsWorkspace<Real> ws(chain);
    project_momenta_kernel(chain, st, ws);
    const Real e0 = total_energy_kernel(chain, st);
    Real worst = abs(e0 - energy);
    std::vector<SectionPoint<Real>>& points = per_orbit[k];
    ChainState<Real> previous = st;
    std::size_t step = 0;
    while (points.size() < options.points && step < max_steps) {
      previous = st;
      yoshida4_step_kernel(chain, st, h, ws);
      ++step;
      if ((step & 1023) == 0) {
        worst = std::max(worst, abs(total_energy_kernel(chain, st) - energy));
        if (observer.stop_requested()) {
          interrupted[k] = 1;
          break;
        }
        report(false);
      }
      const SectionCoordinate<Real> a = section_coordinate(chain, previous);
      const SectionCoordinate<Real> b = section_coordinate(chain, st);
      if (!(a.x < 0 && b.x >= 0 && a.y < 0 && b.y < 0)) continue;
      // Crossing phi1 = 0 upwards (x1 increasing below the pivot: phidot1 > 0).
      const ChainState<Real> on = section_crossing(chain, previous, a, b, h, ws);
      const ChainObservables<Real> o = observables_kernel(chain, on);
      SectionPoint<Real> point;
      point.orbit = k;
      point.phi2 = o.phi[1];
      point.p2 = o.p_phi[1];
      point.time = on.time;
      points.push_back(point);
      units.fetch_add(1, std::memory_order_relaxed);
    }
    worst = std::max(worst, abs(total_energy_kernel(chain, st) - energy));
    energy_error[k] = worst / scale;
    steps_taken[k] = step;
    units.fetch_add(options.points - points.size(), std::memory_order_relaxed);
    report(false);
  });
  report(true);
  errors.rethrow();
  for (std::size_t k = 0; k < orbits; ++k) {
    out.points.insert(out.points.end(), per_orbit[k].begin(), per_orbit[k].end());
    out.energy_error_max = std::max(out.energy_error_max, energy_error[k]);
    out.steps += steps_taken[k];
    out.interrupted = out.interrupted || interrupted[k] != 0;
  }
  return out;
}

PENDAVG_DYNAMICS_KERNELS_INSTANTIATE(double)
PENDAVG_DYNAMICS_KERNELS_INSTANTIATE(long double)

}  // namespace pendavg::PENDAVG_DYNAMICS_ISA
