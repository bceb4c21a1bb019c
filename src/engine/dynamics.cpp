// Constrained symplectic dynamics of the N-link chain (include/pendavg/dynamics.hpp): states,
// observables and the workspace, and the run-time choice of the kernels' instruction set
// (src/engine/dynamics_kernels.cpp is compiled for baseline x86-64 and, where the compiler
// can, for x86-64-v3 = AVX2 + FMA, about twice as fast; the library runs on any x86-64 CPU).
#include "engine/dynamics_kernels.hpp"

#include <Eigen/Dense>

#include <cmath>
#include <cstdlib>
#include <cstring>
#include <string>

namespace pendavg {

namespace {

using std::abs;
using std::atan2;
using std::cos;
using std::sin;
using std::sqrt;

template <class Real>
void check_finite_vector(const std::vector<Real>& v, const char* what) {
  for (const Real& x : v)
    if (!std::isfinite(static_cast<double>(x)))
      throw invalid_input(std::string(what) + " must be finite");
}

}  // namespace

// ---------------------------------------------------------------- states

template <class Real>
ChainState<Real> state_from_angles(const Chain<Real>& chain, const std::vector<Real>& phi,
                                   const std::vector<Real>& phidot) {
  const std::size_t n = chain.size();
  if (phi.size() != n) throw invalid_input("need one angle per particle");
  if (phidot.size() != n) throw invalid_input("need one angular velocity per particle");
  check_finite_vector(phi, "angles");
  check_finite_vector(phidot, "angular velocities");
  ChainState<Real> st;
  st.position.assign(2 * n, Real(0));
  st.momentum.assign(2 * n, Real(0));
  Real x = 0, y = 0, vx = 0, vy = 0;
  for (std::size_t i = 0; i < n; ++i) {
    const Real l = chain.length(i), s = sin(phi[i]), c = cos(phi[i]);
    x += l * s;
    y -= l * c;
    vx += l * c * phidot[i];
    vy += l * s * phidot[i];
    st.position[2 * i] = x;
    st.position[2 * i + 1] = y;
    st.momentum[2 * i] = chain.mass(i) * vx;
    st.momentum[2 * i + 1] = chain.mass(i) * vy;
  }
  return st;
}

template <class Real>
ChainState<Real> state_from_canonical(const Chain<Real>& chain, const std::vector<Real>& phi,
                                      const std::vector<Real>& p_phi) {
  const std::size_t n = chain.size();
  if (phi.size() != n || p_phi.size() != n)
    throw invalid_input("need one angle and one momentum per particle");
  check_finite_vector(phi, "angles");
  check_finite_vector(p_phi, "momenta");
  // A_jk = S_max(j,k) l_j l_k cos(phi_j - phi_k) (paper eq. a-ij); dense solve (setup only).
  using Matrix = Eigen::Matrix<Real, Eigen::Dynamic, Eigen::Dynamic>;
  using Vector = Eigen::Matrix<Real, Eigen::Dynamic, 1>;
  Matrix a(n, n);
  Vector rhs(n);
  for (std::size_t j = 0; j < n; ++j) {
    rhs(j) = p_phi[j];
    for (std::size_t k = 0; k < n; ++k)
      a(j, k) = chain.tail_mass(std::max(j, k)) * chain.length(j) * chain.length(k) *
                cos(phi[j] - phi[k]);
  }
  const Vector phidot = a.ldlt().solve(rhs);
  std::vector<Real> rates(n);
  for (std::size_t j = 0; j < n; ++j) rates[j] = phidot(j);
  return state_from_angles(chain, phi, rates);
}

template <class Real>
ChainObservables<Real> observables(const Chain<Real>& chain, const ChainState<Real>& st) {
  const std::size_t n = chain.size();
  ChainObservables<Real> o;
  o.phi.resize(n);
  o.phidot.resize(n);
  o.p_phi.resize(n);
  o.kinetic.resize(n);
  o.kinetic_canonical.resize(n);
  const std::vector<Real>& x = st.position;
  const std::vector<Real>& p = st.momentum;
  // Tail momenta P_i = sum_{k >= i} p_k: p_phi_i = l_i e_i . P_i, e_i = (cos phi_i, sin phi_i).
  Real px = 0, py = 0;
  std::vector<Real> tail_x(n), tail_y(n);
  for (std::size_t i = n; i-- > 0;) {
    px += p[2 * i];
    py += p[2 * i + 1];
    tail_x[i] = px;
    tail_y[i] = py;
  }
  Real xprev = 0, yprev = 0, vxprev = 0, vyprev = 0;
  o.kinetic_total = 0;
  o.potential = 0;
  for (std::size_t i = 0; i < n; ++i) {
    const Real m = chain.mass(i);
    const Real rx = x[2 * i] - xprev, ry = x[2 * i + 1] - yprev;
    const Real vx = p[2 * i] / m, vy = p[2 * i + 1] / m;
    o.phi[i] = atan2(rx, -ry);
    // l e_i = (-r_y, r_x)
    const Real ex = -ry, ey = rx;
    const Real l2 = rx * rx + ry * ry;
    o.p_phi[i] = ex * tail_x[i] + ey * tail_y[i];
    o.phidot[i] = (ex * (vx - vxprev) + ey * (vy - vyprev)) / l2;
    o.kinetic[i] = (p[2 * i] * p[2 * i] + p[2 * i + 1] * p[2 * i + 1]) / (2 * m);
    o.kinetic_canonical[i] = o.p_phi[i] * o.phidot[i] / 2;
    o.kinetic_total += o.kinetic[i];
    o.potential += m * chain.gravity() * x[2 * i + 1];
    xprev = x[2 * i];
    yprev = x[2 * i + 1];
    vxprev = vx;
    vyprev = vy;
  }
  o.energy = o.kinetic_total + o.potential;
  return o;
}

template <class Real>
Real potential_energy(const Chain<Real>& chain, const ChainState<Real>& st) {
  Real u = 0;
  for (std::size_t k = 0; k < chain.size(); ++k) u += chain.mass(k) * st.position[2 * k + 1];
  return u * chain.gravity();
}

template <class Real>
Real total_energy(const Chain<Real>& chain, const ChainState<Real>& st) {
  Real kinetic = 0;
  for (std::size_t k = 0; k < chain.size(); ++k)
    kinetic += (st.momentum[2 * k] * st.momentum[2 * k] +
                st.momentum[2 * k + 1] * st.momentum[2 * k + 1]) /
               (2 * chain.mass(k));
  return kinetic + potential_energy(chain, st);
}

template <class Real>
Real constraint_residual(const Chain<Real>& chain, const ChainState<Real>& st) {
  Real worst = 0, xprev = 0, yprev = 0;
  for (std::size_t i = 0; i < chain.size(); ++i) {
    const Real rx = st.position[2 * i] - xprev, ry = st.position[2 * i + 1] - yprev;
    using std::hypot;
    worst = std::max(worst, abs(hypot(rx, ry) - chain.length(i)) / chain.length(i));
    xprev = st.position[2 * i];
    yprev = st.position[2 * i + 1];
  }
  return worst;
}

template <class Real>
Real velocity_constraint_residual(const Chain<Real>& chain, const ChainState<Real>& st) {
  Real worst = 0, scale = 0, xprev = 0, yprev = 0, vxprev = 0, vyprev = 0;
  std::vector<Real> dots(chain.size());
  for (std::size_t i = 0; i < chain.size(); ++i) {
    const Real m = chain.mass(i);
    const Real rx = st.position[2 * i] - xprev, ry = st.position[2 * i + 1] - yprev;
    const Real ux = st.momentum[2 * i] / m - vxprev, uy = st.momentum[2 * i + 1] / m - vyprev;
    dots[i] = abs(rx * ux + ry * uy) / chain.length(i);
    using std::hypot;
    scale = std::max(scale, hypot(ux, uy));
    xprev = st.position[2 * i];
    yprev = st.position[2 * i + 1];
    vxprev = st.momentum[2 * i] / m;
    vyprev = st.momentum[2 * i + 1] / m;
  }
  for (const Real& d : dots) worst = std::max(worst, d);
  return scale > 0 ? worst / scale : worst;
}

template <class Real>
DynamicsWorkspace<Real>::DynamicsWorkspace(const Chain<Real>& chain) : n_(chain.size()) {
  for (auto* v : {&mass, &inv_sqrt_mass, &tail_mass, &joint_compliance, &length, &inv_length,
                  &inv_length_squared, &half_length_squared})
    v->assign(n_, Real(0));
  for (auto* v : {&link_x, &link_y, &rate_x, &rate_y, &inv_mass_padded, &multiplier,
                  &next_link_x, &next_link_y, &next_rate_x, &next_rate_y})
    v->assign(n_ + 2, Real(0));
  for (std::size_t i = 0; i < n_; ++i) {
    mass[i] = chain.mass(i);
    inv_mass_padded[i + 1] = Real(1) / chain.mass(i);
    inv_sqrt_mass[i] = Real(1) / sqrt(chain.mass(i));
    tail_mass[i] = chain.tail_mass(i);
    joint_compliance[i] = inv_mass_padded[i + 1] + inv_mass_padded[i];
    const Real l = chain.length(i);
    length[i] = l;
    inv_length[i] = Real(1) / l;
    inv_length_squared[i] = Real(1) / (l * l);
    half_length_squared[i] = l * l / 2;
  }
  for (auto* v : {&trial_link_x, &trial_link_y, &velocity_x, &velocity_y,
                  &multiplier_estimate, &residual, &diagonal, &sub, &super,
                  &rhs, &pivot})
    v->assign(n_, Real(0));
}

// ---------------------------------------------------------------- kernels, per instruction set

const char* dynamics_instruction_set() {
  static const char* const chosen = [] {
#if defined(PENDAVG_HAVE_DYNAMICS_X86_64_V3)
    const char* forced = std::getenv("PENDAVG_DYNAMICS_ISA");
    if (forced != nullptr && std::strcmp(forced, "base") == 0) return "base";
    __builtin_cpu_init();
    if (__builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma") &&
        __builtin_cpu_supports("bmi2"))
      return "x86-64-v3";
#endif
    return "base";
  }();
  return chosen;
}

namespace {

bool wide_kernels() {
#if defined(PENDAVG_HAVE_DYNAMICS_X86_64_V3)
  static const bool wide = std::strcmp(dynamics_instruction_set(), "x86-64-v3") == 0;
  return wide;
#else
  return false;
#endif
}

}  // namespace

#if defined(PENDAVG_HAVE_DYNAMICS_X86_64_V3)
#define PENDAVG_DISPATCH(call) \
  return wide_kernels() ? dynamics_x86_64_v3::call : dynamics_base::call
#else
#define PENDAVG_DISPATCH(call) return dynamics_base::call
#endif

template <class Real>
void project_momenta(const Chain<Real>& chain, ChainState<Real>& state,
                     DynamicsWorkspace<Real>& ws) {
  PENDAVG_DISPATCH(project_momenta_kernel(chain, state, ws));
}

template <class Real>
void rattle_step(const Chain<Real>& chain, ChainState<Real>& state, const Real& h,
                 DynamicsWorkspace<Real>& ws) {
  PENDAVG_DISPATCH(rattle_step_kernel(chain, state, h, ws));
}

template <class Real>
void composition_step(const Chain<Real>& chain, ChainState<Real>& state, const Real& h,
                      Integrator integrator, DynamicsWorkspace<Real>& ws) {
  PENDAVG_DISPATCH(composition_step_kernel(chain, state, h, integrator, ws));
}

template <class Real>
void yoshida4_step(const Chain<Real>& chain, ChainState<Real>& state, const Real& h,
                   DynamicsWorkspace<Real>& ws) {
  PENDAVG_DISPATCH(yoshida4_step_kernel(chain, state, h, ws));
}

template <class Real>
void baoab_step(const Chain<Real>& chain, ChainState<Real>& state, const Real& h,
                const Real& beta, const Real& friction, std::mt19937_64& rng,
                DynamicsWorkspace<Real>& ws) {
  PENDAVG_DISPATCH(baoab_step_kernel(chain, state, h, beta, friction, rng, ws));
}

template <class Real>
SimulationResult<Real> simulate(const Chain<Real>& chain, ChainState<Real> initial,
                                const SimulationOptions& options,
                                const DynamicsObserver<Real>& observer) {
  PENDAVG_DISPATCH(simulate_kernel(chain, std::move(initial), options, observer));
}

template <class Real>
PoincareSection<Real> poincare_section(const Chain<Real>& chain, const Real& energy,
                                       const PoincareOptions& options,
                                       const DynamicsObserver<Real>& observer) {
  PENDAVG_DISPATCH(poincare_section_kernel(chain, energy, options, observer));
}

#undef PENDAVG_DISPATCH

#define PENDAVG_DYNAMICS_INSTANTIATE(Real)                                                      \
  template ChainState<Real> state_from_angles<Real>(const Chain<Real>&, const std::vector<Real>&, \
                                                    const std::vector<Real>&);                   \
  template ChainState<Real> state_from_canonical<Real>(                                         \
      const Chain<Real>&, const std::vector<Real>&, const std::vector<Real>&);                   \
  template ChainObservables<Real> observables<Real>(const Chain<Real>&, const ChainState<Real>&); \
  template Real potential_energy<Real>(const Chain<Real>&, const ChainState<Real>&);            \
  template Real total_energy<Real>(const Chain<Real>&, const ChainState<Real>&);                \
  template Real constraint_residual<Real>(const Chain<Real>&, const ChainState<Real>&);         \
  template Real velocity_constraint_residual<Real>(const Chain<Real>&, const ChainState<Real>&); \
  template class DynamicsWorkspace<Real>;                                                       \
  template void rattle_step<Real>(const Chain<Real>&, ChainState<Real>&, const Real&,           \
                                  DynamicsWorkspace<Real>&);                                    \
  template void yoshida4_step<Real>(const Chain<Real>&, ChainState<Real>&, const Real&,         \
                                    DynamicsWorkspace<Real>&);                                  \
  template void composition_step<Real>(const Chain<Real>&, ChainState<Real>&, const Real&,     \
                                       Integrator, DynamicsWorkspace<Real>&);                    \
  template void project_momenta<Real>(const Chain<Real>&, ChainState<Real>&,                    \
                                      DynamicsWorkspace<Real>&);                                \
  template void baoab_step<Real>(const Chain<Real>&, ChainState<Real>&, const Real&,            \
                                 const Real&, const Real&, std::mt19937_64&,                    \
                                 DynamicsWorkspace<Real>&);                                     \
  template SimulationResult<Real> simulate<Real>(const Chain<Real>&, ChainState<Real>,          \
                                                 const SimulationOptions&,                      \
                                                 const DynamicsObserver<Real>&);                \
  template PoincareSection<Real> poincare_section<Real>(const Chain<Real>&, const Real&,        \
                                                        const PoincareOptions&,                 \
                                                        const DynamicsObserver<Real>&);

PENDAVG_DYNAMICS_INSTANTIATE(double)
PENDAVG_DYNAMICS_INSTANTIATE(long double)

}  // namespace pendavg
