// SPDX-License-Identifier: GPL-3.0-or-later
// tests/chains.hpp -- chains the engine tests share.
#pragma once

#include "pendavg/chain.hpp"

#include <cstddef>
#include <vector>

namespace pendavg::test {

/// N equal particles on equal links.
inline Chain<double> uniform_chain(std::size_t n, double mass = 1, double length = 1,
                                   double g = 1) {
  return Chain<double>(std::vector<double>(n, mass), std::vector<double>(n, length), g);
}

}  // namespace pendavg::test
