// SPDX-License-Identifier: GPL-3.0-or-later
// src/cli/table.hpp -- `pendavg table`: parameter sweeps written as one CSV (atomically).
#pragma once

#include "args.hpp"

#include <array>
#include <string>
#include <string_view>

namespace pendavg::cli {

extern const std::string_view table_usage;

inline constexpr std::array<std::string_view, 17> table_options{
    "beta",    "mu1",    "l1",   "l2",     "g",      "chain",  "digits",     "method",
    "tol",     "samples", "shifts", "seed", "output", "resume", "energy", "excitation", "shard"};

/// Runs `pendavg table`: streams the CSV to stdout, or to --output (or --resume) through a
/// temporary file in the same directory; returns "".
std::string table_command(const Options& options);

/// 1 - x for a strict positive decimal x < 1, exactly, as a plain decimal string ("0.95" for
/// "0.05", "0.9999" for "1e-4"). Throws usage_error naming `what` when x >= 1.
std::string one_minus_decimal(std::string_view x, std::string_view what);

}  // namespace pendavg::cli
