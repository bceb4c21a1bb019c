// SPDX-License-Identifier: GPL-3.0-or-later
// pendavg/mpfr.hpp -- pendavg in multiprecision: the MPFR number type, its working precision,
// and the library's explicit instantiations for it.
//
// Include this header to call the library with Real = mpfr_real (17..1000 significant digits;
// 16 digits run in double). A double-only program does not need it and does not pull in
// Boost.Multiprecision. pendavg::pendavg links MPFR and GMP for you.
//
// Working precision. Boost 1.74 keeps the default precision of every new mpfr_real in one
// process-wide variable. working_precision makes that variable safe to share between threads:
// it is a shared lock on it. Threads that ask for the same precision run together; a thread that
// asks for another one waits until the threads at the current precision have left (first come,
// first served), and a nested working_precision of another precision on the same thread leaves
// the outer one while it lives. So concurrent calls give the same bits as the same calls made one
// after another, whatever their threads and digits.
//
// Every pendavg entry point that computes in MPFR takes its own working_precision (the requested
// digits plus guard digits) and rounds its inputs to it. Construct the inputs under a
// working_precision of at least that many digits (e.g. working_precision(digits +
// pendavg::guard_digits)), so that decimal inputs such as 0.1 are exact to the digits asked for.
// Code of your own that creates mpfr_real values while other threads run pendavg in MPFR must hold
// a working_precision too. Do not hold one around an OpenMP region whose threads take one: they
// would wait for each other.
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

/// RAII: this thread computes at `digits10` decimal digits while the object lives (see the
/// header comment). Nested objects of the same precision cost nothing.
class PENDAVG_EXPORT working_precision {
 public:
  explicit working_precision(int digits10);
  ~working_precision();
  working_precision(const working_precision&) = delete;
  working_precision& operator=(const working_precision&) = delete;
};

/// The decimal digits of new mpfr_real values on this thread (the working precision, when one is
/// held).
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
