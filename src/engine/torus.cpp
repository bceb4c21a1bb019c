// SPDX-License-Identifier: GPL-3.0-or-later
// Explicit instantiations of the any-N torus and QMC engines (engine/torus.hpp).
#include "engine/torus.hpp"

#include <boost/math/distributions/students_t.hpp>

namespace pendavg {

double qmc_default_sigmas(std::size_t shifts) {
  if (shifts < 2) throw invalid_input("qmc_default_sigmas: at least 2 shifts");
  const boost::math::students_t_distribution<double> t(static_cast<double>(shifts - 1));
  return boost::math::quantile(boost::math::complement(t, 0.0005));
}

#define PENDAVG_TORUS_INSTANTIATE(Real)                                                  \
  template Averages<Real> torus_average<Real>(const Chain<Real>&, const Real&,           \
                                              const TorusOptions&);                      \
  template Averages<Real> qmc_average<Real>(const Chain<Real>&, const Real&,             \
                                            const QmcOptions&);                          \
  template Averages<Real> high_temperature_limit_any<Real>(                              \
      const Chain<Real>&, const TorusOptions&, const QmcOptions&, std::size_t);          \
  template Averages<Real> low_temperature_limit_any<Real>(const Chain<Real>&);
PENDAVG_TORUS_INSTANTIATE(double)
PENDAVG_TORUS_INSTANTIATE(long double)
PENDAVG_TORUS_INSTANTIATE(mpfr_real)
#undef PENDAVG_TORUS_INSTANTIATE

}  // namespace pendavg
