// SPDX-License-Identifier: GPL-3.0-or-later
// src/io/number_text.hpp -- reals as decimal text, the one printer of every front end (CLI,
// Python, files). Two styles:
//   * shortest (write_shortest): a double as the shortest decimal that reads back as the same
//     double (std::to_chars) -- a double run's values lose no bit;
//   * `digits` significant digits (write_decimal): an MPFR run's values, correctly rounded;
// and errors with error_digits significant digits rounded up (write_error), so that a printed
// error never claims less than the computed one. printed_error adds what printing a value with
// `digits` digits moves it by.
#pragma once

#include "pendavg/average.hpp"
#include "pendavg/result.hpp"

#include <cstddef>
#include <string>
#include <string_view>
#include <type_traits>

namespace pendavg::io {

/// Significant digits of an error estimate.
inline constexpr int error_digits = 3;

/// Appends x in scientific notation with `digits` significant digits, e.g. 3.43e-01 for 3.
template <class Real>
void append_decimal(std::string& out, const Real& x, int digits);

/// Longest text write_decimal produces for `digits` significant digits.
inline constexpr std::size_t decimal_max_length(int digits) {
  return static_cast<std::size_t>(digits) + 24;  // sign, point, e, exponent sign and digits
}

/// Writes append_decimal's text of x at `out` (room for decimal_max_length(digits) chars) and
/// returns its end.
template <class Real>
char* write_decimal(char* out, const Real& x, int digits);

/// The printed error of a value printed with `digits` digits (printed_errors, one value).
/// `upward` (certified results, Method::certified_integral): the error is a proven bound and
/// stays one when printed -- it also covers the rounding of a quotient formed from the value
/// (write_quotient: 2^(1-p) |value|, p the value's bits) and is enlarged by 1/64 so that its
/// error_digits-digit decimal, rounded to nearest, is not below it.
template <class Real>
Real printed_error(const Real& value, const Real& error, int digits, bool upward = false);

/// Whether a result's printed errors must stay bounds (printed_error's `upward`).
template <class Real>
bool upward_errors(const Averages<Real>& averages) {
  return averages.method == Method::certified_integral;
}


/// Where a quotient value / divisor (<K_i> = beta<K_i>/beta, Var K_i = beta^2 Var K_i/beta^2) is
/// formed: long double for a double run (beta < 1e-154 leaves double's range), MPFR for MPFR.
template <class Real>
using quotient_t = std::conditional_t<std::is_same_v<Real, double>, long double, Real>;

/// Writes value / divisor (`digits` digits) and, after `separator`, its printed error (error /
/// divisor plus the printing's rounding, error_digits digits); returns the end. For a double run
/// both quotients are rounded to double when they are normal doubles (or 0), so that nearly
/// every row takes the fast double printer; every front end prints quotients through here.
/// A double run prints <K_i> = beta<K_i>/beta and Var K_i = beta^2 Var K_i / beta^2 beside the
/// beta-scaled values: refused before any work (invalid_input) where beta^2 is not a normal
/// double (beta outside 1.5e-154..1.3e154), since Var K_i would then overflow or underflow.
/// Nothing to check in MPFR.
template <class Real>
void check_printed_quotients(const Real& beta) {
  if constexpr (std::is_same_v<Real, double>) {
    if (!(beta >= 1.5e-154 && beta <= 1.3e154))
      throw invalid_input("at beta outside 1.5e-154..1.3e154 a double run's Var K_i = beta^2 "
                          "Var K_i / beta^2 leaves double's range");
  } else {
    (void)beta;
  }
}

template <class Real>
char* write_quotient(char* out, const Real& value, const Real& error,
                     const quotient_t<Real>& divisor, int digits, char separator,
                     bool upward = false);

template <class Real>
std::string decimal(const Real& x, int digits) {
  std::string out;
  append_decimal(out, x, digits);
  return out;
}

/// Writes a finite double x as the shortest decimal that reads back as x (std::to_chars without
/// a precision: 0.7, 1e-300, 3.873103991523665e-01 -> 0.3873103991523665) at `out` (room for 25
/// characters); returns the end. A non-finite x is an internal error (fails closed).
char* write_shortest(char* out, double x);

/// How far the text `written` of x (write_shortest's) lies from x: 0 when it is x's exact
/// decimal value (0.5, 3, 1.25e-3 are; 0.1 is not), else half a unit in x's last binary place,
/// a bound of |text - x| for any text that reads back as x. A double run adds it to the errors
/// of what it prints, so that a printed error covers the printed value, not only the double.
double printing_gap(double x, std::string_view written);

/// Writes an error e >= 0 with error_digits significant digits, rounded up (the text's value is
/// never below e): 1.04e-15. Room: decimal_max_length(error_digits). Double or MPFR.
template <class Real>
char* write_error(char* out, const Real& e);

}  // namespace pendavg::io
