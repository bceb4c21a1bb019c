// SPDX-License-Identifier: GPL-3.0-or-later
// tests/test_fail_closed.cpp -- the one domain module (src/domain.hpp) and the result checks:
// every entry point refuses before any work what its engines cannot compute, a NaN or an
// overflow is a refusal (never a pass), no non-finite or underflowed number is returned, and
// advice to request more digits is given only where it works. One test per root cause found by
// the hostile-input audit, by name.
#include <catch2/catch.hpp>

#include "domain.hpp"
#include "engine/transfer/chain_transfer.hpp"
#include "engine/torus/torus.hpp"
#include "refusals.hpp"
#include "pendavg/mpfr.hpp"
#include "pendavg/pendavg.hpp"

#include <cmath>
#include <limits>
#include <string>
#include <vector>

namespace {

using pendavg::AverageOptions;
using pendavg::Averages;
using pendavg::Chain;
using pendavg::Estimate;
using pendavg::mpfr_real;

using pendavg_test::all_finite;
using pendavg_test::rejection;

AverageOptions digits(int d) {
  AverageOptions o;
  o.digits = d;
  return o;
}

const std::string mpfr_advice = "request 17 or more digits (MPFR)";

}  // namespace

TEST_CASE("fail closed: limit with the lightest mass fraction below double's normal range",
          "[fail_closed]") {
  // masses 1e-300, 1e20: mu1 = 1e-320 is subnormal. It printed beta<K1> = 1.848981e-318 with an
  // error (4.9e-324) that did not cover, and a NaN beta^2 Var K_1 with converged = true.
  const Chain<double> chain({1e-300, 1e20}, {1, 0.5});
  for (const std::string& message :
       {rejection([&] { pendavg::high_temperature_limit(chain); }),
        rejection([&] { pendavg::low_temperature_limit(chain); })}) {
    CHECK_THAT(message, Catch::Contains("below double's normal range"));
    CHECK_THAT(message, Catch::Contains(mpfr_advice));
  }
  // The advice works: both limits in MPFR are finite, and 17 and 40 digits agree.
  const Chain<mpfr_real> wide = chain.cast<mpfr_real>();
  const Averages<mpfr_real> h17 = pendavg::high_temperature_limit(wide, digits(17));
  const Averages<mpfr_real> h40 = pendavg::high_temperature_limit(wide, digits(40));
  const Averages<mpfr_real> l17 = pendavg::low_temperature_limit(wide, digits(17));
  REQUIRE(all_finite(h17));
  REQUIRE(all_finite(l17));
  const mpfr_real k17 = h17.beta_kinetic[0].value, k40 = h40.beta_kinetic[0].value;
  CHECK(k17 > 0);
  CHECK(abs(k17 - k40) <= h17.beta_kinetic[0].error + h40.beta_kinetic[0].error);
}

TEST_CASE("fail closed: limit with M / m_min beyond the trace formula's double range",
          "[fail_closed]") {
  // masses 1, 1e154, 1: the beta -> infinity traces overflowed (NaN) and the beta -> 0 torus at
  // g = 0 ran for minutes.
  for (const std::vector<double>& masses :
       {std::vector<double>{1, 1e154, 1}, std::vector<double>{0.5, 1e-300, 5.467694768196e306}}) {
    const Chain<double> chain(masses, std::vector<double>(3, 1.0));
    CHECK_FALSE(rejection([&] { pendavg::high_temperature_limit(chain); }).empty());
    CHECK_FALSE(rejection([&] { pendavg::low_temperature_limit(chain); }).empty());
  }
  // Inside the range both limits still run.
  const Chain<double> inside({1, 1e100, 1}, {1, 1, 1});
  CHECK(all_finite(pendavg::low_temperature_limit(inside)));
}

TEST_CASE("fail closed: limit N = 2 with mu1 = 1e-400 is one refusal, not Boost's ellint_rf",
          "[fail_closed]") {
  const Chain<double> chain({1e-200, 1e200}, {1, 1});
  const std::string message = rejection([&] { pendavg::high_temperature_limit(chain); });
  CHECK_THAT(message, Catch::Contains("below double's normal range"));
  CHECK(message.find("ellint") == std::string::npos);
  CHECK(all_finite(pendavg::high_temperature_limit(chain.cast<mpfr_real>(), digits(20))));
}

TEST_CASE("fail closed: every joint's stiffness is checked in double, the last link's too",
          "[fail_closed]") {
  // g = 6e307 (N = 3) and a link of 6e307 ran for a minute and failed with four lines; the
  // last link's stiffness was never checked.
  const auto both = [](const Chain<double>& chain, double beta) {
    const std::string checked = rejection([&] { pendavg::check_average(chain, beta, {}); });
    const std::string run = rejection([&] { pendavg::average(chain, beta); });
    CHECK(checked == run);
    return checked;
  };
  CHECK_THAT(both(Chain<double>({1, 1, 1}, {1, 1, 1}, 6e307), 1.0),
             Catch::Contains("beyond double's range for the engines"));
  CHECK_THAT(both(Chain<double>({1, 1, 1}, {6e307, 1, 1}), 1.0),
             Catch::Contains("link 1"));
  CHECK_THAT(both(Chain<double>({1, 1, 1}, {1, 1, 6e307}), 1.0),
             Catch::Contains("link 3"));
  // transfer (N >= 5) forms alpha_j = beta g S_j l_j at the given beta
  CHECK_THAT(both(Chain<double>(std::vector<double>(6, 1.0), std::vector<double>(6, 1.0)),
                  7.7e306),
             Catch::Contains("stiffnesses beta g S_j l_j sum to"));
  // A single message line (the CLI prints it as its one error line).
  CHECK(both(Chain<double>({1, 1, 1}, {1, 1, 6e307}), 1.0).find('\n') == std::string::npos);
}

TEST_CASE("fail closed: MPFR joints' stiffness is formed in MPFR (beta = 1e400)", "[fail_closed]") {
  // beta = 1e400 was converted to double (inf), inf / inf gave NaN, and std::max(x, NaN) kept x:
  // the torus then ran unbounded.
  const pendavg::working_precision precision(20 + pendavg::guard_digits);
  const mpfr_real huge("1e400");
  const std::vector<mpfr_real> ones3(3, mpfr_real(1)), ones4(4, mpfr_real(1));
  CHECK_FALSE(rejection([&] {
                pendavg::check_average(Chain<mpfr_real>(ones3, ones3), huge, digits(20));
              }).empty());
  CHECK_FALSE(rejection([&] {
                pendavg::check_average(Chain<mpfr_real>(ones4, ones4), huge, digits(20));
              }).empty());
  CHECK_FALSE(rejection([&] {
                pendavg::check_average(Chain<mpfr_real>(ones3, ones3, huge), mpfr_real(1),
                                       digits(20));
              }).empty());
  CHECK_FALSE(rejection([&] {
                pendavg::check_average(
                    Chain<mpfr_real>(ones3, {mpfr_real(1), huge, mpfr_real(1)}), mpfr_real(1),
                    digits(20));
              }).empty());
}

TEST_CASE("fail closed: a link far stiffer than the softest joint is refused with digits that work",
          "[fail_closed]") {
  // l_3 = 1e24 made the double torus refine forever (l_3 = 1e20 converges in 0.2 s).
  const Chain<double> chain({1, 1, 1}, {1, 1, 1e24});
  const std::string message = rejection([&] { pendavg::check_average(chain, 1.0, {}); });
  CHECK_THAT(message, Catch::Contains("request 17 or more digits"));
  const Averages<mpfr_real> a = pendavg::average(chain.cast<mpfr_real>(), mpfr_real(1), digits(17));
  REQUIRE(all_finite(a));
  CHECK(a.converged);
  // The first link is the torus' reference and is not limited: l_1 = 1e24 runs in double.
  CHECK(rejection([&] { pendavg::check_average(Chain<double>({1, 1, 1}, {1e24, 1, 1}), 1.0, {}); })
            .empty());
}

TEST_CASE("fail closed: MPFR exponent overflow is named, without advice to request 17 digits",
          "[fail_closed]") {
  const pendavg::working_precision precision(30 + pendavg::guard_digits);
  const Chain<mpfr_real> chain({mpfr_real(1), mpfr_real(1)}, {mpfr_real(1), mpfr_real(1)});
  const std::string message =
      rejection([&] { pendavg::check_average(chain, mpfr_real("1e200000000"), digits(30)); });
  CHECK_THAT(message, Catch::Contains("MPFR's exponent range"));
  CHECK(message.find("request 17") == std::string::npos);
}

TEST_CASE("fail closed: simulate refuses scales whose trajectory leaves double's range",
          "[fail_closed][dynamics]") {
  // lengths 1e-300, 1: the momenta projection made NaN, the time-step check read the NaN
  // frequency as 0, and the run printed null averages with zero errors and exit 0.
  pendavg::SimulationOptions nve;
  nve.duration = 1;
  for (const auto& [masses, lengths] :
       {std::pair{std::vector<double>{1, 1}, std::vector<double>{1e-300, 1}},
        std::pair{std::vector<double>{1, 1, 1}, std::vector<double>{1, 1e-300, 1}},
        std::pair{std::vector<double>{1e-200, 1}, std::vector<double>{1, 1}},
        std::pair{std::vector<double>{1, 1}, std::vector<double>{1, 1e200}}}) {
    const Chain<double> chain(masses, lengths);
    const auto start = pendavg::state_from_angles(chain, std::vector<double>(masses.size(), 1.0),
                                                  std::vector<double>(masses.size(), 0.0));
    for (int variant = 0; variant < 3; ++variant) {
      pendavg::SimulationOptions o = nve;
      if (variant == 1) o.integrator = pendavg::Integrator::rattle2;
      if (variant == 2) {
        o.thermostat = pendavg::Thermostat::langevin;
        o.beta = 1.0;
      }
      CHECK_THAT(rejection([&] { pendavg::simulate(chain, start, o); }),
                 Catch::Contains("choose units nearer 1"));
    }
  }
}

TEST_CASE("fail closed: the result check refuses NaN, infinity and subnormal values",
          "[fail_closed]") {
  Averages<double> a;
  a.beta_kinetic = {{0.5, 1e-16, pendavg::ErrorKind::estimate}};
  a.cos_angle = {{0.5, 1e-16, pendavg::ErrorKind::estimate}};
  a.beta2_kinetic_variance = {{0.5, 1e-16, pendavg::ErrorKind::estimate}};
  CHECK(rejection([&] { pendavg::domain::check_result(a, "average"); }).empty());
  SECTION("NaN value") {
    a.beta2_kinetic_variance[0].value = std::nan("");
    CHECK_THAT(rejection([&] { pendavg::domain::check_result(a, "average"); }),
               Catch::Contains("non-finite beta^2 Var K_i"));
  }
  SECTION("infinite error") {
    a.cos_angle[0].error = std::numeric_limits<double>::infinity();
    CHECK_THAT(rejection([&] { pendavg::domain::check_result(a, "limit"); }),
               Catch::Contains("limit: "));
  }
  SECTION("subnormal value") {
    a.beta_kinetic[0].value = 1e-318;
    CHECK_THAT(rejection([&] { pendavg::domain::check_result(a, "limit", "; advice"); }),
               Catch::Contains("below double's normal range") && Catch::Contains("; advice"));
  }
  SECTION("a value within 2^53 of the subnormals, and a <cos phi_i> of 0 with gravity") {
    a.cos_angle[0].value = 1e-300;
    CHECK_THAT(rejection([&] { pendavg::domain::check_result(a, "average"); }),
               Catch::Contains("<cos phi_i> below double's normal range (2.2e-308), or within "
                               "2^53 of it"));
    a.cos_angle[0].value = 1e-290;
    CHECK(rejection([&] { pendavg::domain::check_result(a, "average"); }).empty());
    a.cos_angle[0] = {0, 0, pendavg::ErrorKind::estimate};
    CHECK(rejection([&] { pendavg::domain::check_result(a, "average"); }).empty());  // g = 0
    CHECK_THAT(rejection([&] { pendavg::domain::check_result(a, "average", "", true); }),
               Catch::Contains("<cos phi_i> below double's normal range"));
  }
  SECTION("NaN ratio") {
    a.ratio = Estimate<double>{std::nan(""), 0, pendavg::ErrorKind::estimate};
    CHECK_THAT(rejection([&] { pendavg::domain::check_result(a, "average"); }),
               Catch::Contains("<K1>/<K2>"));
  }
}

TEST_CASE("fail closed: N = 2 in double where <cos phi_2> passes through the subnormals",
          "[fail_closed]") {
  // a2 = 1e-306: <cos phi_2> = 5e-307 came out 3.6e-11 off with an error of 1e-14 of it; a2 =
  // 7.6e-293 (g = 5.14e-62): 0 +- 0 for 3.8e-293. Refused with advice that works.
  struct Input {
    std::vector<double> m, l;
    double g, beta;
  };
  for (const Input& in : {Input{{1, 1e-300}, {1e8, 1e8}, 1, 1e-14},
                          Input{{1, 1e-298}, {1, 1e8}, 1, 1e-12},
                          Input{{9.55e-36, 6.94e-268}, {1.27e4, 3.53e73}, 5.14e-62, 6.04e-38}}) {
    INFO("m2 = " << in.m[1] << ", l2 = " << in.l[1] << ", beta = " << in.beta);
    const std::string refusal = rejection([&] {
      (void)pendavg::average(Chain<double>(in.m, in.l, in.g), in.beta, digits(16));
    });
    CHECK_THAT(refusal, Catch::Contains("<cos phi_i> below double's normal range") &&
                            Catch::Contains(mpfr_advice));
    const pendavg::working_precision wp(20 + pendavg::guard_digits);
    const auto a = pendavg::average(
        Chain<mpfr_real>({mpfr_real(in.m[0]), mpfr_real(in.m[1])},
                         {mpfr_real(in.l[0]), mpfr_real(in.l[1])}, mpfr_real(in.g)),
        mpfr_real(in.beta), digits(20));
    CHECK(a.cos_angle[1].value > 0);
    CHECK(a.cos_angle[1].error < 1e-18 * a.cos_angle[1].value);
  }
}

TEST_CASE("fail closed: scales are logarithms, finite for every input of every number type",
          "[fail_closed]") {
  const pendavg::working_precision precision(30);
  const mpfr_real tiny("1e-5000"), huge("1e5000");
  CHECK(pendavg::domain::log2_magnitude(huge) == Approx(5000 * std::log2(10.0)).epsilon(1e-12));
  CHECK(pendavg::domain::log2_magnitude(tiny) == Approx(-5000 * std::log2(10.0)).epsilon(1e-12));
  CHECK(std::isnan(pendavg::domain::log2_magnitude(std::nan(""))));
  const Chain<mpfr_real> chain({mpfr_real(1), tiny}, {huge, mpfr_real(1)}, huge);
  const mpfr_real beta(1);
  const pendavg::domain::ChainScales s = pendavg::domain::chain_scales(chain, &beta);
  CHECK(std::isfinite(s.total_stiffness));
  CHECK(s.lightest_fraction == Approx(-5000 * std::log2(10.0)).epsilon(1e-12));
  // alpha_1 = beta g M l_1 ~ 1e10000 dominates the sum.
  CHECK(s.total_stiffness == Approx(10000 * std::log2(10.0)).epsilon(1e-9));
}

TEST_CASE("fail closed: NVE replicas are brought back to the run's energy shell",
          "[fail_closed][dynamics]") {
  const Chain<double> chain({1, 1, 1}, {1, 0.5, 2});
  const std::vector<double> rest{1.0, -0.5, 0.3}, moving{0.2, 0.1, -0.3};
  const std::vector<double> zero(3, 0.0), rates{0.5, -1.0, 0.25};
  for (const auto& [phi, phidot] : {std::pair{rest, zero}, std::pair{moving, rates}}) {
    const double energy = pendavg::total_energy(chain, pendavg::state_from_angles(chain, phi, phidot));
    std::vector<double> moved = phi;
    for (std::size_t j = 0; j < moved.size(); ++j) moved[j] += 1e-3 * (j % 2 ? 1 : -1);
    const auto s = pendavg::state_at_energy(chain, moved, phidot, energy);
    const double scale = 1 * 1 * 3.5 * 3;  // sum m g sum l, an upper bound of the well depth
    CHECK(std::abs(pendavg::total_energy(chain, s) - energy) <= 16 * 2.2e-16 * scale);
    CHECK(pendavg::constraint_residual(chain, s) <= 1e-14);
  }
  // Below the bottom of the well there is no state at all: refused, not a wrong energy.
  const std::vector<double> bottom(3, 0.0);
  const double lowest = pendavg::total_energy(chain, pendavg::state_from_angles(chain, bottom, zero));
  CHECK_THAT(rejection([&] {
               pendavg::state_at_energy(chain, std::vector<double>{1e-3, 0, 0}, zero, lowest - 1);
             }),
             Catch::Contains("no state at the energy"));
}

TEST_CASE("fail closed: microcanonical guards where double lost digits beyond its error",
          "[fail_closed][microcanonical]") {
  // N = 2 with m1/M = 1e-10: <K_1>_E was off by 3x its error (1e-20: 1e5x, 1e-40: 2%).
  CHECK_THAT(rejection([] {
               pendavg::microcanonical_average(Chain<double>({1e-10, 1}, {1, 1}), 0.0);
             }),
             Catch::Contains("below the double engine's accurate range (1e-8)"));
  // Near the edge, 2e-8, the error still covers a 30-digit run.
  const Chain<double> edge({2e-8, 1}, {1, 1});
  const auto a = pendavg::microcanonical_average(edge, 0.0);
  pendavg::MicrocanonicalOptions o30;
  o30.digits = 30;
  const pendavg::working_precision precision(30 + pendavg::guard_digits);
  const auto b = pendavg::microcanonical_average(edge.cast<mpfr_real>(), mpfr_real(0), o30);
  CHECK(std::abs(a.kinetic[0].value - static_cast<double>(b.kinetic[0].value)) <=
        a.kinetic[0].error);
  // Links 1e81 apart: the density of states was off by 5x its error.
  CHECK_THAT(rejection([] {
               pendavg::microcanonical_average(Chain<double>({1.12, 0.638}, {1.02, 2e81}, 0.412),
                                               -0.6101);
             }),
             Catch::Contains("more than 1e30 times the shortest"));
  // Var K_i ~ D^2 = 1e-600 underflowed to 0 +- 0 at the excitation 1e-300.
  CHECK_THAT(rejection([] {
               pendavg::microcanonical_average_excitation(Chain<double>({1, 1}, {1, 1}), 1e-300);
             }),
             Catch::Contains("underflows double"));
}

TEST_CASE("fail closed: a tolerance finer than double resolves is refused", "[fail_closed]") {
  // torus-gauss refined for minutes at --tol 1e-300 (its levels do not nest)
  AverageOptions o;
  o.method = pendavg::AverageMethod::torus_gauss;
  o.tolerance = 1e-300;
  CHECK_THAT(rejection([&] { pendavg::check_average(Chain<double>({1, 1, 1}, {1, 1, 1}), 1.0, o); }),
             Catch::Contains("tol must be in [1e-15, 1)"));
  o.tolerance = 1e-15;
  CHECK(rejection([&] { pendavg::check_average(Chain<double>({1, 1, 1}, {1, 1, 1}), 1.0, o); })
            .empty());
}

TEST_CASE("fail closed: transfer refuses two adjacent light particles it cannot resolve",
          "[fail_closed][transfer]") {
  // Four unit masses before a tail of 1e10 (every m_i / S_(i+1) = 1e-10) ran unbounded; one light
  // particle anywhere converges in seconds (tests/engine/transfer/test_transfer.cpp).
  CHECK_THAT(rejection([] {
               pendavg::check_average(Chain<double>({1, 1, 1, 1, 1e10}, std::vector<double>(5, 1.0)),
                                      1.0, {});
             }),
             Catch::Contains("not two adjacent ones"));
  CHECK_THAT(rejection([] {
               pendavg::check_average(
                   Chain<double>({1, 1e-8, 1e-8, 1, 1}, std::vector<double>(5, 1.0)), 1.0, {});
             }),
             Catch::Contains("not two adjacent ones"));
  CHECK(rejection([] {
          pendavg::check_average(Chain<double>({1, 1e-8, 1, 1, 1}, std::vector<double>(5, 1.0)),
                                 1.0, {});
        }).empty());
}

TEST_CASE("fail closed: transfer refuses a stiff first link far softer than the second",
          "[fail_closed][transfer]") {
  // g = 5e196, l_1 = 1e-164 (alpha_1 = 1e34, alpha_2 = 1e198) printed non-finite values after
  // 5 s; the same at l_1 = 1e-10, g = 1e20 after 0.1 s.
  const std::vector<double> masses{0.442, 2.43, 0.817, 2.65, 0.678, 1.23, 1.1, 0.536};
  const auto lengths = [](double first) {
    return std::vector<double>{first, 0.411, 1.22, 0.742, 0.517, 0.433, 1.57, 1.72};
  };
  CHECK_THAT(rejection([&] {
               pendavg::check_average(Chain<double>(masses, lengths(9.99e-165), 5e196), 2.052, {});
             }),
             Catch::Contains("link 1's stiffness"));
  CHECK_THAT(rejection([&] {
               pendavg::check_average(Chain<double>(masses, lengths(1e-10), 1e20), 2.052, {});
             }),
             Catch::Contains("link 1's stiffness"));
  // a free first link (alpha_1 << 1), and a short one of comparable stiffness, are taken
  const std::vector<double> both_short{1e-9, 1e-9, 1.22, 0.742, 0.517, 0.433, 1.57, 1.72};
  for (const Chain<double>& chain : {Chain<double>(masses, lengths(1e-60), 1e50),
                                     Chain<double>(masses, both_short, 1e13)}) {
    CHECK(rejection([&] { pendavg::check_average(chain, 2.052, {}); }).empty());
    CHECK(all_finite(pendavg::average(chain, 2.052, {})));
  }
}

TEST_CASE("fail closed: the MPFR torus without gravity refuses a particle it cannot resolve",
          "[fail_closed]") {
  // masses 1, 1e20, 1 at g = 0 and 17 digits ran for minutes (the double torus: seconds); the
  // beta -> 0 limit of N >= 3 is that torus.
  const pendavg::working_precision precision(17 + pendavg::guard_digits);
  const Chain<mpfr_real> chain({mpfr_real(1), mpfr_real("1e20"), mpfr_real(1)},
                               std::vector<mpfr_real>(3, mpfr_real(1)), mpfr_real(0));
  CHECK_THAT(rejection([&] { pendavg::check_average(chain, mpfr_real(1), digits(17)); }),
             Catch::Contains("at 16 digits it does"));
  CHECK_THAT(rejection([&] { pendavg::high_temperature_limit(chain, digits(17)); }),
             Catch::Contains("without gravity"));
  // the beta -> infinity limit is a closed form and takes it
  CHECK(all_finite(pendavg::low_temperature_limit(chain, digits(17))));
}

namespace {

/// |a - b| within both errors (and a few ulps) for every beta<K_i>, <cos phi_i> and Var K_i.
void check_within_errors(const Averages<double>& a, const Averages<double>& b) {
  const auto close = [](const Estimate<double>& x, const Estimate<double>& y) {
    return std::abs(x.value - y.value) <=
           x.error + y.error + 4 * std::numeric_limits<double>::epsilon() * std::abs(y.value);
  };
  REQUIRE(a.beta_kinetic.size() == b.beta_kinetic.size());
  for (std::size_t i = 0; i < a.beta_kinetic.size(); ++i) {
    INFO("particle " << i + 1);
    CHECK(close(a.beta_kinetic[i], b.beta_kinetic[i]));
    CHECK(close(a.cos_angle[i], b.cos_angle[i]));
    CHECK(close(a.beta2_kinetic_variance[i], b.beta2_kinetic_variance[i]));
  }
}

}  // namespace

TEST_CASE("fail closed: a soft link between stiff joints is not extrapolated to low temperature",
          "[fail_closed]") {
  // Lengths 1, 1e-9, 1e3 at beta = 1e7: every joint's kappa is ~3e7, but link 2's own alpha is
  // 0.02 (it turns freely between the stiff links). The extrapolation from the joints printed
  // beta<K_1> = 0.49991 +- 1e-5 and <cos phi_2> = 0.9995 +- 7e-5 for 0.3151 and 0.0084. qmc
  // (cheap here) and the transfer operator must now agree within their errors.
  const Chain<double> chain({1, 1, 1}, {1, 1e-9, 1e3});
  AverageOptions qmc, transfer;
  qmc.method = pendavg::AverageMethod::qmc;
  transfer.method = pendavg::AverageMethod::transfer;
  const Averages<double> sampled = pendavg::average(chain, 1e7, qmc);
  const Averages<double> exact = pendavg::average(chain, 1e7, transfer);
  CHECK(sampled.method == pendavg::Method::qmc);
  CHECK(exact.cos_angle[1].value < 0.01);  // the soft link is free
  check_within_errors(sampled, exact);
}

TEST_CASE("fail closed: the torus' work cap ends its refinement with errors that still hold",
          "[fail_closed][torus]") {
  // A light middle particle (1e-6 of its tail) needs ~5e5 nodes in double, 1e-100 more than any
  // budget (MPFR at 17 digits ran for hours before the cap). Capped at 2e4 evaluations, the run
  // stops with converged = false, and its errors cover the converged values.
  const Chain<double> chain({1.27, 1e-6, 0.986}, {0.835, 2.26, 0.88}, 1.58);
  pendavg::TorusOptions capped;
  capped.max_evaluations = 2e4;
  const Averages<double> early = pendavg::torus_average(chain, 2.02, capped);
  const Averages<double> full = pendavg::torus_average(chain, 2.02);
  CHECK_FALSE(early.converged);
  CHECK(early.evaluations <= 20000);
  REQUIRE(full.converged);
  CHECK(full.evaluations > 100000);
  check_within_errors(early, full);
}

TEST_CASE("fail closed: the transfer operator's work cap ends its refinement with verified errors",
          "[fail_closed][transfer]") {
  // Links alternating between 1e-118 and 1e118 (N = 8) refined for over a minute; average() now
  // caps the work at 4e6 kernel evaluations per particle. Capped far below what this ordinary
  // chain needs, the run stops after its verified level: converged = false, errors that cover.
  const Chain<double> chain(std::vector<double>(8, 1.0), std::vector<double>(8, 1.0));
  pendavg::TransferOptions tight, capped;
  tight.tolerance = capped.tolerance = 1e-12;
  capped.max_kernel_evaluations = 3e5;
  const Averages<double> early = pendavg::chain_transfer_average(chain, 1.0, capped);
  const Averages<double> full = pendavg::chain_transfer_average(chain, 1.0, tight);
  CHECK_FALSE(early.converged);
  CHECK(early.evaluations < full.evaluations / 4);
  REQUIRE(full.converged);
  check_within_errors(early, full);
}
