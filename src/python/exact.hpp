// SPDX-License-Identifier: GPL-3.0-or-later
// src/python/exact.hpp -- an MPFR number's exact binary value, kept as plain data (made without
// the GIL, on the thread that computed it) and turned into an mpmath.mpf later (in Python, with
// the GIL, needing no MPFR precision): mantissa * 2^exponent, mantissa an integer in hex.
#pragma once

#include "pendavg/mpfr.hpp"

#include <gmp.h>
#include <mpfr.h>

#include <string>

namespace pendavg::python {

struct ExactNumber {
  std::string mantissa = "0";  ///< signed integer, base 16
  long exponent = 0;
  double rounded = 0;          ///< the value in double (also for nan and inf)
  bool finite = true;
};

inline ExactNumber exact_number(const mpfr_real& x) {
  ExactNumber out;
  const mpfr_srcptr p = x.backend().data();
  out.rounded = mpfr_get_d(p, MPFR_RNDN);
  if (!mpfr_number_p(p)) {
    out.finite = false;
    return out;
  }
  if (mpfr_zero_p(p)) return out;
  mpz_t mantissa;
  mpz_init(mantissa);
  out.exponent = static_cast<long>(mpfr_get_z_2exp(mantissa, p));
  char* digits = mpz_get_str(nullptr, 16, mantissa);
  out.mantissa = digits;
  void (*release)(void*, size_t) = nullptr;
  mp_get_memory_functions(nullptr, nullptr, &release);
  release(digits, out.mantissa.size() + 1);
  mpz_clear(mantissa);
  return out;
}

}  // namespace pendavg::python
