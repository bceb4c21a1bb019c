// SPDX-License-Identifier: GPL-3.0-or-later
// engine/torus/level_sums.hpp -- one refinement level of the torus quadrature: the reduced
// integrand at a node, the walk over the tensor grid (each mirror pair delta, -delta once), and
// the level's weighted sums and ratios.
//
// Equations (src/engine/torus/README.md, 'Reduced weight', 'Isserlis' and 'Mirror halving'):
//     per node:   w = node_weight * exp(log sqrt(det A) - log_hadamard - (S - R)) e^{-R} I0(R),
//                 S - R = sum_j alpha_j (1 - cos(theta_j - arg z)), 1 - cos x = sin^2 x/(1 + cos x)
//     sums:       Z = sum w,  T_i = sum w tr X_i,  M_i = sum w ((tr X_i)^2 + 2 tr X_i^2),
//                 C_i = sum w (I1/I0)(R) cos(theta_i - arg z)
//     ratios:     beta<K_i> = T_i / (2 Z),  beta^2 <K_i^2> = M_i / (4 Z),
//                 beta^2 Var K_i = M_i / (4 Z) - (beta<K_i>)^2,  <cos phi_i> = C_i / Z
#pragma once

#include "engine/numerics/bessel.hpp"
#include "engine/numerics/compensated_sum.hpp"
#include "engine/numerics/parallel.hpp"
#include "engine/torus/circle_rules.hpp"
#include "engine/torus/reduced_weight.hpp"
#include "pendavg/chain.hpp"
#include "pendavg/result.hpp"
#include "pendavg/trace_formula.hpp"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstddef>
#include <optional>
#include <type_traits>
#include <vector>

namespace pendavg::detail::torus {

using std::abs;
using std::exp;
using std::log;
using std::sqrt;

/// Weighted sums over the nodes of one level: the weight and, per particle, the weighted
/// tr X_i, (tr X_i)^2 + 2 tr X_i^2, I1/I0 cos(theta_i - arg z) and its absolute value.
template <class Real>
struct TorusSums {
  CompensatedSum<Real> weight;
  /// sum of w sum_j alpha_j |sin(theta_j - arg z)|: the weight's exponent S - R carries a
  /// rounding error of a few u times that lever at each node (see rounding_ulps).
  CompensatedSum<Real> exponent_lever;
  std::vector<CompensatedSum<Real>> trace, second_moment, cosine, cosine_abs;
  std::size_t evaluations = 0;
  explicit TorusSums(std::size_t n = 0)
      : trace(n), second_moment(n), cosine(n), cosine_abs(n) {}
  void merge(const TorusSums& other) {
    weight.add(other.weight.value());
    exponent_lever.add(other.exponent_lever.value());
    for (std::size_t i = 0; i < trace.size(); ++i) {
      trace[i].add(other.trace[i].value());
      second_moment[i].add(other.second_moment[i].value());
      cosine[i].add(other.cosine[i].value());
      cosine_abs[i].add(other.cosine_abs[i].value());
    }
    evaluations += other.evaluations;
  }
};

/// The reduced integrand at one node: the weight w(delta) (scaled as in the header comment),
/// the traces, and the angle factors. Holds every per-thread buffer.
template <class Real>
class ReducedIntegrand {
 public:
  ReducedIntegrand(const Chain<Real>& chain, const WeightConstants<Real>& constants)
      : chain_(chain), k_(constants), workspace_(chain.size()), unit_cos_(chain.size()),
        unit_sin_(chain.size()), cos_offset_(chain.size()) {}

  /// Evaluates the node with relative angles delta (cosines cd, sines sd; N - 1 each) and adds
  /// weight * multiplicity * (its contributions) to `sums`.
  void accumulate(const Real* /*delta: see cd, sd*/, const Real* cd, const Real* sd, const Real& node_weight,
                  TorusSums<Real>& sums) {
    const std::size_t n = chain_.size();
    // from sines and cosines: the rules form them accurately near pi (CircleRule::from_pi)
    const NodeTraces<Real>& traces = node_traces_sincos(chain_, sd, cd, workspace_);
    // Unit vectors e^{i theta_j} by rotation products, and z = sum_j alpha_j e^{i theta_j}.
    unit_cos_[0] = 1;
    unit_sin_[0] = 0;
    Real zx = k_.alpha[0], zy = 0;
    for (std::size_t j = 1; j < n; ++j) {
      unit_cos_[j] = unit_cos_[j - 1] * cd[j - 1] - unit_sin_[j - 1] * sd[j - 1];
      unit_sin_[j] = unit_sin_[j - 1] * cd[j - 1] + unit_cos_[j - 1] * sd[j - 1];
      zx += k_.alpha[j] * unit_cos_[j];
      zy += k_.alpha[j] * unit_sin_[j];
    }
    Real radius = 0, s_minus_r = k_.alpha_sum, lever = 0;
    if (k_.alpha_sum > 0) {
      const Real sx = zx / k_.alpha_sum, sy = zy / k_.alpha_sum;  // |.| <= 1: no overflow
      radius = k_.alpha_sum * sqrt(sx * sx + sy * sy);
    }
    if (radius > 0) {
      // cos/sin of theta_j - arg z, and S - R = sum_j alpha_j (1 - cos(theta_j - arg z)).
      const Real ux = zx / radius, uy = zy / radius;
      s_minus_r = 0;
      for (std::size_t j = 0; j < n; ++j) {
        const Real c = unit_cos_[j] * ux + unit_sin_[j] * uy;
        const Real s = unit_sin_[j] * ux - unit_cos_[j] * uy;
        cos_offset_[j] = c;
        s_minus_r += k_.alpha[j] * (c >= 0 ? Real(s * s / (1 + c)) : Real(1 - c));
        lever += k_.alpha[j] * abs(s);
      }
    } else {
      for (std::size_t j = 0; j < n; ++j) cos_offset_[j] = 0;
    }
    const ScaledBesselI01<Real> bessel = scaled_bessel_i01(radius);
    const Real w =
        node_weight * exp(traces.log_sqrt_det_A - k_.log_hadamard - s_minus_r) * bessel.i0e;
    const Real bessel_ratio_w = w * (bessel.i1e / bessel.i0e);
    sums.weight.add(w);
    sums.exponent_lever.add(w * lever);
    for (std::size_t i = 0; i < n; ++i) {
      const Real& t = traces.trace_X[i];
      sums.trace[i].add(w * t);
      sums.second_moment[i].add(w * (t * t + 2 * traces.trace_X_squared[i]));
      const Real cw = bessel_ratio_w * cos_offset_[i];
      sums.cosine[i].add(cw);
      sums.cosine_abs[i].add(abs(cw));
    }
    ++sums.evaluations;
  }

 private:
  const Chain<Real>& chain_;
  const WeightConstants<Real>& k_;
  TraceWorkspace<Real> workspace_;
  std::vector<Real> unit_cos_, unit_sin_, cos_offset_;
};

/// Walks the grid of one level below the outermost dimension, visiting each mirror orbit of the
/// nodes not inherited from the previous level once, with its multiplicity (1 or 2).
template <class Real>
class GridWalker {
 public:
  /// `control` (or null) is polled before each innermost row of nodes: a stop request abandons
  /// the walk (abandoned(); the level is then discarded), so that a level of seconds (N = 8)
  /// stops within milliseconds, not at the end of its outermost slice.
  GridWalker(const std::vector<CircleRule<Real>>& rules, std::size_t dims,
             ReducedIntegrand<Real>& integrand, const RunControl* control = nullptr)
      : rules_(rules), dims_(dims), integrand_(integrand), control_(control), delta_(dims),
        cd_(dims), sd_(dims), weight_(dims + 1) {}

  bool abandoned() const { return abandoned_; }

  /// Every node with outermost index k0 (dims >= 1), or the single node (dims = 0).
  void walk_outer(std::size_t k0, TorusSums<Real>& sums) {
    weight_[0] = 1;
    if (dims_ == 0) {
      integrand_.accumulate(nullptr, nullptr, nullptr, weight_[0], sums);
      return;
    }
    const int orbit = rules_[0].orbit[k0];
    if (orbit < 0) return;
    set(0, k0);
    walk(1, orbit == 0, rules_[0].inherited[k0] != 0, orbit == 0 ? 1 : 2, sums);
  }

 private:
  void set(std::size_t d, std::size_t k) {
    const CircleRule<Real>& rule = rules_[d];
    delta_[d] = rule.angle[k];
    cd_[d] = rule.cos_angle[k];
    sd_[d] = rule.sin_angle[k];
    weight_[d + 1] = weight_[d] * rule.weight[k];
  }

  void walk(std::size_t d, bool constrained, bool all_inherited, int multiplicity,
            TorusSums<Real>& sums) {
    if (d == dims_) {
      if (rules_[0].nested && all_inherited) return;  // counted at the previous level
      integrand_.accumulate(delta_.data(), cd_.data(), sd_.data(),
                            multiplicity == 1 ? weight_[d] : Real(2 * weight_[d]), sums);
      return;
    }
    if (d + 1 == dims_ && control_ != nullptr && control_->stop_requested()) abandoned_ = true;
    if (abandoned_) return;
    const CircleRule<Real>& rule = rules_[d];
    for (std::size_t k = 0; k < rule.n && !abandoned_; ++k) {
      int orbit = 1;
      if (constrained) {
        orbit = rule.orbit[k];
        if (orbit < 0) continue;
      }
      set(d, k);
      walk(d + 1, constrained && orbit == 0, all_inherited && rule.inherited[k] != 0,
           constrained && orbit == 1 ? 2 : multiplicity, sums);
    }
  }

  const std::vector<CircleRule<Real>>& rules_;  // one per dimension, same n and orbits
  std::size_t dims_;
  ReducedIntegrand<Real>& integrand_;
  const RunControl* control_;
  bool abandoned_ = false;
  std::vector<Real> delta_, cd_, sd_, weight_;
};

/// Sums of one level over every node (or, for a nested level, every node not on the previous
/// level). Deterministic: one partial sum per outermost index, combined in index order.
template <class Real>
TorusSums<Real> level_sums(const Chain<Real>& chain, const WeightConstants<Real>& constants,
                           const std::vector<CircleRule<Real>>& rules, std::size_t dims,
                           int threads, const RunControl* control, bool& stopped) {
  std::atomic<bool> stop_seen{false};
  std::size_t done = 0;
  const std::size_t n_particles = chain.size();
  const std::size_t outer = dims == 0 ? 1 : rules[0].n;
  std::vector<TorusSums<Real>> partial(outer, TorusSums<Real>(n_particles));
  ParallelErrors errors;  // an exception may not leave the parallel region
  int team = 1;
  if constexpr (std::is_floating_point_v<Real>) team = std::max(threads, 1);
#if defined(_OPENMP)
#pragma omp parallel num_threads(team) if (team > 1)
#endif
  {
    std::optional<ReducedIntegrand<Real>> integrand;
    std::optional<GridWalker<Real>> walker;
    TorusSums<Real> local(n_particles);  // per thread: no false sharing between tasks
    errors.capture([&] {
      integrand.emplace(chain, constants);
      walker.emplace(rules, dims, *integrand, control);
    });
#if defined(_OPENMP)
#pragma omp for schedule(dynamic, 1)
#endif
    for (std::ptrdiff_t k0 = 0; k0 < static_cast<std::ptrdiff_t>(outer); ++k0) {
      errors.capture([&] {
        if (!walker || stop_seen.load(std::memory_order_relaxed)) return;
        local = TorusSums<Real>(n_particles);
        walker->walk_outer(static_cast<std::size_t>(k0), local);
        if (walker->abandoned()) {  // a stop request inside the slice: the level is discarded
          stop_seen.store(true, std::memory_order_relaxed);
          return;
        }
        partial[static_cast<std::size_t>(k0)] = local;
        if (control != nullptr) {
#if defined(_OPENMP)
#pragma omp critical(pendavg_torus_progress)
#endif
          control->report(static_cast<double>(++done) / static_cast<double>(outer));
          if (control->stop_requested()) stop_seen.store(true, std::memory_order_relaxed);
        }
      });
    }
  }
  errors.rethrow();
  stopped = stop_seen.load();
  (void)team;
  TorusSums<Real> total(n_particles);
  for (const auto& p : partial) total.merge(p);
  return total;
}

/// The reported quantities of one level, and their scales for the stopping test.
template <class Real>
struct LevelValues {
  Real mean_weight;
  std::vector<Real> beta_kinetic, beta2_second_moment, variance, cosine, cosine_l1;
};

template <class Real>
LevelValues<Real> level_values(const TorusSums<Real>& s, const Real& normalization) {
  const std::size_t n = s.trace.size();
  LevelValues<Real> v;
  const Real w = s.weight.value();
  v.mean_weight = w / normalization;
  v.beta_kinetic.resize(n);
  v.beta2_second_moment.resize(n);
  v.variance.resize(n);
  v.cosine.resize(n);
  v.cosine_l1.resize(n);
  for (std::size_t i = 0; i < n; ++i) {
    v.beta_kinetic[i] = s.trace[i].value() / (2 * w);
    v.beta2_second_moment[i] = s.second_moment[i].value() / (4 * w);
    v.variance[i] = v.beta2_second_moment[i] - v.beta_kinetic[i] * v.beta_kinetic[i];
    v.cosine[i] = s.cosine[i].value() / w;
    v.cosine_l1[i] = s.cosine_abs[i].value() / w;
  }
  return v;
}

}  // namespace pendavg::detail::torus
