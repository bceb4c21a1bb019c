// SPDX-License-Identifier: GPL-3.0-or-later
// Constrained symplectic dynamics of the N-link chain (include/pendavg/dynamics.hpp): states,
// observables and the workspace, and the run-time choice of the kernels' instruction set
// (src/engine/dynamics/dynamics_kernels.cpp is compiled for baseline x86-64 and, where the compiler
// can, for x86-64-v3 = AVX2 + FMA, about twice as fast; the library runs on any x86-64 CPU).
#include "engine/dynamics/dynamics_kernels.hpp"

#include "domain.hpp"
#include "engine/numerics/text.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <cstdlib>
#include <cstring>
#include <string>
#include <utility>

namespace pendavg {


// ---------------------------------------------------------------- the workspace

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

// ---------------------------------------------------------------- run options

void check_simulation_options(const SimulationOptions& options) {
  const auto finite_positive = [](double x) { return x > 0 && std::isfinite(x); };
  if (!finite_positive(options.time_step))
    throw invalid_input("simulate: the time step must be positive and finite");
  if (!finite_positive(options.duration))
    throw invalid_input("simulate: the duration must be positive and finite");
  if (!(options.burn_in >= 0) || !std::isfinite(options.burn_in))
    throw invalid_input("simulate: the burn-in must be non-negative and finite");
  if (options.duration / options.time_step > max_simulation_steps ||
      options.burn_in / options.time_step > max_simulation_steps)
    throw invalid_input("simulate: more than 1e13 steps (time / dt)");
  if (options.duration / options.time_step < 1)
    throw invalid_input("simulate: the time is shorter than one step dt");
  if (options.block_samples == 0 || options.max_blocks < 16)
    throw invalid_input("simulate: block_samples >= 1 and max_blocks >= 16 required");
  if (options.thermostat == Thermostat::langevin) {
    if (options.integrator)
      throw invalid_input("simulate: integrator is for NVE runs (Langevin uses BAOAB)");
    if (!options.beta) throw invalid_input("simulate: the Langevin thermostat needs beta");
    if (!finite_positive(*options.beta))
      throw invalid_input("simulate: beta must be positive and finite");
    if (options.friction && !finite_positive(*options.friction))
      throw invalid_input("simulate: the friction must be positive and finite");
  } else {
    for (const auto& [given, name] : {std::pair{options.beta.has_value(), "beta"},
                                      std::pair{options.friction.has_value(), "friction"},
                                      std::pair{options.seed.has_value(), "seed"}})
      if (given)
        throw invalid_input(std::string("simulate: ") + name +
                            " is for the Langevin thermostat only (an NVE run has no " + name +
                            ")");
  }
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
ChainState<Real> state_from_angles(const Chain<Real>& chain, const std::vector<Real>& phi,
                                   const std::vector<Real>& phidot) {
  PENDAVG_DISPATCH(state_from_angles_kernel(chain, phi, phidot));
}

template <class Real>
ChainState<Real> state_from_canonical(const Chain<Real>& chain, const std::vector<Real>& phi,
                                      const std::vector<Real>& p_phi) {
  PENDAVG_DISPATCH(state_from_canonical_kernel(chain, phi, p_phi));
}

template <class Real>
ChainObservables<Real> observables(const Chain<Real>& chain, const ChainState<Real>& state) {
  PENDAVG_DISPATCH(observables_kernel(chain, state));
}

template <class Real>
Real potential_energy(const Chain<Real>& chain, const ChainState<Real>& state) {
  PENDAVG_DISPATCH(potential_energy_kernel(chain, state));
}

template <class Real>
Real total_energy(const Chain<Real>& chain, const ChainState<Real>& state) {
  PENDAVG_DISPATCH(total_energy_kernel(chain, state));
}

template <class Real>
Real constraint_residual(const Chain<Real>& chain, const ChainState<Real>& state) {
  PENDAVG_DISPATCH(constraint_residual_kernel(chain, state));
}

template <class Real>
Real velocity_constraint_residual(const Chain<Real>& chain, const ChainState<Real>& state) {
  PENDAVG_DISPATCH(velocity_constraint_residual_kernel(chain, state));
}

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
ChainState<Real> state_at_energy(const Chain<Real>& chain, const std::vector<Real>& phi,
                                 const std::vector<Real>& phidot, const Real& energy) {
  using std::abs;
  using std::cos;
  using std::sin;
  using std::sqrt;
  const std::size_t n = chain.size();
  const ChainState<Real> start = state_from_angles(chain, phi, phidot);
  const Real u = potential_energy(chain, start);
  const Real k = total_energy(chain, start) - u;
  // The energy scale the tolerance is relative to: the well's depth sum_j gamma_j, or |E|.
  Real scale = abs(energy);
  for (std::size_t j = 0; j < n; ++j) scale += chain.potential_coefficient(j);
  const Real tolerance = 8 * std::numeric_limits<Real>::epsilon() * scale;
  if (k > 0 && energy - u > 0) {
    const Real factor = sqrt((energy - u) / k);
    std::vector<Real> rates = phidot;
    for (Real& w : rates) w *= factor;
    ChainState<Real> s = state_from_angles(chain, phi, rates);
    if (abs(total_energy(chain, s) - energy) <= tolerance) return s;
  }
  // At rest (or short of energy): move the angles along grad U, d_j = gamma_j sin phi_j.
  std::vector<Real> direction(n);
  Real norm2 = 0;
  for (std::size_t j = 0; j < n; ++j) {
    direction[j] = chain.potential_coefficient(j) * sin(phi[j]);
    norm2 += direction[j] * direction[j];
  }
  const auto mismatch = [&](const Real& step) {
    std::vector<Real> angles = phi;
    for (std::size_t j = 0; j < n; ++j) angles[j] += step * direction[j];
    return std::pair{total_energy(chain, state_from_angles(chain, angles, phidot)) - energy, angles};
  };
  if (norm2 > 0) {
    Real s0 = 0, f0 = mismatch(s0).first;
    Real s1 = -f0 / norm2;  // dU/ds = |grad U|^2 at s = 0
    for (int iteration = 0; iteration < 60; ++iteration) {
      auto [f1, angles] = mismatch(s1);
      if (abs(f1) <= tolerance && abs(s1) * sqrt(norm2) <= Real(0.5))
        return state_from_angles(chain, angles, phidot);
      if (f1 == f0) break;
      const Real next = s1 - f1 * (s1 - s0) / (f1 - f0);
      s0 = s1, f0 = f1, s1 = next;
      using std::isfinite;
      if (!isfinite(s1)) break;
    }
  }
  throw invalid_input("simulate: no state at the energy " + short_decimal(static_cast<long double>(energy)) +
                      " near these angles (a start at rest at an equilibrium cannot be moved "
                      "along its energy shell); start elsewhere or use a smaller --perturb");
}

template <class Real>
void check_simulation(const Chain<Real>& chain, const ChainState<Real>& initial,
                      const SimulationOptions& options) {
  check_simulation_options(options);
  domain::check_dynamics_scales(chain, "simulate");
  const std::size_t n = chain.size();
  if (initial.position.size() != 2 * n || initial.momentum.size() != 2 * n)
    throw invalid_input("simulate: the state does not match the chain");
  // The kinetic energy the motion can reach, as simulate() bounds it: E - U_min with
  // U_min >= -g (sum m)(sum l); for Langevin at least 20 N / beta.
  long double mass_sum = 0, length_sum = 0;
  for (std::size_t i = 0; i < n; ++i) {
    mass_sum += static_cast<long double>(chain.mass(i));
    length_sum += static_cast<long double>(chain.length(i));
  }
  long double kinetic = static_cast<long double>(total_energy(chain, initial)) +
                        static_cast<long double>(chain.gravity()) * mass_sum * length_sum;
  if (options.thermostat == Thermostat::langevin && options.beta)
    kinetic = std::max(kinetic, 20 * static_cast<long double>(n) / *options.beta);
  domain::check_stable_time_step(chain, options.time_step, kinetic, "simulate",
                                 options.duration + options.burn_in, max_simulation_steps);
}

/// The result check of simulate() (domain.hpp): every time average, energy and residual finite.
/// A statistical error is NaN only where it is documented as unknown (fewer than 16 blocks);
/// an infinite or negative one is refused.
template <class Real>
void check_simulation_result(const SimulationResult<Real>& r) {
  const auto average = [](const TimeAverage<Real>& a, const char* what) {
    domain::check_finite_value(a.value, "simulate", what);
    using std::isinf;
    if (isinf(a.error) || a.error < 0)
      throw invalid_input(std::string("simulate: the error of ") + what +
                          " is not finite for this input (please report it)");
  };
  for (const auto& a : r.kinetic) average(a, "<K_i>");
  for (const auto& a : r.kinetic_canonical) average(a, "<K_i^(c)>");
  for (const auto& a : r.cos_angle) average(a, "<cos phi_i>");
  average(r.kinetic_total, "<K>");
  average(r.potential, "<U>");
  for (const auto& [x, what] : {std::pair{&r.initial_energy, "initial energy"},
                                std::pair{&r.final_energy, "final energy"},
                                std::pair{&r.energy_error_max, "energy error"},
                                std::pair{&r.energy_drift, "energy drift"},
                                std::pair{&r.constraint_residual, "constraint residual"}})
    domain::check_finite_value(*x, "simulate", what);
}

template <class Real>
SimulationResult<Real> simulate(const Chain<Real>& chain, ChainState<Real> initial,
                                const SimulationOptions& options,
                                const DynamicsObserver<Real>& observer) {
  check_simulation_options(options);
  domain::check_dynamics_scales(chain, "simulate");
  SimulationResult<Real> result = [&] {
    PENDAVG_DISPATCH(simulate_kernel(chain, std::move(initial), options, observer));
  }();
  check_simulation_result(result);
  return result;
}

template <class Real>
PoincareSection<Real> poincare_section(const Chain<Real>& chain, const Real& energy,
                                       const PoincareOptions& options,
                                       const DynamicsObserver<Real>& observer) {
  domain::check_dynamics_scales(chain, "poincare");
  PoincareSection<Real> section = [&] {
    PENDAVG_DISPATCH(poincare_section_kernel(chain, energy, options, observer));
  }();
  for (const SectionPoint<Real>& p : section.points) {
    domain::check_finite_value(p.phi2, "poincare", "phi_2 of a section point");
    domain::check_finite_value(p.p2, "poincare", "p_2 of a section point");
  }
  domain::check_finite_value(section.energy_error_max, "poincare", "energy error");
  return section;
}

#undef PENDAVG_DISPATCH

#define PENDAVG_DYNAMICS_INSTANTIATE(Real)                                                       \
  template PENDAVG_EXPORT ChainState<Real> state_from_angles<Real>(                              \
      const Chain<Real>&, const std::vector<Real>&, const std::vector<Real>&);                   \
  template PENDAVG_EXPORT ChainState<Real> state_from_canonical<Real>(                           \
      const Chain<Real>&, const std::vector<Real>&, const std::vector<Real>&);                   \
  template PENDAVG_EXPORT ChainObservables<Real> observables<Real>(const Chain<Real>&,           \
                                                                   const ChainState<Real>&);     \
  template PENDAVG_EXPORT Real potential_energy<Real>(const Chain<Real>&,                        \
                                                      const ChainState<Real>&);                  \
  template PENDAVG_EXPORT Real total_energy<Real>(const Chain<Real>&, const ChainState<Real>&);  \
  template PENDAVG_EXPORT void check_simulation<Real>(const Chain<Real>&, const ChainState<Real>&, \
                                                      const SimulationOptions&);                 \
  template PENDAVG_EXPORT ChainState<Real> state_at_energy<Real>(                                \
      const Chain<Real>&, const std::vector<Real>&, const std::vector<Real>&, const Real&);     \
  template PENDAVG_EXPORT Real constraint_residual<Real>(const Chain<Real>&,                     \
                                                         const ChainState<Real>&);               \
  template PENDAVG_EXPORT Real velocity_constraint_residual<Real>(const Chain<Real>&,            \
                                                                  const ChainState<Real>&);      \
  template class PENDAVG_EXPORT DynamicsWorkspace<Real>;                                         \
  template PENDAVG_EXPORT void rattle_step<Real>(const Chain<Real>&, ChainState<Real>&,          \
                                                 const Real&, DynamicsWorkspace<Real>&);         \
  template PENDAVG_EXPORT void yoshida4_step<Real>(const Chain<Real>&, ChainState<Real>&,        \
                                                   const Real&, DynamicsWorkspace<Real>&);       \
  template PENDAVG_EXPORT void composition_step<Real>(                                           \
      const Chain<Real>&, ChainState<Real>&, const Real&, Integrator, DynamicsWorkspace<Real>&); \
  template PENDAVG_EXPORT void project_momenta<Real>(const Chain<Real>&, ChainState<Real>&,      \
                                                     DynamicsWorkspace<Real>&);                  \
  template PENDAVG_EXPORT void baoab_step<Real>(const Chain<Real>&, ChainState<Real>&,           \
                                                const Real&, const Real&, const Real&,           \
                                                std::mt19937_64&, DynamicsWorkspace<Real>&);     \
  template PENDAVG_EXPORT SimulationResult<Real> simulate<Real>(                                 \
      const Chain<Real>&, ChainState<Real>, const SimulationOptions&,                            \
      const DynamicsObserver<Real>&);                                                            \
  template PENDAVG_EXPORT PoincareSection<Real> poincare_section<Real>(                          \
      const Chain<Real>&, const Real&, const PoincareOptions&, const DynamicsObserver<Real>&);

PENDAVG_DYNAMICS_INSTANTIATE(double)
PENDAVG_DYNAMICS_INSTANTIATE(long double)

}  // namespace pendavg
