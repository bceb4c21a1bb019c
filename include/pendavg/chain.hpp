// SPDX-License-Identifier: GPL-3.0-or-later
// pendavg/chain.hpp -- the model: a planar chain of N point masses on massless rigid links,
// hanging from a fixed pivot in uniform gravity (paper Sec. II, eqs. a-ij, potential-energy).
//
// The model holds only parameters (masses m_i > 0, link lengths l_i > 0, gravity g >= 0).
// The state (inverse temperature beta, energy, angles) is kept apart from it and passed to the
// algorithms explicitly. A chain is validated on construction; an invalid one cannot exist.
#pragma once

#include "pendavg/export.hpp"

#include <cstddef>
#include <stdexcept>
#include <string>
#include <vector>

namespace pendavg {

/// Thrown for invalid physical input (non-positive or non-finite masses, lengths, beta, ...).
/// The message is one line, suitable for a CLI error.
class PENDAVG_EXPORT invalid_input : public std::invalid_argument {
 public:
  using std::invalid_argument::invalid_argument;
};

template <class Real>
class PENDAVG_EXPORT Chain {
 public:
  /// Validates: equal, non-zero counts; every mass and length finite and > 0; g finite and >= 0.
  Chain(std::vector<Real> masses, std::vector<Real> lengths, Real g = Real(1));

  std::size_t size() const { return masses_.size(); }
  const std::vector<Real>& masses() const { return masses_; }
  const std::vector<Real>& lengths() const { return lengths_; }
  const Real& gravity() const { return g_; }
  Real mass(std::size_t i) const { return masses_[i]; }
  Real length(std::size_t i) const { return lengths_[i]; }

  /// M = sum of all masses.
  Real total_mass() const { return tail_masses_.front(); }
  /// S_j = sum_{i >= j} m_i (0-based j), so tail_mass(0) = M.
  Real tail_mass(std::size_t j) const { return tail_masses_[j]; }
  /// gamma_j = g S_j l_j: U(phi) = -sum_j gamma_j cos(phi_j)  (src/engine/README.md, 'Notation').
  Real potential_coefficient(std::size_t j) const { return g_ * tail_masses_[j] * lengths_[j]; }

  /// mu_i = m_i / M for a double pendulum, computed directly (no 1 - mu cancellation).
  Real mass_fraction(std::size_t i) const { return masses_[i] / total_mass(); }

  /// The same model in another number type (Pinocchio's model.cast<Scalar>()).
  template <class Other>
  Chain<Other> cast() const {
    std::vector<Other> m(masses_.begin(), masses_.end()), l(lengths_.begin(), lengths_.end());
    return Chain<Other>(std::move(m), std::move(l), Other(g_));
  }

 private:
  std::vector<Real> masses_, lengths_, tail_masses_;
  Real g_;
};

/// Smallest and largest significant digits a caller may request: 16 runs in double, 17..1000 in
/// MPFR (Real = mpfr_real, pendavg/mpfr.hpp).
inline constexpr int min_digits = 16;
inline constexpr int max_digits = 1000;

/// Guard digits carried beyond the requested ones in every MPFR computation.
inline constexpr int guard_digits = 12;

/// Validates an inverse temperature: finite and > 0. Throws invalid_input otherwise.
template <class Real>
PENDAVG_EXPORT void check_beta(const Real& beta);

/// Validates a requested number of significant digits: exactly 16 for double (its one
/// precision), min_digits..max_digits for MPFR. Throws invalid_input otherwise.
template <class Real>
PENDAVG_EXPORT void check_digits(int digits);

}  // namespace pendavg
