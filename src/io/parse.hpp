// SPDX-License-Identifier: GPL-3.0-or-later
// src/io/parse.hpp -- strict reading of the numbers a user writes (the CLI's options and cases
// files, Python's str/Decimal arguments): one grammar for double and MPFR, refusals as one line
// naming the field (`what`: the CLI passes "--beta", Python "beta", a cases file "m1").
#pragma once

#include "pendavg/chain.hpp"

#include <cstddef>
#include <cstdint>
#include <span>
#include <string>
#include <string_view>
#include <vector>

namespace pendavg::io {

/// Bad input found by a front end (a number, an option, a file). Its message is one line,
/// starting with the field's name. It is a pendavg::invalid_input, so one handler covers the
/// front ends' and the library's validation.
class bad_input : public invalid_input {
 public:
  using invalid_input::invalid_input;
};

/// 'text', for messages.
std::string in_quotes(std::string_view text);

/// Which values a physical parameter may take.
enum class Domain { positive, nonnegative, any };

/// Parses one decimal number strictly: [+-]digits[.digits][e[+-]digits], the whole token, finite,
/// inside `domain`. `what` names the quantity in the error message (e.g. "--beta").
/// For mpfr_real the text is rounded once, directly to this thread's working precision (0.1 never
/// goes through double): parse under the working_precision of the call the value is for.
/// Whether the running command takes --digits: a number out of double's range is then refused
/// with the advice "use --digits > 16" (set by run() for each command; on by default).
void set_digits_advice(bool command_takes_digits);
/// What set_digits_advice was last given.
bool command_takes_digits();
/// How the advice spells the digits option: "--digits" (the CLI, the default) or "digits"
/// (Python's argument). Set once by a front end before any parsing.
void set_digits_option_name(std::string_view name);
/// The advice a refusal of a number out of double's range ends with, " (use --digits > 16)"; empty
/// when the running command takes no digits.
std::string digits_advice();

/// `advise_digits` false leaves the advice out for this number (a tolerance: more digits do not
/// help it).
template <class Real>
Real parse_real(std::string_view text, std::string_view what, Domain domain,
                bool advise_digits = true);

/// A comma-separated list of numbers, each parsed by parse_real; empty elements are errors.
template <class Real>
std::vector<Real> parse_real_list(std::string_view text, std::string_view what, Domain domain);

/// A non-negative decimal integer in [lowest, highest], digits only.
long parse_integer(std::string_view text, std::string_view what, long lowest, long highest);

/// An unsigned 64-bit decimal integer, digits only (e.g. a seed).
std::uint64_t parse_unsigned(std::string_view text, std::string_view what);

/// digits: an integer in pendavg::min_digits..pendavg::max_digits.
int parse_digits(std::string_view text, std::string_view what = "--digits");

/// Index of `text` in `choices`; throws bad_input "unknown <what> '<text>' (expected a|b|c)".
std::size_t parse_choice(std::string_view text, std::string_view what,
                         std::span<const std::string_view> choices);

}  // namespace pendavg::io
