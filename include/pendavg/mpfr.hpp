// SPDX-License-Identifier: GPL-3.0-or-later
// pendavg/mpfr.hpp -- pendavg in multiprecision: the MPFR number type, its working precision,
// and the library's explicit instantiations for it.
//
// Include this header to call the library with Real = mpfr_real (17..1000 significant digits;
// 16 digits run in double). A double-only program does not need it and does not pull in
// Boost.Multiprecision. pendavg::pendavg links MPFR and GMP for you.
//
// Working precision. Boost.Multiprecision (>= 1.77) keeps the default precision of new mpfr_real
// values, and how operations mix precisions, per thread. Every pendavg entry point that is given
// digits (AverageOptions::digits, MicrocanonicalOptions::digits > 0, series_convergence's digits,
// ...) sets its own thread's precision (the requested digits plus guard_digits, and the precision
// rules below), rounds its inputs to it, and restores the thread's settings when it returns. So
// an MPFR call works from any thread without the caller holding anything, threads at different
// digits run truly concurrently (no lock, no waiting), and a call gives the same bits on any
// thread, alone or beside others. An entry point that is not given digits (digits = 0,
// minimum_energy, the Chain constructor, ...) computes at this thread's current precision.
//
// working_precision sets this thread's precision for a scope: a convenience for building inputs.
// An input is taken as the value it holds; to have decimal inputs such as 0.1 exact to the digits
// asked for, construct them at a precision of at least digits + guard_digits (e.g. under
// working_precision(digits + pendavg::guard_digits)), as a value built at Boost's default of 50
// digits carries only those.
#pragma once

#include "pendavg/export.hpp"
#include "pendavg/average.hpp"
#include "pendavg/dynamics.hpp"
#include "pendavg/microcanonical.hpp"
#include "pendavg/series.hpp"
#include "pendavg/trace_formula.hpp"

#include <boost/multiprecision/mpfr.hpp>

namespace pendavg {

/// Boost.Multiprecision's variable-precision MPFR float.
using mpfr_real = boost::multiprecision::mpfr_float;

/// RAII: new mpfr_real values of this thread have `digits10` decimal digits while the object
/// lives, and operations on this thread mix precisions by pendavg's rule (Boost's
/// preserve_related_precision: an operation computes at the largest precision among its operands
/// and the thread's default). The destructor restores this thread's previous precision and rule.
/// Affects no other thread; nests. Throws std::invalid_argument for digits10 < 1.
class PENDAVG_EXPORT working_precision {
 public:
  explicit working_precision(int digits10);
  ~working_precision();
  working_precision(const working_precision&) = delete;
  working_precision& operator=(const working_precision&) = delete;

 private:
  unsigned previous_digits10_;
  boost::multiprecision::variable_precision_options previous_options_;
};

/// The decimal digits of new mpfr_real values on this thread (its current precision).
PENDAVG_EXPORT int current_mpfr_digits();

// Explicit instantiations for mpfr_real live in the library (src/).
extern template class PENDAVG_EXPORT Chain<mpfr_real>;
extern template PENDAVG_EXPORT Averages<mpfr_real> average<mpfr_real>(const Chain<mpfr_real>&,
                                                                      const mpfr_real&,
                                                                      const AverageOptions&);
extern template PENDAVG_EXPORT Averages<mpfr_real> average<mpfr_real>(const Chain<mpfr_real>&,
                                                                      const mpfr_real&,
                                                                      const AverageOptions&,
                                                                      AverageWorkspace<mpfr_real>&);
extern template class PENDAVG_EXPORT AverageWorkspace<mpfr_real>;
extern template PENDAVG_EXPORT void check_average<mpfr_real>(const Chain<mpfr_real>&,
                                                             const mpfr_real&,
                                                             const AverageOptions&);
extern template PENDAVG_EXPORT Averages<mpfr_real> high_temperature_limit<mpfr_real>(
    const Chain<mpfr_real>&, const AverageOptions&);
extern template PENDAVG_EXPORT Averages<mpfr_real> low_temperature_limit<mpfr_real>(
    const Chain<mpfr_real>&, const AverageOptions&);
extern template PENDAVG_EXPORT void check_beta<mpfr_real>(const mpfr_real&);
extern template PENDAVG_EXPORT void check_digits<mpfr_real>(int);
extern template PENDAVG_EXPORT std::vector<SeriesRow<mpfr_real>> series_convergence<mpfr_real>(
    const Chain<mpfr_real>&, const mpfr_real&, int, std::size_t, const RunControl&);
extern template class PENDAVG_EXPORT TraceWorkspace<mpfr_real>;
extern template PENDAVG_EXPORT MicrocanonicalAverages<mpfr_real> microcanonical_average<mpfr_real>(
    const Chain<mpfr_real>&, const mpfr_real&, const MicrocanonicalOptions&);
extern template PENDAVG_EXPORT MicrocanonicalAverages<mpfr_real>
microcanonical_average_excitation<mpfr_real>(const Chain<mpfr_real>&, const mpfr_real&,
                                             const MicrocanonicalOptions&);
extern template PENDAVG_EXPORT mpfr_real minimum_energy<mpfr_real>(const Chain<mpfr_real>&);
extern template PENDAVG_EXPORT mpfr_real excitation_energy<mpfr_real>(const Chain<mpfr_real>&,
                                                                      const mpfr_real&);

}  // namespace pendavg
