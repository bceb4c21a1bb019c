// SPDX-License-Identifier: GPL-3.0-or-later
// engine/numerics/text.hpp -- numbers in the engines' one-line error messages.
#pragma once

#include <charconv>
#include <string>

namespace pendavg {

/// x with 3 significant digits ("2e+303", "0.125"), for messages: printf's "%.3Lg" in the C
/// locale whatever the process's LC_NUMERIC (a program embedding the library, e.g. Python under
/// de_DE, would otherwise get "0,125").
inline std::string short_decimal(long double x) {
  char buffer[48];
  const auto end =
      std::to_chars(buffer, buffer + sizeof buffer, x, std::chars_format::general, 3).ptr;
  return std::string(buffer, end);
}

/// x with 6 digits after the point ("-3.000000"), as std::to_string(double) writes it in the C
/// locale, whatever the process's LC_NUMERIC.
inline std::string fixed_decimal(double x) {
  char buffer[400];  // |x| < 1.8e308: at most 309 digits before the point
  const auto end =
      std::to_chars(buffer, buffer + sizeof buffer, x, std::chars_format::fixed, 6).ptr;
  return std::string(buffer, end);
}

}  // namespace pendavg
