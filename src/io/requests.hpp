// SPDX-License-Identifier: GPL-3.0-or-later
// src/io/requests.hpp -- a front end's request to the library, read and checked in one place:
// the options of pendavg::average (method, digits, tol, samples, shifts, seed; shared by the
// CLI's `average`, `limit` and `table` and by Python's average, sweep, limit and
// microcanonical), the microcanonical state, and the threads one call may use. Only the reading
// is here: which options a method accepts is the library's rule
// (pendavg::resolve_average_method), so no front end can disagree with it.
//
// Fields are named without a front end's spelling: `prefix` spells them in messages (the CLI
// "--", so "--tol: '1' must be < 1"; Python "", so "tol: '1' must be < 1").
#pragma once

#include "io/number_text.hpp"
#include "io/parse.hpp"

#include "pendavg/average.hpp"
#include "pendavg/microcanonical.hpp"

#include <optional>
#include <string>
#include <string_view>

namespace pendavg::io {

/// The options of pendavg::average as a front end received them: each the text given, or
/// absent (the library's default).
struct AverageOptionTexts {
  std::optional<std::string_view> method, digits, tol, samples, shifts, seed;
};

/// Reads `texts` into AverageOptions (absent ones keep their defaults: unset optionals). Throws
/// bad_input (or the library's invalid_input for an unknown method) naming the field as
/// prefix + name.
AverageOptions parse_average_options(const AverageOptionTexts& texts, std::string_view prefix);

/// The microcanonical state `value` of `state` (energy or excitation), parsed and checked
/// against `chain` before any work: an excitation must be > 0, an energy above E_min (refused
/// with the valid range), and the run `options` select must be in the engine's domain
/// (check_microcanonical: e.g. the double range of the energy scale and the masses). `what`
/// names the value in messages (the CLI's --energy, a cases file's column energy, Python's
/// energy); `prefix` spells the other state's option in the advice "(or <prefix>excitation ...)".
template <class Real>
Real microcanonical_state(const Chain<Real>& chain, std::string_view state, std::string_view value,
                          std::string_view what, const MicrocanonicalOptions& options,
                          std::string_view prefix) {
  const Real x = parse_real<Real>(value, what, Domain::any);
  if (state == "excitation") {
    if (!(x > 0))
      throw bad_input(std::string(what) + ": " + in_quotes(value) +
                      " must be > 0 (the excitation D = E - E_min; E_min = " +
                      decimal(minimum_energy(chain), 17) + " for this chain)");
  } else if (!(excitation_energy(chain, x) > 0)) {
    throw bad_input(std::string(what) + ": " + in_quotes(value) +
                    " is at or below the minimum energy E_min = " +
                    decimal(minimum_energy(chain), 17) + " of this chain: give E > E_min (or " +
                    std::string(prefix) + "excitation D > 0)");
  }
  try {
    if (state == "excitation")
      check_microcanonical_excitation(chain, x, options);
    else
      check_microcanonical(chain, x, options);
  } catch (const invalid_input& bad) {
    throw bad_input(std::string(what) + " " + std::string(value) + ": " + bad.what());
  }
  return x;
}

/// OpenMP threads available to one call (1 without OpenMP).
int hardware_threads();

}  // namespace pendavg::io
