// SPDX-License-Identifier: GPL-3.0-or-later
// tests/engine/torus/test_torus.cpp -- the any-N torus quadrature (src/engine/torus/; the
// identities of src/engine/README.md) against independent methods and exact identities:
//  * N = 2 against the library's 1-D reduced integral (double_pendulum.hpp), which shares none of
//    the torus code (Graf sums or sinh-mapped Clenshaw-Curtis over t = phi2 - phi1), over betas,
//    masses and lengths; and g = 0 against the public beta -> 0 limit (elliptic K/E);
//  * the same in double, long double and MPFR against the reduced integral at reference_digits,
//    with the hard cases by name;
//  * N = 3 against the public reference row of tests/data/public_values.csv, to the digits given;
//  * the psi reduction of src/engine/README.md, 'Reduction' against a brute-force trapezoid over
//    all N angles with the plain Boltzmann factor exp(sum_j alpha_j cos phi_j) and plain cos phi_j;
//  * trapezoid against Gauss-Legendre, each number type against a higher-precision run;
//  * identities: sum_i beta<K_i> = N/2, beta<K_i^(c)> = 1/2, N = 1 in closed form;
//  * the reported errors against true errors, including a run stopped before the peak at
//    large beta is resolved (converged = false must come with an error bar that covers);
//  * src/engine/README.md, 'Diagonal approximation': N = 3, beta = 0.1, beta<K_1> = 0.3114096682
//    against the diagonal 1/6;
//  * the work: mirror-halved node counts, determinism across thread counts, the n^(N-1) guard.
// qmc: tests/engine/qmc/test_qmc.cpp; the limits: tests/engine/limits/test_limits.cpp.
// Tags: [torus] (default, ~2 s in Release), [torus][.slow] for the longer variants.
#include <catch2/catch.hpp>

#include <array>

#include "pendavg/chain.hpp"
#include "engine/double_pendulum/double_pendulum.hpp"
#include "engine/numerics/precision.hpp"
#include "chains.hpp"
#include "real_types.hpp"
#include "pendavg/result.hpp"
#include "engine/torus/torus.hpp"
#include "engine/transfer/chain_transfer.hpp"
#include "pendavg/trace_formula.hpp"

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#ifndef PENDAVG_TEST_DATA_DIR
#error "PENDAVG_TEST_DATA_DIR must name the tests/data directory"
#endif

namespace {

using pendavg::Chain;
using pendavg::mpfr_real;
using pendavg::torus_average;
using pendavg::TorusOptions;
using pendavg::TorusRule;

using pendavg::test::uniform_chain;

/// |a - b| <= both reported errors (each method's estimate must cover the difference) and
/// <= rel * scale (the target accuracy).
void check_close(double a, double a_err, double b, double b_err, double scale, double rel,
                 const std::string& what) {
  INFO(what << ": " << a << " +- " << a_err << " vs " << b << " +- " << b_err);
  CHECK(std::abs(a - b) <= a_err + b_err);
  CHECK(std::abs(a - b) <= rel * scale);
}

/// The N = 3 row of the public reference file: three beta<K_i> as text.
std::vector<std::string> public_n3_values() {
  std::ifstream in(std::string(PENDAVG_TEST_DATA_DIR) + "/public_values.csv");
  REQUIRE(in.good());
  std::string line;
  while (std::getline(in, line)) {
    if (line.rfind("3,1 1 1,1 1 1,1,1,", 0) != 0) continue;
    const std::string values = line.substr(line.rfind(',') + 1);
    std::istringstream words(values);
    std::vector<std::string> out;
    for (std::string w; words >> w;) out.push_back(w);
    return out;
  }
  FAIL("no N = 3 row in public_values.csv");
  return {};
}

/// Brute force over all N angles (no psi reduction): an n-point trapezoid per angle on the
/// plain weight sqrt(det A) exp(sum_j alpha_j cos phi_j), with node_traces at absolute angles.
struct BruteForce {
  std::vector<double> beta_kinetic, cos_angle;
};
BruteForce brute_force_torus(const Chain<double>& chain, double beta, std::size_t n) {
  const std::size_t np = chain.size();
  pendavg::TraceWorkspace<double> ws(chain);
  std::vector<double> phi(np), alpha(np);
  for (std::size_t j = 0; j < np; ++j) alpha[j] = beta * chain.potential_coefficient(j);
  double alpha_sum = 0;
  for (double a : alpha) alpha_sum += a;
  std::vector<double> sum_trace(np, 0), sum_cos(np, 0);
  double sum_w = 0;
  std::vector<std::size_t> index(np, 0);
  const double h = 2 * M_PI / static_cast<double>(n);
  for (;;) {
    double exponent = -alpha_sum;
    for (std::size_t j = 0; j < np; ++j) {
      phi[j] = h * static_cast<double>(index[j]);
      exponent += alpha[j] * std::cos(phi[j]);
    }
    const auto& t = pendavg::node_traces(chain, phi.data(), ws);
    const double w = std::exp(t.log_sqrt_det_A + exponent);
    sum_w += w;
    for (std::size_t j = 0; j < np; ++j) {
      sum_trace[j] += w * t.trace_X[j];
      sum_cos[j] += w * std::cos(phi[j]);
    }
    std::size_t d = 0;
    while (d < np && ++index[d] == n) index[d++] = 0;
    if (d == np) break;
  }
  BruteForce out;
  for (std::size_t j = 0; j < np; ++j) {
    out.beta_kinetic.push_back(sum_trace[j] / (2 * sum_w));
    out.cos_angle.push_back(sum_cos[j] / sum_w);
  }
  return out;
}

}  // namespace

TEST_CASE("torus N = 2 agrees with the 1-D reduced integral", "[torus]") {
  struct Params {
    double m1, m2, l1, l2, g;
  };
  const std::vector<Params> chains = {
      {1, 1, 1, 1, 1},      {0.3, 2, 0.5, 2, 1},   {5, 0.7, 2, 0.3, 9.81},
      {0.05, 0.95, 1, 1, 1}, {1, 1e-3, 2, 0.3, 1}, {2, 3, 1.5, 0.25, 2},
  };
  for (const auto& p : chains) {
    for (double beta : {0.01, 0.3, 1.0, 3.0, 10.0, 30.0}) {
      const Chain<double> chain({p.m1, p.m2}, {p.l1, p.l2}, p.g);
      const auto torus = torus_average(chain, beta);
      const auto ref = pendavg::reduced_integral_average(chain, beta);
      INFO("m = (" << p.m1 << ", " << p.m2 << "), l = (" << p.l1 << ", " << p.l2 << "), g = " << p.g
                   << ", beta = " << beta);
      REQUIRE(torus.converged);
      for (std::size_t i = 0; i < 2; ++i) {
        check_close(torus.beta_kinetic[i].value, torus.beta_kinetic[i].error, ref.beta_kinetic[i].value,
                    ref.beta_kinetic[i].error, ref.beta_kinetic[i].value, 1e-13, "beta<K>");
        check_close(torus.beta2_kinetic_variance[i].value, torus.beta2_kinetic_variance[i].error,
                    ref.beta2_kinetic_variance[i].value, ref.beta2_kinetic_variance[i].error,
                    ref.beta2_kinetic_variance[i].value, 1e-13, "beta^2 Var K");
        // <cos phi> -> alpha/2 as beta -> 0: compare relative to its size, floor 1e-3.
        check_close(torus.cos_angle[i].value, torus.cos_angle[i].error, ref.cos_angle[i].value,
                    ref.cos_angle[i].error, std::max(std::abs(ref.cos_angle[i].value), 1e-3), 1e-13,
                    "<cos phi>");
      }
      check_close(torus.ratio->value, torus.ratio->error, ref.ratio->value, ref.ratio->error, ref.ratio->value, 1e-13,
                  "<K1>/<K2>");
      // The error bars are honest but not wildly loose.
      CHECK(torus.beta_kinetic[0].error < 2e-14);
    }
  }
}

// Found by an extreme-input audit (2026-11-26): a light particle's traces vary on
// sin^2 delta ~ m_1 / S_2, at delta = 0 and at delta = pi. Near pi the rules took the sine from
// the rounded angle (an error u pi, relative u pi / eps), and Gauss-Legendre's nodes near angle 0
// came from 1 + x with x rounded: the light particle's average was off by up to ~1e-12 relative,
// 165 times the reported error at m1 = 1e-12, g = 0 (trapezoid, converged), 2.5 times with
// Gauss-Legendre at m1 = 1e-8. Both rules against the MPFR reduced integral at 30 digits (code
// shared with neither): the reported errors must cover.
TEST_CASE("torus: light particles, errors cover near delta = 0 and pi (both rules)", "[torus]") {
  struct Case {
    double m1, l2, beta, g;
  };
  for (const Case c : {Case{1e-8, 1, 1e4, 0}, Case{1e-10, 1, 1, 0}, Case{1e-12, 1, 1, 0},
                       Case{1e-12, 1e3, 1, 0}, Case{1e-13, 1e-3, 1, 0}, Case{1e-8, 1e8, 1, 1},
                       Case{1e-15, 1, 1e4, 1}, Case{1e-8, 1, 1, 1}, Case{1e-11, 1, 0.1, 1}}) {
    const Chain<double> chain({c.m1, 1.0}, {1.0, c.l2}, c.g);
    std::array<double, 2> reference{};
    {
      const pendavg::working_precision wp(30 + pendavg::guard_digits);
      const auto exact =
          pendavg::reduced_integral_average(chain.cast<mpfr_real>(), mpfr_real(c.beta), 30);
      for (std::size_t i = 0; i < 2; ++i)
        reference[i] = exact.beta_kinetic[i].value.convert_to<double>();
    }
    for (const TorusRule rule : {TorusRule::trapezoid, TorusRule::gauss_legendre}) {
      TorusOptions options;
      options.rule = rule;
      const auto torus = torus_average(chain, c.beta, options);
      for (std::size_t i = 0; i < 2; ++i) {
        INFO("m1 = " << c.m1 << ", l2 = " << c.l2 << ", beta = " << c.beta << ", g = " << c.g
                     << (rule == TorusRule::trapezoid ? ", trapezoid" : ", Gauss-Legendre")
                     << ", K" << i + 1 << " = " << torus.beta_kinetic[i].value << " +- "
                     << torus.beta_kinetic[i].error << ", reference " << reference[i]);
        // the reference rounded to double: half an ulp of slack
        CHECK(std::abs(torus.beta_kinetic[i].value - reference[i]) <=
              torus.beta_kinetic[i].error + 0.5 * std::abs(reference[i]) * 0x1p-52);
      }
    }
  }
}

TEST_CASE("torus N = 2 with g = 0 is the public beta -> 0 limit", "[torus]") {
  // tests/data/public_values.csv: beta*K1 (beta->0 limit) for masses 0.5 0.5 = (mu1/2) K(k)/E(k).
  const Chain<double> chain({0.5, 0.5}, {1, 1}, 0.0);
  const auto r = torus_average(chain, 1.0);
  CHECK(std::abs(r.beta_kinetic[0].value - 0.3431834814709248549) <= 4e-16);
  CHECK(std::abs(r.beta_kinetic[1].value - 0.6568165185290751451) <= 4e-16);
  CHECK(r.cos_angle[0].value == 0.0);
  CHECK(r.cos_angle[1].value == 0.0);
}

TEST_CASE("torus N = 3 reproduces the public reference value", "[torus]") {
  const std::vector<std::string> values = public_n3_values();
  REQUIRE(values.size() == 3);
  const auto r = torus_average(uniform_chain(3), 1.0);
  REQUIRE(r.converged);
  for (std::size_t i = 0; i < 3; ++i) {
    const std::string& text = values[i];
    const std::size_t decimals = text.size() - text.find('.') - 1;
    const double half_unit = 0.5 * std::pow(10.0, -static_cast<double>(decimals));
    INFO("particle " << i + 1 << ": " << r.beta_kinetic[i].value << " vs " << text);
    CHECK(std::abs(r.beta_kinetic[i].value - std::stod(text)) <=
          half_unit + r.beta_kinetic[i].error);
    CHECK(r.beta_kinetic[i].error < 1e-14);
  }
}

TEST_CASE("torus identities: equipartition sum, canonical energies, N = 1", "[torus]") {
  for (std::size_t n : {2u, 3u, 4u}) {
    const std::vector<double> masses = {0.7, 1.9, 0.4, 1.1};
    const Chain<double> chain(std::vector<double>(masses.begin(), masses.begin() + n),
                              std::vector<double>(n, 1.3), 1.0);
    TorusOptions options;
    options.tolerance = 1e-10;
    const auto r = torus_average(chain, 0.8, options);
    INFO("N = " << n);
    REQUIRE(r.converged);
    double sum = 0;
    for (const pendavg::Estimate<double>& k : r.beta_kinetic) sum += k.value;
    CHECK(std::abs(sum - 0.5 * static_cast<double>(n)) <= 1e-14 * static_cast<double>(n));
    CHECK(r.equipartition_residual <= 1e-14 * static_cast<double>(n));
    REQUIRE(r.beta_kinetic_canonical.size() == n);
    for (const pendavg::Estimate<double>& kc : r.beta_kinetic_canonical) CHECK(kc.value == 0.5);
    const auto diagonal = pendavg::diagonal_approximation(chain);
    CHECK(r.diagonal_approximation == diagonal);
  }
  // N = 1: the simple pendulum. beta<K> = 1/2, beta^2 Var K = 1/2, <cos phi> = I1(a)/I0(a).
  const Chain<double> single({2.0}, {0.75}, 1.0);
  const double beta = 1.7, a = beta * 2.0 * 0.75;
  const auto r = torus_average(single, beta);
  REQUIRE(r.converged);
  CHECK(r.evaluations == 1);
  CHECK(std::abs(r.beta_kinetic[0].value - 0.5) <= 1e-16);
  CHECK(std::abs(r.beta2_kinetic_variance[0].value - 0.5) <= 1e-15);
  CHECK(std::abs(r.cos_angle[0].value - std::cyl_bessel_i(1.0, a) / std::cyl_bessel_i(0.0, a)) <=
        1e-15);
}

TEST_CASE("torus psi reduction agrees with brute force over all N angles", "[torus]") {
  // src/engine/README.md, 'Reduction': the closed-form psi integral (I0 weight, I1/I0 cos factor)
  // against the plain Boltzmann factor and plain cos phi_j on an N-dimensional trapezoid grid.
  const Chain<double> chain({1.0, 0.6, 1.4}, {0.9, 1.2, 0.7}, 1.0);
  const double beta = 1.3;
  const auto r = torus_average(chain, beta);
  const BruteForce brute = brute_force_torus(chain, beta, 48);
  for (std::size_t i = 0; i < 3; ++i) {
    INFO("particle " << i + 1);
    CHECK(std::abs(r.beta_kinetic[i].value - brute.beta_kinetic[i]) <= 1e-13);
    CHECK(std::abs(r.cos_angle[i].value - brute.cos_angle[i]) <= 1e-13);
  }
}

TEST_CASE("torus trapezoid and Gauss-Legendre agree", "[torus]") {
  const Chain<double> chain({1.5, 0.5, 1.0}, {1.0, 0.6, 1.4}, 1.0);
  for (double beta : {0.2, 1.0, 4.0}) {
    TorusOptions gl;
    gl.rule = TorusRule::gauss_legendre;
    const auto t = torus_average(chain, beta);
    const auto g = torus_average(chain, beta, gl);
    INFO("beta = " << beta);
    REQUIRE(t.converged);
    REQUIRE(g.converged);
    CHECK(g.method == pendavg::Method::torus_gauss_legendre);
    // Gauss-Legendre is the weaker rule on the circle: it needs at least as many nodes.
    CHECK(g.torus->points_per_dim >= t.torus->points_per_dim);
    for (std::size_t i = 0; i < 3; ++i) {
      const auto& x = t;
      const auto& y = g;
      check_close(x.beta_kinetic[i].value, x.beta_kinetic[i].error, y.beta_kinetic[i].value,
                  y.beta_kinetic[i].error, x.beta_kinetic[i].value, 1e-13, "beta<K>");
      check_close(x.beta2_kinetic_variance[i].value, x.beta2_kinetic_variance[i].error,
                  y.beta2_kinetic_variance[i].value, y.beta2_kinetic_variance[i].error,
                  x.beta2_kinetic_variance[i].value, 1e-13, "beta^2 Var K");
      check_close(x.cos_angle[i].value, x.cos_angle[i].error, y.cos_angle[i].value, y.cos_angle[i].error,
                  std::abs(x.cos_angle[i].value), 1e-13, "<cos phi>");
    }
  }
}

TEST_CASE("torus N = 3 at beta = 0.1 against the paper's diagonal approximation", "[torus]") {
  // src/engine/README.md, 'Diagonal approximation': the diagonal approximation gives 1/6 where the
  // exact value is ~0.311.
  const auto r = torus_average(uniform_chain(3), 0.1);
  REQUIRE(r.converged);
  CHECK(std::abs(r.beta_kinetic[0].value - 0.3114096682) <= 5e-11);
  CHECK(std::abs(r.diagonal_approximation[0] - 1.0 / 6.0) <= 1e-16);
  CHECK(r.beta_kinetic[0].value > 1.8 * r.diagonal_approximation[0]);
}

// The work bound (points per dimension), not the time: speed is for the benchmarks
// (bench_any_n). The values against the transfer operator, an independent method (messages
// along the chain instead of a grid on the torus).
TEST_CASE("torus N = 4 reaches 1e-11 on a bounded grid, and agrees with the transfer operator",
          "[torus]") {
  TorusOptions options;
  options.tolerance = 1e-11;
  const auto r = torus_average(uniform_chain(4), 1.0, options);
  REQUIRE(r.converged);
  CHECK(r.torus->points_per_dim <= 64);
  double sum = 0;
  for (std::size_t i = 0; i < 4; ++i) {
    CHECK(r.beta_kinetic[i].error <= 1e-11 * r.beta_kinetic[i].value);
    sum += r.beta_kinetic[i].value;
  }
  CHECK(std::abs(sum - 2.0) <= 1e-14);
  pendavg::TransferOptions transfer;
  transfer.tolerance = 1e-12;
  const auto t = pendavg::chain_transfer_average(uniform_chain(4), 1.0, transfer);
  REQUIRE(t.converged);
  for (std::size_t i = 0; i < 4; ++i) {
    INFO("particle " << i + 1 << ": torus " << r.beta_kinetic[i].value << " +- "
                     << r.beta_kinetic[i].error << ", transfer " << t.beta_kinetic[i].value
                     << " +- " << t.beta_kinetic[i].error);
    CHECK(std::abs(r.beta_kinetic[i].value - t.beta_kinetic[i].value) <=
          r.beta_kinetic[i].error + t.beta_kinetic[i].error + 1e-15);
  }
}

TEST_CASE("torus work: mirror halving, nesting, determinism, the node guard", "[torus]") {
  // Every node of the final n^D grid is evaluated once per mirror orbit: (n^D + 2^D) / 2
  // (the 2^D fixed points have every delta_i in {0, pi}), summed over the nested levels.
  const auto r = torus_average(uniform_chain(3), 1.0);
  const std::size_t n = r.torus->points_per_dim;
  CHECK(r.evaluations == (n * n + 4) / 2);
  CHECK(r.torus->grid_points == static_cast<double>(n * n));

  // Bitwise identical results for any thread count (partials combined in a fixed order).
  TorusOptions two;
  two.threads = 2;
  const auto s = torus_average(uniform_chain(3), 1.0, two);
  CHECK(s.beta_kinetic == r.beta_kinetic);
  CHECK(s.cos_angle == r.cos_angle);
  CHECK(s.beta2_kinetic_variance == r.beta2_kinetic_variance);

  // n^(N-1) > 1e9 at the first level is refused; so are bad inputs.
  CHECK_THROWS_AS(torus_average(uniform_chain(12), 1.0), pendavg::invalid_input);
  CHECK_THROWS_AS(torus_average(uniform_chain(3), -1.0), pendavg::invalid_input);
  TorusOptions bad;
  bad.min_points_per_dim = 1;
  CHECK_THROWS_AS(torus_average(uniform_chain(3), 1.0, bad), pendavg::invalid_input);
  bad = TorusOptions{};
  bad.tolerance = 0;
  CHECK_THROWS_AS(torus_average(uniform_chain(3), 1.0, bad), pendavg::invalid_input);
}

TEST_CASE("torus stopped before the large-beta peak is resolved reports it honestly", "[torus]") {
  // At beta = 1e4 the weight is a peak of width ~1e-2 at delta = 0, a node of every grid: with
  // n <= 64 the ratios freeze at that node's values (1/2) while Z does not converge. The run must
  // say converged = false, and its error bars must still cover the resolved value.
  // Equispaced nodes (node_map = none) make the peak a one-node affair; the automatic map
  // resolves it with n = 256.
  const Chain<double> chain = uniform_chain(3);
  TorusOptions coarse;
  coarse.max_points_per_dim = 64;
  coarse.node_map = pendavg::TorusNodeMap::none;
  const auto c = torus_average(chain, 1e4, coarse);
  CHECK_FALSE(c.converged);
  const auto f = torus_average(chain, 1e4);
  CHECK(f.torus->points_per_dim <= 256);
  REQUIRE(f.converged);
  for (std::size_t i = 0; i < 3; ++i) {
    INFO("particle " << i + 1);
    CHECK(std::abs(c.beta_kinetic[i].value - f.beta_kinetic[i].value) <=
          c.beta_kinetic[i].error);
    CHECK(std::abs(c.cos_angle[i].value - f.cos_angle[i].value) <=
          c.cos_angle[i].error);
    // Still above its true value's distance from 1/2: the peak was seen, not resolved.
    CHECK(std::abs(f.beta_kinetic[i].value - 0.5) > 1e-6);
  }
}

TEST_CASE("torus hard cases: light particles and large beta, mapped nodes", "[torus]") {
  // src/engine/torus/README.md, 'Node maps': a light particle puts singularities of sqrt(det A) at
  // distance ~sqrt(m_i/S_i) from the real axis, and large beta makes the weight a peak of width
  // ~alpha^{-1/2}; equispaced nodes then need O(1/distance) per dimension. The automatic periodic
  // map keeps n bounded.
  struct Hard {
    std::vector<double> masses;
    double beta;
    std::size_t max_n;  // nodes per dimension the mapped rule needs (observed, with margin 1x)
  };
  const std::vector<Hard> n2 = {{{1e-4, 1}, 1, 512}, {{1e-6, 1}, 0.1, 512}, {{1e-4, 1}, 100, 512},
                                {{1, 1}, 1e3, 128},    {{1, 1}, 1e5, 512}};
  for (const auto& h : n2) {
    const Chain<double> chain(h.masses, {1.0, 1.0}, 1.0);
    const auto t = torus_average(chain, h.beta);
    const auto ref = pendavg::reduced_integral_average(chain, h.beta);
    INFO("m1 = " << h.masses[0] << ", beta = " << h.beta);
    REQUIRE(t.converged);
    CHECK(t.torus->points_per_dim <= h.max_n);
    for (std::size_t i = 0; i < 2; ++i) {
      check_close(t.beta_kinetic[i].value, t.beta_kinetic[i].error,
                  ref.beta_kinetic[i].value, ref.beta_kinetic[i].error, ref.beta_kinetic[i].value, 1e-13,
                  "beta<K>");
      check_close(t.cos_angle[i].value, t.cos_angle[i].error, ref.cos_angle[i].value,
                  ref.cos_angle[i].error, std::abs(ref.cos_angle[i].value), 1e-13, "<cos phi>");
    }
  }
  // N = 3, light particle first or in the middle: mapped trapezoid, mapped Gauss-Legendre and the
  // plain trapezoid (which needs 4x the nodes per dimension) agree.
  for (const auto& masses : {std::vector<double>{1e-3, 1, 1}, std::vector<double>{1, 1e-3, 1}}) {
    const Chain<double> chain(masses, {1.0, 1.0, 1.0}, 1.0);
    const auto t = torus_average(chain, 1.0);
    TorusOptions gl;
    gl.rule = TorusRule::gauss_legendre;
    const auto g = torus_average(chain, 1.0, gl);
    TorusOptions plain;
    plain.node_map = pendavg::TorusNodeMap::none;
    plain.tolerance = 1e-11;
    const auto p = torus_average(chain, 1.0, plain);
    INFO("masses " << masses[0] << " " << masses[1] << " " << masses[2]);
    REQUIRE(t.converged);
    REQUIRE(g.converged);
    REQUIRE(p.converged);
    CHECK(t.torus->points_per_dim <= 256);
    CHECK(p.torus->points_per_dim >= 2 * t.torus->points_per_dim);
    for (std::size_t i = 0; i < 3; ++i) {
      check_close(t.beta_kinetic[i].value, t.beta_kinetic[i].error,
                  g.beta_kinetic[i].value, g.beta_kinetic[i].error,
                  t.beta_kinetic[i].value, 1e-13, "trapezoid vs Gauss-Legendre");
      check_close(t.beta_kinetic[i].value, t.beta_kinetic[i].error,
                  p.beta_kinetic[i].value, p.beta_kinetic[i].error,
                  t.beta_kinetic[i].value, 1e-11, "mapped vs plain");
    }
  }
}

namespace {

/// Torus options for a number type: the tolerance at 450 units of its precision (in double
/// 1e-13, the default), MPFR at test_digits.
template <class Real>
TorusOptions typed_options() {
  TorusOptions options;
  if constexpr (pendavg::is_mpfr_v<Real>) {
    options.digits = pendavg::test::test_digits;
  } else {
    options.tolerance = 450 * pendavg::test::unit<Real>();
  }
  return options;
}

/// Every reported quantity of `r` against `reference`: the error bars cover the difference, and
/// it is within `units` of the type's precision relative to the quantity's scale (the torus'
/// tolerance's: beta<K_i> itself, beta^2 <K_i^2> for the variance, <cos phi_i> its size with a
/// floor of 1e-3).
template <class Real>
void check_against(const pendavg::Averages<Real>& r, const pendavg::Averages<mpfr_real>& reference,
                   double units) {
  using namespace pendavg::test;
  const double tolerance = units * unit<Real>();
  for (std::size_t i = 0; i < r.beta_kinetic.size(); ++i) {
    INFO("particle " << i + 1 << ": beta<K> " << as_double(r.beta_kinetic[i].value) << " +- "
                     << as_double(r.beta_kinetic[i].error) << " against "
                     << as_double(reference.beta_kinetic[i].value) << ", off by "
                     << relative_distance(r.beta_kinetic[i].value, reference.beta_kinetic[i].value) /
                            unit<Real>()
                     << " units");
    CHECK(distance(r.beta_kinetic[i].value, reference.beta_kinetic[i].value) <=
          as_double(r.beta_kinetic[i].error));
    CHECK(relative_distance(r.beta_kinetic[i].value, reference.beta_kinetic[i].value) <= tolerance);
    CHECK(distance(r.beta2_kinetic_variance[i].value, reference.beta2_kinetic_variance[i].value) <=
          as_double(r.beta2_kinetic_variance[i].error));
    const ReferencePrecision wide;
    const mpfr_real second_moment = reference.beta2_kinetic_variance[i].value +
                                    reference.beta_kinetic[i].value * reference.beta_kinetic[i].value;
    CHECK(relative_distance(r.beta2_kinetic_variance[i].value,
                            reference.beta2_kinetic_variance[i].value, second_moment) <= tolerance);
    const mpfr_real cos_scale = abs(reference.cos_angle[i].value) > mpfr_real("1e-3")
                                    ? mpfr_real(abs(reference.cos_angle[i].value))
                                    : mpfr_real("1e-3");
    CHECK(distance(r.cos_angle[i].value, reference.cos_angle[i].value) <=
          as_double(r.cos_angle[i].error));
    CHECK(relative_distance(r.cos_angle[i].value, reference.cos_angle[i].value, cos_scale) <=
          tolerance);
  }
}

}  // namespace

// The torus in every number type it is instantiated for, N = 2 against the reduced integral at
// reference_digits (an independent method), the hard cases by name.
TEMPLATE_TEST_CASE("torus N = 2 in every number type against the 40-digit reduced integral",
                   "[torus]", double, long double, mpfr_real) {
  using Real = TestType;
  struct Case {
    const char* name;
    double m1, m2, l1, l2, g, beta;
  };
  for (const Case c : {Case{"moderate", 1.2, 0.8, 1.0, 0.7, 1.0, 0.9},
                       Case{"mu1 -> 0", 1e-6, 1.0, 1.0, 1.0, 1.0, 1.0},
                       Case{"mu1 -> 0, g = 0", 1e-12, 1.0, 1.0, 1.0, 0.0, 1.0},
                       Case{"mu1 -> 0, large beta", 1e-8, 1.0, 1.0, 1.0, 1.0, 1e4},
                       Case{"beta -> 0", 0.3, 0.7, 1.0, 2.0, 1.0, 1e-6},
                       Case{"large beta", 1.0, 1.0, 1.0, 1.0, 1.0, 1e3},
                       Case{"long lower link", 1.0, 1.0, 1.0, 1e3, 1.0, 1.0},
                       Case{"short lower link", 1.0, 1.0, 1.0, 1e-3, 1.0, 1.0}}) {
    const Chain<double> chain({c.m1, c.m2}, {c.l1, c.l2}, c.g);
    // Outside the MPFR torus' domain (m_i / S_i < 1e-6 at g = 0: average() refuses it, tested in
    // tests/test_fail_closed.cpp, "the MPFR torus without gravity ...").
    if (pendavg::is_mpfr_v<Real> && c.g == 0 && c.m1 / (c.m1 + c.m2) < 1e-6) continue;
    pendavg::Averages<mpfr_real> reference;
    {
      const pendavg::test::ReferencePrecision wide;
      reference = pendavg::reduced_integral_average(chain.cast<mpfr_real>(), mpfr_real(c.beta),
                                                    pendavg::test::reference_digits);
      REQUIRE(reference.converged);
    }
    const pendavg::test::TypePrecision<Real> precision;
    const auto r = torus_average(chain.cast<Real>(), Real(c.beta), typed_options<Real>());
    INFO(c.name << ": m = (" << c.m1 << ", " << c.m2 << "), l = (" << c.l1 << ", " << c.l2
                << "), beta = " << c.beta);
    REQUIRE(r.converged);
    check_against(r, reference, 450);
  }
}

namespace {

/// The N = 3 reference: Gauss-Legendre (the other rule) at 30 digits, computed once.
const pendavg::Averages<mpfr_real>& n3_reference() {
  static const pendavg::Averages<mpfr_real> reference = [] {
    const pendavg::working_precision wp(30 + pendavg::guard_digits);
    TorusOptions options;
    options.digits = 30;
    options.rule = TorusRule::gauss_legendre;
    return torus_average(Chain<double>({1.2, 0.8, 0.5}, {1.0, 0.7, 1.3}, 1.0).cast<mpfr_real>(),
                         mpfr_real(0.875), options);
  }();
  return reference;
}

}  // namespace

TEMPLATE_TEST_CASE("torus N = 3 in every number type against Gauss-Legendre at 30 digits",
                   "[torus]", double, long double, mpfr_real) {
  using Real = TestType;
  const auto& reference = n3_reference();
  REQUIRE(reference.converged);
  const pendavg::test::TypePrecision<Real> precision;
  const auto r = torus_average(Chain<double>({1.2, 0.8, 0.5}, {1.0, 0.7, 1.3}, 1.0).cast<Real>(),
                               Real(0.875), typed_options<Real>());
  REQUIRE(r.converged);
  check_against(r, reference, 450);
}

TEST_CASE("torus N = 3 at 30 digits: trapezoid, Gauss-Legendre and the public value", "[torus][.slow]") {
  pendavg::working_precision wp(30 + pendavg::guard_digits);
  const Chain<mpfr_real> chain = uniform_chain(3).cast<mpfr_real>();
  TorusOptions options;
  options.digits = 30;
  const auto t = torus_average(chain, mpfr_real(1), options);
  options.rule = TorusRule::gauss_legendre;
  const auto g = torus_average(chain, mpfr_real(1), options);
  REQUIRE(t.converged);
  REQUIRE(g.converged);
  const std::vector<std::string> values = public_n3_values();
  for (std::size_t i = 0; i < 3; ++i) {
    CHECK(abs(t.beta_kinetic[i].value - g.beta_kinetic[i].value) <= t.beta_kinetic[i].error + g.beta_kinetic[i].error);
    CHECK(abs(t.beta_kinetic[i].value - g.beta_kinetic[i].value) <= mpfr_real("1e-30"));
    CHECK(abs(t.beta_kinetic[i].value - mpfr_real(values[i])) <= mpfr_real("5e-15"));
  }
}

TEST_CASE("torus N = 5 reaches 1e-10", "[torus][.slow]") {
  TorusOptions options;
  options.tolerance = 1e-10;
  options.threads = 2;
  const auto r = torus_average(uniform_chain(5), 1.0, options);
  REQUIRE(r.converged);
  double sum = 0;
  for (const pendavg::Estimate<double>& k : r.beta_kinetic) sum += k.value;
  CHECK(std::abs(sum - 2.5) <= 1e-14);
  // beta<K_i> increases down the chain for equal masses (as for N = 2, 3, 4).
  for (std::size_t i = 0; i + 1 < 5; ++i) {
    CHECK(r.beta_kinetic[i].value < r.beta_kinetic[i + 1].value);
  }
}
