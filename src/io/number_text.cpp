// SPDX-License-Identifier: GPL-3.0-or-later
// src/io/number_text.cpp -- reals as decimal text: the front ends' one printer.
#include "io/number_text.hpp"

#include "io/decimal_fast.hpp"

#include "engine/numerics/precision.hpp"
#include "engine/numerics/text.hpp"
#include "pendavg/average.hpp"

#include <algorithm>
#include <array>
#include <bit>
#include <charconv>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <stdexcept>
#include <string>
#include <type_traits>

namespace pendavg::io {

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

double printing_gap(double x, std::string_view text) {
  if (x == 0) return 0;
  // Most values settle here, from their bits alone: a normal |x| = m 2^-k with m odd and
  // k >= 25 has the exact decimal m 5^k 10^-k, whose m 5^k >= 5^25 > 10^17 has more significant
  // digits than any shortest text (at most 17), so the text is not x's exact value.
  {
    const auto bits = std::bit_cast<std::uint64_t>(x) & ~(std::uint64_t{1} << 63);
    const auto biased = static_cast<int>(bits >> 52);
    if (biased > 53 && biased < 2047) {
      const std::uint64_t m = (bits & ((std::uint64_t{1} << 52) - 1)) | (std::uint64_t{1} << 52);
      const int k = 1075 - biased - std::countr_zero(m);
      if (k >= 25)  // half a unit in the last place: 2^(biased - 1076)
        return std::bit_cast<double>(static_cast<std::uint64_t>(biased - 53) << 52);
    }
  }
  // the text as D * 10^q (D < 10^38: a long integer's fixed notation has up to 39 digits)
  using u128 = unsigned __int128;
  u128 digits = 0;
  int significant = 0, fraction = 0, exponent = 0;
  bool point = false;
  std::size_t i = text.starts_with('-') ? 1 : 0;
  for (; i < text.size() && text[i] != 'e' && text[i] != 'E'; ++i) {
    if (text[i] == '.') {
      point = true;
      continue;
    }
    if (digits == 0 && text[i] == '0') {  // leading zeros
      if (point) ++fraction;
      continue;
    }
    if (++significant > 38) return std::max(std::ldexp(1.0, std::ilogb(x) - 53),
                                            std::numeric_limits<double>::denorm_min());
    digits = digits * 10 + static_cast<u128>(text[i] - '0');
    if (point) ++fraction;
  }
  if (i < text.size()) {
    const char* first = text.data() + i + 1;
    if (*first == '+') ++first;
    std::from_chars(first, text.data() + text.size(), exponent);
  }
  const int q = exponent - fraction;
  const double half_unit = std::max(std::ldexp(1.0, std::ilogb(x) - 53),
                                    std::numeric_limits<double>::denorm_min());
  // |x| = m 2^e; exact iff m 2^e == D 10^q
  int e = 0;
  const double mantissa = std::frexp(std::fabs(x), &e);  // in [0.5, 1)
  const auto m = static_cast<std::uint64_t>(std::ldexp(mantissa, 53));
  e -= 53;
  if (q >= 0) {
    // an integer: D 10^q == m 2^e, compared below 2^127 (beyond, shortest text has <= 17
    // digits and an exponent, and no double above 2^127 is a 17-digit decimal times 10^q
    // without being compared here as well: D 10^q < 10^38 holds it)
    if (e < -53) return half_unit;
    u128 lhs = digits;
    for (int k = 0; k < q; ++k) {
      if (lhs > (~static_cast<u128>(0)) / 10) return half_unit;
      lhs *= 10;
    }
    if (e >= 0) return e <= 74 && lhs == (static_cast<u128>(m) << e) ? 0.0 : half_unit;
    const int t = -e;
    if (m & ((std::uint64_t{1} << t) - 1)) return half_unit;  // x is not an integer
    return lhs == (m >> t) ? 0.0 : half_unit;
  }
  // D = x 10^k = m 5^k 2^(e + k), k = -q; a fraction's shortest text has D < 10^17 < 5^25,
  // so k > 27 cannot be exact
  const int k = -q;
  if (k > 27) return half_unit;
  u128 product = m;
  for (int j = 0; j < k; ++j) product *= 5;
  const int s = e + k;
  if (s >= 0) return s <= 64 && (product << s) == digits ? 0.0 : half_unit;
  const int t = -s;
  if (t >= 127) return half_unit;
  if (product & ((static_cast<u128>(1) << t) - 1)) return half_unit;
  return (product >> t) == digits ? 0.0 : half_unit;
}

char* write_shortest(char* out, double x) {
  if (!std::isfinite(x))
    throw std::logic_error("pendavg internal error: a non-finite value reached the printer");
  return std::to_chars(out, out + 25, x).ptr;
}

namespace {

/// error_digits significant digits of x >= 0 rounded up, exactly (mpfr_get_str with MPFR_RNDU;
/// no locale's radix character).
char* write_error_exact(char* out, mpfr_srcptr x) {
  if (mpfr_zero_p(x)) {
    std::memcpy(out, "0.00e+00", 8);
    return out + 8;
  }
  mpfr_exp_t exponent = 0;
  char digits[error_digits + 2];
  mpfr_get_str(digits, &exponent, 10, error_digits, x, MPFR_RNDU);
  char* p = out;
  *p++ = digits[0];
  *p++ = '.';
  for (int i = 1; i < error_digits; ++i) *p++ = digits[i];
  *p++ = 'e';
  const long shown = static_cast<long>(exponent) - 1;
  *p++ = shown < 0 ? '-' : '+';
  const long magnitude = shown < 0 ? -shown : shown;
  if (magnitude < 10) *p++ = '0';
  return std::to_chars(p, p + 24, magnitude).ptr;
}

void refuse_error(bool ok) {
  if (!ok)
    throw std::logic_error("pendavg internal error: an error that is negative or not finite "
                           "reached the printer");
}

}  // namespace

template <class Real>
char* write_error(char* out, const Real& e) {
  if constexpr (is_mpfr_v<Real>) {
    refuse_error(e >= 0 && mpfr_number_p(e.backend().data()));
    return write_error_exact(out, e.backend().data());
  } else {
    refuse_error(e >= 0 && std::isfinite(e));
    if constexpr (std::is_same_v<Real, double>) {
      if (e > 0)
        if (char* end = detail::scientific_fast(out, e, error_digits, true)) return end;
      static_assert(error_digits == 3, "the zero error below has error_digits digits");
      if (e == 0) {  // as write_error_exact writes it (errors of exact values: common)
        std::memcpy(out, "0.00e+00", 8);
        return out + 8;
      }
    }
    // zero, subnormals, magnitudes outside the fast path, long double: exactly, in MPFR
    mpfr_t x;
    mpfr_init2(x, 64);  // holds a double or an x87 long double exactly
    if constexpr (std::is_same_v<Real, double>) mpfr_set_d(x, e, MPFR_RNDN);
    else mpfr_set_ld(x, e, MPFR_RNDN);
    char* end = write_error_exact(out, x);
    mpfr_clear(x);
    return end;
  }
}

template char* write_error<double>(char*, const double&);
template char* write_error<long double>(char*, const long double&);
template char* write_error<mpfr_real>(char*, const mpfr_real&);

}  // namespace pendavg::io
