// SPDX-License-Identifier: GPL-3.0-or-later
// src/cli/format.cpp -- decimal strings and the JSON, CSV and text writers of the pendavg CLI.
#include "format.hpp"

#include "decimal.hpp"

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
char* write_decimal(char* out, const Real& x, int digits) {
  const std::size_t room = decimal_max_length(digits);
  if constexpr (is_mpfr_v<Real>) {
    // Same layout as the double branch (d.ddde-XX), correctly rounded by MPFR. mpfr_snprintf
    // writes the radix character of the C locale's LC_NUMERIC (',' under de_DE, set e.g. by a
    // Python program that embeds the library, maybe several bytes): the characters between the
    // leading digit and the next digit are replaced by '.', so the text never depends on the
    // locale (as std::to_chars in the other branches).
    thread_local std::string buffer;
    buffer.resize(room + 8);  // a radix character of up to 8 bytes
    char* text = buffer.data();
    const std::size_t size = buffer.size();
    const int written = mpfr_snprintf(text, size, "%.*Re", digits - 1, x.backend().data());
    std::size_t length = std::min<std::size_t>(static_cast<std::size_t>(std::max(written, 0)), size - 1);
    const std::size_t lead = text[0] == '-' ? 1 : 0;  // the leading digit's position
    if (length > lead + 1 && text[lead] >= '0' && text[lead] <= '9' &&
        !(text[lead + 1] >= '0' && text[lead + 1] <= '9') && text[lead + 1] != 'e') {
      std::size_t next = lead + 1;
      while (next < length && !(text[next] >= '0' && text[next] <= '9')) ++next;
      text[lead + 1] = '.';
      std::memmove(text + lead + 2, text + next, length - next);
      length -= next - (lead + 2);
    }
    length = std::min(length, room - 1);
    std::memcpy(out, text, length);
    return out + length;
  } else {
    if constexpr (std::is_same_v<Real, double>) {
      if (char* end = detail::scientific_fast(out, x, digits)) return end;
    }
    return std::to_chars(out, out + room, x, std::chars_format::scientific, digits - 1).ptr;
  }
}

template <class Real>
char* write_quotient(char* out, const Real& value, const Real& error,
                     const quotient_t<Real>& divisor, int digits, char separator, bool upward) {
  using Wide = quotient_t<Real>;
  const Wide q = Wide(value) / divisor, e = Wide(error) / divisor;
  if constexpr (std::is_same_v<Real, double>) {
    const double qd = static_cast<double>(q), ed = static_cast<double>(e);
    // <K_i> = beta<K_i>/beta and Var K_i = beta^2 Var K_i / beta^2 of a double run are printed
    // as doubles: a quotient outside double's normal range (Var K_i = 5e-601 at beta = 1e300)
    // would read as 0 +- 0 or with lost digits, so it is refused rather than printed.
    if (value != 0 && !std::isnormal(qd))
      throw invalid_input("<K_i> = beta<K_i>/beta or Var K_i = beta^2 Var K_i/beta^2 is " +
                          short_decimal(static_cast<long double>(q)) +
                          ", outside double's normal range (2.2e-308..1.8e308) at this beta");
    const auto plain = [](double x) { return x == 0 || std::isnormal(x); };
    if (plain(qd) && plain(ed)) {
      out = write_decimal(out, qd, digits);
      *out++ = separator;
      return write_decimal(out, printed_error(qd, ed, digits, upward), error_digits);
    }
  }
  out = write_decimal(out, q, digits);
  *out++ = separator;
  return write_decimal(out, printed_error(q, e, digits, upward), error_digits);
}

template <class Real>
void append_decimal(std::string& out, const Real& x, int digits) {
  const std::size_t start = out.size();
  out.resize(start + decimal_max_length(digits));
  out.resize(static_cast<std::size_t>(write_decimal(out.data() + start, x, digits) - out.data()));
}

namespace {

/// 10^n as std::pow(10, n) computes it, for the integer n of printed_error (a table of pow's
/// own values: the same numbers, without a pow call per value).
double power_of_ten(double n) {
  constexpr int lowest = -400, highest = 400;
  static const auto table = [] {
    std::array<double, highest - lowest + 1> t{};
    for (int i = lowest; i <= highest; ++i) t[static_cast<std::size_t>(i - lowest)] = std::pow(10.0, i);
    return t;
  }();
  if (n >= lowest && n <= highest) return table[static_cast<std::size_t>(static_cast<int>(n) - lowest)];
  return std::pow(10.0, n);
}

/// floor(log10 a) exactly as std::floor(std::log10(a)) gives it, for a > 0, mostly without
/// the call: a's binary exponent and one comparison with a power of ten decide, and a within
/// 1e-12 (relative) of a power of ten -- where log10's rounding may land on the integer -- asks
/// log10 itself. (Outside that band log10, accurate to a few ulp of numbers <= 324, stays
/// strictly between the two integers.)
double floor_log10(double a) {
  constexpr int lowest = -308, highest = 309;
  static const auto table = [] {
    std::array<double, highest - lowest + 1> t{};
    for (int i = lowest; i <= highest; ++i)
      t[static_cast<std::size_t>(i - lowest)] = std::pow(10.0, i);
    return t;
  }();
  if (!(a >= std::numeric_limits<double>::min() && a <= std::numeric_limits<double>::max()))
    return std::floor(std::log10(a));  // subnormal, infinite or NaN
  const int e = std::ilogb(a);  // a in [2^e, 2^(e+1))
  int d = static_cast<int>((static_cast<long>(e) * 78913) >> 18);  // floor(e log10 2)
  const auto ten = [&](int k) { return table[static_cast<std::size_t>(k - lowest)]; };
  if (d + 1 <= highest && a >= ten(d + 1)) ++d;
  const double band = 1e-12;
  if (a < ten(d) * (1 + band) || (d + 1 <= highest && a > ten(d + 1) * (1 - band)))
    return std::floor(std::log10(a));
  return d;
}

/// The same for an MPFR number (where log10 costs ~10 us at 50 digits): log10 |a| from a's
/// binary exponent and a 53-bit mantissa in long double (absolute error < 1e-9 over MPFR's
/// exponent range), and MPFR's own log10 only within 1e-8 of an integer -- farther out, the
/// correctly rounded log10 (error < 5e-9 from prec >= 56 bits) has the same floor.
long floor_log10(const mpfr_real& a) {
  long binary_exponent = 0;
  const double mantissa = mpfr_get_d_2exp(&binary_exponent, a.backend().data(), MPFR_RNDN);
  const long double estimate =
      std::log10(static_cast<long double>(std::fabs(mantissa))) +
      static_cast<long double>(binary_exponent) * 0.301029995663981195213738894724493027L;
  const long double below = std::floor(estimate);
  if (mpfr_get_prec(a.backend().data()) >= 56 && estimate - below > 1e-8L &&
      estimate - below < 1 - 1e-8L)
    return static_cast<long>(below);
  using std::abs;
  using std::floor;
  using std::log10;
  return floor(log10(abs(a))).template convert_to<long>();
}

}  // namespace

template <class Real>
Real printed_error(const Real& value, const Real& error, int digits, bool upward) {
  using std::abs;
  using std::floor;
  using std::log10;
  using std::pow;
  if (upward) {
    // 2^(1-p) |value| (p the value's bits): the rounding of a quotient value / divisor formed
    // in Real (MPFR: relative error <= 2^(1-p)) or in long double and rounded to double
    // (<= 2^-53 + 2^-64 < 2^-52)
    Real rounding = abs(value);
    if constexpr (is_mpfr_v<Real>) {
      mpfr_mul_2si(rounding.backend().data(), rounding.backend().data(),
                   1 - static_cast<long>(mpfr_get_prec(value.backend().data())), MPFR_RNDU);
    } else {
      rounding *= std::numeric_limits<Real>::epsilon();
    }
    const Real shown = printed_error(value, Real(error + rounding), digits, false);
    return shown + shown / 64;
  }
  if (value == 0) return error;
  // scientific notation with `digits` significant digits: the last place is
  // 10^(floor(log10 |v|) - digits + 1); rounding to it moves the value by at most half.
  Real exponent;
  if constexpr (std::is_same_v<Real, double>)
    exponent = floor_log10(std::fabs(value)) - (digits - 1);
  else if constexpr (is_mpfr_v<Real>)
    exponent = Real(floor_log10(value) - (digits - 1));
  else
    exponent = floor(log10(abs(value))) - Real(digits - 1);
  if constexpr (std::is_same_v<Real, double>) {
    // Below 1e-307 the half unit is subnormal in double (a few digits, or 0 below 1e-324): form
    // the sum in long double and round it up, so that it still covers the rounding.
    if (exponent >= -307) return error + power_of_ten(exponent) / 2;
    const long double sum = static_cast<long double>(error) + std::pow(10.0L, exponent) / 2;
    const double bound = static_cast<double>(sum);
    return static_cast<long double>(bound) < sum
               ? std::nextafter(bound, std::numeric_limits<double>::infinity())
               : bound;
  } else if constexpr (is_mpfr_v<Real>) {
    // 10^exponent correctly rounded, as pow(Real(10), exponent) (mpfr_pow) gives it, by
    // mpfr_pow_si (no log and exp for an integer power)
    Real ten_power(10);
    mpfr_pow_si(ten_power.backend().data(), ten_power.backend().data(),
                exponent.template convert_to<long>(), MPFR_RNDN);
    return error + ten_power / 2;
  } else {
    return error + pow(Real(10), exponent) / 2;
  }
}

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
template void append_decimal<double>(std::string&, const double&, int);
template void append_decimal<long double>(std::string&, const long double&, int);
template char* write_decimal<double>(char*, const double&, int);
template char* write_decimal<mpfr_real>(char*, const mpfr_real&, int);
template char* write_decimal<long double>(char*, const long double&, int);
template char* write_quotient<double>(char*, const double&, const double&, const long double&, int,
                                      char, bool);
template char* write_quotient<mpfr_real>(char*, const mpfr_real&, const mpfr_real&,
                                         const mpfr_real&, int, char, bool);
template double printed_error<double>(const double&, const double&, int, bool);
template mpfr_real printed_error<mpfr_real>(const mpfr_real&, const mpfr_real&, int, bool);
template long double printed_error<long double>(const long double&, const long double&, int,
                                                bool);
template void append_decimal<mpfr_real>(std::string&, const mpfr_real&, int);
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

std::string seconds_text(double seconds) {
  char buffer[32];
  const auto end = std::to_chars(buffer, buffer + sizeof buffer, seconds,
                                 std::chars_format::general, 6).ptr;
  return std::string(buffer, end);
}

}  // namespace pendavg::cli
