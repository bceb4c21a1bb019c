// SPDX-License-Identifier: GPL-3.0-or-later
// tests/engine/double_pendulum/test_double_pendulum.cpp -- the N = 2 engines on their hard cases, by name, and the
// library's own cross-checks: exact Graf-moment sums against sinh-mapped quadrature, the
// beta -> 0 limit in Boost.Math (Carlson) against GSL's Legendre-form elliptic integrals, and
// validation of the model.
#include <catch2/catch.hpp>

#include "pendavg/chain.hpp"
#include "engine/double_pendulum/double_pendulum.hpp"
#include "engine/limits/limits.hpp"
#include "engine/numerics/precision.hpp"
#include "real_types.hpp"

#include <gsl/gsl_mode.h>
#include <gsl/gsl_sf_ellint.h>

#include <array>
#include <cmath>
#include <numbers>
#include <limits>
#include <iterator>
#include <map>
#include <string>
#include <vector>

using pendavg::Chain;
using pendavg::mpfr_real;

namespace {

Chain<double> chain2(double m1, double m2, double l1, double l2, double g = 1) {
  return Chain<double>({m1, m2}, {l1, l2}, g);
}

Chain<mpfr_real> chain2_mpfr(double m1, double m2, double l1, double l2, double g = 1) {
  return Chain<mpfr_real>({mpfr_real(m1), mpfr_real(m2)}, {mpfr_real(l1), mpfr_real(l2)},
                          mpfr_real(g));
}

template <class Real>
Chain<Real> chain2_real(double m1, double m2, double l1, double l2, double g = 1) {
  return Chain<Real>({Real(m1), Real(m2)}, {Real(l1), Real(l2)}, Real(g));
}

/// The reduced integral in Real (double at 16 digits, MPFR at test_digits) against the identical
/// (double-valued) problem at reference_digits: beta<K_i> to 9 units of the type's precision
/// relative (2e-15 in double) and inside the reported error.
template <class Real>
void check_against_reference(double m1, double m2, double l2, double beta) {
  using namespace pendavg::test;
  using std::isfinite;
  const TypePrecision<Real> precision;
  const int digits = pendavg::is_mpfr_v<Real> ? test_digits : 16;
  const auto r = pendavg::reduced_integral_average(chain2_real<Real>(m1, m2, 1, l2), Real(beta),
                                                   digits);
  std::array<mpfr_real, 2> reference;
  {
    const ReferencePrecision wide;
    const auto m = pendavg::reduced_integral_average(chain2_mpfr(m1, m2, 1, l2), mpfr_real(beta),
                                                     reference_digits);
    REQUIRE(m.converged);
    for (int i = 0; i < 2; ++i) reference[i] = m.beta_kinetic[i].value;
  }
  INFO("m1 = " << m1 << " m2 = " << m2 << " l2 = " << l2 << " beta = " << beta);
  REQUIRE(r.converged);
  for (int i = 0; i < 2; ++i) {
    INFO("beta<K" << i + 1 << "> = " << as_double(r.beta_kinetic[i].value) << " +- "
                  << as_double(r.beta_kinetic[i].error) << ", off by "
                  << relative_distance(r.beta_kinetic[i].value, reference[i]) / unit<Real>()
                  << " units relative");
    CHECK(relative_distance(r.beta_kinetic[i].value, reference[i]) <= 9 * unit<Real>());
    CHECK(distance(r.beta_kinetic[i].value, reference[i]) <= as_double(r.beta_kinetic[i].error));
    CHECK(isfinite(r.cos_angle[i].value));
    CHECK(isfinite(r.beta2_kinetic_variance[i].value));
  }
}

}  // namespace

// The hard cases in every number type the N = 2 engine is instantiated for (double, MPFR).
TEMPLATE_TEST_CASE("hard case mu1 -> 0: the integral stays exact and cheap", "[double_pendulum]",
                   double, mpfr_real) {
  for (double mu1 : {1e-6, 1e-9, 1e-12}) {
    for (double beta : {1e-3, 1.0, 30.0}) check_against_reference<TestType>(mu1, 1 - mu1, 1.0, beta);
  }
  // The limit value is approached: beta<K1> ~ (mu1/2) K/E -> 0 like mu1 log(1/mu1).
  const pendavg::test::TypePrecision<TestType> precision;
  const auto r = pendavg::reduced_integral_average(chain2_real<TestType>(1e-12, 1, 1, 1),
                                                   TestType(1e-6),
                                                   pendavg::is_mpfr_v<TestType>
                                                       ? pendavg::test::test_digits
                                                       : 16);
  CHECK(r.beta_kinetic[0].value > 0);
  CHECK(r.beta_kinetic[0].value < 1e-10);
}

TEMPLATE_TEST_CASE("hard case mu2 -> 0: a light lower bob", "[double_pendulum]", double, mpfr_real) {
  for (double beta : {1e-2, 1.0, 1e3, 1e6}) check_against_reference<TestType>(1.0, 1e-10, 1.0, beta);
}

TEMPLATE_TEST_CASE("hard case beta -> infinity: scaled Bessel functions, no overflow",
                   "[double_pendulum]", double, mpfr_real) {
  for (double beta : {1e3, 1e6, 1e8}) check_against_reference<TestType>(0.5, 0.5, 1.0, beta);
  if constexpr (pendavg::is_mpfr_v<TestType>) {
    // Far beyond double's exp range in MPFR: beta = 1e300 gives 1/2 - O(1/beta).
    pendavg::working_precision guard(30 + pendavg::guard_digits);
    const auto r = pendavg::reduced_integral_average(chain2_mpfr(0.5, 0.5, 1, 1), mpfr_real("1e300"), 30);
    CHECK(r.converged);
    CHECK(abs(r.beta_kinetic[0].value - mpfr_real(0.5)) < mpfr_real("1e-290"));
    CHECK(abs(r.beta_kinetic[1].value - mpfr_real(0.5)) < mpfr_real("1e-290"));
  }
}

TEMPLATE_TEST_CASE("hard case beta -> 0: the elliptic limit is reached without underflow",
                   "[double_pendulum]", double, mpfr_real) {
  // Against the closed form (mu1/2) K(k)/E(k) at reference_digits (limits.hpp, an independent
  // method): the finite-beta corrections are O(beta), below the type's precision here.
  using Real = TestType;
  using namespace pendavg::test;
  using std::isfinite;
  mpfr_real limit;
  {
    const ReferencePrecision wide;
    limit = pendavg::elliptic_high_temperature_limit(chain2_mpfr(0.5, 0.5, 1, 1), reference_digits)
                .beta_kinetic[0]
                .value;
  }
  const TypePrecision<Real> precision;
  const std::vector<const char*> betas = pendavg::is_mpfr_v<Real>
                                             ? std::vector<const char*>{"1e-30", "1e-300", "1e-3000"}
                                             : std::vector<const char*>{"1e-8", "1e-100", "1e-300"};
  for (const char* text : betas) {
    Real beta;
    if constexpr (pendavg::is_mpfr_v<Real>) {
      beta = Real(text);
    } else {
      beta = std::stod(text);
    }
    const auto r = pendavg::reduced_integral_average(chain2_real<Real>(0.5, 0.5, 1, 1), beta,
                                                     pendavg::is_mpfr_v<Real> ? test_digits : 16);
    INFO("beta = " << text);
    CHECK(relative_distance(r.beta_kinetic[0].value, limit) <= 45 * unit<Real>());
    CHECK(isfinite(r.cos_angle[0].value));
    // <cos phi1> ~ a1/2, a1 = beta M g l1
    CHECK(relative_distance(r.cos_angle[0].value, mpfr_real(beta) / 2) <= 1e-6);
  }
}

TEMPLATE_TEST_CASE("hard case extreme length ratios", "[double_pendulum]", double, mpfr_real) {
  for (double l2 : {1e-4, 1e4}) {
    for (double beta : {1e-2, 1.0, 1e2, 1e5}) check_against_reference<TestType>(0.3, 0.7, l2, beta);
  }
}

namespace {

struct SeriesCase {
  const char* name;
  double m1, m2, l2, beta;
};
const SeriesCase series_cases[] = {{"moderate", 0.5, 0.5, 1.0, 1.0},
                                   {"mu2 -> 0", 1.0, 1e-10, 1.0, 1.0},
                                   {"beta -> 0", 0.3, 0.7, 1.0, 1e-3},
                                   {"large beta", 0.5, 0.5, 1.0, 30.0},
                                   {"short lower link", 0.3, 0.7, 1e-4, 1.0},
                                   {"long lower link", 0.3, 0.7, 1e4, 1.0}};

/// beta<K_i> of the reduced integral at reference_digits, once per case.
const std::array<mpfr_real, 2>& integral_reference(const SeriesCase& c) {
  static std::map<std::string, std::array<mpfr_real, 2>> references;
  if (!references.count(c.name)) {
    const pendavg::test::ReferencePrecision wide;
    const auto m = pendavg::reduced_integral_average(chain2_mpfr(c.m1, c.m2, 1, c.l2),
                                                     mpfr_real(c.beta),
                                                     pendavg::test::reference_digits);
    REQUIRE(m.converged);
    references[c.name] = {m.beta_kinetic[0].value, m.beta_kinetic[1].value};
  }
  return references.at(c.name);
}

/// The series in Real (double at 16 digits, MPFR at test_digits) on `c`; max_terms = 0: until
/// the bound meets the digits.
template <class Real>
pendavg::Averages<Real> series_in(const SeriesCase& c, std::size_t max_terms = 0) {
  return pendavg::series_average(chain2_real<Real>(c.m1, c.m2, 1, c.l2), Real(c.beta),
                                 pendavg::is_mpfr_v<Real> ? pendavg::test::test_digits : 16,
                                 max_terms);
}

/// Counts the quantities of the series in Real whose certified bound covers the distance from the
/// 40-digit integral (two per case).
template <class Real>
int covered_by_series_bound(std::size_t max_terms = 0) {
  using namespace pendavg::test;
  int covered = 0;
  for (const SeriesCase& c : series_cases) {
    const auto& reference = integral_reference(c);
    const TypePrecision<Real> precision;
    const auto s = series_in<Real>(c, max_terms);
    for (int i = 0; i < 2; ++i) {
      const bool ok = distance(s.beta_kinetic[i].value, reference[i]) <=
                      as_double(s.beta_kinetic[i].error);
      if (!ok)
        WARN(c.name << ", particle " << i + 1 << ": off by "
                    << distance(s.beta_kinetic[i].value, reference[i]) << ", bound "
                    << as_double(s.beta_kinetic[i].error));
      covered += ok;
    }
  }
  return covered;
}

}  // namespace

// The paper's series (double, MPFR) on the hard cases against the reduced integral at 40 digits
// (mu1 -> 0 is beyond the series: hundreds of terms, tested by non-convergence below). Slow: the
// series in double takes seconds per case.
TEMPLATE_TEST_CASE("the series in double and MPFR on the hard cases against the 40-digit integral",
                   "[double_pendulum][.slow]", double, mpfr_real) {
  using Real = TestType;
  using namespace pendavg::test;
  for (const SeriesCase& c : series_cases) {
    const auto& reference = integral_reference(c);
    const TypePrecision<Real> precision;
    const auto s = series_in<Real>(c);
    INFO(c.name);
    REQUIRE(s.converged);
    for (int i = 0; i < 2; ++i) {
      INFO("particle " << i + 1 << ": " << as_double(s.beta_kinetic[i].value) << " +- "
                       << as_double(s.beta_kinetic[i].error) << ", off by "
                       << relative_distance(s.beta_kinetic[i].value, reference[i]) / unit<Real>()
                       << " units");
      CHECK(relative_distance(s.beta_kinetic[i].value, reference[i]) <= 9 * unit<Real>());
    }
  }
}

TEST_CASE("the series' certified bound covers the true error in double",
          "[double_pendulum][.slow]") {
  CHECK(covered_by_series_bound<double>() == 2 * static_cast<int>(std::size(series_cases)));
}

TEST_CASE("the series' certified bound covers the true error in MPFR", "[double_pendulum][mpfr]") {
  CHECK(covered_by_series_bound<mpfr_real>() == 2 * static_cast<int>(std::size(series_cases)));
}

// Given max_terms, the MPFR series sums past its digits (a truncation bound ~1e-33 at
// test_digits = 24), and its bound must also cover the rounding of the sums at their own
// precision (digits + a few guard digits), several times the truncation then. Slow: 400 MPFR
// terms per case.
TEST_CASE("the series' certified bound covers the true error in MPFR with max_terms given",
          "[double_pendulum][mpfr][.slow]") {
  CHECK(covered_by_series_bound<mpfr_real>(400) == 2 * static_cast<int>(std::size(series_cases)));
}

TEST_CASE("g = 0 is the beta -> 0 limit exactly, with <cos phi> = 0", "[double_pendulum]") {
  const auto r = pendavg::reduced_integral_average(chain2(0.2, 0.8, 1, 3, 0.0), 7.0, 16);
  const auto limit = pendavg::elliptic_high_temperature_limit(chain2(0.2, 0.8, 1, 3), 16);
  CHECK(r.beta_kinetic[0].value == Approx(limit.beta_kinetic[0].value).epsilon(1e-15));
  CHECK(r.cos_angle[0].value == 0.0);
  CHECK(r.cos_angle[0].error >= 0.0);
  CHECK(r.beta2_kinetic_variance[0].value == Approx(limit.beta2_kinetic_variance[0].value).epsilon(1e-14));
}

TEST_CASE("exact Graf-moment sums agree with sinh-mapped quadrature at 30 digits", "[double_pendulum]") {
  pendavg::working_precision guard(30 + pendavg::guard_digits);
  pendavg::IntegralOptions nodes;
  nodes.evaluation = pendavg::IntegralEvaluation::quadrature;
  struct P {
    double m1, m2, l2, beta;
  };
  for (const P& p : {P{0.5, 0.5, 1, 1}, P{0.05, 0.95, 2, 5}, P{1e-6, 1, 1, 3}, P{0.9, 0.1, 0.5, 0.2},
                     P{1e-10, 1, 0.3, 20}}) {
    const auto chain = chain2_mpfr(p.m1, p.m2, 1, p.l2);
    const auto exact = pendavg::reduced_integral_average(chain, mpfr_real(p.beta), 30);
    const auto quad = pendavg::reduced_integral_average(chain, mpfr_real(p.beta), 30, nodes);
    INFO("m1 = " << p.m1 << " l2 = " << p.l2 << " beta = " << p.beta << ", terms " << exact.evaluations
                 << ", nodes " << quad.evaluations);
    for (int i = 0; i < 2; ++i) {
      const mpfr_real tol = pow(mpfr_real(10), -29);
      CHECK(abs(exact.beta_kinetic[i].value - quad.beta_kinetic[i].value) <= tol * exact.beta_kinetic[i].value);
      CHECK(abs(exact.cos_angle[i].value - quad.cos_angle[i].value) <= tol * (abs(exact.cos_angle[i].value) + 1e-20));
      CHECK(abs(exact.beta2_kinetic_variance[i].value - quad.beta2_kinetic_variance[i].value) <=
            tol * exact.beta2_kinetic_variance[i].value);
    }
  }
}

TEST_CASE("beta -> 0 limit: Boost's Carlson forms agree with GSL's Legendre forms", "[double_pendulum]") {
  for (double mu1 : {0.5, 0.25, 0.05, 1e-3, 0.9}) {
    const auto r = pendavg::elliptic_high_temperature_limit(chain2(mu1, 1 - mu1, 1, 1), 16);
    const double mu2 = (1 - mu1) / (mu1 + (1 - mu1));
    const double k = std::sqrt(mu2);
    const double K = gsl_sf_ellint_Kcomp(k, GSL_PREC_DOUBLE);
    const double E = gsl_sf_ellint_Ecomp(k, GSL_PREC_DOUBLE);
    INFO("mu1 = " << mu1);
    // GSL takes k, which carries mu1 only to ~eps/mu1 relative: compare at that level.
    const double tol = 8e-16 + 4e-16 / mu1;
    CHECK(r.beta_kinetic[0].value == Approx(mu1 / 2 * K / E).epsilon(tol));
  }
}

TEST_CASE("the beta -> infinity limit is equipartition for both particles", "[double_pendulum]") {
  const auto r = pendavg::low_temperature_limit(chain2(0.1, 0.9, 2, 0.5));
  for (std::size_t i = 0; i < 2; ++i) {
    CHECK(r.beta_kinetic[i].value == 0.5);
    CHECK(r.beta_kinetic[i].error == 0);
    CHECK(r.cos_angle[i].value == 1.0);
    CHECK(r.beta2_kinetic_variance[i].value == 0.5);
    CHECK(r.beta2_kinetic_variance[i].error <= 16 * std::numeric_limits<double>::epsilon());
  }
  CHECK(r.error_kind == pendavg::ErrorKind::bound);
  // The integral approaches it: beta = 1e8 with mu1 = 0.5.
  const auto big = pendavg::reduced_integral_average(chain2(0.5, 0.5, 1, 1), 1e8, 16);
  CHECK(big.beta2_kinetic_variance[0].value == Approx(0.5).epsilon(1e-6));
  CHECK(big.beta2_kinetic_variance[1].value == Approx(0.5).epsilon(1e-6));
}

TEST_CASE("the model rejects invalid parameters with one-line messages", "[double_pendulum]") {
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const double inf = std::numeric_limits<double>::infinity();
  CHECK_THROWS_AS(Chain<double>({1, 0}, {1, 1}), pendavg::invalid_input);
  CHECK_THROWS_AS(Chain<double>({1, -1}, {1, 1}), pendavg::invalid_input);
  CHECK_THROWS_AS(Chain<double>({1, nan}, {1, 1}), pendavg::invalid_input);
  CHECK_THROWS_AS(Chain<double>({1, 1}, {1, inf}), pendavg::invalid_input);
  CHECK_THROWS_AS(Chain<double>({1, 1}, {1, 0}), pendavg::invalid_input);
  CHECK_THROWS_AS(Chain<double>({1, 1}, {1}), pendavg::invalid_input);
  CHECK_THROWS_AS(Chain<double>({}, {}), pendavg::invalid_input);
  CHECK_THROWS_AS(Chain<double>({1, 1}, {1, 1}, -1.0), pendavg::invalid_input);
  CHECK_THROWS_AS(Chain<double>({1, 1}, {1, 1}, nan), pendavg::invalid_input);
  const auto c = chain2(1, 1, 1, 1);
  CHECK_THROWS_AS(pendavg::reduced_integral_average(c, 0.0, 16), pendavg::invalid_input);
  CHECK_THROWS_AS(pendavg::reduced_integral_average(c, -1.0, 16), pendavg::invalid_input);
  CHECK_THROWS_AS(pendavg::reduced_integral_average(c, nan, 16), pendavg::invalid_input);
  CHECK_THROWS_AS(pendavg::reduced_integral_average(c, 1e300, 16), pendavg::invalid_input);
  CHECK_THROWS_AS(pendavg::reduced_integral_average(Chain<double>({1, 1, 1}, {1, 1, 1}), 1.0, 16),
                  pendavg::invalid_input);
  try {
    Chain<double>({1, -2}, {1, 1});
  } catch (const pendavg::invalid_input& e) {
    const std::string what = e.what();
    CHECK(what.find('\n') == std::string::npos);
    CHECK(what.find("mass 2") != std::string::npos);
  }
  pendavg::working_precision guard(30);
  CHECK_THROWS_AS(pendavg::reduced_integral_average(chain2_mpfr(1, 1, 1, 1), mpfr_real(1), 15),
                  pendavg::invalid_input);
  CHECK_THROWS_AS(pendavg::reduced_integral_average(chain2_mpfr(1, 1, 1, 1), mpfr_real(1), 1001),
                  pendavg::invalid_input);
}

TEST_CASE("the series stops at its certified bound and reports non-convergence honestly",
          "[double_pendulum]") {
  pendavg::working_precision guard(30 + pendavg::guard_digits);
  const auto chain = chain2_mpfr(0.5, 0.5, 1, 1);
  const auto certified = pendavg::series_average(chain, mpfr_real(1), 30);
  CHECK(certified.converged);
  CHECK(certified.beta_kinetic[0].error <= pow(mpfr_real(10), -30) * certified.beta_kinetic[0].value);
  // Capped at 10 terms: the value is still bracketed by the bound, and flagged.
  const auto capped = pendavg::series_average(chain, mpfr_real(1), 30, 10);
  CHECK_FALSE(capped.converged);
  CHECK(abs(capped.beta_kinetic[0].value - certified.beta_kinetic[0].value) <= capped.beta_kinetic[0].error);
}

TEST_CASE("cut ranges: half-angle sinh map, two panels and J_{-3/2} by parts agree with the exact sums",
          "[double_pendulum]") {
  // With a1 a2/(a1 + a2) large the quadrature cuts the range where the weight has decayed and
  // (Direct Bessel weights) maps sin(t/2) by a sinh at q's zero, integrates q^{-3/2} W by parts,
  // and, at high precision with mu1 tiny, splits [0, T] into two panels. The reference is the
  // exact finite sum of Graf coefficients times Fourier moments (no nodes, no map, q^{-3/2}'s
  // moments directly), forced for these parameters (Graf rows of 440-740 orders), whatever the
  // cost model would pick. Checked: every observable to the requested digits, and each error
  // estimate covers the difference.
  pendavg::IntegralOptions nodes, sums;
  nodes.evaluation = pendavg::IntegralEvaluation::quadrature;
  sums.evaluation = pendavg::IntegralEvaluation::graf_sums;
  struct P {
    double m1, m2, l2, beta;
  };
  for (int digits : {30, 50}) {
    pendavg::working_precision guard(digits + pendavg::guard_digits);
    const mpfr_real tol = pow(mpfr_real(10), -(digits - 1));
    // two panels (mu1 tiny), one sinh-mapped panel (mu1 = 1e-4), linear map (mu1 moderate),
    // unequal arms
    for (const P& p : {P{1e-9, 1, 1, 4000}, P{1e-12, 1, 1, 3000}, P{1e-4, 1, 1, 3000},
                       P{0.3, 0.7, 1, 4000}, P{2e-7, 1, 0.5, 5000}, P{0.02, 0.98, 3, 1500}}) {
      const auto chain = chain2_mpfr(p.m1, p.m2, 1, p.l2);
      const auto exact = pendavg::reduced_integral_average(chain, mpfr_real(p.beta), digits, sums);
      const auto quad = pendavg::reduced_integral_average(chain, mpfr_real(p.beta), digits, nodes);
      INFO("digits " << digits << ", m1 = " << p.m1 << " l2 = " << p.l2 << " beta = " << p.beta
                     << ", terms " << exact.evaluations << ", nodes " << quad.evaluations);
      REQUIRE(exact.converged);
      REQUIRE(quad.converged);
      auto check = [&](const mpfr_real& a, const mpfr_real& a_err, const mpfr_real& b,
                       const mpfr_real& b_err) {
        const mpfr_real diff = abs(a - b);
        CHECK(diff <= tol * abs(b));
        CHECK(diff <= a_err + b_err);
        CHECK(a_err <= tol * abs(b));
      };
      for (int i = 0; i < 2; ++i) {
        check(quad.beta_kinetic[i].value, quad.beta_kinetic[i].error, exact.beta_kinetic[i].value,
              exact.beta_kinetic[i].error);
        check(quad.cos_angle[i].value, quad.cos_angle[i].error, exact.cos_angle[i].value,
              exact.cos_angle[i].error);
        check(quad.beta2_kinetic_variance[i].value, quad.beta2_kinetic_variance[i].error,
              exact.beta2_kinetic_variance[i].value, exact.beta2_kinetic_variance[i].error);
      }
      if (digits != 30) continue;
      // The double engine on the same parameters (cut range, half-angle map, by parts; one
      // panel) against the exact sums: the accuracy split of the randomized double test.
      const auto d = pendavg::reduced_integral_average(chain2(p.m1, p.m2, 1, p.l2), p.beta, 16);
      REQUIRE(d.converged);
      auto check_double = [&](double v, double v_err, const mpfr_real& ref, bool kinetic) {
        const double r = static_cast<double>(ref);
        const double err = static_cast<double>(mpfr_real(abs(mpfr_real(v) - ref)));
        CHECK((kinetic ? err <= 2e-15 * std::abs(r) : (err <= 1e-13 * std::abs(r) || err <= 1e-15)));
        CHECK(err <= v_err);
      };
      for (int i = 0; i < 2; ++i) {
        check_double(d.beta_kinetic[i].value, d.beta_kinetic[i].error, exact.beta_kinetic[i].value, true);
        check_double(d.cos_angle[i].value, d.cos_angle[i].error, exact.cos_angle[i].value, false);
        check_double(d.beta2_kinetic_variance[i].value, d.beta2_kinetic_variance[i].error,
                     exact.beta2_kinetic_variance[i].value, false);
      }
    }
  }
}

// ---- product integration over the inner panel (engine/double_pendulum/inner_panel_series.hpp) --------------

#include "bench/cases.hpp"
#include "engine/numerics/bessel.hpp"
#include "engine/double_pendulum/inner_panel_series.hpp"

#include "engine/numerics/quadrature.hpp"

TEST_CASE("inner-panel series agrees with Clenshaw-Curtis quadrature and covers its error",
          "[double_pendulum][mpfr]") {
  // The nine slowest benchmark cases at 77 digits (tests/bench/cases.hpp), inner panel
  // t in [0, t1], t1 = 2 (a1 a2 / (a1 + a2))^{-1/2} as in reduced_integral_average; and five
  // where q's zero lies at or beyond the peak's width (700, 620, 354, 816, 116: the panel's
  // end moves out, detail::inner_panel_end, e = 0.45, series of ~90-135 terms).
  const auto cases = pendavg_bench::make_cases();
  for (const int digits : {30, 50, 80}) {
    const pendavg::precision_guard<mpfr_real> precision(digits + pendavg::guard_digits);
    const mpfr_real u = pendavg::unit_roundoff<mpfr_real>();
    for (const std::size_t i :
         {46u, 24u, 82u, 18u, 38u, 94u, 22u, 78u, 16u, 700u, 620u, 354u, 816u, 116u}) {
      const auto& c = cases[i];
      const mpfr_real M = mpfr_real(c.m1) + mpfr_real(c.m2);
      const mpfr_real mu1 = mpfr_real(c.m1) / M, mu2 = mpfr_real(c.m2) / M;
      const mpfr_real a1 = mpfr_real(c.beta) * M * c.g * c.l1;
      const mpfr_real a2 = mpfr_real(c.beta) * mpfr_real(c.m2) * c.g * c.l2;
      const mpfr_real A = a1 + a2, P = 4 * a1 * a2;
      const double h = static_cast<double>(a1 * a2 / A);
      const mpfr_real c2 = mu1 / mu2;
      const mpfr_real eps = sqrt(c2 / (2 * (1 + sqrt(1 + c2))));
      const mpfr_real s1 =
          pendavg::detail::inner_panel_end(mpfr_real(sin(mpfr_real(2.0 / std::sqrt(h)) / 2)), eps);
      const auto series = pendavg::detail::inner_panel_series(mu1, mu2, a1, a2, s1);
      REQUIRE(series.ok);
      // Reference: sin(t/2) = eps sinh(v) on [0, asinh(s1 / eps)], where q = 4 mu2 eps^2
      // cosh^2 v (1 + eps^2 - sin^2(t/2)) and dt = 2 eps cosh v dv / cos(t/2): analytic in v.
      const mpfr_real v1 = asinh(s1 / eps);
      auto integrands = [&](const mpfr_real& v) {
        const mpfr_real ch = cosh(v), sh = eps * sinh(v);
        const mpfr_real z = sh * sh;
        const mpfr_real dt = 2 * eps * ch / sqrt(1 - z);
        const mpfr_real sq = 2 * sqrt(mu2) * eps * ch * sqrt(1 + eps * eps - z);  // q^{1/2}
        const mpfr_real R = sqrt(A * A - P * z);
        const auto b = pendavg::scaled_bessel_i01(R);
        const mpfr_real ex = exp(-P * z / (R + A));
        const mpfr_real W = b.i0e * ex, g = b.i1e * ex / R;
        const mpfr_real cos_t = 1 - 2 * z, sin2_t = 4 * z * (1 - z);
        return std::array<mpfr_real, 5>{
            sq * W * dt, W / sq * dt,
            (sq * W + mu2 * sin2_t * cos_t / sq * (P / 4) * g) / mu1 * dt,
            sq * g * (a1 + a2 * cos_t) * dt, sq * g * (a2 + a1 * cos_t) * dt};
      };
      // Clenshaw-Curtis in v (the integrands are analytic there), levels until two agree.
      pendavg::ClenshawCurtisRule<mpfr_real> rule(8);
      std::array<mpfr_real, 5> previous{}, current{}, l1_sum{};
      std::array<mpfr_real, 5> err_level{};
      bool converged = false;
      for (std::size_t level = 0; level <= 9 && !converged; ++level) {
        rule.ensure_level(level);
        const auto& x = rule.nodes(level);
        const auto& wt = rule.weights(level);
        for (auto& s : current) s = 0;
        for (auto& s : l1_sum) s = 0;
        for (std::size_t j = 0; j < x.size(); ++j) {
          const auto F = integrands(x[j] * v1);
          for (std::size_t k = 0; k < 5; ++k) {
            current[k] += wt[j] * v1 * F[k];
            l1_sum[k] += abs(wt[j] * v1 * F[k]);
          }
        }
        converged = level >= 3;
        for (std::size_t k = 0; k < 5; ++k) {
          err_level[k] = abs(current[k] - previous[k]);
          if (!(err_level[k] <= pow(mpfr_real(10), -(digits + 8)) * abs(current[k]))) {
            converged = false;
          }
        }
        previous = current;
      }
      REQUIRE(converged);
      for (std::size_t k = 0; k < 5; ++k) {
        const mpfr_real ref = current[k], err = err_level[k], l1 = l1_sum[k];
        const mpfr_real diff = abs(series.value[k] - ref);
        INFO("case " << i << " digits " << digits << " integral " << k << " diff "
                     << static_cast<double>(diff / abs(ref)) << " reported "
                     << static_cast<double>(series.error[k] / abs(ref)));
        // Value: the requested tolerance 10^{-(digits + 2)} (what the engine asks for).
        CHECK(diff <= pow(mpfr_real(10), -(digits + 2)) * abs(ref));
        // Error estimate: covers the difference up to the reference's own rounding (l1 u 1e3),
        // and is tight (within the tolerance).
        CHECK(diff <= series.error[k] + 1000 * u * l1 + 100 * err);
        CHECK(series.error[k] <= pow(mpfr_real(10), -(digits + 2)) * abs(ref));
      }
    }
  }
}

TEST_CASE("averages through the inner-panel series: 30 and 50 digits against 80, errors cover",
          "[double_pendulum][mpfr]") {
  // The slow benchmark cases, which take the series path (inner panel) at every precision;
  // the last five with the panel's end moved out to q's zero (detail::inner_panel_end).
  const auto cases = pendavg_bench::make_cases();
  for (const std::size_t i :
       {46u, 24u, 82u, 18u, 38u, 94u, 22u, 78u, 16u, 700u, 620u, 354u, 816u, 116u}) {
    const auto& c = cases[i];
    auto run = [&](int digits) {
      const pendavg::precision_guard<mpfr_real> precision(100);
      const Chain<mpfr_real> chain({mpfr_real(c.m1), mpfr_real(c.m2)},
                                   {mpfr_real(c.l1), mpfr_real(c.l2)}, mpfr_real(c.g));
      return pendavg::reduced_integral_average(chain, mpfr_real(c.beta), digits);
    };
    const auto ref = run(80);
    REQUIRE(ref.converged);
    for (const int digits : {30, 50}) {
      const auto r = run(digits);
      REQUIRE(r.converged);
      const pendavg::precision_guard<mpfr_real> precision(100);
      for (std::size_t j = 0; j < 2; ++j) {
        INFO("case " << i << " digits " << digits << " component " << j);
        const mpfr_real diff = abs(r.beta_kinetic[j].value - ref.beta_kinetic[j].value);
        CHECK(diff <= r.beta_kinetic[j].error + ref.beta_kinetic[j].error);
        const mpfr_real tolerance = pow(mpfr_real(10), -digits);
        CHECK(r.beta_kinetic[j].error <= tolerance * (abs(r.beta_kinetic[j].value) + 1));
        CHECK(abs(r.cos_angle[j].value - ref.cos_angle[j].value) <=
              r.cos_angle[j].error + ref.cos_angle[j].error);
        CHECK(abs(r.beta2_kinetic_variance[j].value - ref.beta2_kinetic_variance[j].value) <=
              r.beta2_kinetic_variance[j].error + ref.beta2_kinetic_variance[j].error);
      }
    }
  }
}

// ---------------------------------------------------------------- the cost model (plan)

namespace {

template <class Real>
struct Planned {
  pendavg::IntegralPlan<Real> plan;
  pendavg::NodePlan<Real> nodes;
};

template <class Real>
Planned<Real> planned(double m1, double beta, double l2, int digits,
                      pendavg::IntegralEvaluation evaluation = pendavg::IntegralEvaluation::automatic) {
  const pendavg::Chain<Real> chain({Real(m1), Real(1 - m1)}, {Real(1), Real(l2)});
  const auto p = pendavg::double_pendulum_parameters(chain, Real(beta));
  const auto plan = pendavg::plan_reduced_integral(p, digits, evaluation);
  return {plan, pendavg::plan_nodes(p, plan)};
}

}  // namespace

TEST_CASE("N = 2 cost model: exact sums for moderate weights, nodes for sharp peaks", "[double_pendulum][plan]") {
  using Sums = pendavg::IntegralPlan<double>::Sums;
  // No peak (a1 a2/(a1 + a2) = 1/3): the sums in double, long double if rejected; short Graf rows.
  const auto flat = planned<double>(0.5, 1, 1, 16);
  CHECK(flat.plan.sums == Sums::double_then_long_double);
  CHECK(flat.plan.graf_nodes);
  CHECK(flat.nodes.fold);
  CHECK(flat.nodes.T == Approx(std::numbers::pi / 2));
  // q's zero very close to t = 0 (mu1 = 1e-7), a mild peak: long double sums, and (if they were
  // rejected) nodes clustered at t = 0 by the sinh map.
  const auto light = planned<double>(1e-7, 10, 1, 16);
  CHECK(light.plan.sums == Sums::long_double);
  CHECK(light.nodes.use_sinh);
  CHECK_FALSE(light.nodes.half_angle);
  CHECK(light.nodes.eps == Approx(std::asinh(std::sqrt(1e-7 / (1 - 1e-7)))));
  // A sharp peak (harmonic 3333): no sums; Bessel nodes on a range cut where the weight decayed.
  const auto sharp = planned<double>(0.5, 1e4, 1, 16);
  CHECK(sharp.plan.sums == Sums::none);
  CHECK_FALSE(sharp.plan.graf_nodes);
  CHECK_FALSE(sharp.nodes.fold);
  CHECK(sharp.nodes.T < 0.2);
  // Both: the sinh map on sin(t/2) over the cut range, and the 12 2^L levels for its span.
  const auto both = planned<double>(1e-6, 1e3, 1, 16);
  CHECK(both.nodes.half_angle);
  CHECK(both.nodes.sigma > 3.8);
  CHECK(both.nodes.sigma < 8.4);
  CHECK(both.nodes.base12);
  CHECK_FALSE(both.nodes.inner_series);  // panels are for MPFR only
  // The evaluation option forces either path.
  CHECK(planned<double>(0.5, 1, 1, 16, pendavg::IntegralEvaluation::quadrature).plan.sums == Sums::none);
  CHECK(planned<double>(0.5, 1e4, 1, 16, pendavg::IntegralEvaluation::graf_sums).plan.sums ==
        Sums::long_double);
  // Pure: the same input gives the same plan.
  const auto again = planned<double>(1e-6, 1e3, 1, 16);
  CHECK(again.plan.graf_terms == both.plan.graf_terms);
  CHECK(again.nodes.sigma == both.nodes.sigma);
}

TEST_CASE("N = 2 cost model in MPFR: sums while the Graf orders are cheap, panels for close zeros", "[double_pendulum][plan][mpfr]") {
  using Sums = pendavg::IntegralPlan<pendavg::mpfr_real>::Sums;
  {
    const pendavg::working_precision guard(38 + pendavg::guard_digits);
    CHECK(planned<pendavg::mpfr_real>(0.5, 1, 1, 38).plan.sums == Sums::working);
    const auto sharp = planned<pendavg::mpfr_real>(0.5, 1e6, 1, 38);
    CHECK(sharp.plan.sums == Sums::none);
    CHECK_FALSE(sharp.nodes.half_angle);
  }
  const pendavg::working_precision guard(77 + pendavg::guard_digits);
  // q's zero far inside the peak: product integration over [0, t1] first; with the longest
  // spans also two sinh-mapped panels as its fallback.
  const auto close = planned<pendavg::mpfr_real>(1e-7, 1e5, 1, 77);
  CHECK(close.plan.sums == Sums::none);
  CHECK(close.nodes.half_angle);
  CHECK(close.nodes.inner_series);
  CHECK_FALSE(close.nodes.two_panels);
  CHECK(close.nodes.t1 == Approx(2 / std::sqrt(close.plan.harmonic)));
  const auto closer = planned<pendavg::mpfr_real>(1e-8, 3e4, 1, 77);
  CHECK(closer.nodes.inner_series);
  CHECK(closer.nodes.two_panels);
  CHECK_FALSE(closer.nodes.base12);
}

TEST_CASE("MPFR sums at large beta: rows cut by the moments agree with the nodes and with more digits",
          "[double_pendulum][mpfr]") {
  // Where mu1 is not small the Fourier moments of q^s decay like r^k, r = (1 - sqrt mu1)/(1 +
  // sqrt mu1), long before the Graf coefficients at large beta (~sqrt(a1 a2 / (a1 + a2)) rows):
  // the exact sums stop there (moment_sum_terms; e.g. 134 -> 64 rows for mu1 = 0.5, beta = 1000
  // at 38 digits). Against an independent evaluation (the nodes) at the same digits and the sums
  // at 40 more digits: every observable within the reported errors, each below 10^-digits.
  struct Case {
    double m1, beta;
  };
  for (const Case c : {Case{0.5, 1000}, Case{0.9, 3000}, Case{0.3, 1e4}, Case{0.999, 2000}}) {
    for (const int digits : {38, 77}) {
      auto run = [&](int d, pendavg::IntegralEvaluation evaluation) {
        const pendavg::precision_guard<mpfr_real> precision(140);
        const Chain<mpfr_real> chain({mpfr_real(c.m1), mpfr_real(1 - c.m1)},
                                     {mpfr_real(1), mpfr_real(1)}, mpfr_real(1));
        return pendavg::reduced_integral_average(chain, mpfr_real(c.beta), d,
                                                 pendavg::IntegralOptions{evaluation});
      };
      const auto sums = run(digits, pendavg::IntegralEvaluation::graf_sums);
      const auto nodes = run(digits, pendavg::IntegralEvaluation::quadrature);
      const auto ref = run(digits + 40, pendavg::IntegralEvaluation::graf_sums);
      REQUIRE(sums.converged);
      REQUIRE(nodes.converged);
      REQUIRE(ref.converged);
      const pendavg::precision_guard<mpfr_real> precision(140);
      const mpfr_real tolerance = pow(mpfr_real(10), -digits);
      for (std::size_t j = 0; j < 2; ++j) {
        INFO("m1 = " << c.m1 << " beta = " << c.beta << " digits " << digits << " component " << j);
        const std::array<const pendavg::Estimate<mpfr_real>*, 3> observables_sums = {
            &sums.beta_kinetic[j], &sums.cos_angle[j], &sums.beta2_kinetic_variance[j]};
        const std::array<const pendavg::Estimate<mpfr_real>*, 3> observables_nodes = {
            &nodes.beta_kinetic[j], &nodes.cos_angle[j], &nodes.beta2_kinetic_variance[j]};
        const std::array<const pendavg::Estimate<mpfr_real>*, 3> observables_ref = {
            &ref.beta_kinetic[j], &ref.cos_angle[j], &ref.beta2_kinetic_variance[j]};
        for (std::size_t o = 0; o < 3; ++o) {
          const auto& s = *observables_sums[o];
          const auto& n = *observables_nodes[o];
          const auto& e = *observables_ref[o];
          INFO("observable " << o);
          CHECK(abs(s.value - e.value) <= s.error + e.error);
          CHECK(abs(s.value - n.value) <= s.error + n.error);
          CHECK(abs(s.value - e.value) <= tolerance * abs(e.value));
        }
        CHECK(sums.beta_kinetic[j].error <= tolerance * abs(sums.beta_kinetic[j].value));
      }
    }
  }
}
