// SPDX-License-Identifier: GPL-3.0-or-later
// engine/certified.cpp -- the certified N = 2 engine (engine/certified.hpp) in Arb's ball
// arithmetic. Every step, and why each enclosure holds, is in engine/certified.md; the section
// numbers below (Sec. n) refer to it.
#include "engine/certified.hpp"

#include "engine/detail/graf_rows.hpp"
#include "engine/numerics/estimates.hpp"
#include "engine/numerics/precision.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstddef>
#include <limits>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#ifdef PENDAVG_HAS_ARB
#include "engine/detail/certified_balls.hpp"
#include "engine/detail/certified_fast.hpp"

#include <acb.h>
#include <acb_hypgeom.h>
#include <arb.h>
#include <arb_hypgeom.h>
#endif

namespace pendavg {

#ifndef PENDAVG_HAS_ARB

bool certified_available() { return false; }

std::string certified_backend() { return certified_unavailable_reason(); }

const char* certified_unavailable_reason() {
  return "this pendavg was built without Arb (Debian libflint-arb-dev), which certified "
         "enclosures need";
}

template <class Real>
Averages<Real> certified_double_pendulum_average(const Chain<Real>&, const Real&, int) {
  throw invalid_input(std::string("certified: ") + certified_unavailable_reason());
}

template <class Real>
Averages<Real> certified_high_temperature_limit(const Chain<Real>&, int) {
  throw invalid_input(std::string("certified: ") + certified_unavailable_reason());
}

#else  // PENDAVG_HAS_ARB

bool certified_available() { return true; }

std::string certified_backend() {
  return "Arb " + std::to_string(__ARB_VERSION) + "." + std::to_string(__ARB_VERSION_MINOR) + "." +
         std::to_string(__ARB_VERSION_PATCHLEVEL);
}

const char* certified_unavailable_reason() { return ""; }

namespace certified_detail {

/// An upper bound of |x| as a double (+inf if x is not finite or beyond double).
double upper_abs(const arb_t x) {
  mag_t m;
  mag_init(m);
  arb_get_mag(m, x);
  arf_t f;
  arf_init(f);
  arf_set_mag(f, m);
  const double d = arf_get_d(f, ARF_RND_UP);
  arf_clear(f);
  mag_clear(m);
  return std::isfinite(d) ? d : std::numeric_limits<double>::infinity();
}

/// The ball's midpoint as a double (for plans only).
double mid_double(const arb_t x) { return arf_get_d(arb_midref(x), ARF_RND_NEAR); }

/// log2 of the ball's radius over |midpoint| (+inf when the ball is not finite or contains 0
/// with a radius not below it).
double relative_radius_log2(const arb_t x) {
  if (!arb_is_finite(x)) return std::numeric_limits<double>::infinity();
  if (mag_is_zero(arb_radref(x))) return -std::numeric_limits<double>::infinity();
  return static_cast<double>(arb_rel_error_bits(x));
}

/// Estimate<Real> of a ball: the midpoint rounded to Real, the error an upper bound of the
/// distance from it to every point of the ball (radius + the rounding), rounded up.
template <class Real>
Estimate<Real> estimate_of(const arb_t x, slong prec) {
  Estimate<Real> out;
  out.kind = ErrorKind::bound;
  Ball value, distance;
  if constexpr (is_mpfr_v<Real>) {
    Real v = 0;  // at the working precision
    arf_get_mpfr(v.backend().data(), arb_midref(x), MPFR_RNDN);
    out.value = v;
  } else {
    out.value = static_cast<Real>(arf_get_d(arb_midref(x), ARF_RND_NEAR));
  }
  set_exact(value, out.value);
  arb_sub(distance, x, value, prec + 64);
  mag_t m;
  mag_init(m);
  arb_get_mag(m, distance);
  arf_t f;
  arf_init(f);
  arf_set_mag(f, m);
  if constexpr (is_mpfr_v<Real>) {
    Real e = 0;
    arf_get_mpfr(e.backend().data(), f, MPFR_RNDU);
    out.error = e;
  } else {
    out.error = static_cast<Real>(arf_get_d(f, ARF_RND_UP));
  }
  arf_clear(f);
  mag_clear(m);
  return out;
}

// ---------------------------------------------------------------- the parameters (Sec. 1)

template <class Real>
Parameters parameters_of(const Chain<Real>& chain, const Real* beta, slong prec) {
  if (chain.size() != 2)
    throw invalid_input("certified: the certified engine is for N = 2, got " +
                        std::to_string(chain.size()) + " masses");
  Ball m1, m2, l1, l2, g, b, M;
  set_exact(m1, chain.mass(0));
  set_exact(m2, chain.mass(1));
  set_exact(l1, chain.length(0));
  set_exact(l2, chain.length(1));
  set_exact(g, chain.gravity());
  Parameters p;
  arb_add(M, m1, m2, prec);
  arb_div(p.mu1, m1, M, prec);
  arb_div(p.mu2, m2, M, prec);
  if (beta) {
    set_exact(b, *beta);
    arb_mul(p.a1, b, M, prec);
    arb_mul(p.a1, p.a1, g, prec);
    arb_mul(p.a1, p.a1, l1, prec);
    arb_mul(p.a2, b, m2, prec);
    arb_mul(p.a2, p.a2, g, prec);
    arb_mul(p.a2, p.a2, l2, prec);
  }
  if (!arb_is_positive(p.mu1) || !arb_is_positive(p.mu2) || arb_is_negative(p.a1) ||
      arb_is_negative(p.a2) || !arb_is_nonnegative(p.a1) || !arb_is_nonnegative(p.a2))
    throw invalid_input("certified: needs positive masses and lengths and g >= 0");
  p.mu1_d = mid_double(p.mu1);
  p.a1_d = mid_double(p.a1);
  p.a2_d = mid_double(p.a2);
  return p;
}

// ---------------------------------------------------------------- Bessel tables (Sec. 3)

/// out[m] = e^{-a} I_m(a) for m = 0 .. count-1 (count >= 2), a > 0 a ball. `L`: the table must
/// hold to about e^{-L} of out[0] (the plan; every entry is an enclosure whatever L is).
void scaled_bessel_table(Balls& out, const arb_t a, double a_d, double L, slong prec,
                         slong miller_extra) {
  const slong count = out.size();
  if (arb_is_zero(a)) {  // I_m(0) = delta_{m0}
    arb_one(out[0]);
    for (slong m = 1; m < count; ++m) arb_zero(out[m]);
    return;
  }
  Ball two_over_a, t, u0;
  arb_set_ui(two_over_a, 2);
  arb_div(two_over_a, two_over_a, a, prec);
  // Miller's recurrence needs N^2 - m^2 >~ a L beyond the table (Sec. 3.2).
  const double extra_d = 16.0 + std::ceil(std::sqrt(std::max(a_d, 0.0) * (L + 16.0)));
  const bool miller = miller_extra > 0 || (miller_extra < 0 && extra_d <= 4.0 * static_cast<double>(count) + 4000.0);
  if (!miller) {
    // Sec. 3.3: the two top orders from Arb, then the backward recurrence (all terms > 0).
    Ball nu;
    arb_set_si(nu, count - 1);
    arb_hypgeom_bessel_i_scaled(out[count - 1], nu, a, prec);
    arb_set_si(nu, count - 2);
    arb_hypgeom_bessel_i_scaled(out[count - 2], nu, a, prec);
    for (slong m = count - 2; m >= 1; --m) {
      arb_mul_ui(t, two_over_a, static_cast<ulong>(m), prec);
      arb_mul(t, t, out[m], prec);
      arb_add(out[m - 1], out[m + 1], t, prec);
    }
    return;
  }
  // Sec. 3.2: Miller's backward recurrence from N + 1, N with the start vectors (1, 0) and
  // (0, 1); the true ratios I_m / I_0 lie between those of the two runs (the mediant).
  slong extra = miller_extra > 0 ? miller_extra : static_cast<slong>(extra_d);
  if (miller_extra < 0) {
    // The normalization sum (by_sum below) converges like the square root of the ratios: its
    // terms near N are ~e^{-N^2/(2a)} where the two runs' ratios differ by its square. Where a
    // run of N >= a + 8 and N >= 16 + sqrt(2 a (L + 16)) costs at most 100 steps more than the
    // plan (Arb's e^{-a} I_0(a) costs ~60-300 steps at 191-320 bits), it is taken.
    const double sum_run = std::max(16.0 + std::ceil(std::sqrt(2.0 * a_d * (L + 16.0))),
                                    std::ceil(a_d) + 8.0);
    const double planned = static_cast<double>(count + extra);
    if (sum_run > planned && sum_run <= planned + 100.0)
      extra = static_cast<slong>(sum_run) - count;
  }
  Ball ratio_u, ratio_v, sum_u, sum_v;
  bool by_sum = false;  // I~_0 from sum_m I~_m = 1 (Sec. 3.2) instead of Arb
  for (int attempt = 0;; ++attempt) {
    const slong N = count + extra;
    by_sum = static_cast<double>(N) >= a_d + 8;
    Balls u(count), v(count);
    Ball up, ui, vp, vi, next;  // X_{m+1}, X_m of the two runs
    arb_one(up);
    arb_zero(ui);
    arb_zero(vp);
    arb_one(vi);
    arb_zero(sum_u);
    arb_zero(sum_v);
    for (slong m = N; m >= 1; --m) {
      // X_{m-1} = X_{m+1} + (2m/a) X_m
      arb_mul_ui(t, two_over_a, static_cast<ulong>(m), prec);
      arb_mul(next, t, ui, prec);
      arb_add(next, next, up, prec);
      arb_swap(up, ui);
      arb_swap(ui, next);
      arb_mul(next, t, vi, prec);
      arb_add(next, next, vp, prec);
      arb_swap(vp, vi);
      arb_swap(vi, next);
      if (by_sum && m - 1 >= 1) {  // sum_{m=1}^{N-1} X_m
        arb_add(sum_u, sum_u, ui, prec);
        arb_add(sum_v, sum_v, vi, prec);
      }
      if (m - 1 < count) {
        arb_set(u[m - 1], ui);
        arb_set(v[m - 1], vi);
      }
    }
    if (by_sum) {
      // sum_{m>=1} I~_m / I~_0 = S + T: S = sum_{m<N} between the runs' (the mediant again),
      // T = the rest from N on, <= rho_{N-1} q / (1 - q) with I~_{m+1}/I~_m < a/(2(m+1)) <=
      // q = a/(2N) < 1 and rho_{N-1} between U_{N-1}/U_0 = 1/U_0 and V_{N-1}/V_0 = (2N/a)/V_0.
      Ball S, T, q, rho;
      arb_div(ratio_u, sum_u, u[0], prec);
      arb_div(ratio_v, sum_v, v[0], prec);
      arb_union(S, ratio_u, ratio_v, prec);
      arb_inv(ratio_u, u[0], prec);
      arb_mul_ui(ratio_v, two_over_a, static_cast<ulong>(N), prec);
      arb_div(ratio_v, ratio_v, v[0], prec);
      arb_union(rho, ratio_u, ratio_v, prec);
      arb_mul_ui(q, two_over_a, static_cast<ulong>(N), prec);  // 2N/a
      arb_inv(q, q, prec);  // a / (2N)
      if (!arb_lt(q, Ball(1))) by_sum = false;
      arb_sub_ui(T, q, 1, prec);
      arb_neg(T, T);
      arb_div(T, q, T, prec);
      arb_mul(T, T, rho, prec);
      mag_t rest;
      mag_init(rest);
      arb_get_mag(rest, T);
      mag_mul_2exp_si(rest, rest, -1);
      arf_set_mag(arb_midref(T), rest);  // [0, T] = T/2 +- T/2
      mag_set(arb_radref(T), rest);
      mag_clear(rest);
      arb_add(S, S, T, prec);
      arb_mul_2exp_si(S, S, 1);
      arb_add_ui(S, S, 1, prec);
      if (by_sum) arb_inv(u0, S, prec);
    }
    // ratios and their hull; accept when every ratio is resolved to 2^-(prec - 16) absolutely
    bool resolved = true;
    arb_one(out[0]);
    for (slong m = 1; m < count; ++m) {
      arb_div(ratio_u, u[m], u[0], prec);
      arb_div(ratio_v, v[m], v[0], prec);
      arb_union(out[m], ratio_u, ratio_v, prec);
      if (resolved && mag_cmp_2exp_si(arb_radref(out[m]), -(prec - 16)) > 0) resolved = false;
    }
    if (resolved || attempt >= 3 || miller_extra > 0) break;
    extra = 2 * extra + 32;
  }
  if (!by_sum) {
    Ball zero;
    arb_hypgeom_bessel_i_scaled(u0, zero, a, prec);
  }
  for (slong m = 1; m < count; ++m) arb_mul(out[m], out[m], u0, prec);
  arb_set(out[0], u0);
}

/// e^{-a} I_nu(a) for nu = 0, 1: from a two-entry table when its Miller run may normalize by
/// the sum (a below ~L), else from Arb.
void scaled_bessel_low_orders(arb_t i0, arb_t i1, const arb_t a, double a_d, double L,
                              slong prec) {
  // a two-entry table when its run may normalize by the sum (within the 100 steps above)
  if (a_d + 8 <= 126.0 + std::ceil(std::sqrt(std::max(a_d, 0.0) * (L + 16.0)))) {
    Balls table(2);
    scaled_bessel_table(table, a, a_d, L, prec);
    arb_set(i0, table[0]);
    arb_set(i1, table[1]);
    return;
  }
  Ball nu;
  arb_zero(nu);
  arb_hypgeom_bessel_i_scaled(i0, nu, a, prec);
  arb_one(nu);
  arb_hypgeom_bessel_i_scaled(i1, nu, a, prec);
}

/// e^{-(a1 + a2)} I_nu(a1 - a2) = sign(a1 - a2)^nu e^{-2 min(a1, a2)} e^{-|d|} I_nu(|d|) for
/// nu = 0 (out0) and 1 (out1).
void scaled_difference_bessel(arb_t out0, arb_t out1, const Parameters& p, double L, slong prec) {
  Ball d, ad, lo, e;
  arb_sub(d, p.a1, p.a2, prec);
  arb_abs(ad, d);
  arb_min(lo, p.a1, p.a2, prec);
  if (arb_is_zero(ad)) {
    arb_one(out0);
    arb_zero(out1);
  } else {
    scaled_bessel_low_orders(out0, out1, ad, std::fabs(p.a1_d - p.a2_d), L, prec);
  }
  arb_mul_2exp_si(e, lo, 1);
  arb_neg(e, e);
  arb_exp(e, e, prec);
  arb_mul(out0, out0, e, prec);
  arb_mul(out1, out1, e, prec);
  if (arb_is_positive(d)) {
  } else if (arb_is_negative(d)) {
    arb_neg(out1, out1);
  } else {
    Ball sign;  // [-1, 1]
    arb_zero(sign);
    mag_one(arb_radref(sign.get()));
    arb_mul(out1, out1, sign, prec);
  }
}

// ---------------------------------------------------------------- moments (Sec. 4)

/// Complete elliptic K(m), E(m) at m = mu2 from the arithmetic-geometric mean with a_0 = 1,
/// b_0 = sqrt(mu1), c_0^2 = mu2 (Sec. 4.1): K = pi / (2 M), M = agm(a_0, b_0) in [b_n, a_n], and
/// E = K (1 - sum_n 2^{n-1} c_n^2) with c_{n+1} = c_n^2 / (4 a_{n+1}) and the rest of the sum
/// bounded in closed form.
void complete_elliptic(arb_t K, arb_t E, const arb_t mu1, const arb_t mu2, slong prec) {
  Ball a, b, c2, sum, weight, next_a, t, M, pi, rest, ratio;
  arb_one(a);
  arb_sqrt(b, mu1, prec);
  arb_set(c2, mu2);
  arb_mul_2exp_si(sum, c2, -1);  // 2^{-1} c_0^2
  arb_set_d(weight, 0.5);
  mag_t tail, scale;
  mag_init(tail);
  mag_init(scale);
  for (int n = 1;; ++n) {
    arb_add(next_a, a, b, prec);
    arb_mul_2exp_si(next_a, next_a, -1);
    arb_mul(t, a, b, prec);
    arb_sqrt(b, t, prec);
    // c_n^2 = c_{n-1}^4 / (16 a_n^2)
    arb_sqr(t, next_a, prec);
    arb_mul_2exp_si(t, t, 4);
    arb_sqr(c2, c2, prec);
    arb_div(c2, c2, t, prec);
    arb_swap(a, next_a);
    arb_mul_2exp_si(weight, weight, 1);
    arb_addmul(sum, weight, c2, prec);
    // every later term over its predecessor: c_j^2 / (8 a_{j+1}^2) <= rho = c_n^2 / (8 mu1)
    // (c decreases, a_{j+1} >= M >= b_0 = sqrt(mu1)); rho <= 1/2: the rest <= 2 rho 2^{n-1} c_n^2
    arb_div(ratio, c2, mu1, prec);
    arb_mul_2exp_si(ratio, ratio, -3);
    arb_mul(rest, ratio, weight, prec);
    arb_mul(rest, rest, c2, prec);
    arb_mul_2exp_si(rest, rest, 1);
    arb_get_mag(tail, rest);
    arb_sub_ui(t, sum, 1, prec);  // sum - 1 = -E/K < 0
    arb_get_mag_lower(scale, t);
    mag_mul_2exp_si(scale, scale, -prec - 8);
    Ball half;
    arb_set_d(half, 0.5);
    // done when the rest is negligible and a_n, b_n (which enclose M) agree to rounding
    if ((arb_le(ratio, half) && mag_cmp(tail, scale) <= 0 && arb_overlaps(a, b)) || n > 200)
      break;
  }
  arb_union(M, a, b, prec);
  arb_const_pi(pi, prec);
  arb_mul_2exp_si(K, M, 1);
  arb_div(K, pi, K, prec);
  // E = K (1 - sum - T), T in [0, tail]: 1 - sum - tail/2 +- tail/2
  arb_sub_ui(t, sum, 1, prec);
  arb_neg(t, t);
  mag_mul_2exp_si(tail, tail, -1);
  Ball half_tail;
  arf_set_mag(arb_midref(half_tail), tail);
  arb_sub(t, t, half_tail, prec);
  arb_add_error_mag(t, tail);
  arb_mul(E, K, t, prec);
  mag_clear(tail);
  mag_clear(scale);
}

/// 2F1(a, b; c; z) by its series for a = +-1/2, b = K - s <= c = K + 1, 0 <= z < 1 (Sec. 4.2):
/// from n = 1 on |t_{n+1} / t_n| = |n + a| (n + b) z / ((n + c)(n + 1)) <= z, so the rest from
/// term N on is at most |t_N| / (1 - z). False if it needs more than 80000 terms.
bool hypergeometric_series(arb_t out, const arb_t a, const arb_t b, const arb_t c, const arb_t z,
                           slong prec) {
  if (!arb_is_nonnegative(z) || !arb_lt(z, Ball(1))) return false;
  Ball term, sum, t, one_minus_z, rest;
  arb_one(term);
  arb_one(sum);
  arb_sub_ui(one_minus_z, z, 1, prec);
  arb_neg(one_minus_z, one_minus_z);
  for (ulong n = 0; n < 80000; ++n) {
    // t_{n+1} = t_n (n + a)(n + b) z / ((n + c)(n + 1))
    arb_add_ui(t, a, n, prec);
    arb_mul(term, term, t, prec);
    arb_add_ui(t, b, n, prec);
    arb_mul(term, term, t, prec);
    arb_mul(term, term, z, prec);
    arb_add_ui(t, c, n, prec);
    arb_div(term, term, t, prec);
    arb_div_ui(term, term, n + 1, prec);
    if (n >= 1) {
      // the rest from this term on, against the sum so far
      arb_div(rest, term, one_minus_z, prec);
      mag_t m, scale;
      mag_init(m);
      mag_init(scale);
      arb_get_mag(m, rest);
      arb_get_mag_lower(scale, sum);
      mag_mul_2exp_si(scale, scale, -prec - 4);
      const bool negligible = mag_cmp(m, scale) <= 0;
      if (negligible) {
        arb_add_error_mag(sum, m);
        arb_set(out, sum);
      }
      mag_clear(m);
      mag_clear(scale);
      if (negligible) return true;
    }
    arb_add(sum, sum, term, prec);
  }
  return false;
}

/// Q_K(s) = (pi/2) C^s r^K ((-s)_K / K!) 2F1(-s, K - s; K + 1; r^2) for s = +-1/2 (Sec. 4.2).
void top_moment(arb_t out, int twice_s, ulong K, const arb_t C, const arb_t r, slong prec) {
  Ball a, b, c, z, coefficient, f, power;
  arb_set_si(a, -twice_s);
  arb_mul_2exp_si(a, a, -1);  // -s
  arb_add_ui(b, a, K, prec);  // K - s
  arb_set_ui(c, K + 1);
  arb_sqr(z, r, prec);
  // (-s)_K / K!
  arb_hypgeom_rising_ui(coefficient, a, K, prec);
  Ball factorial;
  arb_fac_ui(factorial, K, prec);
  arb_div(coefficient, coefficient, factorial, prec);
  // Arb's 2F1 for short rows (K <= 150: a few of its transformations' terms) and near z = 1
  // (mu1 <~ 1e-6, where the series would need over 60000 terms); otherwise the series itself.
  // Arb's 2F1 returns no finite ball for K >~ 200 at z ~ 0.4 and loses nearly every bit at
  // K ~ 3000, z ~ 0.98: whichever runs first, a ball with no finite radius hands over to the
  // other (either is an enclosure; only its width is at stake), as does one short of prec - 24.
  const double z_d = mid_double(z);
  const double terms = static_cast<double>(prec) * 0.6931471805599453 / -std::log(z_d);
  const bool series_possible = z_d < 1 && terms <= 60000;
  const auto held = [&](const arb_t x) { return arb_rel_accuracy_bits(x) >= prec - 24; };
  const auto by_arb = [&](slong extra) {
    acb_t fa, fb, fc, fz, res;
    acb_init(fa);
    acb_init(fb);
    acb_init(fc);
    acb_init(fz);
    acb_init(res);
    acb_set_arb(fa, a);
    acb_set_arb(fb, b);
    acb_set_arb(fc, c);
    acb_set_arb(fz, z);
    acb_hypgeom_2f1(res, fa, fb, fc, fz, ACB_HYPGEOM_2F1_AB | ACB_HYPGEOM_2F1_ABC, prec + extra);
    arb_set(f, acb_realref(res));
    acb_clear(fa);
    acb_clear(fb);
    acb_clear(fc);
    acb_clear(fz);
    acb_clear(res);
  };
  bool done = false;
  if (K <= 150 || !series_possible) {
    by_arb(32);
    done = held(f);
  }
  if (!done && series_possible) done = hypergeometric_series(f, a, b, c, z, prec) && held(f);
  // Near z = 1: Arb again with the bits it lost (measured ~25 of 145 at K ~ 3600, mu1 = 1e-7).
  for (slong extra = 32; !done && extra <= 8 * prec; extra *= 2) {
    const slong before = arb_rel_accuracy_bits(f);
    by_arb(before > 0 ? std::max(extra, prec - before + 24) : extra);
    done = held(f);
  }
  arb_pow_ui(power, r, K, prec);
  arb_mul(out, coefficient, f, prec);
  arb_mul(out, out, power, prec);
  // C^s
  Ball cs;
  arb_sqrt(cs, C, prec);
  if (twice_s < 0) {
    arb_div(out, out, cs, prec);
  } else {
    arb_mul(out, out, cs, prec);
  }
  Ball pi;
  arb_const_pi(pi, prec);
  arb_mul(out, out, pi, prec);
  arb_mul_2exp_si(out, out, -1);
}

/// Rows k = 0 .. K-1 of Q_k(1/2), Q_k(-1/2), Q_k(-3/2) (Sec. 4).
Moments moments_of(const Parameters& p, slong K, slong prec) {
  Moments m;
  complete_elliptic(m.K_ell, m.E_ell, p.mu1, p.mu2, prec);
  Ball root, one_plus, C, e;
  arb_sqrt(root, p.mu1, prec);
  arb_add_ui(one_plus, root, 1, prec);
  arb_sqr(C, one_plus, prec);
  arb_div(m.r, p.mu2, C, prec);  // r = (1 - sqrt mu1)/(1 + sqrt mu1) = mu2 / (1 + sqrt mu1)^2
  arb_mul_2exp_si(C, C, -2);      // C = ((1 + sqrt mu1)/2)^2
  arb_div(e, p.mu1, p.mu2, prec);
  arb_mul_2exp_si(e, e, 3);  // e = 8 mu1 / mu2
  const ulong Ku = static_cast<ulong>(K);
  Ball q_half, q_minus_half, q_minus_three_halves;  // at K
  top_moment(q_half, 1, Ku, C, m.r, prec);
  top_moment(q_minus_half, -1, Ku, C, m.r, prec);
  // Q_K(-3/2) = -(4K^2 - 1) Q_K(1/2) / mu1 (Sec. 4.1, (R3))
  Ball t, u;
  arb_set_ui(t, 4 * Ku * Ku - 1);
  arb_mul(q_minus_three_halves, q_half, t, prec);
  arb_div(q_minus_three_halves, q_minus_three_halves, p.mu1, prec);
  arb_neg(q_minus_three_halves, q_minus_three_halves);
  // D_{K-1} of both rows from (R4), sums of nonnegative terms
  Ball d_minus_half, d_minus_three_halves;
  arb_mul(t, p.mu1, q_minus_half, prec);
  arb_mul_2exp_si(t, t, 1);
  arb_mul_ui(u, q_half, 2 * (2 * Ku + 1), prec);
  arb_sub(d_minus_half, t, u, prec);
  arb_div(d_minus_half, d_minus_half, p.mu2, prec);
  arb_mul(t, p.mu1, q_minus_three_halves, prec);
  arb_mul_2exp_si(t, t, 1);
  arb_mul_ui(u, q_minus_half, 2 * (2 * Ku - 1), prec);
  arb_add(d_minus_three_halves, t, u, prec);
  arb_div(d_minus_three_halves, d_minus_three_halves, p.mu2, prec);
  // The difference recurrences down to k = 0 (Sec. 4.3, (R5), (R6))
  m.minus_half = Balls(K);
  m.minus_three_halves = Balls(K);
  m.half = Balls(K);
  auto run = [&](Balls& Q, Ball top, Ball D, bool minus_half) {
    for (slong k = K - 1; k >= 0; --k) {
      arb_add(Q[k], k + 1 < K ? Q[k + 1] : top.get(), D, prec);
      if (k == 0) break;
      const ulong ku = static_cast<ulong>(k);
      // row -1/2: (2k - 1) D_{k-1} = (2k + 1) D_k + e k Q_k
      // row -3/2: (2k + 1) D_{k-1} = (2k - 1) D_k + e k Q_k
      arb_mul_ui(D, D, minus_half ? 2 * ku + 1 : 2 * ku - 1, prec);
      arb_mul_ui(t, e, ku, prec);
      arb_addmul(D, t, Q[k], prec);
      arb_div_ui(D, D, minus_half ? 2 * ku - 1 : 2 * ku + 1, prec);
    }
  };
  run(m.minus_half, q_minus_half, d_minus_half, true);
  run(m.minus_three_halves, q_minus_three_halves, d_minus_three_halves, false);
  // Q_0 exactly: K(mu2) and E(mu2)/mu1; both enclosures hold, keep their intersection.
  Ball exact;
  arb_div(exact, m.E_ell, p.mu1, prec);
  for (auto [row, closed] : {std::pair{&m.minus_half, m.K_ell.get()},
                             std::pair{&m.minus_three_halves, exact.get()}}) {
    arb_ptr q0 = (*row)[0];
    if (!arb_is_finite(q0)) {
      arb_set(q0, closed);
    } else if (!arb_intersection(q0, q0, closed, prec)) {
      throw std::logic_error("certified: the moment recurrence misses its closed form at k = 0");
    }
  }
  // Row 1/2 from row -3/2: Q_k(1/2) = -mu1 Q_k(-3/2) / (4k^2 - 1), Q_0(1/2) = E (R3)
  arb_set(m.half[0], m.E_ell);
  for (slong k = 1; k < K; ++k) {
    const ulong ku = static_cast<ulong>(k);
    arb_mul(m.half[k], p.mu1, m.minus_three_halves[k], prec);
    arb_div_ui(m.half[k], m.half[k], 4 * ku * ku - 1, prec);
    arb_neg(m.half[k], m.half[k]);
  }
  return m;
}

// ---------------------------------------------------------------- the integrals (Sec. 2, 5)

/// The five integrals with K rows of the Graf sums and their proven tails.
Integrals integrals_of(const Parameters& p, slong K, double L, slong prec) {
  // Bessel tables to order 2K + 1: coefficients k = 0 .. K (row K bounds the tail)
  Balls i1(2 * K + 2), i2(2 * K + 2);
  scaled_bessel_table(i1, p.a1, p.a1_d, L, prec);
  scaled_bessel_table(i2, p.a2, p.a2_d, L, prec);
  Balls c0(K + 1), c1(K + 1), c2(K + 1);
  Ball t;
  for (slong k = 0; k <= K; ++k) {
    const slong m = 2 * k;
    arb_mul(c0[k], i1[m], i2[m], prec);
    arb_mul_2exp_si(c0[k], c0[k], k == 0 ? 1 : 2);
    if (k == 0) {
      arb_mul(c1[k], i1[1], i2[0], prec);
      arb_mul(c2[k], i2[1], i1[0], prec);
      arb_mul_2exp_si(c1[k], c1[k], 1);
      arb_mul_2exp_si(c2[k], c2[k], 1);
    } else {
      arb_add(t, i1[m - 1], i1[m + 1], prec);
      arb_mul(c1[k], t, i2[m], prec);
      arb_add(t, i2[m - 1], i2[m + 1], prec);
      arb_mul(c2[k], t, i1[m], prec);
      // 4 I_m' I_m with I_m' = (I_{m-1} + I_{m+1}) / 2
      arb_mul_2exp_si(c1[k], c1[k], 1);
      arb_mul_2exp_si(c2[k], c2[k], 1);
    }
  }
  const Moments mo = moments_of(p, K, prec);
  Integrals out;
  out.rows = K;
  const std::array<const Balls*, 5> coefficient = {&c0, &c0, &c0, &c1, &c2};
  const std::array<const Balls*, 5> moment = {&mo.half, &mo.minus_half, &mo.minus_three_halves,
                                              &mo.half, &mo.half};
  for (std::size_t j = 0; j < 5; ++j)
    arb_dot(out.value[j], nullptr, 0, coefficient[j]->data(), 1, moment[j]->data(), 1, K, prec);

  // ---- tails (Sec. 5)
  const std::array<const Balls*, 3> rows = {&c0, &c1, &c2};
  // The moments beyond K: sup_{k >= K} |Q_k(s)| and sum_{k >= K} |Q_k(s)| (Sec. 4.4).
  const ulong Ku = static_cast<ulong>(K);
  Ball rK, one_minus_r, geometric;
  arb_pow_ui(rK, mo.r, Ku, prec);
  arb_sub_ui(one_minus_r, mo.r, 1, prec);
  arb_neg(one_minus_r, one_minus_r);
  arb_div(geometric, rK, one_minus_r, prec);  // r^K / (1 - r)
  Ball Q0_three;
  arb_div(Q0_three, mo.E_ell, p.mu1, prec);
  std::array<Ball, 3> sup, sum;  // s = 1/2, -1/2, -3/2
  // s = 1/2: |Q_k| <= E r^k / (2k - 1)
  arb_mul(sup[0], mo.E_ell, rK, prec);
  arb_div_ui(sup[0], sup[0], 2 * Ku - 1, prec);
  arb_mul(sum[0], mo.E_ell, geometric, prec);
  arb_div_ui(sum[0], sum[0], 2 * Ku - 1, prec);
  // s = -1/2: 0 <= Q_k <= r^k K
  arb_mul(sup[1], mo.K_ell, rK, prec);
  arb_mul(sum[1], mo.K_ell, geometric, prec);
  // s = -3/2: 0 <= Q_k <= min(1, (2k + 1) r^k) E/mu1
  {
    // (2k + 1) r^k decreases from k = K on when (2K + 3) r <= 2K + 1
    Ball lhs, rhs;
    arb_mul_ui(lhs, mo.r, 2 * Ku + 3, prec);
    arb_set_ui(rhs, 2 * Ku + 1);
    if (arb_le(lhs, rhs)) {
      arb_mul_ui(sup[2], rK, 2 * Ku + 1, prec);
      arb_mul(sup[2], sup[2], Q0_three, prec);
      if (arb_gt(sup[2], Q0_three)) arb_set(sup[2], Q0_three);
    } else {
      arb_set(sup[2], Q0_three);
    }
    // sum_{k >= K} (2k + 1) r^k = r^K [(2K + 1)/(1 - r) + 2r/(1 - r)^2]
    Ball second;
    arb_mul_ui(sum[2], geometric, 2 * Ku + 1, prec);
    arb_mul(second, geometric, mo.r, prec);
    arb_div(second, second, one_minus_r, prec);
    arb_mul_2exp_si(second, second, 1);
    arb_add(sum[2], sum[2], second, prec);
    arb_mul(sum[2], sum[2], Q0_three, prec);
  }
  constexpr std::array<std::size_t, 5> row_of = {0, 0, 0, 1, 2};    // coefficient row
  constexpr std::array<std::size_t, 5> power_of = {0, 1, 2, 0, 0};  // s = 1/2, -1/2, -3/2
  // The bound by the moments' decay, c_K sum_{k >= K} |Q_k|, first: where it is below
  // 2^-(prec + 16) of every integral, the bound by the coefficients' rest (their full sums:
  // two more Bessel evaluations and an exponential) cannot matter and is not formed.
  std::array<Ball, 5> bound_decay;
  bool decay_enough = true;
  for (std::size_t j = 0; j < 5; ++j) {
    arb_mul(bound_decay[j], (*rows[row_of[j]])[K], sum[power_of[j]], prec);
    mag_t bound, scale;
    mag_init(bound);
    mag_init(scale);
    arb_get_mag(bound, bound_decay[j]);
    arb_get_mag_lower(scale, out.value[j]);
    mag_mul_2exp_si(scale, scale, -(prec + 16));
    if (mag_cmp(bound, scale) > 0) decay_enough = false;
    mag_clear(bound);
    mag_clear(scale);
  }
  if (decay_enough) {
    for (std::size_t j = 0; j < 5; ++j) {
      mag_t m;
      mag_init(m);
      arb_get_mag(m, bound_decay[j]);
      arb_add_error_mag(out.value[j], m);
      mag_clear(m);
    }
    return out;
  }
  // The coefficients' full sums from Graf's theorem at t = 0 and t = pi.
  Ball A, total0, total1, total2, diff0, diff1;
  arb_add(A, p.a1, p.a2, prec);
  if (arb_is_zero(A)) {
    arb_one(total0);
    arb_zero(total1);
  } else {
    scaled_bessel_low_orders(total0, total1, A, p.a1_d + p.a2_d, L, prec);
  }
  scaled_difference_bessel(diff0, diff1, p, L, prec);
  arb_add(total0, total0, diff0, prec);
  arb_set(total2, total1);
  arb_add(total1, total1, diff1, prec);
  arb_sub(total2, total2, diff1, prec);
  const std::array<const Ball*, 3> totals = {&total0, &total1, &total2};
  std::array<Ball, 3> rest;  // sum_{k >= K} c_k, >= 0
  for (std::size_t j = 0; j < 3; ++j) {
    Ball partial;  // 0
    for (slong k = 0; k < K; ++k) arb_add(partial, partial, (*rows[j])[k], prec);
    arb_sub(rest[j], *totals[j], partial, prec);
  }
  for (std::size_t j = 0; j < 5; ++j) {
    // |tail| <= min(rest * sup, c_K * sum)
    const double by_rest = upper_abs(rest[row_of[j]]) * upper_abs(sup[power_of[j]]);
    const double by_decay = upper_abs(bound_decay[j]);
    Ball bound_rest;
    arb_mul(bound_rest, rest[row_of[j]], sup[power_of[j]], prec);
    mag_t m;
    mag_init(m);
    arb_get_mag(m, by_rest <= by_decay ? bound_rest.get() : bound_decay[j].get());
    arb_add_error_mag(out.value[j], m);
    mag_clear(m);
  }
  return out;
}

// ---------------------------------------------------------------- observables (Sec. 6)

struct Observables {
  Ball k1, k2, ratio, cos1, cos2, var1, var2;
};

/// ball := ball intersected with [lo, hi] (both contain the truth).
void clamp(arb_t x, const arb_t lo, const arb_t hi, slong prec) {
  Ball range;
  arb_union(range, lo, hi, prec);
  if (!arb_is_finite(x)) {  // no information: the range itself
    arb_set(x, range);
    return;
  }
  if (!arb_intersection(x, x, range, prec))
    throw std::logic_error("certified: an enclosure misses its a priori range");
}

Observables observables_of(const Parameters& p, const std::array<Ball, 5>& J, slong prec) {
  Observables o;
  Ball x1, x2, t, zero, half, one, three_quarters, nine_quarters, minus_one, lo;
  arb_zero(zero);
  arb_one(one);
  arb_set_d(half, 0.5);
  arb_set_d(three_quarters, 0.75);
  arb_set_d(nine_quarters, 2.25);
  arb_set_si(minus_one, -1);
  // <x> = mu1 J_{-1/2} / J_{1/2} in [mu1, 1]
  arb_div(x1, J[1], J[0], prec);
  arb_mul(x1, x1, p.mu1, prec);
  {
    arf_t f;
    arf_init(f);
    arb_get_lbound_arf(f, p.mu1, prec);
    arb_set_arf(lo, f);
    arf_clear(f);
  }
  clamp(x1, lo, one, prec);
  // <x^2> = mu1^2 J_{-3/2} / J_{1/2} in [mu1^2, 1]
  arb_div(x2, J[2], J[0], prec);
  arb_mul(x2, x2, p.mu1, prec);
  arb_mul(x2, x2, p.mu1, prec);
  clamp(x2, zero, one, prec);
  arb_mul_2exp_si(o.k1, x1, -1);
  arb_sub(o.k2, one, o.k1, prec);
  arb_div(o.ratio, o.k1, o.k2, prec);
  clamp(o.ratio, zero, one, prec);
  arb_div(o.cos1, J[3], J[0], prec);
  arb_div(o.cos2, J[4], J[0], prec);
  clamp(o.cos1, minus_one, one, prec);
  clamp(o.cos2, minus_one, one, prec);
  // beta^2 Var K1 = (3/4)<x^2> - <x>^2/4; beta^2 Var K2 = (1 - <x>) + <x>^2/2 + (3/4)(<x^2> -
  // <x>^2) (both >= 0: variances)
  Ball sq;
  arb_sqr(sq, x1, prec);
  arb_mul_2exp_si(t, sq, -2);
  arb_mul(o.var1, x2, three_quarters, prec);
  arb_sub(o.var1, o.var1, t, prec);
  clamp(o.var1, zero, three_quarters, prec);
  arb_sub(o.var2, one, x1, prec);
  arb_mul_2exp_si(t, sq, -1);
  arb_add(o.var2, o.var2, t, prec);
  arb_sub(t, x2, sq, prec);
  arb_mul(t, t, three_quarters, prec);
  arb_add(o.var2, o.var2, t, prec);
  clamp(o.var2, zero, nine_quarters, prec);
  return o;
}

/// The worst log2 relative radius over the observables.
double worst_relative_radius_log2(const Observables& o) {
  double worst = -std::numeric_limits<double>::infinity();
  for (const Ball* b : {&o.k1, &o.k2, &o.ratio, &o.cos1, &o.cos2, &o.var1, &o.var2})
    worst = std::max(worst, relative_radius_log2(*b));
  return worst;
}

/// The bits of the result type: 53 for double, the working precision's for MPFR.
template <class Real>
slong result_bits() {
  if constexpr (is_mpfr_v<Real>) {
    const Real probe = 0;
    return static_cast<slong>(mpfr_get_prec(probe.backend().data()));
  } else {
    return 53;
  }
}

/// The bits a run at `digits` must certify: 52 for double, digits log2(10) + 1 for MPFR.
slong target_bits(int digits) {
  return digits <= 16 ? 52 : static_cast<slong>(std::ceil(digits * 3.321928094887362)) + 1;
}

template <class Real>
Averages<Real> averages_of(const Observables& o, slong prec, std::size_t rows, bool converged,
                           Method method) {
  Averages<Real> out;
  out.method = method;
  out.error_kind = ErrorKind::bound;
  out.work_unit = WorkUnit::terms;
  out.evaluations = rows;
  out.converged = converged;
  out.beta_kinetic = {estimate_of<Real>(o.k1, prec), estimate_of<Real>(o.k2, prec)};
  out.cos_angle = {estimate_of<Real>(o.cos1, prec), estimate_of<Real>(o.cos2, prec)};
  out.beta2_kinetic_variance = {estimate_of<Real>(o.var1, prec), estimate_of<Real>(o.var2, prec)};
  out.ratio = estimate_of<Real>(o.ratio, prec);
  return out;
}

template Parameters parameters_of<double>(const Chain<double>&, const double*, slong);
template Parameters parameters_of<mpfr_real>(const Chain<mpfr_real>&, const mpfr_real*, slong);

}  // namespace certified_detail

using namespace certified_detail;

namespace {

/// The fast path's enclosure as an Estimate: the midpoint rounded to double, the error the ball's
/// radius plus that rounding (|h + l - value| computed with one rounding: two ulps up cover it).
Estimate<double> estimate_of_fast(const certified_fast::Enclosure& e) {
  Estimate<double> out;
  out.kind = ErrorKind::bound;
  out.value = e.hi + e.lo;
  const double rounding = std::fabs((e.hi - out.value) + e.lo);  // e.hi - value is exact
  const double inf = std::numeric_limits<double>::infinity();
  out.error = std::nextafter(std::nextafter(rounding + e.rad, inf), inf);
  return out;
}

Averages<double> averages_of_fast(const certified_fast::FastResult& r) {
  Averages<double> out;
  out.method = Method::certified_integral;
  out.error_kind = ErrorKind::bound;
  out.work_unit = WorkUnit::terms;
  out.evaluations = r.rows;
  out.converged = true;  // every radius is within 2^-60 of its value
  const auto& o = r.observables;
  out.beta_kinetic = {estimate_of_fast(o[0]), estimate_of_fast(o[1])};
  out.ratio = estimate_of_fast(o[2]);
  out.cos_angle = {estimate_of_fast(o[3]), estimate_of_fast(o[4])};
  out.beta2_kinetic_variance = {estimate_of_fast(o[5]), estimate_of_fast(o[6])};
  return out;
}

}  // namespace

template <class Real>
Averages<Real> certified_double_pendulum_average(const Chain<Real>& chain, const Real& beta,
                                                 int digits) {
  check_beta(beta);
  if constexpr (!is_mpfr_v<Real>) {
    // Double inputs and results: the double-word fast path (Sec. 10) when it certifies every
    // observable to 2^-60; otherwise Arb's balls below.
    if (chain.size() == 2 && digits <= 16) {
      if (const auto fast = certified_fast::fast_double_average(chain, static_cast<double>(beta)))
        return averages_of_fast(*fast);
    }
  }
  return certified_detail::arb_double_pendulum_average(chain, beta, digits);
}

template <class Real>
Averages<Real> certified_detail::arb_double_pendulum_average(const Chain<Real>& chain,
                                                             const Real& beta, int digits) {
  check_beta(beta);
  // Two goals (Sec. 7): the requested digits decide `converged`; the result type's own
  // precision (53 bits, or the working precision) is what the radius aims at, so that the
  // error stays within a few units of the value's last place (tight).
  const double requested = static_cast<double>(target_bits(digits));
  const double tight = static_cast<double>(result_bits<Real>());
  slong prec = static_cast<slong>(tight) + 24;
  // Tiny mu1: 1 - r^2 ~ 4 sqrt(mu1), which the 2F1 near z = 1 needs resolved in the ball of z
  // (whose radius is ~2^-prec): log2(1/mu1)/2 more bits where that exceeds 30 (mu1 < 1e-18).
  using std::log2;
  const double mu1_log2 = static_cast<double>(log2(Real(chain.mass(0) / chain.total_mass())));
  const slong near_one = std::isfinite(mu1_log2) ? static_cast<slong>(-mu1_log2 / 2) - 30 : 0;
  if (near_one > 0) prec += near_one;
  const slong max_prec = 2 * prec + 256;
  Observables best;
  double best_radius = std::numeric_limits<double>::infinity();
  std::size_t best_rows = 0;
  slong best_prec = prec;
  for (int attempt = 0; attempt < 5; ++attempt) {
    const Parameters p = parameters_of(chain, &beta, prec);
    // The plan (Sec. 7): rows until the Graf coefficients or the moments make the tail
    // negligible at e^{-L}, L = prec ln 2 + a margin; the tails are bounded a posteriori.
    const double L = static_cast<double>(prec) * 0.6931471805599453 + 8.0;
    const double orders = graf_orders_needed(p.a1_d, p.a2_d, L);
    const std::size_t moment_rows = moment_sum_terms(p.mu1_d, L);
    double rows_d = orders / 2.0 + 3.0;
    if (moment_rows > 0) rows_d = std::min(rows_d, static_cast<double>(moment_rows) + 2.0);
    rows_d = std::max(rows_d, 2.0);
    const bool capped = rows_d > static_cast<double>(certified_max_rows);
    const slong K = capped ? static_cast<slong>(certified_max_rows) : static_cast<slong>(rows_d);
    const Integrals I = integrals_of(p, K, L, prec);
    Observables o = observables_of(p, I.value, prec);
    const double radius = worst_relative_radius_log2(o);
    if (radius < best_radius || attempt == 0) {
      best = o;
      best_radius = radius;
      best_rows = static_cast<std::size_t>(K);
      best_prec = prec;
    }
    if (radius <= -tight || capped || prec >= max_prec) break;
    // Raise the precision by the bits missing (and at least 16).
    const double missing = std::isfinite(radius) ? radius + tight : 64.0;
    prec = std::min(max_prec, prec + std::max<slong>(16, static_cast<slong>(missing) + 16));
  }
  return averages_of<Real>(best, best_prec, best_rows, best_radius <= -requested,
                           Method::certified_integral);
}

template <class Real>
Averages<Real> certified_high_temperature_limit(const Chain<Real>& chain, int digits) {
  const slong prec = target_bits(digits) + 32;
  const Parameters p = parameters_of<Real>(chain, nullptr, prec);
  // beta -> 0: W = 1, J_s = 2 Q_0(s): J_{1/2} = 2E, J_{-1/2} = 2K, J_{-3/2} = 2E/mu1, C_j = 0.
  std::array<Ball, 5> J;
  complete_elliptic(J[1], J[0], p.mu1, p.mu2, prec);
  arb_div(J[2], J[0], p.mu1, prec);
  arb_zero(J[3]);
  arb_zero(J[4]);
  const Observables o = observables_of(p, J, prec);
  const bool converged = worst_relative_radius_log2(o) <= -static_cast<double>(target_bits(digits));
  return averages_of<Real>(o, prec, 1, converged, Method::certified_integral);
}

#endif  // PENDAVG_HAS_ARB

#ifdef PENDAVG_HAS_ARB
template Averages<double> certified_detail::arb_double_pendulum_average<double>(
    const Chain<double>&, const double&, int);
template Averages<mpfr_real> certified_detail::arb_double_pendulum_average<mpfr_real>(
    const Chain<mpfr_real>&, const mpfr_real&, int);
#endif

#define PENDAVG_INSTANTIATE_CERTIFIED(Real)                                                    \
  template Averages<Real> certified_double_pendulum_average<Real>(const Chain<Real>&,          \
                                                                  const Real&, int);           \
  template Averages<Real> certified_high_temperature_limit<Real>(const Chain<Real>&, int);
PENDAVG_INSTANTIATE_CERTIFIED(double)
PENDAVG_INSTANTIATE_CERTIFIED(mpfr_real)
#undef PENDAVG_INSTANTIATE_CERTIFIED

}  // namespace pendavg
