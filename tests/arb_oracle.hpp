// SPDX-License-Identifier: GPL-3.0-or-later
// tests/arb_oracle.hpp -- Arb's rigorous integrator (acb_calc_integrate) on the double
// pendulum's reduced integrand: the independent oracle of the certified engine's tests
// (tests/engine/certified/test_certified.cpp) and of bench_arb_cases (issue 30). Needs Arb (PENDAVG_HAS_ARB).
//
// The integrals, unfolded to [0, pi] (engine/double_pendulum/integral.cpp folds them onto [0, pi/2]):
//   J_s = int_0^pi q(t)^s e^{-A} I_0(R(t)) dt,  q = mu1 + mu2 sin^2 t,  A = a1 + a2,
//   R^2 = A^2 - 4 a1 a2 sin^2(t/2),  a1 = beta M g l1,  a2 = beta m2 g l2,
// with e^{-A} I_0(R) = e^{R - A} [e^{-R} I_0(R)] and R - A = -4 a1 a2 sin^2(t/2) / (R + A).
// beta<K1> = (mu1/2) J_{-1/2} / J_{1/2}; <x^2> = mu1^2 J_{-3/2} / J_{1/2} (x = mu1/q).
// The parameters are formed in ball arithmetic from the exact double inputs.
#pragma once

#include "engine/detail/certified_balls.hpp"
#include "pendavg/chain.hpp"

#include <acb_calc.h>
#include <acb_hypgeom.h>
#include <arb.h>

namespace pendavg_test {

/// The reduced integrand's parameters as balls, and the power s = twice_s / 2 of q.
struct ArbIntegrand {
  arb_t mu1, mu2, a1, a2, A, P;  // P = 4 a1 a2
  int twice_s = 1;               // 1: q^{1/2}; -1: q^{-1/2}; -3: q^{-3/2}
  ArbIntegrand() {
    for (arb_ptr x : {mu1, mu2, a1, a2, A, P}) arb_init(x);
  }
  ~ArbIntegrand() {
    for (arb_ptr x : {mu1, mu2, a1, a2, A, P}) arb_clear(x);
  }
  ArbIntegrand(const ArbIntegrand&) = delete;
  ArbIntegrand& operator=(const ArbIntegrand&) = delete;
  /// From the exact double inputs: mu1, mu2, a1, a2 as the certified engine forms them
  /// (certified_detail::parameters_of: ball arithmetic on the inputs, nothing else shared).
  void set(double m1, double m2, double l1, double l2, double g, double beta, slong prec) {
    const pendavg::Chain<double> chain({m1, m2}, {l1, l2}, g);
    const auto p = pendavg::certified_detail::parameters_of<double>(chain, &beta, prec);
    arb_set(mu1, p.mu1);
    arb_set(mu2, p.mu2);
    arb_set(a1, p.a1);
    arb_set(a2, p.a2);
    arb_add(A, a1, a2, prec);
    arb_mul(P, a1, a2, prec);
    arb_mul_2exp_si(P, P, 2);
  }
};

/// q(t)^s e^{-A} I_0(R(t)). q^s by the analytic square root (non-finite where the ball meets
/// the branch cut, as acb_calc_integrate requires); R by the principal square root, which is
/// harmless: e^{R - A} e^{-R} I_0(R) = e^{-A} I_0(R) is even in R.
inline int arb_integrand(acb_ptr out, const acb_t t, void* param, slong order, slong prec) {
  if (order > 1) flint_abort();
  const auto* p = static_cast<const ArbIntegrand*>(param);
  acb_t s, q, root, h, R, E, I, zero;
  for (acb_ptr x : {s, q, root, h, R, E, I, zero}) acb_init(x);
  acb_sin(s, t, prec);
  acb_sqr(s, s, prec);
  acb_mul_arb(q, s, p->mu2, prec);
  acb_add_arb(q, q, p->mu1, prec);
  if (p->twice_s > 0) {
    acb_sqrt_analytic(root, q, order != 0, prec);
  } else {
    acb_rsqrt_analytic(root, q, order != 0, prec);
    if (p->twice_s == -3) {
      acb_t cube;
      acb_init(cube);
      acb_sqr(cube, root, prec);
      acb_mul(root, root, cube, prec);
      acb_clear(cube);
    }
  }
  acb_mul_2exp_si(h, t, -1);
  acb_sin(h, h, prec);
  acb_sqr(h, h, prec);
  acb_mul_arb(h, h, p->P, prec);  // P sin^2(t/2)
  acb_set_arb(R, p->A);
  acb_sqr(R, R, prec);
  acb_sub(R, R, h, prec);
  acb_sqrt(R, R, prec);
  acb_add_arb(E, R, p->A, prec);
  acb_div(E, h, E, prec);
  acb_neg(E, E);  // R - A
  acb_exp(E, E, prec);
  acb_hypgeom_bessel_i_scaled(I, zero, R, prec);
  acb_mul(out, I, E, prec);
  acb_mul(out, out, root, prec);
  for (acb_ptr x : {s, q, root, h, R, E, I, zero}) acb_clear(x);
  return 0;
}

/// J_s over [0, pi] to about `goal` bits relative (|J| from a coarse run first), at working
/// precision prec; `eval_limit` caps the integrand evaluations (0: Arb's default).
inline void arb_reduced_integral(arb_t out, ArbIntegrand& f, int twice_s, slong goal, slong prec,
                                 slong eval_limit = 0) {
  f.twice_s = twice_s;
  acb_t a, b, result;
  acb_init(a);
  acb_init(b);
  acb_init(result);
  acb_zero(a);
  acb_const_pi(b, prec);
  acb_calc_integrate_opt_t options;
  acb_calc_integrate_opt_init(options);
  if (eval_limit > 0) options->eval_limit = eval_limit;
  mag_t tol;
  mag_init(tol);
  mag_set_ui_2exp_si(tol, 1, -20);
  acb_calc_integrate(result, arb_integrand, &f, a, b, 20, tol, options, 64);
  arb_get_mag_lower(tol, acb_realref(result));
  mag_mul_2exp_si(tol, tol, -goal);
  acb_calc_integrate(result, arb_integrand, &f, a, b, goal, tol, options, prec);
  arb_set(out, acb_realref(result));
  mag_clear(tol);
  acb_clear(a);
  acb_clear(b);
  acb_clear(result);
}

}  // namespace pendavg_test
