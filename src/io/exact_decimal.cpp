// SPDX-License-Identifier: GPL-3.0-or-later
// src/io/exact_decimal.cpp -- 1 - x as an exact decimal.
#include "io/exact_decimal.hpp"

#include <algorithm>
#include <charconv>
#include <stdexcept>
#include <string>

namespace pendavg::io {

std::string one_minus_decimal(std::string_view x, std::string_view what) {
  const std::string name(what);
  const auto fail = [&] { return std::invalid_argument(name + ": '" + std::string(x) + "' must be < 1"); };
  std::string_view text = x;
  if (text.starts_with('+')) text.remove_prefix(1);
  long exponent = 0;
  if (const auto e = text.find_first_of("eE"); e != std::string_view::npos) {
    std::string_view exponent_text = text.substr(e + 1);
    if (exponent_text.starts_with('+')) exponent_text.remove_prefix(1);
    const auto [ptr, ec] = std::from_chars(exponent_text.data(),
                                           exponent_text.data() + exponent_text.size(), exponent);
    if (ec != std::errc() || ptr != exponent_text.data() + exponent_text.size() ||
        exponent < -max_decimal_scale || exponent > max_decimal_scale)  // std::labs(LONG_MIN) is UB
      throw std::invalid_argument(name + ": '" + std::string(x) + "' has too many digits for 1 - " + name);
    text = text.substr(0, e);
  }
  std::string digits;
  long scale = 0;  // x = digits * 10^-scale
  const auto point = text.find('.');
  digits = std::string(text.substr(0, point));
  if (point != std::string_view::npos) {
    digits += text.substr(point + 1);
    scale = static_cast<long>(text.size() - point - 1);
  }
  scale -= exponent;
  digits.erase(0, std::min(digits.find_first_not_of('0'), digits.size()));
  if (digits.empty()) throw std::invalid_argument(name + ": '" + std::string(x) + "' must be > 0");
  if (scale > max_decimal_scale)
    throw std::invalid_argument(name + ": '" + std::string(x) + "' has too many digits for 1 - " + name);
  if (scale <= 0 || static_cast<long>(digits.size()) > scale) throw fail();  // x >= 1
  digits.insert(0, static_cast<std::size_t>(scale) - digits.size(), '0');
  // 10^scale - D = (999...9 - D) + 1
  std::string result(digits.size(), '0');
  for (std::size_t i = 0; i < digits.size(); ++i) result[i] = static_cast<char>('9' - (digits[i] - '0'));
  for (std::size_t i = result.size(); i-- > 0;) {
    if (result[i] == '9') { result[i] = '0'; continue; }
    ++result[i];
    break;
  }
  result.erase(result.find_last_not_of('0') + 1);  // D > 0, so some digit is non-zero
  return "0." + result;
}

}  // namespace pendavg::io
