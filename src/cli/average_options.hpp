// SPDX-License-Identifier: GPL-3.0-or-later
// src/cli/average_options.hpp -- the options of pendavg::average as the CLI spells them (--method,
// --digits, --tol, --samples, --shifts, --seed), shared by `average`, `limit` and `table`. Only
// the reading is here: which options a method accepts is the library's rule
// (pendavg::resolve_average_method), so the CLI cannot disagree with it.
#pragma once

#include "args.hpp"
#include "format.hpp"

#include "pendavg/average.hpp"
#include "pendavg/microcanonical.hpp"

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

/// The state `value` of the column or option `state` (energy or excitation), parsed and checked
/// against `chain` before any work: an excitation must be > 0, an energy above E_min (refused
/// with the valid range), and the run `options` select must be in the engine's domain
/// (check_microcanonical: e.g. the double range of the energy scale and the masses).
template <class Real>
Real microcanonical_state(const Chain<Real>& chain, std::string_view state, std::string_view value,
                          std::string_view what, const MicrocanonicalOptions& options) {
  const Real x = parse_real<Real>(value, what, Domain::any);
  if (state == "excitation") {
    if (!(x > 0))
      throw usage_error(std::string(what) + ": '" + std::string(value) +
                        "' must be > 0 (the excitation D = E - E_min; E_min = " +
                        decimal(minimum_energy(chain), 17) + " for this chain)");
  } else if (!(excitation_energy(chain, x) > 0)) {
    throw usage_error(std::string(what) + ": '" + std::string(value) +
                      "' is at or below the minimum energy E_min = " +
                      decimal(minimum_energy(chain), 17) +
                      " of this chain: give E > E_min (or --excitation D > 0)");
  }
  try {
    if (state == "excitation")
      check_microcanonical_excitation(chain, x, options);
    else
      check_microcanonical(chain, x, options);
  } catch (const invalid_input& bad) {
    throw usage_error(std::string(what) + " " + std::string(value) + ": " + bad.what());
  }
  return x;
}

/// OpenMP threads available to one call (1 without OpenMP).
int hardware_threads();

}  // namespace pendavg::cli
