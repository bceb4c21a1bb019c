// SPDX-License-Identifier: GPL-3.0-or-later
// The limits of engine/limits/limits.hpp: the elliptic beta -> 0 limit of the double pendulum,
// and the explicit instantiations of the any-N limits (double, long double, mpfr_real).
//
// Why Carlson's forms of the complementary parameter: K and E are taken with mu1 = k'^2 passed
// directly (numerics/elliptic.hpp), so nothing is lost as mu1 -> 0, where k = sqrt(1 - mu1)
// would round mu1 away.
#include "engine/limits/limits.hpp"

#include "engine/double_pendulum/double_pendulum.hpp"

#include "engine/numerics/elliptic.hpp"

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

#define PENDAVG_LIMITS_INSTANTIATE(Real)                                                 \
  template Averages<Real> high_temperature_limit_any<Real>(                              \
      const Chain<Real>&, const TorusOptions&, const QmcOptions&, std::size_t);          \
  template Averages<Real> low_temperature_limit_any<Real>(const Chain<Real>&);
PENDAVG_LIMITS_INSTANTIATE(double)
PENDAVG_LIMITS_INSTANTIATE(long double)
PENDAVG_LIMITS_INSTANTIATE(mpfr_real)
#undef PENDAVG_LIMITS_INSTANTIATE

}  // namespace pendavg
