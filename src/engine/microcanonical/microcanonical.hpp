// SPDX-License-Identifier: GPL-3.0-or-later
// engine/microcanonical.hpp -- the microcanonical engine's internals (shell integrals, nested
// tanh-sinh quadrature); see include/pendavg/microcanonical.hpp for what it computes.
#pragma once

#include "pendavg/microcanonical.hpp"
#include "engine/numerics/bessel.hpp"
#include "pendavg/chain.hpp"
#include "engine/numerics/precision.hpp"
#include "pendavg/result.hpp"
#include "engine/numerics/parallel.hpp"
#include "engine/numerics/compensated_sum.hpp"
#include "engine/qmc/qmc.hpp"
#include "engine/torus/torus.hpp"
#include "pendavg/trace_formula.hpp"

#include <boost/math/constants/constants.hpp>
#include <boost/math/special_functions/ellint_rd.hpp>
#include <boost/math/special_functions/ellint_rf.hpp>
#include <boost/math/special_functions/ellint_rg.hpp>

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <map>
#include <memory>
#include <mutex>
#include <random>
#include <string>
#include <type_traits>
#include <vector>

#if defined(_OPENMP)
#include <omp.h>
#endif

namespace pendavg {

namespace detail::microcanonical {

using std::abs;
using std::exp;
using std::log;
using std::sqrt;

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

/// Error-free transformations for the compensated excitation (built-in floating types).
template <class Real>
struct DoubleWord {
  Real hi{0}, lo{0};
};

template <class Real>
DoubleWord<Real> two_sum(const Real& a, const Real& b) {
  const Real s = a + b, bb = s - a;
  return {s, (a - (s - bb)) + (b - bb)};
}

template <class Real>
DoubleWord<Real> two_product(const Real& a, const Real& b) {
  const Real p = a * b;
  return {p, std::fma(a, b, -p)};
}

/// x + y for double words (relative error ~ u^2).
template <class Real>
DoubleWord<Real> add(const DoubleWord<Real>& x, const DoubleWord<Real>& y) {
  DoubleWord<Real> s = two_sum(x.hi, y.hi);
  s.lo += x.lo + y.lo;
  return two_sum(s.hi, s.lo);
}

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
/// sin^2 x / (1 + cos x) for cos x >= 0 (torus.hpp's S - R). `rho` = |z| > 0.
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

// --------------------------------------------------------------------------- tanh-sinh nodes

/// Nodes of the tanh-sinh rule on [-1, 1], x = tanh((pi/2) sinh t), t = k h, h = 2^-level, as
/// the distance c = 1 - |x| to the nearer end (no cancellation) and the weight dx/dt.
template <class Real>
struct TanhSinhTable {
  struct Node {
    Real complement, weight;
    int side;  ///< -1: near the left end, +1: near the right end, 0: the midpoint
  };
  std::vector<std::vector<Node>> levels;  ///< level 0: k = all; level L > 0: k odd

  /// The table up to level 12, built once per number type (thread-safe static); for MPFR once
  /// per working precision (the nodes carry that precision), the last max_cached_precisions
  /// precisions kept (a caller holds its table while it computes).
  static std::shared_ptr<const TanhSinhTable> shared() {
    if constexpr (is_mpfr_v<Real>) {
      struct Slot {
        std::shared_ptr<const TanhSinhTable> table;
        unsigned long long used = 0;
      };
      static std::mutex mutex;
      static std::map<long, Slot> tables;
      static unsigned long long clock = 0;
      const long bits = static_cast<long>(mpfr_real::thread_default_precision());
      const std::lock_guard lock(mutex);
      Slot& slot = tables[bits];
      if (!slot.table) slot.table = std::make_shared<const TanhSinhTable>(12);
      slot.used = ++clock;
      std::shared_ptr<const TanhSinhTable> table = slot.table;
      if (tables.size() > max_cached_precisions) {
        auto oldest = tables.begin();
        for (auto it = tables.begin(); it != tables.end(); ++it)
          if (it->second.used < oldest->second.used) oldest = it;
        tables.erase(oldest);  // never this call's: it was used last
      }
      return table;
    } else {
      static const std::shared_ptr<const TanhSinhTable> table =
          std::make_shared<const TanhSinhTable>(12);
      return table;
    }
  }
  static constexpr std::size_t max_cached_precisions = 8;

  explicit TanhSinhTable(int max_level) {
    using std::asinh;
    using std::cosh;
    using std::ldexp;
    using std::sinh;
    const Real u = unit_roundoff<Real>();
    const Real half_pi = pi<Real>() / 2;
    // beyond t_max the weights are below ~u^1.3: sinh t_max = 1.3 log(1/u) / pi
    const Real t_max = asinh(Real(1.3) * -log(u) / pi<Real>());
    levels.resize(static_cast<std::size_t>(max_level) + 1);
    for (int level = 0; level <= max_level; ++level) {
      const Real h = ldexp(Real(1), -level);
      const long count = static_cast<long>(t_max / h);
      for (long k = 0; k <= count; ++k) {
        if (level > 0 && k % 2 == 0) continue;
        const Real t = Real(static_cast<double>(k)) * h;
        const Real s = half_pi * sinh(t);
        const Real ch = cosh(s);
        const Real weight = half_pi * cosh(t) / (ch * ch);
        const Real complement = 1 / (exp(s) * ch);  // 1 - tanh s
        if (k == 0) {
          levels[static_cast<std::size_t>(level)].push_back({Real(1), weight, 0});
        } else {
          levels[static_cast<std::size_t>(level)].push_back({complement, weight, -1});
          levels[static_cast<std::size_t>(level)].push_back({complement, weight, +1});
        }
      }
    }
  }
};

// --------------------------------------------------------------------------- nested integral

/// A critical value t of |v_j| (the level-j partial sum of z, see the header comment), with,
/// where it lies just below sum_{k <= j} gamma_k, its deficit d = sum_{k <= j} gamma_k - t formed
/// from the excitation D (no cancellation near the bottom of the well).
template <class Real>
struct CriticalRadius {
  Real radius{}, deficit{};
  bool has_deficit = false;
};

/// Quantities integrated over theta: [0] sqrt(det A)/Hadamard F_p/W^p; [1 + i] the same with
/// tr X_i F_{p+1}/W^{p+1}; [1 + N + i] with cos(theta_i - arg z) G_p/W^p; [1 + 2N + i] with
/// ((tr X_i)^2 + 2 tr X_i^2) F_{p+2}/W^{p+2}. Then the same count of integrated error estimates.
template <class Real>
class NestedShellIntegral {
 public:
  struct Shared {
    const Chain<Real>* chain;
    const ShellSetup<Real>* setup;
    std::shared_ptr<const TanhSinhTable<Real>> table;  ///< held while the integral runs
    Real tolerance;
    int max_level;
    std::vector<std::vector<CriticalRadius<Real>>> targets;  ///< per level j: critical |v_j|
    std::vector<bool> light;                 ///< per level j: cut at delta_{j-1} = 0, pi
    /// Per level j and quantity c: an absolute error that is small enough whatever the piece's
    /// own size (tolerance x a rough global value / the measure of the outer angles). Without
    /// it, the vanishing fibres near a cut point would be refined to relative accuracy for
    /// nothing. Empty: relative accuracy only (the rough first pass).
    std::vector<std::vector<Real>> floor;
    bool force_stop = false;  ///< stop at max_level without counting it as a failure
    const RunControl* control = nullptr;  ///< progress (outermost pieces) and stop (nodes)
  };

  /// Quantity c is compared with its own size (kinetic and second moments) rather than with
  /// the weight's (the weight itself and the cosines, which can vanish).
  static bool own_scale(std::size_t c, std::size_t n) { return c >= 1 && (c <= n || c > 2 * n); }

  NestedShellIntegral(const Shared& shared, int threads)
      : s_(shared), n_(shared.setup->n), q_(1 + 3 * n_), threads_(std::max(threads, 1)),
        ws_(n_), theta_(n_, Real(0)), ct_(n_, Real(1)), st_(n_, Real(0)), vx_(n_, Real(0)),
        vy_(n_, Real(0)), length_(n_, Real(0)), deficit_(n_, Real(0)),
        deficit_product_(n_, Real(0)), delta_(n_ > 1 ? n_ - 1 : 1), buffers_(n_ + 1) {
    vx_[0] = s_.setup->gamma[0];
    length_[0] = s_.setup->gamma[0];
    for (auto& b : buffers_) b.resize(8 * q_);
  }

  std::size_t evaluations = 0, unconverged_pieces = 0;

  /// All 2q quantities integrated over the whole (N-1)-torus.
  std::vector<Real> integrate() {
    std::vector<Real> out(2 * q_, Real(0));
    if (n_ == 1) {
      evaluate_node(out.data());
      return out;
    }
    integrate_level(1, out.data());
    return out;
  }

 private:
  /// The integrand at the node whose angles theta_[0..n) are set.
  void evaluate_node(Real* out) {
    // A stop request ends the run within 256 nodes (microseconds each): no partial result.
    if ((++evaluations & 255) == 0 && s_.control != nullptr && s_.control->stop_requested())
      throw interrupted("microcanonical: stopped");
    const ShellSetup<Real>& k = *s_.setup;
    for (std::size_t i = 0; i + 1 < n_; ++i) delta_[i] = theta_[i + 1] - theta_[i];
    const Real zx = vx_[n_ - 1], zy = vy_[n_ - 1];
    const Real rho = length_[n_ - 1];
    const ShellMoments<Real> m = k.shell(k.energy, rho, k.depth(rho, deficit_[n_ - 1]), k.scale);
    for (std::size_t c = 0; c < 2 * q_; ++c) out[c] = 0;
    if (m.weight == 0 && m.kinetic == 0) return;
    const NodeTraces<Real>& t = node_traces_relative(*s_.chain, delta_.data(), ws_);
    const Real h = exp(t.log_sqrt_det_A - k.log_hadamard);
    out[0] = h * m.weight;
    const Real hk = h * m.kinetic, hk2 = h * m.kinetic_squared;
    const Real hc = rho > 0 ? Real(h * m.cosine / rho) : Real(0);
    for (std::size_t i = 0; i < n_; ++i) {
      const Real& x = t.trace_X[i];
      out[1 + i] = hk * x;
      // cos(theta_i - arg z) = (cos theta_i zx + sin theta_i zy) / rho
      out[1 + n_ + i] = hc * (ct_[i] * zx + st_[i] * zy);
      out[1 + 2 * n_ + i] = hk2 * (x * x + 2 * t.trace_X_squared[i]);
    }
  }

  /// a (1 - cos(angle - arg v)) for v = (vx, vy), a = |v|, angle given by its cosine and sine:
  /// from the dot and cross products, sin^2 x / (1 + cos x) when cos x >= 0 (no cancellation).
  static Real radial_gap(const Real& vx, const Real& vy, const Real& a, const Real& c,
                         const Real& s) {
    if (!(a > 0)) return Real(0);
    const Real dot = c * vx + s * vy, cross = s * vx - c * vy;
    return dot >= 0 ? Real(cross * cross / (a + dot)) : Real(a - dot);
  }

  /// sum_{k <= j} gamma_k - |v_{j-1} + gamma_j e^{i angle}| given level j - 1, from
  /// head_j^2 - |v_j|^2 = (head_{j-1}^2 - |v_{j-1}|^2) + 2 gamma_j (deficit_{j-1} + |v_{j-1}| (1 -
  /// cos(theta_j - arg v_{j-1}))): non-negative terms only.
  /// `length` = |v_j|; `product` receives head_j^2 - |v_j|^2.
  Real level_deficit(std::size_t j, const Real& c, const Real& s, const Real& length,
                     Real& product) const {
    const Real g = s_.setup->gamma[j];
    product = deficit_product_[j - 1] +
              2 * g * (deficit_[j - 1] + radial_gap(vx_[j - 1], vy_[j - 1], length_[j - 1], c, s));
    return product / (s_.setup->head_gamma[j] + length);
  }

  void set_angle(std::size_t j, const Real& angle) {
    using std::cos;
    using std::sin;
    theta_[j] = angle;
    ct_[j] = cos(angle);
    st_[j] = sin(angle);
    const Real g = s_.setup->gamma[j];
    vx_[j] = vx_[j - 1] + g * ct_[j];
    vy_[j] = vy_[j - 1] + g * st_[j];
    length_[j] = sqrt(vx_[j] * vx_[j] + vy_[j] * vy_[j]);
    deficit_[j] = level_deficit(j, ct_[j], st_[j], length_[j], deficit_product_[j]);
  }

  /// The integral over theta_j (given theta_0..theta_{j-1}) of the inner integral; adds to out.
  void integrate_level(std::size_t j, Real* out) {
    using std::acos;
    using std::asin;
    using std::atan2;
    using std::fmod;
    const Real two_pi = 2 * pi<Real>(), p = pi<Real>();
    const ShellSetup<Real>& k = *s_.setup;
    const Real g = k.gamma[j];
    const Real vx = vx_[j - 1], vy = vy_[j - 1];
    const Real v = length_[j - 1];
    const Real arg_v = (j == 1) ? Real(0) : atan2(vy, vx);
    std::vector<Real> cuts;
    cuts.push_back(arg_v);
    cuts.push_back(arg_v + p);
    if (v > 0) {
      for (const CriticalRadius<Real>& target : s_.targets[j]) {
        // |v_j| = t at cos(theta_j - arg v) = c, c = (t^2 - v^2 - g^2) / (2 g v). Near the bottom
        // 1 - c = (v + g - t)(v + g + t) / (2 g v) with v + g - t = d - deficit_{j-1}.
        const Real& t = target.radius;
        if (target.has_deficit) {
          const Real one_minus_c =
              (target.deficit - deficit_[j - 1]) * (v + g + t) / (2 * g * v);
          if (one_minus_c > 0 && one_minus_c < 2) {
            const Real a = one_minus_c <= 1 ? Real(2 * asin(sqrt(one_minus_c / 2)))
                                            : Real(acos(1 - one_minus_c));
            cuts.push_back(arg_v + a);
            cuts.push_back(arg_v - a);
          }
          continue;
        }
        const Real c = (t * t - v * v - g * g) / (2 * g * v);
        if (c > -1 && c < 1) {
          const Real a = acos(c);
          cuts.push_back(arg_v + a);
          cuts.push_back(arg_v - a);
        }
      }
    }
    if (s_.light[j]) {
      cuts.push_back(theta_[j - 1]);
      cuts.push_back(theta_[j - 1] + p);
    }
    // Into [-pi, pi), touching only the cuts outside it: a cut near 0 (near the bottom of the
    // well every cut is within ~sqrt(D) of arg v, and arg v = 0 at j = 1) keeps its relative
    // accuracy, which fmod(c + pi, 2 pi) - pi would reduce to an absolute u pi: the piece would
    // then end up to ~u pi / sqrt(D) (relative) off the square-root edge of the accessible arc.
    for (Real& c : cuts) {
      if (c >= -p && c < p) continue;
      c = fmod(c + p, two_pi);
      if (c < 0) c += two_pi;
      c -= p;
    }
    std::sort(cuts.begin(), cuts.end());
    // Cuts closer than 64 u (relative) are one cut.
    const Real close = 64 * unit_roundoff<Real>();
    const auto apart = [&](const Real& a, const Real& b) {
      using std::max;
      return b - a > close * max(abs(a), abs(b));
    };
    std::vector<Real> ends;
    for (const Real& c : cuts) {
      if (j == 1 && (c < 0)) continue;  // symmetric: [0, pi] only
      if (ends.empty() || apart(ends.back(), c)) ends.push_back(c);
    }
    if (j == 1) {
      if (ends.empty() || ends.front() > 0) ends.insert(ends.begin(), Real(0));
      if (apart(ends.back(), p)) {
        ends.push_back(p);
      } else {
        ends.back() = p;
      }
    } else {
      const Real first = ends.front();
      if (apart(ends.back(), first + two_pi)) {
        ends.push_back(first + two_pi);
      } else {
        ends.back() = first + two_pi;
      }
    }
    Real* piece = buffers_[j].data() + 4 * q_;  // 2q entries
    const Real multiplicity = (j == 1) ? Real(2) : Real(1);
    for (std::size_t a = 0; a + 1 < ends.size(); ++a) {
      const Real lo = ends[a], hi = ends[a + 1];
      if (!apart(lo, hi)) continue;
      if (k.excitation < k.gamma_sum) {
        // E < 0: a fibre whose largest reachable |z| stays below |E| contributes nothing, i.e.
        // sum_{k <= j} gamma_k - |v_j| >= D at the piece's midpoint (no cut inside it).
        using std::cos;
        using std::sin;
        const Real mid = (lo + hi) / 2;
        const Real c = cos(mid), s = sin(mid);
        const Real wx = vx + g * c, wy = vy + g * s;
        Real product;
        const Real deficit = level_deficit(j, c, s, sqrt(wx * wx + wy * wy), product);
        if (deficit >= k.excitation) continue;
      }
      integrate_piece(j, lo, hi, piece);
      for (std::size_t c = 0; c < 2 * q_; ++c) out[c] += multiplicity * piece[c];
      if (j == 1 && s_.control != nullptr)
        s_.control->report(static_cast<double>(a + 1) / static_cast<double>(ends.size() - 1));
    }
    if (j == 1 && s_.control != nullptr) s_.control->report(1.0);  // skipped pieces included
  }

  /// tanh-sinh on [lo, hi] over theta_j; writes 2q entries (values, then error estimates).
  void integrate_piece(std::size_t j, const Real& lo, const Real& hi, Real* result) {
    using std::ldexp;
    std::vector<Real>& buf = buffers_[j];
    Real* acc = buf.data();             // 2q: sum of weight * f over all nodes so far
    Real* previous = buf.data() + 2 * q_;  // q: previous level's values
    Real* difference = buf.data() + 3 * q_;  // q: previous level's differences
    for (std::size_t c = 0; c < 2 * q_; ++c) acc[c] = 0;
    const Real half = (hi - lo) / 2;
    const Real tolerance = s_.tolerance;
    for (int level = 0; level <= s_.max_level; ++level) {
      const auto& nodes = s_.table->levels[static_cast<std::size_t>(level)];
      accumulate_nodes(j, lo, hi, half, nodes, acc);
      const Real h = ldexp(Real(1), -level);
      for (std::size_t c = 0; c < 2 * q_; ++c) result[c] = h * acc[c];
      if (level >= 1) {
        bool done = true;
        for (std::size_t c = 0; c < q_; ++c) {
          const Real d = abs(result[c] - previous[c]);
          Real e = d;
          if (level >= 2 && difference[c] > 0 && d <= difference[c] / 10) {
            e = d * (d / difference[c]);
          }
          difference[c] = d;
          const Real scale = own_scale(c, n_) ? abs(result[c]) : abs(result[0]);
          const Real floor = s_.floor.empty() ? Real(0) : s_.floor[j][c];
          if (!(e <= tolerance * scale) && !(e <= floor)) done = false;
          previous[c] = e;  // reuse: holds the estimate until overwritten below
        }
        if (done || level == s_.max_level) {
          if (!done && !s_.force_stop) {
            ++unconverged_pieces;
          }
          for (std::size_t c = 0; c < q_; ++c) result[q_ + c] += previous[c];
          break;
        }
      }
      for (std::size_t c = 0; c < q_; ++c) previous[c] = result[c];
    }
  }

  /// Adds weight * integrand (2q entries) over the given nodes to acc.
  void accumulate_nodes(std::size_t j, const Real& lo, const Real& hi, const Real& half,
                        const std::vector<typename TanhSinhTable<Real>::Node>& nodes, Real* acc);

 public:
  /// The integrand (q values, then q zero errors) at the node theta[0..n), theta[0] = 0.
  void evaluate_at(const Real* theta, Real* out) {
    for (std::size_t j = 1; j < n_; ++j) set_angle(j, theta[j]);
    evaluate_node(out);
  }
  /// Integrand of level j at theta_j = angle (inner integral or node), 2q entries.
  void level_integrand(std::size_t j, const Real& angle, Real* out) {
    set_angle(j, angle);
    if (j + 1 == n_) {
      evaluate_node(out);
    } else {
      for (std::size_t c = 0; c < 2 * q_; ++c) out[c] = 0;
      integrate_level(j + 1, out);
    }
  }
  /// Copies the outer angles (levels < j) of another integrator.
  void copy_outer(const NestedShellIntegral& other, std::size_t j) {
    for (std::size_t i = 0; i < j; ++i) {
      theta_[i] = other.theta_[i];
      ct_[i] = other.ct_[i];
      st_[i] = other.st_[i];
      vx_[i] = other.vx_[i];
      vy_[i] = other.vy_[i];
      length_[i] = other.length_[i];
      deficit_[i] = other.deficit_[i];
      deficit_product_[i] = other.deficit_product_[i];
    }
  }
  std::vector<std::unique_ptr<NestedShellIntegral>>* workers = nullptr;

 private:
  const Shared& s_;
  std::size_t n_, q_;
  int threads_;
  TraceWorkspace<Real> ws_;
  std::vector<Real> theta_, ct_, st_, vx_, vy_;
  /// Per level j: |v_j|, head_j - |v_j| and head_j^2 - |v_j|^2 (head_j = sum_{k <= j} gamma_k).
  std::vector<Real> length_, deficit_, deficit_product_;
  std::vector<Real> delta_;
  std::vector<std::vector<Real>> buffers_;  ///< per level: acc, previous, difference, piece, scratch
  std::vector<Real> batch_;                 ///< outermost level: per-node results
};

template <class Real>
void NestedShellIntegral<Real>::accumulate_nodes(
    std::size_t j, const Real& lo, const Real& hi, const Real& half,
    const std::vector<typename TanhSinhTable<Real>::Node>& nodes, Real* acc) {
  const std::size_t count = nodes.size();
  const auto angle_of = [&](const typename TanhSinhTable<Real>::Node& node) {
    if (node.side == 0) return Real((lo + hi) / 2);
    return node.side < 0 ? Real(lo + half * node.complement) : Real(hi - half * node.complement);
  };
  if (j == 1 && threads_ > 1 && workers != nullptr && count > 1) {
    // Outermost level: nodes in parallel, one integrator per thread, summed in node order.
    batch_.assign(count * 2 * q_, Real(0));
    auto& team = *workers;
    ParallelErrors errors;  // an exception may not leave the parallel region
#if defined(_OPENMP)
#pragma omp parallel for num_threads(threads_) schedule(dynamic, 1)
#endif
    for (std::ptrdiff_t i = 0; i < static_cast<std::ptrdiff_t>(count); ++i) {
      errors.capture([&] {
#if defined(_OPENMP)
        const int id = omp_get_thread_num();
#else
        const int id = 0;
#endif
        NestedShellIntegral& worker = *team[static_cast<std::size_t>(id)];
        worker.copy_outer(*this, 1);
        worker.level_integrand(1, angle_of(nodes[static_cast<std::size_t>(i)]),
                               batch_.data() + static_cast<std::size_t>(i) * 2 * q_);
      });
    }
    errors.rethrow();
    for (std::size_t i = 0; i < count; ++i) {
      const Real w = half * nodes[i].weight;
      for (std::size_t c = 0; c < 2 * q_; ++c) acc[c] += w * batch_[i * 2 * q_ + c];
    }
    return;
  }
  Real* f = buffers_[j].data() + 6 * q_;  // scratch of level j
  for (std::size_t i = 0; i < count; ++i) {
    level_integrand(j, angle_of(nodes[i]), f);
    const Real w = half * nodes[i].weight;
    for (std::size_t c = 0; c < 2 * q_; ++c) acc[c] += w * f[c];
  }
}

}  // namespace detail::microcanonical

}  // namespace pendavg
