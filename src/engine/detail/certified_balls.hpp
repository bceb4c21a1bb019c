// SPDX-License-Identifier: GPL-3.0-or-later
// engine/detail/certified_balls.hpp -- the parts of the certified N = 2 engine
// (engine/certified.cpp, derivations in engine/certified.md), declared for its tests: Arb balls
// with owners, the parameters, the Bessel tables, the Fourier moments and the five integrals
// with their proven tails. Only in builds with Arb (PENDAVG_HAS_ARB).
#pragma once

#include "engine/numerics/precision.hpp"
#include "pendavg/chain.hpp"
#include "pendavg/result.hpp"

#include <arb.h>

#include <array>
#include <utility>

namespace pendavg::certified_detail {

/// One Arb ball, owned.
class Ball {
 public:
  Ball() { arb_init(x_); }
  explicit Ball(slong v) {
    arb_init(x_);
    arb_set_si(x_, v);
  }
  ~Ball() { arb_clear(x_); }
  Ball(const Ball& o) {
    arb_init(x_);
    arb_set(x_, o.x_);
  }
  Ball& operator=(const Ball& o) {
    arb_set(x_, o.x_);
    return *this;
  }
  operator arb_ptr() { return x_; }
  operator arb_srcptr() const { return x_; }
  arb_ptr get() { return x_; }
  arb_srcptr get() const { return x_; }
  // so that Arb's macros arb_midref(b), arb_radref(b) take a Ball
  arb_ptr operator->() { return x_; }
  arb_srcptr operator->() const { return x_; }

 private:
  arb_t x_;
};

/// A vector of Arb balls, owned.
class Balls {
 public:
  explicit Balls(slong n = 0) : n_(n), v_(n > 0 ? _arb_vec_init(n) : nullptr) {}
  ~Balls() {
    if (v_) _arb_vec_clear(v_, n_);
  }
  Balls(const Balls&) = delete;
  Balls& operator=(const Balls&) = delete;
  Balls(Balls&& o) noexcept : n_(o.n_), v_(o.v_) {
    o.v_ = nullptr;
    o.n_ = 0;
  }
  Balls& operator=(Balls&& o) noexcept {
    std::swap(n_, o.n_);
    std::swap(v_, o.v_);
    return *this;
  }
  arb_ptr operator[](slong i) { return v_ + i; }
  arb_srcptr operator[](slong i) const { return v_ + i; }
  arb_ptr data() { return v_; }
  arb_srcptr data() const { return v_; }
  slong size() const { return n_; }

 private:
  slong n_ = 0;
  arb_ptr v_ = nullptr;
};

/// The exact ball of a double or MPFR input.
template <class Real>
void set_exact(arb_t out, const Real& x) {
  if constexpr (is_mpfr_v<Real>) {
    arf_set_mpfr(arb_midref(out), x.backend().data());
    mag_zero(arb_radref(out));
  } else {
    arb_set_d(out, static_cast<double>(x));
  }
}

/// mu1, mu2, a1, a2 as balls from the exact inputs (Sec. 1), and their midpoints for plans.
struct Parameters {
  Ball mu1, mu2, a1, a2;
  double mu1_d = 0, a1_d = 0, a2_d = 0;
};

/// The parameters of `chain` at `beta` (null: the beta -> 0 limit, a1 = a2 = 0). Throws
/// invalid_input for N != 2 or inputs outside the domain.
template <class Real>
Parameters parameters_of(const Chain<Real>& chain, const Real* beta, slong prec);

/// out[m] = e^{-a} I_m(a), m = 0 .. out.size() - 1 (Sec. 3). miller_extra: -1 the plan's choice;
/// 0 the top orders from Arb and the backward recurrence (Sec. 3.3); > 0 Miller's run with this
/// many steps beyond the table, once (Sec. 3.2; any length gives an enclosure).
void scaled_bessel_table(Balls& out, const arb_t a, double a_d, double L, slong prec,
                         slong miller_extra = -1);

/// The Fourier moments Q_k(s) of q^s, k < K, and K(mu2), E(mu2), r (Sec. 4).
struct Moments {
  Balls half, minus_half, minus_three_halves;  // Q_k(1/2), Q_k(-1/2), Q_k(-3/2), k < K
  Ball K_ell, E_ell, r;                         // K(mu2), E(mu2), r = e^{-2d}
};

Moments moments_of(const Parameters& p, slong K, slong prec);

/// J_{1/2}, J_{-1/2}, J_{-3/2}, C_1, C_2 from K rows with their tails bounded (Secs. 2, 5).
struct Integrals {
  std::array<Ball, 5> value;  // J_{1/2}, J_{-1/2}, J_{-3/2}, C_1, C_2
  slong rows = 0;
};

Integrals integrals_of(const Parameters& p, slong K, double L, slong prec);

/// The certified averages by Arb's balls alone (certified_double_pendulum_average without the
/// double fast path of Sec. 10; for tests and benchmarks of either path).
template <class Real>
Averages<Real> arb_double_pendulum_average(const Chain<Real>& chain, const Real& beta, int digits);

}  // namespace pendavg::certified_detail
