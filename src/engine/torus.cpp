// Explicit instantiations of the any-N torus and QMC engines (engine/torus.hpp).
#include "engine/torus.hpp"

namespace pendavg {

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
