// SPDX-License-Identifier: GPL-3.0-or-later
// Explicit instantiations of the torus engine (engine/torus/torus.hpp).
#include "engine/torus/torus.hpp"

namespace pendavg {

#define PENDAVG_TORUS_INSTANTIATE(Real)                                                  \
  template Averages<Real> torus_average<Real>(const Chain<Real>&, const Real&,           \
                                              const TorusOptions&);
PENDAVG_TORUS_INSTANTIATE(double)
PENDAVG_TORUS_INSTANTIATE(long double)
PENDAVG_TORUS_INSTANTIATE(mpfr_real)
#undef PENDAVG_TORUS_INSTANTIATE

}  // namespace pendavg
