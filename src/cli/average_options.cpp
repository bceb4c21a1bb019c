// SPDX-License-Identifier: GPL-3.0-or-later
// src/cli/average_options.cpp -- see average_options.hpp.
#include "average_options.hpp"

#include <algorithm>
#include <string>
#include <utility>

#if defined(_OPENMP)
#include <omp.h>
#endif

namespace pendavg::cli {

AverageOptions parse_average_options(const Options& options,
                                     std::span<const std::string_view> read) {
  const auto reads = [&](std::string_view name) {
    return std::ranges::find(read, name) != read.end() && options.has(name);
  };
  AverageOptions out;
  if (reads("method")) out.method = parse_average_method(std::string(options.required("method")).c_str());
  if (reads("digits")) out.digits = parse_digits(options.required("digits"));
  if (reads("tol")) {
    const std::string_view text = options.required("tol");
    out.tolerance = parse_real<double>(text, "--tol", Domain::positive);
    if (!(*out.tolerance < 1)) throw usage_error("--tol: '" + std::string(text) + "' must be < 1");
  }
  // The library checks the ranges of these for the method that runs.
  if (reads("samples"))
    out.samples = static_cast<std::size_t>(
        parse_integer(options.required("samples"), "--samples", 1, 1L << 40));
  if (reads("shifts"))
    out.shifts = static_cast<std::size_t>(
        parse_integer(options.required("shifts"), "--shifts", 1, 1L << 40));
  if (reads("seed")) out.seed = parse_unsigned(options.required("seed"), "--seed");
  return out;
}

int hardware_threads() {
#if defined(_OPENMP)
  return std::max(1, omp_get_max_threads());
#else
  return 1;
#endif
}

}  // namespace pendavg::cli
