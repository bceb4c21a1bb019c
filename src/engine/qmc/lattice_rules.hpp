// SPDX-License-Identifier: GPL-3.0-or-later
// engine/qmc/lattice_rules.hpp -- component-by-component (CBC) constructions of rank-1 lattice
// rules for qmc_average: the generating vectors of qmc/lattice_table.hpp were made by
// fast_cbc_generating_vector, and a chain beyond their 256 dimensions passes its own.
//
// Equations (src/engine/qmc/README.md, 'Lattice rules'):
//     x_k = frac(k z / n),  k = 0 .. n-1,  n = 2^m
//     P(z) = -1 + (1/n) sum_k prod_j (1 + gamma_j omega({k z_j / n}))    (squared worst-case error)
//     omega(x) = 2 pi^2 B_2(x),  B_2(x) = x^2 - x + 1/6                  (Korobov space, alpha = 2)
// CBC: z_1 = 1, then each z_j minimizes P over the odd z_j < n/2 with z_1..z_{j-1} fixed, ties to
// the smaller z. The fast version (Nuyens-Cools) writes the odd residues mod 2^r as +-5^a, which
// turns the criterion into cyclic correlations done by FFT (GSL's radix-2 complex FFT).
#pragma once

#include "pendavg/average.hpp"

#include <gsl/gsl_errno.h>
#include <gsl/gsl_fft_complex.h>

#include <algorithm>
#include <cmath>
#include <complex>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <stdexcept>
#include <vector>

namespace pendavg::detail::qmc {

/// The Korobov-space kernel omega(k / n), k = 0..n-1, of smoothness alpha = 2 (2 pi^2 B_2(x))
/// or 4 (-(4 pi^4 / 3) B_4(x)): the one-dimensional factor of the CBC criterion.
inline std::vector<double> korobov_kernel(std::uint64_t n, int alpha) {
  const double two_pi2 = 2 * 9.869604401089358;  // 2 pi^2
  std::vector<double> omega(n);
  for (std::uint64_t k = 0; k < n; ++k) {
    const double x = static_cast<double>(k) / static_cast<double>(n);
    omega[k] = alpha == 4 ? -(two_pi2 * 9.869604401089358 / 3) *
                                (x * x * x * x - 2 * x * x * x + x * x - 1.0 / 30.0)
                          : two_pi2 * (x * x - x + 1.0 / 6.0);
  }
  return omega;
}

/// Component-by-component construction (Sloan-Reztsov; Nuyens-Cools) of a rank-1 lattice rule
/// with n = 2^m points in d dimensions for the Korobov space of smoothness alpha = 2 with product
/// weights gamma_j: z_1 = 1, then each z_j in {1, 3, ..., n/2 - 1} minimizes the squared worst-case
/// error  P(z) = -1 + (1/n) sum_k prod_j (1 + gamma_j 2 pi^2 B_2({k z_j / n})),
/// B_2(x) = x^2 - x + 1/6, ties to the smaller z. Cost O(d n^2 / 4) (plain, not the FFT version):
/// use it offline or for n <= 2^12.
inline std::vector<std::uint32_t> cbc_generating_vector(unsigned m, std::size_t d,
                                                        const std::vector<double>& gamma,
                                                        int alpha = 2) {
  const std::uint64_t n = std::uint64_t(1) << m;
  const std::vector<double> omega = korobov_kernel(n, alpha);
  std::vector<double> product(n, 1.0);
  std::vector<std::uint32_t> z;
  for (std::size_t j = 0; j < d; ++j) {
    const double g = j < gamma.size() ? gamma[j] : gamma.back();
    std::uint64_t best = 1;
    if (j > 0) {
      double best_value = std::numeric_limits<double>::infinity();
      for (std::uint64_t c = 1; c < n / 2; c += 2) {
        double sum = 0;
        // k = 0 adds the same prod_j (1 + gamma_j omega(0)) for every c: left out.
        for (std::uint64_t k = 1; k < n; ++k) sum += product[k] * (1 + g * omega[(k * c) & (n - 1)]);
        if (sum < best_value) {
          best_value = sum;
          best = c;
        }
      }
    }
    z.push_back(static_cast<std::uint32_t>(best));
    for (std::uint64_t k = 0; k < n; ++k) product[k] *= 1 + g * omega[(k * best) & (n - 1)];
  }
  return z;
}

/// In-place complex FFT of a power-of-two length (sign -1: forward, +1: inverse without the
/// 1/n), by GSL's radix-2 transform (std::complex<double> is laid out as GSL's packed {re, im}
/// pairs). The generating vectors it gives are those of the hand-written radix-2 FFT it replaced,
/// for every size and dimension the library uses (tests/engine/qmc/test_lattice_fft.cpp).
inline void lattice_fft(std::vector<std::complex<double>>& a, int sign) {
  double* data = reinterpret_cast<double*>(a.data());
  const int status = sign < 0 ? gsl_fft_complex_radix2_forward(data, 1, a.size())
                              : gsl_fft_complex_radix2_backward(data, 1, a.size());
  if (status != GSL_SUCCESS) throw std::logic_error("lattice_fft: the length is no power of two");
}

/// The same construction and criterion as cbc_generating_vector, in O(d n log n) (Nuyens-Cools
/// fast CBC, for n = 2^m): the odd residues mod 2^r (r >= 3) are {+-5^a}, the kernel is even
/// (omega(1 - x) = omega(x)), so for the k with 2-adic valuation s the criterion of the
/// candidate 5^a is a cyclic correlation of length 2^(m-s-2), done by FFT. Candidates z and
/// n - z are equivalent; the one below n/2 is returned. Picks the same z as the plain version
/// up to ties within rounding (~1e-13 relative). m <= 24; n = 2^20 in 256 dimensions: ~10 s.
/// `fft(a, sign)` transforms in place as lattice_fft does (a parameter so that the tests can hold
/// the construction to the hand-written FFT it used before).
template <class Fft>
std::vector<std::uint32_t> fast_cbc_generating_vector_with(unsigned m, std::size_t d,
                                                           const std::vector<double>& gamma,
                                                           int alpha, const Fft& fft) {
  if (m < 3 || m > 24) throw invalid_input("fast_cbc_generating_vector: 3 <= m <= 24");
  const std::uint64_t n = std::uint64_t(1) << m;
  const std::vector<double> omega = korobov_kernel(n, alpha);
  // Per valuation s (modulus n_s = 2^(m-s) >= 8, L_s = n_s / 4): the powers of 5 mod n_s and
  // the transformed kernel W_s[t] = omega(2^s (5^t mod n_s)).
  struct Level {
    unsigned s;
    std::size_t length;
    std::vector<std::uint64_t> power;  // 5^t mod n_s
    std::vector<std::complex<double>> kernel_hat;
  };
  std::vector<Level> levels;
  for (unsigned s = 0; s + 3 <= m; ++s) {
    Level lv;
    lv.s = s;
    const std::uint64_t ns = n >> s;
    lv.length = static_cast<std::size_t>(ns / 4);
    lv.power.resize(lv.length);
    std::vector<std::complex<double>> w(lv.length);
    std::uint64_t p = 1;
    for (std::size_t t = 0; t < lv.length; ++t) {
      lv.power[t] = p;
      w[t] = omega[(p << s) & (n - 1)];
      p = (p * 5) & (ns - 1);
    }
    fft(w, -1);
    lv.kernel_hat = std::move(w);
    levels.push_back(std::move(lv));
  }
  const std::size_t candidates = static_cast<std::size_t>(n / 4);  // a = 0 .. n/4 - 1
  std::vector<double> product(n, 1.0), criterion(candidates);
  std::vector<std::uint32_t> z;
  for (std::size_t j = 0; j < d; ++j) {
    const double g = j < gamma.size() ? gamma[j] : gamma.back();
    std::uint64_t best = 1;
    if (j > 0) {
      std::fill(criterion.begin(), criterion.end(), 0.0);
      for (const Level& lv : levels) {
        const std::uint64_t ns = n >> lv.s;
        std::vector<std::complex<double>> q(lv.length);
        for (std::size_t b = 0; b < lv.length; ++b) {
          const std::uint64_t o = lv.power[b];
          q[b] = product[(o << lv.s) & (n - 1)] + product[((ns - o) << lv.s) & (n - 1)];
        }
        fft(q, -1);
        // Correlation S[a] = sum_b Q[b] W[a + b]: inverse FFT of conj(Q^) W^.
        for (std::size_t t = 0; t < lv.length; ++t) q[t] = std::conj(q[t]) * lv.kernel_hat[t];
        fft(q, +1);
        const double inv = 1.0 / static_cast<double>(lv.length);
        for (std::size_t a = 0; a < candidates; ++a) criterion[a] += q[a % lv.length].real() * inv;
      }
      double best_value = std::numeric_limits<double>::infinity();
      std::uint64_t p = 1;
      for (std::size_t a = 0; a < candidates; ++a) {
        const std::uint64_t c = p < n / 2 ? p : n - p;
        // Ties (within rounding) to the smaller z, as in the plain construction.
        const double tol = 1e-13 * std::abs(criterion[a]);
        if (criterion[a] < best_value - tol ||
            (criterion[a] <= best_value + tol && c < best)) {
          if (criterion[a] < best_value) best_value = criterion[a];
          best = c;
        }
        p = (p * 5) & (n - 1);
      }
    }
    z.push_back(static_cast<std::uint32_t>(best));
    for (std::uint64_t k = 0; k < n; ++k) product[k] *= 1 + g * omega[(k * best) & (n - 1)];
  }
  return z;
}

/// fast_cbc_generating_vector_with GSL's FFT (lattice_fft).
inline std::vector<std::uint32_t> fast_cbc_generating_vector(unsigned m, std::size_t d,
                                                             const std::vector<double>& gamma,
                                                             int alpha = 2) {
  return fast_cbc_generating_vector_with(m, d, gamma, alpha, lattice_fft);
}

}  // namespace pendavg::detail::qmc
