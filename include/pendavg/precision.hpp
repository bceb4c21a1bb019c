// pendavg/precision.hpp -- number types and explicit working precision.
//
// The library is generic over the number type `Real`. Two types are instantiated:
//   * double          -- the fast path (microseconds per parameter set);
//   * mpfr_real       -- Boost.Multiprecision's variable-precision MPFR float, used for
//                        16..1000 requested digits.
// Precision is always an explicit argument (`digits`), never a hidden global: entry points
// that take `digits` install a `working_precision` guard for the duration of the call.
// Boost 1.74 keeps MPFR's default precision in one process-wide variable, so callers that
// run MPFR work on several threads must use one precision for all of them.
#pragma once

#include <boost/multiprecision/mpfr.hpp>

#include <cmath>
#include <limits>
#include <optional>
#include <type_traits>

namespace pendavg {

using mpfr_real = boost::multiprecision::mpfr_float;

template <class Real>
inline constexpr bool is_mpfr_v = std::is_same_v<Real, mpfr_real>;

/// Smallest and largest decimal digits a caller may request.
inline constexpr int min_digits = 16;
inline constexpr int max_digits = 1000;

/// Guard digits carried beyond the requested ones in every MPFR computation.
inline constexpr int guard_digits = 12;

/// RAII guard: sets the default MPFR precision (decimal digits) for the life of the object,
/// and restores the previous one afterwards. A no-op for `double`.
class working_precision {
 public:
  explicit working_precision(int digits10)
      : previous_(mpfr_real::default_precision()) {
    mpfr_real::default_precision(static_cast<unsigned>(digits10));
  }
  ~working_precision() { mpfr_real::default_precision(previous_); }
  working_precision(const working_precision&) = delete;
  working_precision& operator=(const working_precision&) = delete;

 private:
  unsigned previous_;
};

/// The entry points' guard: a working_precision for MPFR, nothing for other number types.
template <class Real>
class precision_guard {
 public:
  explicit precision_guard(int digits10) {
    if constexpr (is_mpfr_v<Real>) guard_.emplace(digits10);
  }

 private:
  std::optional<working_precision> guard_;
};

/// Unit roundoff of `Real` at the current working precision.
template <class Real>
Real unit_roundoff() {
  if constexpr (is_mpfr_v<Real>) {
    // 2^(1 - p) with p the current precision in bits.
    const long bits = static_cast<long>(
        boost::multiprecision::detail::digits10_2_2(mpfr_real::default_precision()));
    Real one = 1;
    return ldexp(one, static_cast<int>(1 - bits));
  } else {
    return std::numeric_limits<Real>::epsilon();
  }
}

/// Decimal digits carried by `Real` at the current working precision.
template <class Real>
int current_digits10() {
  if constexpr (is_mpfr_v<Real>) {
    return static_cast<int>(mpfr_real::default_precision());
  } else {
    return std::numeric_limits<Real>::digits10 + 1;
  }
}

}  // namespace pendavg
