// pendavg/quadrature.hpp -- nested Clenshaw-Curtis rules on [0, 1], generic over Real.
//
// What for: the 1-D reduced integral (and later the torus rules) need a rule whose levels
// nest, so that each refinement reuses every earlier node and the difference between two
// levels is a free error estimate (as in Boost's tanh_sinh and trapezoidal). Clenshaw-Curtis
// converges like Gauss-Legendre for functions with nearby complex singularities, which is
// our case after the sinh map (Trefethen, "Is Gauss quadrature better than Clenshaw-Curtis?").
// Level L has n = n0 2^L intervals and nodes x_j = (1 - cos(j pi / n)) / 2, j = 0..n; the
// nodes of level L are the even-indexed nodes of level L + 1.
//
// When not to use it: for periodic integrands over a full period the trapezoid rule is the
// better rule (MATH.md Sec. 6).
//
// Levels are built on first use (O(n^2) weights, Waldvogel's cosine sums) and kept in the
// rule object, which lives in a workspace: never global state.
#pragma once

#include <cstddef>
#include <vector>

namespace pendavg {

template <class Real>
class ClenshawCurtisRule {
 public:
  /// n0 intervals at level 0; n0 must be even and >= 2.
  explicit ClenshawCurtisRule(std::size_t n0 = 8);

  /// Makes levels 0..level available.
  void ensure_level(std::size_t level);
  std::size_t levels() const { return nodes_.size(); }
  std::size_t intervals(std::size_t level) const { return n0_ << level; }

  /// Nodes x_j (j = 0..n) and weights of the level-L rule on [0, 1].
  const std::vector<Real>& nodes(std::size_t level) const { return nodes_[level]; }
  const std::vector<Real>& weights(std::size_t level) const { return weights_[level]; }

  /// Decimal digits the rule was built at (mpfr); 0 for double.
  int digits() const { return digits_; }

 private:
  std::size_t n0_;
  int digits_;
  std::vector<std::vector<Real>> nodes_, weights_;
};

}  // namespace pendavg
