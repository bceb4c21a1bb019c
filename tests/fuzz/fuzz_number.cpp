// SPDX-License-Identifier: GPL-3.0-or-later
// tests/fuzz/fuzz_number.cpp -- libFuzzer target: the CLI's numbers, read and printed. The input
// is two control bytes (the printed digits 1..17; the MPFR digits 17..1000) and a token.
//
// Differential checks, each against an independent reference:
// - parse_real<double> accepts exactly the decimal grammar [+-]digits[.digits][(e|E)[+-]digits]
//   within double's range, and gives strtod's bits; its domains agree with the value;
// - parse_real<mpfr_real> accepts every token the double parser accepts, and the two values
//   agree to double precision;
// - write_decimal (the fast path of decimal.hpp, then std::to_chars) gives std::to_chars's
//   characters for a double, the MPFR printer the same characters for the same value, 17 digits
//   read back give the same bits, and printed_error covers the rounding of the printed value
//   (checked exactly in MPFR);
// - one_minus_decimal(x) + x == 1 exactly (in MPFR at 4100+ digits) for any positive decimal x,
//   and it refuses x >= 1;
// - parse_integer and parse_unsigned agree with strtoull on digit strings;
// - parse_real_list splits at every comma.
// The same for the first 8 bytes of the token taken as a double's bits (every double, subnormals
// and the largest included).
#include "fuzz_common.hpp"

#include "cli/args.hpp"
#include "cli/format.hpp"
#include "io/exact_decimal.hpp"

#include "pendavg/mpfr.hpp"

#include <bit>
#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <limits>
#include <optional>
#include <string>
#include <string_view>

namespace {

using pendavg::mpfr_real;
using pendavg::fuzz::fail;
using pendavg::cli::Domain;
using pendavg::cli::usage_error;

bool is_digit(char c) { return c >= '0' && c <= '9'; }

/// The grammar the CLI documents for a number, written out separately from args.cpp.
bool decimal_grammar(std::string_view s) {
  std::size_t i = 0, mantissa = 0, exponent = 0;
  const std::size_t n = s.size();
  if (i < n && (s[i] == '+' || s[i] == '-')) ++i;
  for (; i < n && is_digit(s[i]); ++i) ++mantissa;
  if (i < n && s[i] == '.')
    for (++i; i < n && is_digit(s[i]); ++i) ++mantissa;
  if (mantissa == 0) return false;
  if (i == n) return true;
  if (s[i] != 'e' && s[i] != 'E') return false;
  ++i;
  if (i < n && (s[i] == '+' || s[i] == '-')) ++i;
  for (; i < n && is_digit(s[i]); ++i) ++exponent;
  return exponent > 0 && i == n;
}

template <class Real>
std::optional<Real> try_parse(std::string_view text, Domain domain, std::string_view input) {
  try {
    return pendavg::cli::parse_real<Real>(text, "--x", domain);
  } catch (const usage_error& refused) {
    pendavg::fuzz::check_message(refused.what(), input);
    return std::nullopt;
  }
}

std::string to_chars_text(double x, int digits) {
  char buffer[64];
  const auto end = std::to_chars(buffer, buffer + sizeof buffer, x, std::chars_format::scientific,
                                 digits - 1).ptr;
  return std::string(buffer, end);
}

std::string double_text(double x) { return to_chars_text(x, 17); }

/// The printers on one finite double, at `digits` significant digits.
void check_printing(double x, int digits, std::string_view input) {
  const std::string text = pendavg::cli::decimal(x, digits);
  if (text != to_chars_text(x, digits))
    fail("write_decimal(" + double_text(x) + ", " + std::to_string(digits) + ") gives " + text +
             ", std::to_chars " + to_chars_text(x, digits),
         input);
  const mpfr_real exact(x);  // at the working precision (>= 53 bits): exact
  const std::string mpfr_text = pendavg::cli::decimal(exact, digits);
  if (mpfr_text != text)
    fail("the MPFR printer gives " + mpfr_text + ", the double printer " + text + " for " +
             double_text(x) + " at " + std::to_string(digits) + " digits",
         input);
  // 17 digits name a double exactly (a subnormal is refused: out of double's range).
  const std::string full = pendavg::cli::decimal(x, 17);
  if (const auto back = try_parse<double>(full, Domain::any, input)) {
    if (std::bit_cast<std::uint64_t>(*back) != std::bit_cast<std::uint64_t>(x))
      fail(full + " reads back as " + double_text(*back), input);
  } else if (std::fpclassify(x) == FP_NORMAL || x == 0) {
    fail(full + " (printed from a normal double) is refused when read back", input);
  }
  // The printed error of a value printed with `digits` digits covers the printing's rounding:
  // |text - x| <= printed_error(x, 0, digits), compared exactly (the text at 300 digits).
  const double half_unit = pendavg::cli::printed_error(x, 0.0, digits);
  if (!(half_unit >= 0) || !std::isfinite(half_unit))
    fail("printed_error(" + double_text(x) + ", 0, " + std::to_string(digits) + ") = " +
             double_text(half_unit),
         input);
  const pendavg::working_precision wide(300);
  mpfr_real printed;
  mpfr_set_str(printed.backend().data(), text.c_str(), 10, MPFR_RNDN);
  const mpfr_real rounding = abs(printed - mpfr_real(x));
  // Slack of 2^-50 relative: 10^k/2 computed in double may fall an ulp short of an exact tie.
  if (rounding > mpfr_real(half_unit) * (1 + std::ldexp(1.0, -50)))
    fail("printed_error(" + double_text(x) + ", 0, " + std::to_string(digits) + ") = " +
             double_text(half_unit) + " does not cover the printed " + text + " (off by " +
             pendavg::cli::decimal(rounding, 5) + ")",
         input);
}

/// one_minus_decimal on an accepted positive decimal: exact, or refused for x >= 1.
void check_one_minus(std::string_view text, std::string_view input) {
  std::string result;
  std::string refusal;
  try {
    result = pendavg::io::one_minus_decimal(text, "--mu1");
  } catch (const std::invalid_argument& refused) {
    pendavg::fuzz::check_message(refused.what(), input);
    refusal = refused.what();
  }
  // x and 1 - x have at most 4000 decimals (one_minus_decimal's limit) and the token's digits.
  const pendavg::working_precision exact(static_cast<int>(4100 + 2 * text.size()));
  mpfr_real x;
  mpfr_set_str(x.backend().data(), std::string(text).c_str(), 10, MPFR_RNDN);
  if (!refusal.empty()) {
    if (refusal.find("must be < 1") != std::string::npos && x < 1)
      fail("one_minus_decimal refuses " + std::string(text) + " as >= 1", input);
    if (refusal.find("too many digits") == std::string::npos &&
        refusal.find("must be < 1") == std::string::npos)
      fail("one_minus_decimal refuses " + std::string(text) + ": " + refusal, input);
    return;
  }
  if (!(x < 1)) fail("one_minus_decimal accepts " + std::string(text) + " >= 1", input);
  if (!result.starts_with("0.") || result.size() < 3 || result.back() == '0' ||
      result.find_first_not_of("0123456789", 2) != std::string::npos)
    fail("one_minus_decimal(" + std::string(text) + ") = '" + result + "' is not 0.d..d", input);
  mpfr_real y;
  mpfr_set_str(y.backend().data(), result.c_str(), 10, MPFR_RNDN);
  const mpfr_real tolerance = pow(mpfr_real(2), -static_cast<long>(3.3 * 4000));
  if (abs(x + y - 1) > tolerance)
    fail("one_minus_decimal(" + std::string(text) + ") = " + result + " is not 1 - x", input);
}

/// parse_unsigned and parse_integer against strtoull on a string of digits.
void check_integers(std::string_view text, std::string_view input) {
  const bool digits_only =
      !text.empty() && std::ranges::all_of(text, [](char c) { return is_digit(c); });
  std::optional<unsigned long long> reference;
  if (digits_only) {
    errno = 0;
    const unsigned long long value = std::strtoull(std::string(text).c_str(), nullptr, 10);
    if (errno == 0) reference = value;
  }
  std::optional<std::uint64_t> unsigned_value;
  try {
    unsigned_value = pendavg::cli::parse_unsigned(text, "--seed");
  } catch (const usage_error& refused) {
    pendavg::fuzz::check_message(refused.what(), input);
  }
  if (unsigned_value != reference)
    fail("parse_unsigned(" + std::string(text) + ") disagrees with strtoull", input);
  std::optional<long> integer_value;
  try {
    integer_value = pendavg::cli::parse_integer(text, "--points", 1, 1000000);
  } catch (const usage_error& refused) {
    pendavg::fuzz::check_message(refused.what(), input);
  }
  const bool in_range = reference && *reference >= 1 && *reference <= 1000000;
  if (integer_value.has_value() != in_range ||
      (integer_value && static_cast<unsigned long long>(*integer_value) != *reference))
    fail("parse_integer(" + std::string(text) + ", 1, 1000000) disagrees with strtoull", input);
}

void check_list(std::string_view text, std::string_view input) {
  try {
    const auto values = pendavg::cli::parse_real_list<double>(text, "--masses", Domain::any);
    if (values.size() != static_cast<std::size_t>(std::ranges::count(text, ',')) + 1)
      fail("parse_real_list found " + std::to_string(values.size()) + " values", input);
    std::size_t k = 0;
    for (const std::string& element : pendavg::fuzz::split(text, ','))
      if (std::bit_cast<std::uint64_t>(values[k++]) !=
          std::bit_cast<std::uint64_t>(pendavg::cli::parse_real<double>(element, "x", Domain::any)))
        fail("parse_real_list's element " + element + " differs from parse_real's", input);
  } catch (const usage_error& refused) {
    pendavg::fuzz::check_message(refused.what(), input);
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size < 2) return -1;
  const int digits = 1 + data[0] % 17;
  const int mpfr_digits = 17 + (data[1] * 983) / 255;  // 17..1000
  const std::string_view input(reinterpret_cast<const char*>(data), size);
  const std::string_view text = input.substr(2);

  // ---- double: the grammar, strtod, the domains
  const bool grammar = decimal_grammar(text);
  const std::optional<double> value = try_parse<double>(text, Domain::any, input);
  if (value && !grammar) fail("parse_real<double> accepts a token outside the grammar", input);
  if (grammar) {
    errno = 0;
    const double reference = std::strtod(std::string(text).c_str(), nullptr);
    const bool out_of_range = errno == ERANGE;
    if (value && std::bit_cast<std::uint64_t>(*value) != std::bit_cast<std::uint64_t>(reference))
      fail("parse_real<double> gives " + double_text(*value) + ", strtod " +
               double_text(reference),
           input);
    if (!value && !out_of_range)
      fail("parse_real<double> refuses a number in range (strtod: " + double_text(reference) +
               ")",
           input);
  }
  const bool positive = try_parse<double>(text, Domain::positive, input).has_value();
  const bool nonnegative = try_parse<double>(text, Domain::nonnegative, input).has_value();
  if (positive != (value && *value > 0) || nonnegative != (value && !(*value < 0)))
    fail("parse_real<double>'s domains disagree with its value", input);

  // ---- MPFR at the requested digits: accepts what double accepts, the same value
  {
    const pendavg::working_precision precision(mpfr_digits + pendavg::guard_digits);
    const std::optional<mpfr_real> wide = try_parse<mpfr_real>(text, Domain::any, input);
    if (wide && !grammar) fail("parse_real<mpfr_real> accepts a token outside the grammar", input);
    if (value && !wide) fail("parse_real<mpfr_real> refuses a token double accepts", input);
    if (value && wide) {
      const double rounded = wide->convert_to<double>();
      if (rounded != *value && std::nextafter(*value, rounded) != rounded)
        fail("parse_real<mpfr_real> gives " + double_text(rounded) + ", double " +
                 double_text(*value),
             input);
    }
  }

  // ---- printing, and 1 - x
  {
    const pendavg::working_precision precision(40);
    if (value) check_printing(*value, digits, input);
    if (text.size() >= 8) {
      double bits = 0;
      std::memcpy(&bits, text.data(), sizeof bits);
      if (std::isfinite(bits)) check_printing(bits, digits, input);
    }
  }
  // one_minus_decimal takes any positive decimal (table passes the --mu1 values double accepts).
  if (grammar && text.front() != '-' &&
      text.substr(0, text.find_first_of("eE")).find_first_of("123456789") != std::string_view::npos)
    check_one_minus(text, input);

  // ---- integers and lists
  check_integers(text, input);
  if (text.size() <= 512) check_list(text, input);
  return 0;
}
