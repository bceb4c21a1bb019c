// SPDX-License-Identifier: GPL-3.0-or-later
// src/cli/simulate.hpp -- `pendavg simulate` and `pendavg poincare` (dynamics, issue 4).
#pragma once

#include "args.hpp"

#include <array>
#include <string>
#include <string_view>

namespace pendavg::cli {

extern const std::string_view simulate_usage;
extern const std::string_view poincare_usage;

inline constexpr std::array<std::string_view, 20> simulate_options{
    "masses",     "lengths", "g",    "theta",  "phi",      "phidot",     "time",
    "dt",         "burn-in", "integrator", "thermostat", "beta", "friction", "seed",
    "exact",      "format",  "trajectory", "every", "replicas", "perturb"};
inline constexpr std::array<std::string_view, 8> poincare_options{
    "masses", "lengths", "g", "energy", "orbits", "points", "dt", "output"};

/// Runs a trajectory and returns its report (JSON or CSV) for stdout.
std::string simulate_command(const Options& options);

/// Computes the section and returns the CSV (or "" after writing --output atomically).
std::string poincare_command(const Options& options);

}  // namespace pendavg::cli
