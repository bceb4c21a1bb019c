// SPDX-License-Identifier: GPL-3.0-or-later
// src/io/exact_values.hpp -- the exact values beside a trajectory: the microcanonical averages
// at the run's initial state (NVE) or the canonical ones at its beta (Langevin), as `simulate`
// prints them and pendavg.simulate returns them (one implementation for the CLI and Python).
#pragma once

#include "pendavg/chain.hpp"
#include "pendavg/dynamics.hpp"

#include <string>
#include <vector>

namespace pendavg::io {

/// Exact values of the run's ensemble, per particle, in energy units.
struct ExactValues {
  std::vector<double> kinetic, kinetic_error, cos_angle, cos_angle_error;
  std::vector<double> variance, variance_error;  ///< Var K_i (energy units squared)
  double kinetic_canonical = 0, kinetic_canonical_error = 0;
  double excitation = 0;  ///< microcanonical: D = E - E_min of the initial state
  std::string method;
  /// What the errors promise: error_kind those of kinetic (as the library's error_kind), the
  /// others their own (a series' beta<K_i> error is a bound, its <cos phi_i> error an estimate).
  std::string error_kind, kinetic_canonical_error_kind, cos_angle_error_kind, variance_error_kind;
};

/// D = E - E_min of the state (phi, phidot) in the excitation form: its kinetic energy plus
/// U - U_min = sum_j 2 gamma_j sin^2(phi_j / 2), so a start near the bottom of the well keeps
/// its digits (E = K + U would lose them to the cancellation of U and E_min).
double initial_excitation(const Chain<double>& chain, const ChainState<double>& state,
                          const std::vector<double>& phi);

/// The microcanonical averages at excitation D (all cores).
ExactValues microcanonical_values(const Chain<double>& chain, double excitation);

/// The canonical averages at beta, per particle in energy units (all cores).
ExactValues canonical_values(const Chain<double>& chain, double beta);

}  // namespace pendavg::io
