// SPDX-License-Identifier: GPL-3.0-or-later
// src/io/exact_values.cpp -- see exact_values.hpp.
#include "io/exact_values.hpp"

#include "io/requests.hpp"

#include "pendavg/pendavg.hpp"

#include <cmath>

namespace pendavg::io {

double initial_excitation(const Chain<double>& chain, const ChainState<double>& state,
                          const std::vector<double>& phi) {
  double potential = 0;
  for (std::size_t j = 0; j < chain.size(); ++j) {
    const double s = std::sin(phi[j] / 2);
    potential += 2 * chain.potential_coefficient(j) * s * s;
  }
  return observables(chain, state).kinetic_total + potential;
}

ExactValues microcanonical_values(const Chain<double>& chain, double excitation) {
  MicrocanonicalOptions options;
  options.threads = hardware_threads();
  const MicrocanonicalAverages<double> r =
      microcanonical_average_excitation(chain, excitation, options);
  ExactValues out;
  out.excitation = r.excitation;
  for (const Estimate<double>& v : r.kinetic_variance) {
    out.variance.push_back(v.value);
    out.variance_error.push_back(v.error);
  }
  for (const Estimate<double>& k : r.kinetic) {
    out.kinetic.push_back(k.value);
    out.kinetic_error.push_back(k.error);
  }
  for (const Estimate<double>& c : r.cos_angle) {
    out.cos_angle.push_back(c.value);
    out.cos_angle_error.push_back(c.error);
  }
  out.kinetic_canonical = r.kinetic_canonical.value;
  out.kinetic_canonical_error = r.kinetic_canonical.error;
  out.method = std::string(method_name(r.method)) + "/" + method_name(r.quadrature);
  out.error_kind = error_kind_name(r.error_kind);
  out.kinetic_canonical_error_kind = error_kind_name(r.kinetic_canonical.kind);
  out.cos_angle_error_kind = error_kind_name(r.cos_angle.front().kind);
  out.variance_error_kind = error_kind_name(r.kinetic_variance.front().kind);
  return out;
}

ExactValues canonical_values(const Chain<double>& chain, double beta) {
  AverageOptions options;
  options.threads = hardware_threads();
  const Averages<double> a = average(chain, beta, options);
  ExactValues out;
  for (std::size_t i = 0; i < chain.size(); ++i) {
    out.kinetic.push_back(a.beta_kinetic[i].value / beta);
    out.kinetic_error.push_back(a.beta_kinetic[i].error / beta);
    out.cos_angle.push_back(a.cos_angle[i].value);
    out.cos_angle_error.push_back(a.cos_angle[i].error);
    // Var K_i = beta^2 Var K_i / beta^2 (divided twice: beta^2 may underflow where the
    // quotient does not)
    out.variance.push_back(a.beta2_kinetic_variance[i].value / beta / beta);
    out.variance_error.push_back(a.beta2_kinetic_variance[i].error / beta / beta);
  }
  // beta <K_i^(c)> = 1/2 exactly (src/engine/README.md, "Equipartition").
  out.kinetic_canonical = a.beta_kinetic_canonical.front().value / beta;
  out.kinetic_canonical_error = a.beta_kinetic_canonical.front().error / beta;
  out.method = method_name(a.method);
  out.error_kind = error_kind_name(a.error_kind);
  out.kinetic_canonical_error_kind = error_kind_name(a.beta_kinetic_canonical.front().kind);
  out.cos_angle_error_kind = error_kind_name(a.cos_angle.front().kind);
  out.variance_error_kind = error_kind_name(a.beta2_kinetic_variance.front().kind);
  return out;
}

}  // namespace pendavg::io
