// SPDX-License-Identifier: GPL-3.0-or-later
// engine/numerics/bessel.hpp -- exponentially scaled modified Bessel functions, generic over Real.
//
// What for: every Boltzmann weight of the pendulum is a product of I_k(alpha) factors with
// alpha = beta * (mass) * g * (length), which overflows double beyond alpha ~ 700. Everything
// here is scaled by exp(-x) so nothing overflows at any beta.
//
//  * scaled_bessel_i01(x)       -- e^{-x} I0(x) and e^{-x} I1(x), x >= 0. For double this is
//                                  GSL (gsl_sf_bessel_I0_scaled / I1_scaled). For MPFR no
//                                  library offers scaled I (MPFR has none; Boost's cyl_bessel_i
//                                  on mpfr_float is slow: README, Design notes, "Measurements
//                                  behind the design choices"), so the generic version
//                                  sums the power series (all terms positive) below
//                                  asymptotic_threshold(u) and the Hankel asymptotic series
//                                  above it, where its smallest term is below u.
//  * scaled_bessel_i_table(a,K) -- e^{-a} I_m(a), m = 0..K-1, by Miller's backward recurrence
//                                  normalised with the exact sum rule sum_m eps_m e^{-a}I_m(a)=1
//                                  (eps_0 = 1, eps_m = 2). One table per argument feeds Graf's
//                                  addition theorem and the paper's series
//                                  (src/engine/double_pendulum/README.md, 'Series').
//  * reduced_bessel_table(a,K)  -- f_k(a) = I_k(a)/a^k scaled by e^{-a}, k = 0..K-1, from the
//                                  backward recurrence f_{k-1} = a^2 f_{k+1} + 2k f_k (all terms
//                                  positive; exact at a = 0 where f_k = 1/(2^k k!)).
#pragma once

#include <cstddef>
#include <vector>

namespace pendavg {

template <class Real>
struct ScaledBesselI01 {
  Real i0e;  ///< e^{-x} I0(x)
  Real i1e;  ///< e^{-x} I1(x)
};

/// e^{-x} I0(x), e^{-x} I1(x) for x >= 0 at the current working precision.
template <class Real>
ScaledBesselI01<Real> scaled_bessel_i01(const Real& x);

/// The generic (series + asymptotic) implementation, also for double: a test oracle for GSL.
template <class Real>
ScaledBesselI01<Real> scaled_bessel_i01_generic(const Real& x);

/// e^{-x} I0(x), e^{-x} I1(x) for many x in one range [x_min, x_max] (MPFR only; x_min above
/// the Hankel threshold): Hankel's series in y = 1/x re-expanded about y0 = 1/x_max, cut where
/// the shifted tail over the range is below u/64. Over a narrow range (x_max - x_min << x_min,
/// e.g. the peak of the pendulum's weight at large beta) this takes far fewer terms than the
/// series itself: i0e = sqrt(y) inv_sqrt_two_pi sum_j c0[j] (y - y0)^j, i1e likewise with c1.
/// `valid` is false (use scaled_bessel_i01) when the range is not above the threshold.
template <class Real>
struct ScaledBesselI01Range {
  bool valid = false;
  Real y0, inv_sqrt_two_pi;
  std::vector<Real> c0, c1;
};
template <class Real>
ScaledBesselI01Range<Real> scaled_bessel_i01_range(const Real& x_min, const Real& x_max);

/// e^{-a} I_m(a) for m = 0 .. count-1 (a >= 0). Cost O(count + sqrt(a * digits) + a).
template <class Real>
std::vector<Real> scaled_bessel_i_table(const Real& a, std::size_t count);

/// Bound, in units of the roundoff, on the rounding error of entry m of
/// scaled_bessel_i_table(a, count) relative to the table's common scale: a common factor
/// error (the normalisation) is excluded, since it cancels in every ratio of Graf sums.
template <class Real>
double scaled_bessel_table_error_ulps(double a, std::size_t count, std::size_t m);

/// Recurrence steps scaled_bessel_i_table(a, count) takes at the current precision: `count`
/// for the forward recurrence, Miller's start index for the backward one (which starts up to
/// ~sqrt(a ln(1/u)) beyond the table). A cost estimate for callers choosing a method.
template <class Real>
std::size_t scaled_bessel_table_steps(double a, std::size_t count);

/// e^{-a} I_k(a) / a^k for k = 0 .. count-1 (a >= 0).
template <class Real>
std::vector<Real> reduced_bessel_table(const Real& a, std::size_t count);

}  // namespace pendavg
