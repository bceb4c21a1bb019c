// SPDX-License-Identifier: GPL-3.0-or-later
// B_{2j} / (2j) per MPFR precision: see engine/numerics/bernoulli.hpp.
#include "engine/numerics/bernoulli.hpp"

#include "engine/numerics/constant_cache.hpp"
#include "engine/numerics/precision.hpp"

#include <cmath>

namespace pendavg {

namespace {

struct DigammaSeriesTable {
  std::vector<mpfr_real> c;

  DigammaSeriesTable() {
    const mpfr_prec_t bits = static_cast<mpfr_prec_t>(
        boost::multiprecision::detail::digits10_2_2(mpfr_real::thread_default_precision()));
    const double log_inverse_u = static_cast<double>(bits - 1) * 0.6931471805599453;
    // The largest argument-independent index needed: j <= pi x0 with x0 = 1.2 ln(1/u)/(2 pi) + 2.
    const auto count = static_cast<std::size_t>(0.6 * log_inverse_u + 3.2 * 3.14159) + 2;
    const mpfr_prec_t wide = bits + 64;
    mpfr_t factorial, two_pi_power, two_pi_squared, zeta, b;
    mpfr_inits2(wide, factorial, two_pi_power, two_pi_squared, zeta, b, static_cast<mpfr_ptr>(nullptr));
    mpfr_const_pi(two_pi_squared, MPFR_RNDN);
    mpfr_mul_ui(two_pi_squared, two_pi_squared, 2, MPFR_RNDN);
    mpfr_sqr(two_pi_squared, two_pi_squared, MPFR_RNDN);  // (2 pi)^2
    mpfr_set_ui(factorial, 1, MPFR_RNDN);
    mpfr_set_ui(two_pi_power, 1, MPFR_RNDN);
    c.assign(count + 1, mpfr_real(0));
    for (unsigned long j = 1; j <= count; ++j) {
      mpfr_mul_ui(factorial, factorial, (2 * j - 1) * (2 * j), MPFR_RNDN);  // (2j)!
      mpfr_mul(two_pi_power, two_pi_power, two_pi_squared, MPFR_RNDN);     // (2 pi)^{2j}
      mpfr_zeta_ui(zeta, 2 * j, MPFR_RNDN);
      mpfr_mul(b, factorial, zeta, MPFR_RNDN);
      mpfr_div(b, b, two_pi_power, MPFR_RNDN);
      mpfr_div_ui(b, b, j, MPFR_RNDN);  // 2 (2j)! zeta / (2 pi)^{2j} / (2j)
      if (j % 2 == 0) mpfr_neg(b, b, MPFR_RNDN);
      mpfr_set(c[j].backend().data(), b, MPFR_RNDN);  // rounded to the table's precision
    }
    mpfr_clears(factorial, two_pi_power, two_pi_squared, zeta, b, static_cast<mpfr_ptr>(nullptr));
  }
};

}  // namespace

std::shared_ptr<const std::vector<mpfr_real>> digamma_series_coefficients() {
  static ConstantCache<DigammaSeriesTable> cache;
  const auto table = cache.get(0, mpfr_real::thread_default_precision());
  return {table, &table->c};  // aliasing: keeps the table alive
}

}  // namespace pendavg
