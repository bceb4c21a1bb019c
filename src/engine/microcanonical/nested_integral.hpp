// SPDX-License-Identifier: GPL-3.0-or-later
// engine/microcanonical/nested_integral.hpp -- the nested tanh-sinh integral over the relative
// angles of the microcanonical averages (rule `integral`).
//
// Equations (src/engine/microcanonical/README.md, 'Nested integral'): the shell integrals
// F_p, G_p (microcanonical/shell.hpp) vanish where E + rho < 0, so the angle theta_j of level j
// integrates between the critical values of |v_j|, v_j = sum_{k <= j} gamma_k e^{i theta_k},
// at which the allowed region opens or closes; each piece between two cuts is a tanh-sinh
// integral (numerics/tanh_sinh.hpp), whose nodes cluster at the square-root edges.
#pragma once

#include "engine/microcanonical/shell.hpp"
#include "engine/numerics/compensated_sum.hpp"
#include "engine/numerics/parallel.hpp"
#include "engine/numerics/precision.hpp"
#include "engine/numerics/tanh_sinh.hpp"
#include "pendavg/chain.hpp"
#include "pendavg/microcanonical.hpp"
#include "pendavg/result.hpp"
#include "pendavg/trace_formula.hpp"

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <memory>
#include <type_traits>
#include <vector>

#if defined(_OPENMP)
#include <omp.h>
#endif

namespace pendavg::detail::microcanonical {

using std::abs;
using std::exp;
using std::log;
using std::sqrt;

using detail::pi;

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

}  // namespace pendavg::detail::microcanonical
