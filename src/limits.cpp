// The beta -> 0 and beta -> infinity limits of the double pendulum (paper eq. aveK1-beta0).
//
// beta -> 0: the Boltzmann factor drops out and t = phi2 - phi1 is uniform, so with
// q = 1 - mu2 cos^2 t (k^2 = mu2, k'^2 = mu1):
//   int_0^pi q^{1/2} = 2 E(k),  int_0^pi q^{-1/2} = 2 K(k),  int_0^pi q^{-3/2} = 2 E(k)/mu1,
// giving beta<K1> = (mu1/2) K/E, <x> = mu1 K/E, <x^2> = mu1. K and E are taken from Carlson's
// forms with the complementary parameter mu1 passed directly (detail/elliptic.hpp), so
// nothing is lost as mu1 -> 0, where k = sqrt(1 - mu1) would round mu1 away.
// beta -> infinity: the chain hangs straight down, tr X_i(0) = 1, so beta<K_i> = 1/2,
// <cos phi_i> = 1 and beta^2 Var K_i = 1/2 (X_i has rank one at phi = 0).
#include "pendavg/double_pendulum.hpp"

#include "pendavg/detail/elliptic.hpp"


namespace pendavg {

template <class Real>
Averages<Real> high_temperature_limit(const Chain<Real>& chain, int digits) {
  if (chain.size() != 2) {
    throw invalid_input("the beta -> 0 limit is implemented for N = 2 only, got N = " +
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
  out.evaluations = 1;
  const Real k1 = x1 / 2, k2 = 1 - k1;
  // Boost's Carlson functions are accurate to a few ulp; allow 64 ulp.
  const Real err = 64 * u;
  out.beta_kinetic = {k1, k2};
  out.beta_kinetic_error = {err * k1, err * k1 + 2 * u};
  out.cos_angle = {Real(0), Real(0)};
  out.cos_angle_error = {Real(0), Real(0)};
  out.beta2_kinetic_variance = {Real(3) / 4 * x2 - x1 * x1 / 4,
                                (1 - x1) + x1 * x1 / 2 + Real(3) / 4 * (x2 - x1 * x1)};
  out.beta2_kinetic_variance_error = {4 * err, 4 * err};
  out.ratio = k1 / k2;
  out.ratio_error = out.ratio * 3 * err;
  return out;
}

template <class Real>
Averages<Real> low_temperature_limit(const Chain<Real>& chain) {
  const std::size_t N = chain.size();
  Averages<Real> out;
  out.method = Method::low_temperature_limit;
  out.evaluations = 0;
  out.beta_kinetic.assign(N, Real(1) / 2);
  out.beta_kinetic_error.assign(N, Real(0));
  out.cos_angle.assign(N, Real(1));
  out.cos_angle_error.assign(N, Real(0));
  out.beta2_kinetic_variance.assign(N, Real(1) / 2);
  out.beta2_kinetic_variance_error.assign(N, Real(0));
  out.ratio = 1;
  out.ratio_error = 0;
  return out;
}

template Averages<double> high_temperature_limit<double>(const Chain<double>&, int);
template Averages<mpfr_real> high_temperature_limit<mpfr_real>(const Chain<mpfr_real>&, int);
template Averages<double> low_temperature_limit<double>(const Chain<double>&);
template Averages<mpfr_real> low_temperature_limit<mpfr_real>(const Chain<mpfr_real>&);

}  // namespace pendavg
