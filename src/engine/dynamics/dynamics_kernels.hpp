// SPDX-License-Identifier: GPL-3.0-or-later
// engine/dynamics/dynamics_kernels.hpp -- the dynamics kernels, declared once per instruction set
// they are compiled for (src/engine/dynamics/dynamics_kernels.cpp): dynamics_base (baseline
// x86-64, any CPU) and dynamics_x86_64_v3 (AVX2 + FMA). The public functions of
// pendavg/dynamics.hpp pick one at run time (src/engine/dynamics/dynamics.cpp); the same
// definitions give the same results up to fused multiply-adds. The math: src/engine/dynamics/
// README.md.
//
// Equations (Cartesian positions q, momenta p, masses M, constraints sigma_i = (|r_i|^2 - l_i^2)/2,
// G = d sigma / dq; RATTLE, one step of length h):
//     p_{1/2} = p_n - (h/2) grad U(q_n) - G(q_n)^T lambda,   q_{n+1} = q_n + h M^{-1} p_{1/2},
//     sigma(q_{n+1}) = 0                                   (lambda: Newton, tridiagonal, O(N))
//     p_{n+1} = p_{1/2} - (h/2) grad U(q_{n+1}) - G(q_{n+1})^T mu,  G(q_{n+1}) M^{-1} p_{n+1} = 0
// composed as Yoshida's fourth-order triple jump (NVE), or as BAOAB with an Ornstein-Uhlenbeck
// step on the momenta projected onto the constraints (Langevin); time averages of K_i, K_i^(c),
// cos phi_i, K, U with Flyvbjerg-Petersen blocking errors (1 sigma).
#pragma once

#include "pendavg/dynamics.hpp"

#include <random>
#include <vector>

#define PENDAVG_DECLARE_DYNAMICS_KERNELS(isa)                                                    \
  namespace pendavg::isa {                                                                       \
  template <class Real>                                                                          \
  ChainState<Real> state_from_angles_kernel(const Chain<Real>&, const std::vector<Real>&,        \
                                            const std::vector<Real>&);                           \
  template <class Real>                                                                          \
  ChainState<Real> state_from_canonical_kernel(const Chain<Real>&, const std::vector<Real>&,     \
                                               const std::vector<Real>&);                        \
  template <class Real>                                                                          \
  ChainObservables<Real> observables_kernel(const Chain<Real>&, const ChainState<Real>&);        \
  template <class Real>                                                                          \
  Real potential_energy_kernel(const Chain<Real>&, const ChainState<Real>&);                     \
  template <class Real>                                                                          \
  Real total_energy_kernel(const Chain<Real>&, const ChainState<Real>&);                         \
  template <class Real>                                                                          \
  Real constraint_residual_kernel(const Chain<Real>&, const ChainState<Real>&);                  \
  template <class Real>                                                                          \
  Real velocity_constraint_residual_kernel(const Chain<Real>&, const ChainState<Real>&);         \
  template <class Real>                                                                          \
  void project_momenta_kernel(const Chain<Real>&, ChainState<Real>&, DynamicsWorkspace<Real>&); \
  template <class Real>                                                                          \
  void rattle_step_kernel(const Chain<Real>&, ChainState<Real>&, const Real&,                    \
                          DynamicsWorkspace<Real>&);                                             \
  template <class Real>                                                                          \
  void composition_step_kernel(const Chain<Real>&, ChainState<Real>&, const Real&, Integrator,   \
                               DynamicsWorkspace<Real>&);                                        \
  template <class Real>                                                                          \
  void yoshida4_step_kernel(const Chain<Real>&, ChainState<Real>&, const Real&,                  \
                            DynamicsWorkspace<Real>&);                                           \
  template <class Real>                                                                          \
  void baoab_step_kernel(const Chain<Real>&, ChainState<Real>&, const Real&, const Real&,        \
                         const Real&, std::mt19937_64&, DynamicsWorkspace<Real>&);               \
  template <class Real>                                                                          \
  SimulationResult<Real> simulate_kernel(const Chain<Real>&, ChainState<Real>,                   \
                                         const SimulationOptions&, const DynamicsObserver<Real>&); \
  template <class Real>                                                                          \
  PoincareSection<Real> poincare_section_kernel(const Chain<Real>&, const Real&,                 \
                                                const PoincareOptions&,                          \
                                                const DynamicsObserver<Real>&);                  \
  }

PENDAVG_DECLARE_DYNAMICS_KERNELS(dynamics_base)
#if defined(PENDAVG_HAVE_DYNAMICS_X86_64_V3)
PENDAVG_DECLARE_DYNAMICS_KERNELS(dynamics_x86_64_v3)
#endif

#define PENDAVG_DYNAMICS_KERNELS_INSTANTIATE(Real)                                              \
  template ChainState<Real> state_from_angles_kernel<Real>(                                    \
      const Chain<Real>&, const std::vector<Real>&, const std::vector<Real>&);                  \
  template ChainState<Real> state_from_canonical_kernel<Real>(                                 \
      const Chain<Real>&, const std::vector<Real>&, const std::vector<Real>&);                  \
  template ChainObservables<Real> observables_kernel<Real>(const Chain<Real>&,                 \
                                                           const ChainState<Real>&);            \
  template Real potential_energy_kernel<Real>(const Chain<Real>&, const ChainState<Real>&);    \
  template Real total_energy_kernel<Real>(const Chain<Real>&, const ChainState<Real>&);        \
  template Real constraint_residual_kernel<Real>(const Chain<Real>&, const ChainState<Real>&); \
  template Real velocity_constraint_residual_kernel<Real>(const Chain<Real>&,                  \
                                                          const ChainState<Real>&);            \
  template void project_momenta_kernel<Real>(const Chain<Real>&, ChainState<Real>&,            \
                                             DynamicsWorkspace<Real>&);                         \
  template void rattle_step_kernel<Real>(const Chain<Real>&, ChainState<Real>&, const Real&,   \
                                         DynamicsWorkspace<Real>&);                             \
  template void composition_step_kernel<Real>(const Chain<Real>&, ChainState<Real>&,           \
                                              const Real&, Integrator, DynamicsWorkspace<Real>&); \
  template void yoshida4_step_kernel<Real>(const Chain<Real>&, ChainState<Real>&, const Real&, \
                                           DynamicsWorkspace<Real>&);                           \
  template void baoab_step_kernel<Real>(const Chain<Real>&, ChainState<Real>&, const Real&,    \
                                        const Real&, const Real&, std::mt19937_64&,             \
                                        DynamicsWorkspace<Real>&);                              \
  template SimulationResult<Real> simulate_kernel<Real>(const Chain<Real>&, ChainState<Real>,   \
                                                        const SimulationOptions&,               \
                                                        const DynamicsObserver<Real>&);         \
  template PoincareSection<Real> poincare_section_kernel<Real>(                                \
      const Chain<Real>&, const Real&, const PoincareOptions&, const DynamicsObserver<Real>&);
