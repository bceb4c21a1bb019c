// SPDX-License-Identifier: GPL-3.0-or-later
// pendavg/dynamics.hpp -- constrained symplectic trajectories of the N-link chain, their time
// averages with error bars, constrained Langevin sampling and the double pendulum's Poincare
// section (paper Sec. "Simulation Method", Appendix "Poincare surface of section";
// src/engine/microcanonical/README.md).
//
// What it computes.
//   * rattle_step: one RATTLE step (Andersen 1983; Leimkuhler-Reich 2004 Sec. 7.2) of the
//     Cartesian equations of motion with the link constraints sigma_i = (|r_i|^2 - l_i^2)/2 = 0,
//     r_i = x_i - x_{i-1} (pivot x_0 = 0), potential U = sum_k m_k g y_k (y up; equal to the
//     paper's U = -sum_j gamma_j cos phi_j):
//         p_{1/2} = p_n - (h/2) grad U - G(q_n)^T lambda,     q_{n+1} = q_n + h M^{-1} p_{1/2},
//         sigma(q_{n+1}) = 0,
//         p_{n+1} = p_{1/2} - (h/2) grad U - G(q_{n+1})^T mu,  G(q_{n+1}) M^{-1} p_{n+1} = 0.
//     Position stage: the N multipliers solve N quadratic equations. Each constraint couples
//     only neighbouring multipliers, so Newton's Jacobian is tridiagonal and one iteration is an
//     O(N) solve (src/engine/README.md, 'Traces in O(N)'; src/engine/dynamics/README.md), done by a
//     twisted factorization: elimination from both ends towards the middle row, two independent
//     serial chains of one multiply-add per row. Iterations run until every |sigma_i| / l_i^2 is at
//     most a few ulps; the guess is the quadratic extrapolation of the stage's multipliers over the
//     last three steps, which leaves one solve per stage (1.00 at N = 16). Velocity stage: a linear
//     system with the symmetric positive definite tridiagonal matrix H = G M^{-1} G^T
//     (src/engine/README.md, 'Traces in O(N)'), the same O(N) solve. The kernels run on the links
//     r_i = x_i - x_{i-1} and link velocities u_i = v_i - v_{i-1} stored as separate arrays
//     (uniform gravity then kicks u_0 alone), so every pass but the two serial chains vectorizes.
//   * composition_step: a symmetric composition of RATTLE steps RATTLE(w_s h) o ... o
//     RATTLE(w_1 h): Yoshida's (1990) fourth-order triple jump w1 = 1/(2 - 2^{1/3}),
//     w0 = -2^{1/3} w1 (the paper's; yoshida4_step), Suzuki's 5-stage fourth order, Yoshida's
//     7-stage sixth order (solution A) and Kahan-Li's 9-stage sixth order. All are
//     symplectic on the constraint manifold and time reversible. Gravity is uniform, so the
//     kick forces are constants. Velocity stages between the substeps are skipped: the next
//     position stage absorbs any momentum component along G(q)^T exactly, so only the last
//     one (which returns the momenta to the cotangent space) changes the state. Same map, one
//     solve fewer per substep.
//   * baoab_step: constrained Langevin dynamics (Leimkuhler-Matthews 2016, "g-BAOAB" with one
//     RATTLE solve per A): B(h/2) A(h/2) O(h) A(h/2) B(h/2), the O step
//     p <- e^{-gamma h} p + sqrt((1 - e^{-2 gamma h}) m / beta) xi followed by the projection
//     onto the cotangent space. Its invariant measure is exp(-beta H) times the Liouville
//     measure of the constrained phase space (dphi dp_phi), i.e. the canonical ensemble of the
//     paper, up to O(h^2) in configurational averages (about 1e-6 relative at h = 1e-3).
//   * simulate: a run of T/h steps with time averages of K_i = |p_i|^2 / 2 m_i and of the
//     canonical kinetic energy K_i^(c) = p_phi_i phidot_i / 2 (paper eq. ke-canonical-i), the
//     energy error, and the largest constraint residual. Error bars come from Flyvbjerg-
//     Petersen blocking: block means over a geometric ladder of block lengths, the standard
//     error read at the first level after which it stops growing beyond its own noise. They
//     are one standard error (1 sigma), a statistical estimate, not a bound; the integrated
//     autocorrelation time they imply is reported with them.
//   * poincare_section: the double pendulum's section phi_1 = 0, phidot_1 > 0 (the paper's
//     A_3 p_1 - A_2 p_2 > 0), points (phi_2, p_2) with p_2 the canonical momentum. Each crossing
//     is located by cubic Hermite interpolation of x_1 between two steps and then refined by
//     integrating a partial step of the same integrator onto the section (Newton on the step
//     length), so the points are accurate to the integrator, not to the step.
//
// When to use it. To confirm the exact averages of average() (canonical,
// via baoab_step) and of microcanonical.hpp (fixed energy, via yoshida4_step) by dynamics, as
// the paper does. A fixed-energy run samples the microcanonical ensemble of its energy only
// if the motion is ergodic there; regular islands (see the Poincare section) make time
// averages differ from ensemble averages. With g = 0 the angular momentum is conserved too.
//
// Accuracy (tests/engine/dynamics/test_dynamics.cpp, tests/bench/bench_dynamics.cpp, tables/dynamics_*.csv).
// Constraint residuals stay at rounding level (<= 2e-15 relative over 1e7 steps). The observed
// orders are 2, 4, 4, 6, 6 (rattle2, yoshida4, suzuki4, yoshida6, kahan_li6). The paper's
// N = 16 run (unit chain from phi_i = pi/2, E = 0, dt = 1e-3, T = 1e4): max |E(t) - E(0)| /
// ((sum m) g (sum l)) = 2.8e-7 with yoshida4 (rms 1.4e-9, drift 3e-10: bounded, no secular
// growth; the maxima come from the fast whips of the free end), 6e-11 to 2e-10 with yoshida6
// (the default), 1.5e-11 with kahan_li6. Time averages of N = 2, 3 (NVE and Langevin) and of
// the paper's N = 7, 16 runs agree with the exact values within ~2 combined error bars. Cost
// per step: linear in N.
// Why: README, Design notes, 'Measurements behind the design choices' (dynamics).
//
// Generic over Real (double and long double are instantiated in src/engine/dynamics/dynamics.cpp). The model
// (Chain) is kept apart from the state (ChainState) and the workspace (DynamicsWorkspace). The
// library does no I/O: progress, trajectories and interruption go through DynamicsObserver.
#pragma once

#include "pendavg/export.hpp"
#include "pendavg/chain.hpp"
#include "pendavg/result.hpp"

#include <atomic>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <optional>
#include <random>
#include <vector>

namespace pendavg {

enum class Integrator;

/// Cartesian phase-space point of an N-link chain: positions x_k = (position[2k],
/// position[2k+1]) relative to the pivot (y up, so hanging at rest is y < 0) and momenta
/// p_k = m_k v_k, k = 0..N-1.
template <class Real>
struct ChainState {
  std::vector<Real> position;
  std::vector<Real> momentum;
  Real time{0};
};

/// The state with angles phi (from the downward vertical) and angular velocities phidot.
/// Throws invalid_input on a count mismatch or a non-finite entry.
template <class Real>
PENDAVG_EXPORT ChainState<Real> state_from_angles(const Chain<Real>& chain,
                                                  const std::vector<Real>& phi,
                                                  const std::vector<Real>& phidot);

/// The state with angles phi and canonical momenta p_phi = A(phi) phidot (paper eq. a-ij).
template <class Real>
PENDAVG_EXPORT ChainState<Real> state_from_canonical(const Chain<Real>& chain,
                                                     const std::vector<Real>& phi,
                                                     const std::vector<Real>& p_phi);

/// Generalized coordinates and per-particle energies of a state (O(N)).
template <class Real>
struct ChainObservables {
  std::vector<Real> phi, phidot, p_phi;  ///< angles, angular velocities, canonical momenta
  std::vector<Real> kinetic;             ///< K_i = |p_i|^2 / 2 m_i
  std::vector<Real> kinetic_canonical;   ///< K_i^(c) = p_phi_i phidot_i / 2
  Real kinetic_total{}, potential{}, energy{};
};

template <class Real>
PENDAVG_EXPORT ChainObservables<Real> observables(const Chain<Real>& chain,
                                                  const ChainState<Real>& state);

/// U = -sum_j gamma_j cos phi_j = sum_k m_k g y_k.
template <class Real>
PENDAVG_EXPORT Real potential_energy(const Chain<Real>& chain, const ChainState<Real>& state);

/// H = sum_k |p_k|^2 / 2 m_k + U.
template <class Real>
PENDAVG_EXPORT Real total_energy(const Chain<Real>& chain, const ChainState<Real>& state);

/// A state at total energy `energy` near the angles phi and rates phidot: the rates scaled by
/// sqrt((E - U) / K) when the chain moves and E > U(phi) (K is quadratic in phidot at fixed
/// angles); otherwise the angles moved along grad U by a secant search on H = E with the rates
/// kept. For replicas of one NVE run that start apart but on the same energy shell. Throws
/// invalid_input when no such state is found near phi (|shift| <= 0.5 rad).
template <class Real>
ChainState<Real> state_at_energy(const Chain<Real>& chain, const std::vector<Real>& phi,
                                 const std::vector<Real>& phidot, const Real& energy);

/// max_i | |x_i - x_{i-1}| - l_i | / l_i.
template <class Real>
PENDAVG_EXPORT Real constraint_residual(const Chain<Real>& chain, const ChainState<Real>& state);

/// max_i |r_i . (v_i - v_{i-1})| / (l_i * max_k |v_k - v_{k-1}|): the velocity constraints.
template <class Real>
PENDAVG_EXPORT Real velocity_constraint_residual(const Chain<Real>& chain,
                                                 const ChainState<Real>& state);

/// Buffers of the constraint solves, sized once for N particles (Pinocchio's Data), and the
/// counters of the work done. Not thread-safe: one workspace per thread.
template <class Real>
class PENDAVG_EXPORT DynamicsWorkspace {
 public:
  explicit DynamicsWorkspace(const Chain<Real>& chain);
  std::size_t size() const { return n_; }

  /// Newton iterations (tridiagonal solves) of all position stages so far.
  std::size_t newton_solves = 0;
  /// Position stages so far.
  std::size_t position_stages = 0;
  /// Position stages that stopped at max_newton_iterations before the tolerance.
  std::size_t unconverged_stages = 0;
  /// The largest |sigma_i| / l_i^2 accepted by a position stage (after its last iteration).
  Real largest_stage_residual{0};
  /// Newton stops when max_i |sigma_i| / l_i^2 <= this many ulps (of Real).
  double newton_tolerance_ulps = 4;
  int max_newton_iterations = 30;

  /// Multipliers of the last three position stages at one place in a composition (their
  /// quadratic extrapolation is the next guess), N + 2 each with zero pads at both ends. Slots:
  /// 0 RATTLE, 4-5 BAOAB, 8 + j stage j of a composition.
  struct StageHistory {
    std::vector<Real> last, before, oldest;
    std::size_t count = 0;
  };
  StageHistory& stage_history(std::size_t slot) {
    if (slot >= history_.size()) history_.resize(slot + 1);
    return history_[slot];
  }
  /// Forget the multiplier history (after the state was changed from outside).
  void reset_history() {
    for (StageHistory& h : history_) h.count = 0;
  }
  /// The weights of a composition, computed once per workspace.
  template <class Make>
  const std::vector<Real>& composition(Integrator integrator, Make make) {
    if (!weights_valid_ || weights_integrator_ != integrator) {
      weights_ = make(integrator);
      weights_integrator_ = integrator;
      weights_valid_ = true;
    }
    return weights_;
  }

  // Internal. Chain constants (N each): masses, 1/sqrt(m), tail masses, joint compliances
  // 1/m_i + 1/m_{i-1}, lengths and their inverses.
  std::vector<Real> mass, inv_sqrt_mass, tail_mass, joint_compliance, length, inv_length,
      inv_length_squared, half_length_squared;
  // The link frame (N + 2 each, zero pads at both ends): links r_i = x_i - x_{i-1}, link
  // velocities u_i = v_i - v_{i-1}, 1/m_i and the multipliers.
  std::vector<Real> link_x, link_y, rate_x, rate_y, inv_mass_padded, multiplier;
  // The frame a position stage writes (swapped in when it has converged).
  std::vector<Real> next_link_x, next_link_y, next_rate_x, next_rate_y;
  // Scratch of the constraint stages (N each).
  std::vector<Real> trial_link_x, trial_link_y, velocity_x, velocity_y, multiplier_estimate,
      residual, diagonal, sub, super, rhs, pivot;
  /// Kick time since the last position or velocity stage (its constraint impulse is pending).
  Real pending_kick_time{0};

 private:
  std::size_t n_;
  std::vector<StageHistory> history_;
  std::vector<Real> weights_;
  Integrator weights_integrator_{};
  bool weights_valid_ = false;
};

/// One RATTLE step of length h (h may be negative: the map is time reversible).
template <class Real>
PENDAVG_EXPORT void rattle_step(const Chain<Real>& chain, ChainState<Real>& state, const Real& h,
                                DynamicsWorkspace<Real>& ws);

/// One step of a symmetric composition of RATTLE with the integrator's weights w_j:
/// RATTLE(w_s h) o ... o RATTLE(w_1 h), the intermediate velocity stages skipped (exact).
template <class Real>
PENDAVG_EXPORT void composition_step(const Chain<Real>& chain, ChainState<Real>& state,
                                     const Real& h, Integrator integrator,
                                     DynamicsWorkspace<Real>& ws);

/// One step of Yoshida's fourth-order composition of RATTLE.
template <class Real>
PENDAVG_EXPORT void yoshida4_step(const Chain<Real>& chain, ChainState<Real>& state, const Real& h,
                                  DynamicsWorkspace<Real>& ws);

/// Returns the momenta to the cotangent space at the current positions (the velocity stage
/// without a kick): p <- p - M G^T (G M^{-1} G^T)^{-1} G M^{-1} p.
template <class Real>
PENDAVG_EXPORT void project_momenta(const Chain<Real>& chain, ChainState<Real>& state,
                                    DynamicsWorkspace<Real>& ws);

/// One constrained BAOAB Langevin step at inverse temperature beta with friction gamma.
template <class Real>
PENDAVG_EXPORT void baoab_step(const Chain<Real>& chain, ChainState<Real>& state, const Real& h,
                               const Real& beta, const Real& friction, std::mt19937_64& rng,
                               DynamicsWorkspace<Real>& ws);

// ---------------------------------------------------------------- runs with time averages

/// The symmetric compositions of RATTLE (see composition_step).
enum class Integrator {
  rattle2,    ///< RATTLE alone: second order
  yoshida4,   ///< Yoshida's triple jump: fourth order, 3 stages (the paper's)
  suzuki4,    ///< Suzuki's 5-stage fourth order: smaller error constants
  kahan_li6,  ///< Kahan-Li s9odr6a: sixth order, 9 stages
  yoshida6,   ///< Yoshida's solution A: sixth order, 7 stages (larger error constants)
};
enum class Thermostat { none, langevin };

/// The integrator of NVE runs when SimulationOptions::integrator is unset: Yoshida-6 meets 1e-9
/// relative energy error on the paper's N = 16 run at dt = 1e-3; yoshida4 is the paper's own
/// scheme (2.8e-7 there, half the cost).
inline constexpr Integrator default_integrator = Integrator::yoshida6;

/// How simulate() runs. The thermostat decides which settings apply; simulate() refuses one that
/// its thermostat does not use (invalid_input), as average() does for methods.
struct SimulationOptions {
  double time_step = 1e-3;
  double duration = 0;     ///< T: steps = round(T / time_step), 1..1e13
  double burn_in = 0;      ///< run this long before averaging starts (in addition to T)
  Thermostat thermostat = Thermostat::none;
  /// NVE only (thermostat none): the composition of RATTLE; unset: default_integrator.
  std::optional<Integrator> integrator;
  std::optional<double> beta;      ///< Langevin only, required: inverse temperature
  std::optional<double> friction;  ///< Langevin only: gamma (1/time); unset: 1
  std::optional<std::uint64_t> seed;  ///< Langevin only: noise std::mt19937_64(seed); unset: 1
  /// Samples for the averages: every step. The finest blocks hold max(block_samples,
  /// ceil(steps / max_blocks)) samples each.
  std::size_t block_samples = 1;
  /// At most this many finest blocks are stored; beyond it pairs are merged (length doubles).
  std::size_t max_blocks = 1 << 14;
};

/// The longest run simulate() takes, in steps of time_step (duration and burn-in each).
inline constexpr double max_simulation_steps = 1e13;

/// Checks `options` as simulate() does before any step (time step, duration and steps, the
/// settings of the thermostat); throws invalid_input with a one-line message. Cheap.
PENDAVG_EXPORT void check_simulation_options(const SimulationOptions& options);

/// Callbacks of a run (the library does no I/O). All optional. Progress and stop are the
/// RunControl every engine takes (pendavg/result.hpp): `progress` is called every 1024 steps (or
/// every 1% of a shorter run; for a Poincare section, every 1/200th of its points) with the
/// fraction done, and `stop` is checked every 1024 steps (a dynamics run of N > 64 particles:
/// every 2^k <= 65536 / N steps): true ends the run early with the averages so far
/// (interrupted = true). A dynamics run adds the trajectory callback.
template <class Real>
struct DynamicsObserver : RunControl {
  /// Called every `trajectory_every` steps (and at step 0) with the current state.
  std::function<void(const ChainState<Real>&)> trajectory;
  std::size_t trajectory_every = 0;
};

/// A time average with its statistical error bar: the mean and one standard error (1 sigma)
/// from blocking (kind statistical at 1 sigma, not the 99.9% of the qmc bars: pendavg/result.hpp
/// says what `statistical` means per method), and the integrated autocorrelation time they imply.
/// The error is NaN (unknown, never 0) when fewer than 16 blocks finished: a run interrupted early
/// or shorter than its block length.
template <class Real>
struct TimeAverage : Estimate<Real> {
  TimeAverage() { this->kind = ErrorKind::statistical; }
  Real autocorrelation_time{};  ///< integrated autocorrelation time (time units)
};

template <class Real>
struct SimulationResult {
  std::vector<TimeAverage<Real>> kinetic;            ///< <K_i> over time
  std::vector<TimeAverage<Real>> kinetic_canonical;  ///< <K_i^(c)> over time
  std::vector<TimeAverage<Real>> cos_angle;          ///< <cos phi_i> over time
  TimeAverage<Real> kinetic_total, potential;
  Method method = Method::dynamics_nve;  ///< dynamics_nve or dynamics_langevin
  Real initial_energy{}, final_energy{};
  /// Energy scale (sum m) g (sum l) (or |E0| + K0 when g = 0) the energy errors are relative to.
  Real energy_scale{};
  Real energy_drift{};      ///< (E(T) - E(0)) / scale (NVE)
  Real energy_error_max{};  ///< max_t |E(t) - E(0)| / scale (NVE)
  Real energy_error_rms{};  ///< sqrt(mean_t (E(t) - E(0))^2) / scale (NVE)
  /// Least-squares slope of E(t) over the block means, / scale, times T: secular drift.
  Real energy_trend{};
  Real constraint_residual{};  ///< max over the run of max_i | |r_i| - l_i | / l_i
  std::size_t steps = 0, samples = 0, newton_solves = 0, unconverged_stages = 0;
  double simulated_time = 0;
  bool interrupted = false;
};

/// Checks, without a step, what simulate(chain, initial, options) checks before its first one:
/// the options, the chain's scales (masses, lengths and g within 1e-50..1e50) and the time
/// step against the fastest motion at the start's energy. Throws invalid_input. Cheap: a front
/// end calls it before anything slow (the exact values of the run's ensemble).
template <class Real>
void check_simulation(const Chain<Real>& chain, const ChainState<Real>& initial,
                      const SimulationOptions& options);

/// Integrates from `initial` (the momenta are projected first) and returns the averages.
/// Throws invalid_input for a non-positive time step or duration, or bad Langevin parameters.
template <class Real>
PENDAVG_EXPORT SimulationResult<Real> simulate(const Chain<Real>& chain, ChainState<Real> initial,
                                               const SimulationOptions& options,
                                               const DynamicsObserver<Real>& observer = {});

/// "x86-64-v3" (AVX2 + FMA) or "base": the instruction set the dynamics kernels run with on this
/// CPU, chosen at the first call (PENDAVG_DYNAMICS_ISA=base in the environment forces the
/// baseline). Results agree to rounding (fused multiply-adds).
PENDAVG_EXPORT const char* dynamics_instruction_set();

// ---------------------------------------------------------------- Poincare section (N = 2)

struct PoincareOptions {
  double time_step = 1e-3;
  std::size_t orbits = 8;      ///< initial conditions on the section
  std::size_t points = 500;    ///< crossings per orbit
  double max_time = 0;         ///< per orbit; 0: 200 * points
  int threads = 1;             ///< OpenMP over orbits (results independent of the count)
};

template <class Real>
struct SectionPoint {
  std::size_t orbit = 0;
  Real phi2{}, p2{};  ///< phi_2 in (-pi, pi], canonical momentum p_2
  Real time{};
};

template <class Real>
struct PoincareSection {
  std::vector<SectionPoint<Real>> points;  ///< grouped by orbit, in time order
  /// Initial conditions (phi2, p2) of the orbits, on the section.
  std::vector<Real> start_phi2, start_p2;
  Real energy{};
  Real energy_error_max{};  ///< over all orbits, relative to (sum m) g (sum l)
  std::size_t steps = 0;
  bool interrupted = false;
};

/// Orbits of the double pendulum at energy E (paper's U convention; E > -(gamma_1 + gamma_2)),
/// started on the section phi_1 = 0 at p_2 = 0 over the allowed phi_2 >= 0 and at phi_2 = 0
/// over the allowed p_2, and the points where they cross phi_1 = 0 with phidot_1 > 0.
template <class Real>
PENDAVG_EXPORT PoincareSection<Real> poincare_section(const Chain<Real>& chain, const Real& energy,
                                                      const PoincareOptions& options,
                                                      const DynamicsObserver<Real>& observer = {});

}  // namespace pendavg
