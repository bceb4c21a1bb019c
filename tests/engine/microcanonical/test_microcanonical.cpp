// SPDX-License-Identifier: GPL-3.0-or-later
// Tests of pendavg/microcanonical.hpp. Every check compares independent methods:
//   * the shell integrals F_p, G_p against adaptive quadrature of their definitions;
//   * N = 2 against brute-force quadrature of the definition over (phi_1, phi_2) with Eigen's
//     dense A (tests/oracle/dense_traces.hpp) and the exact phi_1 limits of {U < E};
//   * N = 2 hard cases against the psi reduction done numerically (phi_1 by tanh-sinh over the
//     accessible arcs, delta = phi_2 - phi_1 by tanh-sinh), again with the dense oracle;
//   * N = 3: the nested integral against QMC (bars), the torus trapezoid, and a brute force
//     over all three angles;
//   * ensemble equivalence: the Laplace transform of Omega(E) <K_i>_E against the canonical
//     engines (reduced_integral_average for N = 2, torus_average for N = 3) and of Omega(E)
//     against the closed-form partition function of N = 1;
//   * limits: E -> infinity (canonical beta -> 0) and E -> E_min (harmonic equipartition over
//     normal modes: D/(2N) for every particle of every chain);
//   * the near-minimum ladder D = 1e-4..1e-12 |E_min| (N = 2, 3) against a long-double quadrature
//     of the definition in the excitation form (tests/oracle/near_minimum.hpp), and far below it
//     (D down to 1e-250 |E_min|) against the harmonic limit;
//   * Var K_i's conditional moment against momenta sampled on the energy shell;
//   * error estimates against tighter runs, long double runs (separatrices, above the top) and
//     MPFR; qmc finite at every excitation; bad input.
#include <catch2/catch.hpp>

#include "refusals.hpp"
#include "oracle/dense_traces.hpp"
#include "oracle/near_minimum.hpp"
#include "pendavg/chain.hpp"
#include "pendavg/mpfr.hpp"
#include "engine/double_pendulum/double_pendulum.hpp"
#include "engine/microcanonical/microcanonical.hpp"
#include "engine/torus/torus.hpp"
#include "real_types.hpp"

#include <boost/math/quadrature/exp_sinh.hpp>
#include <boost/math/quadrature/gauss.hpp>
#include <boost/math/quadrature/tanh_sinh.hpp>
#include <boost/math/special_functions/bessel.hpp>

#include <Eigen/Dense>

#include <cmath>
#include <limits>
#include <map>
#include <random>
#include <string>
#include <utility>
#include <vector>

using namespace pendavg;
using Rule = MicrocanonicalOptions::Rule;

namespace {

constexpr double kPi = 3.14159265358979323846;

double gamma_sum(const Chain<double>& c) {
  double s = 0;
  for (std::size_t j = 0; j < c.size(); ++j) s += c.potential_coefficient(j);
  return s;
}

/// Weight and numerators at one absolute configuration, from the dense oracle:
/// [0] sqrt(det A) (E - U)^{N/2-1}, [1 + i] the same times tr X_i (E - U)/N, [1 + N + i] times
/// cos phi_i, [1 + 2N + i] times (E - U)^2 ((tr X_i)^2 + 2 tr X_i^2) / (N (N + 2)) (= <K_i^2 | phi>,
/// the sphere's fourth moments; checked by sampling below).
std::vector<double> definition_integrand(const Chain<double>& c, const std::vector<double>& phi,
                                         double energy) {
  const std::size_t n = c.size();
  std::vector<double> out(1 + 3 * n, 0.0);
  double u = 0;
  for (std::size_t j = 0; j < n; ++j) u -= c.potential_coefficient(j) * std::cos(phi[j]);
  const double kinetic = energy - u;
  if (!(kinetic > 0)) return out;
  const auto d = oracle::dense_traces<double>(c.masses(), c.lengths(), phi);
  const double w = std::exp(d.log_sqrt_det_A) * std::pow(kinetic, double(n) / 2 - 1);
  const double nn = double(n);
  out[0] = w;
  for (std::size_t i = 0; i < n; ++i) {
    const double x = d.trace_X[i];
    out[1 + i] = w * x * kinetic / nn;
    out[1 + n + i] = w * std::cos(phi[i]);
    out[1 + 2 * n + i] =
        w * kinetic * kinetic * (x * x + 2 * d.trace_X_squared[i]) / (nn * (nn + 2));
  }
  return out;
}

/// Oracle (a): N = 2 over (phi_1, phi_2) literally. For fixed phi_2, U < E iff cos phi_1 > c with
/// c = -(E + gamma_2 cos phi_2)/gamma_1: phi_1 in (-arccos c, arccos c), Gauss-Legendre (smooth
/// there). The phi_2 integrand has square-root ends where c = +-1: tanh-sinh between them.
std::vector<double> brute_force_2d(const Chain<double>& c, double energy) {
  const double g1 = c.potential_coefficient(0), g2 = c.potential_coefficient(1);
  std::vector<double> cuts{0.0, kPi};
  for (double s : {-1.0, 1.0}) {  // c = s: cos phi_2 = (-E - s g1)/g2
    const double x = (-energy - s * g1) / g2;
    if (x > -1 && x < 1) cuts.push_back(std::acos(x));
  }
  std::sort(cuts.begin(), cuts.end());
  boost::math::quadrature::tanh_sinh<double> outer(10);
  std::vector<double> total(7, 0.0);
  for (std::size_t q = 0; q < 7; ++q) {
    for (std::size_t k = 0; k + 1 < cuts.size(); ++k) {
      const auto f = [&](double phi2) {
        const double x = -(energy + g2 * std::cos(phi2)) / g1;
        if (x >= 1) return 0.0;
        const double a = x <= -1 ? kPi : std::acos(x);
        return boost::math::quadrature::gauss<double, 40>::integrate(
            [&](double phi1) { return definition_integrand(c, {phi1, phi2}, energy)[q]; }, -a, a);
      };
      total[q] += 2 * outer.integrate(f, cuts[k], cuts[k + 1], 1e-13);
    }
  }
  return total;
}

/// Oracle (b): N = 2 with the psi reduction done numerically. delta = phi_2 - phi_1 in [0, pi]
/// (doubled), phi_1 over the accessible arc of E + rho cos(phi_1 + arg z) > 0 by tanh-sinh,
/// delta by tanh-sinh split at rho(delta) = |E|.
std::vector<double> reduced_numeric_2d(const Chain<double>& c, double energy) {
  const double g1 = c.potential_coefficient(0), g2 = c.potential_coefficient(1);
  std::vector<double> cuts{0.0, kPi};
  const double x = (energy * energy - g1 * g1 - g2 * g2) / (2 * g1 * g2);
  if (x > -1 && x < 1) cuts.push_back(std::acos(x));
  std::sort(cuts.begin(), cuts.end());
  boost::math::quadrature::tanh_sinh<double> rule(10);
  std::vector<double> total(7, 0.0);
  for (std::size_t q = 0; q < 3; ++q) {
    for (std::size_t k = 0; k + 1 < cuts.size(); ++k) {
      const auto f = [&](double delta) {
        const double zx = g1 + g2 * std::cos(delta), zy = g2 * std::sin(delta);
        const double rho = std::hypot(zx, zy), arg = std::atan2(zy, zx);
        if (!(energy + rho > 0)) return 0.0;
        const double half = energy >= rho ? kPi : std::acos(-energy / rho);
        // E - U = E + rho cos(phi_1 + arg): phi_1 + arg in (-half, half); for N = 2 the
        // integrand there is smooth in phi_1 (det A depends on delta only): Gauss-Legendre
        return boost::math::quadrature::gauss<double, 30>::integrate(
            [&](double s) {
              const double phi1 = s - arg;
              return definition_integrand(c, {phi1, phi1 + delta}, energy)[q];
            },
            -half, half);
      };
      total[q] += 2 * rule.integrate(f, cuts[k], cuts[k + 1], 1e-13);
    }
  }
  return total;
}

/// <K_1>, <K_2>, <cos phi_1>, <cos phi_2>, Var K_1, Var K_2 from the integrals of an oracle.
std::vector<double> oracle_averages(const std::vector<double>& t) {
  const double k1 = t[1] / t[0], k2 = t[2] / t[0];
  return {k1, k2, t[3] / t[0], t[4] / t[0], t[5] / t[0] - k1 * k1, t[6] / t[0] - k2 * k2};
}

}  // namespace

TEST_CASE("shell integrals F_p, F_{p+1}, G_p match adaptive quadrature", "[microcanonical]") {
  boost::math::quadrature::tanh_sinh<double> rule(15);
  for (int twice_p = -1; twice_p <= 14; ++twice_p) {
    const double p = twice_p / 2.0;
    for (double rho : {1.0, 0.3}) {
      for (double ratio : {-0.999, -0.9, -0.5, -1e-3, 0.0, 0.3, 0.5, 0.9, 0.999, 1.001, 1.5,
                           2.0, 2.5, 10.0, 1e3}) {
        const double e = ratio * rho;
        const double end = e < rho ? std::acos(-e / rho) : kPi;
        // E + rho cos u near the right end u = end - d, without cancellation (Boost passes d):
        // cap: 2E sin^2(d/2) + rho sin(end) sin d; full circle: (E - rho) + 2 rho sin^2(d/2).
        const auto shell = [&](double u, double d) {
          if (d > 0 && d < 0.5) {
            const double s = std::sin(d / 2);
            return e < rho ? 2 * e * s * s + rho * std::sin(end) * std::sin(d)
                           : (e - rho) + 2 * rho * s * s;
          }
          return e + rho * std::cos(u);
        };
        const auto pw = [&](double u, double d, double power) {
          const double x = shell(u, d);
          return x > 0 ? std::pow(x, power) : 0.0;
        };
        const double f = 2 * rule.integrate([&](double u, double d) { return pw(u, d, p); }, 0.0,
                                            end, 1e-15);
        const double f1 = 2 * rule.integrate(
                                  [&](double u, double d) { return pw(u, d, p + 1); }, 0.0, end, 1e-15);
        const double g = 2 * rule.integrate(
                                 [&](double u, double d) { return std::cos(u) * pw(u, d, p); }, 0.0,
                                 end, 1e-15);
        const auto m = detail::microcanonical::shell_integrals<double>(twice_p, e, rho);
        INFO("p = " << p << ", rho = " << rho << ", E = " << e);
        CHECK(std::abs(m.weight / f - 1) < 2e-13);
        CHECK(std::abs(m.kinetic / f1 - 1) < 2e-13);
        CHECK(std::abs(m.cosine - g) < 2e-13 * f);
        // long double runs the same algorithm with more bits: agreement bounds double's rounding
        const auto ml = detail::microcanonical::shell_integrals<long double>(
            twice_p, (long double)e, (long double)rho);
        CHECK(std::abs(double(ml.weight) / m.weight - 1) < 1e-14);
      }
    }
  }
  // below the bottom of the well nothing is accessible; rho = 0 is the whole circle
  CHECK(detail::microcanonical::shell_integrals<double>(3, -1.0, 0.5).weight == 0);
  CHECK(std::abs(detail::microcanonical::shell_integrals<double>(2, 2.0, 0.0).weight -
                 2 * kPi * 2.0) < 1e-14);
}

TEST_CASE("N = 2 matches brute-force quadrature of the definition over (phi1, phi2)",
          "[microcanonical]") {
  const std::vector<Chain<double>> chains{
      Chain<double>({1.0, 1.0}, {1.0, 1.0}, 1.0),
      Chain<double>({2.0, 0.5}, {0.7, 1.3}, 1.5),
  };
  for (const auto& c : chains) {
    const double top = gamma_sum(c);
    for (double fraction : {-0.97, -0.5, -0.2, 0.0, 0.3, 0.7, 1.0, 1.8}) {
      const double energy = fraction * top;
      const auto o = oracle_averages(brute_force_2d(c, energy));
      MicrocanonicalOptions tight;
      tight.tolerance = 1e-12;
      const auto r = microcanonical_average(c, energy, tight);
      INFO("E = " << energy);
      CHECK(r.quadrature == Method::reduced_integral);
      CHECK(r.converged);
      for (int i = 0; i < 2; ++i) {
        CHECK(std::abs(r.kinetic[i].value - o[i]) < 1e-11 * o[i]);
        CHECK(r.kinetic[i].error < 1e-11 * r.kinetic[i].value);
        CHECK(std::abs(r.cos_angle[i].value - o[2 + i]) < 1e-11);
        // Var K_i = <K_i^2> - <K_i>^2 against the definition's second moments
        CHECK(std::abs(r.kinetic_variance[i].value - o[4 + i]) < 1e-10 * o[4 + i]);
        CHECK(r.kinetic_variance[i].error < 1e-10 * r.kinetic_variance[i].value);
      }
      CHECK(std::abs(r.kinetic_total.value - (r.kinetic[0].value + r.kinetic[1].value)) < 1e-13 * r.kinetic_total.value);
      CHECK(r.kinetic_canonical.value == r.kinetic_total.value / 2);
    }
  }
}

TEST_CASE("N = 2 hard cases: light first mass, extreme length ratios, near the minimum",
          "[microcanonical]") {
  struct Case {
    Chain<double> chain;
    double fraction;  // E = fraction * sum gamma
  };
  const std::vector<Case> cases{
      {Chain<double>({1e-6, 1.0}, {1.0, 1.0}, 1.0), -0.5},
      {Chain<double>({1e-6, 1.0}, {1.0, 1.0}, 1.0), 0.2},
      {Chain<double>({1.0, 1.0}, {1.0, 1e-3}, 1.0), -0.5},
      {Chain<double>({1.0, 1.0}, {1.0, 1e-3}, 1.0), 0.9999},
      {Chain<double>({1.0, 1.0}, {1.0, 1e3}, 1.0), -0.3},
      {Chain<double>({1.0, 1.0}, {1.0, 1e3}, 1.0), 0.5},
      {Chain<double>({1.0, 1.0}, {1.0, 1.0}, 1.0), -0.999999},
  };
  for (const auto& k : cases) {
    const double energy = k.fraction * gamma_sum(k.chain);
    const auto o = oracle_averages(reduced_numeric_2d(k.chain, energy));
    MicrocanonicalOptions tight;
    tight.tolerance = 1e-12;
    const auto r = microcanonical_average(k.chain, energy, tight);
    INFO("m1 = " << k.chain.mass(0) << ", l2 = " << k.chain.length(1) << ", E = " << energy);
    CHECK(r.converged);
    for (int i = 0; i < 2; ++i) {
      // the dense oracle loses ~log10(cond A) digits for m1 = 1e-6
      CHECK(std::abs(r.kinetic[i].value - o[i]) < 1e-9 * o[i]);
      CHECK(r.kinetic[i].error < 1e-10 * r.kinetic[i].value);
    }
  }
}

TEST_CASE("harmonic limit: <K_i>_E -> D/(2N) for every particle, whatever the masses and lengths",
          "[microcanonical]") {
  // Small oscillations (include/pendavg/microcanonical.hpp, "Harmonic limit"): on the energy shell
  // of N oscillators every normal mode carries kinetic energy D/(2N) on average, and the modes map
  // back to particle i through sum_k v_k^T A^(i)(0) v_k = tr X_i(0) = 1, so <K_i>_E = D/(2N) (1 +
  // O(D)) for every particle of every chain, not only of uniform ones. The positions give
  // 1 - <cos phi_i>_E -> D/(2N gamma_i); the fourth moments of the (2N)-sphere give
  // Var K_i -> D^2 [(1 + 2 tr X_i(0)^2)/(4N(N+1)) - 1/(4N^2)] = D^2 (2N - 1)/(4N^2 (N + 1)), as
  // X_i(0) has rank one (at phi = 0 every velocity is horizontal) and trace 1. The corrections
  // are linear in D: (<K_i>_E / (D/(2N)) - 1) / D tends to a constant.
  const std::vector<Chain<double>> chains{
      Chain<double>({1.0, 1.0}, {1.0, 1.0}, 1.0),
      Chain<double>({1.0, 0.3}, {1.3, 0.6}, 9.81),
      Chain<double>({1.0, 1.0, 1.0}, {1.0, 1.0, 1.0}, 1.0),
      Chain<double>({0.7, 1.9, 0.4}, {0.8, 1.1, 1.7}, 2.5),
  };
  for (const auto& c : chains) {
    const std::size_t n = c.size();
    const double nn = double(n);
    const double depth = -minimum_energy(c);
    TraceWorkspace<double> ws(c);
    const std::vector<double> zero(n - 1, 0.0);
    const NodeTraces<double> t0 = node_traces_relative(c, zero.data(), ws);
    double previous = 1;
    std::vector<double> slope_at_1e3(n);
    for (double fraction : {1e-3, 1e-6, 1e-9, 1e-12}) {
      const double d = fraction * depth;
      const auto r = microcanonical_average_excitation(c, d);
      double worst = 0;
      for (std::size_t i = 0; i < n; ++i) {
        INFO("N = " << n << ", m1 = " << c.mass(0) << ", D/|E_min| = " << fraction << ", i = " << i);
        CHECK(std::abs(t0.trace_X[i] - 1) < 1e-15);          // tr X_i(0) = 1
        CHECK(std::abs(t0.trace_X_squared[i] - 1) < 1e-15);  // rank one
        const double k = r.kinetic[i].value / (d / (2 * nn)) - 1;
        worst = std::max(worst, std::abs(k));
        CHECK(std::abs(k) < 10 * fraction + 1e-13);
        // O(D) corrections: the slope k / D at D = 1e-6 |E_min| within 1% of the one at 1e-3
        if (fraction == 1e-3) slope_at_1e3[i] = k / d;
        if (fraction == 1e-6) CHECK(std::abs((k / d) / slope_at_1e3[i] - 1) < 1e-2);
        const double harmonic_variance = d * d * (2 * nn - 1) / (4 * nn * nn * (nn + 1));
        CHECK(std::abs(r.kinetic_variance[i].value / harmonic_variance - 1) < 10 * fraction + 1e-12);
        // 1 - <cos phi_i> from a value near 1: its error bar (~5e-15) limits the check
        const double gap = d / (2 * nn * c.potential_coefficient(i));
        CHECK(std::abs((1 - r.cos_angle[i].value) / gap - 1) <
              10 * fraction + r.cos_angle[i].error / gap);
      }
      CHECK(worst < previous / 100);  // the deviation shrinks with D
      previous = std::max(worst, 1e-300);
      CHECK(std::abs(r.kinetic_total.value / (d / 2) - 1) < 10 * fraction + 1e-13);
    }
  }
}

TEST_CASE("near-minimum ladder: D = 1e-4..1e-12 |E_min| for N = 2, 3 against a long-double "
          "quadrature of the definition",
          "[microcanonical]") {
  // tests/oracle/near_minimum.hpp integrates the definition over the absolute angles in the
  // excitation form (dense A, no reduction). Both entry points: the excitation D and the energy
  // E = E_min + D (in double; its own D is formed in double-double and handed to the oracle).
  // Targets (issue 15): relative error <= 1e-13 and every error bar covering the truth.
  struct Case {
    std::vector<double> masses, lengths;
    double g;
  };
  const std::vector<Case> cases{
      {{1.0, 1.0}, {1.0, 1.0}, 1.0},
      {{1.0, 0.3}, {1.3, 0.6}, 9.81},
      {{1.0, 1.0, 1.0}, {1.0, 1.0, 1.0}, 1.0},
      {{0.7, 1.9, 0.4}, {0.8, 1.1, 1.7}, 2.5},
  };
  double worst_relative = 0, worst_ratio = 0;
  for (const Case& k : cases) {
    const Chain<double> c(k.masses, k.lengths, k.g);
    const std::size_t n = c.size();
    const std::vector<long double> ml(k.masses.begin(), k.masses.end()),
        ll(k.lengths.begin(), k.lengths.end());
    const double e_min = minimum_energy(c);
    for (int power = 4; power <= 12; ++power) {
      const double fraction = std::pow(10.0, -power);
      const double excitation = fraction * -e_min;
      const double energy = e_min + excitation;
      const auto by_excitation = microcanonical_average_excitation(c, excitation);
      const auto by_energy = microcanonical_average(c, energy);
      CHECK(by_energy.excitation == excitation_energy(c, energy));
      for (const auto* r : {&by_excitation, &by_energy}) {
        const int nodes = 24;
        const auto o = oracle::near_minimum_average<long double>(
            ml, ll, (long double)k.g, (long double)r->excitation, nodes);
        if (power % 4 == 0 && r == &by_excitation) {  // the oracle's own convergence
          const auto finer = oracle::near_minimum_average<long double>(
              ml, ll, (long double)k.g, (long double)r->excitation, nodes * 3 / 2);
          for (std::size_t i = 0; i < n; ++i) {
            CHECK(std::abs(o.kinetic[i] / finer.kinetic[i] - 1) < 1e-16L);
            CHECK(std::abs(o.kinetic_variance[i] / finer.kinetic_variance[i] - 1) < 1e-16L);
          }
        }
        for (std::size_t i = 0; i < n; ++i) {
          INFO("N = " << n << ", m1 = " << k.masses[0] << ", D/|E_min| = 1e-" << power
                      << (r == &by_energy ? " (from E)" : " (from D)") << ", i = " << i);
          const auto check = [&](const Estimate<double>& e, long double truth, double tight) {
            const double deviation = std::abs(double(e.value - truth));
            const double relative = deviation / std::abs(double(truth));
            INFO("value " << e.value << ", truth " << double(truth) << ", error " << e.error);
            CHECK(relative <= 1e-13);            // the accuracy target
            CHECK(deviation <= e.error);         // the bar covers the truth
            CHECK(e.error <= tight * std::abs(double(truth)));  // and is tight
            return std::pair{relative, deviation / e.error};
          };
          const auto [rel, ratio] = check(r->kinetic[i], o.kinetic[i], 1e-13);
          worst_relative = std::max(worst_relative, rel);
          worst_ratio = std::max(worst_ratio, ratio);
          // Var = <K^2> - <K>^2: its bar carries the rounding of <K^2> ~ 4 Var
          check(r->kinetic_variance[i], o.kinetic_variance[i], 1e-12);
          CHECK(std::abs(double(r->cos_angle[i].value - o.cos_angle[i])) <= r->cos_angle[i].error);
        }
      }
    }
  }
  INFO("worst relative error " << worst_relative << ", worst |deviation|/error " << worst_ratio);
  CHECK(worst_ratio < 1);
}

TEST_CASE("far below the ladder (D = 1e-20..1e-250 |E_min|) the bars cover the harmonic limit",
          "[microcanonical]") {
  // There the harmonic values are the truth to ~D/|E_min| relative: <K_i>_E = D/(2N), Var K_i =
  // D^2 (2N - 1)/(4N^2 (N + 1)), 1 - <cos phi_i>_E = D/(2N gamma_i). Every cut of the nested
  // integral sits within ~sqrt(D) of 0 here, so this catches any cut or node formed with an
  // absolute (rather than relative) rounding error, which would lie by ~(u / sqrt(D))^(3/2).
  struct Case {
    Chain<double> chain;
    std::vector<double> fractions;
  };
  const std::vector<Case> cases{
      {Chain<double>({1.0, 1.0}, {1.0, 1.0}, 1.0), {1e-20, 1e-50, 1e-100, 1e-250}},
      {Chain<double>({1.0, 0.3}, {1.3, 0.6}, 9.81), {1e-20, 1e-100}},
      {Chain<double>({0.7, 1.9, 0.4}, {0.8, 1.1, 1.7}, 2.5), {1e-20}},
  };
  for (const Case& k : cases) {
    const Chain<double>& c = k.chain;
    const std::size_t n = c.size();
    const double nn = double(n);
    for (double fraction : k.fractions) {
      const double d = fraction * -minimum_energy(c);
      MicrocanonicalOptions o;
      o.tolerance = n == 2 ? 1e-13 : 1e-11;
      if (d * d < std::numeric_limits<double>::min()) {
        // Var K_i ~ D^2 underflows double: refused, never printed as 0 +- 0 (issue 26)
        CHECK_THROWS_WITH(microcanonical_average_excitation(c, d, o),
                          Catch::Contains("underflows double"));
        continue;
      }
      const auto r = microcanonical_average_excitation(c, d, o);
      INFO("N = " << n << ", m1 = " << c.mass(0) << ", D/|E_min| = " << fraction);
      if (n == 2) CHECK(r.converged);
      for (std::size_t i = 0; i < n; ++i) {
        INFO("i = " << i << ": <K_i>/(D/(2N)) = " << r.kinetic[i].value / (d / (2 * nn)) << " +- "
                    << r.kinetic[i].error / (d / (2 * nn)));
        CHECK(std::abs(r.kinetic[i].value - d / (2 * nn)) <= r.kinetic[i].error);
        CHECK(r.kinetic[i].error <= 1e-13 * r.kinetic[i].value);
        const double variance = d * d * (2 * nn - 1) / (4 * nn * nn * (nn + 1));
        CHECK(std::abs(r.kinetic_variance[i].value - variance) <= r.kinetic_variance[i].error);
        const double gap = d / (2 * nn * c.potential_coefficient(i));
        CHECK(std::abs(r.cos_angle[i].value - (1 - gap)) <= r.cos_angle[i].error);
      }
    }
  }
}

TEMPLATE_TEST_CASE("excitation_energy keeps every digit of E - E_min (against MPFR at 60 digits)",
                   "[microcanonical]", double, long double, mpfr_real) {
  // E a hair above E_min (D down to 1e-14 |E_min|): D to 1.35 units of the type's precision
  // (3e-16 in double, where the subtraction is carried in double-double).
  using Real = TestType;
  const test::TypePrecision<Real> precision;
  const Chain<Real> c = Chain<double>({0.7, 1.9, 0.4}, {0.8, 1.1, 1.7}, 2.5).cast<Real>();
  const Real e_min = minimum_energy(c);
  for (double fraction : {1e-3, 1e-9, 1e-14}) {
    const Real energy = e_min * (1 - Real(fraction));
    const Real d = excitation_energy(c, energy);
    // the exact value of E + sum_j g S_j l_j for the stored values, at 60 digits
    const working_precision guard(60);
    mpfr_real exact(energy);
    for (std::size_t j = 0; j < c.size(); ++j)
      for (std::size_t k = j; k < c.size(); ++k)
        exact += mpfr_real(c.mass(k)) * mpfr_real(c.length(j)) * mpfr_real(c.gravity());
    INFO("E - E_min ~ " << fraction << " |E_min|: off by "
                        << test::relative_distance(d, exact) / test::unit<Real>() << " units");
    CHECK(test::relative_distance(d, exact) <= 1.35 * test::unit<Real>());
  }
}

TEST_CASE("Var K_i: momenta sampled on the energy shell give <K_i^2 | phi, E> = (E - U)^2 "
          "[(tr X_i)^2 + 2 tr X_i^2] / (N (N + 2))",
          "[microcanonical]") {
  // At fixed angles the momenta are uniform on p^T A^{-1} p / 2 = K: with A = L L^T, p = L y and
  // y uniform on the sphere |y|^2 = 2 K. K_i = m_i |v_i|^2 / 2 with v_i = sum_{j <= i} l_j
  // phidot_j (cos phi_j, sin phi_j), phidot = A^{-1} p: literally the definition.
  const std::vector<double> m{0.7, 1.9, 0.4}, l{0.8, 1.1, 1.7}, phi{0.4, -1.1, 2.3};
  const std::size_t n = m.size();
  const double kinetic = 1.3;
  using Matrix = Eigen::MatrixXd;
  Matrix a(n, n);
  for (std::size_t j = 0; j < n; ++j)
    for (std::size_t k = 0; k < n; ++k) {
      double tail = 0;
      for (std::size_t i = std::max(j, k); i < n; ++i) tail += m[i];
      a(Eigen::Index(j), Eigen::Index(k)) = tail * l[j] * l[k] * std::cos(phi[j] - phi[k]);
    }
  const Eigen::LLT<Matrix> cholesky(a);
  const Matrix lower = cholesky.matrixL();
  const auto d = oracle::dense_traces<double>(m, l, phi);
  std::mt19937_64 rng(7);
  std::normal_distribution<double> normal;
  const int samples = 400000;
  std::vector<double> sum(n, 0.0), sum2(n, 0.0), sum4(n, 0.0);
  for (int s = 0; s < samples; ++s) {
    Eigen::VectorXd y(n);
    for (std::size_t i = 0; i < n; ++i) y(Eigen::Index(i)) = normal(rng);
    y *= std::sqrt(2 * kinetic) / y.norm();
    const Eigen::VectorXd phidot = cholesky.solve(lower * y);
    double vx = 0, vy = 0;
    for (std::size_t i = 0; i < n; ++i) {
      vx += l[i] * phidot(Eigen::Index(i)) * std::cos(phi[i]);
      vy += l[i] * phidot(Eigen::Index(i)) * std::sin(phi[i]);
      const double k = m[i] * (vx * vx + vy * vy) / 2;
      sum[i] += k;
      sum2[i] += k * k;
      sum4[i] += k * k * k * k;
    }
  }
  const double nn = double(n);
  for (std::size_t i = 0; i < n; ++i) {
    const double mean = sum[i] / samples, mean2 = sum2[i] / samples;
    const double se = std::sqrt((mean2 - mean * mean) / samples);
    const double se2 = std::sqrt((sum4[i] / samples - mean2 * mean2) / samples);
    const double x = d.trace_X[i];
    INFO("i = " << i << ": <K_i> " << mean << " +- " << se << ", <K_i^2> " << mean2 << " +- " << se2);
    CHECK(std::abs(mean - x * kinetic / nn) < 5 * se);
    CHECK(std::abs(mean2 - kinetic * kinetic * (x * x + 2 * d.trace_X_squared[i]) /
                               (nn * (nn + 2))) < 5 * se2);
  }
}

namespace {

/// The critical energies sum_j (+-gamma_j) of the potential, sorted, each once.
std::vector<double> critical_energies(const Chain<double>& c) {
  std::vector<double> critical{0.0};
  for (std::size_t j = 0; j < c.size(); ++j) {
    std::vector<double> next;
    for (double v : critical) {
      next.push_back(v + c.potential_coefficient(j));
      next.push_back(v - c.potential_coefficient(j));
    }
    critical.swap(next);
  }
  std::sort(critical.begin(), critical.end());
  critical.erase(std::unique(critical.begin(), critical.end()), critical.end());
  return critical;
}

/// Every critical energy sum_j (+-gamma_j) > E_min (the separatrices and the top of the
/// potential), each exactly and, with `hair`, 1e-9 of the top above and below it; then 1.5, 10
/// and 1000 times the top.
std::vector<double> separatrix_energies(const Chain<double>& c, bool hair) {
  const std::vector<double> critical = critical_energies(c);
  const double top = critical.back();
  std::vector<double> energies;
  for (std::size_t k = 1; k < critical.size(); ++k) {
    energies.push_back(critical[k]);
    if (hair) {
      energies.push_back(critical[k] + 1e-9 * top);
      energies.push_back(critical[k] - 1e-9 * top);
    }
  }
  for (double f : {1.5, 10.0, 1e3}) energies.push_back(f * top);
  return energies;
}

/// The double run's bars (at the CLI's default tolerance: 1e-13 for N = 2, 1e-11 for N = 3) must
/// cover its distance from the long double run (3 more digits, a 1000x tighter tolerance) at
/// every energy. Returns the number of estimates checked.
int check_covered_by_long_double(const Chain<double>& c, const std::vector<double>& energies) {
  const std::size_t n = c.size();
  MicrocanonicalOptions fast, exact;
  fast.tolerance = n == 2 ? 1e-13 : 1e-11;
  exact.tolerance = *fast.tolerance * 1e-3;
  const Chain<long double> cl = c.cast<long double>();
  int checked = 0;
  for (double e : energies) {
    const auto r = microcanonical_average(c, e, fast);
    const auto t = microcanonical_average(cl, (long double)e, exact);
    INFO("N = " << n << ", m1 = " << c.mass(0) << ", E = " << e);
    CHECK(r.converged);
    const auto covers = [&](const Estimate<double>& a, const Estimate<long double>& b) {
      INFO("double " << a.value << " +- " << a.error << ", long double " << double(b.value)
                     << " +- " << double(b.error));
      CHECK(std::abs(double(a.value - b.value)) <= a.error);
      CHECK(double(b.error) <= a.error);
      ++checked;
    };
    for (std::size_t i = 0; i < n; ++i) {
      covers(r.kinetic[i], t.kinetic[i]);
      covers(r.cos_angle[i], t.cos_angle[i]);
      covers(r.kinetic_variance[i], t.kinetic_variance[i]);
    }
    covers(r.density_of_states, t.density_of_states);
  }
  return checked;
}

}  // namespace

TEST_CASE("errors cover the truth at separatrix energies and above the top (double against "
          "long double)",
          "[microcanonical]") {
  // N = 2 at every separatrix, exactly and a hair off; N = 3 exactly on them (the hairs: slow
  // test below). tests/bench/near_minimum_ladder.py --separatrix checks N = 2 there against an
  // independent mpmath quadrature of the definition.
  int checked = 0;
  for (const auto& c : {Chain<double>({1.0, 1.0}, {1.0, 1.0}, 1.0),
                        Chain<double>({1.0, 0.3}, {1.3, 0.6}, 9.81)})
    checked += check_covered_by_long_double(c, separatrix_energies(c, true));
  const Chain<double> c3({0.7, 1.9, 0.4}, {0.8, 1.1, 1.7}, 2.5);
  checked += check_covered_by_long_double(c3, separatrix_energies(c3, false));
  CHECK(checked > 150);
}

TEST_CASE("errors cover the truth a hair off the N = 3 separatrices and at E = 0 of N = 4",
          "[microcanonical][.slow]") {
  const Chain<double> c3({0.7, 1.9, 0.4}, {0.8, 1.1, 1.7}, 2.5);
  CHECK(check_covered_by_long_double(c3, separatrix_energies(c3, true)) > 100);

  // N = 4 unit chain at E = 0, itself a critical energy (4 - 3 - 2 + 1 = 0): z = 0 along curves
  // of the torus, where E + rho ~ rho must not be formed as D - (S - rho) (~S - S).
  const Chain<double> c4(std::vector<double>(4, 1.0), std::vector<double>(4, 1.0), 1.0);
  MicrocanonicalOptions loose, tight;
  loose.tolerance = 1e-5;
  tight.tolerance = 1e-7;
  loose.threads = tight.threads = 2;
  const auto r = microcanonical_average(c4, 0.0, loose);
  const auto t = microcanonical_average(c4.cast<long double>(), 0.0L, tight);
  CHECK(r.converged);
  for (std::size_t i = 0; i < 4; ++i) {
    INFO("N = 4, E = 0, i = " << i << ": " << r.kinetic[i].value << " +- " << r.kinetic[i].error
                               << " against " << double(t.kinetic[i].value));
    CHECK(std::abs(double(r.kinetic[i].value - t.kinetic[i].value)) <= r.kinetic[i].error);
    CHECK(std::abs(double(r.kinetic_variance[i].value - t.kinetic_variance[i].value)) <=
          r.kinetic_variance[i].error);
  }
}

namespace {

/// Microcanonical options for a number type: the tolerance at 450 units of its precision (in
/// double 1e-13, the N = 2 default), MPFR at test_digits.
template <class Real>
MicrocanonicalOptions typed_options() {
  MicrocanonicalOptions options;
  if constexpr (is_mpfr_v<Real>) {
    options.digits = test::test_digits;
  } else {
    options.tolerance = 450 * test::unit<Real>();
  }
  return options;
}

/// The chain at excitation D and reference_digits, computed once for the three types.
const MicrocanonicalAverages<mpfr_real>& reference_run(const std::string& name,
                                                       const Chain<double>& chain, double excitation) {
  static std::map<std::string, MicrocanonicalAverages<mpfr_real>> references;
  if (!references.count(name)) {
    const test::ReferencePrecision wide;
    MicrocanonicalOptions options;
    options.digits = test::reference_digits;
    references[name] = microcanonical_average_excitation(chain.cast<mpfr_real>(),
                                                         mpfr_real(excitation), options);
  }
  return references.at(name);
}

}  // namespace

// Generic over the number type (double, long double, MPFR at test_digits): N = 2 at excitations
// from the bottom of the well to above the top, on a separatrix, with a light first mass and an
// extreme length, against the same chain at reference_digits.
TEMPLATE_TEST_CASE("microcanonical N = 2 in every number type against a 40-digit run",
                   "[microcanonical]", double, long double, mpfr_real) {
  using Real = TestType;
  struct Case {
    const char* name;
    Chain<double> chain;
    double excitation;  // D = E - E_min, as a fraction of |E_min| (exact in every type)
  };
  const Chain<double> c({1.0, 0.3}, {1.3, 0.6}, 9.81), unit({1.0, 1.0}, {1.0, 1.0}, 1.0);
  for (const Case& k : {Case{"near the minimum", c, 1e-10}, Case{"inside the well", c, 0.5},
                        Case{"above the top", c, 3.0},
                        Case{"on the separatrix E = gamma_2 - gamma_1", unit, 2.0 / 3.0},
                        Case{"light first mass", Chain<double>({1e-6, 1.0}, {1.0, 1.0}, 1.0), 0.5},
                        Case{"short lower link", Chain<double>({1.0, 1.0}, {1.0, 1e-3}, 1.0), 0.5}}) {
    const double depth = -minimum_energy(k.chain);
    const double excitation = k.excitation * depth;
    const MicrocanonicalAverages<mpfr_real>& reference =
        reference_run(k.name, k.chain, excitation);
    REQUIRE(reference.converged);
    const test::TypePrecision<Real> precision;
    const auto r = microcanonical_average_excitation(k.chain.template cast<Real>(), Real(excitation),
                                                     typed_options<Real>());
    INFO(k.name << ": D = " << excitation);
    CHECK(r.converged);
    for (std::size_t i = 0; i < 2; ++i) {
      const test::ReferencePrecision wide;
      const mpfr_real second_moment = reference.kinetic_variance[i].value +
                                      reference.kinetic[i].value * reference.kinetic[i].value;
      INFO("particle " << i + 1 << ": <K> " << test::as_double(r.kinetic[i].value) << " +- "
                       << test::as_double(r.kinetic[i].error) << ", off by "
                       << test::relative_distance(r.kinetic[i].value, reference.kinetic[i].value) /
                              test::unit<Real>()
                       << " units");
      CHECK(test::distance(r.kinetic[i].value, reference.kinetic[i].value) <=
            test::as_double(r.kinetic[i].error));
      CHECK(test::relative_distance(r.kinetic[i].value, reference.kinetic[i].value) <=
            450 * test::unit<Real>());
      CHECK(test::distance(r.kinetic_variance[i].value, reference.kinetic_variance[i].value) <=
            test::as_double(r.kinetic_variance[i].error));
      CHECK(test::relative_distance(r.kinetic_variance[i].value, reference.kinetic_variance[i].value,
                                    second_moment) <= 450 * test::unit<Real>());
      CHECK(test::distance(r.cos_angle[i].value, reference.cos_angle[i].value) <=
            test::as_double(r.cos_angle[i].error));
    }
  }
}

TEST_CASE("microcanonical qmc has no MPFR run", "[microcanonical]") {
  const working_precision guard(30 + guard_digits);
  MicrocanonicalOptions d30;
  d30.digits = 30;
  const Chain<mpfr_real> c5(std::vector<mpfr_real>(5, mpfr_real(1)),
                            std::vector<mpfr_real>(5, mpfr_real(1)), mpfr_real(1));
  CHECK_THROWS_AS(microcanonical_average(c5, mpfr_real(0), d30), invalid_input);
}

TEST_CASE("microcanonical qmc: finite from the bottom of the well to far above the top",
          "[microcanonical]") {
  // log-sum-exp weights: no NaN at any excitation; near the bottom the harmonic limit D/(2N).
  const Chain<double> c({1.0, 0.5, 2.0, 1.0, 0.7}, {1.0, 1.2, 0.8, 1.0, 0.5}, 1.0);
  const double depth = -minimum_energy(c);
  for (double fraction : {1e-12, 1e-6, 1e-2, 1.0, 1e6}) {
    for (std::uint64_t seed : {1, 2}) {
      MicrocanonicalOptions q;
      q.points = 1 << 10;
      q.shifts = 8;
      q.seed = seed;
      const double d = fraction * depth;
      const auto r = microcanonical_average_excitation(c, d, q);
      INFO("D/|E_min| = " << fraction << ", seed " << seed);
      CHECK(r.quadrature == Method::qmc);
      CHECK(r.converged);
      for (std::size_t i = 0; i < 5; ++i) {
        CHECK(std::isfinite(r.kinetic[i].value));
        CHECK(std::isfinite(r.kinetic[i].error));
        CHECK(std::isfinite(r.cos_angle[i].value));
        CHECK(std::isfinite(r.kinetic_variance[i].value));
        if (fraction <= 1e-6) {
          CHECK(std::abs(r.kinetic[i].value - d / 10) <= r.kinetic[i].error + 10 * fraction * d);
        }
      }
      CHECK(std::isfinite(r.density_of_states.value));
      CHECK(r.density_of_states.value > 0);
    }
  }
}

TEST_CASE("N = 3: nested integral, QMC, torus trapezoid and brute force agree",
          "[microcanonical]") {
  const Chain<double> c({1.0, 0.7, 1.4}, {1.0, 1.2, 0.8}, 1.0);
  const double top = gamma_sum(c);
  for (double fraction : {-0.6, 0.0, 0.4}) {
    const double energy = fraction * top;
    MicrocanonicalOptions exact;
    exact.tolerance = 1e-11;
    const auto r = microcanonical_average(c, energy, exact);
    REQUIRE(r.converged);
    INFO("E = " << energy);
    // QMC: within its statistical bars
    MicrocanonicalOptions q;
    q.rule = Rule::qmc;
    q.points = 1 << 12;
    const auto m = microcanonical_average(c, energy, q);
    CHECK(m.quadrature == Method::qmc);
    for (int i = 0; i < 3; ++i) {
      CHECK(std::abs(m.kinetic[i].value - r.kinetic[i].value) <= m.kinetic[i].error + r.kinetic[i].error);
      CHECK(std::abs(m.cos_angle[i].value - r.cos_angle[i].value) <= m.cos_angle[i].error + r.cos_angle[i].error);
    }
    CHECK(std::abs(m.density_of_states.value - r.density_of_states.value) <=
          m.density_of_states.error + r.density_of_states.error);
    // torus trapezoid (algebraic convergence through the kinks; its bar is the last difference)
    MicrocanonicalOptions t;
    t.rule = Rule::torus;
    t.tolerance = 1e-7;
    t.max_points_per_dim = 512;
    const auto tr = microcanonical_average(c, energy, t);
    CHECK(tr.quadrature == Method::torus_trapezoid);
    for (int i = 0; i < 3; ++i) {
      CHECK(std::abs(tr.kinetic[i].value - r.kinetic[i].value) <= tr.kinetic[i].error + r.kinetic[i].error);
      CHECK(tr.kinetic[i].error < 1e-5 * r.kinetic[i].value);
    }
  }
}

TEST_CASE("N = 3 against brute force over all three angles (dense A)", "[microcanonical]") {
  // phi_1 over its exact accessible arc (tanh-sinh: sqrt ends), (phi_2, phi_3) on an n x n
  // trapezoid grid; the kinks make that O(n^-2), so the oracle's own error is taken from n vs 2n.
  const Chain<double> c({1.0, 1.0, 1.0}, {1.0, 1.0, 1.0}, 1.0);
  const double energy = -1.5;
  boost::math::quadrature::tanh_sinh<double> rule(10);
  const auto oracle = [&](int n) {
    std::vector<double> sums(7, 0.0);
    const double g1 = c.potential_coefficient(0);
    for (int a = 0; a < n; ++a) {
      for (int b = 0; b < n; ++b) {
        const double phi2 = 2 * kPi * a / n, phi3 = 2 * kPi * b / n;
        const double x = -(energy + c.potential_coefficient(1) * std::cos(phi2) +
                           c.potential_coefficient(2) * std::cos(phi3)) /
                         g1;
        if (x >= 1) continue;
        const double half = x <= -1 ? kPi : std::acos(x);
        for (int q = 0; q < 4; ++q) {
          sums[q] += rule.integrate(
              [&](double phi1) { return definition_integrand(c, {phi1, phi2, phi3}, energy)[q]; },
              -half, half, 1e-12);
        }
      }
    }
    return std::vector<double>{sums[1] / sums[0], sums[2] / sums[0], sums[3] / sums[0]};
  };
  const auto coarse = oracle(24), fine = oracle(48);
  const auto r = microcanonical_average(c, energy);
  for (int i = 0; i < 3; ++i) {
    const double oracle_error = std::abs(fine[i] - coarse[i]);
    INFO("i = " << i << ": library " << r.kinetic[i].value << ", oracle " << fine[i] << " +- "
                << oracle_error);
    CHECK(oracle_error < 1e-3 * fine[i]);  // the oracle itself is meaningful
    CHECK(std::abs(r.kinetic[i].value - fine[i]) <= oracle_error);
  }
}

TEST_CASE("ensemble equivalence: Laplace transforms give the canonical averages",
          "[microcanonical]") {
  // <K_i>_beta = ∫ Omega(E) e^{-beta E} <K_i>_E dE / ∫ Omega(E) e^{-beta E} dE, and
  // ∫ Omega(E) e^{-beta E} dE = Z(beta). The E integrals are split at the critical energies
  // -sum_j (+-gamma_j), where Omega is not smooth.
  const auto laplace = [](const Chain<double>& c, double beta, const MicrocanonicalOptions& o,
                          double tolerance) {
    const std::size_t n = c.size();
    const std::vector<double> critical = critical_energies(c);
    const double bottom = critical.front();
    std::vector<double> out(n + 1, 0.0);  // Z, then numerators
    boost::math::quadrature::tanh_sinh<double> finite(8);
    boost::math::quadrature::exp_sinh<double> tail(8);
    for (std::size_t q = 0; q <= n; ++q) {
      const auto f = [&](double energy) {
        if (!(energy > bottom)) return 0.0;
        const auto r = microcanonical_average(c, energy, o);
        const double weight = r.density_of_states.value * std::exp(-beta * (energy - bottom));
        return q == 0 ? weight : weight * r.kinetic[q - 1].value;
      };
      for (std::size_t k = 0; k + 1 < critical.size(); ++k) {
        out[q] += finite.integrate(f, critical[k], critical[k + 1], tolerance);
      }
      const double top = critical.back();
      // (N = 1: Omega has an integrable log singularity at the separatrix E = top)
      out[q] += tail.integrate([&](double x) { return top + x > top ? f(top + x) : 0.0; },
                               tolerance);
    }
    return out;
  };

  SECTION("N = 1: Z(beta) = sqrt(2 pi / beta) l sqrt(m) 2 pi I0(beta m g l) exactly") {
    const Chain<double> c({1.7}, {0.6}, 2.0);
    for (double beta : {0.3, 2.0}) {
      const auto t = laplace(c, beta, {}, 1e-12);
      const double a = beta * c.potential_coefficient(0);
      const double z = std::sqrt(2 * kPi / beta) * 0.6 * std::sqrt(1.7) * 2 * kPi *
                       boost::math::cyl_bessel_i(0, a) * std::exp(-a);  // shifted by E_min
      CHECK(std::abs(t[0] / z - 1) < 1e-9);
      // canonical <K> = 1/(2 beta) for one degree of freedom
      CHECK(std::abs(t[1] / t[0] * 2 * beta - 1) < 1e-9);
    }
  }
  SECTION("N = 2 against reduced_integral_average") {
    const Chain<double> c({1.0, 0.6}, {1.0, 1.3}, 1.0);
    for (double beta : {0.5, 3.0}) {
      const auto t = laplace(c, beta, {}, 1e-11);
      const auto canonical = reduced_integral_average(c, beta);
      for (int i = 0; i < 2; ++i) {
        INFO("beta = " << beta << ", i = " << i);
        CHECK(std::abs(beta * t[1 + i] / t[0] / canonical.beta_kinetic[i].value - 1) < 1e-9);
      }
    }
  }
}

TEST_CASE("ensemble equivalence for N = 3 against torus_average", "[microcanonical][.slow]") {
  const Chain<double> c({1.0, 1.0, 1.0}, {1.0, 1.0, 1.0}, 1.0);
  const double beta = 1.0;
  std::vector<double> critical{-6, -4, -2, 0, 2, 4, 6};
  MicrocanonicalOptions o;
  o.tolerance = 1e-9;
  o.threads = 2;
  boost::math::quadrature::tanh_sinh<double> finite(6);
  boost::math::quadrature::exp_sinh<double> tail(6);
  std::vector<double> t(4, 0.0);
  std::map<double, MicrocanonicalAverages<double>> cache;  // one evaluation per E for all q
  for (std::size_t q = 0; q < 4; ++q) {
    const auto f = [&](double energy) {
      if (!(energy > -6)) return 0.0;
      auto it = cache.find(energy);
      if (it == cache.end()) it = cache.emplace(energy, microcanonical_average(c, energy, o)).first;
      const auto& r = it->second;
      const double w = r.density_of_states.value * std::exp(-beta * (energy + 6));
      return q == 0 ? w : w * r.kinetic[q - 1].value;
    };
    for (std::size_t k = 0; k + 1 < critical.size(); ++k) {
      t[q] += finite.integrate(f, critical[k], critical[k + 1], 1e-8);
    }
    t[q] += tail.integrate([&](double x) { return f(6 + x); }, 1e-8);
  }
  const auto canonical = torus_average(c, beta);
  for (int i = 0; i < 3; ++i) {
    CHECK(std::abs(beta * t[1 + i] / t[0] / canonical.beta_kinetic[i].value - 1) < 1e-7);
  }
}

TEST_CASE("high-energy limit: <K_i>_E / <K>_E -> (beta <K_i>)_{beta -> 0} / (N/2)",
          "[microcanonical]") {
  // F_p(E, rho) / (2 pi E^p) = 1 + O(rho^2/E^2): at E = 1e4 sum gamma the ratio is the
  // uniform-angle (beta -> 0) canonical one to ~1e-8.
  {
    const Chain<double> c({1.0, 0.25}, {1.0, 0.5}, 1.0);
    const auto limit = high_temperature_limit(c);
    const auto r = microcanonical_average(c, 1e4 * gamma_sum(c));
    for (int i = 0; i < 2; ++i) {
      CHECK(std::abs(r.kinetic[i].value / r.kinetic_total.value / limit.beta_kinetic[i].value - 1) < 1e-7);
    }
  }
  {
    const Chain<double> c({1.0, 2.0, 0.5}, {1.0, 0.8, 1.1}, 1.0);
    const auto limit = torus_average(c, 1e-12);
    MicrocanonicalOptions o;
    o.tolerance = 1e-10;
    const auto r = microcanonical_average(c, 1e4 * gamma_sum(c), o);
    for (int i = 0; i < 3; ++i) {
      CHECK(std::abs(r.kinetic[i].value / r.kinetic_total.value / (limit.beta_kinetic[i].value / 1.5) - 1) < 1e-7);
    }
  }
}

TEST_CASE("error estimates cover the true error", "[microcanonical]") {
  SECTION("integral rule, loose against tight") {
    const Chain<double> c({1.0, 0.5, 2.0}, {1.0, 1.0, 0.5}, 1.0);
    const double top = gamma_sum(c);
    for (double fraction : {-0.8, -0.1, 0.3, 1.2}) {
      MicrocanonicalOptions loose, tight;
      loose.tolerance = 1e-5;
      tight.tolerance = 1e-12;
      const auto a = microcanonical_average(c, fraction * top, loose);
      const auto b = microcanonical_average(c, fraction * top, tight);
      for (int i = 0; i < 3; ++i) {
        INFO("E/sum gamma = " << fraction << ", i = " << i);
        CHECK(std::abs(a.kinetic[i].value - b.kinetic[i].value) <= a.kinetic[i].error + b.kinetic[i].error);
        CHECK(std::abs(a.cos_angle[i].value - b.cos_angle[i].value) <= a.cos_angle[i].error + b.cos_angle[i].error);
      }
      CHECK(std::abs(a.density_of_states.value - b.density_of_states.value) <=
            a.density_of_states.error + b.density_of_states.error);
    }
  }
  SECTION("QMC bars over seeds (N = 3 against the integral rule)") {
    const Chain<double> c({1.0, 1.0, 1.0}, {1.0, 1.0, 1.0}, 1.0);
    const auto exact = microcanonical_average(c, 0.0);
    int covered = 0, total = 0;
    for (std::uint64_t seed = 1; seed <= 20; ++seed) {
      MicrocanonicalOptions q;
      q.rule = Rule::qmc;
      q.points = 1 << 10;
      q.seed = seed;
      const auto m = microcanonical_average(c, 0.0, q);
      for (int i = 0; i < 3; ++i) {
        ++total;
        covered += std::abs(m.kinetic[i].value - exact.kinetic[i].value) <= m.kinetic[i].error;
      }
    }
    INFO(covered << " of " << total << " bars cover");
    CHECK(covered >= total - 3);  // 99.9% Student-t bars
  }
}

TEST_CASE("QMC results do not depend on the thread count", "[microcanonical]") {
  const Chain<double> c(std::vector<double>(6, 1.0), std::vector<double>(6, 1.0), 1.0);
  MicrocanonicalOptions a, b;
  a.points = b.points = 1 << 10;
  a.shifts = b.shifts = 8;
  b.threads = 2;
  const auto x = microcanonical_average(c, 0.0, a), y = microcanonical_average(c, 0.0, b);
  CHECK(x.quadrature == Method::qmc);
  for (int i = 0; i < 6; ++i) CHECK(x.kinetic[i].value == y.kinetic[i].value);
}

TEST_CASE("microcanonical bad input throws invalid_input", "[microcanonical]") {
  const Chain<double> c({1.0, 1.0}, {1.0, 1.0}, 1.0);
  CHECK_THROWS_AS(microcanonical_average(c, std::numeric_limits<double>::quiet_NaN()), invalid_input);
  CHECK_THROWS_AS(microcanonical_average(c, std::numeric_limits<double>::infinity()), invalid_input);
  CHECK_THROWS_AS(microcanonical_average(c, -3.0), invalid_input);  // E = E_min
  CHECK_THROWS_AS(microcanonical_average(c, -4.0), invalid_input);
  CHECK_THROWS_AS(microcanonical_average(c, std::nextafter(-3.0, -4.0)), invalid_input);
  CHECK_NOTHROW(microcanonical_average(c, std::nextafter(-3.0, 0.0)));  // D = 4.4e-16
  CHECK_THROWS_AS(microcanonical_average_excitation(c, 0.0), invalid_input);
  CHECK_THROWS_AS(microcanonical_average_excitation(c, -1e-300), invalid_input);
  CHECK_THROWS_AS(microcanonical_average_excitation(c, std::numeric_limits<double>::quiet_NaN()),
                  invalid_input);
  CHECK_THROWS_AS(microcanonical_average_excitation(c, std::numeric_limits<double>::infinity()),
                  invalid_input);
  CHECK(minimum_energy(c) == -3.0);
  CHECK(excitation_energy(c, -2.5) == 0.5);
  MicrocanonicalOptions o;
  o.tolerance = 0;
  CHECK_THROWS_AS(microcanonical_average(c, 0.0, o), invalid_input);
  o = {};
  o.rule = Rule::qmc;
  o.points = 1000;
  CHECK_THROWS_AS(microcanonical_average(c, 0.0, o), invalid_input);
  o.points = 1024;
  o.shifts = 2;
  CHECK_THROWS_AS(microcanonical_average(c, 0.0, o), invalid_input);
  o.shifts = 16;
  o.sigmas = -1;
  CHECK_THROWS_AS(microcanonical_average(c, 0.0, o), invalid_input);
  o = {};
  o.digits = 20;  // digits > 16 are for mpfr_real
  CHECK_THROWS_AS(microcanonical_average(c, 0.0, o), invalid_input);
  o = {};
  o.threads = 0;
  CHECK_THROWS_AS(microcanonical_average(c, 0.0, o), invalid_input);
  o = {};
  o.rule = Rule::integral;
  const Chain<double> long_chain(std::vector<double>(8, 1.0), std::vector<double>(8, 1.0), 1.0);
  CHECK_THROWS_AS(microcanonical_average(long_chain, 0.0, o), invalid_input);
}

TEST_CASE("microcanonical rule and default tolerance are the library's (front ends ask them)",
          "[microcanonical]") {
  using Rule = MicrocanonicalOptions::Rule;
  for (std::size_t n = 1; n <= 4; ++n) CHECK(resolve_microcanonical_rule(n, Rule::automatic) == Rule::integral);
  for (std::size_t n : {5, 8, 256}) CHECK(resolve_microcanonical_rule(n, Rule::automatic) == Rule::qmc);
  for (const Rule r : {Rule::integral, Rule::torus, Rule::qmc})
    for (std::size_t n : {2, 7}) CHECK(resolve_microcanonical_rule(n, r) == r);
  CHECK(default_microcanonical_tolerance(1) == 1e-13);
  CHECK(default_microcanonical_tolerance(2) == 1e-13);
  CHECK(default_microcanonical_tolerance(3) == 1e-11);
  CHECK(default_microcanonical_tolerance(4) == 1e-9);
  // The automatic rule at N = 5 is qmc, in the result as well.
  MicrocanonicalOptions o;
  o.points = 1024;
  const auto r = microcanonical_average(Chain<double>({1, 1, 1, 1, 1}, {1, 1, 1, 1, 1}), 0.0, o);
  CHECK(r.quadrature == Method::qmc);
}

TEST_CASE("microcanonical_options: one set of options for both ensembles, checked by the library",
          "[microcanonical][api]") {
  using Rule = MicrocanonicalOptions::Rule;
  // Refused with one line that names `needle`.
  const auto refused = [](std::size_t n, const AverageOptions& o, const std::string& needle) {
    const std::string message = pendavg_test::rejection([&] { microcanonical_options(o, n); });
    UNSCOPED_INFO(message);  // shown by the CHECK of the result
    return message.find(needle) != std::string::npos && message.find('\n') == std::string::npos;
  };
  AverageOptions o;
  CHECK(microcanonical_options(o, 2).rule == Rule::automatic);
  CHECK_FALSE(microcanonical_options(o, 2).tolerance.has_value());  // the per-N default
  o.method = AverageMethod::transfer;
  CHECK(refused(8, o, "not available for microcanonical"));
  o.method = AverageMethod::series;
  CHECK(refused(2, o, "not available for microcanonical"));
  o = {};
  o.tolerance = 1e-6;
  CHECK(microcanonical_options(o, 3).tolerance == 1e-6);
  CHECK(refused(5, o, "tol"));  // auto is qmc for N = 5
  o.digits = 30;
  CHECK(refused(3, o, "tol is for double runs"));
  o = {};
  o.samples = 2048;
  CHECK(refused(2, o, "samples"));  // the integral rule
  o.method = AverageMethod::qmc;
  CHECK(microcanonical_options(o, 2).points == 2048);
  o.samples = 131072;
  CHECK(refused(2, o, "power of two"));
  o = {};
  o.seed = 9;
  CHECK(microcanonical_options(o, 40).seed == 9);  // qmc's lattices cover N <= 256
  CHECK(refused(257, o, "N <= 256"));
  o = {};
  o.digits = 20;
  CHECK(refused(5, o, "double only"));
  CHECK(microcanonical_options(o, 4).digits == 20);
  o.method = AverageMethod::torus_trapezoid;
  CHECK(refused(3, o, "algebraically"));
  o = {};
  o.method = AverageMethod::integral;
  CHECK(refused(7, o, "N <= 6"));
  // What the rules use, as front ends ask it (pendavg table spreads one set over its rows).
  CHECK(microcanonical_rule_uses_option(Rule::integral, AverageOption::tolerance, 16));
  CHECK_FALSE(microcanonical_rule_uses_option(Rule::integral, AverageOption::tolerance, 30));
  CHECK_FALSE(microcanonical_rule_uses_option(Rule::qmc, AverageOption::tolerance, 16));
  for (const AverageOption q : {AverageOption::samples, AverageOption::shifts, AverageOption::seed}) {
    CHECK(microcanonical_rule_uses_option(Rule::qmc, q, 16));
    CHECK_FALSE(microcanonical_rule_uses_option(Rule::torus, q, 16));
  }
  CHECK(std::string(microcanonical_rule_name(Rule::automatic, 3)) == "integral");
  CHECK(std::string(microcanonical_rule_name(Rule::automatic, 6)) == "qmc");
  CHECK(std::string(microcanonical_rule_name(Rule::torus, 2)) == "torus-trapezoid");
  // Unset tolerance: the per-N default, the same bits as that default spelled out.
  const Chain<double> c({1.0, 2.0}, {1.0, 0.5}, 1.0);
  MicrocanonicalOptions implicit, spelled;
  spelled.tolerance = default_microcanonical_tolerance(2);
  const auto a = microcanonical_average(c, 0.3, implicit);
  const auto b = microcanonical_average(c, 0.3, spelled);
  CHECK(a.kinetic[0].value == b.kinetic[0].value);
  CHECK(a.kinetic[0].error == b.kinetic[0].error);
  // A long chain by qmc beyond the old 32-particle cap: finite, with bars.
  AverageOptions q;
  q.samples = 1024;
  q.shifts = 8;
  const MicrocanonicalOptions long_run = microcanonical_options(q, 40);
  const auto r = microcanonical_average(
      Chain<double>(std::vector<double>(40, 1.0), std::vector<double>(40, 1.0), 1.0), 0.0, long_run);
  CHECK(r.quadrature == Method::qmc);
  for (const auto& k : r.kinetic) {
    CHECK(std::isfinite(k.value));
    CHECK(std::isfinite(k.error));
    CHECK(k.error > 0);
  }
}

// A process that asks for many precisions (a notebook, a --digits sweep) keeps the tanh-sinh
// tables of the last few only; a table in use stays valid when it leaves the cache.
TEST_CASE("microcanonical MPFR tanh-sinh tables: a bounded cache, held tables stay valid",
          "[microcanonical][mpfr]") {
  using Table = detail::TanhSinhTable<mpfr_real>;
  std::shared_ptr<const Table> first;
  {
    const working_precision precision(20);
    first = Table::shared();
    CHECK(Table::shared() == first);  // the same precision: the cached table
  }
  const std::size_t nodes = first->levels.back().size();
  for (int k = 0; k <= static_cast<int>(Table::max_cached_precisions); ++k) {
    const working_precision precision(21 + k);
    CHECK(Table::shared() != first);
  }
  const working_precision precision(20);
  const std::shared_ptr<const Table> again = Table::shared();
  CHECK(again != first);              // evicted, rebuilt
  CHECK(first.use_count() == 1);      // held here alone, and still whole
  CHECK(first->levels.back().size() == nodes);
  CHECK(again->levels.back().size() == nodes);
  CHECK(again->levels.back().front().weight == first->levels.back().front().weight);
}
