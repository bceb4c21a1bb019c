// SPDX-License-Identifier: GPL-3.0-or-later
// engine/numerics/quadrature.hpp -- nested Clenshaw-Curtis rules on [0, 1], generic over Real.
//
// What for: the 1-D reduced integral needs a rule whose levels nest, so that each refinement
// reuses every earlier node and the difference between two levels is a free error estimate (as
// in Boost's tanh_sinh and trapezoidal). Clenshaw-Curtis converges like Gauss-Legendre for
// functions with nearby complex singularities, which is our case after the sinh map (Trefethen,
// "Is Gauss quadrature better than Clenshaw-Curtis?"). Level L has n = n0 2^L intervals and
// nodes x_j = (1 - cos(j pi / n)) / 2, j = 0..n; the nodes of level L are the even-indexed nodes
// of level L + 1.
//
// When not to use it: for periodic integrands over a full period the trapezoid rule is the
// better rule (src/engine/torus/README.md, 'Node maps').
//
// Levels are built on first use (O(n^2) weights, Waldvogel's cosine sums), once: a rule is a
// table of constants that any number of threads may read while one of them adds a level.
// shared_clenshaw_curtis_rule hands out one rule per (n0, precision) for the whole process.
#pragma once

#include <array>
#include <atomic>
#include <cstddef>
#include <memory>
#include <mutex>
#include <vector>

namespace pendavg {

template <class Real>
class ClenshawCurtisRule {
 public:
  /// Levels 0 .. max_levels - 1 can be built.
  static constexpr std::size_t max_levels = 16;

  /// n0 intervals at level 0; n0 must be even and >= 2. MPFR: built at the working precision.
  explicit ClenshawCurtisRule(std::size_t n0 = 8);

  /// Makes levels 0..level available (thread-safe).
  void ensure_level(std::size_t level) const;
  std::size_t levels() const { return ready_.load(std::memory_order_acquire); }
  std::size_t intervals(std::size_t level) const { return n0_ << level; }

  /// Nodes x_j (j = 0..n) and weights of the level-L rule on [0, 1] (built on first use).
  const std::vector<Real>& nodes(std::size_t level) const { return built(level).nodes; }
  const std::vector<Real>& weights(std::size_t level) const { return built(level).weights; }

  /// Decimal digits the rule was built at (mpfr); 0 for double.
  int digits() const { return digits_; }

 private:
  struct Level {
    std::vector<Real> nodes, weights;
  };
  const Level& built(std::size_t level) const {
    if (level >= ready_.load(std::memory_order_acquire)) ensure_level(level);
    return *level_[level];
  }

  std::size_t n0_;
  int digits_;
  mutable std::mutex mutex_;  // held while a level is added
  mutable std::array<std::unique_ptr<const Level>, max_levels> level_;
  mutable std::atomic<std::size_t> ready_{0};  // levels 0 .. ready_ - 1 are built
};

/// The process's rule with n0 intervals at level 0 at the working precision (double: one per n0;
/// MPFR: one per n0 and precision, the 32 most recently used precisions kept).
template <class Real>
std::shared_ptr<const ClenshawCurtisRule<Real>> shared_clenshaw_curtis_rule(std::size_t n0);

}  // namespace pendavg
