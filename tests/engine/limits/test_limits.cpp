// SPDX-License-Identifier: GPL-3.0-or-later
// tests/engine/limits/test_limits.cpp -- the beta -> 0 and beta -> infinity limits for any N
// (src/engine/limits/): N = 2 against the paper's elliptic K/E formula (an independent method),
// N = 3 approached by the finite-beta torus, N = 8 (the qmc branch) within its bars of the
// identity sum_i beta<K_i> = N/2.
#include <catch2/catch.hpp>

#include "pendavg/chain.hpp"
#include "pendavg/result.hpp"
#include "engine/double_pendulum/double_pendulum.hpp"
#include "engine/limits/limits.hpp"
#include "engine/torus/torus.hpp"
#include "oracle/dense_traces.hpp"
#include "real_types.hpp"

#include <cmath>
#include <cstddef>
#include <vector>

using pendavg::mpfr_real;

TEST_CASE("limits for any N: beta -> 0 and beta -> infinity", "[torus][limits]") {
  using pendavg::Chain;
  // N = 2: the torus limit reproduces the paper's elliptic K/E formula (an independent method).
  const Chain<double> pair({0.3, 0.7}, {1.0, 2.0}, 1.0);
  const pendavg::Averages<double> elliptic = pendavg::elliptic_high_temperature_limit(pair, 16);
  const pendavg::Averages<double> any2 = pendavg::high_temperature_limit_any(pair);
  for (std::size_t i = 0; i < 2; ++i) {
    CHECK(std::abs(any2.beta_kinetic[i].value - elliptic.beta_kinetic[i].value) <=
          any2.beta_kinetic[i].error + elliptic.beta_kinetic[i].error + 1e-15);
    CHECK(std::abs(any2.beta2_kinetic_variance[i].value - elliptic.beta2_kinetic_variance[i].value) <= 1e-12);
    CHECK(any2.cos_angle[i].value == 0.0);
  }
  const pendavg::Averages<double> low2 = pendavg::low_temperature_limit_any(pair);
  const pendavg::Averages<double> low2_ref = pendavg::low_temperature_limit(pair);
  for (std::size_t i = 0; i < 2; ++i) {
    CHECK(low2.beta_kinetic[i].value == 0.5);
    CHECK(std::abs(low2.beta2_kinetic_variance[i].value - low2_ref.beta2_kinetic_variance[i].value) <= 1e-15);
  }
  // N = 3 with unequal masses and lengths: the limits are approached by the finite-beta torus.
  const Chain<double> chain({1.0, 0.4, 2.0}, {1.0, 0.6, 1.3}, 1.0);
  const pendavg::Averages<double> high = pendavg::high_temperature_limit_any(chain);
  const pendavg::Averages<double> hot = pendavg::torus_average(chain, 1e-9);
  const pendavg::Averages<double> low = pendavg::low_temperature_limit_any(chain);
  pendavg::TorusOptions cold_options;
  cold_options.tolerance = 1e-10;
  const pendavg::Averages<double> cold = pendavg::torus_average(chain, 1e4, cold_options);
  double sum = 0;
  for (std::size_t i = 0; i < 3; ++i) {
    sum += high.beta_kinetic[i].value;
    CHECK(std::abs(high.beta_kinetic[i].value - hot.beta_kinetic[i].value) <= 1e-8);  // O(beta) corrections
    CHECK(std::abs(high.beta2_kinetic_variance[i].value - hot.beta2_kinetic_variance[i].value) <= 1e-8);
    CHECK(std::abs(hot.cos_angle[i].value) <= 1e-8);
    // beta = 1e4: the corrections are O(1/beta) ~ 1e-4.
    CHECK(std::abs(cold.beta_kinetic[i].value - low.beta_kinetic[i].value) <= 1e-3);
    CHECK(std::abs(cold.beta2_kinetic_variance[i].value - low.beta2_kinetic_variance[i].value) <= 1e-3);
    CHECK(std::abs(cold.cos_angle[i].value - 1) <= 1e-3);
  }
  CHECK(std::abs(sum - 1.5) <= 1e-13);  // sum_i beta<K_i> = N/2 holds in the limit too
  // N = 8: the QMC branch, within its bars of the identity sum = N/2.
  const Chain<double> eight(std::vector<double>(8, 1.0), std::vector<double>(8, 1.0), 1.0);
  const pendavg::Averages<double> high8 = pendavg::high_temperature_limit_any(eight);
  CHECK(high8.method == pendavg::Method::qmc);
  double sum8 = 0, bars8 = 0;
  for (std::size_t i = 0; i < 8; ++i) {
    sum8 += high8.beta_kinetic[i].value;
    bars8 += high8.beta_kinetic[i].error;
  }
  CHECK(std::abs(sum8 - 4) <= bars8);
}

namespace {

/// Torus options for a number type: the tolerance at 450 units of its precision (in double
/// 1e-13, the default), MPFR at test_digits.
template <class Real>
pendavg::TorusOptions typed_options() {
  pendavg::TorusOptions options;
  if constexpr (pendavg::is_mpfr_v<Real>) {
    options.digits = pendavg::test::test_digits;
  } else {
    options.tolerance = 450 * pendavg::test::unit<Real>();
  }
  return options;
}

}  // namespace

// Generic over the number type (double, long double, MPFR at test_digits). beta -> 0: the any-N
// limit (the torus at g = 0) against the elliptic K/E formula at reference_digits, including
// mu1 -> 0 and extreme lengths; beta -> infinity: tr X_i(0)^2 / 2 against the dense oracle.
TEMPLATE_TEST_CASE("limits for any N in every number type against independent references",
                   "[torus][limits]", double, long double, mpfr_real) {
  using Real = TestType;
  using namespace pendavg::test;
  using pendavg::Chain;
  struct Case {
    const char* name;
    double m1, m2, l1, l2;
  };
  for (const Case c : {Case{"moderate", 0.3, 0.7, 1.0, 2.0}, Case{"mu1 -> 0", 1e-6, 1.0, 1.0, 1.0},
                       Case{"long lower link", 1.0, 1.0, 1.0, 1e3}}) {
    const Chain<double> pair({c.m1, c.m2}, {c.l1, c.l2}, 1.0);
    pendavg::Averages<mpfr_real> elliptic;
    {
      const ReferencePrecision wide;
      elliptic = pendavg::elliptic_high_temperature_limit(pair.cast<mpfr_real>(), reference_digits);
    }
    const TypePrecision<Real> precision;
    const pendavg::Averages<Real> any2 =
        pendavg::high_temperature_limit_any(pair.cast<Real>(), typed_options<Real>());
    for (std::size_t i = 0; i < 2; ++i) {
      INFO(c.name << ", particle " << i + 1 << ": " << as_double(any2.beta_kinetic[i].value)
                  << " +- " << as_double(any2.beta_kinetic[i].error) << ", off by "
                  << relative_distance(any2.beta_kinetic[i].value, elliptic.beta_kinetic[i].value) /
                         unit<Real>()
                  << " units");
      CHECK(distance(any2.beta_kinetic[i].value, elliptic.beta_kinetic[i].value) <=
            as_double(any2.beta_kinetic[i].error));
      CHECK(relative_distance(any2.beta_kinetic[i].value, elliptic.beta_kinetic[i].value) <=
            450 * unit<Real>());
      CHECK(distance(any2.beta2_kinetic_variance[i].value,
                     elliptic.beta2_kinetic_variance[i].value) <=
            as_double(any2.beta2_kinetic_variance[i].error));
      CHECK(any2.cos_angle[i].value == 0);
    }
  }
  // beta -> infinity: 1/2, 1 and tr X_i(0)^2 / 2 (dense oracle at 50 digits), N = 2 and 3.
  for (const Chain<double>& chain : {Chain<double>({0.1, 0.9}, {2.0, 0.5}, 1.0),
                                     Chain<double>({1.0, 0.4, 2.0}, {1.0, 0.6, 1.3}, 1.0),
                                     Chain<double>({1e-6, 1.0, 1.0}, {1.0, 1e3, 1.0}, 1.0)}) {
    const std::size_t n = chain.size();
    pendavg::oracle::DenseTraces<mpfr_real> dense;
    {
      const pendavg::working_precision guard(50);
      const auto as_mpfr = [](const std::vector<double>& v) {
        return std::vector<mpfr_real>(v.begin(), v.end());
      };
      dense = pendavg::oracle::dense_traces(as_mpfr(chain.masses()), as_mpfr(chain.lengths()),
                                            std::vector<mpfr_real>(n, mpfr_real(0)));
    }
    const TypePrecision<Real> precision;
    const pendavg::Averages<Real> low = pendavg::low_temperature_limit_any(chain.cast<Real>());
    for (std::size_t i = 0; i < n; ++i) {
      INFO("N = " << n << ", m1 = " << chain.mass(0) << ", particle " << i + 1);
      CHECK(low.beta_kinetic[i].value == Real(1) / 2);
      CHECK(low.cos_angle[i].value == 1);
      const pendavg::working_precision guard(50);
      const mpfr_real variance = dense.trace_X_squared[i] / 2;
      CHECK(relative_distance(low.beta2_kinetic_variance[i].value, variance) <= 16 * unit<Real>());
      CHECK(distance(low.beta2_kinetic_variance[i].value, variance) <=
            as_double(low.beta2_kinetic_variance[i].error));
    }
  }
}
