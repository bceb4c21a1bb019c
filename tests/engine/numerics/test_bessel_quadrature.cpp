// SPDX-License-Identifier: GPL-3.0-or-later
// Building blocks: scaled Bessel functions (GSL vs the generic series/asymptotic code vs
// Boost.Math at high precision), Miller tables vs direct values, and the nested Clenshaw-Curtis
// rule on integrals known in closed form; in every number type each is instantiated for
// (Bessel: double, long double, MPFR; Clenshaw-Curtis: double, MPFR).
#include <catch2/catch.hpp>

#include "engine/numerics/bessel.hpp"
#include "engine/numerics/precision.hpp"
#include "engine/numerics/quadrature.hpp"
#include "real_types.hpp"

#include <boost/math/special_functions/bessel.hpp>
#include <gsl/gsl_sf_bessel.h>

#include <algorithm>
#include <map>
#include <cmath>
#include <type_traits>
#include <utility>

using pendavg::mpfr_real;

TEST_CASE("generic scaled Bessel I0, I1 agree with GSL in double", "[bessel]") {
  for (double x : {1e-3, 0.3, 1.0, 7.5, 25.0, 26.0, 27.0, 40.0, 700.0, 1e4, 1e8}) {
    gsl_sf_result g0, g1;
    gsl_sf_bessel_I0_scaled_e(x, &g0);
    gsl_sf_bessel_I1_scaled_e(x, &g1);
    const auto m = pendavg::scaled_bessel_i01_generic(x);  // series / Hankel
    INFO("x = " << x);
    CHECK(m.i0e == Approx(g0.val).epsilon(4e-15));
    CHECK(m.i1e == Approx(g1.val).epsilon(4e-15));
  }
}

TEST_CASE("small arguments: the double path avoids GSL's unscaled I1 below 2 sqrt(eps)",
          "[bessel]") {
  // e^{-x} I1(x) = (x/2)(1 - x + ...): GSL 2.7 returns x/2 here (relative error x).
  for (double x : {0.0, 1e-300, 1e-12, 1e-8, 2e-8}) {
    const auto p = pendavg::scaled_bessel_i01(x);
    const double i0e = boost::math::cyl_bessel_i(0, x) * std::exp(-x);
    const double i1e = boost::math::cyl_bessel_i(1, x) * std::exp(-x);
    INFO("x = " << x);
    CHECK(p.i0e == Approx(i0e).epsilon(2e-16));
    CHECK(p.i1e == Approx(i1e).epsilon(2e-16).margin(1e-320));
  }
}

TEST_CASE("generic scaled Bessel I0, I1 agree with Boost.Math at 60 digits", "[bessel]") {
  pendavg::working_precision guard(60);
  const mpfr_real tol = pow(mpfr_real(10), -57);
  for (const char* xs : {"0.001", "0.7", "3", "19.5", "44", "45", "80", "1000"}) {
    const mpfr_real x(xs);
    const auto m = pendavg::scaled_bessel_i01_generic(x);
    const mpfr_real e = exp(-x);
    const mpfr_real i0 = boost::math::cyl_bessel_i(0, x) * e;
    const mpfr_real i1 = boost::math::cyl_bessel_i(1, x) * e;
    INFO("x = " << xs);
    CHECK(abs(m.i0e / i0 - 1) < tol);
    CHECK(abs(m.i1e / i1 - 1) < tol);
  }
}

namespace {

/// e^{-x} I_m(x) by Boost.Math at 60 digits (an independent implementation), once per (m, x).
const mpfr_real& boost_scaled_bessel(int m, double x) {
  static std::map<std::pair<int, double>, mpfr_real> values;
  const auto key = std::make_pair(m, x);
  if (!values.count(key)) {
    pendavg::working_precision guard(60);
    values[key] = boost::math::cyl_bessel_i(m, mpfr_real(x)) * exp(-mpfr_real(x));
  }
  return values.at(key);
}

}  // namespace

// Generic over the number type (double, long double, MPFR at test_digits), against Boost.Math at
// 60 digits: both paths (series, Hankel) and the dispatching scaled_bessel_i01, from the tiny
// arguments where GSL's unscaled I1 loses its digits to x = 1000.
TEMPLATE_TEST_CASE("scaled Bessel I0, I1 in every number type agree with Boost.Math at 60 digits",
                   "[bessel]", double, long double, mpfr_real) {
  using Real = TestType;
  using pendavg::test::relative_distance;
  const pendavg::test::TypePrecision<Real> precision;
  const double tolerance = 18 * pendavg::test::unit<Real>();  // 4e-15 in double
  for (double x : {1e-300, 1e-12, 2e-8, 1e-3, 0.3, 1.0, 7.5, 19.5, 25.0, 26.0, 27.0, 40.0, 44.0,
                   45.0, 80.0, 700.0, 1000.0}) {
    const mpfr_real& i0 = boost_scaled_bessel(0, x);
    const mpfr_real& i1 = boost_scaled_bessel(1, x);
    const auto p = pendavg::scaled_bessel_i01(Real(x));
    const auto g = pendavg::scaled_bessel_i01_generic(Real(x));
    INFO("x = " << x << ": I0e, I1e off by " << relative_distance(p.i0e, i0) / pendavg::test::unit<Real>()
                << ", " << relative_distance(p.i1e, i1) / pendavg::test::unit<Real>()
                << " units (generic: " << relative_distance(g.i0e, i0) / pendavg::test::unit<Real>()
                << ", " << relative_distance(g.i1e, i1) / pendavg::test::unit<Real>() << ")");
    CHECK(relative_distance(p.i0e, i0) <= tolerance);
    CHECK(relative_distance(p.i1e, i1) <= tolerance);
    CHECK(relative_distance(g.i0e, i0) <= tolerance);
    CHECK(relative_distance(g.i1e, i1) <= tolerance);
  }
}

// Miller's backward recurrence in every type against Boost.Math at 60 digits: the ratios to
// entry 0 (the normalisation cancels) within the table's own bound at the working precision
// (scaled_bessel_table_error_ulps); each entry to 450 units of the type's precision (1e-13 in
// double; MPFR: of the requested digits, as the engines use the tables) and the reduced table
// f_k = e^{-a} I_k(a) / a^k to 4500 units (1e-12 in double).
TEMPLATE_TEST_CASE("Miller tables in every number type agree with Boost.Math at 60 digits",
                   "[bessel]", double, long double, mpfr_real) {
  using Real = TestType;
  using pendavg::test::relative_distance;
  const pendavg::test::TypePrecision<Real> precision;
  const double u = static_cast<double>(pendavg::unit_roundoff<Real>());
  const double unit = pendavg::test::unit<Real>();
  for (double a : {1e-6, 0.5, 3.0, 30.0, 300.0}) {
    const std::size_t count = 40;
    const auto t = pendavg::scaled_bessel_i_table(Real(a), count);
    const auto f = pendavg::reduced_bessel_table(Real(a), 30);
    const double bound0 = pendavg::scaled_bessel_table_error_ulps<Real>(a, count, 0);
    for (int m : {0, 1, 2, 5, 13}) {
      const double bound = pendavg::scaled_bessel_table_error_ulps<Real>(a, count, m) + bound0 + 2;
      const pendavg::working_precision guard(60);
      const mpfr_real ratio = boost_scaled_bessel(m, a) / boost_scaled_bessel(0, a);
      INFO("a = " << a << " m = " << m << ": off by "
                  << relative_distance(t[m], boost_scaled_bessel(m, a)) / u << " roundoffs, ratio by "
                  << relative_distance(mpfr_real(t[m]) / mpfr_real(t[0]), ratio) / u
                  << " (bound " << bound << ")");
      CHECK(relative_distance(t[m], boost_scaled_bessel(m, a)) <= 450 * unit);
      CHECK(relative_distance(mpfr_real(mpfr_real(t[m]) / mpfr_real(t[0])), ratio) <= bound * u);
    }
    for (int k : {0, 1, 4, 9}) {
      const pendavg::working_precision guard(60);
      INFO("a = " << a << " k = " << k << ": off by "
                  << relative_distance(f[k], mpfr_real(boost_scaled_bessel(k, a) / pow(mpfr_real(a), k))) / u
                  << " roundoffs");
      CHECK(relative_distance(f[k], mpfr_real(boost_scaled_bessel(k, a) / pow(mpfr_real(a), k))) <=
            4500 * unit);
    }
  }
  // a = 0: f_k = 1 / (2^k k!)
  const auto f0 = pendavg::reduced_bessel_table(Real(0), 6);
  CHECK(relative_distance(f0[3], mpfr_real(1) / 48) <= 4 * u);
}

namespace {
/// Level L's nodes contain level L - 1's (every other node): the levels nest.
template <class Real>
void check_nested(const pendavg::ClenshawCurtisRule<Real>& rule, std::size_t L) {
  if (L == 0) return;
  const auto& x = rule.nodes(L);
  for (std::size_t j = 0; j < rule.nodes(L - 1).size(); ++j)
    CHECK(pendavg::test::distance(rule.nodes(L - 1)[j], mpfr_real(x[2 * j])) <=
          0.45 * pendavg::test::unit<Real>());
}
/// sum_j w_j f(x_j) over level L of the rule (the integral of f over [0, 1]).
template <class Real, class F>
Real level_sum(const pendavg::ClenshawCurtisRule<Real>& rule, std::size_t L, F f) {
  const auto& x = rule.nodes(L);
  const auto& w = rule.weights(L);
  Real s = 0;
  for (std::size_t j = 0; j < x.size(); ++j) s += w[j] * f(x[j]);
  return s;
}
}  // namespace

// The rule is instantiated for double and MPFR: the exact integrals in both, to a few units of
// the type's precision (1e-15 in double), against the closed forms at reference_digits.
TEMPLATE_TEST_CASE("Clenshaw-Curtis levels integrate known integrals and nest", "[quadrature]",
                   double, mpfr_real) {
  using Real = TestType;
  using pendavg::test::relative_distance;
  const pendavg::test::TypePrecision<Real> precision;
  const double tolerance = 4.5 * pendavg::test::unit<Real>();
  mpfr_real e_minus_1;
  {
    const pendavg::test::ReferencePrecision wide;
    e_minus_1 = exp(mpfr_real(1)) - 1;
  }
  pendavg::ClenshawCurtisRule<Real> rule(8);
  rule.ensure_level(5);
  for (std::size_t L = 0; L <= 5; ++L) {
    INFO("level " << L);
    CHECK(relative_distance(level_sum(rule, L, [](const Real&) { return Real(1); }), mpfr_real(1)) <=
          tolerance);
    if (L >= 1) {
      using std::exp;
      CHECK(relative_distance(level_sum(rule, L, [](const Real& x) { return Real(exp(x)); }),
                              e_minus_1) <= tolerance);
    }
    check_nested(rule, L);
  }
  if constexpr (std::is_same_v<Real, double>) {
    // 1 / (1 + 25 x^2) on [0, 1] (Runge): converges geometrically.
    const double exact = std::atan(5.0) / 5.0;
    double err_prev = 1;
    for (std::size_t L = 1; L <= 5; ++L) {
      const double s = level_sum(rule, L, [](double x) { return 1 / (1 + 25 * x * x); });
      const double err = std::abs(s - exact);
      CHECK((err < 1e-15 || err < err_prev));
      err_prev = err;
    }
    CHECK(err_prev < 1e-14);
  }
}

TEST_CASE("double Hankel path (fixed-length Horner) agrees with independent references", "[bessel]") {
  // x >= 25: scaled_bessel_i01<double> sums Hankel's series by Horner's rule with a table of
  // coefficients and an x-dependent length. References: the term-by-term generic series in long
  // double (roundoff 5e-20) up to 1e12, and Boost.Math's cyl_bessel_i at 40 digits up to 3000.
  double worst = 0;
  for (double x = 25.0; x < 1e12; x *= 1.0173) {
    const auto d = pendavg::scaled_bessel_i01(x);
    const auto l = pendavg::scaled_bessel_i01_generic(static_cast<long double>(x));
    const double e0 = static_cast<double>(std::abs((d.i0e - l.i0e) / l.i0e));
    const double e1 = static_cast<double>(std::abs((d.i1e - l.i1e) / l.i1e));
    worst = std::max({worst, e0, e1});
  }
  CHECK(worst <= 4e-16);
  pendavg::working_precision guard(40);
  for (double x : {25.0, 25.5, 31.0, 49.9, 50.1, 77.0, 333.0, 2999.0}) {
    const auto d = pendavg::scaled_bessel_i01(x);
    const mpfr_real X(x);
    const mpfr_real e = exp(-X);
    const double i0 = static_cast<double>(mpfr_real(boost::math::cyl_bessel_i(0, X) * e));
    const double i1 = static_cast<double>(mpfr_real(boost::math::cyl_bessel_i(1, X) * e));
    INFO("x = " << x);
    CHECK(d.i0e == Approx(i0).epsilon(4e-16));
    CHECK(d.i1e == Approx(i1).epsilon(4e-16));
  }
}

TEST_CASE("MPFR Hankel path (cached coefficients) agrees with Boost.Math across precisions",
          "[bessel]") {
  // The coefficient cache is per precision: alternate precisions to check it is rebuilt.
  for (int digits : {60, 100, 60, 38}) {
    pendavg::working_precision guard(digits);
    const mpfr_real tol = 8 * pendavg::unit_roundoff<mpfr_real>();
    for (const char* xs : {"70", "150.25", "400", "1000", "2500"}) {
      const mpfr_real x(xs);
      const auto m = pendavg::scaled_bessel_i01(x);
      mpfr_real i0, i1;
      {
        pendavg::working_precision wide(digits + 20);
        const mpfr_real X(xs);
        const mpfr_real e = exp(-X);
        i0 = boost::math::cyl_bessel_i(0, X) * e;
        i1 = boost::math::cyl_bessel_i(1, X) * e;
      }
      INFO("digits = " << digits << ", x = " << xs);
      CHECK(abs(m.i0e / i0 - 1) < tol);
      CHECK(abs(m.i1e / i1 - 1) < tol);
    }
  }
}

TEST_CASE("MPFR Hankel series re-expanded over a range agrees with Boost.Math", "[bessel]") {
  // scaled_bessel_i01_range: the double pendulum's nodes at large beta, where R spans a narrow
  // range below A = a1 + a2. Independent reference: Boost.Math's cyl_bessel_i at 20 more
  // digits. Points across the range, both ends included, several precisions and widths.
  for (int digits : {50, 89, 140, 50}) {
    pendavg::working_precision guard(digits);
    const mpfr_real tol = 8 * pendavg::unit_roundoff<mpfr_real>();
    for (const auto& [lo, hi] : {std::pair<const char*, const char*>{"196920.5", "197119.25"},
                                 {"400", "2500"}, {"600", "600"}, {"3e7", "3.0001e7"}}) {
      const mpfr_real x_min(lo), x_max(hi);
      const auto range = pendavg::scaled_bessel_i01_range(x_min, x_max);
      REQUIRE(range.valid);
      for (int k = 0; k <= 4; ++k) {
        const mpfr_real x = x_min + (x_max - x_min) * k / 4;
        const mpfr_real y = 1 / x, dy = y - range.y0;
        mpfr_real s0 = 0, s1 = 0;
        for (std::size_t j = range.c0.size(); j-- > 0;) {
          s0 = s0 * dy + range.c0[j];
          s1 = s1 * dy + range.c1[j];
        }
        const mpfr_real pre = sqrt(y) * range.inv_sqrt_two_pi;
        mpfr_real i0, i1;
        {
          pendavg::working_precision wide(digits + 20);
          const mpfr_real X = mpfr_real(x_min) + (mpfr_real(x_max) - mpfr_real(x_min)) * k / 4;
          const mpfr_real e = exp(-X);
          i0 = boost::math::cyl_bessel_i(0, X) * e;
          i1 = boost::math::cyl_bessel_i(1, X) * e;
        }
        INFO("digits = " << digits << ", range [" << lo << ", " << hi << "], k = " << k);
        CHECK(abs(pre * s0 / i0 - 1) < tol);
        CHECK(abs(pre * s1 / i1 - 1) < tol);
      }
    }
    // Below the Hankel threshold the range expansion declines.
    CHECK_FALSE(pendavg::scaled_bessel_i01_range(mpfr_real(10), mpfr_real(20)).valid);
  }
}

TEMPLATE_TEST_CASE("Clenshaw-Curtis levels from n0 = 12 integrate exactly and nest",
                   "[quadrature]", double, mpfr_real) {
  // The second level family (12 2^L intervals) for sinh maps of moderate span. Exact for
  // polynomials of degree <= n: x^n integrates to 1/(n+1), to 45 units of the type's precision
  // (1e-14 in double).
  using Real = TestType;
  const pendavg::test::TypePrecision<Real> precision;
  pendavg::ClenshawCurtisRule<Real> rule(12);
  rule.ensure_level(4);
  for (std::size_t L = 0; L <= 4; ++L) {
    REQUIRE(rule.nodes(L).size() == (std::size_t{12} << L) + 1);
    const std::size_t n = rule.nodes(L).size() - 1;
    using std::pow;
    const Real s = level_sum(rule, L, [n](const Real& x) { return Real(pow(x, static_cast<int>(n))); });
    CHECK(pendavg::test::relative_distance(s, mpfr_real(1) / static_cast<double>(n + 1)) <=
          45 * pendavg::test::unit<Real>());
    check_nested(rule, L);
  }
}

TEST_CASE("MPFR Miller tables (classic form, large arguments) agree with Boost.Math at 80 digits",
          "[bessel]") {
  // scaled_bessel_i_table's MPFR Miller run (division-free) at 50 digits against Boost's
  // cyl_bessel_i at 80, within the table's own rounding bound (scaled_bessel_table_error_ulps,
  // relative to entry 0) plus a few roundings of the common normalisation.
  for (const double a : {1e-3, 0.5, 30.0, 500.0, 1000.0}) {
    const std::size_t count = 300;
    std::vector<mpfr_real> table;
    mpfr_real u;
    {
      pendavg::working_precision guard(50);
      table = pendavg::scaled_bessel_i_table(mpfr_real(a), count);
      u = pendavg::unit_roundoff<mpfr_real>();
    }
    pendavg::working_precision guard(80);
    const mpfr_real scale = exp(-mpfr_real(a));
    for (const std::size_t m : {0u, 1u, 2u, 17u, 60u, 150u, 299u}) {
      if (a < 1 && m > 60) continue;  // below 1e-300: Boost's policy would flush to zero
      const mpfr_real reference = boost::math::cyl_bessel_i(static_cast<int>(m), mpfr_real(a)) * scale;
      const double ulps = pendavg::scaled_bessel_table_error_ulps<mpfr_real>(a, count, m) + 16;
      INFO("a = " << a << " m = " << m);
      CHECK(abs(mpfr_real(table[m]) - reference) <= ulps * u * reference);
    }
  }
}
