// SPDX-License-Identifier: GPL-3.0-or-later
// engine/numerics/precision.hpp -- the engines' view of the number types: which Real is MPFR, its unit
// roundoff at the working precision, a guard for the entry points (and for the threads of a
// parallel region: MPFR's working precision is per thread), and the rounding of inputs to the
// working precision (include/pendavg/mpfr.hpp explains the working precision).
//
// The library is generic over the number type `Real`. Instantiated: double (the fast path,
// microseconds per parameter set), long double where an engine gains from it, and mpfr_real
// (Boost.Multiprecision's MPFR float, 16..1000 requested digits, computed at digits +
// guard_digits).
#pragma once

#include "pendavg/chain.hpp"
#include "pendavg/mpfr.hpp"

#include <boost/math/constants/constants.hpp>

#include <cmath>
#include <limits>
#include <optional>
#include <type_traits>
#include <vector>

namespace pendavg {

template <class Real>
inline constexpr bool is_mpfr_v = std::is_same_v<Real, mpfr_real>;

/// How operations of this thread mix MPFR values of several precisions while a
/// working_precision lives. preserve_related_precision (Boost's default, as the library has always
/// run): an operation computes at the largest precision among its operands and the default, and
/// a copy keeps its source's precision. The series and the Fourier moments rely on that: their
/// inputs keep the caller's precision while they run at another one. assume_uniform_precision
/// (every operation at the default) rounds them: it changed the last digit of 38-digit `pendavg
/// series` bounds, and was no faster (bench_double_pendulum, MPFR: +3%/+9% at 38/77 digits).
inline constexpr boost::multiprecision::variable_precision_options mpfr_precision_rule =
    boost::multiprecision::variable_precision_options::preserve_related_precision;

/// The entry points' guard: a working_precision for MPFR, nothing for other number types. MPFR's
/// working precision is per thread: a parallel region's threads each take one, of the digits
/// current_digits10<Real>() gave on the thread that starts the region.
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
        boost::multiprecision::detail::digits10_2_2(mpfr_real::thread_default_precision()));
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
    return static_cast<int>(mpfr_real::thread_default_precision());
  } else {
    return std::numeric_limits<Real>::digits10 + 1;
  }
}

/// x rounded to the working precision (MPFR: an input of a higher precision would make every
/// operation it enters compute at that precision, and one of a lower precision would carry fewer
/// digits than the run's); x itself otherwise.
template <class Real>
Real at_working_precision(const Real& x) {
  if constexpr (is_mpfr_v<Real>) {
    return Real(x, mpfr_real::thread_default_precision());
  } else {
    return x;
  }
}

/// The chain with every parameter rounded to the working precision (see at_working_precision);
/// in a hardware type the chain itself (a reference: no copy).
template <class Real>
decltype(auto) at_working_precision(const Chain<Real>& chain) {
  if constexpr (is_mpfr_v<Real>) {
    std::vector<Real> masses, lengths;
    masses.reserve(chain.size());
    lengths.reserve(chain.size());
    for (std::size_t i = 0; i < chain.size(); ++i) {
      masses.push_back(at_working_precision(chain.mass(i)));
      lengths.push_back(at_working_precision(chain.length(i)));
    }
    return Chain<Real>(std::move(masses), std::move(lengths),
                       at_working_precision(chain.gravity()));
  } else {
    return (chain);
  }
}

namespace detail {

/// pi at the working precision of `Real`.
template <class Real>
Real pi() {
  return boost::math::constants::pi<Real>();
}

}  // namespace detail

}  // namespace pendavg
