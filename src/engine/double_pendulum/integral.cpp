// SPDX-License-Identifier: GPL-3.0-or-later
// The exact 1-D reduced integral for the double pendulum (src/engine/double_pendulum/README.md,
// 'Reduced integral'), generic over Real, plus the engine dispatcher. See
// engine/double_pendulum/double_pendulum.hpp for the design.
//
// Integrals (t = phi2 - phi1 folded onto [0, pi/2] with t -> pi - t, q(t) = mu1 + mu2 sin^2 t,
// W(t) = I0(R(t)) e^{-(a1+a2)}, R(t)^2 = a1^2 + a2^2 + 2 a1 a2 cos t):
//   J_s  = int_0^{pi/2} q^s [W(t) + W(pi - t)] dt,          s = 1/2, -1/2, -3/2
//   C_j  = int_0^{pi/2} q^{1/2} [dW/da_j (t) + dW/da_j (pi - t)] dt,  j = 1, 2
// give beta<K1> = (mu1/2) J_{-1/2}/J_{1/2}, <cos phi_j> = C_j / J_{1/2}, and with x = mu1/q
// (= tr X_1): <x> = mu1 J_{-1/2}/J_{1/2}, <x^2> = mu1^2 J_{-3/2}/J_{1/2},
//   beta^2 Var K1 = (3/4)<x^2> - <x>^2/4,
//   beta^2 Var K2 = (1 - <x>) + <x>^2/2 + (3/4)(<x^2> - <x>^2)      (src/engine/README.md,
//   'Isserlis').
// On a cut range [0, T] (unfolded weight, Bessel weights at the nodes) J_{-3/2} is integrated
// by parts: with q' = 2 mu2 sin t cos t and mu1 + mu2 = 1,
//   mu1 J_{-3/2} = J_{1/2} - mu2 int_0^T sin t cos t q^{-1/2} W' dt + mu2 B(T),
//   B(t) = sin t cos t q^{-1/2} W(t),   W' = -a1 a2 sin t e^{-A} I1(R)/R <= 0,
// so both integrand terms are >= 0 and only q^{-1/2}'s branch point at q = 0 remains.
#include "engine/double_pendulum/double_pendulum.hpp"

#include "engine/numerics/bessel.hpp"
#include "engine/numerics/quadrature.hpp"
#include "engine/numerics/text.hpp"

#include <boost/math/constants/constants.hpp>
#include "engine/double_pendulum/fourier_moments.hpp"
#include "engine/detail/graf_rows.hpp"
#include "engine/double_pendulum/inner_panel_series.hpp"
#include <boost/math/special_functions/fpclassify.hpp>

#include <algorithm>
#include <array>
#include <limits>
#include <cmath>
#include <memory>
#include <string>
#include <type_traits>

namespace pendavg {

template <class Real>
DoublePendulumParameters<Real> double_pendulum_parameters(const Chain<Real>& chain,
                                                          const Real& beta) {
  if (chain.size() != 2) {
    throw invalid_input("the double-pendulum engines need 2 masses, got " +
                        std::to_string(chain.size()));
  }
  check_beta(beta);
  DoublePendulumParameters<Real> p;
  p.mu1 = chain.mass_fraction(0);
  p.mu2 = chain.mass_fraction(1);
  p.a1 = beta * chain.total_mass() * chain.gravity() * chain.length(0);
  p.a2 = beta * chain.mass(1) * chain.gravity() * chain.length(1);
  // a1 * a2 must stay representable (the integral forms 4 a1 a2), and in hardware floats the
  // weights' scaled Bessel functions over R ~ a1 + a2 (and R^2) must too: a1, a2 <= 1e150.
  if (!(boost::math::isfinite)(p.a1 * p.a2) || !(boost::math::isfinite)(p.a1 + p.a2) ||
      (!is_mpfr_v<Real> && !(p.a1 + p.a2 <= Real(1e150)))) {
    if constexpr (is_mpfr_v<Real>)
      throw invalid_input("beta g M l1 + beta g m2 l2 overflows MPFR's exponent range (the "
                          "integral forms their product, beyond 1e323228496)");
    else
      throw invalid_input("beta g M l1 + beta g m2 l2 = " +
                          short_decimal(static_cast<double>(p.a1 + p.a2)) +
                          " is beyond the double engine's range (1e150); request 17 or more "
                          "digits (MPFR)");
  }
  // The variances' integral J_{-3/2} grows like mu1^(-3/2) times the weight's peak: below
  // mu1 = 1e-150 it overflows double at large beta.
  if (!is_mpfr_v<Real> && !(p.mu1 >= Real(1e-150))) {
    throw invalid_input("the top mass is mu1 = m1/M = " + short_decimal(static_cast<double>(p.mu1)) +
                        " of the total, below the double engine's range (1e-150); request 17 "
                        "or more digits (MPFR)");
  }
  return p;
}

namespace {

using std::abs;
using std::asin;
using std::asinh;
using std::cosh;
using std::exp;
using std::log;
using std::pow;
using std::sin;
using std::sinh;
using std::sqrt;

constexpr std::size_t integral_count = integral::count;
template <class Real>
using Integrands = std::array<Real, integral_count>;

/// Relative tolerance each integral is driven to.
template <class Real>
Real integral_tolerance(int digits) {
  if constexpr (is_mpfr_v<Real>) {
    return pow(Real(10), -(digits + 2));
  } else {
    (void)digits;
    return unit_roundoff<Real>();
  }
}

template <class Real>
double to_double_saturated(const Real& x) {
  const double d = static_cast<double>(x);
  return (boost::math::isfinite)(d) ? d : std::numeric_limits<double>::max();
}

/// Node placement, returning the half-angle sine sh = sin(t/2) and dt/dx:
///  * t(x) = eps sinh(sigma x) (clusters nodes at t = 0, where q nearly vanishes when mu1 is
///    small and where the Boltzmann weight peaks when beta is large), or t = T x;
///  * half_angle: sin(t/2) = eps sinh(sigma x) itself, the same clustering without a sine per
///    node (t = 2 asin(sh), dt/dx = 2 d(sh)/dx / cos(t/2)). Used on cut ranges only, where the
///    branch point of asin at sh = 1 lies beyond the cut, under a weight below e^{-L}; eps is
///    then |sh| at the zero of q, so the zero sits at x = i pi/(2 sigma) in both maps.
template <class Real>
struct NodeMap {
  bool use_sinh = false;
  bool half_angle = false;
  Real eps = 0, sigma = 0, T = 0;
  Real v0 = 0;  // half_angle only: sin(t/2) = eps sinh(v0 + sigma x) (a panel away from t = 0)
  mutable Real arg_, e_, num_, den_;  // MPFR scratch: in-place arithmetic
  void operator()(const Real& x, Real& sh, Real& dtdx) const {
    if constexpr (is_mpfr_v<Real>) {
      if (use_sinh && half_angle) {
        // The same operations as below, in place.
        arg_ = sigma;
        arg_ *= x;
        arg_ += v0;
        e_ = sinh(arg_);
        sh = eps;
        sh *= e_;
        num_ = e_;
        num_ *= e_;
        num_ += 1;
        den_ = sh;
        den_ *= sh;
        den_ = 1 - den_;
        num_ /= den_;
        dtdx = sqrt(num_);
        dtdx *= eps;
        dtdx *= sigma;
        dtdx *= 2;
        return;
      }
    }
    if (use_sinh) {
      // sinh itself, not (e^s - e^-s)/2, which cancels for the small s near x = 0.
      const Real e = half_angle ? Real(sinh(v0 + sigma * x)) : Real(sinh(sigma * x));
      if (half_angle) {
        sh = eps * e;
        dtdx = 2 * eps * sigma * sqrt((1 + e * e) / (1 - sh * sh));
      } else {
        dtdx = eps * sigma * sqrt(1 + e * e);
        sh = sin(eps * e / 2);
      }
    } else {
      sh = sin(T * x / 2);
      dtdx = T;
    }
  }
};

/// Weight W and its a-derivatives from Graf's addition theorem (moderate a1, a2):
///   W(t) + W(pi - t) = 2 sum_k eps_{2k} I~_{2k}(a1) I~_{2k}(a2) T_k(cos 2t),  I~ = e^{-a} I.
template <class Real>
struct GrafWeights {
  std::vector<Real> c0, c1, c2;  // coefficients of T_k(y), y = cos 2t
  std::vector<double> error_ulps;  // rounding bound of c0[k], c1[k], c2[k], in roundoffs
  static constexpr bool by_parts = false;  // F[3] is not provided
  void operator()(const Real& sin2_t, const Real& /*half-angle sine*/,
                  std::array<Real, 4>& F) const {
    const Real y = 1 - 2 * sin2_t;
    const Real two_y = 2 * y;
    Real b0 = 0, b0n = 0, b1 = 0, b1n = 0, b2 = 0, b2n = 0, tmp;
    for (std::size_t k = c0.size(); k-- > 1;) {
      tmp = b0;
      b0 = c0[k] + two_y * b0 - b0n;
      b0n = tmp;
      tmp = b1;
      b1 = c1[k] + two_y * b1 - b1n;
      b1n = tmp;
      tmp = b2;
      b2 = c2[k] + two_y * b2 - b2n;
      b2n = tmp;
    }
    F[0] = c0[0] + y * b0 - b0n;
    F[1] = c1[0] + y * b1 - b1n;
    F[2] = c2[0] + y * b2 - b2n;
  }
};

/// Weight W and its a-derivatives from scaled Bessel functions at each node (large a1 + a2).
template <class Real>
struct DirectWeights {
  Real a1, a2, A, P;  // P = 4 a1 a2
  bool fold = true;   // add the reflected node pi - t
  Real negligible_exponent = std::numeric_limits<double>::infinity();  // see operator()
  // Without the fold F[3] = -W'(t) / sin t = a1 a2 e^{-A} I1(R) / R, for J_{-3/2} by parts.
  bool by_parts = false;
  // MPFR scratch (in-place arithmetic, no allocation per operation); A^2 and P/4 per call.
  mutable Real s2_{}, c2_{}, cos_t_{}, R_{}, E_{}, tmp_{}, ex_{}, g_{}, A2_{}, quarter_P_{}, y_{},
      dy_{}, b0_{}, b1_{};
  // MPFR, unfolded: e^{-R} I0(R), e^{-R} I1(R) from Hankel's series re-expanded over the
  // range of R at the nodes (set by the caller when that range is above the Hankel threshold).
  ScaledBesselI01Range<Real> bessel_range{};
  void operator()(const Real& sin2_t, const Real& sh, std::array<Real, 4>& F) const {
    if constexpr (is_mpfr_v<Real>) {
      if (!fold) {
        // The same operations as below, in place.
        if (A2_ == 0) {
          A2_ = A;
          A2_ *= A;
          quarter_P_ = P;
          quarter_P_ /= 4;
        }
        s2_ = sh;
        s2_ *= sh;
        cos_t_ = 1;
        cos_t_ -= s2_;
        cos_t_ -= s2_;
        tmp_ = P;
        tmp_ *= s2_;  // P s2
        R_ = A2_;
        R_ -= tmp_;
        R_ = sqrt(R_);
        E_ = R_;
        E_ += A;
        tmp_ /= E_;
        E_ = -tmp_;  // R - A = -P s2 / (R + A)
        ex_ = exp(E_);
        if (bessel_range.valid) {
          // y = 1/R; sums in (y - y0) by Horner's rule; prefactor sqrt(y / (2 pi)).
          y_ = 1;
          y_ /= R_;
          dy_ = y_;
          dy_ -= bessel_range.y0;
          const auto& c0 = bessel_range.c0;
          const auto& c1 = bessel_range.c1;
          b0_ = c0.back();
          b1_ = c1.back();
          for (std::size_t j = c0.size() - 1; j-- > 0;) {
            b0_ *= dy_;
            b0_ += c0[j];
            b1_ *= dy_;
            b1_ += c1[j];
          }
          tmp_ = sqrt(y_);
          tmp_ *= bessel_range.inv_sqrt_two_pi;
          tmp_ *= ex_;  // e^{R - A} sqrt(y / (2 pi))
          F[0] = b0_;
          F[0] *= tmp_;
          g_ = b1_;
          g_ *= tmp_;
          g_ *= y_;
        } else {
          const auto b = scaled_bessel_i01(R_);
          F[0] = b.i0e;
          F[0] *= ex_;
          g_ = b.i1e;
          g_ *= ex_;
          g_ /= R_;
        }
        F[1] = a2;
        F[1] *= cos_t_;
        F[1] += a1;
        F[1] *= g_;
        F[2] = a1;
        F[2] *= cos_t_;
        F[2] += a2;
        F[2] *= g_;
        if (by_parts) {
          F[3] = g_;
          F[3] *= quarter_P_;
        }
        return;
      }
    }
    const Real s2 = sh * sh;                // sin^2(t/2)
    const Real c2 = 1 - s2;                 // cos^2(t/2) >= 1/2 on [0, pi/2]
    const Real cos_t = c2 - s2;
    (void)sin2_t;
    // R(t)^2 = (a1 + a2)^2 - 4 a1 a2 sin^2(t/2): no cancellation for t <= pi/2.
    const Real R = sqrt(A * A - P * s2);
    const Real E = -P * s2 / (R + A);  // R - A without cancellation
    auto b = scaled_bessel_i01(R);
    const Real ex = exp(E);
    F[0] = b.i0e * ex;
    const Real g = b.i1e * ex / R;  // R >= |a1 - a2| + ... > 0 here
    F[1] = g * (a1 + a2 * cos_t);
    F[2] = g * (a2 + a1 * cos_t);
    if (by_parts) F[3] = g * (P / 4);
    if (fold) {
      // pi - t: R'^2 = (a1 - a2)^2 + 4 a1 a2 sin^2(t/2), R' - A = -4 a1 a2 cos^2(t/2)/(R' + A).
      const Real d = a1 - a2;
      const Real Rp = sqrt(d * d + P * s2);
      const Real Ep = -P * c2 / (Rp + A);
      // Below e^{-negligible_exponent} of the peak the reflected weight (and its a-derivatives,
      // at most A times larger) is far below the roundoff of the sum: skip its Bessel functions.
      if (Ep < -negligible_exponent) return;
      auto bp = scaled_bessel_i01(Rp);
      const Real exp_p = exp(Ep);
      F[0] += bp.i0e * exp_p;
      if (Rp > 0) {
        const Real gp = bp.i1e * exp_p / Rp;
        F[1] += gp * (a1 - a2 * cos_t);
        F[2] += gp * (a2 - a1 * cos_t);
      }
    }
  }
};

template <class Real>
struct LevelResult {
  Integrands<Real> value{}, error{};
  std::size_t nodes = 0;
  bool converged = false;
};

/// One node's integrands in MPFR with J_{-3/2} by parts: the operations of the generic node in
/// integrate_levels, in place (no allocation per operation).
template <class Real, class Weights>
void by_parts_node_in_place(const Real& mu1, const Real& mu2, const Real& inv_mu1,
                            const Weights& weights, const Real& sh, const Real& dtdx,
                            std::array<Real, 9>& node_scratch, std::array<Real, 4>& F,
                            Integrands<Real>& v) {
  node_scratch[0] = sh;
  node_scratch[0] *= sh;  // sin^2(t/2)
  node_scratch[1] = 1;
  node_scratch[1] -= node_scratch[0];  // cos^2(t/2)
  node_scratch[2] = node_scratch[0];
  node_scratch[2] *= node_scratch[1];
  node_scratch[2] *= 4;  // sin^2 t
  node_scratch[3] = node_scratch[2];
  node_scratch[3] *= mu2;
  node_scratch[3] += mu1;  // q
  mpfr_rec_sqrt(node_scratch[5].backend().data(), node_scratch[3].backend().data(),
                MPFR_RNDN);  // q^{-1/2}
  node_scratch[4] = node_scratch[3];
  node_scratch[4] *= node_scratch[5];  // sqrt(q) = q q^{-1/2}
  weights(node_scratch[2], sh, F);
  node_scratch[6] = dtdx;
  node_scratch[6] *= node_scratch[4];  // dt/dx q^{1/2}
  v[integral::J_half] = node_scratch[6];
  v[integral::J_half] *= F[0];
  v[integral::J_minus_half] = dtdx;
  v[integral::J_minus_half] *= node_scratch[5];
  v[integral::J_minus_half] *= F[0];
  // by parts (below): cos t = 1 - 2 sin^2(t/2)
  node_scratch[7] = 1;
  node_scratch[7] -= node_scratch[0];
  node_scratch[7] -= node_scratch[0];
  node_scratch[7] *= node_scratch[2];
  node_scratch[7] *= mu2;
  node_scratch[7] *= node_scratch[5];
  node_scratch[7] *= F[3];
  node_scratch[8] = node_scratch[4];
  node_scratch[8] *= F[0];
  node_scratch[7] += node_scratch[8];
  node_scratch[7] *= dtdx;
  v[integral::J_minus_three_halves] = node_scratch[7];
  v[integral::J_minus_three_halves] *= inv_mu1;
  v[integral::C_1] = node_scratch[6];
  v[integral::C_1] *= F[1];
  v[integral::C_2] = node_scratch[6];
  v[integral::C_2] *= F[2];
}

/// The integrands at the nodes x of one level (the even nodes' values moved from the coarser
/// level); returns the number of new nodes evaluated.
template <class Real, class Weights>
std::size_t level_node_values(const NodeMap<Real>& map, const Real& mu1, const Real& mu2,
                              const Weights& weights, const std::vector<Real>& x,
                              std::size_t level, std::vector<Integrands<Real>>& vals,
                              std::vector<Integrands<Real>>& coarse) {
  std::array<Real, 4> F{};
  std::array<Real, 9> node_scratch;
  Real sh, dtdx;
  const Real inv_mu1 = 1 / mu1;
  std::size_t nodes = 0;
  vals.resize(x.size());
  for (std::size_t j = 0; j < x.size(); ++j) {
    if (level > 0 && j % 2 == 0) {
      std::swap(vals[j], coarse[j / 2]);
      continue;
    }
    map(x[j], sh, dtdx);
    if constexpr (is_mpfr_v<Real>) {
      if (weights.by_parts) {
        by_parts_node_in_place(mu1, mu2, inv_mu1, weights, sh, dtdx, node_scratch, F, vals[j]);
        ++nodes;
        continue;
      }
    }
    const Real ch2 = 1 - sh * sh;
    const Real sin2_t = 4 * sh * sh * ch2;  // sin^2 t = 4 sin^2(t/2) cos^2(t/2)
    const Real q = mu1 + mu2 * sin2_t;
    const Real sq = sqrt(q);
    const Real iq = 1 / sq;
    weights(sin2_t, sh, F);
    auto& v = vals[j];
    v[integral::J_half] = dtdx * sq * F[0];
    v[integral::J_minus_half] = dtdx * iq * F[0];
    if (weights.by_parts) {
      // q^{-3/2} W integrated by parts (see by_parts_boundary): the integrand
      // [q^{1/2} W - mu2 sin t cos t q^{-1/2} W'] / mu1, both terms >= 0 for t <= pi/2,
      // keeps only q^{-1/2}'s branch point at q = 0 instead of q^{-3/2}'s stronger one.
      const Real cos_t = 1 - 2 * sh * sh;
      v[integral::J_minus_three_halves] = dtdx * (sq * F[0] + mu2 * sin2_t * cos_t * iq * F[3]) / mu1;
    } else {
      v[integral::J_minus_three_halves] = v[integral::J_minus_half] / q;
    }
    v[integral::C_1] = dtdx * sq * F[1];
    v[integral::C_2] = dtdx * sq * F[2];
    ++nodes;
  }
  return nodes;
}

/// The sums of one level, their L1 norms, and the two highest Chebyshev coefficients of the
/// interpolant in xi = 1 - 2x: a_n = (1/n) sum'' (-1)^j f_j (top), a_{n-1} = (2/n) sum''
/// (-1)^j xi_j f_j (next_top), with sum'' |f_j| (sample_l1) for their rounding.
template <class Real>
struct LevelSums {
  Integrands<Real> sum{}, l1{}, top{}, next_top{}, sample_l1{};
};

template <class Real>
[[gnu::always_inline]] inline void chebyshev_guard_sums(const std::vector<Real>& x, const std::vector<Real>& w,
                          const std::vector<Integrands<Real>>& vals, LevelSums<Real>& s) {
  const std::size_t n = x.size() - 1;
  // In-place updates (no multiprecision temporaries): the signs and the endpoint halves of
  // the Chebyshev sums are applied as additions, subtractions and one halving.
  Real xi, wf, scratch;
  if constexpr (!is_mpfr_v<Real>) {
    // Hardware floats: branch-free (sign and half as multipliers), into local sums (stores
    // through `s` may alias the nodes and values for the compiler), inlined into
    // integrate_levels: as a function of its own with sums in `s` the loop took twice the
    // instructions (tests/bench: the N = 2 cases of 41-200 nodes 12% slower).
    Integrands<Real> sum = s.sum, l1 = s.l1, top = s.top, next_top = s.next_top,
                     sample_l1 = s.sample_l1;
    for (std::size_t j = 0; j <= n; ++j) {
      const Real h = (j == 0 || j == n) ? Real(0.5) : Real(1);
      const Real hs = (j % 2 == 0) ? h : -h;
      const Real hsx = hs * (1 - 2 * x[j]);
      for (std::size_t k = 0; k < integral_count; ++k) {
        const Real f = vals[j][k];
        const Real wfk = w[j] * f;
        sum[k] += wfk;
        l1[k] += abs(wfk);
        top[k] += hs * f;
        next_top[k] += hsx * f;
        sample_l1[k] += h * abs(f);
      }
    }
    s.sum = sum;
    s.l1 = l1;
    s.top = top;
    s.next_top = next_top;
    s.sample_l1 = sample_l1;
  }
  for (std::size_t j = 0; is_mpfr_v<Real> && j <= n; ++j) {
    const bool endpoint = (j == 0 || j == n);
    const bool odd = (j % 2 == 1);
    xi = x[j];
    xi *= -2;
    xi += 1;
    for (std::size_t k = 0; k < integral_count; ++k) {
      const Real* f = &vals[j][k];
      wf = w[j];
      wf *= *f;
      s.sum[k] += wf;
      if (wf < 0) s.l1[k] -= wf; else s.l1[k] += wf;
      if (endpoint) {
        scratch = *f;
        scratch /= 2;
        f = &scratch;
      }
      if (odd) s.top[k] -= *f; else s.top[k] += *f;
      if (*f < 0) s.sample_l1[k] -= *f; else s.sample_l1[k] += *f;
      wf = *f;
      wf *= xi;
      if (odd) s.next_top[k] -= wf; else s.next_top[k] += wf;
    }
  }
}

/// MPFR pre-check of one level: its sums and the level-difference estimate alone (never larger
/// than the final one, which adds the Chebyshev guard, in diff_estimate). True when the level
/// may be accepted; then `sum` is zeroed for chebyshev_guard_sums.
template <class Real>
bool mpfr_level_candidate(const std::vector<Real>& w, const std::vector<Integrands<Real>>& vals,
                          std::size_t level, const Real& tol, const Integrands<Real>& previous,
                          Integrands<Real>& previous_diff, Integrands<Real>& sum,
                          Integrands<Real>& diff_estimate) {
  Real wf;
  for (std::size_t j = 0; j < vals.size(); ++j) {
    for (std::size_t k = 0; k < integral_count; ++k) {
      wf = w[j];
      wf *= vals[j][k];
      sum[k] += wf;
    }
  }
  bool candidate = level >= 2;
  for (std::size_t k = 0; k < integral_count; ++k) {
    Real& est = diff_estimate[k];
    est = abs(sum[k] - previous[k]);
    if (level >= 2 && previous_diff[k] > 0 && est < previous_diff[k]) {
      const Real r = est / previous_diff[k];
      previous_diff[k] = est;
      est *= r;
      est *= r;
    } else {
      previous_diff[k] = est;
    }
    const Real tol_k =
        (k == integral::J_half || k == integral::J_minus_half ? tol : 16 * tol) * abs(sum[k]);
    if (!(est <= tol_k)) candidate = false;
  }
  return candidate;
}

/// The error estimate of every integral at one level (into `error`), and whether all of them
/// pass the stopping test.
template <class Real>
bool level_errors(const LevelSums<Real>& s, std::size_t level, std::size_t n, const Real& tol,
                  const Integrands<Real>& previous, Integrands<Real>& previous_diff,
                  const Integrands<Real>& diff_estimate, Integrands<Real>& error) {
  const Real u = unit_roundoff<Real>();
  // One division (level_errors ran ~6% of a 65-node double case on its 30 divisions).
  const Real inv_n = 1 / Real(n);
  bool all_ok = level >= 2;
  for (std::size_t k = 0; k < integral_count; ++k) {
    // Rounding: a few ulps per node in the sum and in the Chebyshev coefficients.
    const Real rounding = 8 * u * (s.l1[k] + 2 * s.sample_l1[k] * inv_n);
    Real est;
    if (is_mpfr_v<Real>) {
      est = diff_estimate[k];  // formed by mpfr_level_candidate, as below
    } else if (level == 0) {
      est = abs(s.sum[k]);
    } else {
      const Real diff = abs(s.sum[k] - previous[k]);
      est = diff;
      // Geometric extrapolation e_L r^2, r = e_L / e_{L-1}: the doubling squares the error.
      if (level >= 2 && previous_diff[k] > 0 && diff < previous_diff[k]) {
        const Real r = diff / previous_diff[k];
        est = diff * r * r;
      }
      previous_diff[k] = diff;
    }
    const Real a_n = abs(s.top[k]) * inv_n, a_n1 = 2 * abs(s.next_top[k]) * inv_n;
    // max(64 max(|a_n|, |a_{n-1}|) / n^2, e_L r^2): calibrated on 254 (case, integral,
    // level >= 2) triples against 8192-node references at 40 digits, it never fell below
    // the true error (smallest ratio 14; median over-estimate 1.7e3), while the level
    // difference e_L min(1, r) alone under-estimated 5% of them (pre-asymptotic stalls).
    const Real chebyshev = 64 * (a_n > a_n1 ? a_n : a_n1) * inv_n * inv_n;
    if (chebyshev > est) est = chebyshev;
    error[k] = est > rounding ? est : rounding;
    // beta<K_i> needs J_{1/2}, J_{-1/2} to the full tolerance; J_{-3/2} (variances) and
    // C_1, C_2 (<cos phi>) may stop at a few roundings (their error is still reported).
    const bool kinetic = k == integral::J_half || k == integral::J_minus_half;
    const Real tol_k = (kinetic ? tol : 16 * tol) * abs(s.sum[k]);
    const Real noise = kinetic ? rounding : 2 * rounding;
    if (!(est <= (tol_k > noise ? tol_k : noise) || s.l1[k] == 0)) all_ok = false;
  }
  return all_ok;
}

/// Nested Clenshaw-Curtis on x in [0, 1] (levels n = 8 .. 8 2^max_level); stops when the
/// estimated error of J_{1/2}, J_{-1/2} is below tol |J| (16 tol for the others) or at the
/// rounding floor. The estimate of level L is the larger of 64 max(|a_n|, |a_{n-1}|)/n^2
/// (top Chebyshev coefficients) and e_L r^2 (level difference e_L, ratio r = e_L/e_{L-1}).
template <class Real, class Weights>
LevelResult<Real> integrate_levels(const NodeMap<Real>& map, const Real& mu1, const Real& mu2,
                                   const Weights& weights, const Real& tol,
                                   std::size_t max_level, bool base12,
                                   IntegralWorkspace<Real>& ws) {
  const auto shared_rule = shared_clenshaw_curtis_rule<Real>(base12 ? 12 : 8);
  const ClenshawCurtisRule<Real>& rule = *shared_rule;
  LevelResult<Real> out;
  Integrands<Real> previous{}, previous_diff{};
  if (ws.values.size() < 2) ws.values.resize(2);
  for (std::size_t level = 0; level <= max_level; ++level) {
    const auto& x = rule.nodes(level);
    const auto& w = rule.weights(level);
    // The nodes of the previous level are the even nodes of this one: move their values.
    std::swap(ws.values[0], ws.values[1]);
    auto& vals = ws.values[0];
    out.nodes += level_node_values(map, mu1, mu2, weights, x, level, vals, ws.values[1]);
    // The sums and the Chebyshev guard expose features the level differences have not yet
    // seen (pre-asymptotic stalls).
    LevelSums<Real> s;
    // MPFR: the level-difference estimate alone decides first whether this level can be
    // accepted at all; only then (or at the last level) are the guard's sums and the L1 norms
    // formed. A level the pre-check rejects is rejected by the full test too, unless the
    // rounding floor exceeded the tolerance (never at the MPFR tolerances, 10 digits above the
    // roundoff); its error is not reported, since a later level's replaces it.
    Integrands<Real> diff_estimate{};
    if constexpr (is_mpfr_v<Real>) {
      const bool candidate =
          mpfr_level_candidate(w, vals, level, tol, previous, previous_diff, s.sum, diff_estimate);
      if (!candidate && level < max_level) {
        out.value = s.sum;
        previous = s.sum;
        continue;
      }
      for (auto& v : s.sum) v = 0;
    }
    chebyshev_guard_sums(x, w, vals, s);
    const bool all_ok = level_errors(s, level, x.size() - 1, tol, previous, previous_diff,
                                     diff_estimate, out.error);
    out.value = s.sum;
    previous = s.sum;
    if (all_ok) {
      out.converged = true;
      break;
    }
  }
  return out;
}

/// Number of Graf terms m with e^{-a1} I_m(a1) e^{-a2} I_m(a2) above e^{-L}: the product
/// decays like exp(-m^2 / (2 a1 a2 / (a1 + a2))) and, for small a, like ((g/2)^m / m!)^2 with
/// g = sqrt(a1 a2). An estimate: graf_weights checks the actual tail and grows if needed.
inline double graf_terms_estimate(double a1, double a2, double L) {
  const double geometric_mean = std::sqrt(a1 * a2);
  if (!(geometric_mean > 0)) return 1.0;
  const double harmonic = a1 * a2 / (a1 + a2);
  const double gaussian = std::sqrt(2.0 * L * (harmonic + 0.5)) + 4.0;
  // 2 m ln(2m / (e g)) >= L. While 2m < e g the logarithm is negative (L > 0): no log needed.
  double m = 1.0;
  while (m < 1e7) {
    const double r = 2.0 * m / (2.718281828 * geometric_mean);
    if (!(r < 1.0 && L > 0) && 2.0 * m * std::log(r) >= L) break;
    m *= 1.25;
  }
  return std::min(gaussian, m + 2.0);
}

/// Graf coefficients for the folded weight, trimmed to the terms above exp(-L) of each scale.
/// The trim needs two negligible rows beyond the kept ones; a table that turns out too short is
/// rebuilt longer. MPFR sizes its tables from graf_orders_needed plus a margin of 12, so that
/// no table is rebuilt (a rebuild at twice the size can switch a large argument's recurrence
/// to a Miller run thousands of steps long). Hardware types keep graf_terms_estimate + 8: its
/// shorter tables keep the forward recurrence for large a (count^2 <= 2a), which costs less
/// than the occasional rebuild of ~20-50 entries.
/// `terms_estimate`: graf_terms_estimate(a1, a2, L) when the caller has it (hardware types).
/// `moment_terms`: for the exact sums, the number of rows beyond which the Fourier moments of
/// q^s make the sum's tail negligible whatever the Graf coefficients (moment_sum_terms); the
/// rows stop there even where the coefficients themselves have not decayed (0: no such cut).
template <class Real>
GrafWeights<Real> graf_weights(const Real& a1, const Real& a2, double L,
                               double terms_estimate = -1.0, std::size_t moment_terms = 0) {
  const double a1_d = to_double_saturated(a1), a2_d = to_double_saturated(a2);
  if (!is_mpfr_v<Real> && terms_estimate < 0) terms_estimate = graf_terms_estimate(a1_d, a2_d, L);
  std::size_t count = is_mpfr_v<Real>
                          ? 12 + static_cast<std::size_t>(graf_orders_needed(a1_d, a2_d, L))
                          : 8 + static_cast<std::size_t>(terms_estimate);
  // Rows k = 0 .. moment_terms - 1 need the orders 0 .. 2 moment_terms - 1 and the tables one
  // order more (c1, c2); kmax = count / 2 >= moment_terms.
  if (moment_terms > 0) count = std::min(count, 2 * moment_terms + 2);
  // In place (MPFR: no temporaries), in the order of eps * I1 * I2 (eps a power of two).
  auto add_magnitude = [](Real& sum, const Real& x) {
    if (x < 0) {
      sum -= x;
    } else {
      sum += x;
    }
  };
  const Real cut = exp(Real(-L));
  for (;;) {
    const auto i1 = scaled_bessel_i_table(a1, count + 2);
    const auto i2 = scaled_bessel_i_table(a2, count + 2);
    const std::size_t kmax = count / 2;
    GrafWeights<Real> g;
    g.c0.resize(kmax + 1);
    g.c1.resize(kmax + 1);
    g.c2.resize(kmax + 1);
    for (std::size_t k = 0; k <= kmax; ++k) {
      const std::size_t m = 2 * k;
      const int eps = (m == 0) ? 2 : 4;  // 2 (fold) * eps_m
      // c0 = eps I1_m I2_m, c1 = eps I1_m' I2_m, c2 = eps I1_m I2_m', I_m' = (I_{m-1} + I_{m+1})/2
      Real& c0 = g.c0[k];
      Real& c1 = g.c1[k];
      Real& c2 = g.c2[k];
      c0 = i1[m];
      c0 *= eps;
      c0 *= i2[m];
      c1 = i1[m + 1];
      c2 = i2[m + 1];
      if (m > 0) {
        c1 += i1[m - 1];
        c1 /= 2;
        c2 += i2[m - 1];
        c2 /= 2;
      }
      c1 *= eps;
      c1 *= i2[m];
      c2 *= eps;
      c2 *= i1[m];
    }
    // Trim: drop the top terms whose summed magnitude is below exp(-L) times each sum's own
    // leading coefficient, as graf_moment_integrals' bound of the cut tail assumes. (Floored at
    // e^{-L} c0[0], the trim once cut every row but the first of a <cos phi_j> below e^{-L}:
    // a link whose a_j is ~1e-40 of the other's lost its relative O(1) corrections.)
    const Real limit0 = cut * g.c0[0];
    const Real limit1 = cut * g.c1[0];
    const Real limit2 = cut * g.c2[0];
    Real t0 = 0, t1 = 0, t2 = 0;
    std::size_t keep = kmax + 1;
    while (keep > 1) {
      const std::size_t k = keep - 1;
      add_magnitude(t0, g.c0[k]);
      add_magnitude(t1, g.c1[k]);
      add_magnitude(t2, g.c2[k]);
      if (t0 > limit0 || t1 > limit1 || t2 > limit2) break;
      keep = k;
    }
    // The tail really was negligible (or lies beyond the moments' cut): done.
    if (moment_terms > 0 && keep >= moment_terms) keep = moment_terms;
    if (keep + 2 <= kmax || (moment_terms > 0 && keep == moment_terms)) {
      g.error_ulps.resize(keep);
      for (std::size_t k = 0; k < keep; ++k) {
        g.error_ulps[k] =
            scaled_bessel_table_error_ulps<Real>(a1_d, count + 2, 2 * k + 1) +
            scaled_bessel_table_error_ulps<Real>(a2_d, count + 2, 2 * k + 1) + 4;
      }
      g.c0.resize(keep);
      g.c1.resize(keep);
      g.c2.resize(keep);
      return g;
    }
    count = is_mpfr_v<Real> ? count + count / 2 + 16 : 2 * count;
  }
}

/// A sum of non-negative magnitudes m 2^e in double with a running binary exponent, for error
/// bounds of MPFR sums (whose terms may lie outside double's exponent range): terms more than
/// 2^-1000 below the largest one underflow to 0.
struct ExponentSum {
  double mantissa = 0;
  long exponent = std::numeric_limits<long>::min();
  void add(double m, long e) {
    if (e > exponent) {
      mantissa = exponent == std::numeric_limits<long>::min()
                     ? 0.0
                     : std::ldexp(mantissa, static_cast<int>(std::max(exponent - e, -2000L)));
      exponent = e;
    }
    mantissa += std::ldexp(m, static_cast<int>(std::max(e - exponent, -2000L)));
  }
  template <class Real>
  Real to(double factor) const {
    if (mantissa == 0) return Real(0);
    Real r = mantissa * factor;
    mpfr_mul_2si(r.backend().data(), r.backend().data(), exponent, MPFR_RNDU);
    return r;
  }
};

/// The five integrals from Graf's coefficients and the exact Fourier moments of q^s
/// (double_pendulum/fourier_moments.hpp): no quadrature at all.
template <class Real>
LevelResult<Real> graf_moment_integrals(const DoublePendulumParameters<Real>& p,
                                        const GrafWeights<Real>& g, double L) {
  const std::size_t K = g.c0.size();
  const auto m = detail::q_power_moments(p.mu1, p.mu2, K);
  // Indexed by integral::Index. Rows of m.Q: s = 1/2, -1/2, -3/2. J_s uses c0 with its row;
  // C_j uses c_j with s = 1/2.
  const std::array<const std::vector<Real>*, integral_count> coefficient = {&g.c0, &g.c0, &g.c0,
                                                                            &g.c1, &g.c2};
  constexpr std::array<std::size_t, integral_count> row = {0, 1, 2, 0, 0};
  LevelResult<Real> out;
  const Real u = unit_roundoff<Real>();
  const Real tail = exp(Real(-L));
  for (std::size_t k = 0; k < integral_count; ++k) {
    const auto& c = *coefficient[k];
    const auto& Q = m.Q[row[k]];
    if constexpr (is_mpfr_v<Real>) {
      // In place: one fused multiply-add per term for the value, and the bound's L1 sums in
      // double with a running binary exponent (magnitudes only; a term 2^-1000 below the
      // largest one drops out of them, far below their own rounding).
      Real sum = 0;
      ExponentSum l1, c_l1, weighted;
      for (std::size_t j = 0; j < K; ++j) {
        mpfr_fma(sum.backend().data(), c[j].backend().data(), Q[j].backend().data(),
                 sum.backend().data(), MPFR_RNDN);
        long ec = 0, eq = 0;
        const double mc = std::abs(mpfr_get_d_2exp(&ec, c[j].backend().data(), MPFR_RNDA));
        const double mq = std::abs(mpfr_get_d_2exp(&eq, Q[j].backend().data(), MPFR_RNDA));
        if (mc == 0) continue;
        c_l1.add(mc, ec);
        if (mq == 0) continue;
        l1.add(mc * mq, ec + eq);
        weighted.add((g.error_ulps[j] + double(K)) * mc * mq, ec + eq);
      }
      // Each double sum is within (1 + 2^-40) of its exact value (K << 2^13 terms).
      constexpr double slack = 1 + 0x1p-40;
      out.value[k] = sum;
      out.error[k] = c_l1.to<Real>(slack) * m.relative_error * abs(Q[0]) +
                     u * weighted.to<Real>(slack) + tail * l1.to<Real>(slack);
      continue;
    }
    Real sum = 0, l1 = 0, c_l1 = 0, weighted = 0, term;
    for (std::size_t j = 0; j < K; ++j) {
      term = c[j] * Q[j];
      sum += term;
      l1 += abs(term);
      c_l1 += abs(c[j]);
      weighted += Real(g.error_ulps[j] + double(K)) * abs(term);
    }
    out.value[k] = sum;
    // Moments: |dQ_j| <= relative_error max_j |Q_j| = relative_error |Q_0|. Coefficients:
    // the Bessel tables' rounding, term by term; summation: K ulps per term. The cut Graf
    // tail is below e^{-L} of the leading coefficient, hence of the L1 norm (|Q_j| <= Q_0).
    out.error[k] = c_l1 * m.relative_error * abs(Q[0]) + u * weighted + tail * l1;
  }
  out.nodes = K;
  out.converged = true;
  return out;
}

/// The moment sums are exact up to rounding, which the alternating sums for the q^{1/2}
/// integrals amplify when the weight is peaked where q is small (large beta, small mu1).
/// Accept them when that amplification leaves the requested accuracy; else use nodes.
template <class Real>
bool moment_sum_accepted(const LevelResult<Real>& r, const Real& tol) {
  // double: error bound <= 32 ulp of the value (the bounds run ~10x above actual errors);
  // MPFR: the guard digits absorb cancellation, so compare with the tolerance directly.
  const Real limit = is_mpfr_v<Real> ? tol : Real(32) * unit_roundoff<Real>();
  for (const std::size_t k : {integral::J_half, integral::J_minus_half,
                              integral::J_minus_three_halves}) {
    if (!(r.error[k] <= limit * abs(r.value[k]))) return false;
  }
  return true;
}

template <class Real>
Averages<Real> finish_averages(const DoublePendulumParameters<Real>& p,
                               const LevelResult<Real>& r) {
  using namespace integral;
  const Real u = unit_roundoff<Real>();
  const auto& I = r.value;
  const auto& e = r.error;
  // Absolute error of a ratio X/Y: err(X)/|Y| + |X| err(Y)/Y^2, plus a few ulps.
  auto ratio = [&](std::size_t x, std::size_t y, Real& value, Real& error) {
    value = I[x] / I[y];
    error = e[x] / abs(I[y]) + abs(value) * (e[y] / abs(I[y]) + 4 * u);
  };
  Averages<Real> out;
  out.method = Method::reduced_integral;
  out.error_kind = ErrorKind::estimate;
  out.work_unit = WorkUnit::nodes;
  out.evaluations = r.nodes;
  out.converged = r.converged;
  constexpr ErrorKind kind = ErrorKind::estimate;
  Real q, q_err;
  ratio(J_minus_half, J_half, q, q_err);
  const Real k1 = p.mu1 / 2 * q;
  const Real k1_err = p.mu1 / 2 * q_err + 2 * u * k1;
  const Real k2 = 1 - k1;
  const Real k2_err = k1_err + 2 * u * k2;
  out.beta_kinetic = {{k1, k1_err, kind}, {k2, k2_err, kind}};
  Real cos1, cos1_err, cos2, cos2_err;
  ratio(C_1, J_half, cos1, cos1_err);
  ratio(C_2, J_half, cos2, cos2_err);
  out.cos_angle = {{cos1, cos1_err, kind}, {cos2, cos2_err, kind}};
  Real x2, x2_err;
  ratio(J_minus_three_halves, J_half, x2, x2_err);  // <x^2> / mu1^2
  x2 *= p.mu1 * p.mu1;
  x2_err *= p.mu1 * p.mu1;
  const Real x1 = 2 * k1, x1_err = 2 * k1_err;  // <x> = <tr X_1>
  const Real var1 = Real(3) / 4 * x2 - x1 * x1 / 4;
  const Real var2 = (1 - x1) + x1 * x1 / 2 + Real(3) / 4 * (x2 - x1 * x1);
  // |d var1/d x1| = x1/2, |d var2/d x1| = 1 + x1/2, d var/d x2 = 3/4; x1 <= 1.
  out.beta2_kinetic_variance = {{var1, Real(3) / 4 * x2_err + x1 / 2 * x1_err + 8 * u, kind},
                                {var2, Real(3) / 4 * x2_err + (1 + x1 / 2) * x1_err + 8 * u, kind}};
  const Real k_ratio = k1 / k2;
  out.ratio = Estimate<Real>{k_ratio, k1_err / k2 + k_ratio * (k2_err / k2 + 4 * u), kind};
  return out;
}

}  // namespace

template <class Real>
Averages<Real> reduced_integral_average(const Chain<Real>& chain, const Real& beta, int digits,
                                        const IntegralOptions& options) {
  IntegralWorkspace<Real> workspace;
  return reduced_integral_average(chain, beta, digits, options, workspace);
}

// ---------------------------------------------------------------- plan (the cost model)

template <class Real>
IntegralPlan<Real> plan_reduced_integral(const DoublePendulumParameters<Real>& p, int digits,
                                         IntegralEvaluation evaluation) {
  using Sums = typename IntegralPlan<Real>::Sums;
  IntegralPlan<Real> plan;
  plan.max_level = is_mpfr_v<Real> ? 10 : 7;
  plan.ln_inv_tol = -static_cast<double>(log(integral_tolerance<Real>(digits)));
  const double a1 = to_double_saturated(p.a1), a2 = to_double_saturated(p.a2);
  const double A = to_double_saturated(Real(p.a1 + p.a2));
  // Graf's cosine series is cut where its tail is below e^{-L_graf} of its leading term. The
  // cut changes every integral by at most e^{-L_graf} times its L1 norm (reported, so the
  // bound is rigorous); L_graf adds to the tolerance the expected cancellation l1/|J| ~ 1/w,
  // w = (1/a1 + 1/a2)^{1/2} the width of the weight's peak, and the Bessel prefactor.
  plan.harmonic = (a1 > 0 && a2 > 0) ? a1 * a2 / (a1 + a2) : 0.0;
  plan.L_graf = plan.ln_inv_tol + 5.0 + 0.5 * std::log1p(plan.harmonic) +
                0.5 * std::log1p(2 * 3.14159 * A);
  // Per-node Graf sums beat per-node Bessel functions while they are short; they also keep
  // <cos phi_j> free of the cancellation between t and pi - t when one of a1, a2 is small. In
  // double, once both arguments stay >= 25 (R >= |a1 - a2|) the fixed-length Hankel series
  // makes the Bessel functions cheaper than 24 or more Graf terms; a smaller argument >= 16
  // keeps the t <-> pi - t cancellation in <cos phi_j> (at most max(a1, a2)/min(a1, a2)) as
  // small as for the cases with long Graf rows.
  plan.graf_terms = graf_terms_estimate(a1, a2, plan.L_graf);
  const bool direct_cheaper = !is_mpfr_v<Real> && plan.graf_terms > 24.0 &&
                              std::min(a1, a2) >= 16.0 && std::abs(a1 - a2) >= 25.0;
  plan.graf_nodes = plan.graf_terms <= (is_mpfr_v<Real> ? 400.0 : 48.0) && !direct_cheaper;
  plan.zero_distance = asinh(sqrt(p.mu1 / p.mu2));
  const double d = static_cast<double>(plan.zero_distance);

  bool worthwhile;
  if constexpr (is_mpfr_v<Real>) {
    // The sums cost about the same per Graf order at any precision, plus the Bessel tables'
    // Miller runs beyond the rows; the nodes' count grows like ln(1/tol) and each costs more
    // at higher precision. With per-node Bessel weights the sums win while the orders plus a
    // tenth of the extra Miller steps stay below 10 ln(1/tol); with per-node Graf rows every
    // node costs a fraction of the sums themselves, so the sums win.
    const double orders = graf_orders_needed(a1, a2, plan.L_graf);
    const auto rows = 14 + static_cast<std::size_t>(orders);  // graf_weights' tables
    const double miller_extra = static_cast<double>(scaled_bessel_table_steps<Real>(a1, rows) +
                                                    scaled_bessel_table_steps<Real>(a2, rows) -
                                                    2 * rows);
    worthwhile = plan.graf_nodes || orders + 0.1 * miller_extra <= 10.0 * plan.ln_inv_tol;
  } else {
    // In double, skip the sums where they would likely be rejected (cancellation ~ a1 a2 /
    // (a1 + a2) together with the Bessel tables' rounding bounds passes 32 ulps beyond a
    // harmonic mean of ~30) or are slow: long double moments are cheap for short rows, for
    // K d < 1/4 (a convergent series; K ~ graf_terms / 2 rows) and for d > 1/2 (a short Miller
    // run). Beyond harmonic 30 they still win when q's zero is very close to t = 0 (d < 1e-3),
    // where the nodes need a long sinh-mapped level while the rows stay short.
    const bool tiny_d_short_rows = plan.harmonic <= 64.0 && d < 1e-3;
    worthwhile = plan.graf_terms <= 400.0 && (plan.harmonic <= 30.0 || tiny_d_short_rows) &&
                 (plan.graf_terms <= 24.0 || plan.graf_terms * d < 0.5 || d > 0.5);
  }
  const bool try_sums = evaluation == IntegralEvaluation::graf_sums ||
                        (evaluation == IntegralEvaluation::automatic && worthwhile);
  if (try_sums) {
    // Double without a peak (little cancellation) is faster than long double, whose 3 extra
    // digits absorb the cancellation of the alternating q^{1/2} sums, ~(1 + harmonic).
    // Why: README, Design notes, 'Measurements behind the design choices' (N = 2).
    plan.sums = is_mpfr_v<Real>          ? Sums::working
                : plan.harmonic <= 1.0 ? Sums::double_then_long_double
                                       : Sums::long_double;
  }
  return plan;
}

template <class Real>
NodePlan<Real> plan_nodes(const DoublePendulumParameters<Real>& p, const IntegralPlan<Real>& plan) {
  NodePlan<Real> nodes;
  nodes.T = boost::math::constants::pi<Real>() / 2;
  const Real& d = plan.zero_distance;
  if (!plan.graf_nodes) {
    // Cut the range where the weight has fallen below tol / (1 + A) of its peak:
    // R(T) - A = -L  <=>  sin^2(T/2) = L (2A - L) / (4 a1 a2).
    const Real A = p.a1 + p.a2;
    const double A_d = to_double_saturated(A);
    const double L = plan.ln_inv_tol + 5.0 + std::log1p(A_d);
    if (L < A_d) {
      const Real s2 = Real(L) * (2 * A - Real(L)) / (4 * p.a1 * p.a2);
      if (s2 < Real(0.5)) {
        nodes.T = 2 * asin(sqrt(s2));
        nodes.fold = false;  // W(pi - t) <= W(T) on [0, T]: negligible
      }
    }
  }
  if (d < nodes.T / 4) {
    nodes.use_sinh = true;
    if (!nodes.fold) {
      // sin^2(t/2) at the zero of q: 4 mu2 s^2 (1 - s^2) = -mu1, s^2 = -eps^2 with
      // eps^2 = c^2 / (2 (1 + sqrt(1 + c^2))), c^2 = mu1 / mu2.
      const Real c2 = p.mu1 / p.mu2;
      nodes.half_angle = true;
      nodes.eps = sqrt(c2 / (2 * (1 + sqrt(1 + c2))));
      nodes.sigma = asinh(sin(nodes.T / 2) / nodes.eps);
    } else {
      nodes.eps = d;
      nodes.sigma = asinh(nodes.T / d);
    }
  }
  // Level sizes: the nodes needed grow with the sinh map's span sigma (~ln(T/d)); in double a
  // span in (3.8, 8.4) is served by a level of the 12 2^L ladder where the 8 2^L ladder needs a
  // level more (per-node Bessel weights only: per-node Graf rows are dearer).
  nodes.base12 = !is_mpfr_v<Real> && !plan.graf_nodes && nodes.use_sinh && nodes.sigma > 3.8 &&
                 nodes.sigma < 8.4;
  if (is_mpfr_v<Real> && !plan.graf_nodes && nodes.half_angle) {
    // When q's zero (distance ~sqrt(mu1)) is far closer to t = 0 than the peak's width
    // w = (a1 a2 / (a1 + a2))^{-1/2}, one sinh map over [0, T] turns the Gaussian into a
    // double-exponential cliff; splitting at t1 = 2 w (product integration over the inner
    // panel, or a second sinh-mapped panel) halves the nodes. In double both panels need as
    // many levels as the single one.
    nodes.t1 = 2.0 / std::sqrt(plan.harmonic);
    const double T = static_cast<double>(nodes.T);
    nodes.inner_series = nodes.t1 < T / 3;
    nodes.two_panels = nodes.sigma > 6 && nodes.t1 < T / 3 &&
                       std::sin(nodes.t1 / 2) > 40 * static_cast<double>(nodes.eps);
  }
  return nodes;
}

// ---------------------------------------------------------------- run

namespace {

using namespace integral;

/// Each integral's relative tolerance: beta<K_i> needs J_{1/2}, J_{-1/2} to the full
/// tolerance; J_{-3/2} (variances) and C_1, C_2 (<cos phi>) may stop at 16 times it.
template <class Real>
Real integral_tolerance_of(std::size_t k, const Real& tol) {
  return k == J_half || k == J_minus_half ? tol : Real(16 * tol);
}

/// The exact finite sums in the plan's number type; true when their error bound accepts them.
template <class Real>
bool run_exact_sums(const DoublePendulumParameters<Real>& p, const IntegralPlan<Real>& plan,
                    const Real& tol, LevelResult<Real>& r) {
  using Sums = typename IntegralPlan<Real>::Sums;
  const auto sums_in = [&]<class Work>() {
    const DoublePendulumParameters<Work> pw{Work(p.mu1), Work(p.mu2), Work(p.a1), Work(p.a2)};
    // MPFR: the rows also stop where the moments of q^s have decayed (moment_sum_terms), e.g.
    // at large beta, whose Graf coefficients stay large for ~sqrt(a1 a2 / (a1 + a2)) rows. The
    // double engines keep their rows (and their bits).
    const std::size_t moment_terms =
        is_mpfr_v<Real> ? moment_sum_terms(to_double_saturated(p.mu1), plan.L_graf) : 0;
    const auto rw = graf_moment_integrals(
        pw, graf_weights(pw.a1, pw.a2, plan.L_graf, plan.graf_terms, moment_terms), plan.L_graf);
    for (std::size_t k = 0; k < integral_count; ++k) {
      r.value[k] = Real(rw.value[k]);
      r.error[k] = Real(rw.error[k]) + unit_roundoff<Real>() * abs(r.value[k]);
    }
    r.nodes = rw.nodes;
    r.converged = rw.converged;
    return moment_sum_accepted(r, tol);
  };
  if constexpr (is_mpfr_v<Real>) {
    return sums_in.template operator()<Real>();
  } else {
    if (plan.sums == Sums::double_then_long_double && sums_in.template operator()<double>())
      return true;
    return sums_in.template operator()<long double>();
  }
}

/// The sum of two panels' integrals (both integrands are positive on t <= T < pi/2, so relative
/// tolerances add up).
template <class Real>
LevelResult<Real> panels_sum(const LevelResult<Real>& a, const LevelResult<Real>& b) {
  LevelResult<Real> r;
  for (std::size_t k = 0; k < integral_count; ++k) {
    r.value[k] = a.value[k] + b.value[k];
    r.error[k] = a.error[k] + b.error[k];
  }
  r.nodes = a.nodes + b.nodes;
  r.converged = a.converged && b.converged;
  return r;
}

/// The integrals by nodes with per-node scaled Bessel weights, on the plan's panels.
template <class Real>
LevelResult<Real> run_bessel_nodes(const DoublePendulumParameters<Real>& p,
                                   const IntegralPlan<Real>& plan, const NodePlan<Real>& np,
                                   const Real& tol, IntegralWorkspace<Real>& ws) {
  NodeMap<Real> map;
  map.T = np.T;
  map.use_sinh = np.use_sinh;
  map.half_angle = np.half_angle;
  map.eps = np.eps;
  map.sigma = np.sigma;
  const Real A = p.a1 + p.a2;
  DirectWeights<Real> dw{p.a1, p.a2, A, 4 * p.a1 * p.a2, np.fold};
  dw.by_parts = !np.fold;
  if constexpr (is_mpfr_v<Real>) {
    if (!np.fold) {
      // R at the nodes lies in [R(T), A]: R(T)^2 = A^2 - 4 a1 a2 sin^2(T/2). Slightly
      // widened (relative 2^-40) so that rounding of R at the nodes stays inside.
      const Real sT = sin(map.T / 2);
      const Real R_T = sqrt(A * A - dw.P * sT * sT);
      dw.bessel_range = scaled_bessel_i01_range(Real(R_T * (1 - ldexp(Real(1), -40))),
                                                Real(A * (1 + ldexp(Real(1), -40))));
    }
  }
  // W(pi - t) e^{...} below u e^{-5} / (1 + A) of W(0) ~ (2 pi A)^{-1/2} is negligible beside
  // every integral, each at least its value at the peak times the peak's width.
  dw.negligible_exponent = Real(plan.ln_inv_tol + 5.0 + 2 * std::log1p(to_double_saturated(A)));
  const auto levels = [&](const NodeMap<Real>& m) {
    return integrate_levels(m, p.mu1, p.mu2, dw, tol, plan.max_level, np.base12, ws);
  };
  // The outer panel [t1, T]: the sinh map at scale s1 = sin(t1/2), shifted past the inner one.
  const auto outer_panel = [&](const Real& s1) {
    NodeMap<Real> outer = map;
    outer.eps = s1;
    outer.v0 = asinh(Real(1));
    outer.sigma = asinh(sin(map.T / 2) / s1) - outer.v0;
    return levels(outer);
  };
  LevelResult<Real> r;
  bool done = false;
  if constexpr (is_mpfr_v<Real>) {
    if (np.inner_series) {
      // Product integration over the inner panel (double_pendulum/inner_panel_series.hpp) replaces its
      // ~130-260 nodes by ~50-100 series terms. When q's zero is at or beyond the peak's width
      // the panel's end moves out (inner_panel_end), if still well inside [0, T].
      const Real s1 = detail::inner_panel_end(sin(Real(np.t1) / 2), map.eps);
      const double s1_d = static_cast<double>(s1);
      detail::InnerPanelSeries<Real> inner;
      if (s1_d < 1 && 2 * std::asin(s1_d) < static_cast<double>(map.T) / 3) {
        inner = detail::inner_panel_series(p.mu1, p.mu2, p.a1, p.a2, s1);
      }
      bool accepted = inner.ok;
      for (std::size_t k = 0; accepted && k < integral_count; ++k) {
        if (!(inner.error[k] <= integral_tolerance_of(k, tol) * abs(inner.value[k])))
          accepted = false;
      }
      if (accepted) {
        LevelResult<Real> series;
        series.value = inner.value;
        series.error = inner.error;
        series.nodes = inner.terms;
        series.converged = true;
        r = panels_sum(series, outer_panel(s1));
        done = true;
      }
    }
  }
  if (!done && np.two_panels) {
    // Up to ~50 digits the inner panel still converges at 129 nodes for spans sigma <= 8.3;
    // a longer span costs a level more there than the longer outer panel does, so the split
    // moves in. At higher precision the outer panel is the dearer one: t1 = 2 w stays.
    Real s1 = sin(Real(np.t1) / 2);
    constexpr double inner_span_cap = 8.3;
    if (plan.ln_inv_tol < 120.0 && asinh(s1 / map.eps) > inner_span_cap) {
      s1 = map.eps * sinh(Real(inner_span_cap));
    }
    NodeMap<Real> inner = map;
    inner.sigma = asinh(s1 / map.eps);
    const LevelResult<Real> inner_nodes = levels(inner);
    r = panels_sum(inner_nodes, outer_panel(s1));
  } else if (!done) {
    r = levels(map);
  }
  if (dw.by_parts) {
    // By parts on [0, T] (src/engine/double_pendulum/README.md, 'Reduced integral'; q' = 2 mu2 sin
    // t cos t, mu1 + mu2 = 1):
    //   mu1 J_{-3/2} = J_{1/2} - mu2 int sin t cos t q^{-1/2} W' dt + mu2 B(T),
    //   B(t) = sin t cos t q^{-1/2} W(t),  B(0) = 0.
    // (Panel boundaries cancel.) Add the boundary term at the cut, exactly.
    const Real sT = sin(map.T / 2);
    const Real s2 = sT * sT;
    const Real sin2_T = 4 * s2 * (1 - s2);
    std::array<Real, 4> FT;
    dw(sin2_T, sT, FT);
    const Real boundary =
        p.mu2 / p.mu1 * sqrt(sin2_T) * (1 - 2 * s2) / sqrt(p.mu1 + p.mu2 * sin2_T) * FT[0];
    r.value[J_minus_three_halves] += boundary;
    r.error[J_minus_three_halves] += 8 * unit_roundoff<Real>() * boundary;
  }
  if (!np.fold) {
    // The cut at T drops a tail below tol |J| by the choice of L: report it.
    for (std::size_t k = 0; k < integral_count; ++k) r.error[k] += tol * abs(r.value[k]);
  }
  return r;
}

}  // namespace

template <class Real>
Averages<Real> reduced_integral_average(const Chain<Real>& chain, const Real& beta, int digits,
                                        const IntegralOptions& options,
                                        IntegralWorkspace<Real>& ws) {
  check_digits<Real>(digits);
  const precision_guard<Real> precision(digits + guard_digits);
  const auto p = double_pendulum_parameters(chain, beta);  // validates
  const IntegralPlan<Real> plan = plan_reduced_integral(p, digits, options.evaluation);
  const Real tol = integral_tolerance<Real>(digits);
  LevelResult<Real> r;
  if (plan.sums != IntegralPlan<Real>::Sums::none && run_exact_sums(p, plan, tol, r))
    return finish_averages(p, r);
  const NodePlan<Real> nodes = plan_nodes(p, plan);
  if (plan.graf_nodes) {
    NodeMap<Real> map;
    map.T = nodes.T;
    map.use_sinh = nodes.use_sinh;
    map.eps = nodes.eps;
    map.sigma = nodes.sigma;
    r = integrate_levels(map, p.mu1, p.mu2, graf_weights(p.a1, p.a2, plan.L_graf, plan.graf_terms),
                         tol, plan.max_level, nodes.base12, ws);
  } else {
    r = run_bessel_nodes(p, plan, nodes, tol, ws);
  }
  return finish_averages(p, r);
}

#define PENDAVG_INSTANTIATE(Real)                                                           \
  template DoublePendulumParameters<Real> double_pendulum_parameters<Real>(const Chain<Real>&, \
                                                                           const Real&);    \
  template IntegralPlan<Real> plan_reduced_integral<Real>(const DoublePendulumParameters<Real>&, \
                                                          int, IntegralEvaluation);          \
  template NodePlan<Real> plan_nodes<Real>(const DoublePendulumParameters<Real>&,            \
                                           const IntegralPlan<Real>&);                       \
  template Averages<Real> reduced_integral_average<Real>(const Chain<Real>&, const Real&, int,  \
                                                         const IntegralOptions&);            \
  template Averages<Real> reduced_integral_average<Real>(const Chain<Real>&, const Real&, int,  \
                                                         const IntegralOptions&,              \
                                                         IntegralWorkspace<Real>&);
PENDAVG_INSTANTIATE(double)
PENDAVG_INSTANTIATE(mpfr_real)
#undef PENDAVG_INSTANTIATE

}  // namespace pendavg
