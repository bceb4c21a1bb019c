// SPDX-License-Identifier: GPL-3.0-or-later
// src/io/decimal_fast.hpp -- fast exact scientific notation for doubles: the same characters as
// std::to_chars(first, last, x, std::chars_format::scientific, digits - 1) (and printf's
// "%.*e"), i.e. x correctly rounded to `digits` significant digits, ties to even.
//
// Why: the CLI prints every value of `average --cases` with 16 digits; libstdc++'s
// precision-given to_chars (Ryu printf, general tables) takes ~70 ns a value, most of the
// CLI's per-row formatting. Here x = m 2^e and, with k = digits - 1 - floor(log10 |x|),
// x 10^k = m 5^k 2^(e + k) is formed exactly in 128-bit integers (5^k < 2^64: 0 <= k <= 27),
// then shifted with an exact remainder for the rounding (~10-20 ns). Outside that range
// (|x| >= 10^(digits - 1), |x| below ~10^(digits - 29), zero, subnormal, non-finite) the
// caller falls back to std::to_chars. tests/io/test_number_text.cpp compares both on millions of
// values, ties and boundaries included.
#pragma once

#include <bit>
#include <cstdint>
#include <cstring>

namespace pendavg::io::detail {

/// Writes x with `digits` (1..17) significant digits in scientific notation to `out` (at
/// least 26 chars); returns the end, or nullptr when x is outside the fast path's range.
/// `upward` (for x > 0: an error printed as a bound) rounds up instead of to nearest.
inline char* scientific_fast(char* out, double x, int digits, bool upward = false) {
  if (digits < 1 || digits > 17) return nullptr;
  const std::uint64_t bits = std::bit_cast<std::uint64_t>(x);
  const int biased = static_cast<int>((bits >> 52) & 0x7ff);
  if (biased == 0 || biased == 0x7ff) return nullptr;  // zero, subnormal, inf, nan
  const std::uint64_t m = (bits & ((std::uint64_t{1} << 52) - 1)) | (std::uint64_t{1} << 52);
  const int e = biased - 1075;  // |x| = m 2^e, 2^52 <= m < 2^53
  static constexpr std::uint64_t pow10[18] = {1ull,
                                              10ull,
                                              100ull,
                                              1000ull,
                                              10000ull,
                                              100000ull,
                                              1000000ull,
                                              10000000ull,
                                              100000000ull,
                                              1000000000ull,
                                              10000000000ull,
                                              100000000000ull,
                                              1000000000000ull,
                                              10000000000000ull,
                                              100000000000000ull,
                                              1000000000000000ull,
                                              10000000000000000ull,
                                              100000000000000000ull};
  static constexpr auto pow5 = [] {
    struct Table {
      std::uint64_t v[28];
      constexpr std::uint64_t operator[](int i) const { return v[i]; }
    } t{};
    t.v[0] = 1;
    for (int i = 1; i < 28; ++i) t.v[i] = t.v[i - 1] * 5;
    return t;
  }();
  using u128 = unsigned __int128;
  // floor(log10 |x|) is d or d + 1 for d = floor((e + 52) log10 2) (|x| in [2^(e+52), 2^(e+53))).
  int d = static_cast<int>(((e + 52) * 78913) >> 18);  // 78913 / 2^18 ~ log10 2, floor for negatives
  const std::uint64_t top = pow10[digits];             // the digits must stay below this
  std::uint64_t q = 0;
  u128 rem = 0, half = 0;
  bool exact_shift = false;
  // (An estimate one low that would need 5^28 is tried one higher: if that is too high, the
  // digits come out one short and the caller falls back.)
  if (digits - 1 - d == 28) ++d;
  for (int attempt = 0; attempt < 2; ++attempt) {
    const int k = digits - 1 - d;
    if (k < 0 || k > 27) return nullptr;
    const u128 P = static_cast<u128>(m) * pow5[k];  // < 2^117
    const int s = e + k;                      // x 10^k = P 2^s
    if (s >= 0) {
      if (s >= 11) return nullptr;  // P 2^s >= 2^63: beyond any digit count
      const u128 v = P << s;
      if (v >= top) {
        ++d;
        continue;
      }
      q = static_cast<std::uint64_t>(v);
      exact_shift = true;
    } else {
      const int t = -s;
      if (t >= 120) return nullptr;
      const u128 v = P >> t;
      if (v >= top) {
        ++d;
        continue;
      }
      q = static_cast<std::uint64_t>(v);
      rem = P - (v << t);
      half = static_cast<u128>(1) << (t - 1);
    }
    break;
  }
  if (q >= top) return nullptr;  // d was not found in two attempts (cannot happen)
  // Before rounding: fewer digits means d one too high (the 5^28 case above).
  if (q < pow10[digits - 1]) return nullptr;
  if (upward) {
    if (!exact_shift && rem != 0) ++q;
  } else if (!exact_shift && (rem > half || (rem == half && (q & 1)))) {
    ++q;  // ties to even
  }
  if (q == top) {  // rounded up to the next power of ten
    q = pow10[digits - 1];
    ++d;
  }
  char* p = out;
  if (bits >> 63) *p++ = '-';
  // The places of q (< 10^17, leading zeros included) at once: the top place, then two blocks
  // of 8 digits (one block for digits <= 8), each turned into 8 ASCII bytes with three multiply-shift splits over
  // the lanes of one 64-bit word (SWAR); the number's digits are the last `digits` places.
  char places[17];
  const auto eight = [](std::uint32_t v, char* to) {  // v < 10^8, written as 8 digits
    // lanes of 4 digits (high half in the low word: memory order), then 2, then 1
    std::uint64_t x = (v / 10000) | (static_cast<std::uint64_t>(v % 10000) << 32);
    std::uint64_t h = ((x * 5243) >> 19) & 0x0000007F0000007Full;  // lane / 100
    x = h | ((x - 100 * h) << 16);
    h = ((x * 103) >> 10) & 0x000F000F000F000Full;  // lane / 10
    x = h | ((x - 10 * h) << 8);
    x |= 0x3030303030303030ull;
    if constexpr (std::endian::native == std::endian::big) x = __builtin_bswap64(x);
    std::memcpy(to, &x, 8);
  };
  if (digits <= 8) {
    eight(static_cast<std::uint32_t>(q), places + 9);
  } else {
    places[0] = static_cast<char>('0' + q / 10000000000000000ull);
    const std::uint64_t rest = q % 10000000000000000ull;
    eight(static_cast<std::uint32_t>(rest / 100000000u), places + 1);
    eight(static_cast<std::uint32_t>(rest % 100000000u), places + 9);
  }
  const char* digits_text = places + (17 - digits);
  *p++ = digits_text[0];
  if (digits > 1) {
    *p++ = '.';
    std::memcpy(p, digits_text + 1, static_cast<std::size_t>(digits - 1));
    p += digits - 1;
  }
  *p++ = 'e';
  *p++ = d < 0 ? '-' : '+';
  const int a = d < 0 ? -d : d;
  if (a >= 100) {
    *p++ = static_cast<char>('0' + a / 100);
  }
  *p++ = static_cast<char>('0' + (a / 10) % 10);
  *p++ = static_cast<char>('0' + a % 10);
  return p;
}

}  // namespace pendavg::io::detail
