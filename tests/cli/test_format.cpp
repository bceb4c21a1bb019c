// SPDX-License-Identifier: GPL-3.0-or-later
// The CLI's printed errors (src/cli/format.cpp, printed_error): the error printed beside a value
// printed with `digits` digits adds half a unit in the value's last printed place, so it covers
// the printing's rounding. Checked exactly: the printed text read in MPFR at 400 digits.
#include <catch2/catch.hpp>

#include "cli/format.hpp"

#include "pendavg/mpfr.hpp"

#include <cmath>
#include <limits>
#include <cstdint>
#include <string>
#include <vector>

namespace {

/// |decimal(x, digits) - x|, exactly enough (400 digits).
pendavg::mpfr_real printing_rounding(double x, int digits) {
  const std::string text = pendavg::cli::decimal(x, digits);
  const pendavg::working_precision precision(400);
  pendavg::mpfr_real printed;
  mpfr_set_str(printed.backend().data(), text.c_str(), 10, MPFR_RNDN);
  return abs(printed - pendavg::mpfr_real(x));
}

}  // namespace

// Found by tests/fuzz/fuzz_number: below 1e-292 the half unit 10^(e - digits + 1) / 2 is
// subnormal in double (a few significant bits) and below 1e-324 it was 0, so a value such as
// 4.9406564584124654e-324 printed with 17 digits had a printed error of 0.
TEST_CASE("printed errors cover the printing of tiny values (subnormal half units)",
          "[cli][format]") {
  const double smallest = std::numeric_limits<double>::denorm_min();
  for (const double x : {smallest, 7 * smallest, 3.0e-320, 1.2345678901234567e-310,
                         std::numeric_limits<double>::min(), 4.4501477170144023e-308,
                         1.0000000000000002e-300, 3.3e-295, 0.1, -123.456}) {
    for (const int digits : {1, 3, 16, 17}) {
      INFO("x = " << pendavg::cli::decimal(x, 17) << ", " << digits << " digits");
      const double covered = pendavg::cli::printed_error(x, 0.0, digits);
      CHECK(covered > 0);
      CHECK(printing_rounding(x, digits) <= pendavg::mpfr_real(covered));
      // A computed error adds to it: still covered, and never less than the error itself.
      const double error = 1e-3 * std::abs(x);
      CHECK(pendavg::cli::printed_error(x, error, digits) >= error);
      CHECK(printing_rounding(x, digits) <=
            pendavg::mpfr_real(pendavg::cli::printed_error(x, error, digits)));
    }
  }
}

// printed_error takes the value's decimal exponent from its binary exponent and one comparison
// with a power of ten, and asks std::log10 only within 1e-12 of a power of ten: the result must be
// the one floor(log10 |x|) gives, bit for bit, everywhere (powers of ten and their neighbours
// included, where log10 may round onto the integer).
TEST_CASE("printed errors: the decimal exponent without log10 agrees with floor(log10)",
          "[cli][format]") {
  const auto reference = [](double x, double error, int digits) {
    const double exponent = std::floor(std::log10(std::abs(x))) - (digits - 1);
    return error + std::pow(10.0, exponent) / 2;
  };
  std::vector<double> values;
  for (int k = -290; k <= 308; ++k) {
    const double ten = std::pow(10.0, k);
    double up = ten, down = ten;
    for (int step = 0; step < 4; ++step) {
      values.push_back(up);
      values.push_back(down);
      up = std::nextafter(up, HUGE_VAL);
      down = std::nextafter(down, 0.0);
    }
    for (const double r : {1e-13, 1e-12, 2e-12, 1e-11, 0.3, 0.5, 0.99})
      for (const double x : {ten * (1 + r), ten * (1 - r), ten * 9.999999999999, ten * 3.1622776})
        values.push_back(x);
  }
  std::uint64_t state = 2026;  // splitmix64: finite doubles of every binary exponent
  for (int i = 0; i < 200000; ++i) {
    std::uint64_t z = (state += 0x9e3779b97f4a7c15ull);
    z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ull;
    z = (z ^ (z >> 27)) * 0x94d049bb133111ebull;
    z ^= z >> 31;
    const double x = std::ldexp(1.0 + static_cast<double>(z >> 12) * 0x1.0p-52,
                                static_cast<int>(z % 1990) - 960);
    values.push_back(x);
  }
  std::size_t checked = 0, mismatches = 0;
  for (const double x : values) {
    if (!(std::abs(x) >= 1e-290) || !std::isfinite(x)) continue;
    for (const int digits : {3, 16}) {
      for (const double sign : {1.0, -1.0}) {
        const double got = pendavg::cli::printed_error(sign * x, 1e-300, digits);
        const double want = reference(sign * x, 1e-300, digits);
        ++checked;
        if (got != want) {
          if (++mismatches <= 5) FAIL_CHECK("x = " << pendavg::cli::decimal(x, 17) << ", digits " << digits);
        }
      }
    }
  }
  CHECK(checked > 800000);
  CHECK(mismatches == 0);
}
