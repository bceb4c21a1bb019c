// SPDX-License-Identifier: GPL-3.0-or-later
// tests/oracle/dense_traces.hpp -- an independent test oracle for the node quantities of the
// trace formula: dense O(N^3) linear algebra, straight from the paper's definitions.
//
// What it is. For one configuration phi of an N-link chain:
//   * A from eq. a-ij, A_nk = (sum_{i >= max(n,k)} m_i) l_n l_k cos(phi_n - phi_k);
//   * A^(i) from its definition below eq. Ki-linear-dotvarphi-Ai, A^(i)_jk = m_i l_j l_k
//     cos(phi_j - phi_k) for j, k <= i, else 0;
//   * X_i = A^(i) A^{-1} formed explicitly (LU with full pivoting), and tr X_i, tr(X_i X_i),
//     log sqrt(det A), and diag(A^{-1} A) (the canonical energies, eq. ke-canonical-i:
//     beta <K_i^(c) | phi> = (A^{-1} A)_ii / 2).
// Second, src/engine/README.md, 'Traces in O(N)' taken literally (Fixman's Cartesian form): the
// tridiagonal H = C M^{-1} C^T, G = H^{-1} by a dense inverse, det A = (prod m_j l_j)^2 det H and
// tr X_i = 2 - [G_ii + G_{i+1,i+1} - 2 cos(phi_{i+1} - phi_i) G_{i,i+1}] / m_i.
// Neither shares algebra with the library's articulated-body recurrences (src/trace_formula.cpp).
//
// When to use it: ONLY as a test oracle, for N up to a few dozen. It costs O(N^4) per node
// (N products of N x N matrices). In double it loses about log10(cond A) digits, and the
// Fixman traces lose log10(1 / tr X_i) more to cancellation; run it in MPFR with enough guard
// digits when it is the reference.
#pragma once

#include <boost/multiprecision/eigen.hpp>
#include <boost/multiprecision/mpfr.hpp>

#include <Eigen/Dense>

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <vector>

namespace pendavg::oracle {

template <class Real>
struct DenseTraces {
  Real log_sqrt_det_A;                 ///< from the LU determinant of A
  std::vector<Real> trace_X;           ///< tr(A^(i) A^{-1})
  std::vector<Real> trace_X_squared;   ///< tr(A^(i) A^{-1} A^(i) A^{-1})
  std::vector<Real> canonical_diagonal;  ///< (A^{-1} A)_ii
  Real log_sqrt_det_A_fixman;          ///< log sqrt((prod m_j l_j)^2 det H)   (src/engine/README.md, 'Traces in O(N)')
  std::vector<Real> trace_X_fixman;    ///< 2 - [G_ii + G_{i+1,i+1} - 2 c G_{i,i+1}] / m_i
};

/// Dense evaluation at phi; masses, lengths and phi have N entries each.
template <class Real>
DenseTraces<Real> dense_traces(const std::vector<Real>& masses, const std::vector<Real>& lengths,
                               const std::vector<Real>& phi) {
  using std::cos;
  using std::log;
  using Matrix = Eigen::Matrix<Real, Eigen::Dynamic, Eigen::Dynamic>;
  const Eigen::Index n = static_cast<Eigen::Index>(masses.size());
  auto at = [](const std::vector<Real>& v, Eigen::Index i) -> const Real& {
    return v[static_cast<std::size_t>(i)];
  };

  // Tail masses S_j, summed literally.
  std::vector<Real> tail(masses.size(), Real(0));
  for (Eigen::Index j = 0; j < n; ++j) {
    for (Eigen::Index i = j; i < n; ++i) tail[static_cast<std::size_t>(j)] += at(masses, i);
  }

  Matrix a(n, n);
  for (Eigen::Index j = 0; j < n; ++j) {
    for (Eigen::Index k = 0; k < n; ++k) {
      a(j, k) = at(tail, std::max(j, k)) * at(lengths, j) * at(lengths, k) *
                cos(at(phi, j) - at(phi, k));
    }
  }
  const Eigen::FullPivLU<Matrix> lu(a);
  const Matrix a_inv = lu.inverse();

  DenseTraces<Real> out;
  out.log_sqrt_det_A = log(lu.determinant()) / 2;
  const Matrix canonical = a_inv * a;
  for (Eigen::Index i = 0; i < n; ++i) {
    Matrix a_i = Matrix::Zero(n, n);
    for (Eigen::Index j = 0; j <= i; ++j) {
      for (Eigen::Index k = 0; k <= i; ++k) {
        a_i(j, k) = at(masses, i) * at(lengths, j) * at(lengths, k) *
                    cos(at(phi, j) - at(phi, k));
      }
    }
    const Matrix x = a_i * a_inv;
    out.trace_X.push_back(x.trace());
    out.trace_X_squared.push_back((x * x).trace());
    out.canonical_diagonal.push_back(canonical(i, i));
  }

  // src/engine/README.md, 'Traces in O(N)': H = C M^{-1} C^T with C the unit constraint gradients.
  Matrix h = Matrix::Zero(n, n);
  for (Eigen::Index j = 0; j < n; ++j) {
    h(j, j) = 1 / at(masses, j) + (j > 0 ? Real(1 / at(masses, j - 1)) : Real(0));
    if (j + 1 < n) {
      h(j, j + 1) = -cos(at(phi, j + 1) - at(phi, j)) / at(masses, j);
      h(j + 1, j) = h(j, j + 1);
    }
  }
  const Eigen::FullPivLU<Matrix> h_lu(h);
  const Matrix g = h_lu.inverse();
  Real log_mass_length = 0;
  for (Eigen::Index j = 0; j < n; ++j) log_mass_length += log(at(masses, j) * at(lengths, j));
  out.log_sqrt_det_A_fixman = log_mass_length + log(h_lu.determinant()) / 2;
  for (Eigen::Index i = 0; i < n; ++i) {
    Real bracket = g(i, i);
    if (i + 1 < n) {
      bracket += g(i + 1, i + 1) - 2 * cos(at(phi, i + 1) - at(phi, i)) * g(i, i + 1);
    }
    out.trace_X_fixman.push_back(2 - bracket / at(masses, i));
  }
  return out;
}

}  // namespace pendavg::oracle
