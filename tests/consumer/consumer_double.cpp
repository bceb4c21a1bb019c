// SPDX-License-Identifier: GPL-3.0-or-later
// A user's program: beta<K_i> of three chains through the one entry point, in double.
// Prints "label value..." lines that tests/consumer/run.sh compares with the pendavg CLI.
#include <pendavg/pendavg.hpp>

#include <cstdio>
#include <vector>

namespace {

void print(const char* label, const pendavg::Averages<double>& a) {
  std::printf("%s %s %s", label, pendavg::method_name(a.method), pendavg::error_kind_name(a.error_kind));
  for (const pendavg::Estimate<double>& k : a.beta_kinetic) std::printf(" %.15e", k.value);
  std::printf("\n");
}

}  // namespace

int main() {
  // The double pendulum of the paper's Fig. 5 (mu1 = 0.5, l2 = 1) at beta = 1.
  const pendavg::Chain<double> pendulum({0.5, 0.5}, {1.0, 1.0});
  print("N2", pendavg::average(pendulum, 1.0));
  // A 3-link chain with unequal masses and lengths, g = 9.81.
  const pendavg::Chain<double> three({1.0, 2.0, 0.5}, {1.0, 0.5, 2.0}, 9.81);
  print("N3", pendavg::average(three, 0.3));
  // An 8-link unit chain (automatic: the transfer operator, here to 1e-8).
  const pendavg::Chain<double> eight(std::vector<double>(8, 1.0), std::vector<double>(8, 1.0));
  pendavg::AverageOptions options;
  options.tolerance = 1e-8;
  print("N8", pendavg::average(eight, 1.0, options));
  // A bad input is one exception with a one-line message.
  try {
    pendavg::average(pendulum, -1.0);
    return 1;
  } catch (const pendavg::invalid_input& bad) {
    std::printf("bad %s\n", bad.what());
  }
  return 0;
}
