// SPDX-License-Identifier: GPL-3.0-or-later
// tests/engine/certified/test_certified.cpp -- the certified N = 2 engine (src/engine/certified.md): a test per
// bound (Bessel tables by the mediant and by Arb's top orders, the Fourier moments, the tails of
// the Graf sums, the a priori ranges), the whole against Arb's rigorous integrator
// (tests/arb_oracle.hpp) and against higher-precision runs, and the refusals. Default: the fixed
// cases A-E and a few seeded random ones (a few seconds); [.slow]: 200 seeded random cases over
// mu1, l2/l1, beta, g and digits.
//
// What "holds" means here: an enclosure value +- error holds when every reference computed with
// more digits (another certified run, whose own error is added, and Arb's ball) lies within it;
// "tight" when the error is at most 10 times the larger of the true error |value - reference|
// and the result's own last unit (the value is rounded to the result type: its rounding is the
// smallest error any result of that type can claim).
#include <catch2/catch.hpp>

#include "pendavg/average.hpp"
#include "pendavg/mpfr.hpp"
#include "engine/double_pendulum/double_pendulum.hpp"
#include "engine/numerics/precision.hpp"

#ifdef PENDAVG_HAS_ARB
#include "arb_oracle.hpp"
#include "engine/certified.hpp"
#include "engine/detail/certified_balls.hpp"
#include "engine/detail/certified_fast.hpp"
#include "engine/double_pendulum/fourier_moments.hpp"

#include <arb_hypgeom.h>
#endif

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <random>
#include <string>
#include <vector>

using pendavg::AverageOptions;
using pendavg::Averages;
using pendavg::Chain;
using pendavg::ErrorKind;
using pendavg::Estimate;
using pendavg::mpfr_real;

namespace {

struct Case {
  double m1, m2, l1, l2, g, beta;
  std::string text() const {
    char buffer[200];
    std::snprintf(buffer, sizeof buffer, "m1=%.17g m2=%.17g l1=%.17g l2=%.17g g=%.17g beta=%.17g",
                  m1, m2, l1, l2, g, beta);
    return buffer;
  }
};

/// The benchmark's cases A-E (tests/bench/bench_arb_cases.cpp): l = g = 1, m1 = mu1,
/// m2 = double(1 - mu1).
const std::vector<Case> named_cases{{0.5, 0.5, 1, 1, 1, 1},       {0.05, 0.95, 1, 1, 1, 1},
                                    {1e-4, 1 - 1e-4, 1, 1, 1, 1}, {0.5, 0.5, 1, 1, 1, 100},
                                    {0.5, 0.5, 1, 1, 1, 1000}};

/// One observable of a run, as MPFR at the caller's precision.
struct Observable {
  mpfr_real value, error;
  ErrorKind kind;
};

/// Every observable of a result in a fixed order: beta<K_i>, <K1>/<K2>, <cos phi_i>,
/// beta^2 Var K_i.
template <class Real>
std::vector<Observable> observables(const Averages<Real>& a) {
  std::vector<Observable> out;
  const auto add = [&](const Estimate<Real>& e) {
    out.push_back({mpfr_real(e.value), mpfr_real(e.error), e.kind});
  };
  for (const auto& e : a.beta_kinetic) add(e);
  add(*a.ratio);
  for (const auto& e : a.cos_angle) add(e);
  for (const auto& e : a.beta2_kinetic_variance) add(e);
  return out;
}

const char* const observable_names[] = {"beta<K1>", "beta<K2>", "<K1>/<K2>", "<cos phi1>",
                                        "<cos phi2>", "beta^2 Var K1", "beta^2 Var K2"};

AverageOptions certified_options(int digits) {
  AverageOptions o;
  o.digits = digits;
  o.certified = true;
  return o;
}

/// The certified run of a case at `digits`, its observables at 200 digits.
std::vector<Observable> certified_run(const Case& c, int digits, bool* converged = nullptr,
                                      std::string* method = nullptr) {
  if (digits == 16) {
    const auto a = pendavg::average(Chain<double>({c.m1, c.m2}, {c.l1, c.l2}, c.g), c.beta,
                                    certified_options(16));
    if (converged) *converged = a.converged;
    if (method) *method = pendavg::method_name(a.method);
    const pendavg::working_precision wp(200);
    return observables(a);
  }
  Averages<mpfr_real> a;
  {
    const pendavg::working_precision wp(digits + pendavg::guard_digits);
    a = pendavg::average(Chain<mpfr_real>({mpfr_real(c.m1), mpfr_real(c.m2)},
                                          {mpfr_real(c.l1), mpfr_real(c.l2)}, mpfr_real(c.g)),
                         mpfr_real(c.beta), certified_options(digits));
  }
  if (converged) *converged = a.converged;
  if (method) *method = pendavg::method_name(a.method);
  const pendavg::working_precision wp(200);
  return observables(a);
}

/// The uncertified integral of a case at `digits` (an independent evaluation), at 200 digits.
std::vector<Observable> uncertified_run(const Case& c, int digits) {
  AverageOptions o;
  o.digits = digits;
  o.method = pendavg::AverageMethod::integral;
  Averages<mpfr_real> a;
  {
    const pendavg::working_precision wp(digits + pendavg::guard_digits);
    a = pendavg::average(Chain<mpfr_real>({mpfr_real(c.m1), mpfr_real(c.m2)},
                                          {mpfr_real(c.l1), mpfr_real(c.l2)}, mpfr_real(c.g)),
                         mpfr_real(c.beta), o);
  }
  const pendavg::working_precision wp(200);
  return observables(a);
}

/// The unit of the result's last place: 2^-52 |v| in double, 10^-(digits + guard) |v| in MPFR.
mpfr_real last_unit(const mpfr_real& value, int digits) {
  using std::abs;
  using std::pow;
  if (digits == 16) return abs(value) * pow(mpfr_real(2), -52);
  return abs(value) * pow(mpfr_real(10), -(digits + pendavg::guard_digits));
}

/// Checks one certified run against references with more digits; returns the worst ratio
/// error / max(true error, last unit) (the tightness).
double check_run(const Case& c, int digits, const std::vector<Observable>& run,
                 const std::vector<Observable>& reference, bool reference_is_bound) {
  using std::abs;
  const pendavg::working_precision wp(200);
  double worst = 0;
  for (std::size_t i = 0; i < run.size(); ++i) {
    INFO(c.text() << " digits " << digits << ": " << observable_names[i] << " = "
                  << run[i].value.str(digits + 5) << " +- " << run[i].error.str(3)
                  << ", reference " << reference[i].value.str(digits + 15) << " +- "
                  << reference[i].error.str(3));
    CHECK(run[i].kind == ErrorKind::bound);
    const mpfr_real distance = abs(run[i].value - reference[i].value);
    // The exact value lies within run.error of run.value; a bound reference within its own
    // error of the exact value; an estimate reference is far more accurate than the run.
    CHECK(distance <= run[i].error + (reference_is_bound ? reference[i].error : mpfr_real(0)));
    const mpfr_real truth = std::max(distance, last_unit(run[i].value, digits));
    if (truth > 0) worst = std::max(worst, static_cast<double>(run[i].error / truth));
  }
  return worst;
}

/// The certified run at `digits` against the certified run and the uncertified integral at
/// digits + 20; returns the tightness ratio (check_run).
double check_against_more_digits(const Case& c, int digits) {
  bool converged = false;
  std::string method;
  const auto run = certified_run(c, digits, &converged, &method);
  CHECK(method == "certified-integral");
  CHECK(converged);
  const double tight = check_run(c, digits, run, certified_run(c, digits + 20), true);
  check_run(c, digits, run, uncertified_run(c, digits + 20), false);
  return tight;
}

#ifdef PENDAVG_HAS_ARB

/// Arb's acb_calc_integrate (the oracle): beta<K1> and <x^2> = mu1^2 J_{-3/2}/J_{1/2} as balls
/// (`goal` bits, at most `evaluations` integrand evaluations each), and whether the certified
/// run's beta<K1> and beta^2 Var K1 meet them. Returns whether Arb's beta<K1> ball came within
/// 2^-20 (relative), i.e. was a sharp test.
bool check_against_arb(const Case& c, int digits, const std::vector<Observable>& run,
                       slong evaluations = 200000) {
  const slong goal = digits == 16 ? 53 : static_cast<slong>(std::ceil(digits * 3.3219281)) + 4;
  const slong prec = goal + 32;
  pendavg_test::ArbIntegrand f;
  f.set(c.m1, c.m2, c.l1, c.l2, c.g, c.beta, prec);
  arb_t half, minus_half, three, k1, x2, var1, t;
  for (arb_ptr x : {half, minus_half, three, k1, x2, var1, t}) arb_init(x);
  pendavg_test::arb_reduced_integral(half, f, 1, goal, prec, evaluations);
  pendavg_test::arb_reduced_integral(minus_half, f, -1, goal, prec, evaluations);
  pendavg_test::arb_reduced_integral(three, f, -3, goal, prec, evaluations);
  arb_div(k1, minus_half, half, prec);
  arb_mul(k1, k1, f.mu1, prec);
  arb_mul_2exp_si(k1, k1, -1);  // beta<K1> = <x>/2
  arb_div(x2, three, half, prec);
  arb_mul(x2, x2, f.mu1, prec);
  arb_mul(x2, x2, f.mu1, prec);
  // beta^2 Var K1 = (3/4)<x^2> - <x>^2/4 = (3/4)<x^2> - beta<K1>^2
  arb_mul_ui(var1, x2, 3, prec);
  arb_mul_2exp_si(var1, var1, -2);
  arb_sqr(t, k1, prec);
  arb_sub(var1, var1, t, prec);
  const auto meets = [&](const Observable& o, const arb_t ball, const char* name) {
    // |value - ball| <= error: the ball and value +- error overlap
    arb_t v, d;
    arb_init(v);
    arb_init(d);
    arf_set_mpfr(arb_midref(v), o.value.backend().data());
    arb_sub(d, v, ball, prec + 64);
    arb_abs(d, d);
    arb_t e;
    arb_init(e);
    arf_set_mpfr(arb_midref(e), o.error.backend().data());
    INFO(c.text() << " digits " << digits << ": " << name << " = " << o.value.str(digits + 5)
                  << " +- " << o.error.str(3) << ", Arb midpoint "
                  << arf_get_d(arb_midref(ball), ARF_RND_NEAR) << " radius "
                  << mag_get_d(arb_radref(ball)));
    CHECK(!arb_gt(d, e));
    arb_clear(v);
    arb_clear(d);
    arb_clear(e);
  };
  meets(run[0], k1, "beta<K1>");
  meets(run[5], var1, "beta^2 Var K1");
  const bool sharp = arb_rel_accuracy_bits(k1) >= 20;
  for (arb_ptr x : {half, minus_half, three, k1, x2, var1, t}) arb_clear(x);
  return sharp;
}

#endif  // PENDAVG_HAS_ARB

/// Seeded random cases: mu1 log-uniform in [1e-9, 1 - 1e-9] (either side of 1/2), l2/l1 in
/// [1e-4, 1e4], beta in [1e-9, 1e6], g in [1e-2, 1e2] (log-uniform), digits 16 or 17..60.
struct RandomCase {
  Case c;
  int digits;
};
std::vector<RandomCase> random_cases(std::size_t count, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  const auto uniform = [&] { return static_cast<double>(rng() >> 11) * 0x1.0p-53; };
  const auto log_uniform = [&](double lo, double hi) {
    return std::exp(std::log(lo) + (std::log(hi) - std::log(lo)) * uniform());
  };
  std::vector<RandomCase> out;
  for (std::size_t i = 0; i < count; ++i) {
    const double x = log_uniform(1e-9, 0.5);
    const double mu1 = i % 2 == 0 ? x : 1 - x;
    RandomCase r;
    r.c = {mu1, 1 - mu1, 1.0, log_uniform(1e-4, 1e4), log_uniform(1e-2, 1e2),
           log_uniform(1e-9, 1e6)};
    r.digits = uniform() < 0.4 ? 16 : 17 + static_cast<int>(uniform() * 44);
    out.push_back(r);
  }
  return out;
}

}  // namespace

TEST_CASE("certified: refused outside N = 2 and the integral, or without Arb", "[certified]") {
  AverageOptions o = certified_options(16);
  if (!pendavg::certified_available()) {
    CHECK_THROWS_AS(pendavg::average(Chain<double>({1, 1}, {1, 1}, 1), 1.0, o),
                    pendavg::invalid_input);
    return;
  }
  CHECK_THROWS_AS(pendavg::average(Chain<double>({1, 1, 1}, {1, 1, 1}, 1), 1.0, o),
                  pendavg::invalid_input);
  o.method = pendavg::AverageMethod::series;
  CHECK_THROWS_AS(pendavg::average(Chain<double>({1, 1}, {1, 1}, 1), 1.0, o),
                  pendavg::invalid_input);
  o.method = pendavg::AverageMethod::integral;
  const auto a = pendavg::average(Chain<double>({1, 1}, {1, 1}, 1), 1.0, o);
  CHECK(a.method == pendavg::Method::certified_integral);
  CHECK(a.error_kind == ErrorKind::bound);
  CHECK(a.converged);
}

#ifdef PENDAVG_HAS_ARB

TEST_CASE("certified: cases A-E hold against Arb's integrator and more digits, and are tight",
          "[certified]") {
  for (const Case& c : named_cases) {
    for (const int digits : {16, 38}) {
      const auto run = certified_run(c, digits);
      check_against_arb(c, digits, run);
      const double tight = check_against_more_digits(c, digits);
      INFO(c.text() << " digits " << digits << ": error / max(true error, last unit) = " << tight);
      CHECK(tight <= 10);
    }
  }
}

TEST_CASE("certified: seeded random cases hold and are tight (a default subset)", "[certified]") {
  for (const RandomCase& r : random_cases(10, 30)) {
    const double tight = check_against_more_digits(r.c, r.digits);
    INFO(r.c.text() << " digits " << r.digits << ": tightness " << tight);
    CHECK(tight <= 10);
  }
}

TEST_CASE("certified: hard cases hold and are tight", "[certified]") {
  // mu1 -> 0 (the 2F1 at z = r^2 next to 1), mu2 -> 0, beta -> infinity, g = 0, extreme lengths
  for (const auto& [c, digits] :
       {std::pair{Case{1e-150, 1, 1, 1, 1, 1}, 30}, std::pair{Case{1e-12, 1, 1, 1, 1, 1e4}, 16},
        std::pair{Case{1, 1e-150, 1, 1, 1, 1}, 30}, std::pair{Case{1, 1, 1, 1, 1, 1e12}, 20},
        std::pair{Case{1, 1, 1, 1, 0, 1}, 16}, std::pair{Case{1, 1, 1, 1e4, 1, 1e6}, 16},
        std::pair{Case{1, 1, 1, 1e-4, 1, 1e6}, 25}}) {
    const double tight = check_against_more_digits(c, digits);
    INFO(c.text() << " digits " << digits << ": tightness " << tight);
    CHECK(tight <= 10);
  }
}

TEST_CASE("certified: a subnormal scale at 36-40 digits is computed, not a crash", "[certified]") {
  // a2 = beta g m2 l2 below double's range made the Graf row plan NaN (m / a2 overflowed):
  // a segmentation fault certified, "cannot create std::vector larger than max_size()" not.
  for (const auto& [c, digits] :
       {std::pair{Case{1, 1e-320, 1, 1, 1, 1}, 40}, std::pair{Case{1, 1e-300, 1, 1, 1, 1e-12}, 37},
        std::pair{Case{1, 1e-200, 1, 1e-110, 1, 0.1}, 40}}) {
    const double tight = check_against_more_digits(c, digits);
    INFO(c.text() << " digits " << digits << ": tightness " << tight);
    CHECK(tight <= 10);
  }
}

TEST_CASE("certified: the uncertified integral's errors cover it where a link's scale is tiny",
          "[certified]") {
  // <cos phi_j>'s Graf rows were trimmed against <K>'s scale, not their own: where a_j is
  // ~1e-40 of the other link's (1e-20 at beta = 1e-6) every row but the first was cut, and
  // <cos phi_2> came out as a2/2, 7% off with an error of 1e-14 of it. The same at 30 and 60
  // digits for 1e-100 and 1e-200; and a subnormal a2 at 37-40 digits failed (above).
  const std::pair<Case, int> cases[] = {
      {Case{1, 1, 1, 1e-40, 1, 5}, 16},    {Case{1, 1, 1e-40, 1, 1, 5}, 16},
      {Case{1, 1, 1, 1e-20, 1, 1e-6}, 16}, {Case{1, 1, 1, 1e-100, 1, 5}, 30},
      {Case{1, 1, 1, 1e-200, 1, 5}, 60},   {Case{1, 1e-320, 1, 1, 1, 1}, 40},
      {Case{1, 1e-300, 1, 1, 1, 1e-12}, 37}};
  for (const auto& [c, digits] : cases) {
    std::vector<Observable> plain;
    if (digits == 16) {
      AverageOptions o;
      o.method = pendavg::AverageMethod::integral;
      const auto a = pendavg::average(Chain<double>({c.m1, c.m2}, {c.l1, c.l2}, c.g), c.beta, o);
      const pendavg::working_precision wp(200);
      plain = observables(a);
    } else {
      plain = uncertified_run(c, digits);
    }
    const auto certified = certified_run(c, digits);
    const pendavg::working_precision wp(200);
    for (std::size_t i = 0; i < plain.size(); ++i) {
      INFO(c.text() << " digits " << digits << ": " << observable_names[i] << " "
                    << plain[i].value << " +- " << plain[i].error << ", certified "
                    << certified[i].value << " +- " << certified[i].error);
      CHECK(abs(plain[i].value - certified[i].value) <= plain[i].error + certified[i].error);
    }
  }
}

TEST_CASE("certified: the beta -> 0 limit holds against the elliptic formula", "[certified]") {
  for (const double mu1 : {0.5, 1e-9, 1 - 1e-9}) {
    const Case c{mu1, 1 - mu1, 1, 1, 1, 1};
    AverageOptions o = certified_options(30);
    Averages<mpfr_real> certified, reference;
    {
      const pendavg::working_precision wp(30 + pendavg::guard_digits);
      certified = pendavg::high_temperature_limit(
          Chain<mpfr_real>({mpfr_real(c.m1), mpfr_real(c.m2)}, {mpfr_real(1), mpfr_real(1)},
                           mpfr_real(1)),
          o);
    }
    {
      AverageOptions more;
      more.digits = 60;
      const pendavg::working_precision wp(60 + pendavg::guard_digits);
      reference = pendavg::high_temperature_limit(
          Chain<mpfr_real>({mpfr_real(c.m1), mpfr_real(c.m2)}, {mpfr_real(1), mpfr_real(1)},
                           mpfr_real(1)),
          more);
    }
    const pendavg::working_precision wp(200);
    check_run(c, 30, observables(certified), observables(reference), false);
    // and the certified average at beta = 1e-30 is within O(beta) of it
    const auto near = certified_run({mu1, 1 - mu1, 1, 1, 1, 1e-30}, 30);
    const auto limit = observables(certified);
    CHECK(abs(near[0].value - limit[0].value) <= near[0].error + limit[0].error + 1e-29);
  }
}

TEST_CASE("certified: Bessel tables by the mediant and by Arb's top orders enclose Arb's I~_m",
          "[certified]") {
  using namespace pendavg::certified_detail;
  const slong prec = 200;
  for (const double a_d : {1e-6, 0.7, 30.0, 1000.0}) {
    Ball a, nu, direct;
    arb_set_d(a, a_d);
    const slong count = 40;
    Balls automatic(count), short_run(count), from_top(count);
    scaled_bessel_table(automatic, a, a_d, 140, prec);
    scaled_bessel_table(short_run, a, a_d, 140, prec, 3);  // far too short: still enclosures
    scaled_bessel_table(from_top, a, a_d, 140, prec, 0);
    for (slong m = 0; m < count; m += 3) {
      arb_set_si(nu, m);
      arb_hypgeom_bessel_i_scaled(direct, nu, a, prec);
      INFO("a = " << a_d << ", m = " << m);
      CHECK(arb_overlaps(automatic[m], direct));
      CHECK(arb_overlaps(short_run[m], direct));
      CHECK(arb_overlaps(from_top[m], direct));
      // the planned run resolves the table to ~prec bits of its first entry
      CHECK(mag_cmp_2exp_si(arb_radref(automatic[m]), -(prec - 24)) <= 0);
    }
  }
}

TEST_CASE("certified: the moment rows enclose the uncertified moments at higher precision",
          "[certified]") {
  using namespace pendavg::certified_detail;
  const slong prec = 200;
  for (const double mu1 : {0.5, 0.05, 1e-4, 1e-9, 1 - 1e-6}) {
    const Chain<double> chain({mu1, 1 - mu1}, {1, 1}, 1);
    const Parameters p = parameters_of<double>(chain, nullptr, prec);
    const slong K = 60;
    const Moments m = moments_of(p, K, prec);
    const pendavg::working_precision wp(90);
    const mpfr_real m1(mu1), m2(1 - mu1), M = m1 + m2;
    const auto reference = pendavg::detail::q_power_moments(mpfr_real(m1 / M), mpfr_real(m2 / M),
                                                            static_cast<std::size_t>(K));
    const std::array<const Balls*, 3> rows{&m.half, &m.minus_half, &m.minus_three_halves};
    for (std::size_t row = 0; row < 3; ++row) {
      for (slong k = 0; k < K; k += 7) {
        Ball ref;
        arf_set_mpfr(arb_midref(ref),
                     reference.Q[row][static_cast<std::size_t>(k)].backend().data());
        const mpfr_real bound = reference.relative_error * abs(reference.Q[row][0]);
        arf_t f;
        arf_init(f);
        arf_set_mpfr(f, bound.backend().data());
        mag_t e;
        mag_init(e);
        arf_get_mag(e, f);
        arb_add_error_mag(ref, e);
        INFO("mu1 = " << mu1 << ", row " << row << ", k = " << k);
        CHECK(arb_overlaps((*rows[row])[k], ref));
        // tight: the radius is within 2^-(prec - 40) of the row's scale |Q_0|
        const double scale =
            std::ldexp(std::fabs(arf_get_d(arb_midref((*rows[row])[0]), ARF_RND_NEAR)), -(prec - 40));
        CHECK(mag_get_d(arb_radref((*rows[row])[k])) <= scale);
        arf_clear(f);
        mag_clear(e);
      }
    }
  }
}

#endif  // PENDAVG_HAS_ARB

#ifdef PENDAVG_HAS_ARB

TEST_CASE("certified: truncated Graf sums still enclose, with tail bounds near the true tail",
          "[certified]") {
  using namespace pendavg::certified_detail;
  const slong prec = 200;
  struct TailCase {
    double mu1, beta, l2;
  };
  for (const TailCase t : {TailCase{0.5, 10, 1}, TailCase{0.05, 3, 1}, TailCase{1e-4, 30, 1},
                           TailCase{1e-9, 100, 1}, TailCase{1e-4, 1, 100},
                           TailCase{0.9, 50, 0.01}}) {
    const Chain<double> chain({t.mu1, 1 - t.mu1}, {1.0, t.l2}, 1.0);
    const Parameters p = parameters_of<double>(chain, &t.beta, prec);
    const Integrals full = integrals_of(p, 400, 150, prec);
    for (const slong K : {2, 4, 8, 16}) {
      const Integrals cut = integrals_of(p, K, 150, prec);
      for (std::size_t j = 0; j < 5; ++j) {
        INFO("mu1 = " << t.mu1 << ", beta = " << t.beta << ", l2 = " << t.l2 << ", K = " << K
                      << ", integral " << j);
        CHECK(arb_overlaps(cut.value[j], full.value[j]));
        // where the tail dominates the radius, the bound is within 100x of the true tail
        // (measured: 1.0-65x; the s = 1/2 rows' bound r^K E/(2K-1) against ~1/(4K^2))
        Ball d;
        arb_sub(d, cut.value[j], full.value[j], prec);
        const double truth = std::fabs(arf_get_d(arb_midref(d), ARF_RND_NEAR));
        const double radius = mag_get_d(arb_radref(cut.value[j]));
        const double scale = std::fabs(arf_get_d(arb_midref(full.value[j]), ARF_RND_NEAR));
        if (radius > std::ldexp(scale, -(prec - 40))) CHECK(radius <= 100 * truth);
      }
    }
  }
}

TEST_CASE("certified: beyond the work limit converged is false and the bound still holds",
          "[certified]") {
  // mu1 = 1e-9 at beta = 1e9: ~1.2e5 Graf rows (and no moment cut) against the limit of 40000
  const Case c{1e-9, 1 - 1e-9, 1, 1, 1, 1e9};
  bool converged = true;
  const auto run = certified_run(c, 16, &converged);
  CHECK_FALSE(converged);
  AverageOptions o;
  o.digits = 30;
  Averages<mpfr_real> reference;
  {
    const pendavg::working_precision wp(30 + pendavg::guard_digits);
    reference = pendavg::average(Chain<mpfr_real>({mpfr_real(c.m1), mpfr_real(c.m2)},
                                                  {mpfr_real(1), mpfr_real(1)}, mpfr_real(1)),
                                 mpfr_real(c.beta), o);
  }
  const pendavg::working_precision wp(200);
  check_run(c, 16, run, observables(reference), false);
  for (const Observable& x : run) CHECK(x.kind == ErrorKind::bound);
}

TEST_CASE("certified: 200 seeded random cases hold against Arb's integrator and more digits",
          "[certified][.slow]") {
  double worst = 0;
  std::size_t not_converged = 0, sharp = 0;
  for (const RandomCase& r : random_cases(200, 2026)) {
    bool converged = false;
    const auto run = certified_run(r.c, r.digits, &converged);
    if (!converged) ++not_converged;
    // Arb's integrator gets 20000 evaluations per integral (seconds); where it stops short its
    // ball is wide (still a check, a weak one): counted.
    if (check_against_arb(r.c, r.digits, run, 20000)) ++sharp;
    const double tight = check_against_more_digits(r.c, r.digits);
    INFO(r.c.text() << " digits " << r.digits << ": tightness " << tight);
    CHECK(tight <= 10);
    worst = std::max(worst, tight);
  }
  std::printf("certified random cases: worst error / max(true error, last unit) = %.2f, "
              "%zu not converged, %zu of 200 Arb balls within 2^-20\n", worst, not_converged,
              sharp);
  CHECK(not_converged == 0);
}

#endif  // PENDAVG_HAS_ARB

#ifdef PENDAVG_HAS_ARB

// ---------------------------------------------------------------- the double fast path (Sec. 10)

namespace {

using pendavg::certified_fast::Enclosure;
using pendavg::certified_fast::Variant;

/// The fast path's ball hi + lo +- rad as an Arb ball (exact midpoint, radius rounded up).
void set_enclosure(arb_t out, const Enclosure& e) {
  arf_t t;
  arf_init(t);
  arf_set_d(arb_midref(out), e.hi);
  arf_set_d(t, e.lo);
  arf_add(arb_midref(out), arb_midref(out), t, ARF_PREC_EXACT, ARF_RND_DOWN);
  arf_clear(t);
  mag_set_d(arb_radref(out), e.rad);
}

/// An MPFR value +- error as an Arb ball.
void set_observable(arb_t out, const Observable& o) {
  arf_set_mpfr(arb_midref(out), o.value.backend().data());
  arf_t f;
  arf_init(f);
  arf_set_mpfr(f, o.error.backend().data());
  arf_get_mag(arb_radref(out), f);
  arf_clear(f);
}

/// The variants this CPU runs: baseline always, fma where it has fused multiply-adds.
std::vector<Variant> runnable_variants() {
  std::vector<Variant> out{Variant::baseline};
  if (pendavg::certified_fast::fast_double_has_fma()) out.push_back(Variant::fma);
  return out;
}

struct FastCheck {
  bool taken = false;
  double worst_radius_over_error = 0;  // raw ball radius / |midpoint - reference|
  double tightness = 0;                // the public result's error / max(true error, last unit)
};

/// The fast path on one case in every runnable variant: each ball contains the Arb engine's
/// 50-digit enclosure, the variants agree bit for bit, and the public (double) result is tight
/// against that reference. Nothing checked (taken = false) where the path refuses the case.
FastCheck check_fast(const Case& c) {
  FastCheck out;
  const Chain<double> chain({c.m1, c.m2}, {c.l1, c.l2}, c.g);
  std::vector<pendavg::certified_fast::FastResult> results;
  for (const Variant v : runnable_variants()) {
    const auto r = pendavg::certified_fast::fast_double_average(chain, c.beta, v);
    if (!r) {
      INFO(c.text() << ": refused at line " << pendavg::certified_fast::fast_double_last_refusal());
      CHECK(results.empty());  // both variants refuse alike
      return out;
    }
    results.push_back(*r);
  }
  out.taken = true;
  const auto reference = certified_run(c, 50);
  const pendavg::working_precision wp(200);
  arb_t ball, ref, d;
  arb_init(ball);
  arb_init(ref);
  arb_init(d);
  for (std::size_t i = 0; i < 7; ++i) {
    const Enclosure& e = results[0].observables[i];
    for (std::size_t v = 1; v < results.size(); ++v) {
      const Enclosure& f = results[v].observables[i];
      CHECK((f.hi == e.hi && f.lo == e.lo && f.rad == e.rad));  // same exact operations
    }
    set_enclosure(ball, e);
    set_observable(ref, reference[i]);
    INFO(c.text() << ": " << observable_names[i] << " = " << e.hi << " + " << e.lo << " +- "
                  << e.rad << ", reference " << reference[i].value.str(40) << " +- "
                  << reference[i].error.str(3));
    CHECK(arb_contains(ball, ref));
    CHECK((e.rad <= std::ldexp(std::fabs(e.hi), -60) || e.rad <= 0x1p-900));
    arb_sub(d, ball, ref, 400);
    const double truth = std::fabs(arf_get_d(arb_midref(d), ARF_RND_NEAR));
    if (truth > 0) out.worst_radius_over_error = std::max(out.worst_radius_over_error, e.rad / truth);
  }
  arb_clear(ball);
  arb_clear(ref);
  arb_clear(d);
  // the public double result (the fast path when it certifies) against the same reference
  const auto run = certified_run(c, 16);
  out.tightness = check_run(c, 16, run, reference, true);
  return out;
}

}  // namespace

TEST_CASE("certified fast path: cases A-E and hard cases are enclosed in both variants",
          "[certified]") {
  for (const Case& c : named_cases) {
    const FastCheck f = check_fast(c);
    INFO(c.text());
    CHECK(f.taken);
    CHECK(f.tightness <= 10);
    // and the Arb engine in double (what runs where the fast path declines) on the same case
    const Chain<double> chain({c.m1, c.m2}, {c.l1, c.l2}, c.g);
    const auto by_arb =
        pendavg::certified_detail::arb_double_pendulum_average<double>(chain, c.beta, 16);
    CHECK(by_arb.converged);
    CHECK(check_run(c, 16, observables(by_arb), certified_run(c, 50), true) <= 10);
  }
  // mu1 at either end, tiny and huge beta, g = 0, extreme lengths; where the path refuses, the
  // public call is the Arb engine's result
  std::size_t taken = 0;
  for (const Case& c :
       {Case{1e-9, 1 - 1e-9, 1, 1, 1, 1}, Case{1 - 1e-9, 1e-9, 1, 1, 1, 1},
        Case{0.5, 0.5, 1, 1, 1, 1e-9}, Case{1e-9, 1 - 1e-9, 1, 1, 1, 1e4},
        Case{0.3, 0.7, 1, 1e4, 1e-2, 30}, Case{0.3, 0.7, 1, 1e-4, 1e2, 3e4},
        Case{1, 1, 1, 1, 0, 1}, Case{0.5, 0.5, 1, 1, 1, 79.5}, Case{0.5, 0.5, 1, 1, 1, 80.5},
        Case{1, 1, 1, 1e4, 1, 1e6}, Case{0.5, 0.5, 1, 1, 1e300, 1e-300}}) {
    const FastCheck f = check_fast(c);
    INFO(c.text());
    if (f.taken) {
      ++taken;
      CHECK(f.tightness <= 10);
    } else {
      const Chain<double> chain({c.m1, c.m2}, {c.l1, c.l2}, c.g);
      const auto via_public = pendavg::average(chain, c.beta, certified_options(16));
      const auto by_arb =
          pendavg::certified_detail::arb_double_pendulum_average<double>(chain, c.beta, 16);
      for (std::size_t i = 0; i < 2; ++i) {
        CHECK(via_public.beta_kinetic[i].value == by_arb.beta_kinetic[i].value);
        CHECK(via_public.beta_kinetic[i].error == by_arb.beta_kinetic[i].error);
      }
    }
  }
  CHECK(taken == 10);  // all but g = 1e300 (outside the path's input range: the Arb engine)
}

/// The fast path on `count` seeded random cases: every case it takes is enclosed and tight
/// (check_fast), and `against_arb` also checks it against Arb's integrator; returns how many it
/// took.
std::size_t check_random_fast_cases(std::size_t count, unsigned seed, bool against_arb) {
  std::size_t taken = 0;
  double worst_tightness = 0, worst_radius = 0;
  for (const RandomCase& r : random_cases(count, seed)) {
    const FastCheck f = check_fast(r.c);
    if (!f.taken) continue;
    ++taken;
    INFO(r.c.text());
    CHECK(f.tightness <= 10);
    worst_tightness = std::max(worst_tightness, f.tightness);
    worst_radius = std::max(worst_radius, f.worst_radius_over_error);
    // and against Arb's integrator (beta<K1>, beta^2 Var K1)
    if (against_arb) check_against_arb(r.c, 16, certified_run(r.c, 16), 20000);
  }
  std::printf("fast path, %zu random cases: %zu taken, worst public tightness %.2f, worst raw "
              "radius / true error %.3g\n", count, taken, worst_tightness, worst_radius);
  return taken;
}

TEST_CASE("certified fast path: seeded random cases are enclosed (a default subset)",
          "[certified]") {
  CHECK(check_random_fast_cases(24, 31, false) >= 23);  // measured: 24 of 24
}

TEST_CASE("certified fast path: 300 seeded random cases are enclosed", "[certified][.slow]") {
  CHECK(check_random_fast_cases(300, 2027, true) >= 295);  // measured: 300 of 300
}

TEST_CASE("certified fast path: Bessel tables and low orders enclose Arb's I~_m",
          "[certified]") {
  arb_t direct, ball, nu, a;
  for (arb_ptr x : {direct, ball, nu, a}) arb_init(x);
  for (const Variant v : runnable_variants()) {
    for (const double a_d : {0.0, 1e-9, 0.7, 30.0, 79.99, 80.0, 150.0, 1000.0, 3e4}) {
      for (const std::size_t count : {std::size_t{2}, std::size_t{40}}) {
        const auto t = pendavg::certified_fast::fast_double_bessel(a_d, count, v);
        INFO("a = " << a_d << ", count " << count);
        REQUIRE(t);
        arb_set_d(a, a_d);
        for (std::size_t m = 0; m < count; ++m) {
          arb_set_si(nu, static_cast<slong>(m));
          if (a_d == 0) {
            arb_set_si(direct, m == 0 ? 1 : 0);
          } else {
            arb_hypgeom_bessel_i_scaled(direct, nu, a, 256);
          }
          set_enclosure(ball, (*t)[m]);
          INFO("m = " << m << ": " << (*t)[m].hi << " +- " << (*t)[m].rad);
          CHECK(arb_contains(ball, direct));
          // tight: within 2^-80 of the first entry
          CHECK((*t)[m].rad <= std::ldexp((*t)[0].hi, -80));
        }
      }
    }
  }
  for (arb_ptr x : {direct, ball, nu, a}) arb_clear(x);
}

TEST_CASE("certified fast path: the moment rows, forward and from the top, enclose the moments",
          "[certified]") {
  for (const Variant v : runnable_variants()) {
    for (const double mu1 : {0.5, 0.05, 1e-4, 1e-9, 1 - 1e-6}) {
      for (const std::size_t K : {std::size_t{3}, std::size_t{60}}) {
        const auto rows = pendavg::certified_fast::fast_double_moments(mu1, 1 - mu1, K, v);
        INFO("mu1 = " << mu1 << ", K = " << K);
        REQUIRE(rows);
        const pendavg::working_precision wp(90);
        const mpfr_real m1(mu1), m2(1 - mu1), M = m1 + m2;
        const auto reference =
            pendavg::detail::q_power_moments(mpfr_real(m1 / M), mpfr_real(m2 / M), K);
        arb_t ball, ref;
        arb_init(ball);
        arb_init(ref);
        for (std::size_t row = 0; row < 3; ++row) {
          for (std::size_t k = 0; k < K; ++k) {
            arf_set_mpfr(arb_midref(ref), reference.Q[row][k].backend().data());
            const mpfr_real bound = reference.relative_error * abs(reference.Q[row][0]);
            arf_t f;
            arf_init(f);
            arf_set_mpfr(f, bound.backend().data());
            arf_get_mag(arb_radref(ref), f);
            arf_clear(f);
            const Enclosure& e = (*rows)[row][k];
            set_enclosure(ball, e);
            INFO("row " << row << ", k = " << k << ": " << e.hi << " +- " << e.rad);
            CHECK(arb_overlaps(ball, ref));
            // tight: the forward route's radii grow like k^2 from 2^-96 per operation (measured
            // 2^-80 at k = 9 to 2^-74.5 at k = 59 of |Q_0| for mu1 = 1e-9); the top-down
            // route's stay near 2^-90
            CHECK(e.rad <= std::ldexp(std::fabs((*rows)[row][0].hi), -72));
          }
        }
        arb_clear(ball);
        arb_clear(ref);
      }
    }
  }
}

#endif  // PENDAVG_HAS_ARB
