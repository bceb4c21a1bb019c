// src/cli/average_options.hpp -- the options of pendavg::average as the CLI spells them (--method,
// --digits, --tol, --samples, --shifts, --seed), shared by `average`, `limit` and `table`. Only
// the reading is here: which options a method accepts is the library's rule
// (pendavg::resolve_average_method), so the CLI cannot disagree with it.
#pragma once

#include "args.hpp"

#include "pendavg/average.hpp"

#include <array>
#include <span>
#include <string_view>

namespace pendavg::cli {

/// Reads the options named in `read` (a subset of method, digits, tol, samples, shifts, seed)
/// into AverageOptions; absent ones keep their defaults (unset optionals).
AverageOptions parse_average_options(const Options& options, std::span<const std::string_view> read);

/// Every option parse_average_options reads.
inline constexpr std::array<std::string_view, 6> average_option_names{
    "method", "digits", "tol", "samples", "shifts", "seed"};

/// OpenMP threads available to one call (1 without OpenMP).
int hardware_threads();

}  // namespace pendavg::cli
