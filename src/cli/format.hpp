// SPDX-License-Identifier: GPL-3.0-or-later
// src/cli/format.hpp -- output side of the pendavg CLI: numbers as decimal strings (double and
// MPFR alike, `digits` significant digits), and small JSON, CSV and aligned-text writers.
// Everything builds strings; the caller writes them to stdout once, after all work succeeded.
#pragma once

#include "pendavg/microcanonical.hpp"
#include "pendavg/result.hpp"
#include "io/number_text.hpp"
#include "io/report.hpp"

#include <cstddef>
#include <span>
#include <string>
#include <string_view>
#include <type_traits>
#include <vector>

namespace pendavg::cli {

using io::append_decimal;
using io::check_printed_quotients;
using io::decimal;
using io::decimal_max_length;
using io::error_digits;
using io::printed_error;
using io::quotient_t;
using io::upward_errors;
using io::write_decimal;
using io::write_quotient;

using io::Format;

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

using io::seconds_text;

}  // namespace pendavg::cli
