// SPDX-License-Identifier: GPL-3.0-or-later
// Tests of the O(N) trace formula (include/pendavg/trace_formula.hpp) against the dense oracle
// (tests/oracle/dense_traces.hpp, eqs. a-ij and the definition of A^(i)), against
// src/engine/README.md, 'Traces in O(N)' (Fixman's tridiagonal form), against the paper's
// double-pendulum closed forms (eqs. detA, trA1Ainv-dp), and against exact identities
// (src/engine/README.md, 'Notation').
#include "oracle/dense_traces.hpp"
#include "pendavg/chain.hpp"
#include "engine/numerics/precision.hpp"
#include "pendavg/trace_formula.hpp"
#include "real_types.hpp"

#include <catch2/catch.hpp>

#include <Eigen/Dense>

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <random>
#include <vector>

namespace {

using pendavg::Chain;
using pendavg::mpfr_real;
using pendavg::node_traces;
using pendavg::TraceWorkspace;

/// A random chain: masses log-uniform in [mass_lo, mass_hi], lengths log-uniform in [0.1, 10],
/// angles uniform in [-pi, pi). Stored in double (exact in every wider type).
struct RandomNode {
  std::vector<double> masses, lengths, phi;
};

RandomNode random_node(std::mt19937_64& rng, std::size_t n, double mass_lo = 1e-3,
                       double mass_hi = 1e3) {
  std::uniform_real_distribution<double> log_mass(std::log(mass_lo), std::log(mass_hi));
  std::uniform_real_distribution<double> log_length(std::log(0.1), std::log(10.0));
  std::uniform_real_distribution<double> angle(-M_PI, M_PI);
  RandomNode node;
  for (std::size_t i = 0; i < n; ++i) {
    node.masses.push_back(std::exp(log_mass(rng)));
    node.lengths.push_back(std::exp(log_length(rng)));
    node.phi.push_back(angle(rng));
  }
  return node;
}

template <class Real>
std::vector<Real> cast_vector(const std::vector<double>& v) {
  return std::vector<Real>(v.begin(), v.end());
}

template <class Real>
Real relative_error(const Real& value, const Real& reference) {
  using std::abs;
  return abs(value - reference) / abs(reference);
}

/// Largest relative error of the O(N) node against the dense oracle (traces, squared traces)
/// and absolute error of log sqrt(det A) (the relative error of sqrt(det A)).
template <class Real, class Ref>
double node_error(const pendavg::NodeTraces<Real>& fast, const pendavg::oracle::DenseTraces<Ref>& ref) {
  using std::abs;
  Ref worst = abs(Ref(fast.log_sqrt_det_A) - ref.log_sqrt_det_A);
  for (std::size_t i = 0; i < fast.trace_X.size(); ++i) {
    worst = std::max(worst, relative_error(Ref(fast.trace_X[i]), ref.trace_X[i]));
    worst = std::max(worst, relative_error(Ref(fast.trace_X_squared[i]), ref.trace_X_squared[i]));
  }
  return static_cast<double>(worst);
}

}  // namespace

// Generic over the number type (double, long double, MPFR at test_digits): each against the
// dense oracle at 50 digits, tolerances in units of the type's precision.
TEMPLATE_TEST_CASE("trace formula: O(N) matches the dense oracle in 50-digit MPFR", "[trace]",
                   double, long double, mpfr_real) {
  // Two inputs per node: the absolute angles (the code forms phi_{i+1} - phi_i, whose rounding is
  // part of its error), and relative angles given exactly (the oracle sums them in MPFR), which
  // isolates the error of the recurrences themselves.
  using Real = TestType;
  const pendavg::test::TypePrecision<Real> precision;
  std::mt19937_64 rng(20240611);
  double worst_absolute = 0, worst_relative = 0;
  for (std::size_t n = 1; n <= 12; ++n) {
    for (int trial = 0; trial < 8; ++trial) {
      const RandomNode node = random_node(rng, n);
      const Chain<Real> chain(cast_vector<Real>(node.masses), cast_vector<Real>(node.lengths));
      TraceWorkspace<Real> ws(chain);
      const std::vector<Real> phi = cast_vector<Real>(node.phi);
      const pendavg::NodeTraces<Real> fast = node_traces(chain, phi.data(), ws);
      const pendavg::NodeTraces<Real> from_delta =
          pendavg::node_traces_relative(chain, phi.data() + 1, ws);
      const pendavg::working_precision guard(50);
      const std::vector<mpfr_real> masses = cast_vector<mpfr_real>(node.masses);
      const std::vector<mpfr_real> lengths = cast_vector<mpfr_real>(node.lengths);
      const auto ref = pendavg::oracle::dense_traces(masses, lengths,
                                                     cast_vector<mpfr_real>(node.phi));
      worst_absolute = std::max(worst_absolute, node_error(fast, ref));

      std::vector<mpfr_real> phi_exact(n, mpfr_real(0));
      for (std::size_t i = 1; i < n; ++i) phi_exact[i] = phi_exact[i - 1] + mpfr_real(node.phi[i]);
      const auto ref_delta = pendavg::oracle::dense_traces(masses, lengths, phi_exact);
      worst_relative = std::max(worst_relative, node_error(from_delta, ref_delta));
    }
  }
  const double unit = pendavg::test::unit<Real>();
  INFO("largest relative error against 50-digit dense, in units of the type's precision: "
       "absolute angles " << worst_absolute / unit << ", exact relative angles "
       << worst_relative / unit);
  CHECK(worst_absolute < 450 * unit);
  CHECK(worst_relative < 32 * unit);
}

TEST_CASE("trace formula: O(N) in MPFR matches the dense oracle to 40 digits", "[trace]") {
  std::mt19937_64 rng(77);
  const pendavg::working_precision guard(50);
  double worst = 0;
  for (std::size_t n = 1; n <= 12; ++n) {
    for (int trial = 0; trial < 4; ++trial) {
      const RandomNode node = random_node(rng, n);
      const Chain<mpfr_real> chain(cast_vector<mpfr_real>(node.masses),
                                   cast_vector<mpfr_real>(node.lengths));
      TraceWorkspace<mpfr_real> ws(chain);
      const std::vector<mpfr_real> phi = cast_vector<mpfr_real>(node.phi);
      const auto& fast = node_traces(chain, phi.data(), ws);
      const auto ref = pendavg::oracle::dense_traces(chain.masses(), chain.lengths(), phi);
      worst = std::max(worst, node_error(fast, ref));
    }
  }
  INFO("largest relative error, 50-digit O(N) vs 50-digit dense: " << worst);
  CHECK(worst < 1e-40);
}

TEST_CASE("trace formula: src/engine/README.md, 'Traces in O(N)' (Fixman's tridiagonal form) agrees with eq. a-ij",
          "[trace][oracle]") {
  // The dense H = C M^{-1} C^T route against the dense A route, both in MPFR: checks the
  // indexing of H and of the trace formula, and det A = (prod m_j l_j)^2 det H.
  std::mt19937_64 rng(5);
  const pendavg::working_precision guard(50);
  double worst = 0;
  for (std::size_t n = 1; n <= 9; ++n) {
    for (int trial = 0; trial < 3; ++trial) {
      const RandomNode node = random_node(rng, n);
      const auto ref = pendavg::oracle::dense_traces(
          cast_vector<mpfr_real>(node.masses), cast_vector<mpfr_real>(node.lengths),
          cast_vector<mpfr_real>(node.phi));
      mpfr_real err = abs(ref.log_sqrt_det_A_fixman - ref.log_sqrt_det_A);
      for (std::size_t i = 0; i < n; ++i) {
        err = std::max(err, mpfr_real(abs(ref.trace_X_fixman[i] - ref.trace_X[i])));
      }
      worst = std::max(worst, static_cast<double>(err));
    }
  }
  INFO("largest difference, Fixman form vs definition: " << worst);
  CHECK(worst < 1e-40);
}

TEMPLATE_TEST_CASE("trace formula: tiny traces keep their relative accuracy", "[trace]", double,
                   long double, mpfr_real) {
  // Light particles between heavy ones: tr X_i ~ m_i / (neighbouring masses) ~ 1e-16. The O(N)
  // sweeps add only non-negative terms, so these stay accurate to a few ulps relative; the
  // 2 - [...] / m_i would lose every digit here.
  using Real = TestType;
  const pendavg::test::TypePrecision<Real> precision;
  const std::vector<double> masses{1e8, 1e-8, 1e8, 1e-8, 1e8, 1e-8, 1e8, 1e-8};
  const std::vector<double> lengths{1, 2, 0.5, 1, 3, 1, 1, 0.7};
  const std::vector<double> phi{0.3, -1.2, 2.0, 2.0001, -0.4, 1.1, 3.0, -2.5};
  const Chain<Real> chain(cast_vector<Real>(masses), cast_vector<Real>(lengths));
  TraceWorkspace<Real> ws(chain);
  const std::vector<Real> phi_real = cast_vector<Real>(phi);
  const pendavg::NodeTraces<Real> fast = node_traces(chain, phi_real.data(), ws);
  const pendavg::working_precision guard(80);
  const auto ref = pendavg::oracle::dense_traces(cast_vector<mpfr_real>(masses),
                                                 cast_vector<mpfr_real>(lengths),
                                                 cast_vector<mpfr_real>(phi));
  CHECK(fast.trace_X[1] < 1e-10);
  const double err = node_error(fast, ref);
  INFO("largest relative error, in units of the type's precision: "
       << err / pendavg::test::unit<Real>());
  CHECK(err < 450 * pendavg::test::unit<Real>());
}

TEMPLATE_TEST_CASE("trace formula: traces sum to N and equal 1 at phi = 0", "[trace]", double,
                   long double, mpfr_real) {
  using Real = TestType;
  using pendavg::test::relative_distance;
  const pendavg::test::TypePrecision<Real> precision;
  const double tolerance = 45 * pendavg::test::unit<Real>();
  std::mt19937_64 rng(11);
  for (std::size_t n : {1u, 2u, 3u, 7u, 30u, 200u}) {
    INFO("N = " << n);
    const RandomNode node = random_node(rng, n);
    const Chain<Real> chain(cast_vector<Real>(node.masses), cast_vector<Real>(node.lengths));
    TraceWorkspace<Real> ws(chain);
    const std::vector<Real> phi = cast_vector<Real>(node.phi);
    const pendavg::NodeTraces<Real> at_node = node_traces(chain, phi.data(), ws);
    Real sum = 0;
    for (const Real& t : at_node.trace_X) sum += t;
    CHECK(relative_distance(sum, mpfr_real(n)) <= tolerance);
    for (std::size_t i = 0; i < n; ++i) {
      // X_i has rank <= 2 and non-negative eigenvalues: tr X^2 lies in [(tr X)^2 / 2, (tr X)^2].
      const Real t = at_node.trace_X[i], t2 = at_node.trace_X_squared[i];
      CHECK(t2 <= t * t * (1 + tolerance));
      CHECK(t2 >= t * t / 2 * (1 - tolerance));
    }

    const std::vector<Real> zero(n, Real(0));
    const pendavg::NodeTraces<Real> at_rest = node_traces(chain, zero.data(), ws);
    for (std::size_t i = 0; i < n; ++i) {
      CHECK(relative_distance(at_rest.trace_X[i], mpfr_real(1)) <= tolerance);
      CHECK(relative_distance(at_rest.trace_X_squared[i], mpfr_real(1)) <= tolerance);
    }
    // at phi = 0, det A = prod m_j l_j^2: its logarithm in MPFR from the same (exact) inputs
    const pendavg::test::ReferencePrecision reference;
    mpfr_real log_sqrt_det = 0;
    for (std::size_t i = 0; i < n; ++i)
      log_sqrt_det += log(mpfr_real(node.masses[i])) / 2 + log(mpfr_real(node.lengths[i]));
    const mpfr_real scale = abs(log_sqrt_det) > 1 ? mpfr_real(abs(log_sqrt_det)) : mpfr_real(1);
    CHECK(relative_distance(at_rest.log_sqrt_det_A, log_sqrt_det, scale) <= 10 * tolerance);
  }
}

TEST_CASE("trace formula: N = 2 reproduces the paper's closed forms (eqs. detA, trA1Ainv-dp)",
          "[trace]") {
  // 60 digits: the closed forms' 1 - mu2 C12^2 cancels ~6 digits in the last case.
  const pendavg::working_precision guard(60);
  for (const auto& [m1, m2, l1, l2, dphi] :
       std::vector<std::array<double, 5>>{{0.5, 0.5, 1, 1, 0.7},
                                          {0.05, 0.95, 1, 2, 2.9},
                                          {3.0, 1e-3, 0.3, 1.7, -1.3},
                                          {1e-3, 1e3, 1, 1, 1e-9}}) {
    const Chain<mpfr_real> chain({mpfr_real(m1), mpfr_real(m2)}, {mpfr_real(l1), mpfr_real(l2)});
    TraceWorkspace<mpfr_real> ws(chain);
    const std::vector<mpfr_real> phi{mpfr_real(0.25), mpfr_real(0.25) + mpfr_real(dphi)};
    const auto& node = node_traces(chain, phi.data(), ws);
    const mpfr_real total = mpfr_real(m1) + mpfr_real(m2);
    const mpfr_real mu1 = mpfr_real(m1) / total, mu2 = mpfr_real(m2) / total;
    const mpfr_real c12 = cos(phi[1] - phi[0]);
    const mpfr_real q = 1 - mu2 * c12 * c12;
    const mpfr_real tr1 = mu1 / q;                                   // eq. trA1Ainv-dp
    const mpfr_real tr2 = ((1 + mu2) - 2 * mu2 * c12 * c12) / q;     // eq. trA2Ainv-dp
    const mpfr_real det = total * total * mu2 * l1 * l1 * l2 * l2 * q;  // eq. detA
    CHECK(static_cast<double>(relative_error(node.trace_X[0], tr1)) < 1e-45);
    CHECK(static_cast<double>(relative_error(node.trace_X[1], tr2)) < 1e-45);
    CHECK(static_cast<double>(abs(node.log_sqrt_det_A - log(det) / 2)) < 1e-45);
    // X_1 has rank one (src/engine/README.md, 'Isserlis'): tr X_1^2 = (tr X_1)^2.
    CHECK(static_cast<double>(relative_error(node.trace_X_squared[0], mpfr_real(tr1 * tr1))) < 1e-45);
  }
}

TEMPLATE_TEST_CASE("trace formula: N = 2 in every number type against the paper's closed forms",
                   "[trace]", double, long double, mpfr_real) {
  // The closed forms (eqs. detA, trA1Ainv-dp, trA2Ainv-dp) at 60 digits from the inputs as the
  // type holds them, including mu1 -> 0 with nearly parallel links (q = 1 - mu2 C12^2 ~ 1e-6)
  // and extreme lengths.
  using Real = TestType;
  using pendavg::test::relative_distance;
  const pendavg::test::TypePrecision<Real> precision;
  const double tolerance = 450 * pendavg::test::unit<Real>();
  for (const auto& [m1, m2, l1, l2, dphi] :
       std::vector<std::array<double, 5>>{{0.5, 0.5, 1, 1, 0.7},
                                          {0.05, 0.95, 1, 2, 2.9},
                                          {3.0, 1e-3, 0.3, 1.7, -1.3},
                                          {1e-3, 1e3, 1, 1, 1e-9},
                                          {1.0, 1.0, 1e-4, 1e4, 1.1}}) {
    INFO("m = (" << m1 << ", " << m2 << "), l = (" << l1 << ", " << l2 << "), dphi = " << dphi);
    const Chain<Real> chain({Real(m1), Real(m2)}, {Real(l1), Real(l2)});
    TraceWorkspace<Real> ws(chain);
    const std::vector<Real> phi{Real(0.25), Real(0.25) + Real(dphi)};
    const pendavg::NodeTraces<Real> node = node_traces(chain, phi.data(), ws);
    const pendavg::working_precision guard(60);
    const mpfr_real total = mpfr_real(m1) + mpfr_real(m2);
    const mpfr_real mu1 = mpfr_real(m1) / total, mu2 = mpfr_real(m2) / total;
    const mpfr_real c12 = cos(mpfr_real(phi[1]) - mpfr_real(phi[0]));
    const mpfr_real q = 1 - mu2 * c12 * c12;
    const mpfr_real tr1 = mu1 / q;
    const mpfr_real tr2 = ((1 + mu2) - 2 * mu2 * c12 * c12) / q;
    const mpfr_real det = total * total * mu2 * l1 * l1 * l2 * l2 * q;
    CHECK(relative_distance(node.trace_X[0], tr1) <= tolerance);
    CHECK(relative_distance(node.trace_X[1], tr2) <= tolerance);
    CHECK(pendavg::test::distance(node.log_sqrt_det_A, mpfr_real(log(det) / 2)) <= tolerance);
    CHECK(relative_distance(node.trace_X_squared[0], mpfr_real(tr1 * tr1)) <= tolerance);
  }
}

TEST_CASE("trace formula: N = 10^4 stays finite and sums to N", "[trace]") {
  std::mt19937_64 rng(123);
  const std::size_t n = 10000;
  const RandomNode node = random_node(rng, n);
  const Chain<double> chain(node.masses, node.lengths);
  TraceWorkspace<double> ws(chain);
  const auto& at_node = node_traces(chain, node.phi.data(), ws);
  double sum = 0;
  bool all_finite = true, all_positive = true;
  for (std::size_t i = 0; i < n; ++i) {
    all_finite = all_finite && std::isfinite(at_node.trace_X[i]) &&
                 std::isfinite(at_node.trace_X_squared[i]);
    all_positive = all_positive && at_node.trace_X[i] > 0;
    sum += at_node.trace_X[i];
  }
  CHECK(all_finite);
  CHECK(all_positive);
  CHECK(std::isfinite(at_node.log_sqrt_det_A));
  CHECK(std::abs(sum - double(n)) < 1e-9 * double(n));

  // Same chain, unit masses and lengths: det A at phi = 0 is 1, and log det stays O(N) elsewhere
  // (the product of the pivots would overflow double long before N = 10^4).
  const Chain<double> uniform(std::vector<double>(n, 1.0), std::vector<double>(n, 1.0));
  const auto& u = node_traces(uniform, node.phi.data(), ws);
  CHECK(std::isfinite(u.log_sqrt_det_A));
  CHECK(u.log_sqrt_det_A > 300.0);  // det A > 1e260 here: the renormalization is exercised
}

TEMPLATE_TEST_CASE("trace formula: matches a 50-digit run at N = 50", "[trace]", double,
                   long double, mpfr_real) {
  // Against the same O(N) code at 50 digits on a longer chain (dense would be slow): the damped
  // recurrences keep the error at a few ulps, not N ulps.
  using Real = TestType;
  const pendavg::test::TypePrecision<Real> precision;
  std::mt19937_64 rng(9);
  const RandomNode node = random_node(rng, 50);
  const Chain<Real> chain(cast_vector<Real>(node.masses), cast_vector<Real>(node.lengths));
  TraceWorkspace<Real> ws(chain);
  const std::vector<Real> phi_real = cast_vector<Real>(node.phi);
  const pendavg::NodeTraces<Real> fast = node_traces(chain, phi_real.data(), ws);
  const pendavg::working_precision guard(50);
  const Chain<mpfr_real> wide(cast_vector<mpfr_real>(node.masses),
                              cast_vector<mpfr_real>(node.lengths));
  TraceWorkspace<mpfr_real> wide_ws(wide);
  const std::vector<mpfr_real> phi = cast_vector<mpfr_real>(node.phi);
  const auto& ref = node_traces(wide, phi.data(), wide_ws);
  double worst = static_cast<double>(abs(mpfr_real(fast.log_sqrt_det_A) - ref.log_sqrt_det_A));
  for (std::size_t i = 0; i < 50; ++i) {
    worst = std::max(worst, static_cast<double>(relative_error(mpfr_real(fast.trace_X[i]), ref.trace_X[i])));
    worst = std::max(worst, static_cast<double>(relative_error(mpfr_real(fast.trace_X_squared[i]),
                                                               ref.trace_X_squared[i])));
  }
  INFO("largest relative error against the 50-digit run, N = 50, in units of the type's precision: "
       << worst / pendavg::test::unit<Real>());
  CHECK(worst < 450 * pendavg::test::unit<Real>());
}

TEST_CASE("trace formula: relative angles give the same node", "[trace]") {
  std::mt19937_64 rng(3);
  const RandomNode node = random_node(rng, 9);
  const Chain<double> chain(node.masses, node.lengths);
  TraceWorkspace<double> ws(chain);
  const auto a = node_traces(chain, node.phi.data(), ws);
  std::vector<double> delta;
  for (std::size_t i = 0; i + 1 < 9; ++i) delta.push_back(node.phi[i + 1] - node.phi[i]);
  const auto& b = pendavg::node_traces_relative(chain, delta.data(), ws);
  CHECK(a.log_sqrt_det_A == b.log_sqrt_det_A);
  CHECK(a.trace_X == b.trace_X);
  CHECK(a.trace_X_squared == b.trace_X_squared);
  // A workspace of the wrong size is refused.
  TraceWorkspace<double> wrong(4);
  CHECK_THROWS_AS(node_traces(chain, node.phi.data(), wrong), pendavg::invalid_input);
}

TEST_CASE("trace formula: canonical energies are 1/(2 beta) and Isserlis holds (Monte Carlo)",
          "[trace]") {
  // src/engine/README.md, 'Isserlis'. (A^{-1} A)_ii = 1 exactly (dense oracle), so beta <K_i^(c) |
  // phi> = 1/2. Then sample p ~ N(0, A) (beta = 1) and check E[2 K_i] = tr X_i,
  // E[4 K_i^2] = (tr X_i)^2 + 2 tr X_i^2 and E[2 K_i^(c)] = 1 within 5 standard errors.
  const std::vector<double> masses{0.7, 0.05, 2.0};
  const std::vector<double> lengths{1.0, 1.5, 0.6};
  const std::vector<double> phi{0.4, 2.1, -0.9};
  const auto dense = pendavg::oracle::dense_traces(masses, lengths, phi);
  for (double d : dense.canonical_diagonal) CHECK(d == Approx(1.0).epsilon(1e-13));

  const Chain<double> chain(masses, lengths);
  TraceWorkspace<double> ws(chain);
  const auto& node = node_traces(chain, phi.data(), ws);

  using Matrix = Eigen::Matrix3d;
  Matrix a, a_i[3];
  const std::vector<double> tail{2.75, 2.05, 2.0};
  for (int j = 0; j < 3; ++j) {
    for (int k = 0; k < 3; ++k) {
      a(j, k) = tail[std::max(j, k)] * lengths[j] * lengths[k] * std::cos(phi[j] - phi[k]);
    }
  }
  for (int i = 0; i < 3; ++i) {
    a_i[i].setZero();
    for (int j = 0; j <= i; ++j) {
      for (int k = 0; k <= i; ++k) {
        a_i[i](j, k) = masses[i] * lengths[j] * lengths[k] * std::cos(phi[j] - phi[k]);
      }
    }
  }
  const Eigen::LLT<Matrix> llt(a);
  const Matrix a_inv = a.inverse();
  std::mt19937_64 rng(42);
  std::normal_distribution<double> normal;
  const int samples = 200000;
  double sum1[3] = {}, sum2[3] = {}, sum4sq[3] = {}, sumc[3] = {}, sumc2[3] = {};
  for (int s = 0; s < samples; ++s) {
    const Eigen::Vector3d z(normal(rng), normal(rng), normal(rng));
    const Eigen::Vector3d p = llt.matrixL() * z;
    const Eigen::Vector3d rate = a_inv * p;  // phidot
    for (int i = 0; i < 3; ++i) {
      const double two_k = rate.dot(a_i[i] * rate);  // 2 K_i, eq. Ki-linear-dotvarphi-Ai
      const double two_kc = p(i) * rate(i);          // 2 K_i^(c), eq. ke-canonical-i
      sum1[i] += two_k;
      sum2[i] += two_k * two_k;
      sum4sq[i] += std::pow(two_k, 4);
      sumc[i] += two_kc;
      sumc2[i] += two_kc * two_kc;
    }
  }
  for (int i = 0; i < 3; ++i) {
    const double mean = sum1[i] / samples;
    const double se = std::sqrt((sum2[i] / samples - mean * mean) / samples);
    CHECK(std::abs(mean - node.trace_X[i]) < 5 * se);
    const double mean4 = sum2[i] / samples;
    const double se4 = std::sqrt((sum4sq[i] / samples - mean4 * mean4) / samples);
    const double t = node.trace_X[i], t2 = node.trace_X_squared[i];
    CHECK(std::abs(mean4 - (t * t + 2 * t2)) < 5 * se4);
    const double meanc = sumc[i] / samples;
    const double sec = std::sqrt((sumc2[i] / samples - meanc * meanc) / samples);
    CHECK(std::abs(meanc - 1.0) < 5 * sec);
  }
}

TEST_CASE("diagonal approximation (eq. ke-linear-tave-1)", "[trace]") {
  const Chain<double> unit({1.0, 1.0, 1.0}, {1.0, 1.0, 1.0});
  const auto approx = pendavg::diagonal_approximation(unit);
  REQUIRE(approx.size() == 3);
  CHECK(approx[0] == Approx(1.0 / 6.0).epsilon(1e-15));   // the paper's 0.167
  CHECK(approx[1] == Approx(0.5 * (1.0 / 3 + 1.0 / 2)).epsilon(1e-15));
  CHECK(approx[2] == Approx(0.5 * (1.0 / 3 + 1.0 / 2 + 1.0)).epsilon(1e-15));
  // N = 1: exact, beta <K_1> = 1/2.
  const Chain<double> single({2.5}, {0.3});
  CHECK(pendavg::diagonal_approximation(single)[0] == Approx(0.5).epsilon(1e-15));
}
