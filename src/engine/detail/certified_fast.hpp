// SPDX-License-Identifier: GPL-3.0-or-later
// engine/detail/certified_fast.hpp -- the certified N = 2 engine's fast path for double inputs
// and double results (engine/certified/fast_double.cpp; the method and its bounds are
// engine/certified.md, Sec. 10): the same 1-D reduction, rows and tail bounds as the Arb engine
// (engine/certified.cpp), evaluated in double-double ball arithmetic (a double-word midpoint and a
// double radius, both carried with proven error bounds) instead of Arb's balls. Declared for
// engine/certified.cpp, which tries it first for Real = double and falls back to Arb when it
// returns nothing, and for its tests. Only in builds with Arb (PENDAVG_HAS_ARB).
#pragma once

#include "pendavg/chain.hpp"

#include <array>
#include <cstddef>
#include <optional>
#include <vector>

namespace pendavg::certified_fast {

/// A ball: every point of [hi + lo - rad, hi + lo + rad] (exact reals), rad >= 0.
struct Enclosure {
  double hi = 0, lo = 0, rad = 0;
};

/// The seven observables of a certified N = 2 average: beta<K1>, beta<K2>, <K1>/<K2>,
/// <cos phi1>, <cos phi2>, beta^2 Var K1, beta^2 Var K2; and the Graf rows used.
struct FastResult {
  std::array<Enclosure, 7> observables;
  std::size_t rows = 0;
};

/// Which compiled body runs: the one the CPU allows (fma where it has fused multiply-adds),
/// or either on demand (tests; fma where the CPU lacks it is the caller's error, and in builds
/// without that variant nothing is returned).
enum class Variant { automatic, baseline, fma };

/// The certified averages of the double pendulum `chain` (N = 2) at `beta` > 0, every input taken
/// as the exact double it is; nothing (std::nullopt) when this path cannot certify every
/// observable to a relative radius of 2^-60 (then the caller runs the Arb engine). Never an
/// unproven bound: every returned ball contains the exact average.
std::optional<FastResult> fast_double_average(const Chain<double>& chain, double beta,
                                              Variant variant = Variant::automatic);

/// Parts, for the tests: e^{-a} I_m(a), m < count (count = 2: the low orders of the tail sums),
/// for the exact double a >= 0 (Sec. 10.2-10.3); the Fourier moment rows Q_k(1/2), Q_k(-1/2),
/// Q_k(-3/2), k < K, of mu1 = m1 / (m1 + m2) (Secs. 4, 10.4).
std::optional<std::vector<Enclosure>> fast_double_bessel(double a, std::size_t count,
                                                         Variant variant = Variant::automatic);
std::optional<std::array<std::vector<Enclosure>, 3>> fast_double_moments(
    double m1, double m2, std::size_t K, Variant variant = Variant::automatic);

/// Whether Variant::automatic runs the fma body on this CPU.
bool fast_double_has_fma();

/// Which compiled variant fast_double_average runs: "fma" (hardware fused multiply-add) or
/// "baseline" (Dekker's product), chosen once at run time.
const char* fast_double_variant();

/// The line of engine/certified/fast_double_body.inc whose check last refused a case on this
/// thread (0: none yet); for tests and diagnostics.
int fast_double_last_refusal();

}  // namespace pendavg::certified_fast
