// SPDX-License-Identifier: GPL-3.0-or-later
// engine/qmc/options.hpp -- the options of qmc_average (engine/qmc/qmc.hpp) and the default
// multiplier of its error bars.
#pragma once

#include "pendavg/average.hpp"
#include "pendavg/result.hpp"

#include <cstddef>
#include <cstdint>
#include <vector>

namespace pendavg {

/// The law qmc_average maps the lattice points to (engine/qmc/README.md, 'Proposal laws').
enum class QmcProposal {
  automatic,         ///< von_mises for N <= 4, pivot_sequential beyond
  pivot_sequential,  ///< root to tail, each angle's law includes its pivot factor of det A
  von_mises,         ///< independent von Mises laws; all of sqrt(det A) in the weight
};

/// Options of qmc_average.
struct QmcOptions {
  std::size_t points = std::size_t(1) << 14;  ///< lattice points per shift: 2^m, 2^10 <= . <= 2^20
  std::size_t shifts = 16;                    ///< independent random shifts (>= 4)
  std::uint64_t seed = 1;                     ///< the shifts come from std::mt19937_64(seed)
  /// error = sigmas * jackknife standard error; 0 (default): qmc_default_sigmas(shifts), the
  /// 99.9% two-sided Student-t quantile for shifts - 1 degrees of freedom (4.07 for 16 shifts).
  double sigmas = 0;
  int threads = 1;                            ///< OpenMP threads over shifts (double/long double)
  /// Optional generating vector for `points` points (one odd entry per particle); empty: the
  /// built-in table.
  std::vector<std::uint32_t> generating_vector;
  /// The law the points are mapped to: automatic (default), pivot_sequential or von_mises (the
  /// product of von Mises laws, sqrt(det A) left entirely to the weight).
  QmcProposal proposal = QmcProposal::automatic;
  /// Nodes of the tabulated conditional law per angle (pivot_sequential), >= 4.
  std::size_t proposal_grid = 32;
  /// Shares the shifts with other processes (pendavg/average.hpp, ShiftPartition; double only).
  const ShiftPartition* partition = nullptr;
  /// Progress (the fraction of shifts finished) and stop. A stop ends the run after the shifts
  /// running finish: with at least 2 shifts done their average is returned (interrupted = true,
  /// converged = false, the bars from the shifts done), otherwise `interrupted` is thrown. Not
  /// used with a partition (the parts must agree on the shifts).
  const RunControl* control = nullptr;
};

/// The 99.9% two-sided Student-t quantile for shifts - 1 degrees of freedom: the default error
/// multiplier of the QMC bars (engine/qmc/README.md, 'Error bar'). 4.0728 for 16 shifts.
double qmc_default_sigmas(std::size_t shifts);

}  // namespace pendavg
