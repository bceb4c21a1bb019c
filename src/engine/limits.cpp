// SPDX-License-Identifier: GPL-3.0-or-later
// The beta -> 0 limit of the double pendulum (paper eq. aveK1-beta0).
//
// beta -> 0: the Boltzmann factor drops out and t = phi2 - phi1 is uniform, so with
// q = 1 - mu2 cos^2 t (k^2 = mu2, k'^2 = mu1):
//   int_0^pi q^{1/2} = 2 E(k),  int_0^pi q^{-1/2} = 2 K(k),  int_0^pi q^{-3/2} = 2 E(k)/mu1,
// giving beta<K1> = (mu1/2) K/E, <x> = mu1 K/E, <x^2> = mu1. K and E are taken from Carlson's
// forms with the complementary parameter mu1 passed directly (detail/elliptic.hpp), so
// nothing is lost as mu1 -> 0, where k = sqrt(1 - mu1) would round mu1 away.
// (beta -> infinity, in closed form for any N, is low_temperature_limit_any in engine/torus.hpp.)
#include "engine/double_pendulum.hpp"

#include "engine/detail/elliptic.hpp"

namespace pendavg {

template <class Real>
Averages<Real> elliptic_high_temperature_limit(const Chain<Real>& chain, int digits) {
  if (chain.size() != 2) {
    throw invalid_input("the elliptic beta -> 0 limit is for N = 2 only, got N = " +
                        std::to_string(chain.size()));
  }
  check_digits<Real>(digits);
  const precision_guard<Real> precision(digits + guard_digits);
  const Real mu1 = chain.mass_fraction(0);
  const auto ell = detail::complete_elliptic_from_complement(mu1);
  const Real& K = ell.K;
  const Real& E = ell.E;
  const Real u = unit_roundoff<Real>();
  const Real x1 = mu1 * K / E;  // <tr X_1>
  const Real x2 = mu1;          // <(tr X_1)^2>
  Averages<Real> out;
  out.method = Method::high_temperature_limit;
  out.error_kind = ErrorKind::bound;
  out.work_unit = WorkUnit::terms;
  out.evaluations = 1;
  const Real k1 = x1 / 2, k2 = 1 - k1;
  // Boost's Carlson functions are accurate to a few ulp; allow 64 ulp.
  const Real err = 64 * u;
  constexpr ErrorKind bound = ErrorKind::bound;
  out.beta_kinetic = {{k1, err * k1, bound}, {k2, err * k1 + 2 * u, bound}};
  out.cos_angle = {{Real(0), Real(0), bound}, {Real(0), Real(0), bound}};
  out.beta2_kinetic_variance = {
      {Real(3) / 4 * x2 - x1 * x1 / 4, 4 * err, bound},
      {(1 - x1) + x1 * x1 / 2 + Real(3) / 4 * (x2 - x1 * x1), 4 * err, bound}};
  const Real ratio = k1 / k2;
  out.ratio = Estimate<Real>{ratio, ratio * 3 * err, bound};
  return out;
}

template Averages<double> elliptic_high_temperature_limit<double>(const Chain<double>&, int);
template Averages<mpfr_real> elliptic_high_temperature_limit<mpfr_real>(const Chain<mpfr_real>&,
                                                                        int);

}  // namespace pendavg
