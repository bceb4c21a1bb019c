// engine/microcanonical.hpp -- the microcanonical engine's internals (shell integrals, nested
// tanh-sinh quadrature); see include/pendavg/microcanonical.hpp for what it computes.
#pragma once

#include "pendavg/microcanonical.hpp"
#include "engine/bessel.hpp"
#include "pendavg/chain.hpp"
#include "engine/precision.hpp"
#include "pendavg/result.hpp"
#include "engine/torus.hpp"
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
#include <memory>
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

using detail::torus::pi;

/// The psi integrals of one shell, divided by scale^p (see the header comment):
///   weight = F_p / W^p,  kinetic = F_{p+1} / W^{p+1},  cosine = G_p / W^p.
template <class Real>
struct ShellMoments {
  Real weight{0}, kinetic{0}, cosine{0};
};

/// F_p, F_{p+1}, G_p for one fixed p = twice_p / 2 >= -1/2 (header comment for the method).
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
  }

  const Real& p() const { return p_; }

  ShellMoments<Real> operator()(const Real& energy, const Real& rho, const Real& scale) const {
    using std::pow;
    ShellMoments<Real> out;
    const Real& e = energy;
    if (!(e + rho > 0)) return out;  // no psi accessible
    const Real two_pi = 2 * pi<Real>();
    if (!(rho > 0)) {  // rho = 0 < E: E - U = E for every psi
      const Real r = e / scale;
      out.weight = two_pi * pow(r, p_);
      out.kinetic = out.weight * r;
      return out;
    }
    if (e < rho) {  // the cap |psi + arg z| < arccos(-E/rho)
      const Real depth = e + rho;
      const Real m = depth / (2 * rho), mc = (rho - e) / (2 * rho), k = sqrt(m);
      Real jp, jp1;
      cap_integrals(m, mc, e / rho, k, jp, jp1);
      const Real r = depth / scale;
      const Real factor = 4 * k * pow(r, p_);
      out.weight = factor * jp;
      out.kinetic = factor * r * jp1;
      out.cosine = (scale * out.kinetic - e * out.weight) / rho;
      return out;
    }
    // the full circle
    const Real top = e + rho;
    const Real mp = 2 * rho / top, mcp = (e - rho) / top;
    Real lp, lp1;
    full_integrals(mcp, e / top, lp, lp1);
    const Real r = top / scale;
    out.weight = two_pi * pow(r, p_) * lp;
    out.kinetic = out.weight / lp * r * lp1;
    if (!(lp > 0)) out.kinetic = two_pi * pow(r, p_ + 1) * lp1;
    if (e >= 2 * rho) {
      out.cosine = pi<Real>() * p_ * pow(e / scale, p_) * (rho / e) * cosine_series(rho / e);
    } else {
      out.cosine = (scale * out.kinetic - e * out.weight) / rho;
    }
    (void)mp;
    return out;
  }

 private:
  /// J_p(m), J_{p+1}(m) on the cap; e = E / rho = 2m - 1, k = sqrt(m).
  void cap_integrals(const Real& m, const Real& mc, const Real& e, const Real& k, Real& jp,
                     Real& jp1) const {
    using std::asin;
    if (m < Real(0.5)) {
      const Real u = std::numeric_limits<Real>::epsilon() / 2;
      Real tp = 1, tp1 = 1, sp = 1, sp1 = 1;
      for (int n = 0; n < 10000; ++n) {
        const Real nh = Real(n) + Real(0.5);
        const Real common = nh * nh * m / Real(n + 1);
        tp *= common / (Real(n) + p_ + Real(1.5));
        tp1 *= common / (Real(n) + p_ + Real(2.5));
        sp += tp;
        sp1 += tp1;
        if (tp <= u * sp && tp1 <= u * sp1) break;
      }
      jp = half_beta_p_ * sp;
      jp1 = half_beta_p1_ * sp1;
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
    while (q < p_) {
      const Real q1 = q + 1;
      const Real next = ((2 * q1 + 1) * (e / 2) * upper + q1 * mc * lower) / ((q1 + 1) * m);
      lower = upper;
      upper = next;
      q = q1;
    }
    jp = lower;
    jp1 = upper;
  }

  /// L_p(m'), L_{p+1}(m') on the full circle; mcp = 1 - m', ratio = E / (E + rho) = 1 - m'/2.
  void full_integrals(const Real& mcp, const Real& ratio, Real& lp, Real& lp1) const {
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
    while (q < p_) {
      const Real q1 = q + 1;
      const Real tail = mcp > 0 ? Real(q1 * mcp * lower) : Real(0);
      const Real next = ((2 * q1 + 1) * ratio * upper - tail) / (q1 + 1);
      lower = upper;
      upper = next;
      q = q1;
    }
    lp = lower;
    lp1 = upper;
  }

  /// 2F1((1-p)/2, 1-p/2; 2; x^2) for x = rho/E <= 1/2.
  Real cosine_series(const Real& x) const {
    const Real u = std::numeric_limits<Real>::epsilon() / 2;
    const Real x2 = x * x, a = (1 - p_) / 2, b = 1 - p_ / 2;
    Real t = 1, s = 1;
    for (int n = 0; n < 10000; ++n) {
      t *= (a + Real(n)) * (b + Real(n)) * x2 / (Real(n + 2) * Real(n + 1));
      s += t;
      if (t == 0 || (Real(n) > p_ + 2 && abs(t) <= u * abs(s))) break;
    }
    return s;
  }

  int twice_p_;
  Real p_;
  bool even_;
  Real half_beta_p_, half_beta_p1_;
};

/// Unscaled F_p(E, rho), F_{p+1}(E, rho), G_p(E, rho) (scale 1): for tests and callers.
template <class Real>
ShellMoments<Real> shell_integrals(int twice_p, const Real& energy, const Real& rho) {
  return ShellIntegrals<Real>(twice_p)(energy, rho, Real(1));
}

// --------------------------------------------------------------------------- chain constants

/// What every rule needs: gamma_j, W = E + sum gamma_j, the Hadamard bound of sqrt(det A), the
/// shell integrals at p = N/2 - 1, and the constant (2 pi)^{N/2} / Gamma(N/2) of Omega.
template <class Real>
struct ShellSetup {
  std::size_t n = 0;
  Real energy{}, scale{}, gamma_sum{0}, log_hadamard{0};
  std::vector<Real> gamma;
  ShellIntegrals<Real> shell;
  Real log_momentum_sphere{};  ///< log((2 pi)^{N/2} / Gamma(N/2))

  ShellSetup(const Chain<Real>& chain, const Real& e)
      : n(chain.size()), energy(e), shell(static_cast<int>(chain.size()) - 2) {
    using std::lgamma;
    gamma.resize(n);
    for (std::size_t j = 0; j < n; ++j) {
      gamma[j] = chain.potential_coefficient(j);
      gamma_sum += gamma[j];
      log_hadamard += log(chain.length(j)) + log(chain.tail_mass(j)) / 2;
    }
    scale = energy + gamma_sum;
    const Real half_n = Real(static_cast<double>(n)) / 2;
    log_momentum_sphere = half_n * log(2 * pi<Real>()) - lgamma(half_n);
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

  /// The table up to level 12, built once per number type (thread-safe static).
  static const TanhSinhTable& shared() {
    static const TanhSinhTable table(12);
    return table;
  }

  explicit TanhSinhTable(int max_level) {
    using std::asinh;
    using std::cosh;
    using std::sinh;
    const Real u = std::numeric_limits<Real>::epsilon();
    const Real half_pi = pi<Real>() / 2;
    // beyond t_max the weights are below ~u^1.3: sinh t_max = 1.3 log(1/u) / pi
    const Real t_max = asinh(Real(1.3) * -log(u) / pi<Real>());
    levels.resize(static_cast<std::size_t>(max_level) + 1);
    for (int level = 0; level <= max_level; ++level) {
      const Real h = std::ldexp(Real(1), -level);
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

/// Quantities integrated over theta: [0] sqrt(det A)/Hadamard F_p/W^p; [1 + i] the same with
/// tr X_i F_{p+1}/W^{p+1}; [1 + N + i] with cos(theta_i - arg z) G_p/W^p. Then the same count of
/// integrated error estimates.
template <class Real>
class NestedShellIntegral {
 public:
  struct Shared {
    const Chain<Real>* chain;
    const ShellSetup<Real>* setup;
    const TanhSinhTable<Real>* table;
    Real tolerance;
    int max_level;
    std::vector<std::vector<Real>> targets;  ///< per level j: critical values of |v_j|
    std::vector<bool> light;                 ///< per level j: cut at delta_{j-1} = 0, pi
    std::vector<Real> tail_gamma;            ///< sum_{k >= j} gamma_k (0-based, n + 1 entries)
    /// Per level j and quantity c: an absolute error that is small enough whatever the piece's
    /// own size (tolerance x a rough global value / the measure of the outer angles). Without
    /// it, the vanishing fibres near a cut point would be refined to relative accuracy for
    /// nothing. Empty: relative accuracy only (the rough first pass).
    std::vector<std::vector<Real>> floor;
    bool force_stop = false;  ///< stop at max_level without counting it as a failure
  };

  NestedShellIntegral(const Shared& shared, int threads)
      : s_(shared), n_(shared.setup->n), q_(1 + 2 * n_), threads_(std::max(threads, 1)),
        ws_(n_), theta_(n_, Real(0)), ct_(n_, Real(1)), st_(n_, Real(0)), vx_(n_, Real(0)),
        vy_(n_, Real(0)), delta_(n_ > 1 ? n_ - 1 : 1), buffers_(n_ + 1) {
    vx_[0] = s_.setup->gamma[0];
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
    ++evaluations;
    const ShellSetup<Real>& k = *s_.setup;
    for (std::size_t i = 0; i + 1 < n_; ++i) delta_[i] = theta_[i + 1] - theta_[i];
    const Real zx = vx_[n_ - 1], zy = vy_[n_ - 1];
    const Real rho = sqrt(zx * zx + zy * zy);
    const ShellMoments<Real> m = k.shell(k.energy, rho, k.scale);
    for (std::size_t c = 0; c < 2 * q_; ++c) out[c] = 0;
    if (m.weight == 0 && m.kinetic == 0) return;
    const NodeTraces<Real>& t = node_traces_relative(*s_.chain, delta_.data(), ws_);
    const Real h = exp(t.log_sqrt_det_A - k.log_hadamard);
    out[0] = h * m.weight;
    const Real hk = h * m.kinetic, hc = rho > 0 ? Real(h * m.cosine / rho) : Real(0);
    for (std::size_t i = 0; i < n_; ++i) {
      out[1 + i] = hk * t.trace_X[i];
      // cos(theta_i - arg z) = (cos theta_i zx + sin theta_i zy) / rho
      out[1 + n_ + i] = hc * (ct_[i] * zx + st_[i] * zy);
    }
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
  }

  /// The integral over theta_j (given theta_0..theta_{j-1}) of the inner integral; adds to out.
  void integrate_level(std::size_t j, Real* out) {
    using std::acos;
    using std::atan2;
    using std::fmod;
    const Real two_pi = 2 * pi<Real>(), p = pi<Real>();
    const ShellSetup<Real>& k = *s_.setup;
    const Real g = k.gamma[j];
    const Real vx = vx_[j - 1], vy = vy_[j - 1];
    const Real v = sqrt(vx * vx + vy * vy);
    const Real arg_v = (j == 1) ? Real(0) : atan2(vy, vx);
    std::vector<Real> cuts;
    cuts.push_back(arg_v);
    cuts.push_back(arg_v + p);
    if (v > 0) {
      for (const Real& t : s_.targets[j]) {
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
    for (Real& c : cuts) {  // into [-pi, pi)
      c = fmod(c + p, two_pi);
      if (c < 0) c += two_pi;
      c -= p;
    }
    std::sort(cuts.begin(), cuts.end());
    std::vector<Real> ends;
    const Real merge = 64 * std::numeric_limits<Real>::epsilon();
    for (const Real& c : cuts) {
      if (j == 1 && (c < 0)) continue;  // symmetric: [0, pi] only
      if (ends.empty() || c - ends.back() > merge) ends.push_back(c);
    }
    if (j == 1) {
      if (ends.empty() || ends.front() > merge) ends.insert(ends.begin(), Real(0));
      if (p - ends.back() > merge) {
        ends.push_back(p);
      } else {
        ends.back() = p;
      }
    } else {
      const Real first = ends.front();
      if (first + two_pi - ends.back() > merge) {
        ends.push_back(first + two_pi);
      } else {
        ends.back() = first + two_pi;
      }
    }
    Real* piece = buffers_[j].data() + 4 * q_;  // 2q entries
    const Real multiplicity = (j == 1) ? Real(2) : Real(1);
    for (std::size_t a = 0; a + 1 < ends.size(); ++a) {
      const Real lo = ends[a], hi = ends[a + 1];
      if (!(hi - lo > merge)) continue;
      if (k.energy < 0) {  // a fibre entirely below |E| contributes nothing
        using std::cos;
        using std::sin;
        const Real mid = (lo + hi) / 2;
        const Real wx = vx + g * cos(mid), wy = vy + g * sin(mid);
        if (sqrt(wx * wx + wy * wy) + s_.tail_gamma[j + 1] <= -k.energy) continue;
      }
      integrate_piece(j, lo, hi, piece);
      for (std::size_t c = 0; c < 2 * q_; ++c) out[c] += multiplicity * piece[c];
    }
  }

  /// tanh-sinh on [lo, hi] over theta_j; writes 2q entries (values, then error estimates).
  void integrate_piece(std::size_t j, const Real& lo, const Real& hi, Real* result) {
    std::vector<Real>& buf = buffers_[j];
    Real* acc = buf.data();             // 2q: sum of weight * f over all nodes so far
    Real* previous = buf.data() + 2 * q_;  // q: previous level's values
    Real* difference = buf.data() + 3 * q_;  // q: previous level's differences
    for (std::size_t c = 0; c < 2 * q_; ++c) acc[c] = 0;
    const Real half = (hi - lo) / 2;
    const Real tolerance = s_.tolerance;
    bool converged = false;
    for (int level = 0; level <= s_.max_level; ++level) {
      const auto& nodes = s_.table->levels[static_cast<std::size_t>(level)];
      accumulate_nodes(j, lo, hi, half, nodes, acc);
      const Real h = std::ldexp(Real(1), -level);
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
          const Real scale = (c >= 1 && c <= n_) ? abs(result[c]) : abs(result[0]);
          const Real floor = s_.floor.empty() ? Real(0) : s_.floor[j][c];
          if (!(e <= tolerance * scale) && !(e <= floor)) done = false;
          previous[c] = e;  // reuse: holds the estimate until overwritten below
        }
        if (done || level == s_.max_level) {
          if (!done && !s_.force_stop) {
            ++unconverged_pieces;
          }
          for (std::size_t c = 0; c < q_; ++c) result[q_ + c] += previous[c];
          converged = done;
          break;
        }
      }
      for (std::size_t c = 0; c < q_; ++c) previous[c] = result[c];
    }
    (void)converged;
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
    }
  }
  std::vector<std::unique_ptr<NestedShellIntegral>>* workers = nullptr;

 private:
  const Shared& s_;
  std::size_t n_, q_;
  int threads_;
  TraceWorkspace<Real> ws_;
  std::vector<Real> theta_, ct_, st_, vx_, vy_, delta_;
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
#if defined(_OPENMP)
#pragma omp parallel for num_threads(threads_) schedule(dynamic, 1)
#endif
    for (std::ptrdiff_t i = 0; i < static_cast<std::ptrdiff_t>(count); ++i) {
#if defined(_OPENMP)
      const int id = omp_get_thread_num();
#else
      const int id = 0;
#endif
      NestedShellIntegral& worker = *team[static_cast<std::size_t>(id)];
      worker.copy_outer(*this, 1);
      worker.level_integrand(1, angle_of(nodes[static_cast<std::size_t>(i)]),
                             batch_.data() + static_cast<std::size_t>(i) * 2 * q_);
    }
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
