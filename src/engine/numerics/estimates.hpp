// SPDX-License-Identifier: GPL-3.0-or-later
// engine/numerics/estimates.hpp -- helpers the engines share to fill an Averages<Real>
// (result.hpp).
#pragma once

#include "pendavg/chain.hpp"
#include "pendavg/result.hpp"
#include "pendavg/trace_formula.hpp"

#include <cmath>
#include <cstddef>
#include <vector>

namespace pendavg {

/// Estimates from parallel value and error arrays, all of one kind.
template <class Real>
std::vector<Estimate<Real>> estimates(const std::vector<Real>& values,
                                      const std::vector<Real>& errors, ErrorKind kind) {
  std::vector<Estimate<Real>> out(values.size());
  for (std::size_t i = 0; i < values.size(); ++i) out[i] = {values[i], errors[i], kind};
  return out;
}

/// <K_1>/<K_2> from beta<K_1>, beta<K_2> with the error of a ratio plus 4 ulps (u: unit
/// roundoff), of the kind of the beta<K_i>.
template <class Real>
Estimate<Real> kinetic_ratio(const Estimate<Real>& k1, const Estimate<Real>& k2, const Real& u) {
  using std::abs;
  const Real ratio = k1.value / k2.value;
  return {ratio, k1.error / k2.value + ratio * (k2.error / k2.value + 4 * u), k1.kind};
}

/// What every engine reports beside its own observables: beta<K_i^(c)> = 1/2 exactly, the paper's
/// diagonal approximation and the equipartition residual |sum_i beta<K_i> - N/2|
/// (src/engine/README.md, 'Equipartition', 'Diagonal approximation', 'Trace formula').
template <class Real>
void add_chain_extras(Averages<Real>& a, const Chain<Real>& chain) {
  using std::abs;
  const std::size_t n = chain.size();
  a.beta_kinetic_canonical.assign(n, Estimate<Real>{Real(1) / 2, Real(0), ErrorKind::bound});
  a.diagonal_approximation = diagonal_approximation(chain);
  Real kinetic_sum = 0;
  for (const Estimate<Real>& k : a.beta_kinetic) kinetic_sum += k.value;
  a.equipartition_residual = abs(kinetic_sum - Real(static_cast<double>(n)) / 2);
}

}  // namespace pendavg
