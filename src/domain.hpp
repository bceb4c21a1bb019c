// SPDX-License-Identifier: GPL-3.0-or-later
// src/domain.hpp -- the one domain module: what every entry point (average in every method, the
// limits, the microcanonical averages, the series, simulate, poincare; and through them the
// sweeps' pre-check and the Python module) checks before any work, and what it checks of every
// result before it is returned.
//
// Why one module. The engines form products and ratios of the inputs -- the joints' stiffnesses
// alpha_j = beta g S_j l_j (S_j the tail masses; the last link too), the mass fractions
// m_i / M, the trace formula's pivot ratios up to M / m_min and their squares, the dynamics'
// frequencies sqrt(g S / (m l)) -- and a guard that computes such a product in the engine's own
// type can overflow (inf) or underflow (0) before it compares, while a guard that compares with
// `x > limit` lets a NaN through. So every scale is computed here as a base-2 logarithm, which
// is finite for every positive finite input of every number type (an MPFR exponent fits a
// double), and every comparison is written so that NaN is a refusal (`!(x <= limit)`).
//
// The result check is the last line of defence: a non-finite value or error is never returned
// (invalid_input instead), and in double a non-zero value below the normal range (which has
// lost digits, or underflowed to a subnormal) is refused with advice rather than printed.
#pragma once

#include "pendavg/average.hpp"
#include "pendavg/chain.hpp"
#include "pendavg/result.hpp"

#include <string>
#include <vector>

namespace pendavg::domain {

/// log2 |x| as a double for any finite non-zero x of any number type (-inf for 0, NaN for NaN).
template <class Real>
double log2_magnitude(const Real& x);

/// The scales the engines form from a chain (and a temperature), as base-2 logarithms.
struct ChainScales {
  double lightest_fraction = 0;   ///< log2(m_min / M)
  double heaviest_ratio = 0;      ///< log2(M / m_min)
  /// log2(alpha_j) = log2(beta g S_j l_j) for every link j (the last one too); -inf when g = 0
  /// or without beta. With no beta given, beta = 1.
  std::vector<double> stiffness;
  double largest_stiffness = 0;   ///< max_j of stiffness
  double total_stiffness = 0;     ///< log2(sum_j alpha_j)
  double shortest_length = 0, longest_length = 0;  ///< log2 of the extreme lengths
  double lightest_mass = 0, heaviest_mass = 0;     ///< log2 of the extreme masses
  double gravity = 0;                               ///< log2 g (-inf for g = 0)
};

template <class Real>
ChainScales chain_scales(const Chain<Real>& chain, const Real* beta);

/// log2 of double's smallest normal number, and of the largest total stiffness
/// sum_j alpha_j any double engine forms (<= 1e307: its small multiples stay finite).
inline constexpr double log2_double_min = -1022;
inline constexpr double log2_double_stiffness_max = 1019.8306210305521;  // log2(1e307)
/// The trace formula's pivots carry M / m_min and its square: finite in double up to 1e150.
inline constexpr double log2_double_trace_mass_ratio_max = 498.2892142331043;  // log2(1e150)

/// What every double engine needs of its inputs: the lightest mass fraction m_min / M in the
/// normal range and the potential's coefficients sum_j g S_j l_j (every link, the last one too)
/// at most 1e307; with beta (for the engines that form alpha_j at the given beta: transfer),
/// sum_j beta g S_j l_j at most 1e307 as well. `command` prefixes the
/// message. Throws invalid_input.
template <class Real>
void check_double_scales(const Chain<Real>& chain, const Real* beta, const char* command);

/// The trace formula in double (the torus, qmc and transfer methods, the limits of N >= 3 and
/// the beta -> infinity limit of any N): M / m_min <= 1e150. Throws invalid_input.
template <class Real>
void check_trace_formula_mass_range(const Chain<Real>& chain, const char* command);

/// The dynamics (simulate, poincare; double and long double): every mass, length and g > 0
/// within 1e-50..1e50, so that positions, momenta, tensions and frequencies stay normal
/// doubles. Throws invalid_input ("choose units nearer 1").
template <class Real>
void check_dynamics_scales(const Chain<Real>& chain, const char* command);

/// The dynamics' time step against the fastest motion (omega_i^2 = (T_i / l_i + T_{i+1} /
/// l_{i+1}) / m_i, the tensions up to g S_j plus the centrifugal share of `kinetic`): h omega > 1
/// is beyond the integrators' stability limit and refused, with the step that would do; a NaN
/// energy or frequency is refused too (it read as 0 once).
template <class Real>
/// `duration` over the advised step beyond `max_steps` (the run's cap) gives no --dt advice.
void check_stable_time_step(const Chain<Real>& chain, double time_step, long double kinetic,
                            const char* command, double duration, double max_steps);

/// "; request 17 or more digits (MPFR)" when the same chain and beta pass the MPFR checks of
/// `options.method` at 17 digits (so the advice is given only when it is true), else "".
std::string more_digits_advice(const Chain<double>& chain, const double* beta,
                               const AverageOptions& options);

/// The result check: every value and error finite; in double every non-zero value at least
/// 2^53 times the smallest normal double (nearer, terms of it pass through the subnormals and
/// lose digits), and no <cos phi_i> of 0 when `cos_positive` (g > 0: an underflow). Throws
/// invalid_input naming the command, the method and the observable, followed by `advice`
/// (e.g. more_digits_advice's).
template <class Real>
void check_result(const Averages<Real>& averages, const char* command,
                  const std::string& advice = "", bool cos_positive = false);

/// One finite check for the observables of other results (microcanonical, dynamics).
template <class Real>
void check_finite_estimate(const Estimate<Real>& e, const char* command, const char* what);
template <class Real>
void check_finite_value(const Real& x, const char* command, const char* what);

}  // namespace pendavg::domain
