// SPDX-License-Identifier: GPL-3.0-or-later
// src/cli/average_options.hpp -- the options of pendavg::average as the CLI spells them (--method,
// --digits, --tol, --samples, --shifts, --seed), shared by `average`, `limit` and `table`: the
// command line's texts handed to the front-end library's reader (src/io/requests.hpp), which
// names them with the CLI's "--".
#pragma once

#include "args.hpp"
#include "format.hpp"

#include "io/requests.hpp"

#include "pendavg/average.hpp"
#include "pendavg/microcanonical.hpp"

#include <array>
#include <span>
#include <string_view>

namespace pendavg::cli {

using io::hardware_threads;

/// Reads the options named in `read` (a subset of method, digits, tol, samples, shifts, seed)
/// into AverageOptions; absent ones keep their defaults (unset optionals).
AverageOptions parse_average_options(const Options& options, std::span<const std::string_view> read);

/// Every option parse_average_options reads.
inline constexpr std::array<std::string_view, 6> average_option_names{
    "method", "digits", "tol", "samples", "shifts", "seed"};

/// io::microcanonical_state with the CLI's spelling of the advice (--excitation).
template <class Real>
Real microcanonical_state(const Chain<Real>& chain, std::string_view state, std::string_view value,
                          std::string_view what, const MicrocanonicalOptions& options) {
  return io::microcanonical_state(chain, state, value, what, options, "--");
}

}  // namespace pendavg::cli
