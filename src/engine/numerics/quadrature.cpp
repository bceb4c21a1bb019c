// SPDX-License-Identifier: GPL-3.0-or-later
// Nested Clenshaw-Curtis rules (Waldvogel's explicit cosine-sum weights, built per level).
#include "engine/numerics/quadrature.hpp"

#include "engine/numerics/constant_cache.hpp"
#include "engine/numerics/precision.hpp"

#include <boost/math/constants/constants.hpp>

#include <cmath>
#include <stdexcept>

namespace pendavg {

template <class Real>
ClenshawCurtisRule<Real>::ClenshawCurtisRule(std::size_t n0)
    : n0_(n0), digits_(is_mpfr_v<Real> ? current_digits10<Real>() : 0) {
  if (n0 < 2 || n0 % 2 != 0) throw std::invalid_argument("Clenshaw-Curtis: n0 must be even");
}

template <class Real>
void ClenshawCurtisRule<Real>::ensure_level(std::size_t level) const {
  using std::cos;
  if (level >= max_levels) throw std::length_error("Clenshaw-Curtis: too many levels");
  if (level < ready_.load(std::memory_order_acquire)) return;
  const std::lock_guard lock(mutex_);
  const Real pi = boost::math::constants::pi<Real>();
  for (std::size_t L = ready_.load(std::memory_order_relaxed); L <= level; ++L) {
    const std::size_t n = n0_ << L;
    // cos(pi m / n), m = 0..2n-1, from the first quarter by symmetry.
    std::vector<Real> cosines(2 * n);
    for (std::size_t m = 0; m <= n / 2; ++m) cosines[m] = cos(pi * Real(m) / Real(n));
    for (std::size_t m = n / 2 + 1; m <= n; ++m) cosines[m] = -cosines[n - m];
    for (std::size_t m = n + 1; m < 2 * n; ++m) cosines[m] = cosines[2 * n - m];
    auto built = std::make_unique<Level>();
    std::vector<Real>& x = built->nodes;
    std::vector<Real>& w = built->weights;
    x.resize(n + 1);
    w.resize(n + 1);
    for (std::size_t j = 0; j <= n; ++j) x[j] = (1 - cosines[j]) / 2;
    x.front() = 0;
    x.back() = 1;
    // On [-1, 1]: w_j = (c_j / n) [1 - sum_{k=1}^{n/2} b_k / (4k^2 - 1) cos(2 k j pi / n)],
    // c_0 = c_n = 1, c_j = 2 otherwise; b_{n/2} = 1, b_k = 2 otherwise. Halved for [0, 1].
    for (std::size_t j = 0; j <= n / 2; ++j) {
      Real s = 0;
      for (std::size_t k = 1; k <= n / 2; ++k) {
        const unsigned long b = (k == n / 2) ? 1 : 2;
        Real term = cosines[(2 * k * j) % (2 * n)];
        term *= b;
        term /= static_cast<unsigned long>(4 * k * k - 1);
        s += term;
      }
      const unsigned long c = (j == 0 || j == n) ? 1 : 2;
      w[j] = (1 - s) * c / (2 * n);
      w[n - j] = w[j];
    }
    level_[L] = std::move(built);
    ready_.store(L + 1, std::memory_order_release);
  }
}

template <class Real>
std::shared_ptr<const ClenshawCurtisRule<Real>> shared_clenshaw_curtis_rule(std::size_t n0) {
  static ConstantCache<ClenshawCurtisRule<Real>> cache;
  const unsigned precision = is_mpfr_v<Real> ? mpfr_real::thread_default_precision() : 0;
  return cache.get(n0, precision, n0);
}

template class ClenshawCurtisRule<double>;
template class ClenshawCurtisRule<mpfr_real>;
template std::shared_ptr<const ClenshawCurtisRule<double>> shared_clenshaw_curtis_rule<double>(
    std::size_t);
template std::shared_ptr<const ClenshawCurtisRule<mpfr_real>>
shared_clenshaw_curtis_rule<mpfr_real>(std::size_t);

}  // namespace pendavg
