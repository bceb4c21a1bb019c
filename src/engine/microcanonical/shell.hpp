// SPDX-License-Identifier: GPL-3.0-or-later
// engine/microcanonical/shell.hpp -- the psi integrals of one energy shell, the excitation form of
// E - U, and the chain constants every microcanonical rule needs.
//
// Equations (src/engine/microcanonical/README.md, 'Shell integrals' and 'Excitation form'), with
// U = -rho cos(psi - arg z) after the reduction (rho = |sum_j gamma_j e^{i theta_j}|):
//     F_p(E, rho) = int_0^{2 pi} (E + rho cos psi)_+^p dpsi,
//     G_p(E, rho) = int_0^{2 pi} cos psi (E + rho cos psi)_+^p dpsi,
//     weight = sqrt(det A) F_{N/2-1},  <K_i | theta> ~ tr X_i F_{N/2} / N,
//     E - U = D - (U - U_min),  U - U_min = sum_j gamma_j (1 - cos phi_j) >= 0,  D = E - E_min.
#pragma once

#include "engine/numerics/double_word.hpp"
#include "engine/numerics/precision.hpp"
#include "pendavg/chain.hpp"

#include <boost/math/special_functions/ellint_rd.hpp>
#include <boost/math/special_functions/ellint_rf.hpp>
#include <boost/math/special_functions/ellint_rg.hpp>

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <limits>
#include <type_traits>
#include <vector>

namespace pendavg::detail::microcanonical {

using std::abs;
using std::exp;
using std::log;
using std::sqrt;

using detail::pi;

using detail::pi;

/// The psi integrals of one shell, divided by scale^p (see the header comment):
///   weight = F_p / W^p,  kinetic = F_{p+1} / W^{p+1},  kinetic_squared = F_{p+2} / W^{p+2},
///   cosine = G_p / W^p.
template <class Real>
struct ShellMoments {
  Real weight{0}, kinetic{0}, kinetic_squared{0}, cosine{0};
};

/// F_p, F_{p+1}, F_{p+2}, G_p for one fixed p = twice_p / 2 >= -1/2 (header comment for the
/// method). The caller passes depth = E + rho, the largest E - U over psi, formed without
/// cancellation (the excitation form, depth = D - (S - rho)): near the bottom of the well every
/// cap quantity is a function of it, and E + rho itself would have lost all its digits.
template <class Real>
class ShellIntegrals {
 public:
  explicit ShellIntegrals(int twice_p) : twice_p_(twice_p) {
    if (twice_p < -1) throw invalid_input("shell integrals need p >= -1/2");
    p_ = Real(twice_p) / 2;
    even_ = twice_p % 2 == 0;
    // B(1/2, q + 1) from B(1/2, 1) = 2 or B(1/2, 1/2) = pi, B(1/2, q + 2) = B(1/2, q + 1) (q + 1)/(q + 3/2).
    Real q = even_ ? Real(0) : Real(-0.5);
    Real b = even_ ? Real(2) : pi<Real>();
    while (q < p_) {
      b *= (q + 1) / (q + Real(1.5));
      q += 1;
    }
    half_beta_p_ = b / 2;
    half_beta_p1_ = b * (p_ + 1) / (p_ + Real(1.5)) / 2;
    half_beta_p2_ = half_beta_p1_ * (p_ + 2) / (p_ + Real(2.5));
  }

  const Real& p() const { return p_; }

  /// The moments at energy E and radius rho; depth = E + rho (see the class comment).
  ShellMoments<Real> operator()(const Real& energy, const Real& rho, const Real& depth,
                                const Real& scale) const {
    using std::pow;
    ShellMoments<Real> out;
    const Real& e = energy;
    if (!(depth > 0)) return out;  // no psi accessible
    const Real two_pi = 2 * pi<Real>();
    if (!(rho > 0)) {  // rho = 0 < E: E - U = E for every psi
      const Real r = depth / scale;
      out.weight = two_pi * pow(r, p_);
      out.kinetic = out.weight * r;
      out.kinetic_squared = out.kinetic * r;
      return out;
    }
    if (e < rho) {  // the cap |psi + arg z| < arccos(-E/rho)
      using std::max;
      using std::min;
      // 0 < m <= 1 in exact arithmetic; E and depth carry separate roundings
      const Real m = min(Real(depth / (2 * rho)), Real(1));
      const Real mc = max(Real((rho - e) / (2 * rho)), Real(0)), k = sqrt(m);
      Real jp, jp1, jp2;
      cap_integrals(m, mc, e / rho, k, jp, jp1, jp2);
      const Real r = depth / scale;
      const Real factor = 4 * k * pow(r, p_);
      out.weight = factor * jp;
      out.kinetic = factor * r * jp1;
      out.kinetic_squared = factor * r * r * jp2;
      out.cosine = (scale * out.kinetic - e * out.weight) / rho;
      return out;
    }
    // the full circle
    const Real& top = depth;
    const Real mcp = (e - rho) / top;
    Real lp, lp1, lp2;
    full_integrals(mcp, e / top, lp, lp1, lp2);
    const Real r = top / scale;
    const Real rp = pow(r, p_);
    out.weight = two_pi * rp * lp;
    out.kinetic = two_pi * rp * r * lp1;
    out.kinetic_squared = two_pi * rp * r * r * lp2;
    if (e >= 2 * rho) {
      out.cosine = pi<Real>() * p_ * pow(e / scale, p_) * (rho / e) * cosine_series(rho / e);
    } else {
      out.cosine = (scale * out.kinetic - e * out.weight) / rho;
    }
    return out;
  }

  /// The same with depth = E + rho formed here (for callers away from the bottom of the well).
  ShellMoments<Real> operator()(const Real& energy, const Real& rho, const Real& scale) const {
    return (*this)(energy, rho, Real(energy + rho), scale);
  }

 private:
  /// J_p(m), J_{p+1}(m), J_{p+2}(m) on the cap; e = E / rho = 2m - 1, k = sqrt(m).
  void cap_integrals(const Real& m, const Real& mc, const Real& e, const Real& k, Real& jp,
                     Real& jp1, Real& jp2) const {
    using std::asin;
    if (m < Real(0.5)) {
      const Real u = unit_roundoff<Real>() / 2;
      Real tp = 1, tp1 = 1, tp2 = 1, sp = 1, sp1 = 1, sp2 = 1;
      for (int n = 0; n < 100000; ++n) {
        const Real nh = Real(n) + Real(0.5);
        const Real common = nh * nh * m / Real(n + 1);
        tp *= common / (Real(n) + p_ + Real(1.5));
        tp1 *= common / (Real(n) + p_ + Real(2.5));
        tp2 *= common / (Real(n) + p_ + Real(3.5));
        sp += tp;
        sp1 += tp1;
        sp2 += tp2;
        if (tp <= u * sp && tp1 <= u * sp1 && tp2 <= u * sp2) break;
      }
      jp = half_beta_p_ * sp;
      jp1 = half_beta_p1_ * sp1;
      jp2 = half_beta_p2_ * sp2;
      return;
    }
    Real q, lower, upper;  // J_q, J_{q+1}
    if (even_) {
      q = 0;
      const Real a = asin(k);
      lower = a / k;
      upper = a * e / (2 * k * m) + sqrt(mc) / (2 * m);
    } else {
      q = Real(-0.5);
      const Real rf = boost::math::ellint_rf(Real(0), mc, Real(1));
      lower = rf;
      upper = rf - boost::math::ellint_rd(Real(0), mc, Real(1)) / 3;
    }
    // (q+2) m J_{q+2} = (2q+3)(e/2) J_{q+1} + (q+1)(1-m) J_q: non-negative terms for e >= 0.
    const auto step = [&](const Real& q_now, const Real& j0, const Real& j1) {
      const Real q1 = q_now + 1;
      return Real(((2 * q1 + 1) * (e / 2) * j1 + q1 * mc * j0) / ((q1 + 1) * m));
    };
    while (q < p_) {
      const Real next = step(q, lower, upper);
      lower = upper;
      upper = next;
      q += 1;
    }
    jp = lower;
    jp1 = upper;
    jp2 = step(q, lower, upper);
  }

  /// L_p(m'), L_{p+1}(m'), L_{p+2}(m') on the full circle; mcp = 1 - m',
  /// ratio = E / (E + rho) = 1 - m'/2.
  void full_integrals(const Real& mcp, const Real& ratio, Real& lp, Real& lp1, Real& lp2) const {
    Real q, lower, upper;
    if (even_) {
      q = 0;
      lower = 1;
      upper = ratio;
    } else {
      q = Real(-0.5);
      const Real two_over_pi = 2 / pi<Real>();
      lower = mcp > 0 ? Real(two_over_pi * boost::math::ellint_rf(Real(0), mcp, Real(1)))
                      : std::numeric_limits<Real>::infinity();
      upper = 2 * two_over_pi * boost::math::ellint_rg(Real(0), mcp, Real(1));
    }
    // (q+2) L_{q+2} = (2q+3) ratio L_{q+1} - (q+1) (1 - m') L_q: the dominant solution.
    const auto step = [&](const Real& q_now, const Real& l0, const Real& l1) {
      const Real q1 = q_now + 1;
      const Real tail = mcp > 0 ? Real(q1 * mcp * l0) : Real(0);
      return Real(((2 * q1 + 1) * ratio * l1 - tail) / (q1 + 1));
    };
    while (q < p_) {
      const Real next = step(q, lower, upper);
      lower = upper;
      upper = next;
      q += 1;
    }
    lp = lower;
    lp1 = upper;
    lp2 = step(q, lower, upper);
  }

  /// 2F1((1-p)/2, 1-p/2; 2; x^2) for x = rho/E <= 1/2.
  Real cosine_series(const Real& x) const {
    const Real u = unit_roundoff<Real>() / 2;
    const Real x2 = x * x, a = (1 - p_) / 2, b = 1 - p_ / 2;
    Real t = 1, s = 1;
    for (int n = 0; n < 100000; ++n) {
      t *= (a + Real(n)) * (b + Real(n)) * x2 / (Real(n + 2) * Real(n + 1));
      s += t;
      if (t == 0 || (Real(n) > p_ + 2 && abs(t) <= u * abs(s))) break;
    }
    return s;
  }

  int twice_p_;
  Real p_;
  bool even_;
  Real half_beta_p_, half_beta_p1_, half_beta_p2_;
};

/// Unscaled F_p(E, rho), F_{p+1}, F_{p+2}, G_p (scale 1, depth E + rho formed here): for tests.
template <class Real>
ShellMoments<Real> shell_integrals(int twice_p, const Real& energy, const Real& rho) {
  return ShellIntegrals<Real>(twice_p)(energy, rho, Real(1));
}

// --------------------------------------------------------------------------- excitation form

/// sum_j g S_j l_j = -E_min of the chain's exact parameters (masses, lengths, g as stored), as
/// a double word: every product m_k l_j g (k >= j) is formed exactly and summed in double-double.
/// For MPFR the sum at the working precision (its guard digits).
template <class Real>
DoubleWord<Real> well_depth(const Chain<Real>& chain) {
  const std::size_t n = chain.size();
  DoubleWord<Real> total;
  for (std::size_t j = 0; j < n; ++j) {
    for (std::size_t k = j; k < n; ++k) {
      if constexpr (std::is_floating_point_v<Real>) {
        const DoubleWord<Real> ml = two_product(chain.mass(k), chain.length(j));
        DoubleWord<Real> term = two_product(ml.hi, chain.gravity());
        term.lo += ml.lo * chain.gravity();
        total = add(total, term);
      } else {
        total.hi += chain.mass(k) * chain.length(j) * chain.gravity();
      }
    }
  }
  return total;
}

/// D = E - E_min = E + sum_j g S_j l_j, with the sum and the addition done in double-double
/// (MPFR: at the working precision), so that an energy given near the bottom of the well keeps
/// its digits: the relative error of D is ~u, not u |E_min| / D.
template <class Real>
Real excitation_of(const Chain<Real>& chain, const Real& energy) {
  const DoubleWord<Real> depth = well_depth(chain);
  if constexpr (std::is_floating_point_v<Real>) {
    const DoubleWord<Real> d = add(depth, DoubleWord<Real>{energy, Real(0)});
    return d.hi + d.lo;
  } else {
    return energy + depth.hi;
  }
}

/// sum_j gamma_j - |z| >= 0 for z = sum_j gamma_j e^{i phi_j}, without cancellation:
/// sum_j gamma_j (1 - cos(phi_j - arg z)) (Re(z e^{-i arg z}) = |z|), with 1 - cos x =
/// sin^2 x / (1 + cos x) for cos x >= 0 (the torus' S - R, torus/level_sums.hpp). `rho` = |z| > 0.
template <class Real>
Real well_deficit(const std::vector<Real>& gamma, const Real* cos_phi, const Real* sin_phi,
                  const Real& zx, const Real& zy, const Real& rho) {
  const Real ux = zx / rho, uy = zy / rho;
  Real deficit = 0;
  for (std::size_t j = 0; j < gamma.size(); ++j) {
    const Real c = cos_phi[j] * ux + sin_phi[j] * uy;
    const Real s = sin_phi[j] * ux - cos_phi[j] * uy;
    deficit += gamma[j] * (c >= 0 ? Real(s * s / (1 + c)) : Real(1 - c));
  }
  return deficit;
}

// --------------------------------------------------------------------------- chain constants

/// What every rule needs: gamma_j, the excitation D = E - E_min (= W = E + sum gamma, the
/// largest E - U and the scale of the shell integrals), the Hadamard bound of sqrt(det A), the
/// shell integrals at p = N/2 - 1, and the constant (2 pi)^{N/2} / Gamma(N/2) of Omega.
/// Every E - U is formed as D - (U - U_min): the excitation form.
template <class Real>
struct ShellSetup {
  std::size_t n = 0;
  Real energy{}, excitation{}, scale{}, gamma_sum{0}, log_hadamard{0};
  std::vector<Real> gamma;
  std::vector<Real> head_gamma;  ///< sum_{k <= j} gamma_k
  ShellIntegrals<Real> shell;
  Real log_momentum_sphere{};  ///< log((2 pi)^{N/2} / Gamma(N/2))

  /// E + rho, the largest E - U over psi on the fibre of radius rho = |z|, from the deficit
  /// S - rho (formed without cancellation by the caller): as D - (S - rho) below E = 0, where
  /// D and the deficit are small near the bottom of the well, and as E + rho above it, where
  /// the deficit can be ~S while E + rho is ~rho (a folded chain, z ~ 0).
  Real depth(const Real& rho, const Real& deficit) const {
    return excitation < gamma_sum ? Real(excitation - deficit) : Real(energy + rho);
  }

  /// `energy` E and `excitation` D = E - E_min of the same state (D is the accurate one).
  ShellSetup(const Chain<Real>& chain, const Real& e, const Real& d)
      : n(chain.size()), energy(e), excitation(d), shell(static_cast<int>(chain.size()) - 2) {
    gamma.resize(n);
    head_gamma.resize(n);
    for (std::size_t j = 0; j < n; ++j) {
      gamma[j] = chain.potential_coefficient(j);
      gamma_sum += gamma[j];
      head_gamma[j] = gamma_sum;
      log_hadamard += log(chain.length(j)) + log(chain.tail_mass(j)) / 2;
    }
    scale = excitation;
    // log Gamma(N/2) from Gamma(1) = 1, Gamma(1/2) = sqrt(pi), Gamma(x + 1) = x Gamma(x).
    Real x = n % 2 == 0 ? Real(1) : Real(0.5);
    Real log_gamma = n % 2 == 0 ? Real(0) : Real(log(pi<Real>()) / 2);
    const Real half_n = Real(static_cast<double>(n)) / 2;
    for (; x < half_n; x += 1) log_gamma += log(x);
    log_momentum_sphere = half_n * log(2 * pi<Real>()) - log_gamma;
  }
};

}  // namespace pendavg::detail::microcanonical
