// SPDX-License-Identifier: GPL-3.0-or-later
// pendavg/result.hpp -- what every average comes back as: value + error + kind of error, work,
// method.
//
// Following GSL's {val, err} and Arb's balls, every observable is an Estimate: a value and an
// absolute error that is meant to cover the true error. What the error promises is machine
// readable (ErrorKind):
//   * bound       -- a rigorous bound (the series' certified tail bound, the certified integral's
//                    ball arithmetic; exact formulas, whose error is rounding only);
//   * estimate    -- a deterministic error estimate from refinement (quadrature levels), checked
//                    against independent methods in the tests but not a proof;
//   * statistical -- a statistical error bar: error = k * SE (+ a rounding allowance), SE the
//                    standard error of the value from independent replicas of the computation.
//                    The multiplier k, and so the confidence, depends on the method:
//                      - qmc (canonical and microcanonical rule qmc): k = the 99.9% two-sided
//                        Student-t quantile for R - 1 degrees of freedom, R the random shifts
//                        (4.07 for the default 16; QmcOptions::sigmas overrides it), SE the
//                        jackknife over the shifts: the bar misses about 1 run in 1000;
//                      - dynamics time averages (TimeAverage, SimulationResult): k = 1, SE from
//                        Flyvbjerg-Petersen blocking: one standard error, the bar misses about
//                        1 run in 3 (multiply by 3.29 for the qmc bars' confidence);
//                      - low_temperature_extrapolation of a qmc run: the qmc bars carried
//                        through the extrapolation (same k).
//                    The 1-sigma SE of a qmc run is in QmcDiagnostics (the *_standard_error
//                    arrays), so the two can be compared on one scale.
// Tests look for estimates that fail to cover the truth. "Did not converge" is a status with a
// still-valid estimate (converged = false), never a silent wrong value.
#pragma once

#include "pendavg/export.hpp"

#include <atomic>
#include <cstddef>
#include <functional>
#include <optional>
#include <stdexcept>
#include <vector>

namespace pendavg {

/// Progress reports and cancellation of a long computation (the library does no I/O): both
/// optional. `progress` receives the estimated fraction done of the current stage (a torus
/// level, the transfer sweeps, the qmc shifts, the series' Bessel table, a trajectory); `stop`
/// is polled between units of work, and when it reads true the run ends early: with what it
/// finished (converged = false, interrupted = true) when that is a valid result, or by throwing
/// `interrupted` when nothing reportable is finished.
///
/// The one progress and stop type of every engine: AverageOptions::control (torus, qmc,
/// transfer; series through series_convergence), MicrocanonicalOptions::control, and
/// DynamicsObserver (pendavg/dynamics.hpp), which is a RunControl with a trajectory callback.
struct RunControl {
  std::function<void(double fraction)> progress;
  const std::atomic<bool>* stop = nullptr;
  bool stop_requested() const { return stop != nullptr && stop->load(std::memory_order_relaxed); }
  void report(double fraction) const {
    if (progress) progress(fraction);
  }
};

/// A run stopped through RunControl::stop before it finished anything it could report.
struct PENDAVG_EXPORT interrupted : std::runtime_error {
  using std::runtime_error::runtime_error;
};

enum class Method {
  series,                   ///< the paper's series, eq. ave-K1-result (N = 2)
  reduced_integral,         ///< the exact 1-D reduced integral (N = 2; src/engine/double_pendulum/)
  high_temperature_limit,   ///< beta -> 0 (elliptic K/E for N = 2)
  low_temperature_limit,    ///< beta -> infinity (1/2 each)
  torus_trapezoid,          ///< any N: periodic trapezoid on the reduced (N-1)-torus
  torus_gauss_legendre,     ///< any N: Gauss-Legendre tensor rule on the reduced torus
  qmc,                      ///< any N: randomized lattice QMC over the von Mises law
  transfer,                 ///< any N: the transfer operator along the chain (README "Large N")
  /// any N at large beta: Richardson extrapolation in 1/beta of a torus or qmc method's values
  /// at two lower temperatures towards the beta -> infinity limit (src/average.cpp)
  low_temperature_extrapolation,
  microcanonical,           ///< exact averages at fixed energy (src/engine/microcanonical/)
  dynamics_nve,             ///< time averages along a RATTLE + Yoshida-4 trajectory (fixed energy)
  dynamics_langevin,        ///< time averages along constrained Langevin (BAOAB + RATTLE)
  /// N = 2: the exact 1-D reduced integral's finite Graf sums in ball arithmetic with proven
  /// tails (AverageOptions::certified; every error a bound: src/engine/certified.md)
  certified_integral,
};

/// Stable lower-case name used in the CLI and in tables ("series", "integral", ...).
PENDAVG_EXPORT const char* method_name(Method m);

/// What an error promises (see the header comment; `statistical` has a confidence that depends on
/// the method: 99.9% for qmc, one standard error for dynamics time averages).
enum class ErrorKind { bound, estimate, statistical };

/// "bound", "estimate" or "statistical".
PENDAVG_EXPORT const char* error_kind_name(ErrorKind kind);

/// What `evaluations` counts.
enum class WorkUnit {
  terms,    ///< series terms (or exact finite-sum terms)
  nodes,    ///< quadrature nodes (integrand evaluations)
  samples,  ///< QMC points summed over the random shifts
  steps,    ///< time steps of a trajectory
};

/// "terms", "nodes", "samples" or "steps".
PENDAVG_EXPORT const char* work_unit_name(WorkUnit unit);

/// One number with its absolute error and what that error promises.
template <class Real>
struct Estimate {
  Real value{};
  Real error{};
  ErrorKind kind = ErrorKind::estimate;
  bool operator==(const Estimate&) const = default;
};

/// The torus rules' refinement (method torus_trapezoid or torus_gauss_legendre).
template <class Real>
struct TorusDiagnostics {
  std::size_t points_per_dim = 0;  ///< n of the final level
  double grid_points = 0;          ///< n^(N-1) of the final level (before the mirror halving)
  std::size_t levels = 0;          ///< refinement levels evaluated
  /// Z = <exp(log sqrt det A - log_hadamard - S) I0(R)> over the uniform torus (the partition
  /// function up to known factors), with its error.
  Estimate<Real> mean_weight;
};

/// The randomized lattice QMC run (method qmc).
template <class Real>
struct QmcDiagnostics {
  std::size_t points = 0;  ///< lattice points per shift
  std::size_t shifts = 0;  ///< independent random shifts
  /// Jackknife standard errors (1 sigma) over the shifts; the reported errors are `sigmas` times
  /// these plus a rounding allowance.
  std::vector<Real> beta_kinetic_standard_error, cos_angle_standard_error,
      beta2_kinetic_variance_standard_error;
  /// The multiplier used: by default the 99.9% two-sided Student-t quantile for shifts - 1
  /// degrees of freedom (4.07 for 16 shifts).
  double sigmas = 0;
  /// Kish's effective sample size of the pooled weights over points * shifts.
  Real effective_sample_fraction{};
};

/// The transfer operator's refinement (method transfer).
template <class Real>
struct TransferDiagnostics {
  std::size_t angle_nodes = 0;     ///< n of the final level (nodes per angle)
  std::size_t pivot_nodes = 0;     ///< m of the final level (Chebyshev nodes per pivot u_j)
  std::size_t levels = 0;          ///< levels evaluated (angle ladder and pivot checks)
  double kernel_evaluations = 0;   ///< (phi_j, u_j, phi_{j+1}) triples over all levels and sweeps
};

/// Thermal averages of one chain at one inverse temperature (or in one of its limits). Arrays have
/// one entry per particle, index i = particle i + 1 of the paper.
template <class Real>
struct Averages {
  std::vector<Estimate<Real>> beta_kinetic;            ///< beta <K_i>
  std::vector<Estimate<Real>> cos_angle;               ///< <cos phi_i>
  std::vector<Estimate<Real>> beta2_kinetic_variance;  ///< beta^2 Var K_i
  /// <K_1>/<K_2>; empty for a single pendulum (N = 1).
  std::optional<Estimate<Real>> ratio;
  /// beta <K_i^(c)>, K_i^(c) = p_i phidot_i / 2: 1/2 exactly for every chain (generalized
  /// equipartition: <K_i^(c) | phi> = 1/(2 beta) for every angle; src/engine/README.md), reported
  /// as the built-in check it is (error 0, kind bound).
  std::vector<Estimate<Real>> beta_kinetic_canonical;
  /// The paper's diagonal approximation, eq. ke-linear-tave-1, beta<K_i> ~ (m_i/2) sum_{j<=i}
  /// 1/S_j: beside the exact values, never instead of them (it is exact in no limit). An
  /// approximation, not an estimate of the average: no error.
  std::vector<Real> diagonal_approximation;
  /// |sum_i beta<K_i> - N/2|: the trace identity sum_i tr X_i = N after the computation.
  Real equipartition_residual{};
  Method method{Method::reduced_integral};
  /// The kind of the errors of beta_kinetic and ratio (the other observables carry their own).
  ErrorKind error_kind = ErrorKind::estimate;
  std::size_t evaluations = 0;  ///< work done, in `work_unit`
  WorkUnit work_unit = WorkUnit::nodes;
  /// false: the requested accuracy was not reached (a bound still holds; an estimate is the last
  /// refinement's and can fall short of the true error)
  bool converged = true;
  /// true: stopped early through RunControl::stop; the values are those of the work finished
  /// (converged = false, and its errors are what converged = false says).
  bool interrupted = false;
  std::optional<TorusDiagnostics<Real>> torus;  ///< torus methods only
  std::optional<QmcDiagnostics<Real>> qmc;      ///< qmc only
  std::optional<TransferDiagnostics<Real>> transfer;  ///< transfer only
};

}  // namespace pendavg
