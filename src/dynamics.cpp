// Constrained symplectic dynamics of the N-link chain: see pendavg/dynamics.hpp.
#include "pendavg/dynamics.hpp"

#include "pendavg/detail/blocking.hpp"

#include <Eigen/Dense>
#include <boost/math/constants/constants.hpp>

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>

namespace pendavg {

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

/// Link vectors r_i = x_i - x_{i-1} (x_{-1} = pivot = 0) into `link` (2N).
template <class Real>
void link_vectors(const std::vector<Real>& x, std::vector<Real>& link, std::size_t n) {
  link[0] = x[0];
  link[1] = x[1];
  for (std::size_t i = 1; i < n; ++i) {
    link[2 * i] = x[2 * i] - x[2 * i - 2];
    link[2 * i + 1] = x[2 * i + 1] - x[2 * i - 1];
  }
}

/// Continuants are renormalized when they leave [1/limit, limit] (a power of two far inside
/// the exponent range of Real).
template <class Real>
constexpr Real continuant_limit() {
  return Real(1.157920892373162e77);  // 2^256
}

/// Relative rounding of the tridiagonal solve's residual f + J ds (a generous multiple of eps).
template <class Real>
Real rounding_factor() {
  return Real(64) * std::numeric_limits<Real>::epsilon();
}

/// p_k -= tau m_k g y-hat: the kick of uniform gravity. The constraint impulse that belongs to
/// it (tau mu, mu the multiplier) is left to the next position or velocity stage, which
/// absorbs every normal momentum component; the workspace counts that pending kick time to
/// guess the next stage's multipliers.
template <class Real>
void gravity_kick(const Chain<Real>& chain, ChainState<Real>& st, const Real& tau,
                  DynamicsWorkspace<Real>& ws) {
  ws.pending_kick_time += tau;
  const Real g = chain.gravity();
  if (g == 0) return;
  for (std::size_t k = 0; k < chain.size(); ++k) st.momentum[2 * k + 1] -= tau * chain.mass(k) * g;
}

/// Position stage: x_k <- x_k + tau p_k / m_k + (s_{k+1} r_{k+1} - s_k r_k) / m_k with the N
/// scaled multipliers s chosen so that every link has its length at the new positions; p
/// receives the matching impulse (s_{k+1} r_{k+1} - s_k r_k) / tau. With r_i the links at the
/// old positions,
///   r'_i(s) = rt_i - s_i w_i r_i + s_{i+1} r_{i+1} / m_i + s_{i-1} r_{i-1} / m_{i-1},
///   rt_i = r_i + tau (v_i - v_{i-1}),  w_i = 1/m_i + 1/m_{i-1}  (1/m_{-1} = 0, s_N = 0),
///   f_i(s) = (|r'_i|^2 - l_i^2) / 2 = 0.
/// f is quadratic in s, so Newton converges quadratically from a good guess; its Jacobian
/// df_i/ds_j = r'_i . dr'_i/ds_j is tridiagonal (-H at tau = 0, H = G M^{-1} G^T, diagonally
/// dominant enough that Thomas' algorithm needs no pivoting at any usable step) and each
/// iteration costs O(N). `slot` >= 0 names the stage's place in its composition: the guess is
/// then the linear extrapolation of that slot's multipliers over the last two steps (error
/// O(h^2), so one Newton solve usually suffices); otherwise (or for the first two steps)
/// s = tau (pending kick time) mu from the last velocity stage.
template <class Real>
void constrained_drift(const Chain<Real>& chain, ChainState<Real>& st, const Real& tau,
                       DynamicsWorkspace<Real>& ws, int slot = -1) {
  const std::size_t n = chain.size();
  std::vector<Real>& x = st.position;
  std::vector<Real>& p = st.momentum;
  const std::vector<Real>& im = ws.inv_mass;
  std::vector<Real>& r = ws.link;
  std::vector<Real>& rt = ws.trial_link;
  std::vector<Real>& s = ws.multiplier;
  const std::vector<Real>& w = ws.joint_compliance;  // 1/m_i + 1/m_{i-1}
  const std::vector<Real>& inv_l2 = ws.inv_length_squared;
  typename DynamicsWorkspace<Real>::StageHistory* history =
      slot >= 0 ? &ws.stage_history(static_cast<std::size_t>(slot)) : nullptr;
  const bool extrapolate = history != nullptr && history->count >= 2;
  const Real guess_scale = tau * ws.pending_kick_time;
  // Links r_i, trial links rt_i = r_i + tau (v_i - v_{i-1}) and the guess, in one pass.
  {
    Real x_prev = 0, y_prev = 0, vx_prev = 0, vy_prev = 0;
    for (std::size_t i = 0; i < n; ++i) {
      const Real rx = x[2 * i] - x_prev, ry = x[2 * i + 1] - y_prev;
      x_prev = x[2 * i];
      y_prev = x[2 * i + 1];
      r[2 * i] = rx;
      r[2 * i + 1] = ry;
      const Real vx = p[2 * i] * im[i], vy = p[2 * i + 1] * im[i];
      rt[2 * i] = rx + tau * (vx - vx_prev);
      rt[2 * i + 1] = ry + tau * (vy - vy_prev);
      vx_prev = vx;
      vy_prev = vy;
      s[i] = extrapolate ? 2 * history->last[i] - history->before[i]
                         : guess_scale * ws.multiplier_estimate[i];
    }
  }

  const Real tolerance =
      Real(ws.newton_tolerance_ulps) * std::numeric_limits<Real>::epsilon();
  std::vector<Real>& trial = ws.trial;  // r'_i(s), 2N
  std::vector<Real>& f = ws.residual;
  std::vector<Real>& cp = ws.pivot;
  std::vector<Real>& y = ws.rhs;
  Real worst = 0;
  // One pass computes the trial links r'(s) and the residuals f; with `sweep` it also builds
  // the Jacobian rows and runs the forward sweep of Thomas' algorithm for J ds = -f. The
  // pivots d_i - a_i c'_{i-1} are ratios theta_i / theta_{i-1} of continuants (theta_i =
  // d_i theta_{i-1} - a_i c_{i-1} theta_{i-2}), so the serial chain holds multiplications
  // only and the divisions run side by side; theta is renormalized for long chains. The first
  // pass always sweeps (a guess is never exact to a few ulps), later ones only when needed.
  auto pass = [&](bool sweep) {
    worst = 0;
    Real theta_prev = 1, theta_prev2 = 0, c_prev = 0, y_prev = 0;
    for (std::size_t i = 0; i < n; ++i) {
      Real lx = rt[2 * i] - s[i] * w[i] * r[2 * i];
      Real ly = rt[2 * i + 1] - s[i] * w[i] * r[2 * i + 1];
      if (i + 1 < n) {
        lx += s[i + 1] * im[i] * r[2 * i + 2];
        ly += s[i + 1] * im[i] * r[2 * i + 3];
      }
      if (i > 0) {
        lx += s[i - 1] * im[i - 1] * r[2 * i - 2];
        ly += s[i - 1] * im[i - 1] * r[2 * i - 1];
      }
      trial[2 * i] = lx;
      trial[2 * i + 1] = ly;
      // (|r'|^2 - l^2)/2 as a difference of squares is accurate to ~ulp(l^2): all we ask.
      const Real fi = (lx * lx + ly * ly) / 2 - ws.half_length_squared[i];
      f[i] = fi;
      worst = std::max(worst, abs(fi) * inv_l2[i]);
      if (!sweep) continue;
      const Real d = -w[i] * (lx * r[2 * i] + ly * r[2 * i + 1]);
      const Real a = i > 0 ? im[i - 1] * (lx * r[2 * i - 2] + ly * r[2 * i - 1]) : Real(0);
      const Real c = i + 1 < n ? im[i] * (lx * r[2 * i + 2] + ly * r[2 * i + 3]) : Real(0);
      Real theta = d * theta_prev - a * c_prev * theta_prev2;
      const Real inv = theta_prev / theta;  // 1 / pivot_i
      cp[i] = c * inv;
      y_prev = (-fi - a * y_prev) * inv;
      y[i] = y_prev;
      c_prev = c;
      if (abs(theta) > continuant_limit<Real>() || abs(theta) < 1 / continuant_limit<Real>()) {
        const Real scale = 1 / abs(theta);  // any scale works: only ratios are used
        theta *= scale;
        theta_prev *= scale;
      }
      theta_prev2 = theta_prev;
      theta_prev = theta;
    }
  };
  for (int iteration = 0;; ++iteration) {
    pass(iteration == 0);
    if (worst <= tolerance) break;
    if (iteration >= ws.max_newton_iterations) {
      ++ws.unconverged_stages;
      break;
    }
    if (iteration > 0) pass(true);  // the Jacobian at the current s
    Real next = y[n - 1];
    s[n - 1] += next;
    y[n - 1] = next;
    for (std::size_t i = n - 1; i-- > 0;) {
      next = y[i] - cp[i] * next;
      s[i] += next;
      y[i] = next;  // the step ds
    }
    ++ws.newton_solves;
    // f is quadratic in s: after a Newton step ds, f(s + ds) = f(s) + J ds + |dr'_i(ds)|^2 / 2
    // with f(s) + J ds = 0 up to the rounding of the solve (relative ~eps to the old f, which is
    // itself tiny by now). So when |dr'_i| <= |ds_i| w_i l_i + |ds_{i+1}| l_{i+1} / m_i +
    // |ds_{i-1}| l_{i-1} / m_{i-1} bounds the new residual below the tolerance, the stage has
    // converged without a check pass (the usual case: one solve from the extrapolated guess).
    Real predicted = 0;
    for (std::size_t i = 0; i < n; ++i) {
      Real bound = abs(y[i]) * w[i] * ws.length[i];
      if (i + 1 < n) bound += abs(y[i + 1]) * im[i] * ws.length[i + 1];
      if (i > 0) bound += abs(y[i - 1]) * im[i - 1] * ws.length[i - 1];
      predicted = std::max(predicted, (bound * bound / 2 + abs(f[i]) * rounding_factor<Real>()) * inv_l2[i]);
    }
    if (predicted <= tolerance / 2) {
      worst = predicted;
      break;
    }
  }
  ++ws.position_stages;
  ws.pending_kick_time = 0;
  ws.largest_stage_residual = std::max(ws.largest_stage_residual, worst);
  if (history != nullptr) {
    history->before.swap(history->last);
    history->last.resize(n);
    std::copy(s.begin(), s.end(), history->last.begin());
    ++history->count;
  }
  // x_k += tau v_k + (s_{k+1} r_{k+1} - s_k r_k) / m_k;  p_k += (s_{k+1} r_{k+1} - s_k r_k) / tau.
  const Real inv_tau = Real(1) / tau;
  for (std::size_t k = 0; k < n; ++k) {
    Real jx = -s[k] * r[2 * k], jy = -s[k] * r[2 * k + 1];
    if (k + 1 < n) {
      jx += s[k + 1] * r[2 * k + 2];
      jy += s[k + 1] * r[2 * k + 3];
    }
    x[2 * k] += (tau * p[2 * k] + jx) * im[k];
    x[2 * k + 1] += (tau * p[2 * k + 1] + jy) * im[k];
    p[2 * k] += jx * inv_tau;
    p[2 * k + 1] += jy * inv_tau;
  }
}

/// Velocity stage: H t = b, b_i = r_i . (v_i - v_{i-1}), p_k += t_{k+1} r_{k+1} - t_k r_k.
/// With learn = true (a stage that closes kicks, not noise) mu = t / (pending kick time)
/// becomes the guess of the next position stages.
template <class Real>
void velocity_stage(const Chain<Real>& chain, ChainState<Real>& st, DynamicsWorkspace<Real>& ws,
                    bool learn = true) {
  const std::size_t n = chain.size();
  std::vector<Real>& p = st.momentum;
  const std::vector<Real>& im = ws.inv_mass;
  std::vector<Real>& r = ws.link;
  link_vectors(st.position, r, n);
  std::vector<Real>& t = ws.multiplier;
  std::vector<Real>& off = ws.sub;   // off[i] = H_{i,i-1}
  std::vector<Real>& dd = ws.pivot;  // LDL^T pivots
  // Forward sweep of LDL^T with the right-hand side; pivots D_i = theta_i / theta_{i-1} from
  // continuants (theta_i = H_ii theta_{i-1} - H_{i,i-1}^2 theta_{i-2}), as in the position stage.
  Real vx_prev = 0, vy_prev = 0, theta_prev = 1, theta_prev2 = 0;
  for (std::size_t i = 0; i < n; ++i) {
    const Real vx = p[2 * i] * im[i], vy = p[2 * i + 1] * im[i];
    const Real b = r[2 * i] * (vx - vx_prev) + r[2 * i + 1] * (vy - vy_prev);
    vx_prev = vx;
    vy_prev = vy;
    const Real w = im[i] + (i > 0 ? im[i - 1] : Real(0));
    const Real h_ii = w * (r[2 * i] * r[2 * i] + r[2 * i + 1] * r[2 * i + 1]);
    const Real h_off =
        i > 0 ? -im[i - 1] * (r[2 * i] * r[2 * i - 2] + r[2 * i + 1] * r[2 * i - 1]) : Real(0);
    Real theta = h_ii * theta_prev - h_off * h_off * theta_prev2;
    // ell_i = H_{i,i-1} / D_{i-1} = H_{i,i-1} theta_{i-2} / theta_{i-1}; 1 / D_i = theta_{i-1}/theta_i.
    const Real ell = i > 0 ? h_off * theta_prev2 / theta_prev : Real(0);
    off[i] = ell;
    dd[i] = theta_prev / theta;
    t[i] = b - (i > 0 ? ell * t[i - 1] : Real(0));
    if (abs(theta) > continuant_limit<Real>() || abs(theta) < 1 / continuant_limit<Real>()) {
      const Real scale = 1 / abs(theta);
      theta *= scale;
      theta_prev *= scale;
    }
    theta_prev2 = theta_prev;
    theta_prev = theta;
  }
  t[n - 1] *= dd[n - 1];
  for (std::size_t i = n - 1; i-- > 0;) t[i] = t[i] * dd[i] - off[i + 1] * t[i + 1];
  for (std::size_t k = 0; k < n; ++k) {
    Real jx = -t[k] * r[2 * k], jy = -t[k] * r[2 * k + 1];
    if (k + 1 < n) {
      jx += t[k + 1] * r[2 * k + 2];
      jy += t[k + 1] * r[2 * k + 3];
    }
    p[2 * k] += jx;
    p[2 * k + 1] += jy;
  }
  if (learn && ws.pending_kick_time != 0) {
    const Real inv = Real(1) / ws.pending_kick_time;
    for (std::size_t i = 0; i < n; ++i) ws.multiplier_estimate[i] = t[i] * inv;
  }
  ws.pending_kick_time = 0;
}


}  // namespace

// ---------------------------------------------------------------- states

template <class Real>
ChainState<Real> state_from_angles(const Chain<Real>& chain, const std::vector<Real>& phi,
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
ChainState<Real> state_from_canonical(const Chain<Real>& chain, const std::vector<Real>& phi,
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
  return state_from_angles(chain, phi, rates);
}

template <class Real>
ChainObservables<Real> observables(const Chain<Real>& chain, const ChainState<Real>& st) {
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
Real potential_energy(const Chain<Real>& chain, const ChainState<Real>& st) {
  Real u = 0;
  for (std::size_t k = 0; k < chain.size(); ++k) u += chain.mass(k) * st.position[2 * k + 1];
  return u * chain.gravity();
}

template <class Real>
Real total_energy(const Chain<Real>& chain, const ChainState<Real>& st) {
  Real kinetic = 0;
  for (std::size_t k = 0; k < chain.size(); ++k)
    kinetic += (st.momentum[2 * k] * st.momentum[2 * k] +
                st.momentum[2 * k + 1] * st.momentum[2 * k + 1]) /
               (2 * chain.mass(k));
  return kinetic + potential_energy(chain, st);
}

template <class Real>
Real constraint_residual(const Chain<Real>& chain, const ChainState<Real>& st) {
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
Real velocity_constraint_residual(const Chain<Real>& chain, const ChainState<Real>& st) {
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

// ---------------------------------------------------------------- workspace and steps

template <class Real>
DynamicsWorkspace<Real>::DynamicsWorkspace(const Chain<Real>& chain) : n_(chain.size()) {
  inv_mass.resize(n_);
  joint_compliance.resize(n_);
  inv_length_squared.resize(n_);
  half_length_squared.resize(n_);
  length.resize(n_);
  inv_length.resize(n_);
  for (std::size_t i = 0; i < n_; ++i) {
    inv_mass[i] = Real(1) / chain.mass(i);
    joint_compliance[i] = inv_mass[i] + (i > 0 ? inv_mass[i - 1] : Real(0));
    const Real l = chain.length(i);
    length[i] = l;
    inv_length[i] = Real(1) / l;
    inv_length_squared[i] = Real(1) / (l * l);
    half_length_squared[i] = l * l / 2;
  }
  link.assign(2 * n_, Real(0));
  trial_link.assign(2 * n_, Real(0));
  trial.assign(2 * n_, Real(0));
  for (auto* v : {&multiplier, &multiplier_estimate, &residual, &sub, &rhs, &pivot})
    v->assign(n_, Real(0));
}

template <class Real>
void project_momenta(const Chain<Real>& chain, ChainState<Real>& state,
                     DynamicsWorkspace<Real>& ws) {
  velocity_stage(chain, state, ws, /*learn=*/false);
}

template <class Real>
void rattle_step(const Chain<Real>& chain, ChainState<Real>& state, const Real& h,
                 DynamicsWorkspace<Real>& ws) {
  const Real half = h / 2;
  gravity_kick(chain, state, half, ws);
  constrained_drift(chain, state, h, ws, 0);
  gravity_kick(chain, state, half, ws);
  velocity_stage(chain, state, ws);
  state.time += h;
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
  }
  return {Real(1)};
}

template <class Real>
void composition_step(const Chain<Real>& chain, ChainState<Real>& state, const Real& h,
                      Integrator integrator, DynamicsWorkspace<Real>& ws) {
  const std::vector<Real>& w = ws.composition(integrator, composition_weights<Real>);
  // kick(w_1 h/2) drift(w_1 h) kick((w_1 + w_2) h/2) drift(w_2 h) ... drift(w_s h)
  // kick(w_s h/2) project. The position stages absorb the normal momentum components, so the
  // skipped intermediate velocity stages would change nothing but the multipliers.
  const std::size_t stages = w.size();
  gravity_kick(chain, state, w[0] * h / 2, ws);
  for (std::size_t j = 0; j < stages; ++j) {
    constrained_drift(chain, state, w[j] * h, ws, static_cast<int>(8 + j));
    const Real next = j + 1 < stages ? w[j + 1] : Real(0);
    gravity_kick(chain, state, (w[j] + next) * h / 2, ws);
  }
  velocity_stage(chain, state, ws);
  state.time += h;
}

template <class Real>
void yoshida4_step(const Chain<Real>& chain, ChainState<Real>& state, const Real& h,
                   DynamicsWorkspace<Real>& ws) {
  composition_step(chain, state, h, Integrator::yoshida4, ws);
}

template <class Real>
void baoab_step(const Chain<Real>& chain, ChainState<Real>& state, const Real& h,
                const Real& beta, const Real& friction, std::mt19937_64& rng,
                DynamicsWorkspace<Real>& ws) {
  using std::exp;
  using std::expm1;
  const Real half = h / 2;
  gravity_kick(chain, state, half, ws);   // B
  constrained_drift(chain, state, half, ws, 4);   // A (its end projection is folded into O's)
  // O: p <- c1 p + sqrt((1 - c1^2) m / beta) xi, then back to the cotangent space.
  const Real c1 = exp(-friction * h);
  const Real noise = sqrt(-expm1(-2 * friction * h) / beta);
  std::normal_distribution<double> normal(0.0, 1.0);
  for (std::size_t k = 0; k < chain.size(); ++k) {
    const Real sm = noise * sqrt(chain.mass(k));
    state.momentum[2 * k] = c1 * state.momentum[2 * k] + sm * Real(normal(rng));
    state.momentum[2 * k + 1] = c1 * state.momentum[2 * k + 1] + sm * Real(normal(rng));
  }
  velocity_stage(chain, state, ws, /*learn=*/false);
  constrained_drift(chain, state, half, ws, 5);  // A
  gravity_kick(chain, state, half, ws);  // B
  velocity_stage(chain, state, ws);
  state.time += h;
}

// ---------------------------------------------------------------- runs

template <class Real>
SimulationResult<Real> simulate(const Chain<Real>& chain, ChainState<Real> state,
                                const SimulationOptions& options,
                                const DynamicsObserver<Real>& observer) {
  const std::size_t n = chain.size();
  if (state.position.size() != 2 * n || state.momentum.size() != 2 * n)
    throw invalid_input("simulate: the state does not match the chain");
  if (!(options.time_step > 0) || !std::isfinite(options.time_step))
    throw invalid_input("simulate: the time step must be positive and finite");
  if (!(options.duration > 0) || !std::isfinite(options.duration))
    throw invalid_input("simulate: the duration must be positive and finite");
  if (!(options.burn_in >= 0) || !std::isfinite(options.burn_in))
    throw invalid_input("simulate: the burn-in must be non-negative and finite");
  const bool langevin = options.thermostat == Thermostat::langevin;
  if (langevin) {
    if (!(options.beta > 0) || !std::isfinite(options.beta))
      throw invalid_input("simulate: beta must be positive and finite");
    if (!(options.friction > 0) || !std::isfinite(options.friction))
      throw invalid_input("simulate: the friction must be positive and finite");
  }
  if (options.block_samples == 0 || options.max_blocks < 16)
    throw invalid_input("simulate: block_samples >= 1 and max_blocks >= 16 required");
  const double steps_d = std::round(options.duration / options.time_step);
  const double burn_d = std::round(options.burn_in / options.time_step);
  if (steps_d < 1 || steps_d > 1e15 || burn_d > 1e15)
    throw invalid_input("simulate: the duration must be at least one step and at most 1e15 steps");
  const auto steps = static_cast<std::size_t>(steps_d);
  const auto burn_steps = static_cast<std::size_t>(burn_d);

  DynamicsWorkspace<Real> ws(chain);
  velocity_stage(chain, state, ws, false);  // the initial momenta onto the cotangent space
  const Real h(options.time_step);
  const Real beta(options.beta), friction(options.friction);
  std::mt19937_64 rng(options.seed);

  Real mass_sum = 0, length_sum = 0;
  for (std::size_t i = 0; i < n; ++i) {
    mass_sum += chain.mass(i);
    length_sum += chain.length(i);
  }
  SimulationResult<Real> out;
  out.method = langevin ? Method::dynamics_langevin : Method::dynamics_nve;
  out.initial_energy = total_energy(chain, state);
  {
    const Real k0 = out.initial_energy - potential_energy(chain, state);
    out.energy_scale = chain.gravity() > 0 ? mass_sum * chain.gravity() * length_sum
                                           : abs(out.initial_energy) + k0;
    if (!(out.energy_scale > 0)) out.energy_scale = 1;
  }
  out.constraint_residual = constraint_residual(chain, state);

  auto advance = [&]() {
    if (langevin) {
      baoab_step(chain, state, h, beta, friction, rng, ws);
    } else if (options.integrator == Integrator::rattle2) {
      rattle_step(chain, state, h, ws);
    } else {
      composition_step(chain, state, h, options.integrator, ws);
    }
  };
  const std::size_t total_steps = burn_steps + steps;
  const std::size_t progress_every = std::max<std::size_t>(1, total_steps / 100);
  auto stop_requested = [&]() {
    return observer.stop != nullptr && observer.stop->load(std::memory_order_relaxed);
  };

  // Observables per sample: K_i (n), K_i^(c) (n), K, U, E.
  // Observables per sample: K_i (n), K_i^(c) (n), cos phi_i (n), K, U, E.
  const std::size_t width = 3 * n + 3;
  // Finest blocks: as short as max_blocks allows for the planned samples (>= block_samples).
  const std::size_t block_length =
      std::max(options.block_samples, (steps + options.max_blocks - 1) / options.max_blocks);
  detail::BlockAverager<Real> blocks(width, block_length, options.max_blocks);
  std::vector<Real> sample(width);
  std::vector<Real> tail_x(n), tail_y(n);
  Real energy_error_max = 0, energy_error_squares = 0;
  std::size_t done = 0;
  if (observer.trajectory) observer.trajectory(state);
  for (std::size_t step = 1; step <= total_steps; ++step) {
    advance();
    ++done;
    // Per-sample observables in one O(N) pass (cf. observables()).
    const std::vector<Real>& x = state.position;
    const std::vector<Real>& p = state.momentum;
    Real px = 0, py = 0;
    for (std::size_t i = n; i-- > 0;) {
      px += p[2 * i];
      py += p[2 * i + 1];
      tail_x[i] = px;
      tail_y[i] = py;
    }
    Real xprev = 0, yprev = 0, vxprev = 0, vyprev = 0, kinetic = 0, height = 0;
    for (std::size_t i = 0; i < n; ++i) {
      const Real im = ws.inv_mass[i];
      const Real rx = x[2 * i] - xprev, ry = x[2 * i + 1] - yprev;
      const Real vx = p[2 * i] * im, vy = p[2 * i + 1] * im;
      const Real p_phi = rx * tail_y[i] - ry * tail_x[i];
      const Real phidot = (rx * (vy - vyprev) - ry * (vx - vxprev)) * ws.inv_length_squared[i];
      const Real k = (p[2 * i] * vx + p[2 * i + 1] * vy) / 2;
      sample[i] = k;
      sample[n + i] = p_phi * phidot / 2;
      sample[2 * n + i] = -ry * ws.inv_length[i];  // cos phi_i
      kinetic += k;
      height += chain.mass(i) * x[2 * i + 1];
      xprev = x[2 * i];
      yprev = x[2 * i + 1];
      vxprev = vx;
      vyprev = vy;
    }
    const Real potential = height * chain.gravity();
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
        step % observer.trajectory_every == 0)
      observer.trajectory(state);
    if (observer.progress && step % progress_every == 0)
      observer.progress(static_cast<double>(step) / static_cast<double>(total_steps));
    if ((step & 1023) == 0) {
      out.constraint_residual = std::max(out.constraint_residual, constraint_residual(chain, state));
      if (stop_requested()) {
        out.interrupted = step < total_steps;
        break;
      }
    }
  }
  out.constraint_residual = std::max(out.constraint_residual, constraint_residual(chain, state));
  // The position stages' own residual |sigma|/l^2 ~ relative length error: include it.
  out.constraint_residual = std::max(out.constraint_residual, ws.largest_stage_residual);
  out.final_energy = total_energy(chain, state);
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

template <class Real>
PoincareSection<Real> poincare_section(const Chain<Real>& chain, const Real& energy,
                                       const PoincareOptions& options,
                                       const DynamicsObserver<Real>& observer) {
  if (chain.size() != 2) throw invalid_input("poincare: the section is defined for N = 2");
  if (!std::isfinite(static_cast<double>(energy))) throw invalid_input("poincare: energy must be finite");
  if (!(chain.gravity() > 0)) throw invalid_input("poincare: needs g > 0");
  const Real g1 = chain.potential_coefficient(0), g2 = chain.potential_coefficient(1);
  if (!(energy > -(g1 + g2)))
    throw invalid_input("poincare: the energy must exceed the minimum -(gamma_1 + gamma_2) = " +
                        std::to_string(static_cast<double>(-(g1 + g2))));
  if (!(options.time_step > 0) || !std::isfinite(options.time_step))
    throw invalid_input("poincare: the time step must be positive and finite");
  if (options.orbits == 0 || options.points == 0)
    throw invalid_input("poincare: orbits and points must be positive");
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
  const double max_time =
      options.max_time > 0 ? options.max_time : 200.0 * static_cast<double>(options.points);
  const auto max_steps = static_cast<std::size_t>(std::ceil(max_time / options.time_step));
  const Real h(options.time_step);
  Real mass_sum = chain.mass(0) + chain.mass(1), length_sum = chain.length(0) + chain.length(1);
  const Real scale = mass_sum * chain.gravity() * length_sum;

  std::vector<std::vector<SectionPoint<Real>>> per_orbit(orbits);
  std::vector<Real> energy_error(orbits, Real(0));
  std::vector<std::size_t> steps_taken(orbits, 0);
  std::vector<char> interrupted(orbits, 0);
  std::atomic<std::size_t> finished{0};
#pragma omp parallel for schedule(dynamic, 1) num_threads(options.threads) if (options.threads > 1)
  for (std::size_t k = 0; k < orbits; ++k) {
    const Real phi2 = out.start_phi2[k], p2 = out.start_p2[k];
    // p1 from (A_3 p1 - A_2 p2)^2 = det A (2 A_3 (E - U) - p2^2), positive root (Appendix E).
    const Real u = -g1 - g2 * cos(phi2);
    const Real a1 = chain.total_mass() * chain.length(0) * chain.length(0);
    const Real a2 = m2 * chain.length(0) * l2 * cos(phi2);
    const Real det = a1 * a3 - a2 * a2;
    Real disc = det * (2 * a3 * (energy - u) - p2 * p2);
    if (disc < 0) disc = 0;
    const Real p1 = (a2 * p2 + sqrt(disc)) / a3;
    ChainState<Real> st = state_from_canonical(chain, {Real(0), phi2}, {p1, p2});
    DynamicsWorkspace<Real> ws(chain);
    velocity_stage(chain, st, ws, false);
    const Real e0 = total_energy(chain, st);
    Real worst = abs(e0 - energy);
    std::vector<SectionPoint<Real>>& points = per_orbit[k];
    ChainState<Real> previous = st;
    std::size_t step = 0;
    while (points.size() < options.points && step < max_steps) {
      previous = st;
      yoshida4_step(chain, st, h, ws);
      ++step;
      if ((step & 1023) == 0) {
        worst = std::max(worst, abs(total_energy(chain, st) - energy));
        if (observer.stop != nullptr && observer.stop->load(std::memory_order_relaxed)) {
          interrupted[k] = 1;
          break;
        }
      }
      const SectionCoordinate<Real> a = section_coordinate(chain, previous);
      const SectionCoordinate<Real> b = section_coordinate(chain, st);
      if (!(a.x < 0 && b.x >= 0 && a.y < 0 && b.y < 0)) continue;
      // Crossing phi1 = 0 upwards (x1 increasing below the pivot: phidot1 > 0).
      Real tau = hermite_crossing(a.x, a.xdot, b.x, b.xdot, h);
      ChainState<Real> on;
      DynamicsWorkspace<Real> ws_partial = ws;
      for (int refine = 0; refine < 4; ++refine) {
        on = previous;
        ws_partial = ws;
        if (tau > 0) yoshida4_step(chain, on, tau, ws_partial);
        const SectionCoordinate<Real> c = section_coordinate(chain, on);
        if (c.xdot == 0) break;
        const Real correction = -c.x / c.xdot;
        tau += correction;
        if (abs(correction) <= 4 * std::numeric_limits<Real>::epsilon() * h) break;
      }
      const ChainObservables<Real> o = observables(chain, on);
      SectionPoint<Real> point;
      point.orbit = k;
      point.phi2 = o.phi[1];
      point.p2 = o.p_phi[1];
      point.time = on.time;
      points.push_back(point);
    }
    worst = std::max(worst, abs(total_energy(chain, st) - energy));
    energy_error[k] = worst / scale;
    steps_taken[k] = step;
    const std::size_t now = ++finished;
    if (observer.progress) {
#pragma omp critical(pendavg_poincare_progress)
      observer.progress(static_cast<double>(now) / static_cast<double>(orbits));
    }
  }
  for (std::size_t k = 0; k < orbits; ++k) {
    out.points.insert(out.points.end(), per_orbit[k].begin(), per_orbit[k].end());
    out.energy_error_max = std::max(out.energy_error_max, energy_error[k]);
    out.steps += steps_taken[k];
    out.interrupted = out.interrupted || interrupted[k] != 0;
  }
  return out;
}

#define PENDAVG_DYNAMICS_INSTANTIATE(Real)                                                      \
  template ChainState<Real> state_from_angles<Real>(const Chain<Real>&, const std::vector<Real>&, \
                                                    const std::vector<Real>&);                   \
  template ChainState<Real> state_from_canonical<Real>(                                         \
      const Chain<Real>&, const std::vector<Real>&, const std::vector<Real>&);                   \
  template ChainObservables<Real> observables<Real>(const Chain<Real>&, const ChainState<Real>&); \
  template Real potential_energy<Real>(const Chain<Real>&, const ChainState<Real>&);            \
  template Real total_energy<Real>(const Chain<Real>&, const ChainState<Real>&);                \
  template Real constraint_residual<Real>(const Chain<Real>&, const ChainState<Real>&);         \
  template Real velocity_constraint_residual<Real>(const Chain<Real>&, const ChainState<Real>&); \
  template class DynamicsWorkspace<Real>;                                                       \
  template void rattle_step<Real>(const Chain<Real>&, ChainState<Real>&, const Real&,           \
                                  DynamicsWorkspace<Real>&);                                    \
  template void yoshida4_step<Real>(const Chain<Real>&, ChainState<Real>&, const Real&,         \
                                    DynamicsWorkspace<Real>&);                                  \
  template void composition_step<Real>(const Chain<Real>&, ChainState<Real>&, const Real&,     \
                                       Integrator, DynamicsWorkspace<Real>&);                    \
  template void project_momenta<Real>(const Chain<Real>&, ChainState<Real>&,                    \
                                      DynamicsWorkspace<Real>&);                                \
  template void baoab_step<Real>(const Chain<Real>&, ChainState<Real>&, const Real&,            \
                                 const Real&, const Real&, std::mt19937_64&,                    \
                                 DynamicsWorkspace<Real>&);                                     \
  template SimulationResult<Real> simulate<Real>(const Chain<Real>&, ChainState<Real>,          \
                                                 const SimulationOptions&,                      \
                                                 const DynamicsObserver<Real>&);                \
  template PoincareSection<Real> poincare_section<Real>(const Chain<Real>&, const Real&,        \
                                                        const PoincareOptions&,                 \
                                                        const DynamicsObserver<Real>&);

PENDAVG_DYNAMICS_INSTANTIATE(double)
PENDAVG_DYNAMICS_INSTANTIATE(long double)

}  // namespace pendavg
