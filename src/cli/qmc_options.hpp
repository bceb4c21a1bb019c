// src/cli/qmc_options.hpp -- the QMC options shared by `average` and `table`: --samples (lattice
// points per shift), --shifts and --seed, validated the same way by both commands.
#pragma once

#include "args.hpp"

#include "pendavg/torus.hpp"

#include <cstddef>
#include <string>
#include <vector>

namespace pendavg::cli {

/// --samples: lattice points per shift, the powers of two of the built-in lattice rows.
inline constexpr std::size_t min_samples = std::size_t(1) << detail::qmc::lattice_table_min_log2;
inline constexpr std::size_t max_samples = std::size_t(1) << detail::qmc::lattice_rows_max_log2;
inline constexpr std::size_t default_samples =
    std::size_t(1) << detail::qmc::lattice_table_max_log2;
/// --shifts: independent random shifts of the lattice.
inline constexpr long min_shifts = 4, max_shifts = 1024;

/// Reads --samples, --shifts and --seed into `qmc` (samples default to default_samples) and
/// returns the names of those that were given, so that a command can refuse them when no
/// QMC runs. Throws usage_error for a value out of range or a sample count not a power of two.
std::vector<std::string> parse_qmc_options(const Options& options, QmcOptions& qmc);

}  // namespace pendavg::cli
