// SPDX-License-Identifier: GPL-3.0-or-later
// The transfer operator along the chain (engine/transfer/chain_transfer.hpp has the equations).
#include "engine/transfer/chain_transfer.hpp"
#include "engine/numerics/legendre.hpp"

#include "engine/numerics/estimates.hpp"
#include "engine/numerics/parallel.hpp"

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstdint>
#include <limits>
#include <string>
#include <type_traits>
#include <vector>

namespace pendavg {
namespace {

template <class Real>
Real pi_value() {
  return Real(3.14159265358979323846264338327950288L);
}

/// Natural logarithm for the interpolation coordinate. In double a branch-free version the
/// compiler vectorizes (fdlibm's reduction: x = 2^e (1 + f), (1 + f) in [sqrt(1/2), sqrt(2)),
/// log(1 + f) = 2 atanh(s), s = f / (2 + f), |s| < 0.172, series to s^23; error ~1 ulp);
/// positive normal arguments only (the caller's are >= eps_j > 0).
template <class Real>
inline Real interpolation_log(const Real& x) {
  using std::log;
  if constexpr (std::is_same_v<Real, double>) {
    const std::uint64_t bits = std::bit_cast<std::uint64_t>(x);
    std::int64_t e = static_cast<std::int64_t>(bits >> 52) - 1023;
    double mant = std::bit_cast<double>((bits & 0x000fffffffffffffULL) | 0x3ff0000000000000ULL);
    const bool high = mant > 1.4142135623730951;
    mant = high ? mant * 0.5 : mant;
    e += high ? 1 : 0;
    const double f = mant - 1;
    const double s = f / (2 + f), s2 = s * s;
    // 2 atanh(s) = 2 s sum_k s^(2k) / (2k + 1), k = 0..11
    double p = 1.0 / 23;
    p = p * s2 + 1.0 / 21;
    p = p * s2 + 1.0 / 19;
    p = p * s2 + 1.0 / 17;
    p = p * s2 + 1.0 / 15;
    p = p * s2 + 1.0 / 13;
    p = p * s2 + 1.0 / 11;
    p = p * s2 + 1.0 / 9;
    p = p * s2 + 1.0 / 7;
    p = p * s2 + 1.0 / 5;
    p = p * s2 + 1.0 / 3;
    const double ln2_hi = 6.93147180369123816490e-01, ln2_lo = 1.90821492927058770002e-10;
    const double ed = static_cast<double>(e);
    // log = e ln2 + f - f^2/2 + (s (f^2/2 + R)) in fdlibm; here the direct 2 s (1 + s^2 p):
    return ed * ln2_hi + (2 * s + (2 * s * s2 * p + ed * ln2_lo));
  } else {
    return log(x);
  }
}

/// The angle rule of one particle: nodes, weights (measure dphi / 2 pi) times the scaled
/// Boltzmann factor exp(alpha (cos phi - 1)), cos phi, and the reflection phi -> -phi on the
/// node indices (both rules are symmetric).
template <class Real>
struct AngleRule {
  std::vector<Real> angle, weight_boltzmann, cos_angle;
  std::vector<Real> boltzmann;  ///< exp(alpha (cos phi - 1)) alone
  std::vector<std::size_t> mirror;
  bool periodic = true;
  Real half_width{0};  ///< pi, or the window's L
};

template <class Real>
AngleRule<Real> angle_rule(const Real& alpha, const Real& truncation, std::size_t n) {
  using std::asin;
  using std::sqrt;
  using std::cos;
  using std::exp;
  using std::sin;
  AngleRule<Real> rule;
  rule.angle.resize(n);
  rule.weight_boltzmann.resize(n);
  rule.cos_angle.resize(n);
  rule.boltzmann.resize(n);
  rule.mirror.resize(n);
  const Real pi = pi_value<Real>();
  const Real nn = Real(static_cast<double>(n));
  const bool periodic = !(2 * alpha > truncation);
  Real half_width = pi, weight = 1 / nn;
  if (!periodic) {
    // 1 - cos L = truncation / alpha, without the cancellation of acos(1 - x) at large alpha.
    half_width = 2 * asin(sqrt(truncation / (2 * alpha)));
    weight = 2 * half_width / (2 * pi * nn);
  }
  rule.periodic = periodic;
  rule.half_width = half_width;
  for (std::size_t a = 0; a < n; ++a) {
    const Real k = Real(static_cast<double>(a));
    // periodic: -pi + 2 pi a / n (-pi and 0 are nodes); window: the midpoints of n cells.
    const Real x = periodic ? -pi + 2 * pi * k / nn : -half_width + half_width * (2 * k + 1) / nn;
    const Real h = sin(x / 2);
    rule.angle[a] = x;
    rule.cos_angle[a] = cos(x);
    rule.boltzmann[a] = exp(-2 * alpha * h * h);
    rule.weight_boltzmann[a] = weight * rule.boltzmann[a];
    rule.mirror[a] = periodic ? (n - a) % n : n - 1 - a;
  }
  return rule;
}

/// The pivot rule of one particle: Chebyshev-Lobatto nodes t_c = cos(pi c / (m - 1)) in
/// t = v_scale log((u + eps) / (1 + saturation u)) + v_shift over u in [0, u_max]; particle 1 has
/// the single node u = 0. saturation is 0 (the coordinate log(u + eps)) or 1 where u_max is large
/// (pivot_saturates): the messages divided by their envelopes are analytic in y = 1/(1 + u) near
/// y = 0 (u' enters the next step only through u'' = r (1 - c^2 / (1 + u'))) and their
/// singularities lie on u in [-1, -m_j/S_j], so in w = (u + eps)/(1 + u) (eps <= m_j/S_j, < 1)
/// they lie on w <= 0: log w has the same strip of analyticity |Im| < pi as log(u + eps), over a
/// range log(1/eps) that no longer grows with u_max. After a very light particle u_max =
/// m_j/m_{j-1} reaches 1e12, and log(u + eps) would span ~30 units (~100 Chebyshev nodes).
template <class Real>
struct PivotRule {
  std::size_t m = 1;
  Real eps{1}, v_scale{0}, v_shift{0}, saturation{0};
  std::vector<Real> u, root_factor, inv_one_plus_u;  ///< u_c, sqrt(m_j (1 + u_c)), 1/(1 + u_c)
  std::vector<Real> to_coefficients;  ///< [k * m + c]: Chebyshev coefficient k from node values
  /// Messages interpolated divided by their envelopes (message_envelopes): only where u spans a
  /// wide range (u_max = m_j / m_{j-1} > envelope_range); elsewhere they vary little and the
  /// sqrt and division per evaluation would cost ~40% of the sweeps for nothing.
  bool enveloped = false;
  /// [q * m + c]: the envelope of message q at the node (message_envelopes at u_c + 1), or 1.
  std::vector<Real> node_envelope;
};

constexpr double envelope_range = 4;

/// The envelopes of the four messages (M0, N1, N2, N3; see chain_transfer_level) at x = u + 1:
/// sqrt(x), 1/sqrt(x), x^(-3/2), 1/sqrt(x). M0 ~ sqrt(1 + kappa s^2 + u (1 + kappa)) grows like
/// sqrt(u) at large u, and rho = d_u log(W / sqrt(m (1 + u))) falls like u^-2 (the next pivot
/// depends on u through 1/(1 + u)), so N1 = W (1+u) rho ~ u^-1/2, N2 = W (1+u)^2 rho^2 ~ u^-3/2,
/// N3 = W (1+u)^2 d_u rho ~ u^-1/2. Over u in [0, m_j/m_{j-1}] (up to 1e12 after a very light
/// particle) they span orders of magnitude. Chebyshev interpolation has uniform absolute
/// accuracy, so the messages are interpolated divided by their envelopes (analytic in the pivot
/// coordinate off the same cut: the convergence rate is unchanged), which keeps their relative
/// accuracy where they are small and are multiplied by large factors.
template <class Real>
inline void message_envelopes(const Real& x, Real* out) {
  using std::sqrt;
  const Real r = sqrt(x), ir = 1 / r;
  out[0] = r;
  out[1] = ir;
  out[2] = ir * ir * ir;
  out[3] = ir;
}

/// Whether the pivot rule of a particle with u in [0, u_max] takes the saturating coordinate
/// (PivotRule): exactly where its messages are enveloped.
template <class Real>
bool pivot_saturates(const Real& u_max) {
  return u_max > Real(envelope_range);
}

/// The offset eps of the pivot coordinate: m_j/S_j, at most 1/2 when saturating (w = (u + eps) /
/// (1 + u) must grow with u; a smaller eps keeps the cut u <= -m_j/S_j on w <= 0).
template <class Real>
Real pivot_offset_eps(const Real& eps, const Real& u_max) {
  return pivot_saturates(u_max) ? std::min(eps, Real(0.5)) : eps;
}

/// The coordinate range [lo, hi] of a pivot rule (see PivotRule).
template <class Real>
void pivot_coordinate_range(const Real& eps, const Real& u_max, Real& lo, Real& hi) {
  using std::log;
  lo = log(eps);
  hi = pivot_saturates(u_max) ? log((u_max + eps) / (1 + u_max)) : log(u_max + eps);
}

template <class Real>
PivotRule<Real> pivot_rule(const Real& mass, const Real& tail_eps, const Real& u_max,
                           std::size_t m) {
  using std::cos;
  using std::expm1;
  using std::log;
  using std::sqrt;
  PivotRule<Real> rule;
  rule.m = m;
  const bool saturating = pivot_saturates(u_max);
  const Real eps = pivot_offset_eps(tail_eps, u_max);
  rule.eps = eps;
  rule.saturation = saturating ? Real(1) : Real(0);
  if (m == 1) {
    rule.u.assign(1, Real(0));
  } else {
    Real lo, hi;
    pivot_coordinate_range(eps, u_max, lo, hi);
    rule.v_scale = 2 / (hi - lo);
    rule.v_shift = -(hi + lo) / (hi - lo);
    rule.u.resize(m);
    rule.to_coefficients.resize(m * m);
    const Real pi = pi_value<Real>();
    const Real mm1 = Real(static_cast<double>(m - 1));
    for (std::size_t c = 0; c < m; ++c) {
      const Real t = cos(pi * Real(static_cast<double>(c)) / mm1);
      const Real above = (t + 1) / rule.v_scale;  // the coordinate minus lo
      if (saturating) {
        // w = e^v, u = (w - eps) / (1 - w) = eps expm1(v - lo) / -expm1(v), v = lo + above < 0
        rule.u[c] = eps * expm1(above) / -expm1(lo + above);
      } else {
        rule.u[c] = eps * expm1(above);  // u + eps = eps e^{(t + 1)(hi - lo)/2}
      }
    }
    rule.u.front() = u_max;
    rule.u.back() = 0;
    for (std::size_t k = 0; k < m; ++k) {
      for (std::size_t c = 0; c < m; ++c) {
        Real w = 2 / mm1 * cos(pi * Real(static_cast<double>((k * c) % (2 * (m - 1)))) / mm1);
        if (c == 0 || c + 1 == m) w /= 2;
        if (k == 0 || k + 1 == m) w /= 2;
        rule.to_coefficients[k * m + c] = w;
      }
    }
  }
  for (const Real& u : rule.u) {
    rule.root_factor.push_back(sqrt(mass * (1 + u)));
    rule.inv_one_plus_u.push_back(1 / (1 + u));
  }
  rule.enveloped = u_max > Real(envelope_range);
  rule.node_envelope.assign(4 * rule.m, Real(1));
  for (std::size_t c = 0; rule.enveloped && c < rule.m; ++c) {
    Real e[4];
    message_envelopes(Real(rule.u[c] + 1), e);
    for (std::size_t q = 0; q < 4; ++q) rule.node_envelope[q * rule.m + c] = e[q];
  }
  return rule;
}

/// Scale x by a power of two so that max |x| lies in [1/2, 1) (no rounding: the factor is an
/// exact power of two, applied as one multiplication per entry).
template <class Real>
void normalize(std::vector<Real>& x) {
  using std::abs;
  using std::frexp;
  using std::ldexp;
  Real top = 0;
  for (const Real& v : x) top = std::max(top, Real(abs(v)));
  if (!(top > 0)) return;
  int e = 0;
  frexp(top, &e);
  const Real factor = ldexp(Real(1), -e);
  for (Real& v : x) v *= factor;
}

/// Indices a <= mirror(a): each reflection orbit once; multiplicity 1 or 2.
template <class Real>
void orbit_representatives(const AngleRule<Real>& rule, std::vector<std::size_t>& index,
                           std::vector<Real>& multiplicity) {
  index.clear();
  multiplicity.clear();
  for (std::size_t a = 0; a < rule.mirror.size(); ++a) {
    if (a <= rule.mirror[a]) {
      index.push_back(a);
      multiplicity.push_back(a == rule.mirror[a] ? Real(1) : Real(2));
    }
  }
}

/// Links after which a heavy mass follows within two particles are integrated over the relative
/// angle (see RelativeRule): with kappa = k_{j+1}/m_j, the coupling of phi_j and phi_{j+1} is
/// sqrt(1 + kappa sin^2 delta + u_j (1 + kappa)) (the split form of det A), a kink of width
/// ~ kappa^-1/2 along the diagonal delta = 0 of the (phi_j, phi_{j+1}) grid that a product rule
/// resolves only with O(kappa^1/2) more nodes. kappa >= m_{j+1}/m_j always, and it reaches
/// (m_{j+1} + k_{j+2})/m_j, k_{j+2} ~ 2 m_{j+2}, when one more link is straight, which a heavy
/// particle j+2 makes likely. So: relative iff (m_{j+1} + 2 m_{j+2}) / m_j > this. Uniform
/// chains stay on the product rule (ratio 3), where straight tails are rare.
constexpr double relative_link_ratio = 4;

/// The relative-angle rule of one light-to-heavy link: delta = phi_{j+1} - phi_j on n nodes
/// clustered at delta = 0 (and pi) by an entire map, so that the kink of width
/// w = sqrt(m_j / S_{j+1}) (the smoothing of |sin delta| at u_j = 0) is resolved:
///   delta in (-pi, pi]:   delta = t - (a/2) sin 2t, t equispaced (periodic trapezoid);
///   delta in [-D, D] (both angles in windows, D = L_j + L_{j+1} < pi):
///                         delta = D (t - (a/pi) sin(pi t)), t the midpoints of [-1, 1];
/// 1 - a = clamp(3 w, 0.02, 1): the node density at 0 is 1/(1 - a) times the mean. Narrower
/// kinks (w < sinh_rule_width) take sinh-mapped panels instead (sinh_relative_rule).
/// Weights are for the measure d delta / (2 pi).
template <class Real>
struct RelativeRule {
  std::vector<Real> delta, weight, sin2, cos2;
};

/// Gauss-Legendre nodes and weights on [-1, 1] (q small): Newton on P_q from the usual guess.
template <class Real>
void gauss_legendre(std::size_t q, std::vector<Real>& x, std::vector<Real>& w) {
  using std::abs;
  using std::cos;
  const Real pi = pi_value<Real>();
  const Real qq = Real(static_cast<double>(q));
  x.assign(q, Real(0));
  w.assign(q, Real(0));
  for (std::size_t i = 0; i < (q + 1) / 2; ++i) {
    Real z = cos(pi * (Real(static_cast<double>(i)) + Real(0.75)) / (qq + Real(0.5)));
    Real derivative = 1;
    for (int iteration = 0; iteration < 100; ++iteration) {
      const detail::LegendreAt<Real> legendre = detail::legendre_at(q, z);
      derivative = legendre.derivative;
      const Real step = legendre.value / derivative;
      z -= step;
      if (abs(step) <= 4 * std::numeric_limits<Real>::epsilon()) break;
    }
    if (2 * i + 1 == q) z = 0;
    const Real weight = 2 / ((1 - z * z) * derivative * derivative);
    x[i] = -z;
    x[q - 1 - i] = z;
    w[i] = w[q - 1 - i] = weight;
  }
}

/// Below this kink width the relative-angle rule is made of sinh-mapped panels (sinh_relative_rule):
/// the entire map's clustering is capped (1 - a >= 0.02), and a kink much narrower than that
/// would take ~1/width angle nodes (a particle of mass 1e-8 before unit masses: width 7e-5).
constexpr double sinh_rule_width = 1e-2;

/// The relative-angle rule of a link whose kink is narrow (width w = sqrt(m_j / S_{j+1}) <
/// sinh_rule_width): the integrand's singularities lie near the imaginary axis at delta = +-i s
/// (s >= w: the zeros of 1 + u' and the cuts of the next messages, u' = r (u + sin^2 delta) /
/// (1 + u) in [-1, -m_{j+1}/S_{j+1}], at sin^2 delta = -(u + kappa (1 + u)/r)), and the same at
/// pi. On each side of 0 (and of pi) the offset e = |delta| or pi - |delta| runs over
/// e = w sinh(s), s in [0, asinh(E / w)] (E = pi/2, or the window span D): every singularity
/// above the axis lies at Im s = pi/2, whatever its distance w..1, so Gauss-Legendre panels of
/// length <= 1.2 in s converge like (5.4)^(-2q) with q nodes each, and the count grows only like
/// log(1/w). Panels are also at most E/6 long in delta, where the Boltzmann factor and the next
/// messages vary (the scale of the window). q = max(4, n/4) follows the angle ladder (about the
/// trapezoid's rate per level). sin^2 and cos^2 are formed from the offset e, accurately near pi.
template <class Real>
RelativeRule<Real> sinh_relative_rule(const Real& span, const Real& width, std::size_t n) {
  using std::asinh;
  using std::cos;
  using std::cosh;
  using std::sin;
  using std::sinh;
  const Real pi = pi_value<Real>();
  const bool periodic = span >= pi;
  const Real extent = periodic ? pi / 2 : span;  // of each half-cluster, in delta
  const Real cap = extent / 6;
  const Real s_end = asinh(extent / width);
  constexpr double panel_length = 1.2;
  const std::size_t q = std::max<std::size_t>(4, (n + 3) / 4);
  std::vector<Real> x, w;
  gauss_legendre(q, x, w);
  // Offsets e >= 0 and their weights (measure d delta / (2 pi)) of one half-cluster.
  std::vector<Real> offset, offset_weight;
  Real s0 = 0;
  while (s0 < s_end) {
    Real s1 = std::min(s_end, Real(s0 + Real(panel_length)));
    if (width * (sinh(s1) - sinh(s0)) > cap) s1 = std::min(s_end, Real(asinh(sinh(s0) + cap / width)));
    const Real mid = (s0 + s1) / 2, half = (s1 - s0) / 2;
    for (std::size_t i = 0; i < q; ++i) {
      const Real s = mid + half * x[i];
      offset.push_back(width * sinh(s));
      offset_weight.push_back(half * w[i] * width * cosh(s) / (2 * pi));
    }
    s0 = s1;
  }
  RelativeRule<Real> rule;
  const auto push = [&](const Real& delta, const Real& e, const Real& weight) {
    const Real se = sin(e), ce = cos(e);
    rule.delta.push_back(delta);
    rule.weight.push_back(weight);
    rule.sin2.push_back(se * se);
    rule.cos2.push_back(ce * ce);
  };
  for (std::size_t i = 0; i < offset.size(); ++i) {
    const Real& e = offset[i];
    push(e, e, offset_weight[i]);
    push(-e, e, offset_weight[i]);
    if (periodic) {
      push(pi - e, e, offset_weight[i]);
      push(e - pi, e, offset_weight[i]);
    }
  }
  return rule;
}

template <class Real>
RelativeRule<Real> relative_rule(const AngleRule<Real>& from, const AngleRule<Real>& to,
                                 const Real& width, std::size_t n) {
  using std::cos;
  using std::sin;
  const Real pi = pi_value<Real>();
  if (width < Real(sinh_rule_width) && 20 * width < from.half_width + to.half_width) {
    return sinh_relative_rule(Real(from.half_width + to.half_width), width, n);
  }
  const Real nn = Real(static_cast<double>(n));
  const Real a = 1 - std::min(Real(1), std::max(Real(0.02), 3 * width));
  const Real span = from.half_width + to.half_width;
  RelativeRule<Real> rule;
  for (std::size_t k = 0; k < n; ++k) {
    const Real kk = Real(static_cast<double>(k));
    Real d, w;
    if (span >= pi) {
      const Real t = -pi + 2 * pi * kk / nn;
      d = t - a / 2 * sin(2 * t);
      w = (1 - a * cos(2 * t)) / nn;
    } else {
      const Real t = -1 + (2 * kk + 1) / nn;
      d = span * (t - a / pi * sin(pi * t));
      w = span * (1 - a * cos(pi * t)) * 2 / (nn * 2 * pi);
    }
    const Real sd = sin(d), cd = cos(d);
    rule.delta.push_back(d);
    rule.weight.push_back(w);
    rule.sin2.push_back(sd * sd);
    rule.cos2.push_back(cd * cd);
  }
  return rule;
}

/// The trigonometric interpolation weight of node b of `rule` at the angle x (the Dirichlet
/// kernel of the uniform grid over its period 2 L: sin(n theta / 2) / (n tan(theta / 2)),
/// theta = pi (x - phi_b) / L); 0 outside a window (the data vanish there to roundoff).
template <class Real>
Real trig_interpolation_weight(const AngleRule<Real>& rule, std::size_t b, const Real& x) {
  using std::abs;
  using std::remainder;
  using std::sin;
  using std::tan;
  const Real pi = pi_value<Real>();
  const Real angle = remainder(x, 2 * pi);  // the physical angle in [-pi, pi]
  if (!rule.periodic && abs(angle) > rule.half_width) return 0;
  const std::size_t n = rule.angle.size();
  Real theta = remainder(pi * (angle - rule.angle[b]) / rule.half_width, 2 * pi);  // (-pi, pi]
  const Real half = theta / 2;
  if (abs(half) < Real(1e-7)) return 1 - Real(static_cast<double>(n * n + 2)) * half * half / 6;
  return sin(Real(static_cast<double>(n)) * half) / (Real(static_cast<double>(n)) * tan(half));
}

/// Vector width of the inner kernels (points kept in registers at once).
constexpr std::size_t lanes = 8;

/// A link is split over threads only above this much work (kernel evaluations times pivot
/// nodes): below it the fork and barrier cost more than they save, and much more when the other
/// cores are busy.
/// Why: README, Design notes, 'Measurements behind the design choices' (transfer).
constexpr double parallel_work_threshold = 1e6;

/// Rounding budget of every quantity, in roundoffs times the sum of the absolute values of the
/// terms it is made of (NodeSums); the variance takes four times this (see flatten).
constexpr double rounding_ulps = 64;

/// The sums of one link at one node (phi_j, u_j) over the next angle, from the next messages at
/// (phi_{j+1}, u'), each weighted by its quadrature weight: the messages of particle j (A0..A3)
/// and the pairings of its node quantities (C, B). The messages are carried with the derivative
/// of the factor sqrt(m (1 + u)) split off (M0 = E[W], N1 = E[W (1+u) rho], N2 = E[W (1+u)^2
/// rho^2], N3 = E[W (1+u)^2 d_u rho], rho = d_u log(W / sqrt(m (1 + u))), pathwise), so that
///   tr X_j = a0 + 2 Q d_{u'} log W_{j+1} = p + 2 q1 (1+u') rho',
///   p = a0 + Q/(1+u') = (1 + T)/(1+u') + u/(1+u),   q1 = Q/(1+u'),
///   T = r u c^2/(1+u)^2,   Q = -u' + T   (r = m_{j+1}/m_j, c = cos delta),
/// is a sum of terms of the size of tr X_j itself: a very light particle has tr X_j ~ m_j log
/// m_j, and the direct form a0 + 2 Q S cancels 1 against ~-1 (Q ~ -u' ~ -1/m_j) and loses all
/// digits at m_j ~ 1e-12. Likewise
///   (tr X_j)^2 = p^2 + 4 p q1 (1+u') rho' + 4 q1^2 (1+u')^2 rho'^2,
///   d^2 log det A / d(log m_j)^2 = h + 2 dq1 (1+u') rho' + 2 q1^2 (1+u')^2 d_{u'} rho',
///   h = u/(1+u)^2 + [(-Q)(1 + T) - 2 u T (1+u')/(1+u)] / (1+u')^2,   dq1 = dQ/(1+u'),
///   dQ = d Q / d log m_j = -Q - 2 u T/(1+u),
/// and the recursion (J = d u'/d u = r c^2/(1+u)^2 = T/u):
///   M0 = f A0,  N1 = f (1+u) A1,  N2 = f (1+u)^2 A2,  N3 = f ((1+u)^2 A3 - 2 (1+u) A1),
///   A0 = E[V0],  A1 = E[J (V0/2 + N1') y'],  A2 = E[J^2 (V0/4 + N1' + N2') y'^2],
///   A3 = E[J^2 (N3' - V0/2) y'^2],   y' = 1/(1+u'),   f = sqrt(m_j (1 + u)).
/// The a-suffixed sums take the absolute values of terms whose sign varies (the rounding scale).
template <class Real>
struct LinkSums {
  Real A0{0}, A1{0}, A2{0}, A3{0};
  Real C1{0}, C2{0}, C3{0}, C3a{0}, B1{0}, B1p{0}, B2{0}, B3{0}, B3a{0}, B4{0};
  /// One next node: r = m_{j+1}/m_j, (u, ip = 1/(1+u)) the node's pivot, s2, c2 = sin^2, cos^2
  /// of the relative angle, up = u', and the weighted next messages V0, N1, N2, N3 at it.
  inline void add(const Real& r, const Real& u, const Real& ip, const Real& s2, const Real& c2,
                  const Real& up, const Real& V0, const Real& N1, const Real& N2,
                  const Real& N3) {
    using std::abs;
    const Real yp = 1 / (1 + up), yp2 = yp * yp;
    const Real J = r * c2 * ip * ip, T = u * J;
    const Real minus_Q = r * (u * u + s2 * (1 + 2 * u)) * ip * ip;
    const Real q1 = -minus_Q * yp;
    const Real p = (1 + T) * yp + u * ip;
    const Real dq1 = (minus_Q - 2 * u * T * ip) * yp;
    const Real h = u * ip * ip + minus_Q * (1 + T) * yp2 - 2 * u * T * ip * yp;
    A0 += V0;
    A1 += J * (V0 / 2 + N1) * yp;
    A2 += J * J * (V0 / 4 + N1 + N2) * yp2;
    A3 += J * J * (N3 - V0 / 2) * yp2;
    const Real pV0 = p * V0, qN1 = q1 * N1;
    C1 += pV0;
    C2 += p * pV0;
    C3 += h * V0;
    C3a += abs(h * V0);
    B1 += qN1;
    B1p += p * qN1;
    B2 += q1 * q1 * N2;
    B3 += dq1 * N1;
    B3a += abs(dq1 * N1);
    B4 += q1 * q1 * N3;
  }
  /// The messages of particle j at the node: out[q * stride] (M0, N1, N2, N3).
  inline void messages(const Real& f, const Real& u, Real* out, std::size_t stride) const {
    const Real x = 1 + u;
    out[0] = f * A0;
    out[stride] = f * x * A1;
    out[2 * stride] = f * x * x * A2;
    out[3 * stride] = f * (x * x * A3 - 2 * x * A1);
  }
};

/// The node sums of one particle over its (phi, u) nodes, with the forward weight fw = F_j f_c
/// and the link sums (LinkSums): Z, Z <cos phi>, Z <tr X>, Z <(tr X)^2>,
/// Z <d^2 log det A / d(log m)^2>, then the same sums over the absolute values of their terms
/// (their rounding is u times these).
constexpr std::size_t node_sum_count = 9;

template <class Real>
struct NodeSums {
  Real v[node_sum_count] = {};
  void add(const Real& fw, const Real& cos_phi, const LinkSums<Real>& L) {
    using std::abs;
    const Real w = fw * L.A0, afw = abs(fw);
    v[0] += w;
    v[1] += w * cos_phi;
    v[2] += fw * (L.C1 + 2 * L.B1);
    v[3] += fw * (L.C2 + 4 * L.B1p + 4 * L.B2);
    v[4] += fw * (L.C3 + 2 * L.B3 + 2 * L.B4);
    v[5] += abs(w * cos_phi);
    v[6] += afw * (abs(L.C1) + 2 * abs(L.B1));
    v[7] += afw * (abs(L.C2) + 4 * abs(L.B1p) + 4 * abs(L.B2));
    v[8] += afw * (L.C3a + 2 * L.B3a + 2 * abs(L.B4));
  }
  void store(Real* out, const Real& multiplicity) const {
    for (std::size_t q = 0; q < node_sum_count; ++q) out[q] = multiplicity * v[q];
  }
};

/// The Chebyshev values T_0..T_{m-1} at t.
template <class Real>
void chebyshev_values(const Real& t, std::size_t m, Real* out) {
  out[0] = 1;
  if (m > 1) out[1] = t;
  for (std::size_t k = 2; k < m; ++k) out[k] = 2 * t * out[k - 1] - out[k - 2];
}

/// The interpolation coordinate of u' = r (u + s^2) / (1 + u) on the pivot rule `to`, and u'.
template <class Real>
Real next_pivot_coordinate(const PivotRule<Real>& to, const Real& ratio, const Real& u,
                           const Real& s2, Real& u_next) {
  u_next = ratio * (u + s2) / (1 + u);
  const Real x =
      to.v_scale * interpolation_log(Real((u_next + to.eps) / (1 + to.saturation * u_next))) +
      to.v_shift;
  return std::min(Real(1), std::max(Real(-1), x));
}

/// At a pivot value u and a relative angle with sin^2 = sin2: the Chebyshev values `tk` (pn.m)
/// of the next pivot coordinate, and the message envelopes `e` there (all 1 unless pn is
/// enveloped). Shared by relative_forward and relative_backward.
template <class Real>
void next_pivot_basis(const PivotRule<Real>& pn, const Real& ratio, const Real& u,
                      const Real& sin2, Real* tk, Real (&e)[4], Real& u_next) {
  chebyshev_values(next_pivot_coordinate(pn, ratio, u, sin2, u_next), pn.m, tk);
  e[0] = e[1] = e[2] = e[3] = 1;
  if (pn.enveloped) message_envelopes(Real(u_next + 1), e);
}

/// Forward step of a light-to-heavy link over the relative angle: F_{j+1}(b, c') = E_b sum_{a,c,k}
/// F_j(a, c) f_c w_k D_b(phi_a + delta_k) L_{c'}(t(u_c, delta_k)), D_b the trigonometric
/// interpolation weight of node b (the transpose of relative_backward's interpolation).
template <class Real>
void relative_forward(const AngleRule<Real>& from, const AngleRule<Real>& to,
                      const PivotRule<Real>& pj, const PivotRule<Real>& pn,
                      const RelativeRule<Real>& rel, const Real& ratio,
                      const std::vector<Real>& forward, std::vector<Real>& next, int team) {
  const std::size_t n = from.angle.size(), nd = rel.delta.size(), mj = pj.m, mn = pn.m;
  // basis[(k * mj + c) * mn + c']: the Lagrange basis of the next pivot rule at t(u_c, delta_k)
  std::vector<Real> basis(nd * mj * mn), tk(mn);
  for (std::size_t k = 0; k < nd; ++k) {
    for (std::size_t c = 0; c < mj; ++c) {
      Real e[4], u_next;
      next_pivot_basis(pn, ratio, pj.u[c], rel.sin2[k], tk.data(), e, u_next);
      for (std::size_t cp = 0; cp < mn; ++cp) {
        Real acc = 0;
        for (std::size_t q = 0; q < mn; ++q) acc += tk[q] * pn.to_coefficients[q * mn + cp];
        basis[(k * mj + c) * mn + cp] = acc * e[0] / pn.node_envelope[cp];
      }
    }
  }
  std::vector<Real> source(n * mj);
  for (std::size_t a = 0; a < n; ++a) {
    for (std::size_t c = 0; c < mj; ++c) source[a * mj + c] = forward[a * mj + c] * pj.root_factor[c];
  }
  const bool parallel = team > 1 && double(n) * double(n) * double(nd) * double(mj) >=
                                        parallel_work_threshold;
  std::vector<std::size_t> orbit;
  std::vector<Real> multiplicity;
  orbit_representatives(to, orbit, multiplicity);
  ParallelErrors errors;  // an exception may not leave the parallel region
#if defined(_OPENMP)
#pragma omp parallel for num_threads(team) schedule(static) if (parallel)
#endif
  for (std::ptrdiff_t ob = 0; ob < static_cast<std::ptrdiff_t>(orbit.size()); ++ob) {
    errors.capture([&] {
      const std::size_t b = orbit[static_cast<std::size_t>(ob)];
      std::vector<Real> column(n), h(mj), row(mn, Real(0));
      for (std::size_t k = 0; k < nd; ++k) {
        for (std::size_t a = 0; a < n; ++a) {
          column[a] = trig_interpolation_weight(to, b, Real(from.angle[a] + rel.delta[k]));
        }
        for (std::size_t c = 0; c < mj; ++c) {
          Real acc = 0;
          for (std::size_t a = 0; a < n; ++a) acc += column[a] * source[a * mj + c];
          h[c] = rel.weight[k] * acc;
        }
        for (std::size_t c = 0; c < mj; ++c) {
          const Real* L = &basis[(k * mj + c) * mn];
          for (std::size_t cp = 0; cp < mn; ++cp) row[cp] += h[c] * L[cp];
        }
      }
      for (std::size_t cp = 0; cp < mn; ++cp) {
        next[b * mn + cp] = to.boltzmann[b] * row[cp];
        next[to.mirror[b] * mn + cp] = to.boltzmann[b] * row[cp];
      }
    });
  }
  errors.rethrow();
}

/// Backward step of a light-to-heavy link over the relative angle (the messages of particle j
/// and its NodeSums, summed over the nodes into `sums`). The next
/// messages times E_{j+1} are interpolated in u (Chebyshev) and in phi (trigonometric) at
/// (phi_a + delta_k, u'(u_c, delta_k)).
template <class Real>
void relative_backward(const AngleRule<Real>& from, const AngleRule<Real>& to,
                       const PivotRule<Real>& pj, const PivotRule<Real>& pn,
                       const RelativeRule<Real>& rel, const Real& ratio,
                       const std::vector<Real>& coef, std::size_t np,
                       const std::vector<Real>& forward, std::vector<Real>& current, Real* sums,
                       int team) {
  const std::size_t n = from.angle.size(), nd = rel.delta.size(), mj = pj.m, mn = pn.m;
  // values[((k * mj + c) * 4 + q) * n + b] = E_b M_q(phi_b, u'(u_c, delta_k)), and u' itself
  std::vector<Real> values(nd * mj * 4 * n), next_u(nd * mj);
  const bool parallel = team > 1 && double(n) * double(n) * double(nd) * double(mj) >=
                                        parallel_work_threshold;
  ParallelErrors errors;  // an exception may not leave the parallel regions
#if defined(_OPENMP)
#pragma omp parallel for num_threads(team) schedule(static) if (parallel)
#endif
  for (std::ptrdiff_t kk = 0; kk < static_cast<std::ptrdiff_t>(nd); ++kk) {
    errors.capture([&] {
      const std::size_t k = static_cast<std::size_t>(kk);
      std::vector<Real> tk(mn);
      for (std::size_t c = 0; c < mj; ++c) {
        Real e[4];
        next_pivot_basis(pn, ratio, pj.u[c], rel.sin2[k], tk.data(), e, next_u[k * mj + c]);
        for (std::size_t q = 0; q < 4; ++q) {
          Real* out = &values[((k * mj + c) * 4 + q) * n];
          for (std::size_t b = 0; b < n; ++b) {
            Real acc = 0;
            for (std::size_t kp = 0; kp < mn; ++kp) acc += coef[(q * mn + kp) * np + b] * tk[kp];
            out[b] = to.boltzmann[b] * e[q] * acc;
          }
        }
      }
    });
  }
  errors.rethrow();
  // Rows a and mirror(a) are equal (the rules are symmetric under phi -> -phi): one per orbit.
  std::vector<std::size_t> orbit;
  std::vector<Real> multiplicity;
  orbit_representatives(from, orbit, multiplicity);
  std::vector<Real> row_sums(node_sum_count * orbit.size(), Real(0));
#if defined(_OPENMP)
#pragma omp parallel for num_threads(team) schedule(static) if (parallel)
#endif
  for (std::ptrdiff_t oa = 0; oa < static_cast<std::ptrdiff_t>(orbit.size()); ++oa) {
    errors.capture([&] {
      const std::size_t a = orbit[static_cast<std::size_t>(oa)];
      std::vector<Real> interp(n);
      std::vector<LinkSums<Real>> link(mj);
      for (std::size_t k = 0; k < nd; ++k) {
        for (std::size_t b = 0; b < n; ++b) {
          interp[b] = trig_interpolation_weight(to, b, Real(from.angle[a] + rel.delta[k]));
        }
        const Real w = rel.weight[k];
        for (std::size_t c = 0; c < mj; ++c) {
          Real v[4];
          for (std::size_t q = 0; q < 4; ++q) {
            const Real* vals = &values[((k * mj + c) * 4 + q) * n];
            Real x = 0;
            for (std::size_t b = 0; b < n; ++b) x += interp[b] * vals[b];
            v[q] = w * x;
          }
          link[c].add(ratio, pj.u[c], pj.inv_one_plus_u[c], rel.sin2[k], rel.cos2[k],
                      next_u[k * mj + c], v[0], v[1], v[2], v[3]);
        }
      }
      NodeSums<Real> row;
      for (std::size_t c = 0; c < mj; ++c) {
        const Real f = pj.root_factor[c];
        for (const std::size_t r : {a, from.mirror[a]}) {
          link[c].messages(f, pj.u[c], &current[(0 * n + r) * mj + c], n * mj);
        }
        row.add(forward[a * mj + c] * f, from.cos_angle[a], link[c]);
      }
      const std::size_t o = static_cast<std::size_t>(oa);
      row.store(&row_sums[node_sum_count * o], multiplicity[o]);
    });
  }
  errors.rethrow();
  for (std::size_t q = 0; q < node_sum_count; ++q) sums[q] = 0;
  for (std::size_t o = 0; o < orbit.size(); ++o) {
    for (std::size_t q = 0; q < node_sum_count; ++q) sums[q] += row_sums[node_sum_count * o + q];
  }
}

}  // namespace

template <class Real>
void check_transfer_domain(const Chain<Real>& chain, const Real& beta) {
  using std::isfinite;
  check_beta(beta);
  for (std::size_t j = 0; j < chain.size(); ++j) {
    if (!isfinite(beta * chain.potential_coefficient(j))) {
      throw invalid_input("transfer: beta g S_j l_j overflows at particle " +
                          std::to_string(j + 1) + " (outside the double range)");
    }
  }
  // The pivots u_j <= m_j / m_{j-1}, their offsets m_j / S_j and the node sums carry ratios up to
  // M / m_min and their squares: finite only for M / m_min <= 1e150 (as the torus).
  const Real lightest = *std::min_element(chain.masses().begin(), chain.masses().end());
  using std::log10;
  if (!(chain.total_mass() / lightest <= Real(1e150))) {
    throw invalid_input("transfer: the total mass is 1e" +
                        std::to_string(static_cast<int>(log10(chain.total_mass() / lightest))) +
                        " times the lightest mass, beyond the double range of the transfer "
                        "operator (1e150)");
  }
  // A particle below 1e-16 of the total mass (the 1e-127 of a 6-particle chain ran unbounded;
  // 1e-12 converges in seconds) is below double's resolution of the chain's sums: refused.
  for (std::size_t i = 0; i < chain.size(); ++i)
    if (!(chain.mass(i) / chain.total_mass() >= Real(1e-16)))
      throw invalid_input("transfer: particle " + std::to_string(i + 1) + " weighs less than "
                          "1e-16 of the total mass, below what the transfer operator resolves");
  // A light particle (m_i / S_{i+1} small) gets its own node placement, but two adjacent ones do
  // not converge in bounded time (measured: four unit masses before a tail of 1e8 took 17 s,
  // 1e9 and 1e10 never finished; 1, 1e-8, 1e-8, 1, 1 never finished): refused before any work.
  for (std::size_t i = 0; i + 2 < chain.size(); ++i) {
    const auto light = [&](std::size_t k) {
      return !(chain.mass(k) / chain.tail_mass(k + 1) >= Real(1e-7));
    };
    if (light(i) && light(i + 1))
      throw invalid_input("transfer: particles " + std::to_string(i + 1) + " and " +
                          std::to_string(i + 2) + " both weigh less than 1e-7 of the mass "
                          "beyond them (m_i / S_(i+1)); the transfer operator resolves one such "
                          "light particle, not two adjacent ones");
  }
  // A stiff first link far softer than the second (alpha_1 >= 10 and alpha_1 <= 1e-8 alpha_2)
  // produced non-finite values (measured on N = 8: alpha_1 = 110..2e12 at ratios 2.5e-9 and
  // below, after up to 5 s; ratio 1e-8 ends non-converged; interior links at any ratio
  // converge; alpha_1 = 22 at 2.5e-12 converged and is refused too, for a margin): refused
  // before any work.
  if (chain.size() >= 2) {
    const Real alpha1 = beta * chain.potential_coefficient(0),
               alpha2 = beta * chain.potential_coefficient(1);
    if (alpha1 >= Real(10) && !(alpha1 > Real(1e-8) * alpha2))
      throw invalid_input("transfer: link 1's stiffness beta g S_1 l_1 is below 1e-8 of link "
                          "2's while itself stiff (>= 10), which the transfer operator does not "
                          "resolve");
  }
}

namespace {

/// The rules of one level: per particle the angle rule and the pivot rule, and per light-to-heavy
/// link the relative-angle rule (is_relative[j] for the link j -> j + 1).
template <class Real>
struct LevelRules {
  std::vector<AngleRule<Real>> angle;
  std::vector<PivotRule<Real>> pivot;
  std::vector<RelativeRule<Real>> relative;
  std::vector<char> is_relative;
};

template <class Real>
LevelRules<Real> level_rules(const Chain<Real>& chain, const Real& beta, std::size_t n,
                             std::size_t pivot_nodes) {
  using std::log;
  using std::sqrt;
  const std::size_t N = chain.size();
  const std::vector<Real>& mass = chain.masses();
  LevelRules<Real> rules;
  // ---- per particle: the angle rule and the pivot rule.
  const Real roundoff = std::numeric_limits<Real>::epsilon();
  rules.angle.resize(N);
  rules.pivot.resize(N);
  for (std::size_t j = 0; j < N; ++j) {
    const Real alpha = beta * chain.potential_coefficient(j);  // finite: checked by the caller
    const Real u_max = j > 0 ? mass[j] / mass[j - 1] : Real(0);
    // The marginal of phi_j is below exp(alpha (cos phi - 1)) times the spread of its conditional
    // factor sqrt(D_j) <= sqrt((1 + u_max) S_j / m_j): cut where the product is below roundoff.
    const Real truncation =
        -log(roundoff) + 3 + log((1 + u_max) * chain.tail_mass(j) / mass[j]) / 2;
    rules.angle[j] = angle_rule(alpha, truncation, n);
    rules.pivot[j] =
        pivot_rule(mass[j], mass[j] / chain.tail_mass(j), u_max, j > 0 ? pivot_nodes : 1);
  }
  // Light-to-heavy links: the relative-angle rule (see RelativeRule).
  rules.relative.resize(N);
  rules.is_relative.assign(N, 0);
  for (std::size_t j = 0; j + 1 < N; ++j) {
    const Real reach = mass[j + 1] + (j + 2 < N ? 2 * mass[j + 2] : Real(0));
    if (reach > Real(relative_link_ratio) * mass[j]) {
      rules.is_relative[j] = 1;
      rules.relative[j] = relative_rule(rules.angle[j], rules.angle[j + 1],
                                        Real(sqrt(mass[j] / chain.tail_mass(j + 1))), n);
    }
  }
  return rules;
}

/// Forward step of a link on the product (phi_j, phi_{j+1}) grid: F_{j+1}(b, c') = E_b w_b
/// sum_{a,c} F_j(a, c) sqrt(m_j (1 + u_c)) L_{c'}(u'(u_c, phi_b - phi_a)), L_{c'} the Lagrange
/// basis of the next pivot rule (through its Chebyshev moments). Returns the kernel evaluations.
template <class Real>
double product_forward(const AngleRule<Real>& from, const AngleRule<Real>& to,
                       const PivotRule<Real>& pj, const PivotRule<Real>& pn, const Real& ratio,
                       const std::vector<Real>& forward, std::vector<Real>& next, int team) {
  using std::sin;
  using std::sqrt;
  const std::size_t n = from.angle.size(), mj = pj.m, mn = pn.m;
  const std::size_t count = n * mj, padded = (count + lanes - 1) / lanes * lanes;
  // Sources: F_j sqrt(m_j (1 + u)), padded with zero weights.
  std::vector<Real> source(padded, Real(0)), source_u(padded, Real(0)),
      source_ip(padded, Real(1));
  for (std::size_t a = 0; a < n; ++a) {
    for (std::size_t c = 0; c < mj; ++c) {
      source[a * mj + c] = forward[a * mj + c] * pj.root_factor[c];
      source_u[a * mj + c] = pj.u[c];
      source_ip[a * mj + c] = pj.inv_one_plus_u[c];
    }
  }
  std::vector<std::size_t> orbit;
  std::vector<Real> multiplicity;
  orbit_representatives(to, orbit, multiplicity);
  const bool parallel = team > 1 && double(orbit.size()) * double(count) * double(mn) >=
                                        parallel_work_threshold;
  ParallelErrors errors;  // an exception may not leave the parallel region
#if defined(_OPENMP)
#pragma omp parallel num_threads(team) if (parallel)
#endif
  {
    std::vector<Real> s2, t, weighted, moment, partial;
    bool ready = false;
    errors.capture([&] {
      s2.assign(n, Real(0));
      t.assign(padded, Real(0));
      weighted.assign(padded, Real(0));
      moment.assign(mn, Real(0));
      partial.assign(mn * lanes, Real(0));
      ready = true;
    });
#if defined(_OPENMP)
#pragma omp for schedule(static)
#endif
    for (std::ptrdiff_t ob = 0; ob < static_cast<std::ptrdiff_t>(orbit.size()); ++ob) {
      errors.capture([&] {
        if (!ready) return;
        const std::size_t b = orbit[static_cast<std::size_t>(ob)];
        for (std::size_t a = 0; a < n; ++a) {
          const Real s = sin(to.angle[b] - from.angle[a]);
          s2[a] = s * s;
        }
        for (std::size_t a = 0; a < n; ++a) {
          const Real sa = s2[a];
          for (std::size_t c = 0; c < mj; ++c) {
            const std::size_t q = a * mj + c;
            const Real up = ratio * (source_u[q] + sa) * source_ip[q];
            const Real x =
                pn.v_scale * interpolation_log(Real((up + pn.eps) / (1 + pn.saturation * up))) +
                pn.v_shift;
            t[q] = std::min(Real(1), std::max(Real(-1), x));
          }
        }
        if (pn.enveloped) {  // M0's envelope (message_envelopes) at u' + 1
          for (std::size_t a = 0; a < n; ++a) {
            for (std::size_t c = 0; c < mj; ++c) {
              const std::size_t q = a * mj + c;
              weighted[q] = source[q] * sqrt(ratio * (source_u[q] + s2[a]) * source_ip[q] + 1);
            }
          }
        }
        const Real* w_source = pn.enveloped ? weighted.data() : source.data();
        // moment[k] = sum_q source_q T_k(t_q), `lanes` points at a time.
        std::fill(partial.begin(), partial.end(), Real(0));
        for (std::size_t q0 = 0; q0 < padded; q0 += lanes) {
          Real x[lanes], w[lanes], tk0[lanes], tk1[lanes];
          for (std::size_t l = 0; l < lanes; ++l) {
            x[l] = t[q0 + l];
            w[l] = w_source[q0 + l];
            tk0[l] = 1;
            tk1[l] = x[l];
            partial[l] += w[l];
            partial[lanes + l] += w[l] * x[l];
          }
          for (std::size_t k = 2; k < mn; ++k) {
            Real* acc = &partial[k * lanes];
            for (std::size_t l = 0; l < lanes; ++l) {
              const Real tn = 2 * x[l] * tk1[l] - tk0[l];
              tk0[l] = tk1[l];
              tk1[l] = tn;
              acc[l] += w[l] * tn;
            }
          }
        }
        for (std::size_t k = 0; k < mn; ++k) {
          Real acc = 0;
          for (std::size_t l = 0; l < lanes; ++l) acc += partial[k * lanes + l];
          moment[k] = acc;
        }
        const Real wb = to.weight_boltzmann[b];
        for (std::size_t c = 0; c < mn; ++c) {
          Real acc = 0;
          for (std::size_t k = 0; k < mn; ++k) acc += moment[k] * pn.to_coefficients[k * mn + c];
          acc /= pn.node_envelope[c];
          next[b * mn + c] = wb * acc;
          next[to.mirror[b] * mn + c] = wb * acc;
        }
      });
    }
  }
  errors.rethrow();
  return double(orbit.size()) * double(count);
}

/// Forward sweep: F_j[a * m_j + c], the measure of (phi_j, u_j), scaled per link (normalize).
/// poll(links_done) runs before each link, outside every parallel region.
template <class Real, class Poll>
std::vector<std::vector<Real>> forward_sweep(const Chain<Real>& chain,
                                             const LevelRules<Real>& rules, int team,
                                             const Poll& poll, double& kernel_evaluations) {
  const std::size_t N = chain.size();
  const std::vector<Real>& mass = chain.masses();
  std::vector<std::vector<Real>> forward(N);
  forward[0] = rules.angle[0].weight_boltzmann;  // u_1 = 0: one pivot node
  normalize(forward[0]);
  for (std::size_t j = 0; j + 1 < N; ++j) {
    poll(j);
    const PivotRule<Real>& pj = rules.pivot[j];
    const PivotRule<Real>& pn = rules.pivot[j + 1];
    const AngleRule<Real>& from = rules.angle[j];
    const AngleRule<Real>& to = rules.angle[j + 1];
    const std::size_t n = from.angle.size();
    const Real ratio = mass[j + 1] / mass[j];
    std::vector<Real> next(n * pn.m, Real(0));
    if (rules.is_relative[j]) {
      relative_forward(from, to, pj, pn, rules.relative[j], ratio, forward[j], next, team);
      kernel_evaluations += double(n) * double(pj.m) * double(rules.relative[j].delta.size());
    } else {
      kernel_evaluations += product_forward(from, to, pj, pn, ratio, forward[j], next, team);
    }
    normalize(next);
    forward[j + 1] = std::move(next);
  }
  return forward;
}

/// The node quantities of particle j from its NodeSums: Z, Z <cos>, Z <tr X>, Z <(tr X)^2>,
/// Z <d^2 log det A>, and the same over |terms| (the rounding scales).
template <class Real>
void store_node_quantities(TransferLevel<Real>& out, std::size_t j, const Real* sums) {
  using std::abs;
  const Real z = sums[0];
  const Real k = sums[2] / (2 * z);
  const Real trace_squared = sums[2] - sums[4];  // Z <tr X^2> = Z <tr X - d^2 log det A>
  out.beta_kinetic[j] = k;
  out.cos_angle[j] = sums[1] / z;
  out.beta2_kinetic_second_moment[j] = (sums[3] + 2 * trace_squared) / (4 * z);
  out.beta2_kinetic_variance[j] = out.beta2_kinetic_second_moment[j] - k * k;
  out.beta_kinetic_rounding_scale[j] = sums[6] / (2 * z);
  out.cos_angle_rounding_scale[j] = sums[5] / z;
  out.beta2_kinetic_variance_rounding_scale[j] =
      (sums[7] + 2 * (sums[6] + sums[8])) / (4 * z) + 2 * abs(k) * sums[6] / (2 * z);
}

/// The messages of the last particle as node values, message[(q * n + a) * m + c], q = 0..3
/// (M0 = sqrt(m (1 + u)); N1 = N2 = N3 = 0: nothing follows), and its NodeSums (no next link:
/// tr X_N = 1 + u/(1 + u), d^2 log det A / d(log m)^2 = u/(1 + u)^2).
template <class Real>
std::vector<Real> last_particle_messages(const AngleRule<Real>& angle, const PivotRule<Real>& pj,
                                         const std::vector<Real>& forward, Real* sums) {
  const std::size_t n = angle.angle.size(), mj = pj.m;
  std::vector<Real> message(4 * n * mj, Real(0));
  NodeSums<Real> last;
  for (std::size_t a = 0; a < n; ++a) {
    for (std::size_t c = 0; c < mj; ++c) {
      const Real u = pj.u[c], ip = pj.inv_one_plus_u[c], f = pj.root_factor[c];
      message[(0 * n + a) * mj + c] = f;
      LinkSums<Real> L;
      const Real a0 = 1 + u * ip;
      L.A0 = 1;
      L.C1 = a0;
      L.C2 = a0 * a0;
      L.C3 = L.C3a = u * ip * ip;
      last.add(forward[a * mj + c] * f, angle.cos_angle[a], L);
    }
  }
  last.store(sums, Real(1));
  return message;
}

/// Chebyshev coefficients of the messages of particle j + 1 divided by their envelopes:
/// coef[(q * mn + k) * np + b], np the angle nodes padded to whole vector blocks.
template <class Real>
std::vector<Real> message_coefficients(const PivotRule<Real>& pn, const std::vector<Real>& message,
                                       std::size_t n, std::size_t np) {
  const std::size_t mn = pn.m;
  std::vector<Real> coef(4 * mn * np, Real(0));
  for (std::size_t q = 0; q < 4; ++q) {
    for (std::size_t b = 0; b < n; ++b) {
      const Real* values = &message[(q * n + b) * mn];
      for (std::size_t k = 0; k < mn; ++k) {
        Real acc = 0;
        for (std::size_t c = 0; c < mn; ++c) {
          acc += pn.to_coefficients[k * mn + c] * values[c] / pn.node_envelope[q * mn + c];
        }
        coef[(q * mn + k) * np + b] = acc;
      }
    }
  }
  return coef;
}

/// The four messages of particle j + 1 at the interpolation coordinates t_b of one pivot node:
/// v[q * np + b] = sum_k coef_q[k][b] T_k(t_b), times the envelopes at u' + 1 (u_next) when the
/// pivot rule is enveloped; `lanes` targets at a time.
template <class Real>
inline void message_values(const std::vector<Real>& coef, std::size_t mn, std::size_t np,
                           const Real* t, const Real* u_next, bool enveloped, Real* v) {
  using std::sqrt;
  for (std::size_t b0 = 0; b0 < np; b0 += lanes) {
    Real x[lanes], tk0[lanes], tk1[lanes], v0[lanes], v1[lanes], v2[lanes], v3[lanes];
    for (std::size_t l = 0; l < lanes; ++l) {
      x[l] = t[b0 + l];
      tk0[l] = 1;
      tk1[l] = x[l];
      v0[l] = coef[(0 * mn) * np + b0 + l] + coef[(0 * mn + 1) * np + b0 + l] * x[l];
      v1[l] = coef[(1 * mn) * np + b0 + l] + coef[(1 * mn + 1) * np + b0 + l] * x[l];
      v2[l] = coef[(2 * mn) * np + b0 + l] + coef[(2 * mn + 1) * np + b0 + l] * x[l];
      v3[l] = coef[(3 * mn) * np + b0 + l] + coef[(3 * mn + 1) * np + b0 + l] * x[l];
    }
    for (std::size_t k = 2; k < mn; ++k) {
      const Real* k0 = &coef[(0 * mn + k) * np + b0];
      const Real* k1 = &coef[(1 * mn + k) * np + b0];
      const Real* k2 = &coef[(2 * mn + k) * np + b0];
      const Real* k3 = &coef[(3 * mn + k) * np + b0];
      for (std::size_t l = 0; l < lanes; ++l) {
        const Real tn = 2 * x[l] * tk1[l] - tk0[l];
        tk0[l] = tk1[l];
        tk1[l] = tn;
        v0[l] += k0[l] * tn;
        v1[l] += k1[l] * tn;
        v2[l] += k2[l] * tn;
        v3[l] += k3[l] * tn;
      }
    }
    if (enveloped) {  // times the envelopes (message_envelopes) at u' + 1
      for (std::size_t l = 0; l < lanes; ++l) {
        const Real r = sqrt(u_next[b0 + l] + 1), ir = 1 / r, ir3 = ir * ir * ir;
        v0[l] *= r;
        v1[l] *= ir;
        v2[l] *= ir3;
        v3[l] *= ir;
      }
    }
    for (std::size_t l = 0; l < lanes; ++l) {
      v[b0 + l] = v0[l];
      v[np + b0 + l] = v1[l];
      v[2 * np + b0 + l] = v2[l];
      v[3 * np + b0 + l] = v3[l];
    }
  }
}

/// Backward step of a link on the product (phi_j, phi_{j+1}) grid: the messages M0..M3 of
/// particle j (`current`) and its NodeSums summed over the nodes (`sums`), from the Chebyshev
/// coefficients of particle j + 1's messages evaluated at u'(u_c, phi_b - phi_a). Returns the
/// kernel evaluations.
template <class Real>
double product_backward(const AngleRule<Real>& from, const AngleRule<Real>& to,
                        const PivotRule<Real>& pj, const PivotRule<Real>& pn, const Real& ratio,
                        const std::vector<Real>& coef, std::size_t np,
                        const std::vector<Real>& forward, std::vector<Real>& current, Real* sums,
                        int team) {
  using std::cos;
  using std::sin;
  using std::sqrt;
  const std::size_t n = from.angle.size(), mj = pj.m, mn = pn.m;
  std::vector<std::size_t> orbit;
  std::vector<Real> multiplicity;
  orbit_representatives(from, orbit, multiplicity);
  std::vector<Real> row_sums(node_sum_count * orbit.size(), Real(0));
  const bool parallel = team > 1 && double(orbit.size()) * double(mj * n) * double(mn) >=
                                        parallel_work_threshold;
  ParallelErrors errors;  // an exception may not leave the parallel region
#if defined(_OPENMP)
#pragma omp parallel num_threads(team) if (parallel)
#endif
  {
    std::vector<Real> s2, c2, t, v, u_next;
    bool ready = false;
    errors.capture([&] {
      s2.assign(np, Real(0));
      c2.assign(np, Real(0));
      t.assign(np, Real(0));
      v.assign(4 * np, Real(0));
      u_next.assign(np, Real(0));
      ready = true;
    });
#if defined(_OPENMP)
#pragma omp for schedule(static)
#endif
    for (std::ptrdiff_t oa = 0; oa < static_cast<std::ptrdiff_t>(orbit.size()); ++oa) {
      errors.capture([&] {
        if (!ready) return;
        const std::size_t a = orbit[static_cast<std::size_t>(oa)];
        for (std::size_t b = 0; b < n; ++b) {
          const Real d = to.angle[b] - from.angle[a];
          const Real s = sin(d), c = cos(d);
          s2[b] = s * s;
          c2[b] = c * c;
        }
        NodeSums<Real> row;
        for (std::size_t c = 0; c < mj; ++c) {
          const Real u = pj.u[c], ip = pj.inv_one_plus_u[c];
          for (std::size_t b = 0; b < n; ++b) {
            const Real up = ratio * (u + s2[b]) * ip;
            const Real x =
                pn.v_scale * interpolation_log(Real((up + pn.eps) / (1 + pn.saturation * up))) +
                pn.v_shift;
            t[b] = std::min(Real(1), std::max(Real(-1), x));
            u_next[b] = up;
          }
          message_values(coef, mn, np, t.data(), u_next.data(), pn.enveloped, v.data());
          LinkSums<Real> L;
          for (std::size_t b = 0; b < n; ++b) {
            const Real w = to.weight_boltzmann[b];
            L.add(ratio, u, ip, s2[b], c2[b], u_next[b], w * v[b], w * v[np + b],
                  w * v[2 * np + b], w * v[3 * np + b]);
          }
          const Real f = pj.root_factor[c];
          L.messages(f, u, &current[(0 * n + a) * mj + c], n * mj);
          if (from.mirror[a] != a) {
            for (std::size_t q = 0; q < 4; ++q) {
              current[(q * n + from.mirror[a]) * mj + c] = current[(q * n + a) * mj + c];
            }
          }
          row.add(forward[a * mj + c] * f, from.cos_angle[a], L);
        }
        const std::size_t o = static_cast<std::size_t>(oa);
        row.store(&row_sums[node_sum_count * o], multiplicity[o]);
      });
    }
  }
  errors.rethrow();
  for (std::size_t q = 0; q < node_sum_count; ++q) sums[q] = 0;
  for (std::size_t o = 0; o < orbit.size(); ++o) {
    for (std::size_t q = 0; q < node_sum_count; ++q) sums[q] += row_sums[node_sum_count * o + q];
  }
  return double(orbit.size()) * double(mj) * double(n);
}

/// Backward sweep: the messages M0..M3 from the free end to the root and, at each particle, its
/// node quantities. poll(links_done) runs before each link, outside every parallel region.
template <class Real, class Poll>
TransferLevel<Real> backward_sweep(const Chain<Real>& chain, const LevelRules<Real>& rules,
                                   const std::vector<std::vector<Real>>& forward, std::size_t np,
                                   int team, const Poll& poll, double& kernel_evaluations) {
  const std::size_t N = chain.size();
  const std::vector<Real>& mass = chain.masses();
  TransferLevel<Real> out;
  out.beta_kinetic.assign(N, Real(0));
  out.cos_angle.assign(N, Real(0));
  out.beta2_kinetic_variance.assign(N, Real(0));
  out.beta2_kinetic_second_moment.assign(N, Real(0));
  out.beta_kinetic_rounding_scale.assign(N, Real(0));
  out.beta2_kinetic_variance_rounding_scale.assign(N, Real(0));
  out.cos_angle_rounding_scale.assign(N, Real(0));
  // Messages of particle j as node values: message[(q * n + a) * m_j + c], q = 0..3.
  std::vector<Real> message;
  {
    Real sums[node_sum_count];
    message = last_particle_messages(rules.angle[N - 1], rules.pivot[N - 1], forward[N - 1], sums);
    store_node_quantities(out, N - 1, sums);
  }
  for (std::size_t j = N - 1; j-- > 0;) {
    poll(2 * N - 1 - j);
    const PivotRule<Real>& pj = rules.pivot[j];
    const PivotRule<Real>& pn = rules.pivot[j + 1];
    const AngleRule<Real>& from = rules.angle[j];
    const AngleRule<Real>& to = rules.angle[j + 1];
    const std::size_t n = from.angle.size(), mj = pj.m;
    const Real ratio = mass[j + 1] / mass[j];
    const std::vector<Real> coef = message_coefficients(pn, message, n, np);
    std::vector<Real> current(4 * n * mj);
    Real sums[node_sum_count];
    if (rules.is_relative[j]) {
      relative_backward(from, to, pj, pn, rules.relative[j], ratio, coef, np, forward[j], current,
                        sums, team);
      kernel_evaluations += double(n) * double(mj) * double(rules.relative[j].delta.size());
    } else {
      kernel_evaluations +=
          product_backward(from, to, pj, pn, ratio, coef, np, forward[j], current, sums, team);
    }
    store_node_quantities(out, j, sums);
    normalize(current);  // all four messages by one power of two: they are linear in W
    message = std::move(current);
  }
  return out;
}

}  // namespace

template <class Real>
TransferLevel<Real> chain_transfer_level(const Chain<Real>& chain, const Real& beta,
                                              std::size_t angle_nodes, std::size_t pivot_nodes,
                                              int threads, const RunControl* control) {
  check_transfer_domain(chain, beta);
  if (angle_nodes < 4 || angle_nodes % 2 != 0) {
    throw invalid_input("chain_transfer: angle_nodes must be even and >= 4");
  }
  if (pivot_nodes < 3) throw invalid_input("chain_transfer: pivot_nodes must be >= 3");
  const std::size_t N = chain.size();
  const std::size_t n = angle_nodes;
  const std::size_t np = (n + lanes - 1) / lanes * lanes;  // n padded to whole vector blocks
  const int team = std::max(threads, 1);
  const LevelRules<Real> rules = level_rules(chain, beta, n, pivot_nodes);
  // Between links (outside every parallel region): progress over both sweeps, and a stop.
  const auto poll = [&](std::size_t links_done) {
    if (control == nullptr) return;
    if (control->stop_requested()) throw interrupted("transfer: stopped during a level");
    control->report(static_cast<double>(links_done) / static_cast<double>(2 * N));
  };
  double kernel_evaluations = 0;
  const std::vector<std::vector<Real>> forward =
      forward_sweep(chain, rules, team, poll, kernel_evaluations);
  TransferLevel<Real> out =
      backward_sweep(chain, rules, forward, np, team, poll, kernel_evaluations);
  out.kernel_evaluations = kernel_evaluations;
  return out;
}

namespace {

// ---------------------------------------------------------------- refinement and error estimate
//
// The levels (n_k, m_k) refine both resolutions together: n_k ~ 1.25^k (multiples of 8 from 16),
// and m_k is the smallest m whose predicted pivot error, rho^-m with rho the Chebyshev rate of
// the slowest pivot range (pivot_rate; a bound in every case measured), is a tenth of a target
// eps_k = pivot_lookahead D_{k-1} (D_{k-1}: the largest scaled difference of the last two
// levels, ~ the error of level k - 2, which two levels on has shrunk 1e3..1e5 times), plus
// pivot_offset nodes. So the pivot part of every level's error stays well below its angle part,
// m never stays put while n grows (which would hide the pivot error from the differences), and
// the last level's m is what its own accuracy needs: light-to-heavy chains converge slowly in
// n, and m tied to n would waste m^2.

/// The pivot targets of the first two levels, the factor from D_{k-1} to level k's target, and
/// the pivot nodes added as a margin.
constexpr double pivot_first_errors[2] = {1e-4, 1e-6};
constexpr double pivot_lookahead = 1e-5;
constexpr double pivot_offset = 2;
/// Each quantity's error is at least this fraction of the largest scaled difference of its
/// observable (beta<K_i>, Var K_i, <cos phi_i> separately) within local_window particles.
constexpr double floor_fraction = 0.01;
/// The local window of verified_error: the particles within N / local_window_fraction of the
/// quantity's own, at least local_window_min and at most local_window_max (O(N) work).
constexpr std::size_t local_window_min = 2;
constexpr std::size_t local_window_max = 64;
constexpr std::size_t local_window_fraction = 16;

/// The ladder of angle resolutions: about x1.25 per level, multiples of 8.
std::size_t next_angle_nodes(std::size_t n) { return std::max(n + 8, (n * 5 / 4 + 7) / 8 * 8); }

/// The predicted Chebyshev rate log rho of the slowest pivot range: interpolation in the pivot
/// coordinate v (PivotRule) over a range of half-width h_j (log(1 + S_j / m_{j-1}) / 2 for
/// log(u + eps_j); at most log(S_j / m_j) / 2 when saturating) with the singularities on
/// Im v = +-pi converges like rho_j^-m, rho_j = pi/h_j + sqrt(1 + (pi/h_j)^2) (Bernstein
/// ellipse). 0 for N = 1 (no pivots).
template <class Real>
double pivot_rate(const Chain<Real>& chain) {
  double rate = 0;
  for (std::size_t j = 1; j < chain.size(); ++j) {
    const double u_max = static_cast<double>(chain.mass(j) / chain.mass(j - 1));
    const double eps =
        pivot_offset_eps(static_cast<double>(chain.mass(j) / chain.tail_mass(j)), u_max);
    double lo, hi;
    pivot_coordinate_range(eps, u_max, lo, hi);
    const double h = (hi - lo) / 2;
    const double x = 3.14159265358979323846 / h;
    const double r = std::log(x + std::sqrt(1 + x * x));
    rate = j == 1 ? r : std::min(rate, r);
  }
  return rate;
}

/// The quantities of one level in one array: beta<K_i>, beta^2 Var K_i, <cos phi_i>; their
/// scales (beta<K_i>; beta^2 <K_i^2>; 1) and their rounding budgets (rounding_ulps roundoffs
/// times the sums of |terms| they are made of).
template <class Real>
void flatten(const TransferLevel<Real>& level, std::vector<Real>& value,
             std::vector<Real>& scale, std::vector<Real>& noise) {
  using std::abs;
  const std::size_t N = level.beta_kinetic.size();
  const Real ulps = Real(rounding_ulps) * std::numeric_limits<Real>::epsilon();
  value.resize(3 * N);
  scale.resize(3 * N);
  noise.resize(3 * N);
  for (std::size_t i = 0; i < N; ++i) {
    value[i] = level.beta_kinetic[i];
    value[N + i] = level.beta2_kinetic_variance[i];
    value[2 * N + i] = level.cos_angle[i];
    scale[i] = abs(level.beta_kinetic[i]);
    scale[N + i] = abs(level.beta2_kinetic_second_moment[i]);
    scale[2 * N + i] = 1;
    noise[i] = ulps * std::max(scale[i], level.beta_kinetic_rounding_scale[i]);
    // The variance pairs second u-derivatives of messages that themselves cancel (M3): four
    // times the budget (measured against long double: light particles, masses 1e-3..1e2).
    noise[N + i] =
        4 * ulps * std::max(scale[N + i], level.beta2_kinetic_variance_rounding_scale[i]);
    noise[2 * N + i] = ulps * std::max(abs(value[2 * N + i]), level.cos_angle_rounding_scale[i]);
  }
}

/// The error of level L - 1 verified by level L (values[L], values[L-1], ...). The difference
/// d = |v_L - v_{L-1}| bounds the error of v_{L-1} up to the (smaller) error of v_L: with a
/// geometric contraction rho per level, err(v_{L-1}) <= d / (1 - rho). rho is measured as the last
/// ratio D_L / D_{L-1} of the largest scaled differences, over every quantity and over the
/// quantity's observable within the local window of its particle (near the root, where
/// S_j / m_{j-1} is large, the pivot part may contract more slowly than the angle part at the free
/// end; where an angle rule switches from the window to the periodic trapezoid a few particles
/// converge unevenly); the larger of the two counts, and the factor 1 / (1 - rho) is taken in
/// [2, 10]. `contracting` is set when rho is measured (three levels at least) and <= 1/2: only
/// then may the caller stop. Each quantity uses max(d, floor_fraction D^loc scale), D^loc the
/// largest scaled difference of its observable within the window, so that an accidentally small
/// difference (a sign change of its error) does not hide its error. The rounding budget of v_L is
/// taken off d first and not included (the caller adds v_{L-1}'s). Reporting the verified level
/// rather than extrapolating the last one costs one level (about the work of all before it) and
/// keeps the estimate honest when a slow component surfaces late (an extrapolated ladder credited
/// contractions that component never showed, and missed by up to 48x).
template <class Real>
std::vector<Real> verified_error(const std::vector<std::vector<Real>>& values,
                                 const std::vector<Real>& scale, const std::vector<Real>& noise,
                                 bool& contracting) {
  using std::abs;
  constexpr double max_contraction = 0.5, largest_factor = 10, smallest_factor = 2;
  const std::size_t L = values.size() - 1, count = scale.size(), N = count / 3;
  std::vector<Real> error(count, std::numeric_limits<Real>::infinity());
  contracting = false;
  if (L == 0) return error;
  const auto ratio = [](const Real& a, const Real& b) { return b > 0 ? Real(a / b) : Real(1); };
  const std::size_t window = std::clamp<std::size_t>(
      (N + local_window_fraction - 1) / local_window_fraction, local_window_min, local_window_max);
  // scaled[back * count + q]: |v_k - v_{k-1}| / scale of quantity q, k = L - back, with the
  // rounding taken off; whole[back]: their largest over every quantity.
  const std::size_t steps = std::min<std::size_t>(L, 2);  // differences L and L-1 (if any)
  std::vector<Real> scaled(2 * count);
  Real whole[2] = {0, 0};
  for (std::size_t back = 0; back < steps; ++back) {
    const std::vector<Real>&now = values[L - back], &before = values[L - back - 1];
    for (std::size_t q = 0; q < count; ++q) {
      const Real d = abs(now[q] - before[q]) - 2 * noise[q];
      scaled[back * count + q] = std::max(Real(0), Real(d / scale[q]));
      whole[back] = std::max(whole[back], scaled[back * count + q]);
    }
  }
  // The contraction of the last step, D_L / D_{L-1} (1: not measured).
  const auto contraction = [&](const Real* D) { return L >= 2 ? ratio(D[0], D[1]) : Real(1); };
  const Real whole_rho = contraction(whole);
  contracting = L >= 2 && (whole_rho <= Real(max_contraction) || !(whole[0] > 0));
  for (std::size_t o = 0; o < 3; ++o) {  // beta<K_i>, Var K_i, <cos phi_i>
    for (std::size_t i = 0; i < N; ++i) {
      const std::size_t q = o * N + i;
      const std::size_t lo = o * N + (i > window ? i - window : 0);
      const std::size_t hi = o * N + std::min(N, i + window + 1);
      Real local[2] = {0, 0};  // the observable's largest near particle i
      for (std::size_t back = 0; back < steps; ++back) {
        for (std::size_t p = lo; p < hi; ++p) {
          local[back] = std::max(local[back], scaled[back * count + p]);
        }
      }
      const Real d = std::max(Real(0), Real(abs(values[L][q] - values[L - 1][q]) - noise[q]));
      const Real floor = Real(floor_fraction) * local[0] * scale[q];
      const Real rho = std::max(whole_rho, contraction(local));
      const Real factor =
          std::clamp(Real(1 / (1 - std::min(rho, Real(0.9)))), Real(smallest_factor),
                     Real(largest_factor));
      error[q] = factor * std::max(d, floor);
    }
  }
  return error;
}

/// Every error within the target, or within the quantity's rounding budget when that is
/// larger (a tolerance below the rounding of a quantity cannot be met by refinement).
template <class Real>
bool within(const std::vector<Real>& error, const std::vector<Real>& scale,
            const std::vector<Real>& noise, const Real& target) {
  for (std::size_t q = 0; q < error.size(); ++q) {
    if (!(error[q] <= std::max(Real(target * scale[q]), noise[q]))) return false;
  }
  return true;
}

}  // namespace

template <class Real>
std::size_t transfer_pivot_nodes(const Chain<Real>& chain, double expected_error) {
  if (chain.size() == 1) return 3;  // particle 1 has the single pivot u = 0 whatever m is
  const double m = std::ceil(std::log(10 / expected_error) / pivot_rate(chain) + pivot_offset);
  return std::max<std::size_t>(3, static_cast<std::size_t>(m));
}

namespace {

/// The options chain_transfer_average refuses (invalid_input), before any work.
void check_transfer_options(const TransferOptions& options) {
  if (!(options.tolerance > 0) || !(options.tolerance < 1)) {
    throw invalid_input("transfer: tolerance must lie in (0, 1)");
  }
  if (options.angle_nodes != 0 && (options.angle_nodes < 4 || options.angle_nodes % 2 != 0)) {
    throw invalid_input("transfer: angle_nodes must be 0 or even and >= 4");
  }
  if (options.pivot_nodes != 0 && options.pivot_nodes < 3) {
    throw invalid_input("transfer: pivot_nodes must be 0 or >= 3");
  }
  if (options.max_angle_nodes < 16 || options.max_pivot_nodes < 8) {
    throw invalid_input("transfer: max_angle_nodes >= 16 and max_pivot_nodes >= 8");
  }
}

/// The reported level's quantities (flatten's order: beta<K_i>, beta^2 Var K_i, <cos phi_i>)
/// as the averages, each error its verified difference plus the level's noise; converged only
/// when `converged` and every error is within the tolerance of its scale.
template <class Real>
Averages<Real> transfer_averages(const Chain<Real>& chain, const TransferDiagnostics<Real>& run,
                                 const std::vector<Real>& value, const std::vector<Real>& scale,
                                 const std::vector<Real>& noise, const std::vector<Real>& error,
                                 const Real& tol, bool converged, bool stopped) {
  const std::size_t N = chain.size();
  Averages<Real> out;
  out.method = Method::transfer;
  out.error_kind = ErrorKind::estimate;
  out.work_unit = WorkUnit::nodes;
  out.evaluations = static_cast<std::size_t>(run.kernel_evaluations);
  out.beta_kinetic.resize(N);
  out.beta2_kinetic_variance.resize(N);
  out.cos_angle.resize(N);
  out.converged = converged;
  out.interrupted = stopped;
  for (std::size_t i = 0; i < N; ++i) {
    const auto pack = [&](std::size_t q) {
      const Real e = error[q] + noise[q];
      if (!(e <= tol * scale[q])) out.converged = false;
      return Estimate<Real>{value[q], e, ErrorKind::estimate};
    };
    out.beta_kinetic[i] = pack(i);
    out.beta2_kinetic_variance[i] = pack(N + i);
    out.cos_angle[i] = pack(2 * N + i);
  }
  if (N >= 2) {
    out.ratio = kinetic_ratio(out.beta_kinetic[0], out.beta_kinetic[1],
                              Real(std::numeric_limits<Real>::epsilon()));
  }
  out.transfer = run;
  add_chain_extras(out, chain);
  return out;
}

}  // namespace

template <class Real>
Averages<Real> chain_transfer_average(const Chain<Real>& chain, const Real& beta,
                                      const TransferOptions& options) {
  check_beta(beta);
  check_transfer_options(options);
  const Real tol = Real(options.tolerance);
  // The pivot nodes of level k (see "refinement and error estimate" above), more than the
  // previous level's (so that the verification level's difference also sees the pivot error).
  // A level whose m is held at max_pivot_nodes may hide its pivot error from the differences:
  // the result is then not converged.
  std::size_t m = 0;
  bool pivots_capped = false;
  const auto next_pivots = [&](std::size_t level, const Real& last_difference) {
    if (options.pivot_nodes != 0) return options.pivot_nodes;
    const double expected =
        std::max(1e-16, level < 2 ? pivot_first_errors[level]
                                  : pivot_lookahead * static_cast<double>(last_difference));
    const std::size_t wanted = transfer_pivot_nodes(chain, expected);
    pivots_capped = wanted > options.max_pivot_nodes;
    return std::min(options.max_pivot_nodes, std::max(m + 1, wanted));
  };

  /// One finished level: its resolution and quantities (flatten).
  struct Rung {
    std::size_t angle_nodes = 0, pivot_nodes = 0;
    bool pivots_capped = false;
    std::vector<Real> value, scale, noise;
  };
  TransferDiagnostics<Real> run;
  std::vector<Rung> rungs;
  std::vector<std::vector<Real>> ladder;  // the rungs' values, for verified_error
  std::vector<Real> error;                // of the last rung but one, verified by the last
  bool contracting = false, stopped = false;
  std::size_t n = options.angle_nodes ? options.angle_nodes : 16;
  Real last_difference = 1;  // the largest scaled difference of the last two levels
  for (;;) {
    m = next_pivots(rungs.size(), last_difference);
    TransferLevel<Real> level;
    try {
      level = chain_transfer_level(chain, beta, n, m, options.threads, options.control);
    } catch (const interrupted&) {
      // Two finished levels carry a verified estimate: report the first of the last two.
      if (rungs.size() < 2) throw;
      stopped = true;
      break;
    }
    run.kernel_evaluations += level.kernel_evaluations;
    ++run.levels;
    Rung rung;
    rung.angle_nodes = n;
    rung.pivot_nodes = m;
    rung.pivots_capped = pivots_capped;
    flatten(level, rung.value, rung.scale, rung.noise);
    ladder.push_back(rung.value);
    rungs.push_back(std::move(rung));
    if (rungs.size() >= 2) {
      using std::abs;
      const Rung &last = rungs.back(), &reported = rungs[rungs.size() - 2];
      last_difference = 0;
      for (std::size_t q = 0; q < last.value.size(); ++q) {
        last_difference = std::max(last_difference,
                                   Real(abs(last.value[q] - reported.value[q]) / last.scale[q]));
      }
      error = verified_error(ladder, last.scale, last.noise, contracting);
      if (contracting && within(error, reported.scale, reported.noise, tol)) break;
    }
    // The caps stop refinement once a level is verified (the first verifies nothing). A
    // level's kernel evaluations grow like n^2 m; m grows by at most a half per level.
    if (rungs.size() >= 2 && next_angle_nodes(n) > options.max_angle_nodes) break;
    const double growth = static_cast<double>(next_angle_nodes(n)) / static_cast<double>(n);
    if (rungs.size() >= 2 &&
        run.kernel_evaluations + 1.5 * growth * growth * level.kernel_evaluations >
            options.max_kernel_evaluations)
      break;
    n = next_angle_nodes(n);
  }
  const Rung& reported = rungs[rungs.size() - 2];
  run.angle_nodes = reported.angle_nodes;
  run.pivot_nodes = reported.pivot_nodes;

  return transfer_averages(chain, run, reported.value, reported.scale, reported.noise, error, tol,
                           !rungs.back().pivots_capped && contracting && !stopped, stopped);
}

#define PENDAVG_INSTANTIATE_CHAIN_TRANSFER(Real)                                          \
  template TransferLevel<Real> chain_transfer_level<Real>(                                \
      const Chain<Real>&, const Real&, std::size_t, std::size_t, int, const RunControl*);  \
  template Averages<Real> chain_transfer_average<Real>(const Chain<Real>&, const Real&,    \
                                                       const TransferOptions&);            \
  template std::size_t transfer_pivot_nodes<Real>(const Chain<Real>&, double);           \
  template void check_transfer_domain<Real>(const Chain<Real>&, const Real&);
PENDAVG_INSTANTIATE_CHAIN_TRANSFER(double)
PENDAVG_INSTANTIATE_CHAIN_TRANSFER(long double)
#undef PENDAVG_INSTANTIATE_CHAIN_TRANSFER

}  // namespace pendavg
