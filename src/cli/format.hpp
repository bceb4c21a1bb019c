// SPDX-License-Identifier: GPL-3.0-or-later
// src/cli/format.hpp -- output side of the pendavg CLI: numbers as decimal strings (double and
// MPFR alike, `digits` significant digits), and small JSON, CSV and aligned-text writers.
// Everything builds strings; the caller writes them to stdout once, after all work succeeded.
#pragma once

#include "pendavg/microcanonical.hpp"
#include "pendavg/result.hpp"

#include <cstddef>
#include <span>
#include <string>
#include <string_view>
#include <type_traits>
#include <vector>

namespace pendavg::cli {

enum class Format { json, csv, text };

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

/// The averages of one run as decimal strings, converted once and shared by every format. Every
/// printed error covers its printed value: the computed error plus half a unit in the value's
/// last printed place (printed_error).
struct AveragesText {
  std::vector<std::string> beta_kinetic;          ///< beta <K_i>
  std::vector<std::string> error;                 ///< errors of beta <K_i>
  std::vector<std::string> cos_angle;             ///< <cos phi_i>
  std::vector<std::string> cos_angle_error;
  std::vector<std::string> beta2_variance;        ///< beta^2 Var K_i
  std::vector<std::string> beta2_variance_error;
  std::vector<std::string> kinetic;               ///< <K_i> = beta<K_i>/beta (empty without beta)
  std::vector<std::string> kinetic_error;
  std::vector<std::string> variance;              ///< Var K_i (empty without beta)
  std::vector<std::string> variance_error;
  std::vector<std::string> beta_kinetic_canonical;  ///< beta <K_i^(c)> = 1/2
  std::vector<std::string> beta_kinetic_canonical_error;
  std::vector<std::string> diagonal_approximation;  ///< eq. ke-linear-tave-1
  std::string ratio, ratio_error;  ///< empty for N = 1
  std::string equipartition_residual;
  std::string method, error_kind, cos_angle_error_kind, variance_error_kind, work_unit;
  std::string beta_kinetic_canonical_error_kind;  ///< bound (1/2 is exact)
  std::size_t evaluations = 0;
  bool converged = true;
};

/// Converts `averages` to strings with `digits` significant digits (errors with error_digits);
/// `beta` (may be null, as for the limits) adds <K_i> and Var K_i.
template <class Real>
AveragesText averages_text(const Averages<Real>& averages, int digits, const Real* beta);

/// Microcanonical averages of one run as decimal strings (MicrocanonicalAverages), converted
/// once and shared by every format; every printed error covers its printed value, as above.
struct MicrocanonicalText {
  std::string energy, excitation;  ///< E and D = E - E_min, `digits` digits
  std::vector<std::string> kinetic, kinetic_error;          ///< <K_i>_E
  std::vector<std::string> cos_angle, cos_angle_error;      ///< <cos phi_i>_E
  std::vector<std::string> variance, variance_error;        ///< Var K_i
  std::string kinetic_canonical, kinetic_canonical_error;   ///< <K_i^(c)>_E = <K>_E / N
  std::string kinetic_total, kinetic_total_error;           ///< <K>_E
  std::string density_of_states, density_of_states_error;   ///< Omega(E)
  std::string method, error_kind, work_unit;
  std::string proposal_beta, effective_sample_fraction;  ///< qmc only (empty otherwise)
  std::size_t evaluations = 0;
  bool converged = true;
};

template <class Real>
MicrocanonicalText microcanonical_text(const MicrocanonicalAverages<Real>& averages, int digits);

/// A JSON array of strings.
std::string json_strings(const std::vector<std::string>& values);

/// A JSON string, or null for an empty text (a value that does not exist, e.g. <K1>/<K2> for
/// N = 1).
std::string json_nullable(const std::string& text);

/// A JSON object written key by key, in insertion order.
class JsonObject {
 public:
  JsonObject& raw(std::string_view key, std::string_view json);  ///< value is already JSON
  JsonObject& string(std::string_view key, std::string_view value);
  JsonObject& strings(std::string_view key, const std::vector<std::string>& values);
  JsonObject& integer(std::string_view key, long long value);
  JsonObject& boolean(std::string_view key, bool value);
  std::string str() const { return "{" + body_ + "}"; }

 private:
  std::string body_;
};

/// Joins `fields` with commas and ends the line.
void append_csv_line(std::string& out, std::span<const std::string> fields);

/// Right-aligned columns separated by two spaces, one line per row.
std::string aligned_table(const std::vector<std::vector<std::string>>& rows);

/// {"stem1", "stem2", ...}: column names for a per-particle array.
std::vector<std::string> indexed_names(std::string_view stem, std::size_t count);

/// A wall time in seconds as a JSON number with 6 significant digits.
std::string seconds_text(double seconds);

}  // namespace pendavg::cli
