// SPDX-License-Identifier: GPL-3.0-or-later
// tests/real_types.hpp -- the number types of the generic engines, for TEMPLATE_TEST_CASE: each
// type's precision inside a test (MPFR at test_digits, set for the test's scope by
// TypePrecision), its unit of accuracy, and the distance of a value from a reference computed
// at reference_digits (an independent method or a higher-precision run, never the same code at
// the same precision). Which engine is instantiated for which type: tests/README.md.
#pragma once

#include "engine/numerics/precision.hpp"
#include "pendavg/mpfr.hpp"

#include <cmath>
#include <limits>
#include <optional>

namespace pendavg::test {

/// The digits the MPFR cases of the default suite ask for: more than long double carries, few
/// enough to keep MPFR runs short.
inline constexpr int test_digits = 24;
/// The digits of the MPFR references the checks compare against (above test_digits).
inline constexpr int reference_digits = 40;

/// For the scope of a test: MPFR values are built and computed at test_digits + guard_digits
/// (what an entry point given test_digits runs at); nothing for double and long double.
template <class Real>
class TypePrecision {
 public:
  TypePrecision() {
    if constexpr (is_mpfr_v<Real>) guard_.emplace(test_digits + guard_digits);
  }

 private:
  std::optional<working_precision> guard_;
};

/// For the scope of a reference computation: reference_digits + guard_digits.
class ReferencePrecision {
 public:
  ReferencePrecision() : guard_(reference_digits + guard_digits) {}

 private:
  working_precision guard_;
};

/// The `digits` option an engine is given for this type: 0 (its native precision) for double
/// and long double, test_digits for MPFR.
template <class Real>
constexpr int digits_option() {
  return is_mpfr_v<Real> ? test_digits : 0;
}

/// One unit of the accuracy a type is asked for: its machine epsilon for double and long double,
/// 10^-test_digits (the requested digits) for MPFR. Tolerances are multiples of it.
template <class Real>
double unit() {
  if constexpr (is_mpfr_v<Real>) {
    return std::pow(10.0, -test_digits);
  } else {
    return static_cast<double>(std::numeric_limits<Real>::epsilon());
  }
}

/// |value - reference| / |scale|, computed at the reference's precision (exact for double and
/// long double values, which MPFR holds exactly).
template <class Real>
double relative_distance(const Real& value, const mpfr_real& reference, const mpfr_real& scale) {
  const ReferencePrecision precision;
  return static_cast<double>(abs(mpfr_real(value) - reference) / abs(scale));
}

/// |value - reference| / |reference|.
template <class Real>
double relative_distance(const Real& value, const mpfr_real& reference) {
  return relative_distance(value, reference, reference);
}

/// |value - reference|, as a double.
template <class Real>
double distance(const Real& value, const mpfr_real& reference) {
  const ReferencePrecision precision;
  return static_cast<double>(abs(mpfr_real(value) - reference));
}

/// A value of any of the types as a double (for messages and error bars).
template <class Real>
double as_double(const Real& x) {
  return static_cast<double>(x);
}

}  // namespace pendavg::test
