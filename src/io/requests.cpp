// SPDX-License-Identifier: GPL-3.0-or-later
// src/io/requests.cpp -- see requests.hpp.
#include "io/requests.hpp"

#include <algorithm>
#include <string>

#if defined(_OPENMP)
#include <omp.h>
#endif

namespace pendavg::io {

AverageOptions parse_average_options(const AverageOptionTexts& texts, std::string_view prefix) {
  const auto name = [&](std::string_view field) { return std::string(prefix) + std::string(field); };
  AverageOptions out;
  if (texts.method) out.method = parse_average_method(std::string(*texts.method).c_str());
  if (texts.digits) out.digits = parse_digits(*texts.digits, name("digits"));
  if (texts.tol) {
    // no advice to use more digits: MPFR helps physical inputs, not a tolerance
    out.tolerance = parse_real<double>(*texts.tol, name("tol"), Domain::positive, false);
    if (!(*out.tolerance < 1))
      throw bad_input(name("tol") + ": " + in_quotes(*texts.tol) + " must be < 1");
  }
  // The library checks the ranges of these for the method that runs.
  if (texts.samples)
    out.samples =
        static_cast<std::size_t>(parse_integer(*texts.samples, name("samples"), 1, 1L << 40));
  if (texts.shifts)
    out.shifts =
        static_cast<std::size_t>(parse_integer(*texts.shifts, name("shifts"), 1, 1L << 40));
  if (texts.seed) out.seed = parse_unsigned(*texts.seed, name("seed"));
  return out;
}

int hardware_threads() {
#if defined(_OPENMP)
  return std::max(1, omp_get_max_threads());
#else
  return 1;
#endif
}

}  // namespace pendavg::io
