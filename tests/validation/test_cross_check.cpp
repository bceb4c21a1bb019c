// SPDX-License-Identifier: GPL-3.0-or-later
// tests/validation/test_cross_check.cpp -- independent methods checked against each other.
//
//  * the test oracle itself: Gauss-Legendre nodes against GSL, the oracle's matrices against the
//    paper's closed forms, the 2-D definition against Graf's series, and its own refinement;
//  * the paper's series, the library's reduced 1-D integral and the brute-force 2-D definition of
//    eq. ave-Ki-linear-pi-trace-varphi (tests/oracle/definition_2d.hpp) at 30 digits and in double;
//  * double against MPFR over randomized parameters, hard cases included (the 2e-15 target);
//  * reported error estimates against true errors ("INCONS" in GSL's test_sf.c), and their
//    tightness at 20/30/50 digits against an 80-digit reference;
//  * the paper's limits (eq. aveK1-beta0) and inequality (eq. trace-ineq-ave);
//  * the series' R_n against Graf's addition theorem and its truncation bound against true errors.
//
// Tags: [cross] (default), [oracle] for oracle self-checks, [.slow] for the long variants.
#include <catch2/catch.hpp>

#include "oracle/definition_2d.hpp"
#include "oracle/graf_series.hpp"

#include "pendavg/chain.hpp"
#include "engine/double_pendulum/double_pendulum.hpp"
#include "engine/limits/limits.hpp"
#include "engine/numerics/precision.hpp"
#include "pendavg/result.hpp"

#include <boost/math/special_functions/ellint_1.hpp>
#include <boost/math/special_functions/ellint_2.hpp>
#include <gsl/gsl_errno.h>
#include <gsl/gsl_integration.h>

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <limits>
#include <random>
#include <sstream>
#include <string>
#include <vector>

namespace {

using pendavg::mpfr_real;
namespace oracle = pendavg::oracle;

// ------------------------------------------------------------------------------ parameter sets

/// One double pendulum at one beta, given in double. Every MPFR computation of a case converts
/// these very doubles (exactly), so double and MPFR solve the identical problem.
struct Case {
  std::string label;
  double m1, m2, l1, l2, g, beta;
};

std::string describe(const Case& c) {
  char buf[320];
  std::snprintf(buf, sizeof buf,
                "[%s] m1=%.17g m2=%.17g l1=%.17g l2=%.17g g=%.17g beta=%.17g (mu1=%.3g mu2=%.3g)",
                c.label.c_str(), c.m1, c.m2, c.l1, c.l2, c.g, c.beta, c.m1 / (c.m1 + c.m2),
                c.m2 / (c.m1 + c.m2));
  return buf;
}

pendavg::Chain<double> chain_of(const Case& c) {
  return pendavg::Chain<double>({c.m1, c.m2}, {c.l1, c.l2}, c.g);
}

/// Must be called under the working precision the MPFR values are meant to have.
pendavg::Chain<mpfr_real> chain_mpfr(const Case& c) { return chain_of(c).cast<mpfr_real>(); }

/// The named hard cases: each pushes one parameter to the end of its range.
std::vector<Case> named_hard_cases() {
  const double tiny = 1e-12;
  return {
      {"mu1 = 1e-12", tiny, 1.0 - tiny, 1, 1, 1, 1},
      {"mu2 = 1e-12", 1.0 - tiny, tiny, 1, 1, 1, 1},
      {"beta = 1e8", 0.5, 0.5, 1, 1, 1, 1e8},
      {"beta = 1e-8", 0.5, 0.5, 1, 1, 1, 1e-8},
      {"l2/l1 = 1e-4", 0.5, 0.5, 1, 1e-4, 1, 1},
      {"l2/l1 = 1e4", 0.5, 0.5, 1, 1e4, 1, 1},
      {"g = 0", 0.5, 0.5, 1, 1, 0, 1},
      {"mu1 = 1e-12, beta = 1e8", tiny, 1.0 - tiny, 1, 1, 1, 1e8},
      {"mu1 = 1e-12, beta = 1e-8", tiny, 1.0 - tiny, 1, 1, 1, 1e-8},
      {"mu2 = 1e-12, beta = 1e8", 1.0 - tiny, tiny, 1, 1, 1, 1e8},
      {"l2/l1 = 1e4, beta = 1e8", 0.5, 0.5, 1, 1e4, 1, 1e8},
      {"l2/l1 = 1e-4, beta = 1e8", 0.5, 0.5, 1, 1e-4, 1, 1e8},
      {"mu1 = 1e-12, l2/l1 = 1e-4, beta = 1e8", tiny, 1.0 - tiny, 1, 1e-4, 1, 1e8},
      {"mu1 = 0.05, beta = 100 (src/engine/README.md, 'Reduction')", 0.05, 0.95, 1, 1, 1, 100},
  };
}

/// Fixed-seed random cases: beta log-uniform in [1e-8, 1e8], the small mass fraction log-uniform
/// in [1e-12, 0.5] (alternately mu1 and, mirrored, mu2), l2/l1 log-uniform in [1e-4, 1e4],
/// g = 1, l1 = 1. Masses are m_small = mu, m_other = 1 - mu, so M = 1 up to one rounding.
std::vector<Case> random_cases(std::size_t count, std::uint64_t seed = 0x5eed2d0b1e5ULL) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  auto log_uniform = [&](double lo, double hi) {
    return std::exp(std::log(lo) + unit(rng) * (std::log(hi) - std::log(lo)));
  };
  std::vector<Case> out;
  out.reserve(count);
  for (std::size_t i = 0; i < count; ++i) {
    const double beta = log_uniform(1e-8, 1e8);
    const double mu = log_uniform(1e-12, 0.5);
    const double l2 = log_uniform(1e-4, 1e4);
    const bool mirrored = (i % 2) == 1;
    Case c{(mirrored ? "random, small mu2 #" : "random, small mu1 #") + std::to_string(i),
           mirrored ? 1.0 - mu : mu,
           mirrored ? mu : 1.0 - mu,
           1.0,
           l2,
           1.0,
           beta};
    out.push_back(c);
  }
  return out;
}

/// The named hard cases first, then 300 random ones.
const std::vector<Case>& all_cases() {
  static const std::vector<Case> cases = [] {
    std::vector<Case> v = named_hard_cases();
    const std::vector<Case> r = random_cases(300);
    v.insert(v.end(), r.begin(), r.end());
    return v;
  }();
  return cases;
}

// ------------------------------------------------------------------------------ quantities

enum class Kind { kinetic, cos_angle, variance };

const char* kind_name(Kind k) {
  switch (k) {
    case Kind::kinetic: return "beta*K";
    case Kind::cos_angle: return "cos phi";
    case Kind::variance: return "beta^2 Var K";
  }
  return "?";
}

constexpr Kind all_kinds[] = {Kind::kinetic, Kind::cos_angle, Kind::variance};

template <class Real>
const Real& value_of(const pendavg::Averages<Real>& a, Kind k, std::size_t i) {
  switch (k) {
    case Kind::kinetic: return a.beta_kinetic.at(i).value;
    case Kind::cos_angle: return a.cos_angle.at(i).value;
    case Kind::variance: return a.beta2_kinetic_variance.at(i).value;
  }
  return a.beta_kinetic.at(i).value;
}

template <class Real>
const Real& error_of(const pendavg::Averages<Real>& a, Kind k, std::size_t i) {
  switch (k) {
    case Kind::kinetic: return a.beta_kinetic.at(i).error;
    case Kind::cos_angle: return a.cos_angle.at(i).error;
    case Kind::variance: return a.beta2_kinetic_variance.at(i).error;
  }
  return a.beta_kinetic.at(i).error;
}

template <class Real>
const Real& oracle_value_of(const oracle::DefinitionAverages<Real>& a, Kind k, std::size_t i) {
  switch (k) {
    case Kind::kinetic: return a.beta_kinetic.at(i);
    case Kind::cos_angle: return a.cos_angle.at(i);
    case Kind::variance: return a.beta2_kinetic_variance.at(i);
  }
  return a.beta_kinetic.at(i);
}

double to_double(const mpfr_real& x) { return x.convert_to<double>(); }

template <class Real>
Real relative_difference(const Real& value, const Real& reference) {
  using std::abs;
  return abs(value - reference) / abs(reference);
}

std::string fmt(double x) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.6e", x);
  return buf;
}

std::string fmt_mp(const mpfr_real& x, int digits = 25) {
  std::ostringstream os;
  os.precision(digits);
  os << x;
  return os.str();
}

/// The oracle for one case at the current precision of Real: P = 8 panels, n from the
/// convergence estimate for `digits` + 2 digits, checked against 1.5 n.
template <class Real>
oracle::CheckedDefinitionAverages<Real> run_oracle(const Case& c, int digits) {
  const oracle::Pendulum2<Real> p{Real(c.m1), Real(c.m2), Real(c.l1), Real(c.l2), Real(c.g)};
  const double mu1 = c.m1 / (c.m1 + c.m2), mu2 = c.m2 / (c.m1 + c.m2);
  const double a1 = c.beta * (c.m1 + c.m2) * c.g * c.l1, a2 = c.beta * c.m2 * c.g * c.l2;
  const int panels = 8;
  const int n = oracle::definition_nodes_per_panel(mu1, mu2, std::max(a1, a2), panels, digits + 2);
  return oracle::definition_average_2d_checked<Real>(p, Real(c.beta), panels, n);
}

// ============================================================================== oracle self-checks

TEST_CASE("oracle Gauss-Legendre nodes match GSL's fixed tables", "[cross][oracle]") {
  // GSL ships correctly rounded tables for some n (table->precomputed); for the other n it runs
  // its own iteration, whose weights are good only to ~1e-10 relative (observed: 9e-11 at
  // n = 50, 4e-10 at n = 129), so those are compared at that level.
  std::size_t precomputed_seen = 0;
  for (int n : {1, 2, 3, 4, 5, 8, 11, 16, 17, 20, 32, 33, 50, 64, 100, 129}) {
    INFO("n = " << n);
    const oracle::GaussLegendreRule<double> rule = oracle::gauss_legendre<double>(n);
    gsl_integration_glfixed_table* table = gsl_integration_glfixed_table_alloc(static_cast<size_t>(n));
    REQUIRE(table != nullptr);
    const bool precomputed = table->precomputed != 0;
    std::vector<std::pair<double, double>> gsl_points;
    for (int i = 0; i < n; ++i) {
      double x = 0, w = 0;
      REQUIRE(gsl_integration_glfixed_point(-1.0, 1.0, static_cast<size_t>(i), &x, &w, table) == GSL_SUCCESS);
      gsl_points.emplace_back(x, w);
    }
    gsl_integration_glfixed_table_free(table);
    std::sort(gsl_points.begin(), gsl_points.end());
    REQUIRE(rule.nodes.size() == static_cast<std::size_t>(n));
    double worst_node = 0, worst_weight = 0;
    for (int i = 0; i < n; ++i) {
      const std::size_t k = static_cast<std::size_t>(i);
      worst_node = std::max(worst_node, std::abs(rule.nodes[k] - gsl_points[k].first));
      worst_weight = std::max(worst_weight, std::abs(rule.weights[k] - gsl_points[k].second) / gsl_points[k].second);
    }
    INFO("precomputed by GSL: " << precomputed << "; worst node difference " << fmt(worst_node)
                                << ", worst relative weight difference " << fmt(worst_weight));
    const double eps = std::numeric_limits<double>::epsilon();
    CHECK(worst_node <= 2 * eps);
    if (precomputed) {
      ++precomputed_seen;
      CHECK(worst_weight <= 4 * eps);
    } else {
      CHECK(worst_weight <= 1e-9);
    }
  }
  CHECK(precomputed_seen >= 8);
}

TEST_CASE("oracle Gauss-Legendre rule is exact to MPFR precision", "[cross][oracle]") {
  const pendavg::working_precision guard(60);
  const mpfr_real tol = pow(mpfr_real(10), -57);
  for (int n : {1, 2, 7, 24, 48}) {
    INFO("n = " << n);
    const oracle::GaussLegendreRule<mpfr_real> rule = oracle::gauss_legendre<mpfr_real>(n);
    // Exact for polynomials of degree <= 2n - 1: the even moments 2/(2k+1), k = 0..n-1.
    for (int k = 0; k < n; ++k) {
      mpfr_real sum = 0;
      for (std::size_t j = 0; j < rule.nodes.size(); ++j) sum += rule.weights[j] * pow(rule.nodes[j], 2 * k);
      const mpfr_real exact = mpfr_real(2) / mpfr_real(2 * k + 1);
      INFO("k = " << k << ", rule = " << fmt_mp(sum, 60));
      CHECK(abs(sum - exact) <= tol);
    }
    // and the first degree it is not exact for really differs (the rule is the n-point one)
    mpfr_real sum = 0;
    for (std::size_t j = 0; j < rule.nodes.size(); ++j) sum += rule.weights[j] * pow(rule.nodes[j], 2 * n);
    CHECK(abs(sum - mpfr_real(2) / mpfr_real(2 * n + 1)) > tol);
  }
}

TEST_CASE("oracle matrices reproduce the paper's double-pendulum closed forms", "[cross][oracle]") {
  // eqs. mat-A-dp, mat-A-1-dp, mat-A-2-dp, detA, trA1Ainv-dp, trA2Ainv-dp, mat-A-i: these are
  // the paper's algebra; here they only validate the oracle's literal construction.
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  for (int trial = 0; trial < 200; ++trial) {
    const double m1 = 0.05 + unit(rng), m2 = 0.05 + unit(rng);
    const double l1 = 0.2 + unit(rng), l2 = 0.2 + 2 * unit(rng);
    const double phi1 = 6.283185307179586 * unit(rng), phi2 = 6.283185307179586 * unit(rng);
    const oracle::Pendulum2<double> p{m1, m2, l1, l2, 1.0};
    const double c12 = std::cos(phi2 - phi1);
    const double big_m = m1 + m2, mu1 = m1 / big_m, mu2 = m2 / big_m;
    const Eigen::Matrix2d a = oracle::matrix_a(p, c12);
    const Eigen::Matrix2d a1 = oracle::matrix_a_particle(p, 0, c12);
    const Eigen::Matrix2d a2 = oracle::matrix_a_particle(p, 1, c12);
    INFO("trial " << trial);
    CHECK(a(0, 0) == Approx(big_m * l1 * l1).epsilon(1e-14));
    CHECK(a(0, 1) == Approx(big_m * mu2 * l1 * l2 * c12).epsilon(1e-14).margin(1e-15));
    CHECK(a(1, 0) == Approx(a(0, 1)).epsilon(1e-15).margin(1e-16));
    CHECK(a(1, 1) == Approx(big_m * mu2 * l2 * l2).epsilon(1e-14));
    CHECK((a1 + a2 - a).cwiseAbs().maxCoeff() <= 1e-14 * a.cwiseAbs().maxCoeff());
    CHECK(a.determinant() ==
          Approx(big_m * big_m * mu2 * l1 * l1 * l2 * l2 * (1 - mu2 * c12 * c12)).epsilon(1e-12));
    const double tr1 = (a1 * a.inverse()).trace(), tr2 = (a2 * a.inverse()).trace();
    CHECK(tr1 == Approx(mu1 / (1 - mu2 * c12 * c12)).epsilon(1e-12));
    CHECK(tr2 == Approx(2 - tr1).epsilon(1e-12));
    // eq. trace-ineq
    CHECK(tr1 >= -1e-15);
    CHECK(tr1 <= 1 + 1e-14);
    CHECK(tr2 >= 1 - 1e-14);
    CHECK(tr2 <= 2 + 1e-14);
  }
}

TEST_CASE("oracle 2-D definition converges and agrees with Graf's series at 30 digits", "[cross][oracle]") {
  const int digits = 30;
  const pendavg::working_precision guard(digits + pendavg::guard_digits);
  const Case c{"mu1 = 0.75, beta = 2, l2 = 1.5", 0.75, 0.25, 1, 1.5, 1, 2};
  const oracle::CheckedDefinitionAverages<mpfr_real> def = run_oracle<mpfr_real>(c, digits);
  INFO(describe(c) << "; refinement difference " << fmt_mp(def.refinement_difference, 5));
  REQUIRE(def.refinement_difference <= pow(mpfr_real(10), -(digits + 1)));
  CHECK(def.fine.trace_sum_deviation <= pow(mpfr_real(10), -(digits + 5)));
  const mpfr_real mu1 = mpfr_real(c.m1) / (mpfr_real(c.m1) + mpfr_real(c.m2));
  const mpfr_real mu2 = mpfr_real(c.m2) / (mpfr_real(c.m1) + mpfr_real(c.m2));
  const mpfr_real a1 = mpfr_real(c.beta) * (mpfr_real(c.m1) + mpfr_real(c.m2)) * mpfr_real(c.g) * mpfr_real(c.l1);
  const mpfr_real a2 = mpfr_real(c.beta) * mpfr_real(c.m2) * mpfr_real(c.g) * mpfr_real(c.l2);
  // mu2 = 1/4: 60 terms leave a tail below 4^-60 ~ 1e-36.
  const mpfr_real series = oracle::graf_series_beta_kinetic1(mu1, mu2, a1, a2, 60);
  INFO("definition " << fmt_mp(def.fine.beta_kinetic[0], 40) << " Graf series " << fmt_mp(series, 40));
  CHECK(relative_difference(def.fine.beta_kinetic[0], series) <= pow(mpfr_real(10), -digits));
  CHECK(abs(def.fine.beta_kinetic[0] + def.fine.beta_kinetic[1] - 1) <= pow(mpfr_real(10), -(digits + 5)));
}

// ============================================================================== a. three methods

/// Moderate parameter sets on which all three methods (series, integral, 2-D oracle) are cheap.
std::vector<Case> moderate_cases() {
  return {
      {"paper: m = 1/2, l = 1, beta = 1", 0.5, 0.5, 1, 1, 1, 1},
      {"mu1 = 0.3, l2 = 2, beta = 5", 0.3, 0.7, 1, 2, 1, 5},
      {"mu1 = 0.8, l2 = 0.5, beta = 0.1", 0.8, 0.2, 1, 0.5, 1, 0.1},
      {"mu1 = 0.2, l2 = 1.5, beta = 10", 0.2, 0.8, 1, 1.5, 1, 10},
  };
}

/// Series, reduced integral and the 2-D definition at `digits` digits (MPFR) on `cases`.
void check_three_methods_mpfr(const std::vector<Case>& cases, int digits) {
  const pendavg::working_precision guard(digits + pendavg::guard_digits);
  const mpfr_real tol = pow(mpfr_real(10), -digits);
  for (const Case& c : cases) {
    INFO(describe(c) << " at " << digits << " digits");
    const pendavg::Chain<mpfr_real> chain = chain_mpfr(c);
    const mpfr_real beta = c.beta;
    const oracle::CheckedDefinitionAverages<mpfr_real> def = run_oracle<mpfr_real>(c, digits);
    INFO("oracle: P = " << def.panels << ", n = " << def.nodes_per_panel << ", refinement difference "
                        << fmt_mp(def.refinement_difference, 5));
    REQUIRE(def.refinement_difference <= pow(mpfr_real(10), -(digits + 1)));
    const pendavg::Averages<mpfr_real> series = pendavg::series_average<mpfr_real>(chain, beta, digits);
    const pendavg::Averages<mpfr_real> integral = pendavg::reduced_integral_average<mpfr_real>(chain, beta, digits);
    CHECK(series.converged);
    CHECK(integral.converged);
    for (std::size_t i = 0; i < 2; ++i) {
      INFO("particle " << i + 1 << ": oracle " << fmt_mp(def.fine.beta_kinetic[i], digits + 10) << ", series "
                       << fmt_mp(series.beta_kinetic.at(i).value, digits + 10) << ", integral "
                       << fmt_mp(integral.beta_kinetic.at(i).value, digits + 10));
      CHECK(relative_difference(series.beta_kinetic.at(i).value, def.fine.beta_kinetic[i]) <= tol);
      CHECK(relative_difference(integral.beta_kinetic.at(i).value, def.fine.beta_kinetic[i]) <= tol);
      CHECK(relative_difference(series.beta_kinetic.at(i).value, integral.beta_kinetic.at(i).value) <= tol);
    }
    for (Kind k : {Kind::cos_angle, Kind::variance}) {
      for (std::size_t i = 0; i < 2; ++i) {
        INFO(kind_name(k) << " " << i + 1 << ": oracle " << fmt_mp(oracle_value_of(def.fine, k, i), digits + 10)
                          << ", integral " << fmt_mp(value_of(integral, k, i), digits + 10));
        CHECK(relative_difference(value_of(integral, k, i), oracle_value_of(def.fine, k, i)) <= tol);
      }
    }
  }
}

TEST_CASE("series, reduced integral and the 2-D definition agree to the requested digits", "[cross]") {
  SECTION("MPFR, 30 digits") { check_three_methods_mpfr(moderate_cases(), 30); }
  SECTION("double") {
    const double tol = 1e-14;
    for (const Case& c : moderate_cases()) {
      INFO(describe(c));
      const pendavg::Chain<double> chain = chain_of(c);
      const oracle::CheckedDefinitionAverages<double> def = run_oracle<double>(c, 16);
      INFO("oracle refinement difference " << fmt(def.refinement_difference));
      REQUIRE(def.refinement_difference <= 1e-15);
      const pendavg::Averages<double> series = pendavg::series_average<double>(chain, c.beta, 16);
      const pendavg::Averages<double> integral = pendavg::reduced_integral_average<double>(chain, c.beta, 16);
      for (std::size_t i = 0; i < 2; ++i) {
        INFO("particle " << i + 1 << ": oracle " << fmt(def.fine.beta_kinetic[i]) << ", series "
                         << fmt(series.beta_kinetic.at(i).value) << ", integral " << fmt(integral.beta_kinetic.at(i).value));
        CHECK(relative_difference(series.beta_kinetic.at(i).value, def.fine.beta_kinetic[i]) <= tol);
        CHECK(relative_difference(integral.beta_kinetic.at(i).value, def.fine.beta_kinetic[i]) <= tol);
        CHECK(relative_difference(series.beta_kinetic.at(i).value, integral.beta_kinetic.at(i).value) <= tol);
      }
      // <cos phi_i> can be small (0.005 at beta = 0.1): the double oracle's sum of w cos(phi) then
      // cancels and carries ~1e-16 absolute rounding (the rule's own node/weight rounding applied
      // to cos), so a 1e-16 absolute floor applies to the angle and variance checks in double.
      for (Kind k : {Kind::cos_angle, Kind::variance}) {
        for (std::size_t i = 0; i < 2; ++i) {
          const double got = value_of(integral, k, i), ref = oracle_value_of(def.fine, k, i);
          INFO(kind_name(k) << " " << i + 1 << ": oracle " << fmt(ref) << ", integral " << fmt(got)
                            << ", difference " << fmt(got - ref));
          CHECK((relative_difference(got, ref) <= tol || std::abs(got - ref) <= 1e-16));
        }
      }
    }
  }
}

TEST_CASE("series, reduced integral and the 2-D definition agree at 50 digits on more parameters",
          "[cross][.slow]") {
  std::vector<Case> cases = moderate_cases();
  cases.push_back({"mu1 = 0.1, l2 = 0.7, beta = 3", 0.1, 0.9, 1, 0.7, 1, 3});
  cases.push_back({"mu1 = 0.6, l2 = 1.8, beta = 20", 0.6, 0.4, 1, 1.8, 1, 20});
  cases.push_back({"mu1 = 0.4, l1 = 2, l2 = 0.5, g = 2.5, beta = 0.01", 0.4, 0.6, 2, 0.5, 2.5, 0.01});
  cases.push_back({"M = 3 (m1 = 1, m2 = 2), l2 = 1, beta = 2", 1, 2, 1, 1, 1, 2});
  check_three_methods_mpfr(cases, 50);
}

// ============================================================================== b, c. double vs MPFR

/// One quantity of one case: the double engine's value and error estimate against MPFR.
struct Comparison {
  Kind kind;
  std::size_t particle;
  double value;      ///< double engine
  double error;      ///< its reported absolute error
  double reference;  ///< MPFR (30 digits), rounded to double
  double diff;       ///< value - reference, computed in MPFR (exact double input)
};

struct CaseOutcome {
  Case c;
  std::string failure;  ///< non-empty: an engine threw
  bool converged_double = false, converged_mpfr = false;
  std::vector<Comparison> quantities;
};

/// Double and MPFR (30 digits) reduced integrals of every case, computed once and shared by
/// the tests below.
const std::vector<CaseOutcome>& double_vs_mpfr_outcomes() {
  static const std::vector<CaseOutcome> outcomes = [] {
    std::vector<CaseOutcome> out;
    const int digits = 30;
    for (const Case& c : all_cases()) {
      CaseOutcome o;
      o.c = c;
      try {
        const pendavg::Averages<double> d = pendavg::reduced_integral_average<double>(chain_of(c), c.beta, 16);
        const pendavg::working_precision guard(digits + pendavg::guard_digits);
        const pendavg::Averages<mpfr_real> m =
            pendavg::reduced_integral_average<mpfr_real>(chain_mpfr(c), mpfr_real(c.beta), digits);
        o.converged_double = d.converged;
        o.converged_mpfr = m.converged;
        for (Kind k : all_kinds) {
          for (std::size_t i = 0; i < 2; ++i) {
            const mpfr_real diff = mpfr_real(value_of(d, k, i)) - value_of(m, k, i);
            o.quantities.push_back(
                {k, i, value_of(d, k, i), error_of(d, k, i), to_double(value_of(m, k, i)), to_double(diff)});
          }
        }
      } catch (const std::exception& e) {
        o.failure = e.what();
      }
      out.push_back(std::move(o));
    }
    return out;
  }();
  return outcomes;
}

TEST_CASE("double agrees with MPFR over randomized parameters including the hard cases", "[cross]") {
  std::size_t failures = 0, checked = 0;
  double worst_kinetic = 0, worst_other_rel = 0;
  std::string worst_kinetic_case;
  for (const CaseOutcome& o : double_vs_mpfr_outcomes()) {
    if (!o.failure.empty()) {
      ++failures;
      FAIL_CHECK(describe(o.c) << ": threw: " << o.failure);
      continue;
    }
    if (!o.converged_double || !o.converged_mpfr) {
      ++failures;
      FAIL_CHECK(describe(o.c) << ": not converged (double " << o.converged_double << ", mpfr "
                               << o.converged_mpfr << ")");
    }
    for (const Comparison& q : o.quantities) {
      ++checked;
      const double rel = std::abs(q.diff) / std::abs(q.reference);
      bool ok = false;
      if (q.kind == Kind::kinetic) {
        ok = rel <= 2e-15;
        if (rel > worst_kinetic) {
          worst_kinetic = rel;
          worst_kinetic_case = describe(o.c);
        }
      } else {
        ok = rel <= 1e-13 || std::abs(q.diff) <= 1e-15;
        if (std::abs(q.diff) > 1e-15) worst_other_rel = std::max(worst_other_rel, rel);
      }
      if (!ok) {
        ++failures;
        FAIL_CHECK(describe(o.c) << ": " << kind_name(q.kind) << q.particle + 1 << " double " << fmt(q.value)
                                 << " mpfr " << fmt(q.reference) << " diff " << fmt(q.diff) << " rel "
                                 << fmt(rel));
      }
    }
  }
  WARN("double vs MPFR: " << checked << " quantities, " << failures << " failures; worst relative error of beta*K "
                          << fmt(worst_kinetic) << " at " << worst_kinetic_case
                          << "; worst relative error of cos/var (beyond 1e-15 absolute) " << fmt(worst_other_rel));
  CHECK(checked >= 6 * 300);
  CHECK(failures == 0);
}

/// Ratio |true error| / reported error, infinite when a nonzero error is reported as zero.
double coverage_ratio(double true_error, double reported) {
  if (true_error == 0) return 0;
  if (reported <= 0) return std::numeric_limits<double>::infinity();
  return true_error / reported;
}

/// Coverage (|value - ref| <= error) and tightness (error <= 10^-digits |value|) of the MPFR
/// engine's estimates. For <cos phi_i> and beta^2 Var K_i, which can be 0 or tiny (g = 0, beta ->
/// 0), tightness is measured against max(|value|, 1e-2), the same relative/absolute split as the
/// double test (1e-13 relative or 1e-15 absolute); the count of strictly relative misses is printed.
void check_mpfr_estimates(const std::vector<Case>& cases) {
  const int ref_digits = 80;
  const int digit_list[] = {20, 30, 50};
  struct Stats {
    std::size_t not_covering = 0, not_tight = 0, not_tight_strict = 0, checked = 0;
    double worst = 0;          // largest true/reported
    double worst_true = 0;     // largest true error relative to max(|value|, floor)
    std::string worst_where;
  };
  Stats stats[3];
  for (const Case& c : cases) {
    const pendavg::working_precision outer(ref_digits + pendavg::guard_digits);
    pendavg::Averages<mpfr_real> ref;
    try {
      ref = pendavg::reduced_integral_average<mpfr_real>(chain_mpfr(c), mpfr_real(c.beta), ref_digits);
    } catch (const std::exception& ex) {
      FAIL_CHECK(describe(c) << ": " << ref_digits << " digits: threw: " << ex.what());
      continue;
    }
    if (!ref.converged) FAIL_CHECK(describe(c) << ": not converged at " << ref_digits << " digits");
    for (std::size_t d = 0; d < 3; ++d) {
      const int digits = digit_list[d];
      Stats& st = stats[d];
      pendavg::Averages<mpfr_real> got;
      try {
        const pendavg::working_precision inner(digits + pendavg::guard_digits);
        got = pendavg::reduced_integral_average<mpfr_real>(chain_mpfr(c), mpfr_real(c.beta), digits);
      } catch (const std::exception& ex) {
        FAIL_CHECK(describe(c) << ": " << digits << " digits: threw: " << ex.what());
        continue;
      }
      if (!got.converged) FAIL_CHECK(describe(c) << ": not converged at " << digits << " digits");
      const mpfr_real scale = pow(mpfr_real(10), -digits);
      for (Kind k : all_kinds) {
        for (std::size_t i = 0; i < 2; ++i) {
          ++st.checked;
          const mpfr_real& v = value_of(got, k, i);
          const mpfr_real& e = error_of(got, k, i);
          const mpfr_real true_error = abs(v - value_of(ref, k, i));  // at ref_digits + guard digits
          const mpfr_real abs_v = abs(v);
          const mpfr_real magnitude = (k == Kind::kinetic || abs_v > mpfr_real(1e-2)) ? abs_v : mpfr_real(1e-2);
          const double ratio = coverage_ratio(to_double(true_error), to_double(e));
          if (ratio > st.worst) {
            st.worst = ratio;
            st.worst_where = describe(c) + " " + kind_name(k) + std::to_string(i + 1);
          }
          st.worst_true = std::max(st.worst_true, to_double(mpfr_real(true_error / magnitude)));
          if (!(true_error <= e)) {
            ++st.not_covering;
            FAIL_CHECK(describe(c) << ": " << digits << " digits, " << kind_name(k) << i + 1 << " true error "
                                   << fmt_mp(true_error, 5) << " > reported " << fmt_mp(e, 5) << " (value "
                                   << fmt_mp(v, digits + 2) << ")");
          }
          if (!(e <= scale * abs_v)) ++st.not_tight_strict;
          if (!(e <= scale * magnitude)) {
            ++st.not_tight;
            FAIL_CHECK(describe(c) << ": " << digits << " digits, " << kind_name(k) << i + 1 << " reported error "
                                   << fmt_mp(e, 5) << " > 10^-" << digits << " * " << fmt_mp(magnitude, 5));
          }
        }
      }
    }
  }
  for (std::size_t d = 0; d < 3; ++d) {
    const Stats& st = stats[d];
    WARN("MPFR " << digit_list[d] << " digits vs " << ref_digits << ": " << st.checked << " checked, "
                 << st.not_covering << " not covering, " << st.not_tight << " not tight (" << st.not_tight_strict
                 << " not tight relative to |value| itself); worst true relative error " << fmt(st.worst_true)
                 << "; worst true/reported = " << fmt(st.worst) << " at " << st.worst_where);
    CHECK(st.not_covering == 0);
    CHECK(st.not_tight == 0);
  }
}

TEST_CASE("reported error estimates cover the true error", "[cross]") {
  SECTION("double against MPFR at 30 digits") {
    std::size_t violations = 0, checked = 0;
    double worst = 0;
    std::string worst_where;
    for (const CaseOutcome& o : double_vs_mpfr_outcomes()) {
      if (!o.failure.empty()) {
        FAIL_CHECK(describe(o.c) << ": threw: " << o.failure);
        continue;
      }
      for (const Comparison& q : o.quantities) {
        ++checked;
        // The reference is good to ~1e-30 relative, far below double's errors.
        const double ratio = coverage_ratio(std::abs(q.diff), q.error);
        if (ratio > worst) {
          worst = ratio;
          worst_where = describe(o.c) + " " + kind_name(q.kind) + std::to_string(q.particle + 1);
        }
        if (!(std::abs(q.diff) <= q.error)) {
          ++violations;
          FAIL_CHECK(describe(o.c) << ": " << kind_name(q.kind) << q.particle + 1 << " true error " << fmt(std::abs(q.diff))
                                   << " > reported " << fmt(q.error) << " (value " << fmt(q.value) << ")");
        }
      }
    }
    WARN("double error estimates: " << checked << " checked, " << violations
                                    << " not covering; worst true/reported = " << fmt(worst) << " at " << worst_where);
    CHECK(violations == 0);
  }

  SECTION("MPFR at 20/30/50 digits against 80 digits") {
    check_mpfr_estimates(all_cases());
  }
}

TEST_CASE("reported error estimates cover the true error on 1000 further random cases", "[cross][.slow]") {
  const std::vector<Case> cases = random_cases(1000, 0xc0ffee5eedULL);
  std::size_t violations = 0, inaccurate = 0;
  double worst = 0;
  for (const Case& c : cases) {
    try {
      const pendavg::Averages<double> d = pendavg::reduced_integral_average<double>(chain_of(c), c.beta, 16);
      const pendavg::working_precision guard(30 + pendavg::guard_digits);
      const pendavg::Averages<mpfr_real> m =
          pendavg::reduced_integral_average<mpfr_real>(chain_mpfr(c), mpfr_real(c.beta), 30);
      for (Kind k : all_kinds) {
        for (std::size_t i = 0; i < 2; ++i) {
          const double true_error = to_double(mpfr_real(abs(mpfr_real(value_of(d, k, i)) - value_of(m, k, i))));
          const double rel = true_error / std::abs(to_double(value_of(m, k, i)));
          // the accuracy targets of the test "double agrees with MPFR ..."
          const bool accurate = (k == Kind::kinetic) ? rel <= 2e-15 : (rel <= 1e-13 || true_error <= 1e-15);
          if (!accurate) {
            ++inaccurate;
            FAIL_CHECK(describe(c) << ": " << kind_name(k) << i + 1 << " double " << fmt(value_of(d, k, i))
                                   << " relative error " << fmt(rel));
          }
          worst = std::max(worst, coverage_ratio(true_error, error_of(d, k, i)));
          if (!(true_error <= error_of(d, k, i))) {
            ++violations;
            FAIL_CHECK(describe(c) << ": " << kind_name(k) << i + 1 << " true error " << fmt(true_error)
                                   << " > reported " << fmt(error_of(d, k, i)));
          }
        }
      }
    } catch (const std::exception& e) {
      FAIL_CHECK(describe(c) << ": threw: " << e.what());
    }
  }
  WARN("double on 1000 further cases: " << inaccurate << " beyond the accuracy target, " << violations
                                         << " error estimates not covering; worst true/reported = " << fmt(worst));
  CHECK(inaccurate == 0);
  CHECK(violations == 0);
  check_mpfr_estimates(cases);
}

// ============================================================================== d. the paper

TEST_CASE("the paper's values and inequality", "[cross]") {
  // Paper eq. aveK1-beta0 with m1 = m2 = 1/2; digits from tests/data/public_values.csv
  // (19 significant digits given: checked to 18).
  const char* k1_limit = "0.3431834814709248549";
  const char* k2_limit = "0.6568165185290751451";
  const Case equal{"m = 1/2", 0.5, 0.5, 1, 1, 1, 1};

  SECTION("beta -> 0 limit, double") {
    const pendavg::Averages<double> lim = pendavg::elliptic_high_temperature_limit<double>(chain_of(equal), 16);
    CHECK(relative_difference(lim.beta_kinetic.at(0).value, std::stod(k1_limit)) <= 2e-15);
    CHECK(relative_difference(lim.beta_kinetic.at(1).value, std::stod(k2_limit)) <= 2e-15);
  }
  SECTION("beta -> 0 limit, 40 digits") {
    const int digits = 40;
    const pendavg::working_precision guard(digits + pendavg::guard_digits);
    const pendavg::Averages<mpfr_real> lim = pendavg::elliptic_high_temperature_limit<mpfr_real>(chain_mpfr(equal), digits);
    INFO("limit " << fmt_mp(lim.beta_kinetic.at(0).value, 45) << " " << fmt_mp(lim.beta_kinetic.at(1).value, 45));
    CHECK(relative_difference(lim.beta_kinetic.at(0).value, mpfr_real(k1_limit)) <= pow(mpfr_real(10), -18));
    CHECK(relative_difference(lim.beta_kinetic.at(1).value, mpfr_real(k2_limit)) <= pow(mpfr_real(10), -18));
    // and to all 40 digits against (mu1/2) K(k)/E(k), k^2 = mu2, from Boost's Legendre forms
    // (independent of the library's Carlson route), for several mass ratios.
    for (double m1 : {0.5, 0.1, 0.9, 0.01}) {
      const Case c{"limit", m1, 1 - m1, 1, 1, 1, 1};
      const pendavg::Chain<mpfr_real> chain = chain_mpfr(c);
      const mpfr_real mu1 = chain.masses()[0] / chain.total_mass();
      const mpfr_real mu2 = chain.masses()[1] / chain.total_mass();
      const mpfr_real k = sqrt(mu2);
      const mpfr_real expected = mu1 / 2 * boost::math::ellint_1(k) / boost::math::ellint_2(k);
      const pendavg::Averages<mpfr_real> l = pendavg::elliptic_high_temperature_limit<mpfr_real>(chain, digits);
      INFO("m1 = " << m1 << ": library " << fmt_mp(l.beta_kinetic.at(0).value, 45) << " K/E " << fmt_mp(expected, 45));
      CHECK(relative_difference(l.beta_kinetic.at(0).value, expected) <= pow(mpfr_real(10), -digits));
      CHECK(abs(l.beta_kinetic.at(0).value + l.beta_kinetic.at(1).value - 1) <= pow(mpfr_real(10), -digits));
    }
  }
  SECTION("0 <= beta<K1> <= 1/2 <= beta<K2> <= 1 (eq. trace-ineq-ave) on every case") {
    std::size_t n = 0;
    for (const Case& c : all_cases()) {
      INFO(describe(c));
      const pendavg::Averages<double> a = pendavg::reduced_integral_average<double>(chain_of(c), c.beta, 16);
      CHECK(a.beta_kinetic.at(0).value >= 0);
      CHECK(a.beta_kinetic.at(0).value <= 0.5);
      CHECK(a.beta_kinetic.at(1).value >= 0.5);
      CHECK(a.beta_kinetic.at(1).value <= 1);
      CHECK(std::abs(a.beta_kinetic.at(0).value + a.beta_kinetic.at(1).value - 1) <= 4e-16);
      ++n;
    }
    CHECK(n > 300);
  }
  SECTION("the integral approaches the beta -> 0 limit") {
    for (const Case& base : {Case{"m = 1/2", 0.5, 0.5, 1, 1, 1, 1e-10}, Case{"mu1 = 0.05, l2 = 3", 0.05, 0.95, 1, 3, 1, 1e-10},
                             Case{"mu1 = 0.9, l2 = 0.2", 0.9, 0.1, 1, 0.2, 1, 1e-10}}) {
      INFO(describe(base));
      const pendavg::Chain<double> chain = chain_of(base);
      const pendavg::Averages<double> lim = pendavg::elliptic_high_temperature_limit<double>(chain, 16);
      const pendavg::Averages<double> a = pendavg::reduced_integral_average<double>(chain, base.beta, 16);
      for (std::size_t i = 0; i < 2; ++i) {
        INFO("particle " << i + 1 << ": limit " << fmt(lim.beta_kinetic.at(i).value) << " integral " << fmt(a.beta_kinetic.at(i).value));
        CHECK(relative_difference(a.beta_kinetic.at(i).value, lim.beta_kinetic.at(i).value) <= 1e-9);
      }
    }
  }
  SECTION("the integral approaches the beta -> infinity limit (equipartition)") {
    const Case cold{"m = 1/2, beta = 1e8", 0.5, 0.5, 1, 1, 1, 1e8};
    const pendavg::Chain<double> chain = chain_of(cold);
    const pendavg::Averages<double> lim = pendavg::low_temperature_limit<double>(chain);
    CHECK(lim.beta_kinetic.at(0).value == 0.5);
    CHECK(lim.beta_kinetic.at(1).value == 0.5);
    const pendavg::Averages<double> a = pendavg::reduced_integral_average<double>(chain, cold.beta, 16);
    INFO("beta<K1> = " << fmt(a.beta_kinetic.at(0).value) << ", beta<K2> = " << fmt(a.beta_kinetic.at(1).value));
    CHECK(std::abs(a.beta_kinetic.at(0).value - lim.beta_kinetic.at(0).value) <= 1e-6);
    CHECK(std::abs(a.beta_kinetic.at(1).value - lim.beta_kinetic.at(1).value) <= 1e-6);
  }
}

// ============================================================================== e, f. the series

/// Parameter sets for the series checks (moderate mu2, so the series is short).
std::vector<Case> series_cases() {
  return {
      {"m = 1/2, beta = 1", 0.5, 0.5, 1, 1, 1, 1},
      {"mu1 = 0.3, l2 = 2, beta = 5", 0.3, 0.7, 1, 2, 1, 5},
      {"mu1 = 0.8, l2 = 0.5, beta = 0.1", 0.8, 0.2, 1, 0.5, 1, 0.1},
      {"mu1 = 0.2, l2 = 1.5, beta = 10", 0.2, 0.8, 1, 1.5, 1, 10},
  };
}

TEST_CASE("series R_n matches Graf's addition theorem", "[cross]") {
  const int digits = 30;
  const int n_max = 20;
  const pendavg::working_precision guard(digits + pendavg::guard_digits);
  const mpfr_real tol = pow(mpfr_real(10), -digits);
  for (const Case& c : series_cases()) {
    INFO(describe(c));
    const pendavg::Chain<mpfr_real> chain = chain_mpfr(c);
    const mpfr_real beta = c.beta;
    const mpfr_real a1 = beta * (chain.masses()[0] + chain.masses()[1]) * chain.gravity() * chain.lengths()[0];
    const mpfr_real a2 = beta * chain.masses()[1] * chain.gravity() * chain.lengths()[1];
    const std::vector<pendavg::SeriesRow<mpfr_real>> rows =
        pendavg::series_convergence<mpfr_real>(chain, beta, digits, n_max + 1);
    REQUIRE(rows.size() >= static_cast<std::size_t>(n_max + 1));
    const std::vector<mpfr_real> graf = oracle::graf_r_all<mpfr_real>(n_max, a1, a2);
    const mpfr_real scale = exp(-(a1 + a2));
    for (int n = 0; n <= n_max; ++n) {
      const std::size_t k = static_cast<std::size_t>(n);
      const mpfr_real expected = graf[k] * scale;
      INFO("n = " << n << ": library R_n " << fmt_mp(rows[k].R_n, 35) << ", Graf " << fmt_mp(expected, 35));
      CHECK(rows[k].n == k);
      CHECK(relative_difference(rows[k].R_n, expected) <= tol);
    }
  }
}

TEST_CASE("the series certifies its bound", "[cross]") {
  const int digits = 30;
  const int ref_digits = 50;
  for (const Case& c : series_cases()) {
    INFO(describe(c));
    const pendavg::working_precision outer(ref_digits + pendavg::guard_digits);
    const pendavg::Averages<mpfr_real> ref =
        pendavg::reduced_integral_average<mpfr_real>(chain_mpfr(c), mpfr_real(c.beta), ref_digits);
    std::vector<pendavg::SeriesRow<mpfr_real>> rows;
    {
      const pendavg::working_precision inner(digits + pendavg::guard_digits);
      rows = pendavg::series_convergence<mpfr_real>(chain_mpfr(c), mpfr_real(c.beta), digits, 0);
    }
    REQUIRE(rows.size() >= 2);
    std::size_t not_covering = 0, not_monotone = 0;
    double worst = 0;
    for (std::size_t k = 0; k < rows.size(); ++k) {
      const mpfr_real true_error = abs(rows[k].beta_kinetic1 - ref.beta_kinetic.at(0).value);  // at 62 digits
      worst = std::max(worst, coverage_ratio(to_double(true_error), to_double(rows[k].bound)));
      if (!(true_error <= rows[k].bound)) {
        ++not_covering;
        FAIL_CHECK("row n = " << rows[k].n << ": true error " << fmt_mp(true_error, 5) << " > bound "
                              << fmt_mp(rows[k].bound, 5));
      }
      // The tail bound c_{n+1} R_{n+1} mu2^{n+1} / (1 - mu2) is non-increasing in n from the
      // first term on; check every row after n = 0.
      if (k >= 2 && !(rows[k].bound <= rows[k - 1].bound)) {
        ++not_monotone;
        FAIL_CHECK("bound increases from row " << rows[k - 1].n << " (" << fmt_mp(rows[k - 1].bound, 5) << ") to row "
                                                << rows[k].n << " (" << fmt_mp(rows[k].bound, 5) << ")");
      }
    }
    // The last row certifies the requested digits.
    const pendavg::SeriesRow<mpfr_real>& last = rows.back();
    INFO("last row n = " << last.n << ", bound " << fmt_mp(last.bound, 5) << ", value " << fmt_mp(last.beta_kinetic1, 35));
    CHECK(last.bound <= pow(mpfr_real(10), -digits) * abs(last.beta_kinetic1));
    CHECK(relative_difference(last.beta_kinetic1, ref.beta_kinetic.at(0).value) <= pow(mpfr_real(10), -digits));
    WARN(describe(c) << ": " << rows.size() << " rows, " << not_covering << " rows with true error > bound, "
                     << not_monotone << " increases; worst true/bound = " << fmt(worst));
    CHECK(not_covering == 0);
    CHECK(not_monotone == 0);
  }
}

}  // namespace
