// SPDX-License-Identifier: GPL-3.0-or-later
// tests/engine/transfer/test_transfer.cpp -- the transfer operator along the chain
// (src/engine/transfer/chain_transfer.hpp, README "Large N"; method transfer of pendavg::average) against independent methods and exact
// identities:
//  * N = 3, 4 and 5 against the tensor torus (engine/torus/: psi-reduced relative angles,
//    node_traces at every node; it shares no code with the transfer operator), over unequal
//    masses, lengths, g and beta from 1e-3 to 1e4: |difference| within the sum of both errors;
//  * N = 2 against the 1-D reduced integral; N = 1 in closed form;
//  * N = 8, 16 and 64 against randomized lattice QMC (the independent check for long chains);
//  * the reported errors against the true errors over randomized chains, betas and tolerances
//    (reference: a finer resolution checked against a second one): coverage and tightness;
//  * identities: sum_i beta<K_i> = N/2; bitwise the same results for any thread count;
//  * hard cases by name: tiny masses, extreme length ratios, beta -> 0, large beta (to 1e12),
//    a long chain (N = 1024), and the automatic choice and option checks of average().
// Tags: [transfer] (default, a few seconds in Release), [transfer][.slow] for the long variants.
#include <catch2/catch.hpp>

#include "engine/transfer/chain_transfer.hpp"
#include "engine/double_pendulum/double_pendulum.hpp"
#include "engine/qmc/qmc.hpp"
#include "engine/torus/torus.hpp"
#include "pendavg/average.hpp"
#include "pendavg/chain.hpp"
#include "pendavg/result.hpp"
#include "chains.hpp"
#include "real_types.hpp"

#include <algorithm>
#include <map>
#include <cmath>
#include <random>
#include <string>
#include <utility>
#include <vector>

namespace {

using pendavg::Averages;
using pendavg::Chain;
using pendavg::chain_transfer_average;
using pendavg::chain_transfer_level;
using pendavg::Estimate;
using pendavg::TransferOptions;

using pendavg::test::uniform_chain;

TransferOptions with_tolerance(double tolerance, int threads = 1) {
  TransferOptions options;
  options.tolerance = tolerance;
  options.threads = threads;
  return options;
}

/// The three observables of particle i, by name.
struct Observable {
  const char* name;
  std::vector<Estimate<double>> Averages<double>::*field;
};
const Observable observables[] = {{"beta<K>", &Averages<double>::beta_kinetic},
                                  {"beta^2 Var K", &Averages<double>::beta2_kinetic_variance},
                                  {"<cos phi>", &Averages<double>::cos_angle}};

/// Compares every quantity of `a` with `ref`: returns {covered, total}, where covered counts the
/// quantities within the sum of both errors; every quantity must lie within `slack` times that.
std::pair<int, int> check_against(const Averages<double>& a, const Averages<double>& ref,
                                  const std::string& what, double slack) {
  int covered = 0, total = 0;
  for (const Observable& o : observables) {
    for (std::size_t i = 0; i < (a.*o.field).size(); ++i) {
      const Estimate<double>& x = (a.*o.field)[i];
      const Estimate<double>& r = (ref.*o.field)[i];
      const double d = std::abs(x.value - r.value);
      ++total;
      if (d <= x.error + r.error) ++covered;
      INFO(what << ", particle " << i + 1 << ", " << o.name << " " << x.value << " +- " << x.error
                << " vs " << r.value << " +- " << r.error << " (difference " << d << ")");
      CHECK(d <= slack * (x.error + r.error));
    }
  }
  return {covered, total};
}

double largest_error(const Averages<double>& a) {
  double e = 0;
  for (const Observable& o : observables)
    for (const Estimate<double>& x : a.*o.field) e = std::max(e, x.error);
  return e;
}

Averages<double> torus_reference(const Chain<double>& chain, double beta, double tolerance) {
  pendavg::TorusOptions options;
  options.tolerance = tolerance;
  options.threads = 2;
  return pendavg::torus_average(chain, beta, options);
}

struct Case {
  std::vector<double> masses, lengths;
  double g, beta;
  double tolerance = 1e-11;
};

}  // namespace

TEST_CASE("transfer N = 3, 4 agrees with the tensor torus", "[transfer]") {
  const std::vector<Case> cases = {
      {{1, 1, 1}, {1, 1, 1}, 1, 1e-3},
      {{1, 1, 1}, {1, 1, 1}, 1, 0.1},
      {{1, 1, 1}, {1, 1, 1}, 1, 1},
      {{1, 1, 1}, {1, 1, 1}, 1, 10},
      {{1, 1, 1}, {1, 1, 1}, 1, 100},
      {{1, 1, 1}, {1, 1, 1}, 1, 1e4},
      {{0.3, 1, 3}, {1, 0.7, 1.4}, 0.6, 2},
      {{3, 1, 0.3}, {0.5, 2, 1}, 2, 0.4},
      {{1, 2, 0.5, 3}, {0.5, 1, 2, 1}, 2.5, 0.05},
      {{1, 2, 0.5, 3}, {0.5, 1, 2, 1}, 2.5, 0.7},
      {{1, 2, 0.5, 3}, {0.5, 1, 2, 1}, 2.5, 30},
      {{100, 10, 1, 0.1}, {1, 1, 1, 1}, 1, 1},  // heavy to light: easy for the pivot recursion
      {{1, 1, 1, 1}, {1, 1, 1, 1}, 0, 1},       // g = 0: the beta -> 0 limit at any beta
      // light to heavy (the relative-angle links), masses over 1e-2 .. 1e2; relative 1e-8 (the
      // light particles' variances are ~1e-3 and their rounding budget ~1e-13):
      {{0.01, 1, 100}, {1, 1, 1}, 1, 1, 1e-8},
      {{0.01, 1, 100}, {1, 1, 1}, 1, 1e4, 1e-8},
      {{0.01, 100, 0.01}, {1, 1, 1}, 1, 1, 1e-8},
      {{0.24, 0.068, 70}, {1, 1, 1}, 1, 0.12, 1e-8},  // a heavy mass two links ahead
      {{1, 5, 1, 5}, {1, 1, 1, 1}, 1, 2, 1e-8},
  };
  int covered = 0, quantities = 0;
  for (const Case& c : cases) {
    const Chain<double> chain(c.masses, c.lengths, c.g);
    const auto ref = torus_reference(chain, c.beta, 1e-13);
    REQUIRE(ref.converged);
    const auto a = chain_transfer_average(chain, c.beta, with_tolerance(c.tolerance));
    const std::string what = "N = " + std::to_string(c.masses.size()) +
                             ", beta = " + std::to_string(c.beta) + ", m_1 = " +
                             std::to_string(c.masses[0]);
    INFO(what);
    CHECK(a.converged);
    CHECK(largest_error(a) <= 10 * c.tolerance);
    const auto [cov, total] = check_against(a, ref, what, 3);
    covered += cov;
    quantities += total;
  }
  INFO(covered << " of " << quantities << " quantities within the combined error bars");
  CHECK(covered >= 0.97 * quantities);
}

TEST_CASE("transfer N = 5 agrees with the tensor torus", "[transfer]") {
  // The torus at 1e-8 (n^4 nodes: ~1 s) checks the transfer operator at 1e-11.
  const Chain<double> chain({1.0, 0.7, 1.3, 0.9, 1.1}, {1.0, 0.8, 1.2, 1.0, 0.6}, 1.0);
  for (const double beta : {1.5}) {
    const auto ref = torus_reference(chain, beta, 1e-8);
    REQUIRE(ref.converged);
    const auto a = chain_transfer_average(chain, beta, with_tolerance(1e-11));
    CHECK(a.converged);
    const auto [covered, total] = check_against(a, ref, "N = 5, beta = " + std::to_string(beta), 1);
    CHECK(covered == total);
  }
}

TEST_CASE("transfer N = 5 to 1e-12 agrees with the tensor torus to 1e-11", "[transfer][.slow]") {
  for (const double beta : {0.2, 1.0, 8.0}) {
    const Chain<double> chain = beta == 1.0 ? uniform_chain(5)
                                            : Chain<double>({1.0, 0.7, 1.3, 0.9, 1.1},
                                                            {1.0, 0.8, 1.2, 1.0, 0.6}, 1.0);
    const auto ref = torus_reference(chain, beta, 1e-11);
    REQUIRE(ref.converged);
    const auto a = chain_transfer_average(chain, beta, with_tolerance(1e-12, 2));
    const auto [covered, total] = check_against(a, ref, "N = 5, beta = " + std::to_string(beta), 1);
    CHECK(covered == total);
  }
}

TEST_CASE("transfer N = 4 with masses 1e-2..1e2 agrees with the tensor torus",
          "[transfer][.slow]") {
  // The torus reference takes ~20 s here (relative angles clustered for two light particles).
  const Chain<double> chain({0.01, 100, 1, 0.01}, {1, 2, 0.5, 1}, 1.5);
  const auto ref = torus_reference(chain, 0.3, 1e-13);
  REQUIRE(ref.converged);
  const auto a = chain_transfer_average(chain, 0.3, with_tolerance(1e-9));
  CHECK(a.converged);
  const auto [covered, total] = check_against(a, ref, "m = (0.01, 100, 1, 0.01)", 3);
  CHECK(covered >= total - 1);
}

TEST_CASE("transfer N = 2 agrees with the 1-D reduced integral; N = 1 in closed form",
          "[transfer]") {
  for (const double beta : {0.01, 1.0, 50.0}) {
    const Chain<double> chain({1.0, 0.5}, {1.0, 2.0}, 1.0);
    const auto ref = pendavg::reduced_integral_average(chain, beta);
    const auto a = chain_transfer_average(chain, beta);
    CHECK(a.converged);
    const auto [covered, total] = check_against(a, ref, "N = 2, beta = " + std::to_string(beta), 1);
    CHECK(covered == total);
    REQUIRE(a.ratio.has_value());
    CHECK(std::abs(a.ratio->value - ref.ratio->value) <= a.ratio->error + ref.ratio->error);
  }
  // N = 1: tr X = 1 at every node, so beta<K> = 1/2, beta^2 Var K = (1 + 2)/4 - 1/4 = 1/2, and
  // <cos phi> = I1(alpha)/I0(alpha) (alpha = beta g m l = 2: 0.697774657964007982...).
  const Chain<double> one({1.0}, {2.0}, 1.0);
  const auto a = chain_transfer_average(one, 1.0);
  CHECK(a.beta_kinetic[0].value == Approx(0.5).margin(1e-15));
  CHECK(a.beta2_kinetic_variance[0].value == Approx(0.5).margin(1e-14));
  CHECK(std::abs(a.cos_angle[0].value - 0.697774657964007982) <= a.cos_angle[0].error + 1e-15);
  CHECK_FALSE(a.ratio.has_value());
}

TEST_CASE("transfer identities: equipartition sum, results independent of the thread count",
          "[transfer]") {
  // 0.5 -> 2.0 and 0.5 -> 1.1, 0.9 are links over the relative angle, the others product rules.
  const Chain<double> chain({1.0, 0.7, 1.3, 2.0, 0.5, 1.1, 0.9, 1.6, 0.8, 1.2},
                            {1.0, 1.2, 0.8, 1.0, 1.5, 0.6, 1.0, 1.1, 0.9, 1.0}, 1.3);
  const auto a = chain_transfer_average(chain, 0.8, with_tolerance(1e-9));
  double sum = 0, bars = 0;
  for (const auto& k : a.beta_kinetic) {
    sum += k.value;
    bars += k.error;
  }
  CHECK(a.converged);
  CHECK(std::abs(sum - 5.0) <= bars);
  CHECK(a.equipartition_residual == Approx(std::abs(sum - 5.0)).margin(1e-15));
  for (const auto& k : a.beta_kinetic_canonical) CHECK(k.value == 0.5);
  CHECK(a.diagonal_approximation == pendavg::diagonal_approximation(chain));
  // One level large enough to be split over two threads: bitwise the same numbers.
  const auto one = chain_transfer_level(chain, 0.8, 96, 24, 1);
  const auto two = chain_transfer_level(chain, 0.8, 96, 24, 2);
  for (std::size_t i = 0; i < chain.size(); ++i) {
    CHECK(one.beta_kinetic[i] == two.beta_kinetic[i]);
    CHECK(one.beta2_kinetic_variance[i] == two.beta2_kinetic_variance[i]);
    CHECK(one.cos_angle[i] == two.cos_angle[i]);
  }
  CHECK(one.kernel_evaluations == two.kernel_evaluations);
  // And through average(): 1, 2 and 3 threads give the same values and errors.
  pendavg::AverageOptions options;
  options.tolerance = 1e-10;
  const Chain<double> long_chain = uniform_chain(40, 1.0, 1.0, 1.0);
  const auto serial = pendavg::average(long_chain, 2.0, options);
  for (const int threads : {2, 3}) {
    options.threads = threads;
    const auto parallel = pendavg::average(long_chain, 2.0, options);
    for (const Observable& o : observables) {
      for (std::size_t i = 0; i < long_chain.size(); ++i) {
        CHECK((parallel.*o.field)[i] == (serial.*o.field)[i]);
      }
    }
    CHECK(parallel.evaluations == serial.evaluations);
  }
}

namespace {

/// Runs chain_transfer_average on `repetitions` random chains (N = 5..maxN, masses log-uniform
/// with neighbour ratios up to `mass_ratio`, lengths in [1/2, 2], g in [1/2, 2], beta
/// log-uniform in [1e-2, 1e3], tolerance log-uniform in [1e-9, 1e-4]); the reference is a finer
/// level that agrees with the next finer one to 1e-13. Counts the quantities whose reported error covers the
/// true error and, per repetition and observable, the ratio of the largest reported error to the
/// largest true error (tightness; only where the true error is above 1e-12, i.e. not rounding).
struct Coverage {
  int covered = 0, quantities = 0;
  int repetitions = 0, repetitions_covered = 0;  ///< repetitions with every quantity covered
  double worst_miss = 0;  ///< the largest true error / reported error over the misses
  std::vector<double> pessimism;  ///< per repetition and observable: max error / max true error
  double geometric_mean_pessimism() const {
    double s = 0;
    for (const double p : pessimism) s += std::log(p);
    return std::exp(s / static_cast<double>(pessimism.size()));
  }
  double arithmetic_mean_pessimism() const {
    double s = 0;
    for (const double p : pessimism) s += p;
    return s / static_cast<double>(pessimism.size());
  }
};

/// Random chains: N from 5 to max_particles (log-uniform), masses within a factor up to
/// mass_ratio of 1 either way, lengths within length_ratio, beta 1e-2..1e3, g 0.5..2, tolerance
/// 1e-9..1e-4; every quantity's reported error against the true error of a much finer level.
Coverage transfer_coverage(int repetitions, std::uint64_t seed, double max_particles,
                           double mass_ratio, double length_ratio = 2) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> unit(0, 1);
  Coverage out;
  for (int rep = 0; rep < repetitions; ++rep) {
    const auto n = static_cast<std::size_t>(
        std::lround(5 * std::exp(unit(rng) * std::log(max_particles / 5))));
    const double beta = std::pow(10.0, -2 + 5 * unit(rng));
    const double ratio = std::pow(mass_ratio, unit(rng));
    std::vector<double> m(n), l(n);
    for (double& x : m) x = std::exp((2 * unit(rng) - 1) * std::log(ratio));
    for (double& x : l) x = std::exp((2 * unit(rng) - 1) * std::log(length_ratio));
    const double g = 0.5 + 1.5 * unit(rng);
    const double tolerance = std::pow(10.0, -9 + 5 * unit(rng));
    const Chain<double> chain(m, l, g);
    const auto a = chain_transfer_average(chain, beta, with_tolerance(tolerance, 2));
    INFO("repetition " << rep << ": N = " << n << ", beta = " << beta << ", mass ratio "
                       << ratio << ", tolerance " << tolerance);
    CHECK(a.converged);
    REQUIRE(a.transfer.has_value());
    // The reference: levels from 24 angle nodes beyond the run's up (each ladder step of ~1.25x
    // gains 1e2..1e4), until two of them 16 nodes apart agree to 1e-13 (slowly converging
    // chains need more).
    const std::size_t pivot = pendavg::transfer_pivot_nodes(chain, 1e-15);
    std::size_t angle = a.transfer->angle_nodes + 24;
    auto ref = chain_transfer_level(chain, beta, angle, pivot, 2);
    for (;;) {
      const auto next = chain_transfer_level(chain, beta, angle + 16, pivot, 2);
      double change = 0;
      for (std::size_t i = 0; i < n; ++i) {
        change = std::max({change, std::abs(next.beta_kinetic[i] - ref.beta_kinetic[i]),
                           std::abs(next.beta2_kinetic_variance[i] - ref.beta2_kinetic_variance[i]),
                           std::abs(next.cos_angle[i] - ref.cos_angle[i])});
      }
      ref = next;
      angle += 16;
      if (change <= 1e-13) break;
      REQUIRE(angle <= 256);
    }
    const std::vector<double>* reference[] = {&ref.beta_kinetic, &ref.beta2_kinetic_variance,
                                              &ref.cos_angle};
    bool all = true;
    for (std::size_t q = 0; q < 3; ++q) {
      double largest_true = 0, largest_reported = 0;
      for (std::size_t i = 0; i < n; ++i) {
        const Estimate<double>& x = (a.*observables[q].field)[i];
        const double r = (*reference[q])[i];
        const double true_error = std::abs(x.value - r);
        ++out.quantities;
        if (true_error <= x.error) {
          ++out.covered;
        } else {
          all = false;
          out.worst_miss = std::max(out.worst_miss, true_error / x.error);
        }
        largest_true = std::max(largest_true, true_error);
        largest_reported = std::max(largest_reported, x.error);
      }
      if (largest_true > 1e-12) out.pessimism.push_back(largest_reported / largest_true);
    }
    ++out.repetitions;
    if (all) ++out.repetitions_covered;
  }
  return out;
}

/// The coverage targets (issue 13): every quantity covered in >= 95% of the repetitions, errors
/// not more than 10x pessimistic on average (arithmetic mean over repetitions and observables).
void check_coverage(const Coverage& c) {
  INFO(c.covered << " of " << c.quantities << " quantities covered; " << c.repetitions_covered
                 << " of " << c.repetitions << " repetitions fully covered; worst miss "
                 << c.worst_miss << "x; pessimism: arithmetic mean " << c.arithmetic_mean_pessimism()
                 << ", geometric mean " << c.geometric_mean_pessimism() << " over "
                 << c.pessimism.size());
  CHECK(c.repetitions_covered >= 0.95 * c.repetitions);
  CHECK(c.covered >= 0.99 * c.quantities);
  CHECK(c.arithmetic_mean_pessimism() <= 10);
  CHECK(c.worst_miss <= 2);
}

}  // namespace

TEST_CASE("transfer error estimates cover the true errors, and tightly (20 random chains)",
          "[transfer]") {
  check_coverage(transfer_coverage(20, 2024, 8, 10));
}

TEST_CASE("transfer error estimates cover the true errors in 100 random repetitions (N <= 32)",
          "[transfer][.slow]") {
  check_coverage(transfer_coverage(100, 13, 32, 10));
}

TEST_CASE("transfer error estimates cover the true errors on wide chains (masses 1e-2..1e2, "
          "lengths 0.1..10, N <= 64)",
          "[transfer][.slow]") {
  check_coverage(transfer_coverage(60, 7, 64, 100, 10));
}

namespace {

/// transfer at 1e-10 against qmc (2^log2_points x 16 shifts): every quantity within twice the
/// combined bars, and >= 95% within them (QMC's statistical bars from 16 shifts miss ~1% of the
/// quantities by chance, several at once since the particles share the shifts).
void check_against_qmc(std::size_t n, const std::vector<double>& betas, unsigned log2_points) {
  const Chain<double> chain = n == 8 ? Chain<double>({1.0, 0.5, 2.0, 0.8, 1.2, 1.0, 0.6, 1.5},
                                                     {1.0, 1.5, 0.7, 1.0, 0.9, 1.2, 1.0, 0.8})
                                     : uniform_chain(n);
  for (const double beta : betas) {
    pendavg::QmcOptions q;
    q.points = std::size_t(1) << log2_points;
    q.threads = 2;
    const auto ref = pendavg::qmc_average(chain, beta, q);
    const auto a = chain_transfer_average(chain, beta, with_tolerance(1e-10, 2));
    CHECK(a.converged);
    CHECK(largest_error(a) <= 1e-9);
    const auto [covered, total] = check_against(
        a, ref, "N = " + std::to_string(n) + ", beta = " + std::to_string(beta), 2);
    CHECK(covered >= 0.95 * total);
  }
}

}  // namespace

TEST_CASE("transfer N = 8, 16, 64 agrees with qmc within the combined bars", "[transfer]") {
  check_against_qmc(8, {0.1, 1.0, 10.0}, 13);
  check_against_qmc(16, {0.1, 1.0, 10.0}, 13);
  check_against_qmc(64, {1.0}, 12);
}

TEST_CASE("transfer N = 16, 64 agrees with qmc at 2^16 points", "[transfer][.slow]") {
  check_against_qmc(16, {0.1, 1.0, 10.0}, 16);
  check_against_qmc(64, {0.1, 1.0, 10.0}, 16);
}

TEST_CASE("transfer hard cases: tiny masses, extreme lengths, beta -> 0, large beta",
          "[transfer]") {
  SECTION("tiny masses (m -> 0 beside unit masses) against the torus") {
    for (const auto& masses : std::vector<std::vector<double>>{{1.0, 0.05, 1.0},
                                                               {1e-3, 1.0, 1.0},
                                                               {1.0, 1e-3, 1.0},
                                                               {1.0, 1.0, 1e-3},
                                                               {1.0, 1.0, 1e-6}}) {
      const Chain<double> chain(masses, {1.0, 1.0, 1.0}, 1.0);
      const auto ref = torus_reference(chain, 1.0, 1e-13);
      const auto a = chain_transfer_average(chain, 1.0, with_tolerance(1e-9));
      const auto [covered, total] = check_against(
          a, ref, "masses " + std::to_string(masses[0]) + ", " + std::to_string(masses[1]) + ", " +
                      std::to_string(masses[2]), 3);
      CHECK(covered >= total - 1);
      CHECK(a.converged);
    }
  }
  SECTION("extreme length ratios (alpha_j over 8 orders) against the torus") {
    for (const auto& lengths : std::vector<std::vector<double>>{{1e-4, 1.0, 1e4},
                                                                {1e4, 1.0, 1e-4},
                                                                {1.0, 1e-3, 1e3, 1.0}}) {
      const Chain<double> chain(std::vector<double>(lengths.size(), 1.0), lengths, 1.0);
      const auto ref = torus_reference(chain, 0.5, 1e-12);
      const auto a = chain_transfer_average(chain, 0.5, with_tolerance(1e-10));
      CHECK(a.converged);
      const auto [covered, total] = check_against(a, ref, "lengths " + std::to_string(lengths[0]), 1);
      CHECK(covered == total);
    }
  }
  SECTION("beta -> 0: the g = 0 chain, and the public limit") {
    const auto chain = uniform_chain(8);
    const auto a = chain_transfer_average(chain, 1e-8);
    const auto limit = pendavg::high_temperature_limit(chain);
    CHECK(limit.method == pendavg::Method::transfer);
    CHECK(a.converged);
    for (std::size_t i = 0; i < 8; ++i) {
      // beta<K_i>(beta) - beta<K_i>(0) = O(beta alpha) ~ 1e-8 * 8
      CHECK(std::abs(a.beta_kinetic[i].value - limit.beta_kinetic[i].value) < 1e-6);
      CHECK(std::abs(a.cos_angle[i].value) < 1e-6);
    }
  }
  SECTION("large beta: against the torus at 1e6, then the 1/beta approach to 1/2") {
    // (0.01, 1, 100) at beta = 1e6: every joint is stiff; the torus resolves it directly.
    const Chain<double> chain({0.01, 1.0, 100.0}, {1.0, 1.0, 1.0}, 1.0);
    pendavg::TorusOptions t;
    t.tolerance = 1e-12;
    const auto ref = pendavg::torus_average(chain, 1e6, t);
    REQUIRE(ref.converged);
    const auto a = chain_transfer_average(chain, 1e6, with_tolerance(1e-11));
    CHECK(a.converged);
    const auto [covered, total] = check_against(a, ref, "(0.01, 1, 100) at beta = 1e6", 1);
    CHECK(covered == total);
    // Unit chain N = 8 up to beta = 1e12: beta<K_i> - 1/2 = c_i / beta + O(beta^-2), so
    // beta (beta<K_i> - 1/2) settles; nothing overflows, errors stay ~1e-14.
    const auto eight = uniform_chain(8);
    const auto b9 = chain_transfer_average(eight, 1e9);
    const auto b12 = chain_transfer_average(eight, 1e12);
    CHECK(b9.converged);
    CHECK(b12.converged);
    for (std::size_t i = 0; i < 8; ++i) {
      const double c9 = 1e9 * (b9.beta_kinetic[i].value - 0.5);
      const double c12 = 1e12 * (b12.beta_kinetic[i].value - 0.5);
      CHECK(std::abs(c9) < 10);
      CHECK(std::abs(c12 - c9) <= 1e12 * b12.beta_kinetic[i].error + 1e9 * b9.beta_kinetic[i].error +
                                       1e-6);
      CHECK(b12.cos_angle[i].value <= 1);
      CHECK(b12.cos_angle[i].value > 1 - 1e-10);
    }
  }
  SECTION("beyond double's range: refused") {
    const Chain<double> chain({1.0, 1.0, 1.0, 1.0, 1.0}, {1.0, 1.0, 1.0, 1.0, 1e10}, 1.0);
    CHECK_THROWS_AS(chain_transfer_average(chain, 1e300), pendavg::invalid_input);
  }
}

namespace {

/// Unit masses and lengths (g = 1) with one particle of mass `light` at `position` (0-based).
Chain<double> light_chain(std::size_t n, std::size_t position, double light) {
  std::vector<double> masses(n, 1.0);
  masses[position] = light;
  return Chain<double>(masses, std::vector<double>(n, 1.0), 1.0);
}

/// Every quantity of `a` covers its true error (the difference from `ref`), and, per observable
/// where the largest true error is above `rounding`, the largest reported error is at most
/// `pessimism` times the largest true error. Both on the scales of the tolerance (beta<K_i>
/// relative to itself, beta^2 Var K_i relative to beta^2 <K_i^2>, <cos phi_i> absolute), so that
/// the light particle's beta<K> (~1e-8) counts as much as the others.
void check_light(const Averages<double>& a, const Averages<double>& ref, const std::string& what,
                 double pessimism, double rounding) {
  for (std::size_t q = 0; q < 3; ++q) {
    const Observable& o = observables[q];
    double largest_true = 0, largest_reported = 0;
    for (std::size_t i = 0; i < (a.*o.field).size(); ++i) {
      const Estimate<double>& x = (a.*o.field)[i];
      const Estimate<double>& r = (ref.*o.field)[i];
      const double k = ref.beta_kinetic[i].value;
      const double scale = q == 0 ? std::abs(k)
                           : q == 1 ? std::abs(ref.beta2_kinetic_variance[i].value) + k * k
                                    : 1.0;
      const double true_error = std::abs(x.value - r.value);
      INFO(what << ", particle " << i + 1 << ", " << o.name << " " << x.value << " +- " << x.error
                << " vs " << r.value << " +- " << r.error);
      CHECK(true_error <= x.error + r.error);
      largest_true = std::max(largest_true, std::max(0.0, true_error - r.error) / scale);
      largest_reported = std::max(largest_reported, x.error / scale);
    }
    INFO(what << ", " << o.name << ": largest relative reported error " << largest_reported
              << ", true " << largest_true);
    if (largest_true > rounding) CHECK(largest_reported <= pessimism * largest_true);
  }
}

/// A light particle of `mass` at `position` of a 3-particle chain against the torus at 1e-13:
/// covered at tol 1e-11, and at tol 1e-5 (where the true errors stand above the rounding) each
/// observable's reported error within 10x of the true one.
void check_light_against_torus(std::size_t position, double mass, const std::string& label) {
  const Chain<double> chain = light_chain(3, position, mass);
  const auto ref = torus_reference(chain, 1.0, 1e-13);
  REQUIRE(ref.converged);
  const std::string what = label + " at particle " + std::to_string(position + 1);
  const auto a = chain_transfer_average(chain, 1.0, with_tolerance(1e-11));
  CHECK(a.converged);
  check_light(a, ref, what + ", tol 1e-11", 1e300, 0);
  const auto loose = chain_transfer_average(chain, 1.0, with_tolerance(1e-5));
  CHECK(loose.converged);
  check_light(loose, ref, what + ", tol 1e-5", 10, 1e-12);
}

}  // namespace

TEST_CASE("transfer: a very light particle (1e-8) at the root, inside and at the tail agrees "
          "with the torus; its errors cover and are within 10x",
          "[transfer]") {
  // The torus maps its relative-angle nodes to the light particle's kink (CircleRule, NodeMap)
  // and evaluates the traces without cancellation (trace_formula.hpp): an independent check.
  for (std::size_t position = 0; position < 3; ++position)
    check_light_against_torus(position, 1e-8, "1e-8");
}

TEST_CASE("transfer: a particle of mass 1e-12 at the tail approaches the double pendulum; "
          "at the root and inside of N = 5 it converges, beta 1e-3 and 1e3",
          "[transfer]") {
  // As m_3 -> 0 the last particle drops out of the weight (sqrt(det A) ~ sqrt(m_3 (1 + u_3)),
  // u_3 <= m_3/m_2): particles 1 and 2 are the double pendulum up to O(m_3), and the light one
  // moves freely across its link: beta<K_3> = 1/2 + O(m_3), beta^2 Var K_3 = 1/2 + O(m_3).
  const auto a = chain_transfer_average(light_chain(3, 2, 1e-12), 1.0, with_tolerance(1e-12));
  CHECK(a.converged);
  const auto pair = pendavg::reduced_integral_average(Chain<double>({1.0, 1.0}, {1.0, 1.0}, 1.0),
                                                      1.0);
  for (std::size_t i = 0; i < 2; ++i) {
    INFO("particle " << i + 1);
    CHECK(std::abs(a.beta_kinetic[i].value - pair.beta_kinetic[i].value) <=
          a.beta_kinetic[i].error + pair.beta_kinetic[i].error + 1e-11);
    CHECK(std::abs(a.beta2_kinetic_variance[i].value - pair.beta2_kinetic_variance[i].value) <=
          a.beta2_kinetic_variance[i].error + pair.beta2_kinetic_variance[i].error + 1e-11);
    CHECK(std::abs(a.cos_angle[i].value - pair.cos_angle[i].value) <=
          a.cos_angle[i].error + pair.cos_angle[i].error + 1e-11);
  }
  CHECK(std::abs(a.beta_kinetic[2].value - 0.5) <= a.beta_kinetic[2].error + 1e-11);
  CHECK(std::abs(a.beta2_kinetic_variance[2].value - 0.5) <=
        a.beta2_kinetic_variance[2].error + 1e-11);
  // Root and interior, N = 5, beta 1e-3 and 1e3: converged, the light particle's beta<K> (tr X_j
  // ~ m_j / (m_j + S sin^2 delta) over the kink: 1e-11 .. 1e-5 here) known to the tolerance
  // relative to itself, and the equipartition sum within the bars.
  for (const std::size_t position : {std::size_t(0), std::size_t(2)}) {
    for (const double beta : {1e-3, 1e3}) {
      const auto b = chain_transfer_average(light_chain(5, position, 1e-12), beta,
                                            with_tolerance(1e-10));
      INFO("particle " << position + 1 << ", beta " << beta << ": beta<K> "
                       << b.beta_kinetic[position].value << " +- "
                       << b.beta_kinetic[position].error);
      CHECK(b.converged);
      CHECK(b.beta_kinetic[position].value > 0);
      CHECK(b.beta_kinetic[position].error <= 1e-10 * b.beta_kinetic[position].value);
      double sum = 0, bars = 0;
      for (const auto& k : b.beta_kinetic) {
        sum += k.value;
        bars += k.error;
      }
      CHECK(std::abs(sum - 2.5) <= bars + 1e-14);
    }
  }
}

TEST_CASE("transfer: a very light particle (1e-12) at the root and inside agrees with the torus",
          "[transfer][.slow]") {
  for (const std::size_t position : {std::size_t(0), std::size_t(1)})
    check_light_against_torus(position, 1e-12, "1e-12");
}

TEST_CASE("transfer: a very light particle in N = 16, 64 agrees with qmc", "[transfer][.slow]") {
  for (const std::size_t n : {std::size_t(16), std::size_t(64)}) {
    for (const std::size_t position : {std::size_t(0), n / 2, n - 1}) {
      const Chain<double> chain = light_chain(n, position, 1e-8);
      pendavg::QmcOptions q;
      q.points = std::size_t(1) << 14;
      q.threads = 2;
      const auto ref = pendavg::qmc_average(chain, 1.0, q);
      const auto a = chain_transfer_average(chain, 1.0, with_tolerance(1e-10, 2));
      CHECK(a.converged);
      const auto [covered, total] = check_against(
          a, ref, "N = " + std::to_string(n) + ", 1e-8 at " + std::to_string(position + 1), 2);
      CHECK(covered >= 0.95 * total);
    }
  }
}

TEST_CASE("transfer N = 1024: finite, the identity, and the tail particle", "[transfer]") {
  const auto chain = uniform_chain(1024);
  const auto r = chain_transfer_level(chain, 1.0, 24, pendavg::transfer_pivot_nodes(chain, 1e-5), 2);
  double sum = 0;
  for (std::size_t i = 0; i < 1024; ++i) {
    CHECK(std::isfinite(r.beta_kinetic[i]));
    CHECK(std::isfinite(r.beta2_kinetic_variance[i]));
    sum += r.beta_kinetic[i];
  }
  CHECK(std::abs(sum - 512) < 1e-2);
}

TEST_CASE("transfer N = 1024 to 1e-8 through average()", "[transfer][.slow]") {
  pendavg::AverageOptions options;
  options.tolerance = 1e-8;
  options.threads = 2;
  const auto a = pendavg::average(uniform_chain(1024), 1.0, options);
  CHECK(a.method == pendavg::Method::transfer);
  CHECK(a.converged);
  CHECK(largest_error(a) <= 1e-8);
  double sum = 0, bars = 0;
  for (const auto& k : a.beta_kinetic) {
    sum += k.value;
    bars += k.error;
  }
  CHECK(std::abs(sum - 512) <= bars);
  // Far from the root a long unit chain looks the same at every N: its last particle's value
  // agrees with N = 64 (1e-11 there) to well within the bars (the root's influence decays
  // geometrically along the chain).
  const auto short_chain = pendavg::average(uniform_chain(64), 1.0, options);
  CHECK(std::abs(a.beta_kinetic.back().value - short_chain.beta_kinetic.back().value) <=
        a.beta_kinetic.back().error + short_chain.beta_kinetic.back().error);
}

namespace {

/// The torus in long double at 450 epsilon, computed once for both types.
const Averages<long double>& long_double_torus(const std::string& name, const Chain<double>& chain,
                                              double beta) {
  static std::map<std::string, Averages<long double>> references;
  if (!references.count(name)) {
    pendavg::TorusOptions options;
    options.tolerance = 450 * pendavg::test::unit<long double>();
    options.threads = 2;
    references[name] = pendavg::torus_average(chain.cast<long double>(),
                                              static_cast<long double>(beta), options);
  }
  return references.at(name);
}

}  // namespace

namespace {

struct NamedChain {
  const char* name;
  std::vector<double> masses, lengths;
  double g, beta;
};

/// The transfer operator in Real at a tolerance scaled to the type's epsilon (45000 epsilon:
/// 1e-11 in double, 5e-15 in long double) against the torus (an independent method) in long
/// double at 450 epsilon: the bars cover, and are within 10 times the tolerance.
template <class Real>
void check_against_long_double_torus(const std::vector<NamedChain>& cases) {
  const double tolerance = 45000 * pendavg::test::unit<Real>();
  for (const NamedChain& c : cases) {
    const Chain<double> chain(c.masses, c.lengths, c.g);
    const Averages<long double>& ref = long_double_torus(c.name, chain, c.beta);
    REQUIRE(ref.converged);
    const auto a = chain_transfer_average(chain.cast<Real>(), Real(c.beta), with_tolerance(tolerance));
    INFO(c.name << " (tolerance " << tolerance << ")");
    CHECK(a.converged);
    const auto field = [](const auto& averages, int q) -> const auto& {
      return q == 0 ? averages.beta_kinetic
                    : q == 1 ? averages.beta2_kinetic_variance : averages.cos_angle;
    };
    for (int q = 0; q < 3; ++q) {
      for (std::size_t i = 0; i < c.masses.size(); ++i) {
        const auto& x = field(a, q)[i];
        const auto& r = field(ref, q)[i];
        const long double d = std::abs(static_cast<long double>(x.value) - r.value);
        INFO(observables[q].name << " of particle " << i + 1 << ": "
                                 << static_cast<double>(x.value) << " +- "
                                 << static_cast<double>(x.error) << " against "
                                 << static_cast<double>(r.value) << " +- "
                                 << static_cast<double>(r.error));
        CHECK(d <= static_cast<long double>(x.error) + r.error);
        CHECK(static_cast<double>(x.error) <= 10 * tolerance);
      }
    }
  }
}

}  // namespace

// The transfer operator is generic over double and long double: both against the long double
// torus, the hard cases by name.
TEMPLATE_TEST_CASE("transfer hard cases in double and long double against the long double torus",
                   "[transfer]", double, long double) {
  check_against_long_double_torus<TestType>(
      {{"beta -> 0", {1, 1, 1}, {1, 1, 1}, 1, 1e-3},
       {"large beta", {1, 1, 1}, {1, 1, 1}, 1, 100},
       {"a light particle at the tail", {1, 1, 1e-3}, {1, 1, 1}, 1, 1},
       {"extreme lengths", {1, 1, 1}, {1e-4, 1, 1e4}, 1, 0.5}});
}

// Unequal masses at moderate beta take the long double operator ~10 s to 5e-15.
TEMPLATE_TEST_CASE("transfer N = 3 and 4 in double and long double against the long double torus",
                   "[transfer][.slow]", double, long double) {
  check_against_long_double_torus<TestType>(
      {{"unequal masses", {0.3, 1, 3}, {1, 0.7, 1.4}, 0.6, 2},
       {"N = 4", {1, 2, 0.5, 3}, {0.5, 1, 2, 1}, 2.5, 0.7}});
}

TEST_CASE("transfer through average(): automatic for N >= 5, options checked", "[transfer][api]") {
  const auto chain = uniform_chain(6);
  const auto a = pendavg::average(chain, 1.0);
  CHECK(a.method == pendavg::Method::transfer);
  CHECK(a.error_kind == pendavg::ErrorKind::estimate);
  CHECK(a.converged);
  REQUIRE(a.transfer.has_value());
  CHECK(largest_error(a) <= 1e-10);
  CHECK(a.evaluations == static_cast<std::size_t>(a.transfer->kernel_evaluations));
  pendavg::AverageOptions loose;
  loose.tolerance = 1e-5;
  const auto b = pendavg::average(chain, 1.0, loose);
  CHECK(b.evaluations < a.evaluations);
  for (std::size_t i = 0; i < 6; ++i)
    CHECK(std::abs(a.beta_kinetic[i].value - b.beta_kinetic[i].value) <=
          a.beta_kinetic[i].error + b.beta_kinetic[i].error);
  pendavg::AverageOptions bad;
  bad.samples = 4096;  // a qmc option
  CHECK_THROWS_AS(pendavg::average(chain, 1.0, bad), pendavg::invalid_input);
  CHECK_THROWS_AS(chain_transfer_average(chain, 0.0), pendavg::invalid_input);
  CHECK_THROWS_AS(chain_transfer_average(chain, -1.0), pendavg::invalid_input);
  CHECK_THROWS_AS(chain_transfer_average(chain, std::nan("")), pendavg::invalid_input);
  TransferOptions wrong;
  wrong.tolerance = 0;
  CHECK_THROWS_AS(chain_transfer_average(chain, 1.0, wrong), pendavg::invalid_input);
  wrong = {};
  wrong.angle_nodes = 7;
  CHECK_THROWS_AS(chain_transfer_average(chain, 1.0, wrong), pendavg::invalid_input);
  CHECK_THROWS_AS(chain_transfer_level(chain, 1.0, 6, 2), pendavg::invalid_input);
  CHECK_THROWS_AS(chain_transfer_level(chain, 1.0, 5, 8), pendavg::invalid_input);
  // Pivot nodes held at a cap below what the ladder asks for: honestly not converged.
  TransferOptions capped = with_tolerance(1e-10);
  capped.max_pivot_nodes = 8;
  CHECK_FALSE(chain_transfer_average(chain, 1.0, capped).converged);
  // The angle nodes capped before the tolerance is reached: not converged either.
  TransferOptions coarse = with_tolerance(1e-12);
  coarse.max_angle_nodes = 24;
  CHECK_FALSE(chain_transfer_average(chain, 1.0, coarse).converged);
}
