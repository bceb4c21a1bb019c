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

#include <cmath>
#include <cstddef>
#include <vector>

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
