// SPDX-License-Identifier: GPL-3.0-or-later
// The fast CBC construction of the qmc lattices (src/engine/qmc/lattice_rules.hpp) runs its cyclic
// correlations with GSL's radix-2 FFT. It replaced a hand-written radix-2 FFT, kept here as the
// reference: the generating vectors of both must agree for every size and dimension the library
// uses -- the built-in table (n = 2^10 .. 2^20 in 256 dimensions, gamma_j = 0.01) and the tests'
// constructions -- and for the smaller sizes down to the construction's minimum n = 2^3. The
// transforms themselves differ in rounding; only the choices of z must not.
#include "engine/qmc/lattice_rules.hpp"
#include "engine/qmc/lattice_table.hpp"

#include <catch2/catch.hpp>

#include <algorithm>
#include <cmath>
#include <complex>
#include <cstddef>
#include <cstdint>
#include <utility>
#include <vector>

namespace {

namespace q = pendavg::detail::qmc;

/// The hand-written in-place radix-2 FFT the construction used before GSL's (sign -1: forward,
/// +1: inverse without the 1/n), size 2^k: the reference of these tests.
void reference_radix2_fft(std::vector<std::complex<double>>& a, int sign) {
  const std::size_t n = a.size();
  for (std::size_t i = 1, j = 0; i < n; ++i) {
    std::size_t bit = n >> 1;
    for (; j & bit; bit >>= 1) j ^= bit;
    j ^= bit;
    if (i < j) std::swap(a[i], a[j]);
  }
  std::vector<std::complex<double>> twiddle(n / 2 + 1);
  for (std::size_t len = 2; len <= n; len <<= 1) {
    const double angle = sign * 2 * 3.141592653589793238462643 / static_cast<double>(len);
    for (std::size_t k = 0; k < len / 2; ++k)
      twiddle[k] = std::polar(1.0, angle * static_cast<double>(k));
    for (std::size_t i = 0; i < n; i += len) {
      for (std::size_t k = 0; k < len / 2; ++k) {
        const std::complex<double> w = twiddle[k];
        const std::complex<double> x = a[i + k], y = a[i + k + len / 2] * w;
        a[i + k] = x + y;
        a[i + k + len / 2] = x - y;
      }
    }
  }
}

std::vector<std::uint32_t> reference_fast_cbc(unsigned m, std::size_t d,
                                              const std::vector<double>& gamma, int alpha) {
  return q::fast_cbc_generating_vector_with(m, d, gamma, alpha, reference_radix2_fft);
}

std::vector<std::uint32_t> table_row(unsigned m) {
  const auto& row = q::lattice_table[m - q::lattice_table_min_log2];
  return std::vector<std::uint32_t>(row, row + q::lattice_max_dimension);
}

}  // namespace

TEST_CASE("lattice FFT: GSL's transform matches the reference to rounding", "[qmc][lattice]") {
  for (std::size_t n : {std::size_t(2), std::size_t(4), std::size_t(8), std::size_t(64),
                        std::size_t(1024), std::size_t(65536)}) {
    std::vector<std::complex<double>> a(n);
    for (std::size_t i = 0; i < n; ++i) {
      const double x = static_cast<double>(i);
      a[i] = {std::cos(0.37 * x) + 1.0 / (x + 1), std::sin(1.1 * x)};
    }
    for (int sign : {-1, +1}) {
      std::vector<std::complex<double>> x = a, y = a;
      q::lattice_fft(x, sign);
      reference_radix2_fft(y, sign);
      double scale = 0, diff = 0;
      for (std::size_t i = 0; i < n; ++i) {
        scale = std::max(scale, std::abs(y[i]));
        diff = std::max(diff, std::abs(x[i] - y[i]));
      }
      CHECK(diff <= 1e-13 * scale);
    }
  }
}

TEST_CASE("lattice FFT: the generating vectors are the reference FFT's", "[qmc][lattice]") {
  const std::vector<double> gamma(256, 0.01);
  // The built-in table's construction (gamma_j = 0.01, 256 dimensions) below the table's sizes
  // and over its first rows (the larger rows: the slow test below).
  for (unsigned m = 3; m <= 14; ++m) {
    INFO("m = " << m);
    const std::vector<std::uint32_t> z = q::fast_cbc_generating_vector(m, 256, gamma, 2);
    CHECK(z == reference_fast_cbc(m, 256, gamma, 2));
    if (m >= q::lattice_table_min_log2) CHECK(z == table_row(m));
  }
  // The tests' other constructions: fewer and more dimensions, weights 1/j (an exact tie broken
  // to the smaller z), smoothness alpha = 4.
  CHECK(q::fast_cbc_generating_vector(11, 24, gamma, 2) == reference_fast_cbc(11, 24, gamma, 2));
  const std::vector<double> wide(300, 0.01);
  CHECK(q::fast_cbc_generating_vector(10, 300, wide, 2) == reference_fast_cbc(10, 300, wide, 2));
  std::vector<double> harmonic;
  for (int j = 1; j <= 64; ++j) harmonic.push_back(1.0 / j);
  for (unsigned m : {10u, 12u}) {
    CHECK(q::fast_cbc_generating_vector(m, 64, harmonic, 2) == reference_fast_cbc(m, 64, harmonic, 2));
    CHECK(q::fast_cbc_generating_vector(m, 64, harmonic, 4) == reference_fast_cbc(m, 64, harmonic, 4));
  }
}

TEST_CASE("lattice FFT: every row of the built-in table", "[qmc][lattice][.slow]") {
  // n = 2^15 .. 2^20 in 256 dimensions: about a minute for both constructions.
  const std::vector<double> gamma(256, 0.01);
  for (unsigned m = 15; m <= q::lattice_rows_max_log2; ++m) {
    INFO("m = " << m);
    const std::vector<std::uint32_t> z = q::fast_cbc_generating_vector(m, 256, gamma, 2);
    CHECK(z == reference_fast_cbc(m, 256, gamma, 2));
    CHECK(z == table_row(m));
  }
}
