// SPDX-License-Identifier: GPL-3.0-or-later
// Explicit instantiations of the QMC engine (engine/qmc/qmc.hpp) and its default error
// multiplier.
#include "engine/qmc/qmc.hpp"

#include <boost/math/distributions/students_t.hpp>

namespace pendavg {

double qmc_default_sigmas(std::size_t shifts) {
  if (shifts < 2) throw invalid_input("qmc_default_sigmas: at least 2 shifts");
  const boost::math::students_t_distribution<double> t(static_cast<double>(shifts - 1));
  return boost::math::quantile(boost::math::complement(t, 0.0005));
}

#define PENDAVG_QMC_INSTANTIATE(Real)                                                    \
  template Averages<Real> qmc_average<Real>(const Chain<Real>&, const Real&,              \
                                            const QmcOptions&);
PENDAVG_QMC_INSTANTIATE(double)
PENDAVG_QMC_INSTANTIATE(long double)
PENDAVG_QMC_INSTANTIATE(mpfr_real)
#undef PENDAVG_QMC_INSTANTIATE

}  // namespace pendavg
