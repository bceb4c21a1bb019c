// SPDX-License-Identifier: GPL-3.0-or-later
// engine/double_pendulum/fourier_moments.hpp -- Fourier moments of q(t)^s, q = mu1 + mu2 sin^2 t.
//
// WHAT. For 0 < mu1 < 1, mu2 = 1 - mu1 (both passed, so neither is rounded away), and
// s in {1/2, -1/2, -3/2}, k = 0 .. count-1:
//     Q_k(s) = int_0^{pi/2} q(t)^s cos(2kt) dt .
// With theta = 2t, q = C |1 - r e^{i theta}|^2, C = ((1+sqrt mu1)/2)^2, r = (1-sqrt mu1)/(1+sqrt mu1)
// = e^{-2d}, d = atanh(sqrt mu1) = asinh(sqrt(mu1/mu2)), so that (DLMF 15.6.1 / Euler integral)
//     Q_k(s) = (pi/2) C^s r^k ((-s)_k / k!) 2F1(-s, k-s; k+1; r^2)                       (1)
// (a Legendre function P_s^k(coth 2d), equivalently a toroidal function of degree k-1/2).
//
// THE DIFFICULTY. In k the wanted Q_k is the minimal solution of
//     (k+1+s) Q_{k+1} = A k Q_k - (k-1-s) Q_{k-1},   A = 2 (1+mu1)/mu2,                    (2)
// but for k << 1/d the two solutions separate only algebraically, so forward recursion loses
// ~2 log10 k digits and Miller's algorithm must start near K + ln(1/u)/(4d) (hopeless for
// mu1 = 1e-12).
//
// METHOD.
//  * Symmetry P_nu = P_{-nu-1}: Q_k(-3/2) = -(4k^2-1)/mu1 Q_k(1/2) exactly (from (1) and the
//    connection formulas below), so only the rows s = -1/2 and s = -3/2 are recursed; the
//    row s = 1/2 is obtained from the row -3/2 elementwise.
//  * Top values (series method, used when the log-case series below is cheap and well
//    conditioned): Q_K(1/2) and Q_K(-1/2), K = count, from (1) expanded about r^2 = 1, i.e.
//    in powers of y = 1 - r^2 = 4 sqrt(mu1)/(1+sqrt mu1)^2 (A&S 15.3.10-12, DLMF 15.8.10,
//    logarithmic cases c-a-b = 2, 0). For half-integer s every Gamma prefactor is rational
//    times a power of pi, so
//      Q_k(1/2)  = C^{1/2} r^k [ -2/(4k^2-1) (1 + (2k-1) y/4) - (y^2/8) S_k ],
//        S_k = sum_n (3/2)_n (k+3/2)_n / (n! (n+2)!) y^n [psi(k+n+3/2) + ln y + psi(n+3/2)
//                                                        - psi(n+1) - psi(n+3)],
//      Q_k(-1/2) = C^{-1/2} r^k (1/2) sum_n (1/2)_n (k+1/2)_n / n!^2 y^n [2 psi(n+1)
//                                         - psi(n+1/2) - psi(k+n+1/2) - ln y].
//    The digamma at k is taken as ln(y x/4) + (psi(x) - ln x) (no cancellation between ln y
//    and psi). These series cost O(ln(1/u)/ln(1/y) + e*4Kd) terms and lose a factor
//    kappa ~ 1 + e^{4Kd}/(4Kd + 1/(4Kd)) to cancellation (measured: 1.0-1.7 for Kd <= 0.5,
//    ~6 at Kd = 1, ~3e2 at 2). Where kappa is not small the loss is absorbed by a wider type:
//    double -> long double (up to Kd ~ 2); mpfr -> mpfr with log10(kappa) extra digits; long
//    double -> long double up to kappa ~ 8, or MPFR when the alternative is a very long
//    Miller run.
//    The differences Q_{K-1} - Q_K are NOT formed by subtraction (that would amplify the top
//    error ~K-fold in the algebraic regime, where the two solutions are nearly parallel)
//    but from the contiguous relation
//    Q_k(s+1) = (s+1)/(s+1+k) [(1+mu1)/2 Q_k(s) - mu2/2 Q_{k-1}(s)], which gives
//      mu2 D_{K-1}(-1/2) = 2 mu1 Q_K(-1/2) - 2(2K+1) Q_K(1/2),
//      mu2 D_{K-1}(-3/2) = 2 mu1 Q_K(-3/2) + 2(2K-1) Q_K(-1/2),   D_k = Q_k - Q_{k+1},
//    sums of same-signed terms (Q_K(1/2) < 0 for K >= 1).
//  * Miller method (used when the series is slow or ill-conditioned, i.e. when K d or mu1 is
//    not small, where it is cheap): (2) run down from N = K + (ln(1/u)+5)/(4d) + 10 with
//    Q_{N+1} = 0, then normalised to the exact Q_0(-1/2) = K(k), Q_0(-3/2) = E(k)/mu1
//    (Carlson forms, numerics/elliptic.hpp). The crossover is decided by an a-priori cost
//    (series terms estimated from the term ratios) and the conditioning estimate kappa.
//  * The downward recursion is run in the difference form, which is free of cancellation
//    (all terms of one sign) and keeps A - 2 = 4 mu1/mu2 exact in relative terms:
//      s = -1/2: w_k = (2k+1) D_k,      w_{k-1} = w_k + e k Q_k,           D_{k-1} = w_{k-1}/(2k-1)
//      s = -3/2: w_k = D_k/(2k+1),      w_{k-1} = w_k + e k Q_k/(4k^2-1),  D_{k-1} = (2k-1) w_{k-1}
//      Q_{k-1} = Q_k + D_{k-1},  e = 8 mu1/mu2.
//    For double and long double the two running sums per row are compensated (TwoSum), and the
//    increments are formed from the compensated values, so the rounding error does not grow
//    with K (naive sums drift ~sqrt(K) u: 15 ulps at K = 3000). MPFR runs the recursion with
//    log10 sqrt(K) + 4 extra digits instead. In the series method the recursion result at
//    k = 0 is compared with the exact Q_0 (a-posteriori check, added to the reported error)
//    and Q_0 is set to the exact value; values below the underflow threshold become 0.
//
// ACCURACY (tests/engine/double_pendulum/test_fourier_moments.cpp, mu1 in [1e-15, 1), count <= 5000): max_k
// |Q_k - exact| / max_k |Q_k| <= ~2 eps in double, <= ~7 eps in long double (mostly Boost's
// long double Carlson E, ~3 eps), <= 0.5 u for MPFR (up to 1000 digits); per element it is
// a few ulps of |Q_k| wherever the Q_k decay algebraically (k d << 1). `relative_error` is a
// first-order bound on max_k |Q_k - exact| / max_k |Q_k| (max over rows): 3 x the top-value
// error (tracked term by term in the series) + recursion/normalisation roundings + the Q_0
// mismatch + final rounding; it exceeded the measured error in every test case (typically
// 3-30x).
// COST: O(count) recursion steps plus, in the worst mid range (Kd ~ 2), a Miller run of
// <~ 5 count extra steps (timings: README, "The N = 2 cost model").
//
// References: DLMF 15.6.1, 15.8.10 (A&S 15.3.10-15.3.12), 14.3, 14.10 (recurrences), 5.7.6 /
// 5.11.2 (digamma), 19.25 (Carlson K, E); Gautschi, SIAM Rev. 9 (1967) (minimal solutions);
// Higham, Accuracy and Stability, ch. 4 (compensated summation).
#pragma once

#include "engine/numerics/bernoulli.hpp"
#include "engine/numerics/elliptic.hpp"
#include "engine/numerics/precision.hpp"

#include <boost/math/constants/constants.hpp>
#include <boost/math/special_functions/digamma.hpp>
#include <boost/math/special_functions/log1p.hpp>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstddef>
#include <limits>
#include <stdexcept>
#include <type_traits>
#include <vector>

namespace pendavg::detail {

template <class Real>
struct QPowerMoments {
  std::array<std::vector<Real>, 3> Q;  // rows: s = 1/2, -1/2, -3/2
  Real relative_error;                 // bound on max_k |Q_k - exact| / max_k |Q_k|, max over rows
};

namespace fourier_moments_impl {

// ---------------------------------------------------------------- number-type plumbing

template <class T>
T make(double v) {
  return T(v);
}

template <class T>
T unit_roundoff_of() {
  if constexpr (is_mpfr_v<T>) {
    return unit_roundoff<T>();
  } else {
    return std::numeric_limits<T>::epsilon() / 2;
  }
}

// ln(1/u) as a double (u may be far below the double range for MPFR).
template <class T>
double log_inv(const T& u) {
  using std::log;
  return -static_cast<double>(log(u));
}

// psi(x) - ln x for x >= 1/2 without the cancellation of psi(x) - ln x at large x.
template <class W>
W digamma_minus_log(const W& x, const W& u) {
  using std::abs;
  using std::log;
  if constexpr (is_mpfr_v<W>) {
    // DLMF 5.11.2 at x + m >= x0: psi(y) ~ ln y - 1/(2y) - sum_j B_{2j} / (2j y^{2j}), with the
    // coefficients of numerics/bernoulli.hpp (per precision, not Boost's process-wide cache), and
    // below x0 the recurrence psi(x) = psi(x + m) - sum_{i<m} 1/(x + i) (which cancels at most
    // ~log10(x0 ln x0) digits, inside the moments' extra digits).
    const double x0 = 1.2 * log_inv(u) / (2 * 3.141592653589793) + 2.0;
    if (x < x0 && x >= 1) {
      // Integers and half-integers (series_top asks for psi(K + 1/2)) in closed form (DLMF
      // 5.4.14-15): psi(n) = -gamma + sum_{k<n} 1/k, psi(n + 1/2) = -gamma - 2 ln 2 +
      // sum_{k<=n} 2/(2k - 1), minus ln x; word divisions only (the recurrence and series below
      // cost ~5x). Summed and cancelled against ln x with 64 guard bits, then rounded once.
      W twice = x;
      twice *= 2;
      if (twice == floor(twice) && twice < 1e9) {
        const auto n2 = static_cast<unsigned long>(twice);  // 2x
        W result;
        mpfr_t psi, t;
        mpfr_inits2(mpfr_get_prec(result.backend().data()) + 64, psi, t,
                    static_cast<mpfr_ptr>(nullptr));
        mpfr_const_euler(psi, MPFR_RNDN);
        mpfr_neg(psi, psi, MPFR_RNDN);
        if (n2 % 2 == 1) {
          mpfr_const_log2(t, MPFR_RNDN);
          mpfr_mul_2ui(t, t, 1, MPFR_RNDN);
          mpfr_sub(psi, psi, t, MPFR_RNDN);
          for (unsigned long odd = 1; odd < n2; odd += 2) {  // 2k - 1 < 2n + 1
            mpfr_set_ui(t, 2, MPFR_RNDN);
            mpfr_div_ui(t, t, odd, MPFR_RNDN);
            mpfr_add(psi, psi, t, MPFR_RNDN);
          }
        } else {
          for (unsigned long k = 1; 2 * k < n2; ++k) {
            mpfr_set_ui(t, 1, MPFR_RNDN);
            mpfr_div_ui(t, t, k, MPFR_RNDN);
            mpfr_add(psi, psi, t, MPFR_RNDN);
          }
        }
        mpfr_log(t, x.backend().data(), MPFR_RNDN);
        mpfr_sub(psi, psi, t, MPFR_RNDN);
        mpfr_set(result.backend().data(), psi, MPFR_RNDN);
        mpfr_clears(psi, t, static_cast<mpfr_ptr>(nullptr));
        return result;
      }
    }
    W y = x, shift = 0;
    if (x < x0) {
      const auto m = static_cast<unsigned long>(std::ceil(x0 - static_cast<double>(x)));
      for (unsigned long i = 0; i < m; ++i) shift -= 1 / (x + i);
      y = x + m;
      shift += log(y / x);
    }
    const auto table = digamma_series_coefficients();
    const std::vector<W>& c = *table;
    const W y2inv = 1 / (y * y);
    W sum = -1 / (2 * y);
    W p = y2inv;
    for (std::size_t j = 1; j < c.size(); ++j) {
      const W term = c[j] * p;
      sum -= term;
      if (abs(term) <= u * abs(sum)) break;
      p *= y2inv;
    }
    return sum + shift;
  } else {
    // B_{2j}/(2j), j = 1..10 (exact rationals rounded to W); for x >= 16 the omitted terms
    // are below 1e-21 relative.
    static const W c[10] = {W(1) / 12,        W(-1) / 120,        W(1) / 252,
                            W(-1) / 240,      W(1) / 132,         W(-691) / 32760,
                            W(1) / 12,        W(-3617) / 8160,    W(43867) / 14364,
                            W(-174611) / 6600};
    if (x < 16) return boost::math::digamma(x) - log(x);
    const W x2inv = 1 / (x * x);
    W poly = c[9];
    for (int j = 8; j >= 0; --j) poly = poly * x2inv + c[j];
    return -1 / (2 * x) - poly * x2inv;
  }
}

// Error-free a + b = s + e (Knuth TwoSum).
template <class T>
inline void two_sum_acc(T& s, T& c, const T& b) {
  const T a = s;
  s = a + b;
  const T bb = s - a;
  c += (a - (s - bb)) + (b - bb);
}

// ---------------------------------------------------------------- top values (series)

template <class W>
struct TopValues {
  W q_half;    // Q_K(1/2)
  W q_mhalf;   // Q_K(-1/2)
  W rel_err;   // estimated relative error bound of both, units of 1
  bool ok = true;
};

// Magnitudes for convergence tests and error weights: double where W is a hardware type
// (cheap; u of long double is representable), W itself for MPFR (u may underflow double).
template <class W>
using mag_t = std::conditional_t<is_mpfr_v<W>, W, double>;

// Q_K(1/2) and Q_K(-1/2) from the log-case expansion in y = 1 - r^2 (see header comment).
template <class W>
TopValues<W> series_top(const W& mu1, std::size_t K) {
  using std::abs;
  using std::exp;
  using std::log;
  using std::sqrt;
  using M = mag_t<W>;
  const W u = unit_roundoff_of<W>();
  const M um = static_cast<M>(u);
  const W one = make<W>(1);
  const W half = one / 2;
  const W rm = sqrt(mu1);
  const W opr = one + rm;
  const W y = 4 * rm / (opr * opr);
  const M ym = static_cast<M>(y);
  const W kk = make<W>(static_cast<double>(K));
  const W lnr = boost::math::log1p(-2 * rm / opr);  // ln r = -2d
  const W rK = exp(kk * lnr);
  const W euler = boost::math::constants::euler<W>();

  // B_0 of row 1/2: psi(K+3/2) + ln y + psi(3/2) - psi(1) - psi(3) = G(K+3/2) + 1/2 + gamma,
  // B_0 of row -1/2: 2 psi(1) - psi(1/2) - psi(K+1/2) - ln y = -gamma - G(K+1/2),
  // G(x) = ln(y x / 4) + (psi(x) - ln x) = psi(x) + ln(y/4).
  const W xm = kk + half;
  const W Gm = log(y * xm / 4) + digamma_minus_log(xm, u);
  const W Gh = Gm + 1 / xm;  // psi(x+1) = psi(x) + 1/x
  W Bh = Gh + half + euler;
  W Bm = -euler - Gm;
  // absolute error of the base brackets in units of u (a few roundings)
  const M Bh_err = abs(static_cast<M>(Gh)) + 4;
  const M Bm_err = abs(static_cast<M>(Gm)) + 4;

  W th = half, tm = one;  // term coefficients t_n
  W Sh = 0, Sm = 0;       // sums of t_n B_n
  M Ah = 0, Am = 0;       // error weights (units of u)
  // carried reciprocals: 1/(n+1/2), 1/(n+1), 1/(n+2), 1/(K+n+1/2)
  W inv_nh = 2 * one;
  W inv_n1 = one;
  W inv_n2 = half;
  W inv_kh = 1 / xm;
  const std::size_t max_terms = 2000000;
  bool done_h = false, done_m = false;
  std::size_t n = 0;
  W nn = 0;
  for (; n < max_terms; ++n, nn += 1) {
    const W inv_n3h = 1 / (nn + 1 + half);      // 1/(n+3/2)
    const W inv_n3 = 1 / (nn + 3);              // 1/(n+3)
    const W inv_k3h = 1 / (kk + nn + 1 + half);  // 1/(K+n+3/2)
    const M nerr = static_cast<M>(6.0 * static_cast<double>(n) + 4.0);  // roundings in t_n B_n
    if (!done_h) {
      const W term = th * Bh;
      Sh += term;
      Ah += abs(static_cast<M>(term)) * nerr + static_cast<M>(th) * Bh_err;
    }
    if (!done_m) {
      const W term = tm * Bm;
      Sm += term;
      Am += abs(static_cast<M>(term)) * nerr + static_cast<M>(tm) * Bm_err;
    }
    // advance to n+1
    const W rho_h = y * (nn + 1 + half) * (kk + nn + 1 + half) * inv_n1 * inv_n3;
    const W rho_m = y * (nn + half) * (kk + nn + half) * inv_n1 * inv_n1;
    th *= rho_h;
    tm *= rho_m;
    Bh += inv_k3h + inv_n3h - inv_n1 - inv_n3;
    Bm += 2 * inv_n1 - inv_nh - inv_kh;
    // Tail bounds: the term ratios are monotone with limit y (decreasing, or increasing
    // towards y), and |B| grows by at most 2j/(n+1) over j further terms, so
    // tail <= t_{n+1} (|B_{n+1}|/(1-rb) + 2/((n+1)(1-rb)^2)), rb = max(rho_n, y).
    const M np1 = static_cast<M>(nn) + 1;
    const auto tail_negligible = [&](const auto& rho_x, const auto& t, const auto& B, const auto& S) {
      const M rho = static_cast<M>(rho_x);
      const M rb = rho > ym ? rho : ym;
      if (!(rb < 1)) return false;
      const M omr = 1 - rb;
      const M tail = static_cast<M>(t) * (abs(static_cast<M>(B)) / omr + 2 / (np1 * omr * omr));
      return tail <= um * abs(static_cast<M>(S)) / 4;
    };
    if (!done_h && tail_negligible(rho_h, th, Bh, Sh)) done_h = true;
    if (!done_m && tail_negligible(rho_m, tm, Bm, Sm)) done_m = true;
    if (done_h && done_m) break;
    // rotate carried reciprocals
    inv_nh = inv_n3h;
    inv_n1 = inv_n2;
    inv_n2 = inv_n3;
    inv_kh = inv_k3h;
  }
  TopValues<W> out;
  out.ok = done_h && done_m;
  const W fourK2m1 = 4 * kk * kk - 1;
  const W fin = -2 / fourK2m1 * (1 + (2 * kk - 1) * y / 4);
  const W logpart = -(y * y / 8) * Sh;
  const W brack = fin + logpart;
  out.q_half = (opr / 2) * rK * brack;
  out.q_mhalf = (2 / opr) * rK * (Sm / 2);
  // relative errors: series (term-wise weights) + bracket assembly + prefactor (the exp
  // argument K ln r carries relative error ~2u, i.e. absolute ~u * 4Kd)
  const M pref_err = um * (8 + 2 * abs(static_cast<M>(kk * lnr)));
  const M eh = um * (Ah * static_cast<M>(y * y / 8) + 4 * abs(static_cast<M>(fin)) +
                     4 * abs(static_cast<M>(logpart))) /
               abs(static_cast<M>(brack));
  const M em = um * Am / abs(static_cast<M>(Sm));
  out.rel_err = static_cast<W>((eh > em ? eh : em) + pref_err);
  return out;
}

// ---------------------------------------------------------------- downward recursion

/// The two rows of the downward recursion: row a (s = -1/2) and row b (s = -3/2), each as the
/// moment Q and the difference variable w with their compensations (cQ, cw), and QF, the value
/// used for the next increment (hi plus the compensation lagging by one step).
template <class Wr>
struct DownwardRows {
  Wr Qa, ca = Wr(0), wa, cwa = Wr(0), Qb, cb = Wr(0), wb, cwb = Wr(0);
  Wr QFa, QFb;
};

/// The downward recursion of recurse_down in MPFR, from index k: in place (see below).
template <class Wr>
void recurse_down_mpfr(const Wr& e, std::size_t K, std::size_t k, DownwardRows<Wr>& r, Wr* qa,
                       Wr* qb) {
  // In-place MPFR loop: integer multipliers/divisors map to mpfr_{mul,div}_ui, no
  // temporaries are allocated, and no rescaling is needed (growth <= e^{2dN} is far inside
  // MPFR's exponent range for any feasible N).
  Wr t;
  for (; k >= 1; --k) {
    const unsigned long ku = static_cast<unsigned long>(k);
    t = e;
    t *= ku;
    t *= r.Qa;
    r.wa += t;  // w_{k-1} = w_k + e k Q_k
    t = r.wa;
    t /= (2 * ku - 1);
    r.Qa += t;  // Q_{k-1} = Q_k + w_{k-1}/(2k-1)
    t = e;
    t *= ku;
    t *= r.Qb;
    t /= (4 * ku * ku - 1);
    r.wb += t;  // w_{k-1} = w_k + e k Q_k/(4k^2-1)
    t = r.wb;
    t *= (2 * ku - 1);
    r.Qb += t;  // Q_{k-1} = Q_k + (2k-1) w_{k-1}
    if (k - 1 < K) {
      qa[k - 1] = r.Qa;
      qb[k - 1] = r.Qb;
    }
  }
}

/// The downward recursion of recurse_down in a hardware type, from index k (kk = k as Wr), with
/// compensated sums when Compensate and rescaling against overflow.
template <class Wr, bool Compensate>
void recurse_down_scaled(const Wr& e, std::size_t K, std::size_t top, std::size_t k, Wr kk,
                         DownwardRows<Wr>& r, Wr* qa, Wr* qb) {
  using std::abs;
  // Rescaling guards against overflow in Miller runs over geometric growth; stored values
  // that would become subnormal are set to 0 (they are < u * max |Q| by far).
  std::size_t live_a = K, live_b = K;
  Wr big, shrink, tiny;
  if constexpr (is_mpfr_v<Wr>) {
    big = ldexp(Wr(1), 1 << 24);
    shrink = ldexp(Wr(1), -(1 << 24));
    tiny = 0;
  } else {
    const int scale_exp = std::numeric_limits<Wr>::max_exponent / 2;
    const double grow = 4.0 + static_cast<double>(e) * (static_cast<double>(top) + 1) * 4;
    big = std::ldexp(Wr(1), scale_exp) / Wr(grow);
    shrink = std::ldexp(Wr(1), -scale_exp);
    tiny = std::numeric_limits<Wr>::min() / shrink;
  }
  auto rescale_tail = [&](Wr* v, std::size_t from, std::size_t& live_end) {
    for (std::size_t i = from; i < live_end; ++i) v[i] = abs(v[i]) < tiny ? Wr(0) : Wr(v[i] * shrink);
    while (live_end > from && v[live_end - 1] == 0) --live_end;
  };
  for (; k >= 1; --k) {
    const Wr tkm1 = 2 * kk - 1;
    const Wr tkp1 = 2 * kk + 1;
    const Wr inv = 1 / (tkm1 * tkp1);  // 1/(4k^2-1)
    const Wr ek = e * kk;
    if constexpr (Compensate) {
      // State (Q, cQ), (w, cw) is kept exactly by TwoSum. The values used to form the next
      // increments/differences are hi + (compensation lagging by one step): local errors
      // <= u, nothing accumulates, and the latency chain avoids the TwoSum error paths.
      // (Using the bare hi parts instead would leak the sqrt(K) u drift of naive summation
      // back through the coupling.)
      const Wr inca = ek * r.QFa;              // row a (s = -1/2)
      const Wr incb = (ek * inv) * r.QFb;      // row b (s = -3/2)
      const Wr Da = (r.wa + inca + r.cwa) * (tkp1 * inv);
      const Wr Db = tkm1 * (r.wb + incb + r.cwb);
      two_sum_acc(r.wa, r.cwa, inca);
      two_sum_acc(r.wb, r.cwb, incb);
      const Wr cao = r.ca, cbo = r.cb;
      two_sum_acc(r.Qa, r.ca, Da);
      two_sum_acc(r.Qb, r.cb, Db);
      r.QFa = r.Qa + cao;
      r.QFb = r.Qb + cbo;
    } else {
      r.wa += ek * r.Qa;
      r.Qa += r.wa * tkp1 * inv;
      r.wb += ek * r.Qb * inv;
      r.Qb += tkm1 * r.wb;
    }
    kk -= 1;
    const std::size_t km1 = k - 1;
    if (km1 < K) {
      if constexpr (Compensate) {
        qa[km1] = r.Qa + r.ca;
        qb[km1] = r.Qb + r.cb;
      } else {
        qa[km1] = r.Qa;
        qb[km1] = r.Qb;
      }
    }
    if (abs(r.Qa) > big) {
      r.Qa *= shrink; r.ca *= shrink; r.wa *= shrink; r.cwa *= shrink; r.QFa *= shrink;
      if (km1 < K) rescale_tail(qa, km1, live_a);
    }
    if (abs(r.Qb) > big) {
      r.Qb *= shrink; r.cb *= shrink; r.wb *= shrink; r.cwb *= shrink; r.QFb *= shrink;
      if (km1 < K) rescale_tail(qb, km1, live_b);
    }
  }
}

// Runs (2) downward for the rows s = -1/2 (a) and s = -3/2 (b) in difference form and stores
// the unnormalised Q_k, k < K, into qa, qb (size K). Start: the top pair (Q_K, D_{K-1}) given
// as hi + lo parts {Q hi, Q lo, D hi, D lo}, or Miller's Q_{N+1} = 0, Q_N = 1 (start == null).
template <class Wr, bool Compensate>
void recurse_down(const Wr& e, std::size_t K, std::size_t top, const Wr* startA,
                  const Wr* startB, Wr* qa, Wr* qb) {
  DownwardRows<Wr> r;
  std::size_t k;
  Wr kk = Wr(static_cast<double>(top));
  if (startA) {
    // state at index K-1: Q_{K-1} = Q_K + D_{K-1}; w_{K-1} = (2K-1) D (row a), D/(2K-1) (b)
    k = top - 1;
    r.Qa = startA[0];
    r.ca = startA[1];
    two_sum_acc(r.Qa, r.ca, startA[2]);
    r.ca += startA[3];
    r.wa = (2 * kk - 1) * startA[2];
    r.cwa = (2 * kk - 1) * startA[3];
    r.Qb = startB[0];
    r.cb = startB[1];
    two_sum_acc(r.Qb, r.cb, startB[2]);
    r.cb += startB[3];
    r.wb = startB[2] / (2 * kk - 1);
    r.cwb = startB[3] / (2 * kk - 1);
    kk -= 1;
  } else {
    k = top;  // Q_{N+1} = 0: D_N = Q_N = 1
    r.Qa = 1;
    r.wa = 2 * kk + 1;
    r.Qb = 1;
    r.wb = 1 / (2 * kk + 1);
  }
  r.QFa = r.Qa + r.ca;
  r.QFb = r.Qb + r.cb;
  if (k < K) {
    qa[k] = r.QFa;
    qb[k] = r.QFb;
  }
  if constexpr (is_mpfr_v<Wr>) {
    static_assert(!Compensate, "MPFR runs with extra digits instead of compensation");
    recurse_down_mpfr(e, K, k, r, qa, qb);
  } else {
    recurse_down_scaled<Wr, Compensate>(e, K, top, k, kk, r, qa, qb);
  }
}

// ---------------------------------------------------------------- planning

struct Plan {
  bool series = false;
  bool series_in_mpfr = false;  // long double only: wide series in MPFR
  std::size_t miller_top = 0;
  int extra_digits = 0;         // mpfr: extra decimal digits of the wide evaluation
};

// A-priori estimates in double. Number of terms the row s = -1/2 series (the slower one)
// needs to reach relative size exp(-lnu) of its largest term, capped at `cap`.
inline double estimate_series_terms(double mu1, std::size_t K, double lnu, double cap) {
  const double rm = std::sqrt(mu1);
  const double y = 4 * rm / ((1 + rm) * (1 + rm));
  const double k = static_cast<double>(K);
  // t is kept as t * 10^e10 to survive very small targets (high MPFR precision).
  double t = 1, tmax = 1;
  int e10 = 0;
  const double direct = lnu < 600 ? std::exp(-lnu) * 0.05 : 0.0;
  for (double n = 0; n < cap; n += 1) {
    const double rho = y * (n + 0.5) * (k + n + 0.5) / ((n + 1) * (n + 1));
    t *= rho;
    if (e10 == 0 && t > tmax) tmax = t;
    if (t < 1e-200) {
      t *= 1e200;
      e10 -= 200;
    }
    if (rho < 1) {
      const double rb = std::max(rho, y);
      if (direct > 0) {
        if (e10 < 0 || t < direct * tmax * (1 - rb)) return n + 1;
      } else if (std::log(t / tmax) + e10 * 2.302585092994046 + std::log(1 / (1 - rb)) <
                 -lnu - 3) {
        return n + 1;
      }
    }
  }
  return cap;
}

inline double series_condition_estimate(double Kd) {
  // sum |terms| / |sum| measured: 1.0-1.2 for Kd <= 0.25, 1.7 at 0.5, 6-7 at 1, 2.2e2-2.8e2
  // at 2, 5e5-6e5 at 4; this formula is above all of them.
  const double x = std::min(4 * Kd, 700.0);
  return 1 + std::exp(x) / (x + 1 / x);
}

}  // namespace fourier_moments_impl

namespace fourier_moments_impl {

// Few terms: plain forward recurrence (2) from the exact Q_0, Q_1 (hardware floats). Fills
// `out` and returns true when its amplification of rounding stays small, false otherwise.
template <class Real>
bool short_row_moments(const Real& mu1, const Real& mu2, std::size_t K, QPowerMoments<Real>& out) {
  // It amplifies rounding by at most (1 + K^2) e^{4Kd} (algebraic, then geometric separation),
  // which for short rows stays small -- and it is several times cheaper than the series or
  // Miller's method (q_power_moments_with).
  const Real u_R = unit_roundoff_of<Real>();
  const double dd = std::atanh(std::sqrt(static_cast<double>(mu1 / (mu1 + mu2))));
  const double Kl = static_cast<double>(K - 1);  // the last index computed
  const double amplification = (1 + Kl * Kl) * std::exp(4 * Kl * dd);
  const double limit = std::is_same_v<Real, long double> ? 64.0 : 16.0;
  if (amplification <= limit) {
    const auto ell = complete_elliptic_from_complement(mu1);
    // Q_0(s) for s = 3/2, 1/2, -1/2, -3/2; rows s = 1/2, -1/2, -3/2 as sigma = 2s.
    const std::array<Real, 4> Q0 = {(2 * (1 + mu1) * ell.E - mu1 * ell.K) / 3, ell.E, ell.K,
                                    ell.E / mu1};
    constexpr std::array<long, 3> sigma = {1, -1, -3};
    const Real two_c = 4 + 8 * mu1 / mu2;
    for (std::size_t r = 0; r < 3; ++r) {
      auto& Q = out.Q[r];
      Q.assign(K, Real(0));
      Q[0] = Q0[r + 1];
      // Q_1(s) = ((1 + mu1)/mu2) Q_0(s) - (2/mu2) Q_0(s + 1)
      if (K > 1) Q[1] = ((1 + mu1) * Q0[r + 1] - 2 * Q0[r]) / mu2;
      // Q_{k+1} = (2c k Q_k - (2k - 2 - sigma) Q_{k-1}) / (2k + 2 + sigma), c = 2 + 4 mu1/mu2
      for (std::size_t k = 1; k + 1 < K; ++k) {
        const long kk = static_cast<long>(k);
        Q[k + 1] = (two_c * Real(kk) * Q[k] - Real(2 * kk - 2 - sigma[r]) * Q[k - 1]) /
                   Real(2 * kk + 2 + sigma[r]);
      }
    }
    // Carlson K, E to a few ulps (long double: ~3 eps = 6 u), then the amplified recurrence.
    out.relative_error = Real(8 + 4 * amplification) * u_R;
    return true;
  }
  return false;
}

// The evaluation plan of q_power_moments_with, in double (ln u and d are fine in double for any
// precision): the top values by the series (in Ws; long double: possibly in MPFR) and the
// recursion down from them, or a Miller run from miller_top; and the extra MPFR digits.
template <class Real, class Ws>
Plan moments_plan(const Real& mu1, const Real& mu2, std::size_t K) {
  namespace impl = fourier_moments_impl;
  constexpr bool is_double = std::is_same_v<Real, double>;
  constexpr bool is_ldouble = std::is_same_v<Real, long double>;
  constexpr bool wide_series = !std::is_same_v<Real, Ws>;  // double result, long double series
  const Real u_R = impl::unit_roundoff_of<Real>();
  const double mu1d = std::max(static_cast<double>(mu1), 1e-300);
  const double mu2d = static_cast<double>(mu2);
  const double d = std::atanh(std::sqrt(mu1d / (mu1d + mu2d)));  // atanh(sqrt mu1)
  const double Kd = static_cast<double>(K) * d;
  const double kappa = impl::series_condition_estimate(Kd);
  impl::Plan plan;
  const double lnu_target = impl::log_inv(u_R);
  const double lnu_s = wide_series ? impl::log_inv(impl::unit_roundoff_of<Ws>()) : lnu_target;
  {
    // Miller: extra steps beyond K so that e^{-4 d (N-K)} < u e^{-5}
    const double miller_len = (lnu_target + 5) / (4 * d) + 10;
    // cost in recursion steps: per series term, fixed (logs, digamma, exp). MPFR: a series
    // term is three divisions, ~20 multiplications and additions on temporaries and the error
    // weights, and the series runs with log10(kappa) extra digits.
    // Why: README, Design notes, 'Measurements behind the design choices' (N = 2).
    double c_term = is_double ? (wide_series ? 8.0 : 2.0) : is_ldouble ? 1.0 : 13.0;
    if constexpr (is_mpfr_v<Real>) {
      c_term *= 1.0 + std::log10(kappa) / static_cast<double>(current_digits10<Real>());
    }
    const double c_fixed = is_double ? (wide_series ? 80.0 : 40.0) : is_ldouble ? 15.0 : 30.0;
    const double cap = (miller_len - c_fixed) / c_term;
    // obviously convergent (y < 0.05, K y < 4) -> skip the estimate
    const bool quick = mu1d < 1.5e-4 && Kd < 1 && cap > 40;
    const double n_terms =
        quick ? 0.0 : cap > 1 ? impl::estimate_series_terms(mu1d, K, lnu_s, cap) : cap;
    const bool cheaper = n_terms < cap;
    double kappa_max;
    if constexpr (wide_series) {
      kappa_max = 0.25 * std::exp(lnu_s - lnu_target);  // long double series, double result
    } else if constexpr (!is_mpfr_v<Real>) {
      kappa_max = 8;  // same-type series: a few ulps (bound reports it)
    } else {
      kappa_max = std::numeric_limits<double>::infinity();  // extra digits instead
    }
    if (cheaper && kappa <= kappa_max) {
      plan.series = true;
    } else if constexpr (is_ldouble) {
      // MPFR series (~60 long double recursion steps per term) versus a long Miller run.
      const double cap2 = (miller_len - 60 * 30) / 60;
      if (cap2 > 1) {
        const double nt =
            impl::estimate_series_terms(mu1d, K, lnu_target + std::log(kappa * 16), cap2);
        if (nt < cap2) {
          plan.series = true;
          plan.series_in_mpfr = true;
          plan.extra_digits = static_cast<int>(std::ceil(std::log10(kappa))) + 3;
        }
      }
    }
    if (!plan.series) {
      if (miller_len > 1e9) throw std::length_error("q_power_moments: Miller run too long");
      plan.miller_top = K + static_cast<std::size_t>(std::ceil(miller_len));
    }
    if constexpr (is_mpfr_v<Real>) {
      const double kd_digits = plan.series ? std::log10(kappa) : 0.0;
      plan.extra_digits =
          static_cast<int>(std::ceil(kd_digits + 0.5 * std::log10(static_cast<double>(K) + 1))) +
          4;
    }
  }
  return plan;
}

/// The recursion's start pairs (Q_K, D_{K-1}) of rows -1/2 (sa) and -3/2 (sb), each as a
/// hi + lo pair of Wr, from the series' top values Q_K(1/2), Q_K(-1/2) (in Ws; long double with
/// plan.series_in_mpfr: in MPFR with the plan's extra digits). Returns the top values' relative
/// error.
template <class Real, class Ws, class Wr>
Wr series_start_pairs(const Plan& plan, const Real& mu1, const Real& mu2, const Ws& mu1s,
                      const Ws& mu2s, std::size_t K, Wr (&sa)[4], Wr (&sb)[4]) {
  namespace impl = fourier_moments_impl;
  auto make_start = [&](const auto& m1, const auto& m2, const auto& top, auto split) {
    using T = std::decay_t<decltype(m1)>;
    const T kw = T(static_cast<double>(K));
    const T q3 = -(4 * kw * kw - 1) * top.q_half / m1;
    const T dA = (2 * m1 * top.q_mhalf - 2 * (2 * kw + 1) * top.q_half) / m2;
    const T dB = (2 * m1 * q3 + 2 * (2 * kw - 1) * top.q_mhalf) / m2;
    split(top.q_mhalf, sa[0], sa[1]);
    split(dA, sa[2], sa[3]);
    split(q3, sb[0], sb[1]);
    split(dB, sb[2], sb[3]);
  };
  if (plan.series_in_mpfr) {
    if constexpr (std::is_same_v<Real, long double>) {
      working_precision guard(std::numeric_limits<long double>::digits10 + 3 + plan.extra_digits);
      const mpfr_real m1 = mpfr_real(mu1);
      const mpfr_real m2 = mpfr_real(mu2);
      const auto top = impl::series_top(m1, K);
      if (!top.ok) throw std::runtime_error("q_power_moments: series did not converge");
      make_start(m1, m2, top, [](const mpfr_real& v, Wr& hi, Wr& lo) {
        hi = static_cast<Wr>(v);
        lo = static_cast<Wr>(mpfr_real(v - mpfr_real(hi)));
      });
      return static_cast<Wr>(top.rel_err);
    }
    return Wr(0);
  }
  const auto top = impl::series_top(mu1s, K);
  if (!top.ok) throw std::runtime_error("q_power_moments: series did not converge");
  make_start(mu1s, mu2s, top, [](const Ws& v, Wr& hi, Wr& lo) {
    hi = static_cast<Wr>(v);
    lo = static_cast<Wr>(v - static_cast<Ws>(hi));
  });
  return static_cast<Wr>(top.rel_err);
}

/// A Miller run's rows scaled to their exact Q_0 (fa = K(m)/qa[0], fb = E(m)/(mu1 qb[0]));
/// values that would underflow become 0 (the rows decrease in |Q_k|).
template <class Wr>
void normalise_miller_rows(Wr* qa, Wr* qb, std::size_t K, const Wr& Kell, const Wr& E_mu1) {
  using std::abs;
  const Wr fa = Kell / qa[0];
  const Wr fb = E_mu1 / qb[0];
  auto normalise = [&](Wr* q, const Wr& f) {
    Wr lim = 0;
    if constexpr (!is_mpfr_v<Wr>) lim = std::numeric_limits<Wr>::min() / f;
    std::size_t k = 0;
    for (; k < K && abs(q[k]) >= lim; ++k) q[k] *= f;
    for (; k < K; ++k) q[k] = 0;
  };
  normalise(qa, fa);
  normalise(qb, fb);
}

/// The output rows from the recursion's rows -1/2 (qa) and -3/2 (qb): row 1/2 from row -3/2
/// (Q_k(1/2) = -mu1 Q_k(-3/2) / (4k^2 - 1), Q_0(1/2) = E), everything rounded to Real (MPFR: to
/// the caller's p_real digits); `bound` gets the relative error bound `b` (in Wr), with the
/// final rounding for MPFR (assigned into the caller's `bound`, at its precision).
template <class Real, class Wr, class Elliptic>
void round_moment_rows(const Wr* qa, const Wr* qb, std::size_t K, const Real& mu1, const Wr& mu1r,
                       const Elliptic& ell, int p_real, const Wr& b, const Real& u_R,
                       QPowerMoments<Real>& out, Real& bound) {
  auto& Qh = out.Q[0];
  auto& Qm = out.Q[1];
  auto& Q3 = out.Q[2];
  if constexpr (is_mpfr_v<Real>) {
    const unsigned pr = static_cast<unsigned>(p_real);
    Wr t;
    for (std::size_t k = 0; k < K; ++k) {
      Qm[k] = Real(qa[k], pr);
      Q3[k] = Real(qb[k], pr);
      if (k == 0) {
        Qh[k] = Real(Wr(ell.E), pr);
      } else {
        const unsigned long ku = static_cast<unsigned long>(k);
        t = qb[k];
        t *= mu1r;
        t /= (4 * ku * ku - 1);
        t = -t;
        Qh[k] = Real(t, pr);
      }
    }
    bound = Real(b, pr) + Real(1.5) * u_R;
  } else {
    (void)qa;
    (void)qb;
    (void)mu1r;
    (void)p_real;
    (void)u_R;
    Qh[0] = static_cast<Real>(ell.E);
    for (std::size_t k = 1; k < K; ++k) {
      const Real kk = static_cast<Real>(k);
      Qh[k] = -mu1 * (Q3[k] / (4 * kk * kk - 1));
    }
    bound = b;
  }
}

// Implementation with explicit evaluation types: Ws for the top values and K, E (also the
// series conditioning limit), Compensate for TwoSum-compensated recursion sums. The
// recursion runs in Real (MPFR: in Real with extra digits).
template <class Real, class Ws, bool Compensate>
QPowerMoments<Real> q_power_moments_with(const Real& mu1, const Real& mu2, std::size_t count) {
  namespace impl = fourier_moments_impl;
  using std::abs;
  QPowerMoments<Real> out;
  out.relative_error = 0;
  if (!(mu1 > 0) || !(mu2 > 0)) throw std::domain_error("q_power_moments: need 0 < mu1 < 1");
  if (count == 0) return out;
  const std::size_t K = count;
  const Real u_R = impl::unit_roundoff_of<Real>();
  if constexpr (!is_mpfr_v<Real>) {
    if (short_row_moments(mu1, mu2, K, out)) return out;
  }
  using Wr = Real;
  constexpr bool compensate = Compensate && !is_mpfr_v<Real>;

  const impl::Plan plan = moments_plan<Real, Ws>(mu1, mu2, K);

  // ---- evaluation
  const int p_real = current_digits10<Real>();
  out.Q[0].resize(K);
  out.Q[1].resize(K);
  out.Q[2].resize(K);
  Real bound;
  auto body = [&]() {
    // inputs in the evaluation types (exact conversions)
    Wr mu1r, mu2r;
    Ws mu1s, mu2s;
    if constexpr (is_mpfr_v<Real>) {
      const unsigned pw = static_cast<unsigned>(p_real + plan.extra_digits);
      mu1r = Wr(mu1, pw);
      mu2r = Wr(mu2, pw);
      mu1s = mu1r;
      mu2s = mu2r;
    } else {
      mu1r = mu1;
      mu2r = mu2;
      mu1s = static_cast<Ws>(mu1);
      mu2s = static_cast<Ws>(mu2);
    }
    const Wr e = 8 * mu1r / mu2r;
    const auto ell = complete_elliptic_from_complement(mu1s);
    const Wr Kell = static_cast<Wr>(ell.K);
    const Wr E_mu1 = static_cast<Wr>(ell.E / mu1s);
    // storage for the recursion: the output rows themselves unless Wr is a wider MPFR
    std::vector<Wr> wa_store, wb_store;
    Wr* qa;
    Wr* qb;
    if constexpr (is_mpfr_v<Real>) {
      wa_store.resize(K);
      wb_store.resize(K);
      qa = wa_store.data();
      qb = wb_store.data();
    } else {
      qa = out.Q[1].data();
      qb = out.Q[2].data();
    }
    Wr top_err = 0, mismatch = 0;
    if (plan.series) {
      // top values Q_K(1/2), Q_K(-1/2) -> start pairs (Q_K, D_{K-1}) of rows -1/2 and -3/2
      Wr sa[4], sb[4];
      top_err = series_start_pairs<Real, Ws, Wr>(plan, mu1, mu2, mu1s, mu2s, K, sa, sb);
      impl::recurse_down<Wr, compensate>(e, K, K, sa, sb, qa, qb);
      mismatch = abs(qa[0] / Kell - 1);
      const Wr mb = abs(qb[0] / E_mu1 - 1);
      if (mb > mismatch) mismatch = mb;
    } else {
      impl::recurse_down<Wr, compensate>(e, K, plan.miller_top, nullptr, nullptr, qa, qb);
      normalise_miller_rows(qa, qb, K, Kell, E_mu1);
    }
    qa[0] = Kell;
    qb[0] = E_mu1;
    // Error bound (units of 1), first order. Start values: their error propagates with a
    // factor <= 3 (measured <= 1). Recursion: compensated (~2 roundings per element) or in
    // MPFR with >= log10 sqrt(K) spare digits (4 sqrt(K) roundings of the wide type).
    // Normalisation (Miller): Carlson K, E (~4 roundings) and one product. Row 1/2: two more
    // roundings. Q_0 mismatch of the series path (a-posteriori). Final rounding for MPFR.
    const Wr uw = impl::unit_roundoff_of<Wr>();
    Wr b = 3 * top_err + mismatch;
    if constexpr (is_mpfr_v<Real>) {
      b += uw * (16 + 4 * std::sqrt(static_cast<double>(K)));
    } else {
      b += uw * (plan.series ? 6 : 12);
    }
    round_moment_rows(qa, qb, K, mu1, mu1r, ell, p_real, b, u_R, out, bound);
  };
  if constexpr (is_mpfr_v<Real>) {
    // Values of the caller's precision and of this wider one meet here (each operation computes
    // at the wider: mpfr_precision_rule).
    const working_precision guard(p_real + plan.extra_digits);
    body();
  } else {
    body();
  }
  out.relative_error = at_working_precision(bound);
  return out;
}

}  // namespace fourier_moments_impl

/// Q_k(s) = int_0^{pi/2} (mu1 + mu2 sin^2 t)^s cos(2kt) dt for s = 1/2, -1/2, -3/2 and
/// k = 0 .. count-1 (rows of Q in that order). Requires 0 < mu1, 0 < mu2, mu1 + mu2 = 1.
/// For mpfr_real the working precision is the current default precision.
template <class Real>
QPowerMoments<Real> q_power_moments(const Real& mu1, const Real& mu2, std::size_t count) {
  namespace impl = fourier_moments_impl;
  if constexpr (std::is_same_v<Real, double>) {
    // Top values in double where the series is well conditioned (4Kd <~ 1.5), otherwise in
    // long double (x87: slower per term, but usable up to Kd ~ 2 before Miller).
    // Why: README, Design notes, 'Measurements behind the design choices' (N = 2).
    const double m = mu1 / (mu1 + mu2);
    const double Kd = static_cast<double>(count) * std::atanh(std::sqrt(m > 0 ? m : 0.0));
    if (impl::series_condition_estimate(Kd) <= 2)
      return impl::q_power_moments_with<double, double, true>(mu1, mu2, count);
    return impl::q_power_moments_with<double, long double, true>(mu1, mu2, count);
  } else {
    return impl::q_power_moments_with<Real, Real, true>(mu1, mu2, count);
  }
}

}  // namespace pendavg::detail
