// SPDX-License-Identifier: GPL-3.0-or-later
// The CLI's fast scientific notation (src/io/decimal_fast.hpp) against std::to_chars: the same
// characters for every value it accepts (ties to even, powers of ten, rounding up to the next
// power), and it accepts the values the CLI prints most (beta<K_i> ~ 1e-13..1, errors ~1e-17).
#include <catch2/catch.hpp>

#include "io/decimal_fast.hpp"
#include "io/number_text.hpp"

#include "pendavg/mpfr.hpp"

#include <bit>
#include <charconv>
#include <cmath>
#include <cstdint>
#include <random>
#include <string>

namespace {

struct Counts {
  long checked = 0, fast = 0, mismatches = 0;
};

/// Compares one value; returns true when the fast path took it.
bool compare(double x, int digits, Counts& counts) {
  char fast[64], reference[64];
  const char* fast_end = pendavg::io::detail::scientific_fast(fast, x, digits);
  const char* reference_end =
      std::to_chars(reference, reference + sizeof reference, x, std::chars_format::scientific,
                    digits - 1)
          .ptr;
  ++counts.checked;
  if (!fast_end) return false;
  ++counts.fast;
  const std::string a(static_cast<const char*>(fast), fast_end);
  const std::string b(static_cast<const char*>(reference), reference_end);
  if (a != b) {
    ++counts.mismatches;
    if (counts.mismatches <= 5) {
      INFO("x = " << b << " (" << std::bit_cast<std::uint64_t>(x) << "), digits " << digits
                  << ": fast " << a);
      CHECK(a == b);
    }
  }
  return true;
}

}  // namespace

TEST_CASE("fast scientific notation matches std::to_chars", "[cli][format]") {
  std::mt19937_64 rng(20261122);
  Counts counts;
  // Random bit patterns: every exponent, every digit count (most outside the fast range).
  for (int i = 0; i < 300000; ++i) {
    const double x = std::bit_cast<double>(rng());
    if (std::isfinite(x)) compare(x, 1 + static_cast<int>(rng() % 17), counts);
  }
  // Values of the CLI's magnitudes, at its digit counts (16 for values, 3 for errors).
  std::uniform_real_distribution<double> unit(-1.0, 1.0);
  for (int i = 0; i < 300000; ++i) {
    const double x = unit(rng) * std::pow(10.0, static_cast<int>(rng() % 40) - 30);
    compare(x, 16, counts);
    compare(x, 3, counts);
  }
  // Short decimals: exact ties at many digit counts (e.g. 0.125 to 2 digits: ties to even).
  for (int i = 0; i < 40000; ++i) {
    const double x = static_cast<double>(rng() % 100000000) / std::pow(10.0, static_cast<int>(rng() % 12));
    for (int digits = 1; digits <= 17; ++digits) compare((i % 2) ? x : -x, digits, counts);
  }
  // Powers of ten and two, their neighbours, and values that round up to a power of ten.
  for (int n = -40; n <= 20; ++n) {
    const double p = std::pow(10.0, n);
    for (const double x : {p, std::nextafter(p, 0.0), std::nextafter(p, 1e300),
                           0.99999999999999999 * p, 9.9999999999999995 * p, 9.5 * p, 0.5 * p}) {
      for (int digits = 1; digits <= 17; ++digits) compare(x, digits, counts);
    }
  }
  for (int n = -120; n <= 60; ++n) {
    for (int digits = 1; digits <= 17; ++digits) compare(std::ldexp(1.0, n), digits, counts);
  }
  CHECK(counts.mismatches == 0);
  // The fast path is taken for the bulk of the values (not only a fallback).
  CHECK(counts.fast > counts.checked / 2);
  // ...and for the CLI's typical values: 16 digits down to ~1e-12, errors with 3 digits.
  for (const double x : {0.3431834814709, 0.6568165185290, -0.98765, 1.5e-12, 7.25}) {
    char buffer[64];
    CHECK(pendavg::io::detail::scientific_fast(buffer, x, 16) != nullptr);
  }
  for (const double x : {1.2e-16, 3.4e-13, 2.2e-17, 0.5}) {
    char buffer[64];
    CHECK(pendavg::io::detail::scientific_fast(buffer, x, 3) != nullptr);
  }
  // Outside the fast range it declines (the caller falls back to std::to_chars).
  char buffer[64];
  CHECK(pendavg::io::detail::scientific_fast(buffer, 0.0, 16) == nullptr);
  CHECK(pendavg::io::detail::scientific_fast(buffer, 1e300, 16) == nullptr);
  CHECK(pendavg::io::detail::scientific_fast(buffer, 4.9e-324, 16) == nullptr);
  CHECK(pendavg::io::detail::scientific_fast(buffer, std::nan(""), 16) == nullptr);
}

TEST_CASE("errors are printed rounded up: never below the error, at most one unit above",
          "[io][format]") {
  // io::write_error (the fast path's `upward` mode, and std::to_chars with a correction where
  // it does not apply: zero, subnormals, MPFR) against exact decimal arithmetic in MPFR.
  std::mt19937_64 rng(20261128);
  long checked = 0;
  const auto check = [&](double e) {
    char text[64];
    const char* end = pendavg::io::write_error(text, e);
    const std::string printed(static_cast<const char*>(text), end);
    // the printed decimal, exactly (MPFR at 400 bits holds a 3-digit decimal times 10^-330 to
    // far below its last unit) against e
    pendavg::mpfr_real shown, value(e), unit;
    {
      const pendavg::working_precision precision(120);
      shown = pendavg::mpfr_real(printed);
      value = pendavg::mpfr_real(e);
      const std::size_t ep = printed.find('e');
      unit = pow(pendavg::mpfr_real(10), std::stoi(printed.substr(ep + 1)) - 2);
      INFO("e = " << e << " printed " << printed);
      REQUIRE(shown >= value);
      REQUIRE(shown - unit < value + unit * pendavg::mpfr_real("1e-20"));
      REQUIRE(printed.size() <= pendavg::io::decimal_max_length(pendavg::io::error_digits));
    }
    ++checked;
  };
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  for (int i = 0; i < 20000; ++i)
    check(unit(rng) * std::pow(10.0, static_cast<int>(rng() % 60) - 40));
  for (int i = 0; i < 5000; ++i) {  // any positive double, subnormals included
    const double x = std::fabs(std::bit_cast<double>(rng()));
    if (std::isfinite(x)) check(x);
  }
  // exactly representable 3-digit values stay themselves; 9.99.. carries to the next power
  for (const double x : {0.0, 1.0, 0.5, 0.125, 1e-300, 9.995e-7, 9.999999e22, 4.9e-324, 1.04e-15})
    check(x);
  char text[64];
  CHECK(std::string(text, pendavg::io::write_error(text, 0.125)) == "1.25e-01");
  CHECK(std::string(text, pendavg::io::write_error(text, 9.9951)) == "1.00e+01");
  CHECK(std::string(text, pendavg::io::write_error(text, 0.0)) == "0.00e+00");
  CHECK(checked > 25000);
}

TEST_CASE("a double's printed text lies within its printing gap, which is 0 only when exact",
          "[io][format]") {
  // io::printing_gap against MPFR: |text - x| <= gap for write_shortest's text, and gap == 0
  // exactly when the text is x's exact decimal value (0.5 is; 0.1 is not).
  std::mt19937_64 rng(20261129);
  const pendavg::working_precision precision(4000);  // holds any double's decimal exactly
  long exact = 0, checked = 0;
  const auto check = [&](double x) {
    char text[40];
    const char* end = pendavg::io::write_shortest(text, x);
    const std::string_view written(text, static_cast<std::size_t>(end - text));
    const double gap = pendavg::io::printing_gap(x, written);
    const pendavg::mpfr_real shown{std::string(written)}, value(x);
    const pendavg::mpfr_real distance = abs(shown - value);
    INFO("x = " << written << " gap " << gap);
    REQUIRE(distance <= pendavg::mpfr_real(gap));
    REQUIRE((gap == 0) == (distance == 0));
    exact += gap == 0;
    ++checked;
  };
  for (int i = 0; i < 20000; ++i) {
    const double x = std::bit_cast<double>(rng());
    if (std::isfinite(x)) check(x);
  }
  std::uniform_real_distribution<double> unit(-1.0, 1.0);
  for (int i = 0; i < 20000; ++i) check(unit(rng));
  // exact decimals: dyadic values with short expansions, integers, and their neighbours
  for (const double x : {0.5, -0.5, 0.25, 0.125, 3.0, 1.5, 0.75, 1024.0, 1e22, 0.1, 1.0 / 3,
                         9007199254740992.0, 4.9e-324, 0.8749999999999999, 6.103515625e-05})
    check(x);
  for (int i = 0; i < 5000; ++i) {
    const double x = std::ldexp(static_cast<double>(rng() % 100000), -static_cast<int>(rng() % 40));
    check(x);
    check(std::nextafter(x, 2.0));
  }
  CHECK(exact > 1000);  // the dyadic values with short expansions (2,660 of the 10,000 here)
  CHECK(checked > 50000);
  CHECK(pendavg::io::printing_gap(0.5, "0.5") == 0);
  CHECK(pendavg::io::printing_gap(0.1, "0.1") > 0);
}
