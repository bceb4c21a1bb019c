// SPDX-License-Identifier: GPL-3.0-or-later
// A user's program in multiprecision: beta<K_i> of the double pendulum to 30 digits.
#include <pendavg/mpfr.hpp>
#include <pendavg/pendavg.hpp>

#include <cstdio>
#include <string>

int main() {
  using pendavg::mpfr_real;
  constexpr int digits = 30;
  // Inputs exact to the digits asked for: construct them at the call's working precision.
  const pendavg::working_precision precision(digits + pendavg::guard_digits);
  const pendavg::Chain<mpfr_real> pendulum({mpfr_real("0.5"), mpfr_real("0.5")},
                                           {mpfr_real(1), mpfr_real(1)});
  pendavg::AverageOptions options;
  options.digits = digits;
  const pendavg::Averages<mpfr_real> a = pendavg::average(pendulum, mpfr_real(1), options);
  std::printf("N2_30 %s %s", pendavg::method_name(a.method), pendavg::error_kind_name(a.error_kind));
  for (const pendavg::Estimate<mpfr_real>& k : a.beta_kinetic)
    std::printf(" %s", k.value.str(digits + 5, std::ios::scientific).c_str());
  std::printf("\n");
  return 0;
}
