// SPDX-License-Identifier: GPL-3.0-or-later
// tests/engine/dynamics/test_dynamics.cpp -- RATTLE + compositions, constrained Langevin, time averages with
// blocking error bars, and the Poincare section (pendavg/dynamics.hpp), checked against
// independent references: dense-matrix Lagrangian mechanics (Eigen), the exact microcanonical
// (microcanonical.hpp) and canonical (double_pendulum.hpp, torus.hpp) averages, and AR(1)
// processes with a known variance of the mean.
#include "engine/dynamics/blocking.hpp"
#include "engine/double_pendulum/double_pendulum.hpp"
#include "pendavg/dynamics.hpp"
#include "engine/microcanonical/microcanonical.hpp"
#include "engine/torus/torus.hpp"
#include "pendavg/mpfr.hpp"
#include "real_types.hpp"

#include <Eigen/Dense>
#include <catch2/catch.hpp>

#include <atomic>
#include <cmath>
#include <numbers>
#include <random>
#include <vector>

using namespace pendavg;
using Catch::Matchers::WithinAbs;
using Catch::Matchers::WithinRel;

namespace {

Chain<double> unit_chain(std::size_t n) {
  return Chain<double>(std::vector<double>(n, 1.0), std::vector<double>(n, 1.0), 1.0);
}

/// A generic state: angles and rates from a seeded generator (doubles, exact in every type).
template <class Real>
ChainState<Real> random_state(const Chain<Real>& chain, std::uint64_t seed, double rate = 1) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> angle(-3.0, 3.0), speed(-rate, rate);
  std::vector<Real> phi(chain.size()), phidot(chain.size());
  for (std::size_t i = 0; i < chain.size(); ++i) {
    phi[i] = angle(rng);
    phidot[i] = speed(rng);
  }
  return state_from_angles(chain, phi, phidot);
}

double max_energy_error(const Chain<double>& chain, ChainState<double> state, double h,
                        double duration, Integrator integrator) {
  DynamicsWorkspace<double> ws(chain);
  project_momenta(chain, state, ws);
  const double e0 = total_energy(chain, state);
  double worst = 0;
  const auto steps = static_cast<std::size_t>(std::llround(duration / h));
  for (std::size_t s = 0; s < steps; ++s) {
    composition_step(chain, state, h, integrator, ws);
    worst = std::max(worst, std::abs(total_energy(chain, state) - e0));
  }
  return worst;
}

}  // namespace

// The dynamics is generic over double and long double: the checks of precision run in both,
// against references at reference_digits, tolerances in units of each type's epsilon.
TEMPLATE_TEST_CASE("states: angles, canonical momenta and energies agree with the dense Lagrangian",
                   "[dynamics]", double, long double) {
  using Real = TestType;
  using pendavg::test::distance;
  using pendavg::test::relative_distance;
  const double u = pendavg::test::unit<Real>();
  const std::vector<double> masses{1.0, 0.3, 2.0, 0.7}, lengths{1.0, 0.5, 1.5, 0.8};
  const double g = 9.81;
  const std::vector<double> phi{0.3, -1.2, 2.5, 0.1}, phidot{0.7, -0.2, 1.1, -2.0};
  const Chain<Real> chain = Chain<double>(masses, lengths, g).cast<Real>();
  const ChainState<Real> state = state_from_angles(chain, std::vector<Real>(phi.begin(), phi.end()),
                                                   std::vector<Real>(phidot.begin(), phidot.end()));
  const ChainObservables<Real> o = observables(chain, state);
  // The dense Lagrangian (the paper's eq. a-ij) at reference_digits: p = A(phi) phidot,
  // K = phidot^T A phidot / 2, U = -sum_j g S_j l_j cos phi_j.
  const pendavg::test::ReferencePrecision wide;
  std::vector<mpfr_real> p(4, mpfr_real(0));
  mpfr_real kinetic = 0, potential = 0;
  for (std::size_t j = 0; j < 4; ++j) {
    mpfr_real tail = 0;
    for (std::size_t i = j; i < 4; ++i) tail += masses[i];
    potential -= g * tail * lengths[j] * cos(mpfr_real(phi[j]));
    for (std::size_t k = 0; k < 4; ++k) {
      mpfr_real tail_jk = 0;
      for (std::size_t i = std::max(j, k); i < 4; ++i) tail_jk += masses[i];
      p[j] += tail_jk * lengths[j] * lengths[k] * cos(mpfr_real(phi[j]) - phi[k]) * phidot[k];
    }
  }
  for (std::size_t j = 0; j < 4; ++j) kinetic += p[j] * phidot[j] / 2;
  for (std::size_t i = 0; i < 4; ++i) {
    INFO("i = " << i);
    CHECK(distance(o.phi[i], mpfr_real(phi[i])) <= 45 * u);
    CHECK(distance(o.phidot[i], mpfr_real(phidot[i])) <= 450 * u);
    CHECK(distance(o.p_phi[i], p[i]) <= 450 * u);
  }
  // K = sum_i K_i = sum_i K_i^(c) (Euler: p . phidot = 2K).
  Real sum_k = 0, sum_kc = 0;
  for (std::size_t i = 0; i < 4; ++i) {
    sum_k += o.kinetic[i];
    sum_kc += o.kinetic_canonical[i];
  }
  CHECK(relative_distance(sum_k, kinetic) <= 45 * u);
  CHECK(relative_distance(sum_kc, kinetic) <= 450 * u);
  CHECK(distance(o.potential, potential) <= 450 * u);
  CHECK(distance(total_energy(chain, state), mpfr_real(kinetic + potential)) <= 450 * u);
  // From canonical momenta back to the same state.
  std::vector<Real> p_real;
  for (const mpfr_real& x : p) p_real.push_back(static_cast<Real>(x));
  const ChainState<Real> again =
      state_from_canonical(chain, std::vector<Real>(phi.begin(), phi.end()), p_real);
  for (std::size_t k = 0; k < 8; ++k) {
    CHECK(distance(again.position[k], mpfr_real(state.position[k])) <= 45 * u);
    CHECK(distance(again.momentum[k], mpfr_real(state.momentum[k])) <= 4500 * u);
  }
  CHECK(constraint_residual(chain, state) <= 2 * u);
  CHECK(velocity_constraint_residual(chain, state) <= 4.5 * u);
}

TEMPLATE_TEST_CASE("RATTLE keeps the position and velocity constraints to rounding", "[dynamics]",
                   double, long double) {
  // Unequal masses (ratios up to 50) and lengths (0.2..5), fast rates. (A light particle
  // between heavy ones under compression is a genuinely stiff, buckling-unstable system: at
  // mass ratios ~1e3 a fixed step of 1e-3 no longer resolves it.)
  using Real = TestType;
  const double u = pendavg::test::unit<Real>();
  const Chain<Real> chain =
      Chain<double>({1.0, 0.1, 5.0, 0.2, 2.0, 1.0}, {0.2, 1.0, 5.0, 0.5, 2.0, 1.0}, 1.0).cast<Real>();
  ChainState<Real> state = random_state(chain, 7, 2.0);
  DynamicsWorkspace<Real> ws(chain);
  project_momenta(chain, state, ws);
  Real position = 0, velocity = 0;
  for (int step = 0; step < 20000; ++step) {
    yoshida4_step(chain, state, Real(1e-3), ws);
    position = std::max(position, constraint_residual(chain, state));
    velocity = std::max(velocity, velocity_constraint_residual(chain, state));
  }
  INFO("largest residuals in units of epsilon: position " << static_cast<double>(position) / u
       << ", velocity " << static_cast<double>(velocity) / u);
  CHECK(position <= 450 * u);
  CHECK(velocity <= 4500 * u);
  CHECK(ws.unconverged_stages == 0);
  CHECK(static_cast<double>(ws.newton_solves) / static_cast<double>(ws.position_stages) < 3);
}

TEST_CASE("the extrapolated multipliers leave about one Newton solve per position stage",
          "[dynamics]") {
  // The paper's N = 16 start; the first 2 steps use the velocity-stage guess.
  const Chain<double> chain = unit_chain(16);
  ChainState<double> state = state_from_angles(chain, std::vector<double>(16, std::numbers::pi / 2),
                                               std::vector<double>(16, 0.0));
  DynamicsWorkspace<double> ws(chain);
  for (int s = 0; s < 5000; ++s) yoshida4_step(chain, state, 1e-3, ws);
  CHECK(ws.unconverged_stages == 0);
  CHECK(static_cast<double>(ws.newton_solves) / static_cast<double>(ws.position_stages) < 1.1);
  CHECK(ws.largest_stage_residual <= 4 * std::numeric_limits<double>::epsilon());
}

TEST_CASE("energy error converges with the order of each composition", "[dynamics]") {
  const Chain<double> chain({1.0, 0.5, 2.0}, {1.0, 0.7, 1.3}, 1.0);
  const ChainState<double> state = random_state(chain, 3, 1.5);
  struct Case {
    Integrator integrator;
    double order, h;
  };
  for (const Case c : {Case{Integrator::rattle2, 2, 4e-3}, Case{Integrator::yoshida4, 4, 2e-2},
                       Case{Integrator::suzuki4, 4, 4e-2}, Case{Integrator::kahan_li6, 6, 8e-2},
                       Case{Integrator::yoshida6, 6, 4e-2}}) {
    const double coarse = max_energy_error(chain, state, c.h, 2.0, c.integrator);
    const double fine = max_energy_error(chain, state, c.h / 2, 2.0, c.integrator);
    const double observed = std::log2(coarse / fine);
    INFO("integrator " << static_cast<int>(c.integrator) << " errors " << coarse << " " << fine);
    CHECK(std::abs(observed - c.order) < 0.5);
  }
  // Suzuki's and Kahan-Li's compositions beat Yoshida's triple jump at equal step.
  const double yoshida = max_energy_error(chain, state, 1e-2, 2.0, Integrator::yoshida4);
  CHECK(max_energy_error(chain, state, 1e-2, 2.0, Integrator::suzuki4) < yoshida / 10);
  CHECK(max_energy_error(chain, state, 1e-2, 2.0, Integrator::kahan_li6) < yoshida / 100);
  CHECK(max_energy_error(chain, state, 1e-2, 2.0, Integrator::yoshida6) < yoshida / 10);
}

TEMPLATE_TEST_CASE("the composed RATTLE map is time reversible", "[dynamics]", double,
                   long double) {
  // Forward, momenta reversed, back: the start again, to rounding (in units of epsilon).
  using Real = TestType;
  const double u = pendavg::test::unit<Real>();
  const Chain<Real> chain =
      Chain<double>({1.0, 2.0, 0.5, 1.0}, {1.0, 0.5, 1.0, 2.0}, 1.0).cast<Real>();
  ChainState<Real> state = random_state(chain, 11);
  DynamicsWorkspace<Real> ws(chain);
  project_momenta(chain, state, ws);
  const ChainState<Real> start = state;
  for (int s = 0; s < 500; ++s) yoshida4_step(chain, state, Real(1e-3), ws);
  Real moved = 0;
  for (std::size_t k = 0; k < state.position.size(); ++k)
    moved = std::max(moved, std::abs(state.position[k] - start.position[k]));
  REQUIRE(moved > 0.1);  // it went somewhere
  for (Real& p : state.momentum) p = -p;
  ws.reset_history();
  for (int s = 0; s < 500; ++s) yoshida4_step(chain, state, Real(1e-3), ws);
  for (std::size_t k = 0; k < state.position.size(); ++k) {
    INFO("k = " << k);
    CHECK(static_cast<double>(std::abs(state.position[k] - start.position[k])) <= 45000 * u);
    CHECK(static_cast<double>(std::abs(state.momentum[k] + start.momentum[k])) <= 45000 * u);
  }
}

TEST_CASE("double and long double trajectories agree over a short run", "[dynamics]") {
  const Chain<double> chain({1.0, 0.5, 2.0}, {1.0, 0.7, 1.3}, 1.0);
  const Chain<long double> chain_ld = chain.cast<long double>();
  ChainState<double> state = random_state(chain, 5);
  ChainState<long double> state_ld;
  state_ld.position.assign(state.position.begin(), state.position.end());
  state_ld.momentum.assign(state.momentum.begin(), state.momentum.end());
  DynamicsWorkspace<double> ws(chain);
  DynamicsWorkspace<long double> ws_ld(chain_ld);
  project_momenta(chain, state, ws);
  project_momenta(chain_ld, state_ld, ws_ld);
  for (int s = 0; s < 2000; ++s) {
    yoshida4_step(chain, state, 1e-3, ws);
    yoshida4_step(chain_ld, state_ld, 1e-3L, ws_ld);
  }
  for (std::size_t k = 0; k < state.position.size(); ++k)
    CHECK_THAT(state.position[k], WithinAbs(static_cast<double>(state_ld.position[k]), 1e-11));
  CHECK(constraint_residual(chain_ld, state_ld) < 1e-18L);
}

TEMPLATE_TEST_CASE("hard cases: tiny first mass, extreme length ratios, long chains", "[dynamics]",
                   double, long double) {
  // The constraints to rounding in each type (450 epsilon: 1e-13 in double); the energy error is
  // the integrator's at the default step, the same in both.
  using Real = TestType;
  struct Case {
    const char* name;
    Chain<double> chain;
  };
  const std::vector<Case> cases{
      {"mu1 -> 0 (m1 = 1e-4)", Chain<double>({1e-4, 1.0}, {1.0, 1.0}, 1.0)},
      {"l2/l1 = 1e-2", Chain<double>({1.0, 1.0}, {1.0, 1e-2}, 1.0)},
      {"l2/l1 = 1e2", Chain<double>({1.0, 1.0}, {1.0, 1e2}, 1.0)},
      {"N = 64 unit chain", unit_chain(64)},
  };
  for (const Case& c : cases) {
    INFO(c.name);
    SimulationOptions options;
    options.duration = 5;
    const std::size_t n = c.chain.size();
    const Chain<Real> chain = c.chain.template cast<Real>();
    const ChainState<Real> start =
        state_from_angles(chain, std::vector<Real>(n, Real(1.2)), std::vector<Real>(n, Real(0)));
    const SimulationResult<Real> r = simulate(chain, start, options);
    INFO("constraint residual " << static_cast<double>(r.constraint_residual) /
                                       pendavg::test::unit<Real>() << " epsilon");
    CHECK(r.constraint_residual <= 450 * pendavg::test::unit<Real>());
    CHECK(r.energy_error_max <= 1e-6);
    CHECK(r.unconverged_stages == 0);
    CHECK(std::isfinite(static_cast<double>(r.kinetic.back().value)));
  }
}

TEST_CASE("blocking error bars cover the mean of AR(1) processes", "[dynamics]") {
  // x_t = a x_{t-1} + e_t: the variance of the mean of n samples is known in closed form,
  // var = sigma_e^2 / (1 - a)^2 / n (1 + O(1/n)); tau_int = (1 + a) / (2 (1 - a)) samples.
  const double a = 0.95;
  const std::size_t n = 1 << 17;
  int covered = 0;
  double ratio_sum = 0;
  const int replicas = 200;
  std::mt19937_64 rng(2024);
  std::normal_distribution<double> normal(0.0, 1.0);
  for (int r = 0; r < replicas; ++r) {
    detail::BlockAverager<double> blocks(1, 8, 1 << 12);
    double x = normal(rng) / std::sqrt(1 - a * a);
    for (std::size_t t = 0; t < n; ++t) {
      x = a * x + normal(rng);
      blocks.add(&x);
    }
    const TimeAverage<double> m = blocks.time_average(0, 1.0);
    if (std::abs(m.value) <= 2 * m.error) ++covered;
    ratio_sum += m.error / (1 / (1 - a) / std::sqrt(static_cast<double>(n)));
    if (r == 0) CHECK_THAT(m.autocorrelation_time, WithinRel((1 + a) / (2 * (1 - a)), 0.3));
  }
  // ~95% for a 2-sigma interval; the estimate is the true standard error within ~15%.
  CHECK(covered >= replicas * 90 / 100);
  CHECK(ratio_sum / replicas > 0.9);
  CHECK(ratio_sum / replicas < 1.3);
}

TEST_CASE("N = 2 chaotic NVE run agrees with the exact microcanonical averages", "[dynamics]") {
  // The paper's start (both links horizontal, at rest): E = 0, strongly chaotic.
  const Chain<double> chain = unit_chain(2);
  const ChainState<double> start = state_from_angles(
      chain, {std::numbers::pi / 2, std::numbers::pi / 2}, {0.0, 0.0});
  SimulationOptions options;
  options.duration = 2000;
  const SimulationResult<double> r = simulate(chain, start, options);
  const MicrocanonicalAverages<double> exact = microcanonical_average(chain, r.initial_energy);
  for (std::size_t i = 0; i < 2; ++i) {
    INFO("particle " << i + 1 << ": " << r.kinetic[i].value << " +- " << r.kinetic[i].error
                     << " vs " << exact.kinetic[i].value);
    CHECK(std::abs(r.kinetic[i].value - exact.kinetic[i].value) <= 3 * r.kinetic[i].error);
    CHECK(std::abs(r.kinetic_canonical[i].value - exact.kinetic_canonical.value) <=
          3 * r.kinetic_canonical[i].error);
    CHECK(r.kinetic[i].error < 0.05 * r.kinetic[i].value);  // a real test, not a wide bar
    CHECK(std::abs(r.cos_angle[i].value - exact.cos_angle[i].value) <= 3 * r.cos_angle[i].error);
  }
  CHECK(r.energy_error_max < 1e-9);
  CHECK(std::abs(r.energy_trend) < 1e-11);
  CHECK(r.constraint_residual < 1e-14);
}

TEST_CASE("N = 2 constrained Langevin run agrees with the exact canonical averages",
          "[dynamics]") {
  const Chain<double> chain({1.0, 1.0}, {1.0, 1.0}, 1.0);
  const double beta = 0.5;
  SimulationOptions options;
  options.duration = 2000;
  options.thermostat = Thermostat::langevin;
  options.beta = beta;
  options.friction = 1;
  options.seed = 1;
  const ChainState<double> start = state_from_angles(chain, {0.0, 0.0}, {0.0, 0.0});
  const SimulationResult<double> r = simulate(chain, start, options);
  const Averages<double> exact = reduced_integral_average(chain, beta);
  for (std::size_t i = 0; i < 2; ++i) {
    const double k = exact.beta_kinetic[i].value / beta;
    INFO("particle " << i + 1 << ": " << r.kinetic[i].value << " +- " << r.kinetic[i].error
                     << " vs " << k);
    CHECK(std::abs(r.kinetic[i].value - k) <= 3 * r.kinetic[i].error);
    CHECK(std::abs(r.kinetic_canonical[i].value - 0.5 / beta) <= 3 * r.kinetic_canonical[i].error);
    CHECK(r.kinetic[i].error < 0.05 * k);
    CHECK(std::abs(r.cos_angle[i].value - exact.cos_angle[i].value) <= 3 * r.cos_angle[i].error);
  }
  // Equipartition holds in total (sum_i beta<K_i> = N/2): the thermostat's temperature.
  CHECK(std::abs(r.kinetic_total.value - 1 / beta) <= 3 * r.kinetic_total.error);
  CHECK(r.constraint_residual < 1e-14);
}

TEST_CASE("a run stops on request and keeps the averages so far", "[dynamics]") {
  const Chain<double> chain = unit_chain(3);
  std::atomic<bool> stop{true};
  DynamicsObserver<double> observer;
  observer.stop = &stop;
  SimulationOptions options;
  options.duration = 1e6;
  const SimulationResult<double> r =
      simulate(chain, state_from_angles(chain, {1.0, 1.0, 1.0}, {0.0, 0.0, 0.0}), options, observer);
  CHECK(r.interrupted);
  CHECK(r.steps == 1024);
  CHECK(r.samples == 1024);
  CHECK(std::isfinite(r.kinetic[0].value));
  CHECK(r.kinetic[0].value > 0);
}

TEST_CASE("Poincare section points lie on the section at the orbit's energy", "[dynamics]") {
  const Chain<double> chain = unit_chain(2);
  const double energy = -1.0;  // mixed regular and chaotic motion
  PoincareOptions options;
  options.orbits = 4;
  options.points = 30;
  const PoincareSection<double> section = poincare_section(chain, energy, options);
  REQUIRE(section.points.size() == 120);
  CHECK(section.energy_error_max < 1e-9);
  for (const SectionPoint<double>& p : section.points) {
    // Rebuild the phase-space point (phi1 = 0, phi2, p1 > root, p2) as in Appendix E and
    // check that it has the section's energy: p2^2 <= 2 A_3 (E - U).
    const double u = -2 - std::cos(p.phi2);
    REQUIRE(p.p2 * p.p2 <= 2 * (energy - u) + 1e-9);
    CHECK(std::abs(p.phi2) <= std::numbers::pi);
  }
  // Each crossing was refined onto phi1 = 0: start an orbit at a recorded point and its first
  // crossing time is positive, its energy is E (checked through a short simulation).
  const SectionPoint<double>& p = section.points[10];
  const double a1 = 2, a2 = std::cos(p.phi2), a3 = 1, det = a1 * a3 - a2 * a2;
  const double u = -2 - std::cos(p.phi2);
  const double p1 = (a2 * p.p2 + std::sqrt(det * (2 * a3 * (energy - u) - p.p2 * p.p2))) / a3;
  const ChainState<double> on = state_from_canonical(chain, {0.0, p.phi2}, {p1, p.p2});
  CHECK_THAT(total_energy(chain, on), WithinAbs(energy, 1e-8));
  // phidot1 > 0 there (the section's orientation).
  CHECK(observables(chain, on).phidot[0] > 0);
}

TEST_CASE("bad dynamics input throws invalid_input", "[dynamics]") {
  const Chain<double> chain = unit_chain(2);
  const ChainState<double> start = state_from_angles(chain, {1.0, 1.0}, {0.0, 0.0});
  SimulationOptions options;
  options.duration = 1;
  SimulationOptions bad = options;
  bad.time_step = 0;
  CHECK_THROWS_AS(simulate(chain, start, bad), invalid_input);
  bad = options;
  bad.duration = std::nan("");
  CHECK_THROWS_AS(simulate(chain, start, bad), invalid_input);
  bad = options;
  bad.thermostat = Thermostat::langevin;
  bad.beta = -1;
  CHECK_THROWS_AS(simulate(chain, start, bad), invalid_input);
  CHECK_THROWS_AS(simulate(unit_chain(3), start, options), invalid_input);
  CHECK_THROWS_AS(state_from_angles(chain, {1.0}, {0.0, 0.0}), invalid_input);
  CHECK_THROWS_AS(state_from_angles(chain, {1.0, std::nan("")}, {0.0, 0.0}), invalid_input);
  CHECK_THROWS_AS(poincare_section(unit_chain(3), 0.0, PoincareOptions{}), invalid_input);
  CHECK_THROWS_AS(poincare_section(chain, -3.0, PoincareOptions{}), invalid_input);
}

TEST_CASE("simulate refuses a setting its thermostat does not use", "[dynamics]") {
  const Chain<double> chain = unit_chain(2);
  const ChainState<double> start = state_from_angles(chain, {1.0, 1.0}, {0.0, 0.0});
  SimulationOptions nve;
  nve.duration = 0.01;
  CHECK_NOTHROW(check_simulation_options(nve));
  for (int field = 0; field < 3; ++field) {
    SimulationOptions bad = nve;  // beta, friction, seed are Langevin settings
    if (field == 0) bad.beta = 1;
    if (field == 1) bad.friction = 1;
    if (field == 2) bad.seed = 7;
    CHECK_THROWS_AS(check_simulation_options(bad), invalid_input);
    CHECK_THROWS_AS(simulate(chain, start, bad), invalid_input);
  }
  SimulationOptions langevin = nve;
  langevin.thermostat = Thermostat::langevin;
  CHECK_THROWS_AS(simulate(chain, start, langevin), invalid_input);  // needs beta
  langevin.beta = 2;
  CHECK_NOTHROW(check_simulation_options(langevin));
  SimulationOptions bad = langevin;
  bad.integrator = Integrator::yoshida4;  // BAOAB is the Langevin scheme
  CHECK_THROWS_AS(simulate(chain, start, bad), invalid_input);
  bad = langevin;
  bad.friction = 0;
  CHECK_THROWS_AS(simulate(chain, start, bad), invalid_input);
  bad = nve;
  bad.duration = 2e10;  // 2e13 steps of 1e-3
  CHECK_THROWS_AS(simulate(chain, start, bad), invalid_input);
  bad = nve;
  bad.duration = 0.5e-3;  // shorter than one step
  CHECK_THROWS_AS(simulate(chain, start, bad), invalid_input);
  // Unset settings take their documented defaults: the same run as with them spelled out.
  SimulationOptions spelled = nve;
  spelled.integrator = default_integrator;
  CHECK(simulate(chain, start, nve).kinetic[0].value ==
        simulate(chain, start, spelled).kinetic[0].value);
  SimulationOptions noise = langevin;
  noise.friction = 1;
  noise.seed = 1;
  CHECK(simulate(chain, start, langevin).kinetic[0].value ==
        simulate(chain, start, noise).kinetic[0].value);
}

// ---------------------------------------------------------------- slow validations

TEST_CASE("long NVE and Langevin runs agree with the exact values (N = 2, 3)",
          "[dynamics][.slow][slow]") {
  struct Case {
    Chain<double> chain;
    double theta;
  };
  for (const Case& c : {Case{unit_chain(2), std::numbers::pi / 2},
                        Case{Chain<double>({1.0, 0.5, 2.0}, {1.0, 1.5, 0.7}, 1.0), 2.0}}) {
    const std::size_t n = c.chain.size();
    const ChainState<double> start =
        state_from_angles(c.chain, std::vector<double>(n, c.theta), std::vector<double>(n, 0.0));
    SimulationOptions options;
    options.duration = 20000;
    const SimulationResult<double> nve = simulate(c.chain, start, options);
    const MicrocanonicalAverages<double> micro = microcanonical_average(c.chain, nve.initial_energy);
    options.thermostat = Thermostat::langevin;
    options.beta = 0.7;
    const SimulationResult<double> nvt = simulate(c.chain, start, options);
    const Averages<double> canonical =
        n == 2 ? reduced_integral_average(c.chain, 0.7) : torus_average(c.chain, 0.7);
    for (std::size_t i = 0; i < n; ++i) {
      INFO("N = " << n << ", particle " << i + 1);
      CHECK(std::abs(nve.kinetic[i].value - micro.kinetic[i].value) <=
            3 * std::hypot(nve.kinetic[i].error, micro.kinetic[i].error));
      CHECK(std::abs(nvt.kinetic[i].value - canonical.beta_kinetic[i].value / 0.7) <=
            3 * nvt.kinetic[i].error);
    }
  }
}
