// SPDX-License-Identifier: GPL-3.0-or-later
// tests/refusals.hpp -- what the domain tests ask of a call: the one-line message of its refusal,
// and whether every value and error it returned is finite.
#pragma once

#include "pendavg/pendavg.hpp"

#include <cmath>
#include <string>

namespace pendavg_test {

/// The message of the invalid_input thrown by `f` ("" when none).
template <class F>
std::string rejection(F&& f) {
  try {
    f();
  } catch (const pendavg::invalid_input& e) {
    return e.what();
  }
  return "";
}

/// Every value and error of beta<K_i>, <cos phi_i> and beta^2 Var K_i finite.
template <class Real>
bool all_finite(const pendavg::Averages<Real>& a) {
  using std::isfinite;
  for (const auto* group : {&a.beta_kinetic, &a.cos_angle, &a.beta2_kinetic_variance})
    for (const pendavg::Estimate<Real>& e : *group)
      if (!isfinite(e.value) || !isfinite(e.error)) return false;
  return true;
}

}  // namespace pendavg_test
