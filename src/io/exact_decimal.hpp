// SPDX-License-Identifier: GPL-3.0-or-later
// src/io/exact_decimal.hpp -- exact decimal arithmetic on the numbers a user writes: the mass of
// a double pendulum's second particle, m2 = 1 - mu1, as an exact decimal (1 - 1e-30 =
// 0.999999999999999999999999999999), so that a table over mu1 runs at the masses written, in
// double and in MPFR alike.
#pragma once

#include <string>
#include <string_view>

namespace pendavg::io {

/// Digits after the point that one_minus_decimal accepts (x = 1e-4000 still works).
inline constexpr long max_decimal_scale = 4000;

/// 1 - x for a decimal x in (0, 1) (already read strictly: [+]digits[.digits][e[+-]digits]) as an
/// exact decimal "0.ddd". Throws std::invalid_argument naming `what` (e.g. "mu1") when x <= 0,
/// x >= 1 or x has more than max_decimal_scale digits after the point.
std::string one_minus_decimal(std::string_view x, std::string_view what);

}  // namespace pendavg::io
