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
//   * limits: E -> infinity (canonical beta -> 0) and E -> E_min (harmonic equipartition);
//   * error estimates against tighter runs; bad input.
#include <catch2/catch.hpp>

#include "oracle/dense_traces.hpp"
#include "pendavg/chain.hpp"
#include "engine/double_pendulum.hpp"
#include "engine/microcanonical.hpp"
#include "engine/torus.hpp"

#include <boost/math/quadrature/exp_sinh.hpp>
#include <boost/math/quadrature/gauss.hpp>
#include <boost/math/quadrature/tanh_sinh.hpp>
#include <boost/math/special_functions/bessel.hpp>

#include <cmath>
#include <limits>
#include <map>
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
/// [0] sqrt(det A) (E - U)^{N/2-1}, [1 + i] the same times tr X_i (E - U)/N, [1 + N + i] times cos phi_i.
std::vector<double> definition_integrand(const Chain<double>& c, const std::vector<double>& phi,
                                         double energy) {
  const std::size_t n = c.size();
  std::vector<double> out(1 + 2 * n, 0.0);
  double u = 0;
  for (std::size_t j = 0; j < n; ++j) u -= c.potential_coefficient(j) * std::cos(phi[j]);
  const double kinetic = energy - u;
  if (!(kinetic > 0)) return out;
  const auto d = oracle::dense_traces<double>(c.masses(), c.lengths(), phi);
  const double w = std::exp(d.log_sqrt_det_A) * std::pow(kinetic, double(n) / 2 - 1);
  out[0] = w;
  for (std::size_t i = 0; i < n; ++i) {
    out[1 + i] = w * d.trace_X[i] * kinetic / double(n);
    out[1 + n + i] = w * std::cos(phi[i]);
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
  std::vector<double> total(5, 0.0);
  for (std::size_t q = 0; q < 5; ++q) {
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
  std::vector<double> total(5, 0.0);
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

/// <K_1>, <K_2>, <cos phi_1>, <cos phi_2> from the integrals of an oracle.
std::vector<double> oracle_averages(const std::vector<double>& t) {
  return {t[1] / t[0], t[2] / t[0], t[3] / t[0], t[4] / t[0]};
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

TEST_CASE("near the minimum energy the averages approach harmonic equipartition",
          "[microcanonical]") {
  // Small oscillations: H is quadratic, tr X_i(0) = 1, so <K_i>_E -> (E - E_min)/(2N) for every i,
  // with relative corrections O(E - E_min).
  for (std::size_t n : {std::size_t(2), std::size_t(3)}) {
    const Chain<double> c(std::vector<double>(n, 1.0), std::vector<double>(n, 1.0), 1.0);
    const double bottom = -gamma_sum(c);
    double previous = 1;
    for (double excess : {1e-2, 1e-3, 1e-4}) {
      MicrocanonicalOptions o;
      o.tolerance = 1e-9;
      const auto r = microcanonical_average(c, bottom + excess, o);
      const double harmonic = excess / (2 * double(n));
      double worst = 0;
      for (std::size_t i = 0; i < n; ++i) worst = std::max(worst, std::abs(r.kinetic[i].value / harmonic - 1));
      INFO("N = " << n << ", E - E_min = " << excess << ", deviation " << worst);
      CHECK(worst < 2 * excess);          // O(E - E_min)
      CHECK(worst < previous / 5);        // and shrinking with it
      previous = worst;
      CHECK(std::abs(r.kinetic_total.value / (excess / 2) - 1) < 2 * excess);
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
    // QMC: within its 3-sigma bars
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
    std::vector<double> critical{0.0};
    for (std::size_t j = 0; j < n; ++j) {
      std::vector<double> next;
      for (double v : critical) {
        next.push_back(v + c.potential_coefficient(j));
        next.push_back(v - c.potential_coefficient(j));
      }
      critical.swap(next);
    }
    std::sort(critical.begin(), critical.end());
    critical.erase(std::unique(critical.begin(), critical.end()), critical.end());
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
    CHECK(covered >= total - 3);  // 3 sigma: ~99% each
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
  o = {};
  o.threads = 0;
  CHECK_THROWS_AS(microcanonical_average(c, 0.0, o), invalid_input);
  o = {};
  o.rule = Rule::integral;
  const Chain<double> long_chain(std::vector<double>(8, 1.0), std::vector<double>(8, 1.0), 1.0);
  CHECK_THROWS_AS(microcanonical_average(long_chain, 0.0, o), invalid_input);
}
