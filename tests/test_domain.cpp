// SPDX-License-Identifier: GPL-3.0-or-later
// tests/test_domain.cpp -- issue 11: every accepted input gives a finite answer with an honest
// error, or one clear error before any work. Each engine's domain check by name:
//  * large beta (any N): the low-temperature extrapolation (src/average.cpp) against the torus
//    run directly where it still resolves the peaks, and against the exact beta -> infinity
//    limit far beyond; single pendulums with overflowing alpha;
//  * extreme length ratios: a root link 1e300 times longer than the rest (the node maps' tail
//    sums, the measured rounding lever) against MPFR;
//  * inputs outside double's range (subnormals, mass ratios beyond 1e150, mu1 < 1e-150 for
//    N = 2, stiffness ratios beyond 1e9) are refused with a message that says what to do, and
//    the advice works where it points to MPFR.
#include <catch2/catch.hpp>

#include "engine/torus/torus.hpp"
#include "refusals.hpp"
#include "pendavg/mpfr.hpp"
#include "pendavg/pendavg.hpp"

#include <atomic>
#include <cmath>
#include <stdexcept>
#include <string>
#include <vector>

namespace {

using pendavg::AverageMethod;
using pendavg::AverageOptions;
using pendavg::Averages;
using pendavg::Chain;
using pendavg::Estimate;
using pendavg::Method;
using pendavg::mpfr_real;

using pendavg_test::all_finite;
using pendavg_test::rejection;

/// |a - b| <= the two errors, for every observable.
void require_agree(const Averages<double>& a, const Averages<double>& b) {
  for (auto field : {&Averages<double>::beta_kinetic, &Averages<double>::cos_angle,
                     &Averages<double>::beta2_kinetic_variance}) {
    REQUIRE((a.*field).size() == (b.*field).size());
    for (std::size_t i = 0; i < (a.*field).size(); ++i) {
      const Estimate<double>& x = (a.*field)[i];
      const Estimate<double>& y = (b.*field)[i];
      INFO("i = " << i << ": " << x.value << " +- " << x.error << " vs " << y.value << " +- "
                  << y.error);
      CHECK(std::abs(x.value - y.value) <= x.error + y.error);
    }
  }
}


}  // namespace

TEST_CASE("domain: large beta, the low-temperature extrapolation against the direct torus",
          "[domain]") {
  // Every joint just stiffer than 1e7 (extrapolated), where the torus still resolves the peaks
  // directly (to kappa ~ 1e13): two independent routes to the same numbers.
  struct Case {
    std::vector<double> masses, lengths;
    double beta;
  };
  for (const Case& c : {Case{{1, 1, 1}, {1, 1, 1}, 2e7},
                        Case{{1, 0.3, 2}, {0.5, 1.5, 1}, 5e7},
                        Case{{1, 1}, {1, 1}, 3e7}}) {
    const Chain<double> chain(c.masses, c.lengths);
    AverageOptions o;
    o.method = AverageMethod::torus_trapezoid;
    const Averages<double> extrapolated = pendavg::average(chain, c.beta, o);
    INFO("N = " << chain.size() << ", beta = " << c.beta);
    REQUIRE(extrapolated.method == Method::low_temperature_extrapolation);
    REQUIRE(extrapolated.converged);
    const Averages<double> direct = pendavg::torus_average(chain, c.beta);
    REQUIRE(direct.converged);
    require_agree(extrapolated, direct);
    for (const Estimate<double>& e : extrapolated.beta_kinetic) CHECK(e.error < 1e-11);
  }
}

TEST_CASE("domain: light particles before a heavy tail are not extrapolated too early",
          "[domain]") {
  // A light particle at joint i makes the weight vary on delta_i^2 ~ m_i / S_{i+1}: every joint
  // can be stiff (kappa ~ beta g M l >= 1e7) while the averages are far from the limit 1/2
  // (beta<K_1> = 0.22 for masses 1, 1e8 at beta = 1). The extrapolation waits for the effective
  // stiffness kappa_i min(1, m_i / S_{i+1}); before it the torus runs directly. Checked against
  // the exact N = 2 integral and, for N = 3, against the transfer operator.
  struct Case {
    std::vector<double> masses;
    double beta;
    bool extrapolated;
  };
  for (const Case& c : {Case{{1, 1e8}, 1, false}, Case{{1, 1e8}, 1e4, false},
                        Case{{1, 1e8}, 1e6, true}, Case{{1, 1e8}, 1e8, true},
                        Case{{1, 1, 1e4}, 1e4, false}, Case{{1, 1, 1e4}, 1e8, true},
                        Case{{1e4, 1e-2, 1}, 1e8, false}}) {
    const Chain<double> chain(c.masses, std::vector<double>(c.masses.size(), 1.0));
    AverageOptions torus;
    torus.method = AverageMethod::torus_trapezoid;
    AverageOptions reference;
    reference.method = chain.size() == 2 ? AverageMethod::integral : AverageMethod::transfer;
    INFO("N = " << chain.size() << ", m_N = " << c.masses.back() << ", beta = " << c.beta);
    const Averages<double> a = pendavg::average(chain, c.beta, torus);
    const Averages<double> b = pendavg::average(chain, c.beta, reference);
    CHECK((a.method == Method::low_temperature_extrapolation) == c.extrapolated);
    REQUIRE(a.converged);
    REQUIRE(b.converged);
    require_agree(a, b);
  }
  // The double pendulum at masses 1, 1e8 and beta = 1 (every joint stiff, kappa = 5e7) is far
  // from its limit: beta<K_1> < 0.3, not 1/2.
  AverageOptions torus;
  torus.method = AverageMethod::torus_trapezoid;
  const Averages<double> far = pendavg::average(Chain<double>({1, 1e8}, {1, 1}), 1.0, torus);
  CHECK(far.beta_kinetic[0].value < 0.3);
}

TEST_CASE("domain: beta -> infinity for any N is finite and reaches the exact limit", "[domain]") {
  // N = 1 with alpha = beta g m l beyond double (1e315), N = 3 at beta = 1e300, N = 6 (auto:
  // transfer; and qmc).
  struct Case {
    std::vector<double> masses, lengths;
    double beta;
  };
  for (const Case& c : {Case{{1e300}, {1}, 1e15}, Case{{1}, {1}, 1e300},
                        Case{{1, 1, 1}, {1, 1, 1}, 1e300}, Case{{1, 2, 3}, {3, 2, 1}, 1e50},
                        Case{{1, 1, 1, 1, 1, 1}, {1, 1, 1, 1, 1, 1}, 1e35}}) {
    const Chain<double> chain(c.masses, c.lengths);
    std::vector<AverageOptions> runs(1);  // auto
    if (chain.size() >= 5) {
      AverageOptions q;
      q.method = pendavg::AverageMethod::qmc;
      q.samples = 1024;
      q.shifts = 8;
      runs.push_back(q);
    }
    const Averages<double> limit = pendavg::low_temperature_limit(chain);
    for (const AverageOptions& o : runs) {
      const Averages<double> a = pendavg::average(chain, c.beta, o);
      INFO("N = " << chain.size() << ", beta = " << c.beta << ", method "
                  << pendavg::average_method_name(o.method));
      REQUIRE(all_finite(a));
      REQUIRE(a.converged);
      require_agree(a, limit);
    }
  }
}

TEST_CASE("domain: a root link 1e300 times longer than the rest, against MPFR", "[domain]") {
  // The node maps once lost the other links' stiffness (total - head cancelled) and the
  // rounding budget grew like sqrt(alpha_1) ~ 1e150: no convergence and an absurd error.
  const Chain<double> chain({1, 1, 1}, {1e300, 1, 1});
  const Averages<double> a = pendavg::average(chain, 1.0);
  REQUIRE(a.converged);
  for (const Estimate<double>& e : a.beta_kinetic) CHECK(e.error < 1e-12);
  AverageOptions o20;
  o20.digits = 20;
  const Averages<mpfr_real> reference =
      pendavg::average(chain.cast<mpfr_real>(), mpfr_real(1), o20);
  for (std::size_t i = 0; i < 3; ++i) {
    INFO("i = " << i);
    CHECK(std::abs(a.beta_kinetic[i].value - static_cast<double>(reference.beta_kinetic[i].value)) <=
          a.beta_kinetic[i].error);
    CHECK(std::abs(a.beta2_kinetic_variance[i].value -
                   static_cast<double>(reference.beta2_kinetic_variance[i].value)) <=
          a.beta2_kinetic_variance[i].error);
  }
  // N = 4 at beta = 1e3: converges to the torus' tolerance like the unit chain.
  const Averages<double> four = pendavg::average(Chain<double>({1, 1, 1, 1}, {1e300, 1, 1, 1}), 1e3);
  CHECK(four.converged);
  for (const Estimate<double>& e : four.beta_kinetic) CHECK(e.error < 1e-12);
}

TEST_CASE("domain: inputs beyond double's range are refused with advice that works", "[domain]") {
  const auto in_double = [](std::vector<double> m, std::vector<double> l, double beta) {
    return rejection([&] { pendavg::average(Chain<double>(m, l), beta); });
  };
  const auto in_mpfr = [](std::vector<double> m, std::vector<double> l, double beta) {
    AverageOptions o;
    o.digits = 20;
    const Chain<mpfr_real> chain(std::vector<mpfr_real>(m.begin(), m.end()),
                                 std::vector<mpfr_real>(l.begin(), l.end()));
    return pendavg::average(chain, mpfr_real(beta), o);
  };
  const std::string mpfr_advice = "request 17 or more digits (MPFR)";
  SECTION("a subnormal mass") {
    // The model cannot know whether the method runs in MPFR: no advice from it (the CLI adds
    // it for N = 2, where every method does).
    CHECK_THAT(in_double({1, 1e-320}, {1, 1}, 1), Catch::Contains("below the normal range"));
    CHECK_THAT(in_double({1, 1e-320}, {1, 1}, 1), !Catch::Contains("request"));
    CHECK(all_finite(in_mpfr({1, 1e-320}, {1, 1}, 1)));
  }
  SECTION("N = 2: mu1 = m1/M below 1e-150 (the variances' integral overflows)") {
    CHECK_THAT(in_double({1e-300, 1}, {1, 1}, 1e10), Catch::Contains(mpfr_advice));
    const Averages<mpfr_real> a = in_mpfr({1e-300, 1}, {1, 1}, 1e10);
    REQUIRE(all_finite(a));
    // The light top particle carries almost nothing: beta<K_2> -> 1.
    CHECK(static_cast<double>(a.beta_kinetic[1].value) == Approx(1.0).epsilon(1e-12));
    CHECK(in_double({1e-150, 1}, {1, 1}, 1e10).empty());
  }
  SECTION("N = 2: beta g M l beyond 1e150") {
    CHECK_THAT(in_double({1, 1}, {1, 1e308}, 1), Catch::Contains(mpfr_advice));
    CHECK(all_finite(in_mpfr({1, 1}, {1, 1e308}, 1)));
  }
  SECTION("N = 3: the total mass beyond 1e150 times the lightest") {
    // advice only where the MPFR torus takes the chain: at beta = 1e-3 the heavy tail's
    // stiffness (1e297) is beyond it, at beta = 1e-200 it is not
    CHECK_THAT(in_double({1, 1, 1e300}, {1, 1, 1}, 1e-3), !Catch::Contains("request"));
    CHECK_THAT(in_double({1, 1, 1e160}, {1, 1, 1}, 1e-200), Catch::Contains(mpfr_advice));
    CHECK_THAT(in_double({1e-200, 1, 1}, {1, 1, 1}, 1), Catch::Contains(mpfr_advice));
    CHECK(in_double({1, 1, 1e140}, {1, 1, 1}, 1e-200).empty());
  }
}

TEST_CASE("domain: a mass ratio beyond double's range in MPFR (~15 s)", "[domain][.slow]") {
  AverageOptions o;
  o.digits = 17;
  const Chain<double> chain({1, 1, 1e160}, {1, 1, 1});
  const Averages<mpfr_real> a = pendavg::average(chain.cast<mpfr_real>(), mpfr_real(1e-200), o);
  REQUIRE(all_finite(a));
  REQUIRE(a.converged);
  // beta -> 0 with g beta S l -> 0: sum_i beta<K_i> = N/2 (equipartition of the total).
  mpfr_real total = 0;
  for (const auto& e : a.beta_kinetic) total += e.value;
  CHECK(abs(total - mpfr_real(1.5)) <= 1e-16);
}

TEST_CASE("domain: stiffness beyond what the torus resolves is refused in one line", "[domain]") {
  // Joint stiffnesses 1.2 beta and 1e-10 beta: at beta = 1e20 every joint is stiff but they
  // differ by 1.2e10, beyond the extrapolation's reference runs.
  const Chain<double> uneven({1, 1, 1}, {1, 1, 1e-10});
  const std::string uneven_message = rejection([&] { pendavg::average(uneven, 1e20); });
  CHECK_THAT(uneven_message, Catch::Contains("differ by more than 2.5e9"));
  CHECK_THAT(uneven_message, Catch::Contains("use method transfer"));
  CHECK(uneven_message.find('\n') == std::string::npos);
  // In MPFR the torus resolves kappa <= 1e9; at 16 digits the same chain is extrapolated.
  AverageOptions o30;
  o30.digits = 30;
  const Chain<double> unit({1, 1, 1}, {1, 1, 1});
  CHECK_THAT(rejection([&] { pendavg::average(unit.cast<mpfr_real>(), mpfr_real(1e20), o30); }),
             Catch::Contains("at 16 digits pendavg extrapolates"));
  CHECK(all_finite(pendavg::average(unit, 1e20)));
}

TEST_CASE("run control: a stopped torus reports its last finished level honestly", "[domain]") {
  // Stop once the second level has begun: the first level's values come back, interrupted,
  // not converged, with errors that still cover the converged answer.
  const Chain<double> chain({1, 1, 1}, {1, 1, 1});
  const Averages<double> converged = pendavg::average(chain, 2.0);
  std::atomic<bool> stop{false};
  AverageOptions o;
  int calls = 0;
  o.control.stop = &stop;
  o.control.progress = [&](double fraction) {
    CHECK(fraction > 0);
    CHECK(fraction <= 1);
    if (++calls > 40) stop = true;  // levels have 8, 16, 32, ... outer indices
  };
  const Averages<double> stopped = pendavg::average(chain, 2.0, o);
  CHECK(stopped.interrupted);
  CHECK_FALSE(stopped.converged);
  CHECK(stopped.evaluations < converged.evaluations);
  require_agree(stopped, converged);
  // Stopped before anything finished: no value at all, an `interrupted` exception.
  stop = true;
  o.control.progress = nullptr;
  CHECK_THROWS_AS(pendavg::average(chain, 2.0, o), pendavg::interrupted);
}

TEST_CASE("run control: a stopped qmc run reports the shifts it finished", "[domain]") {
  // One thread: the shifts finish in order. Stop after 5 of 16: an estimate from 5 shifts
  // (wider Student-t bars for 4 degrees of freedom), interrupted, not converged, covering the
  // converged answer; stopped before two shifts finished: the `interrupted` exception.
  const Chain<double> chain({1, 0.5, 2, 1, 1}, {1, 2, 0.5, 1, 1});
  AverageOptions o;
  o.method = pendavg::AverageMethod::qmc;
  o.samples = 4096;
  o.threads = 1;
  const Averages<double> full = pendavg::average(chain, 1.5, o);
  REQUIRE(full.qmc);
  CHECK(full.qmc->shifts == 16);
  std::atomic<bool> stop{false};
  std::vector<double> fractions;
  o.control.stop = &stop;
  o.control.progress = [&](double fraction) {
    fractions.push_back(fraction);
    if (fractions.size() == 5) stop = true;
  };
  const Averages<double> stopped = pendavg::average(chain, 1.5, o);
  CHECK(stopped.interrupted);
  CHECK_FALSE(stopped.converged);
  REQUIRE(stopped.qmc);
  CHECK(stopped.qmc->shifts == 5);
  CHECK(stopped.evaluations == 5 * 4096);
  CHECK(stopped.qmc->sigmas > full.qmc->sigmas);  // t quantile for 4 dof, 8.61 > 4.07
  CHECK(fractions.size() == 5);
  CHECK(fractions.back() == 5.0 / 16);  // k/16 exactly
  for (std::size_t i = 0; i < chain.size(); ++i) {
    // The first 5 shifts of the full run are the stopped run's shifts: the same seed.
    CHECK(std::abs(stopped.beta_kinetic[i].value - full.beta_kinetic[i].value) <=
          stopped.beta_kinetic[i].error + full.beta_kinetic[i].error);
    CHECK(stopped.beta_kinetic[i].error > full.beta_kinetic[i].error);
  }
  stop = false;
  fractions.clear();
  o.control.progress = [&](double) { stop = true; };  // after the first shift
  CHECK_THROWS_AS(pendavg::average(chain, 1.5, o), pendavg::interrupted);
}

TEST_CASE("run control: one big qmc point stops within its first shift", "[domain]") {
  // 2^16 points per shift are polled every 4096: a stop request ends the shift at the next
  // poll (no shift finished: the `interrupted` exception), and progress counts points.
  const Chain<double> chain({1, 0.5, 2, 1, 1, 1, 1, 1}, {1, 2, 0.5, 1, 1, 1, 1, 1});
  AverageOptions o;
  o.method = pendavg::AverageMethod::qmc;
  o.samples = 65536;
  o.threads = 1;
  std::atomic<bool> stop{false};
  std::vector<double> fractions;
  o.control.stop = &stop;
  o.control.progress = [&](double fraction) {
    fractions.push_back(fraction);
    if (fractions.size() == 3) stop = true;
  };
  CHECK_THROWS_AS(pendavg::average(chain, 1.0, o), pendavg::interrupted);
  REQUIRE(fractions.size() == 3);  // nothing more after the stop
  for (std::size_t k = 0; k < 3; ++k)
    CHECK(fractions[k] == static_cast<double>((k + 1) * 4096) / (16.0 * 65536));
}

TEST_CASE("run control: a stopped transfer run reports its last verified level", "[domain]") {
  // Polled between links (2N - 2 polls per level): stopped in the fourth level, the run reports
  // the second verified by the third, interrupted, not converged, covering the converged answer.
  // Stopped before two levels finished: the `interrupted` exception.
  const Chain<double> chain({1, 0.5, 2, 1, 1.5, 1, 0.7, 1}, {1, 2, 0.5, 1, 1, 0.8, 1, 1.2});
  AverageOptions o;
  o.tolerance = 1e-12;
  const Averages<double> converged = pendavg::average(chain, 2.0, o);
  REQUIRE(converged.method == Method::transfer);
  REQUIRE(converged.converged);
  const std::size_t polls_per_level = 2 * chain.size() - 2;
  for (const std::size_t stop_after : {3 * polls_per_level + 5, polls_per_level + 5, std::size_t(1)}) {
    std::atomic<bool> stop{false};
    std::size_t calls = 0;
    AverageOptions s = o;
    s.control.stop = &stop;
    s.control.progress = [&](double fraction) {
      CHECK(fraction >= 0);
      CHECK(fraction < 1);
      if (++calls == stop_after) stop = true;
    };
    INFO("stopped after " << stop_after << " polls");
    if (stop_after < 2 * polls_per_level) {
      CHECK_THROWS_AS(pendavg::average(chain, 2.0, s), pendavg::interrupted);
      continue;
    }
    const Averages<double> stopped = pendavg::average(chain, 2.0, s);
    CHECK(stopped.interrupted);
    CHECK_FALSE(stopped.converged);
    REQUIRE(stopped.transfer);
    CHECK(stopped.transfer->levels == 3);
    CHECK(stopped.evaluations < converged.evaluations);
    require_agree(stopped, converged);
  }
}

TEST_CASE("run control: microcanonical runs report progress and stop on request", "[domain]") {
  using pendavg::MicrocanonicalOptions;
  const Chain<double> pair({1, 2}, {1, 0.5});
  MicrocanonicalOptions o;
  std::vector<double> fractions;
  o.control.progress = [&](double f) { fractions.push_back(f); };
  const auto r = pendavg::microcanonical_average(pair, 0.3, o);
  CHECK(r.converged);
  REQUIRE_FALSE(fractions.empty());
  CHECK(fractions.back() == 1.0);
  for (const double f : fractions) CHECK((f > 0 && f <= 1));
  // A stop request ends the integral (within 256 nodes) and qmc (between shifts): no partial
  // result carries an error, so both throw `interrupted`.
  std::atomic<bool> stop{true};
  MicrocanonicalOptions stopped;
  stopped.control.stop = &stop;
  const Chain<double> three({1, 1, 1}, {1, 1, 1});
  CHECK_THROWS_AS(pendavg::microcanonical_average(three, 0.0, stopped), pendavg::interrupted);
  stopped.rule = MicrocanonicalOptions::Rule::qmc;
  stopped.points = 1024;
  const Chain<double> six(std::vector<double>(6, 1.0), std::vector<double>(6, 1.0));
  CHECK_THROWS_AS(pendavg::microcanonical_average(six, 0.0, stopped), pendavg::interrupted);
}

TEST_CASE("domain: the microcanonical engine's double range is checked before any work",
          "[domain]") {
  using pendavg::MicrocanonicalOptions;
  const Chain<double> pair({1, 1}, {1, 1});
  for (const auto& [chain, energy] :
       {std::pair{pair, 1e308}, std::pair{Chain<double>({1}, {1}), 1e300},
        std::pair{Chain<double>({1, 1, 1e300}, {1, 1, 1}), 0.0}}) {
    const std::string message = rejection([&] { pendavg::check_microcanonical(chain, energy); });
    CHECK_THAT(message, Catch::Contains("17 or more digits"));
    // check_microcanonical refuses exactly what the run refuses, with the same line.
    CHECK(rejection([&] { pendavg::microcanonical_average(chain, energy); }) == message);
  }
  CHECK_THAT(rejection([&] { pendavg::check_microcanonical_excitation(pair, 1e-310); }),
             Catch::Contains("subnormal"));
  CHECK_NOTHROW(pendavg::check_microcanonical(pair, 1e100));
  // The advice works: the MPFR run at E = 1e300 is finite and at the beta -> 0 limit
  // (mu1/2) K(k)/E(k) = 0.34318348147092485... of <K_1>_E / E for unit masses and lengths.
  pendavg::working_precision wp(20 + pendavg::guard_digits);
  MicrocanonicalOptions o;
  o.digits = 20;
  const auto r = pendavg::microcanonical_average(pair.cast<mpfr_real>(), mpfr_real(1e300), o);
  const mpfr_real ratio = r.kinetic[0].value / mpfr_real(1e300);
  CHECK(abs(ratio - mpfr_real("0.3431834814709248549")) < mpfr_real(1e-18));
}

TEST_CASE("domain: the transfer operator's mass range is checked before any work", "[domain]") {
  const Chain<double> extreme({1e-100, 1e100, 1, 1e-100, 1e100}, {1, 1, 1, 1, 1});
  CHECK_THAT(rejection([&] { pendavg::check_average(extreme, 1.0, AverageOptions{}); }),
             Catch::Contains("1e150"));
}

TEST_CASE("run control: the series refuses unbounded work and stops on request", "[domain]") {
  const Chain<mpfr_real> slow(std::vector<mpfr_real>{1, 1000}, std::vector<mpfr_real>{1, 1});
  CHECK_THAT(rejection([&] { pendavg::series_convergence(slow, mpfr_real(1), 16); }),
             Catch::Contains("beyond the automatic cap"));
  const Chain<mpfr_real> chain(std::vector<mpfr_real>{1, 50}, std::vector<mpfr_real>{1, 1});
  std::atomic<bool> stop{true};
  pendavg::RunControl control;
  control.stop = &stop;
  CHECK_THROWS_AS(pendavg::series_convergence(chain, mpfr_real(1), 16, 0, control),
                  pendavg::interrupted);
}

TEST_CASE("run control: an exception inside a parallel region surfaces to the caller",
          "[domain]") {
  // An exception may not leave an OpenMP region (std::terminate): the engines keep the first
  // one (engine/numerics/parallel.hpp) and rethrow it after the region. The series reports progress
  // from inside its two-thread Bessel-table region (rows beyond 48 terms); a throwing progress
  // callback must come back as that exception, and so must one thrown between transfer links.
  struct callback_failed : std::runtime_error {
    using std::runtime_error::runtime_error;
  };
  const Chain<mpfr_real> pair(std::vector<mpfr_real>{1, 50}, std::vector<mpfr_real>{1, 1});
  pendavg::RunControl control;
  int calls = 0;
  control.progress = [&](double) {
    if (++calls == 3) throw callback_failed("progress callback failed");
  };
  CHECK_THROWS_AS(pendavg::series_convergence(pair, mpfr_real(1), 16, 0, control),
                  callback_failed);
  // The stop request raised inside the same region: `interrupted`, after the region.
  std::atomic<bool> stop{false};
  pendavg::RunControl stopping;
  stopping.stop = &stop;
  calls = 0;
  stopping.progress = [&](double) {
    if (++calls == 3) stop = true;
  };
  CHECK_THROWS_AS(pendavg::series_convergence(pair, mpfr_real(1), 16, 0, stopping),
                  pendavg::interrupted);
  // Transfer on two threads, a level in progress.
  const Chain<double> chain(std::vector<double>(12, 1.0), std::vector<double>(12, 1.0));
  AverageOptions o;
  o.method = AverageMethod::transfer;
  o.threads = 2;
  calls = 0;
  o.control.progress = [&](double) {
    if (++calls == 30) throw callback_failed("progress callback failed");
  };
  CHECK_THROWS_AS(pendavg::average(chain, 1.0, o), callback_failed);
}
