// pendavg/result.hpp -- what every average comes back as: value + error estimate + work + method.
//
// Following GSL's {value, error} and Arb's balls: each value carries an absolute error
// estimate that is meant to cover the true error (tests look for estimates that do not).
// "Did not converge" is a status with a still-valid estimate, never a silent wrong value.
#pragma once

#include <cstddef>
#include <string>
#include <vector>

namespace pendavg {

enum class Method {
  series,                   ///< the paper's series, eq. ave-K1-result (N = 2)
  reduced_integral,         ///< the exact 1-D reduced integral, MATH.md Sec. 2 (N = 2)
  high_temperature_limit,   ///< beta -> 0 (elliptic K/E for N = 2)
  low_temperature_limit,    ///< beta -> infinity (1/2 each)
  torus_trapezoid,          ///< any N: periodic trapezoid on the reduced (N-1)-torus
  torus_gauss_legendre,     ///< any N: Gauss-Legendre tensor rule on the reduced torus
  qmc,                      ///< any N: randomized lattice QMC over the von Mises law
  microcanonical,           ///< exact microcanonical averages at fixed energy (MATH.md Sec. 7)
  dynamics_nve,             ///< time averages along a RATTLE + Yoshida-4 trajectory (fixed energy)
  dynamics_langevin,        ///< time averages along constrained Langevin (BAOAB + RATTLE)
};

/// Stable lower-case name used in the CLI and in tables ("series", "integral", ...).
const char* method_name(Method m);

/// One number with its absolute error estimate.
template <class Real>
struct Estimate {
  Real value{};
  Real error{};
};

/// Thermal averages of one chain at one beta. Arrays have one entry per particle.
template <class Real>
struct Averages {
  std::vector<Real> beta_kinetic;         ///< beta <K_i>
  std::vector<Real> beta_kinetic_error;   ///< absolute error estimates of beta <K_i>
  std::vector<Real> cos_angle;            ///< <cos phi_i>
  std::vector<Real> cos_angle_error;
  std::vector<Real> beta2_kinetic_variance;  ///< beta^2 Var K_i
  std::vector<Real> beta2_kinetic_variance_error;
  Real ratio{};        ///< <K_1>/<K_2> (N = 2)
  Real ratio_error{};
  Method method{Method::reduced_integral};
  std::size_t evaluations = 0;  ///< series terms or quadrature nodes actually used
  bool converged = true;        ///< false: the requested tolerance was not reached
};

}  // namespace pendavg
