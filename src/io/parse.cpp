// SPDX-License-Identifier: GPL-3.0-or-later
// src/io/parse.cpp -- strict decimal numbers, integers and choices.
#include "io/parse.hpp"

#include "engine/numerics/precision.hpp"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <system_error>

namespace pendavg::io {

namespace {
bool digits_advice_on = true;              // set_digits_advice
std::string_view digits_option = "--digits";  // set_digits_option_name
}  // namespace

void set_digits_advice(bool command_takes_digits) { digits_advice_on = command_takes_digits; }
bool command_takes_digits() { return digits_advice_on; }
void set_digits_option_name(std::string_view name) { digits_option = name; }
std::string digits_advice() {
  if (!digits_advice_on) return {};
  return " (use " + std::string(digits_option) + " > 16)";
}

std::string in_quotes(std::string_view text) {
  std::string quoted;  // appended piecewise: "'" + std::string(text) trips GCC 12's -Wrestrict
  quoted.reserve(text.size() + 2);
  quoted += '\'';
  quoted += text;
  quoted += '\'';
  return quoted;
}

namespace {

/// Length of the leading run of decimal digits of `text`.
std::size_t digit_run(std::string_view text) {
  return static_cast<std::size_t>(std::find_if(text.begin(), text.end(), [](char c) {
                                    return c < '0' || c > '9';
                                  }) -
                                  text.begin());
}

/// True for [+-]digits[.digits][(e|E)[+-]digits] with at least one mantissa digit. This one
/// grammar is applied before both parsers, so double and MPFR accept exactly the same tokens
/// (no nan, inf, hex floats or whitespace).
bool is_decimal_literal(std::string_view text) {
  if (!text.empty() && (text.front() == '+' || text.front() == '-')) text.remove_prefix(1);
  std::size_t mantissa_digits = digit_run(text);
  text.remove_prefix(mantissa_digits);
  if (!text.empty() && text.front() == '.') {
    text.remove_prefix(1);
    const std::size_t fraction_digits = digit_run(text);
    mantissa_digits += fraction_digits;
    text.remove_prefix(fraction_digits);
  }
  if (mantissa_digits == 0) return false;
  if (text.empty()) return true;
  if (text.front() != 'e' && text.front() != 'E') return false;
  text.remove_prefix(1);
  if (!text.empty() && (text.front() == '+' || text.front() == '-')) text.remove_prefix(1);
  const std::size_t exponent_digits = digit_run(text);
  return exponent_digits > 0 && exponent_digits == text.size();
}

double to_double(std::string_view text, std::string_view what, bool advise_digits) {
  if (text.front() == '+') text.remove_prefix(1);  // from_chars takes no '+'
  double value = 0;
  const auto [end, status] = std::from_chars(text.data(), text.data() + text.size(), value);
  if (status == std::errc::result_out_of_range)  // MPFR helps physical inputs, not a tolerance
    throw bad_input(std::string(what) + ": " + in_quotes(text) +
                      " is out of the range of double" +
                      (advise_digits ? digits_advice() : std::string()));
  if (status != std::errc() || end != text.data() + text.size())
    throw bad_input(std::string(what) + ": malformed number " + in_quotes(text));
  return value;
}

mpfr_real to_mpfr(std::string_view text, std::string_view what) {
  const std::string terminated(text);
  mpfr_real value;  // at the caller's working precision
  if (mpfr_set_str(value.backend().data(), terminated.c_str(), 10, MPFR_RNDN) != 0)
    throw bad_input(std::string(what) + ": malformed number " + in_quotes(text));
  return value;
}

}  // namespace

// ---------------------------------------------------------------- numbers

template <class Real>
Real parse_real(std::string_view text, std::string_view what, Domain domain,
                bool advise_digits) {
  if (text.empty()) throw bad_input(std::string(what) + ": empty number");
  if (!is_decimal_literal(text))
    throw bad_input(std::string(what) + ": malformed number " + in_quotes(text) +
                      " (expected a finite decimal number)");
  Real value;
  if constexpr (is_mpfr_v<Real>) {
    value = to_mpfr(text, what);
  } else {
    value = to_double(text, what, advise_digits);
  }
  using std::isfinite;
  if (!isfinite(value))
    throw bad_input(std::string(what) + ": " + in_quotes(text) + " is not finite");
  if (domain == Domain::positive && !(value > 0))
    throw bad_input(std::string(what) + ": " + in_quotes(text) + " must be > 0");
  if (domain == Domain::nonnegative && value < 0)
    throw bad_input(std::string(what) + ": " + in_quotes(text) + " must be >= 0");
  return value;
}

template <class Real>
std::vector<Real> parse_real_list(std::string_view text, std::string_view what, Domain domain) {
  std::vector<Real> values;
  for (std::size_t begin = 0;;) {
    const std::size_t comma = std::min(text.find(',', begin), text.size());
    const std::string_view element = text.substr(begin, comma - begin);
    if (element.empty())
      throw bad_input(std::string(what) + ": empty element in list " + in_quotes(text));
    values.push_back(parse_real<Real>(element, what, domain));
    if (comma == text.size()) return values;
    begin = comma + 1;
  }
}

template double parse_real<double>(std::string_view, std::string_view, Domain, bool);
template mpfr_real parse_real<mpfr_real>(std::string_view, std::string_view, Domain, bool);
template std::vector<double> parse_real_list<double>(std::string_view, std::string_view, Domain);
template std::vector<mpfr_real> parse_real_list<mpfr_real>(std::string_view, std::string_view,
                                                           Domain);

long parse_integer(std::string_view text, std::string_view what, long lowest, long highest) {
  long value = 0;
  const auto [end, status] = std::from_chars(text.data(), text.data() + text.size(), value);
  if (text.empty() || digit_run(text) != text.size() || status != std::errc() ||
      end != text.data() + text.size() || value < lowest || value > highest)
    throw bad_input(std::string(what) + ": " + in_quotes(text) + " is not an integer in " +
                      std::to_string(lowest) + ".." + std::to_string(highest));
  return value;
}

std::uint64_t parse_unsigned(std::string_view text, std::string_view what) {
  std::uint64_t value = 0;
  const auto [end, status] = std::from_chars(text.data(), text.data() + text.size(), value);
  if (text.empty() || digit_run(text) != text.size() || status != std::errc() ||
      end != text.data() + text.size())
    throw bad_input(std::string(what) + ": " + in_quotes(text) +
                      " is not an unsigned integer in 0..18446744073709551615");
  return value;
}

int parse_digits(std::string_view text, std::string_view what) {
  return static_cast<int>(parse_integer(text, what, min_digits, max_digits));
}

std::size_t parse_choice(std::string_view text, std::string_view what,
                         std::span<const std::string_view> choices) {
  const auto found = std::ranges::find(choices, text);
  if (found != choices.end()) return static_cast<std::size_t>(found - choices.begin());
  std::string expected;
  for (const std::string_view choice : choices)
    (expected += expected.empty() ? "" : "|") += choice;
  throw bad_input("unknown " + std::string(what) + " " + in_quotes(text) + " (expected " +
                    expected + ")");
}

}  // namespace pendavg::io
