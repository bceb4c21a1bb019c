// SPDX-License-Identifier: GPL-3.0-or-later
// src/cli/format.cpp -- decimal strings and the JSON, CSV and text writers of the pendavg CLI.
#include "format.hpp"


#include "engine/numerics/precision.hpp"
#include "engine/numerics/text.hpp"

#include <algorithm>
#include <array>
#include <charconv>
#include <cmath>
#include <cstring>
#include <limits>
#include <string>
#include <type_traits>

namespace pendavg::cli {

template <class Real>
AveragesText averages_text(const Averages<Real>& averages, int digits, const Real* beta) {
  // <K_i> = beta<K_i>/beta and Var K_i = beta^2 Var K_i / beta^2 leave double's range for
  // beta < 1e-154 (the library returns the beta-scaled values); divide in long double.
  using Wide = std::conditional_t<is_mpfr_v<Real>, Real, long double>;
  // Values with `digits` digits; errors (scaled like their values) with error_digits, plus half a
  // unit in the last place of the printed value.
  const bool upward = upward_errors(averages);
  const auto put = [digits, upward](const std::vector<Estimate<Real>>& estimates, auto scale,
                                    std::vector<std::string>& values,
                                    std::vector<std::string>& errors) {
    values.reserve(estimates.size());
    errors.reserve(estimates.size());
    for (const Estimate<Real>& e : estimates) {
      const auto value = scale(e.value);
      values.push_back(decimal(value, digits));
      errors.push_back(decimal(printed_error(value, scale(e.error), digits, upward), error_digits));
    }
  };
  const auto same = [](const Real& value) { return value; };
  AveragesText text;
  put(averages.beta_kinetic, same, text.beta_kinetic, text.error);
  put(averages.cos_angle, same, text.cos_angle, text.cos_angle_error);
  put(averages.beta2_kinetic_variance, same, text.beta2_variance, text.beta2_variance_error);
  if (beta) {
    const Wide b = Wide(*beta);
    std::string buffer(2 * decimal_max_length(std::max(digits, error_digits)) + 1, '\0');
    const auto put_quotients = [&](const std::vector<Estimate<Real>>& estimates, const Wide& divisor,
                                   std::vector<std::string>& values,
                                   std::vector<std::string>& errors) {
      for (const Estimate<Real>& e : estimates) {
        const char* end =
            write_quotient(buffer.data(), e.value, e.error, divisor, digits, ' ', upward);
        const std::string_view both(buffer.data(), static_cast<std::size_t>(end - buffer.data()));
        const std::size_t space = both.find(' ');
        values.emplace_back(both.substr(0, space));
        errors.emplace_back(both.substr(space + 1));
      }
    };
    put_quotients(averages.beta_kinetic, b, text.kinetic, text.kinetic_error);
    put_quotients(averages.beta2_kinetic_variance, b * b, text.variance, text.variance_error);
  }
  put(averages.beta_kinetic_canonical, same, text.beta_kinetic_canonical,
      text.beta_kinetic_canonical_error);
  for (const Real& d : averages.diagonal_approximation)
    text.diagonal_approximation.push_back(decimal(d, digits));
  if (averages.ratio) {
    text.ratio = decimal(averages.ratio->value, digits);
    text.ratio_error = decimal(
        printed_error(averages.ratio->value, averages.ratio->error, digits, upward), error_digits);
  }
  text.equipartition_residual = decimal(averages.equipartition_residual, error_digits);
  text.method = method_name(averages.method);
  text.error_kind = error_kind_name(averages.error_kind);
  const auto kind_of = [&](const std::vector<Estimate<Real>>& estimates) {
    return std::string(error_kind_name(estimates.empty() ? averages.error_kind
                                                         : estimates.front().kind));
  };
  text.cos_angle_error_kind = kind_of(averages.cos_angle);
  text.variance_error_kind = kind_of(averages.beta2_kinetic_variance);
  text.beta_kinetic_canonical_error_kind = kind_of(averages.beta_kinetic_canonical);
  text.work_unit = work_unit_name(averages.work_unit);
  text.evaluations = averages.evaluations;
  text.converged = averages.converged;
  return text;
}

template <class Real>
MicrocanonicalText microcanonical_text(const MicrocanonicalAverages<Real>& averages, int digits) {
  MicrocanonicalText text;
  const auto put = [digits](const Estimate<Real>& e, std::string& value, std::string& error) {
    value = decimal(e.value, digits);
    error = decimal(printed_error(e.value, e.error, digits), error_digits);
  };
  const auto put_all = [&](const std::vector<Estimate<Real>>& estimates,
                           std::vector<std::string>& values, std::vector<std::string>& errors) {
    values.resize(estimates.size());
    errors.resize(estimates.size());
    for (std::size_t i = 0; i < estimates.size(); ++i) put(estimates[i], values[i], errors[i]);
  };
  text.energy = decimal(averages.energy, digits);
  text.excitation = decimal(averages.excitation, digits);
  put_all(averages.kinetic, text.kinetic, text.kinetic_error);
  put_all(averages.cos_angle, text.cos_angle, text.cos_angle_error);
  put_all(averages.kinetic_variance, text.variance, text.variance_error);
  put(averages.kinetic_canonical, text.kinetic_canonical, text.kinetic_canonical_error);
  put(averages.kinetic_total, text.kinetic_total, text.kinetic_total_error);
  put(averages.density_of_states, text.density_of_states, text.density_of_states_error);
  text.method = method_name(averages.quadrature);
  text.error_kind = error_kind_name(averages.error_kind);
  text.work_unit = work_unit_name(averages.work_unit);
  if (averages.quadrature == Method::qmc) {
    text.proposal_beta = decimal(averages.proposal_beta, error_digits + 3);
    text.effective_sample_fraction = decimal(averages.effective_sample_fraction, error_digits);
  }
  text.evaluations = averages.evaluations;
  text.converged = averages.converged;
  return text;
}

template MicrocanonicalText microcanonical_text<double>(const MicrocanonicalAverages<double>&, int);
template MicrocanonicalText microcanonical_text<mpfr_real>(const MicrocanonicalAverages<mpfr_real>&,
                                                           int);
template AveragesText averages_text<double>(const Averages<double>&, int, const double*);
template AveragesText averages_text<mpfr_real>(const Averages<mpfr_real>&, int,
                                               const mpfr_real*);

// ---------------------------------------------------------------- JSON

namespace {

std::string json_quoted(std::string_view text) {
  std::string out = "\"";
  for (const char c : text) {
    if (c == '"' || c == '\\') out += '\\';
    out += c;
  }
  return out + "\"";
}

}  // namespace

JsonObject& JsonObject::raw(std::string_view key, std::string_view json) {
  if (!body_.empty()) body_ += ", ";
  body_ += json_quoted(key) + ": ";
  body_ += json;
  return *this;
}

JsonObject& JsonObject::string(std::string_view key, std::string_view value) {
  return raw(key, json_quoted(value));
}

std::string json_strings(const std::vector<std::string>& values) {
  std::string array = "[";
  for (std::size_t i = 0; i < values.size(); ++i)
    array += (i ? ", " : "") + json_quoted(values[i]);
  return array + "]";
}

std::string json_nullable(const std::string& text) {
  return text.empty() ? std::string("null") : json_quoted(text);
}

JsonObject& JsonObject::strings(std::string_view key, const std::vector<std::string>& values) {
  return raw(key, json_strings(values));
}

JsonObject& JsonObject::integer(std::string_view key, long long value) {
  return raw(key, std::to_string(value));
}

JsonObject& JsonObject::boolean(std::string_view key, bool value) {
  return raw(key, value ? "true" : "false");
}

// ---------------------------------------------------------------- CSV and text

void append_csv_line(std::string& out, std::span<const std::string> fields) {
  for (std::size_t i = 0; i < fields.size(); ++i) {
    if (i) out += ',';
    out += fields[i];
  }
  out += '\n';
}

std::string aligned_table(const std::vector<std::vector<std::string>>& rows) {
  std::vector<std::size_t> widths;
  for (const auto& row : rows) {
    widths.resize(std::max(widths.size(), row.size()));
    for (std::size_t i = 0; i < row.size(); ++i) widths[i] = std::max(widths[i], row[i].size());
  }
  std::string out;
  for (const auto& row : rows) {
    for (std::size_t i = 0; i < row.size(); ++i) {
      if (i) out += "  ";
      out.append(widths[i] - row[i].size(), ' ');
      out += row[i];
    }
    out += '\n';
  }
  return out;
}

std::vector<std::string> indexed_names(std::string_view stem, std::size_t count) {
  std::vector<std::string> names;
  for (std::size_t i = 1; i <= count; ++i) names.push_back(std::string(stem) + std::to_string(i));
  return names;
}

}  // namespace pendavg::cli
