// pendavg/detail/fourier_moments.hpp -- Fourier moments of q(t)^s, q = mu1 + mu2 sin^2 t.
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
//    and psi). These series cost O(ln(1/u)/ln(1/y) + e*4Kd) terms and lose about
//    e^{4Kd}/(4Kd) to cancellation (measured); the loss is absorbed by evaluating them in a
//    wider type (double -> long double; mpfr -> mpfr with extra digits; long double -> long
//    double, or mpfr when the alternative is a very long Miller run).
//    The differences Q_{K-1} - Q_K are NOT formed by subtraction (that would amplify the top
//    error ~K-fold in the algebraic regime) but from the contiguous relation
//    Q_k(s+1) = (s+1)/(s+1+k) [(1+mu1)/2 Q_k(s) - mu2/2 Q_{k-1}(s)], which gives
//      mu2 D_{K-1}(-1/2) = 2 mu1 Q_K(-1/2) - 2(2K+1) Q_K(1/2),
//      mu2 D_{K-1}(-3/2) = 2 mu1 Q_K(-3/2) + 2(2K-1) Q_K(-1/2),   D_k = Q_k - Q_{k+1},
//    sums of same-signed terms.
//  * Miller method (used when the series is slow or ill-conditioned, i.e. when K d or mu1 is
//    not small, where it is cheap): (2) run down from N = K + ceil((ln(1/u)+5)/(4d)) + 10
//    with Q_{N+1} = 0.
//  * The downward recursion is run in the difference form, which is free of cancellation
//    (all terms of one sign) and keeps A - 2 = 4 mu1/mu2 exact in relative terms:
//      s = -1/2: w_k = (2k+1) D_k,      w_{k-1} = w_k + e k Q_k,           D_{k-1} = w_{k-1}/(2k-1)
//      s = -3/2: w_k = D_k/(2k+1),      w_{k-1} = w_k + e k Q_k/(4k^2-1),  D_{k-1} = (2k-1) w_{k-1}
//      Q_{k-1} = Q_k + D_{k-1},  e = 8 mu1/mu2.
//    In long double the two running sums are compensated (TwoSum), so the rounding error does
//    not grow with K; double runs it in long double, mpfr with extra digits.
//  * Both rows are finally normalised to the exact Q_0(-1/2) = K(k), Q_0(-3/2) = E(k)/mu1
//    (Carlson forms, detail/elliptic.hpp); in the series method the mismatch before
//    normalisation is an a-posteriori check and is added to the reported error.
//
// ACCURACY. A few units of the working roundoff per element relative to |Q_k| where the Q_k
// decay algebraically, and relative to max_j |Q_j| where they decay geometrically (Q_k below
// the underflow threshold come out as 0 or subnormal). `relative_error` is a first-order
// bound on max_k |Q_k - exact| / max_k |Q_k| per row, max over rows: wide-type series
// error (tracked term by term) + recursion and rounding terms + the normalisation mismatch.
// Cost: O(count) plus ~10-60 series terms (series method) or O(ln(1/u)/d) (Miller); the
// choice is made by an a-priori cost and conditioning estimate.
//
// References: DLMF 15.6.1, 15.8.10 (A&S 15.3.10-15.3.12), 14.3, 14.10 (recurrences), 5.7.6 /
// 5.11.2 (digamma), 19.25 (Carlson K, E); Gautschi, SIAM Rev. 9 (1967) (minimal solutions);
// Higham, Accuracy and Stability, ch. 4 (compensated summation).
#pragma once

#include "pendavg/detail/elliptic.hpp"
#include "pendavg/precision.hpp"

#include <boost/math/constants/constants.hpp>
#include <boost/math/special_functions/bernoulli.hpp>
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

template <class T>
double to_double(const T& x) {
  return static_cast<double>(x);
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
  const double x0 = 1.2 * log_inv(u) / (2 * 3.141592653589793) + 2.0;
  if (x < x0) return boost::math::digamma(x) - log(x);
  // DLMF 5.11.2: psi(x) ~ ln x - 1/(2x) - sum_j B_{2j} / (2j x^{2j}).
  const W x2inv = 1 / (x * x);
  W sum = -1 / (2 * x);
  W p = x2inv;
  for (int j = 1; j < 10000; ++j) {
    const W term = boost::math::bernoulli_b2n<W>(j) / (2 * j) * p;
    sum -= term;
    if (abs(term) <= u * abs(sum)) break;
    p *= x2inv;
  }
  return sum;
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

// Q_K(1/2) and Q_K(-1/2) from the log-case expansion in y = 1 - r^2 (see header comment).
template <class W>
TopValues<W> series_top(const W& mu1, std::size_t K) {
  using std::abs;
  using std::exp;
  using std::log;
  using std::sqrt;
  const W u = unit_roundoff_of<W>();
  const W one = make<W>(1);
  const W half = one / 2;
  const W rm = sqrt(mu1);
  const W opr = one + rm;
  const W y = 4 * rm / (opr * opr);
  const W kk = make<W>(static_cast<double>(K));
  const W lnr = boost::math::log1p(-rm) - boost::math::log1p(rm);  // ln r = -2d
  const W rK = exp(kk * lnr);
  const W euler = boost::math::constants::euler<W>();

  // B_0 of row 1/2: psi(K+3/2) + ln y + psi(3/2) - psi(1) - psi(3) = G(K+3/2) + 1/2 + gamma,
  // B_0 of row -1/2: 2 psi(1) - psi(1/2) - psi(K+1/2) - ln y = -gamma - G(K+1/2),
  // G(x) = ln(y x / 4) + (psi(x) - ln x) = psi(x) + ln(y/4).
  const W xh = kk + 1 + half;
  const W xm = kk + half;
  const W Gh = log(y * xh / 4) + digamma_minus_log(xh, u);
  const W Gm = log(y * xm / 4) + digamma_minus_log(xm, u);
  W Bh = Gh + half + euler;
  W Bm = -euler - Gm;
  const W Bh_err = u * (abs(Gh) + 4);  // absolute error of the base brackets (a few roundings)
  const W Bm_err = u * (abs(Gm) + 4);

  W th = half, tm = one;       // term coefficients t_n
  W Sh = 0, Sm = 0;            // sums of t_n B_n
  W Ah = 0, Am = 0;            // error weights
  // carried reciprocals: 1/(n+1/2), 1/(n+1), 1/(n+2), 1/(K+n+1/2)
  W inv_nh = 2 * one;          // 1/(1/2)
  W inv_n1 = one;              // 1/1
  W inv_n2 = half;             // 1/2
  W inv_kh = 1 / xm;           // 1/(K+1/2)
  const std::size_t max_terms = 200000;
  bool done_h = false, done_m = false;
  std::size_t n = 0;
  for (; n < max_terms; ++n) {
    const W nn = make<W>(static_cast<double>(n));
    const W inv_n3h = 1 / (nn + 1 + half);      // 1/(n+3/2)
    const W inv_n3 = 1 / (nn + 3);              // 1/(n+3)
    const W inv_k3h = 1 / (kk + nn + 1 + half);  // 1/(K+n+3/2)
    const double nerr = 6.0 * static_cast<double>(n) + 4.0;  // roundings in t_n and B_n
    if (!done_h) {
      const W term = th * Bh;
      Sh += term;
      Ah += abs(term) * nerr + abs(th) * (Bh_err / u);
    }
    if (!done_m) {
      const W term = tm * Bm;
      Sm += term;
      Am += abs(term) * nerr + abs(tm) * (Bm_err / u);
    }
    // advance to n+1
    const W rho_h = y * (nn + 1 + half) * (kk + nn + 1 + half) * inv_n1 * inv_n3;
    const W rho_m = y * (nn + half) * (kk + nn + half) * inv_n1 * inv_n1;
    th *= rho_h;
    tm *= rho_m;
    Bh += inv_k3h + inv_n3h - inv_n1 - inv_n3;
    Bm += 2 * inv_n1 - inv_nh - inv_kh;
    // tail bounds: ratios are monotone towards y (see notes), B grows at most by 2 j/(n+1)
    const W np1 = nn + 1;
    if (!done_h) {
      const W rb = rho_h > y ? rho_h : y;
      if (rb < 1) {
        const W tail = abs(th) * (abs(Bh) / (1 - rb) + 2 / (np1 * (1 - rb) * (1 - rb)));
        if (tail <= u * abs(Sh) / 4) done_h = true;
      }
    }
    if (!done_m) {
      const W rb = rho_m > y ? rho_m : y;
      if (rb < 1) {
        const W tail = abs(tm) * (abs(Bm) / (1 - rb) + 2 / (np1 * (1 - rb) * (1 - rb)));
        if (tail <= u * abs(Sm) / 4) done_m = true;
      }
    }
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
  // relative errors: series (term-wise weights) + bracket assembly + prefactor (exp argument
  // K ln r carries relative error ~u, i.e. absolute ~u * 2Kd)
  const W pref_err = u * (8 + 2 * abs(kk * lnr));
  const W eh = u * (Ah * (y * y / 8) + 4 * abs(fin) + 4 * abs(logpart)) / abs(brack);
  const W em = u * Am / abs(Sm);
  out.rel_err = (eh > em ? eh : em) + pref_err;
  return out;
}

// ---------------------------------------------------------------- downward recursion

// Runs (2) downward for the rows s = -1/2 (a) and s = -3/2 (b) in difference form and stores
// Q_k, k < K (unnormalised) into qa, qb (type Wr). Start: either the top pair (Q_K, D_{K-1})
// (top given) or Miller's Q_{N+1} = 0, Q_N = 1.
template <class Wr, bool Compensate>
struct Recursion {
  std::vector<Wr> qa, qb;

  static void rescale_tail(std::vector<Wr>& v, std::size_t from, std::size_t& live_end,
                           const Wr& f) {
    for (std::size_t i = from; i < live_end; ++i) v[i] *= f;
    while (live_end > from && v[live_end - 1] == 0) --live_end;
  }

  // top: if Qa_top etc. are given, K is the top index; otherwise Miller from N.
  void run(const Wr& e, std::size_t K, std::size_t top, const Wr* startA, const Wr* startB) {
    using std::abs;
    qa.assign(K, Wr(0));
    qb.assign(K, Wr(0));
    // state at index k = top: Q_k (+ compensation), w_k (+ compensation)
    Wr Qa, ca(0), wa, cwa(0), Qb, cb(0), wb, cwb(0);
    std::size_t k;
    if (startA) {
      // startA = {Q_K, Q_K lo, D_{K-1}, D lo}; state becomes index K-1.
      k = top - 1;
      const Wr kk = Wr(static_cast<double>(top));
      Qa = startA[0];
      ca = startA[1];
      two_sum_acc(Qa, ca, startA[2]);
      ca += startA[3];
      wa = (2 * kk - 1) * startA[2];
      cwa = (2 * kk - 1) * startA[3];
      Qb = startB[0];
      cb = startB[1];
      two_sum_acc(Qb, cb, startB[2]);
      cb += startB[3];
      wb = startB[2] / (2 * kk - 1);
      cwb = startB[3] / (2 * kk - 1);
    } else {
      k = top;  // Q_{N+1} = 0: D_N = Q_N = 1
      const Wr kk = Wr(static_cast<double>(top));
      Qa = 1;
      wa = 2 * kk + 1;
      Qb = 1;
      wb = 1 / (2 * kk + 1);
    }
    if (k < K) {
      qa[k] = Qa + ca;
      qb[k] = Qb + cb;
    }
    // rescaling (only relevant for Miller runs over geometric growth)
    const int max_exp = std::numeric_limits<Wr>::max_exponent;
    const int scale_exp = is_mpfr_v<Wr> ? (1 << 22) : max_exp / 2;
    const double grow = 2.0 + to_double(e) * (static_cast<double>(top) + 1) * 4;
    const Wr big = ldexp(Wr(1), scale_exp) / Wr(grow);
    const Wr shrink = ldexp(Wr(1), -scale_exp);
    std::size_t live_a = K, live_b = K;
    for (; k >= 1; --k) {
      const Wr kk = Wr(static_cast<double>(k));
      const Wr tkm1 = 2 * kk - 1;
      const Wr inv = 1 / (tkm1 * (2 * kk + 1));  // 1/(4k^2-1)
      // row a (s = -1/2)
      const Wr inca = e * kk * Qa;
      Wr Da;
      if constexpr (Compensate) {
        two_sum_acc(wa, cwa, inca);
        Da = (wa + cwa) * (2 * kk + 1) * inv;
        two_sum_acc(Qa, ca, Da);
      } else {
        wa += inca;
        Da = wa * (2 * kk + 1) * inv;
        Qa += Da;
      }
      // row b (s = -3/2)
      const Wr incb = e * kk * Qb * inv;
      Wr Db;
      if constexpr (Compensate) {
        two_sum_acc(wb, cwb, incb);
        Db = tkm1 * (wb + cwb);
        two_sum_acc(Qb, cb, Db);
      } else {
        wb += incb;
        Db = tkm1 * wb;
        Qb += Db;
      }
      const std::size_t km1 = k - 1;
      if (km1 < K) {
        qa[km1] = Compensate ? Wr(Qa + ca) : Qa;
        qb[km1] = Compensate ? Wr(Qb + cb) : Qb;
      }
      if (abs(Qa) > big) {
        Qa *= shrink; ca *= shrink; wa *= shrink; cwa *= shrink;
        if (km1 < K) rescale_tail(qa, km1, live_a, shrink);
      }
      if (abs(Qb) > big) {
        Qb *= shrink; cb *= shrink; wb *= shrink; cwb *= shrink;
        if (km1 < K) rescale_tail(qb, km1, live_b, shrink);
      }
    }
  }
};

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
  // measured: ~1 for Kd <= 0.25, 1.7 at 0.5, 6 at 1, 3e2 at 2, 6e5 at 4 (bounded by this)
  const double x = std::min(4 * Kd, 700.0);
  if (x < 1e-3) return 1;
  return 1 + std::exp(x) / x;
}

}  // namespace fourier_moments_impl

/// Q_k(s) = int_0^{pi/2} (mu1 + mu2 sin^2 t)^s cos(2kt) dt for s = 1/2, -1/2, -3/2 and
/// k = 0 .. count-1 (rows of Q in that order). Requires 0 < mu1, 0 < mu2, mu1 + mu2 = 1.
/// For mpfr_real the working precision is the current default precision.
template <class Real>
QPowerMoments<Real> q_power_moments(const Real& mu1, const Real& mu2, std::size_t count) {
  namespace impl = fourier_moments_impl;
  using std::abs;
  QPowerMoments<Real> out;
  out.relative_error = 0;
  if (!(mu1 > 0) || !(mu2 > 0)) throw std::domain_error("q_power_moments: need 0 < mu1 < 1");
  if (count == 0) return out;
  const std::size_t K = count;
  const Real u_R = impl::unit_roundoff_of<Real>();

  // ---- plan (double arithmetic; mu1 may underflow double only for absurd inputs)
  const double mu1d = std::max(static_cast<double>(mu1), 1e-300);
  const double mu2d = static_cast<double>(mu2);
  const double d = std::atanh(std::sqrt(mu1d / (mu1d + mu2d)));  // atanh(sqrt mu1)
  const double Kd = static_cast<double>(K) * d;
  const double kappa = impl::series_condition_estimate(Kd);

  using Ws = std::conditional_t<std::is_same_v<Real, double>, long double, Real>;
  using Wr = Ws;  // double: long double throughout; long double: long double; mpfr: wide mpfr
  constexpr bool compensate = std::is_same_v<Real, long double>;

  impl::Plan plan;
  const double lnu_target = impl::log_inv(u_R);
  const double lnu_s = is_mpfr_v<Real> ? lnu_target : impl::log_inv(impl::unit_roundoff_of<Ws>());
  {
    // Miller: extra steps beyond K so that e^{-4 d (N-K)} < u e^{-5}
    const double miller_len = (lnu_target + 5) / (4 * d) + 10;
    const double cap = 4 * miller_len + 50;
    const double n_terms = impl::estimate_series_terms(mu1d, K, lnu_s, cap);
    // cost units: one recursion step (two rows). A series term (two series) costs ~1.5 steps,
    // the logs/digammas ~30 steps.
    double series_cost = 1.5 * n_terms + 30;
    double kappa_max;
    if constexpr (std::is_same_v<Real, double>) {
      kappa_max = 0.25 * std::exp(lnu_s - lnu_target);  // long double series, double result
    } else if constexpr (std::is_same_v<Real, long double>) {
      kappa_max = 2;
    } else {
      kappa_max = std::numeric_limits<double>::infinity();  // extra digits instead
      series_cost *= 1 + std::log10(kappa) / std::max(1.0, lnu_target / 2.302585092994046);
    }
    const bool converges = n_terms < cap;
    if (converges && kappa <= kappa_max && series_cost < miller_len) {
      plan.series = true;
    } else if constexpr (std::is_same_v<Real, long double>) {
      // MPFR series (~60x a long double step per term) versus a long Miller run.
      if (60 * 30 < miller_len) {
        const double lnu_w = lnu_target + std::log(kappa * 16);
        const double nt = impl::estimate_series_terms(mu1d, K, lnu_w, miller_len / 60);
        if (nt < miller_len / 60 && 60 * (1.5 * nt + 30) < miller_len) {
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

  // ---- wide evaluation
  const int p_real = current_digits10<Real>();
  std::vector<Wr> qa, qb;
  Wr mismatch_a = 0, mismatch_b = 0, top_err = 0, Kell, Eell, mu1w, mu2w;
  auto body = [&]() {
    if constexpr (is_mpfr_v<Real>) {
      const unsigned pw = static_cast<unsigned>(p_real + plan.extra_digits);
      mu1w = Wr(mu1, pw);
      mu2w = Wr(mu2, pw);
    } else {
      mu1w = static_cast<Wr>(mu1);
      mu2w = static_cast<Wr>(mu2);
    }
    const Wr e = 8 * mu1w / mu2w;
    const auto ell = complete_elliptic_from_complement(mu1w);
    Kell = ell.K;
    Eell = ell.E;
    impl::Recursion<Wr, compensate> rec;
    if (plan.series) {
      Wr QKh, QKm, QKh_lo(0), QKm_lo(0), err;
      Wr DA, DA_lo(0), DB, DB_lo(0), QB, QB_lo(0);
      const Wr kk = Wr(static_cast<double>(K));
      if (plan.series_in_mpfr) {
        if constexpr (std::is_same_v<Real, long double>) {
          working_precision guard(std::numeric_limits<long double>::digits10 + 3 +
                                  plan.extra_digits);
          const mpfr_real m1 = mpfr_real(static_cast<long double>(mu1));
          const mpfr_real m2 = mpfr_real(static_cast<long double>(mu2));
          const auto top = impl::series_top(m1, K);
          if (!top.ok) throw std::runtime_error("q_power_moments: series did not converge");
          const mpfr_real kw = mpfr_real(static_cast<double>(K));
          const mpfr_real qb_top = -(4 * kw * kw - 1) * top.q_half / m1;
          const mpfr_real dA = (2 * m1 * top.q_mhalf - 2 * (2 * kw + 1) * top.q_half) / m2;
          const mpfr_real dB = (2 * m1 * qb_top + 2 * (2 * kw - 1) * top.q_mhalf) / m2;
          auto split = [](const mpfr_real& v, long double& hi, long double& lo) {
            hi = static_cast<long double>(v);
            lo = static_cast<long double>(mpfr_real(v - mpfr_real(hi)));
          };
          split(top.q_mhalf, QKm, QKm_lo);
          split(dA, DA, DA_lo);
          split(qb_top, QB, QB_lo);
          split(dB, DB, DB_lo);
          err = static_cast<long double>(top.rel_err);
        }
      } else {
        const auto top = impl::series_top(mu1w, K);
        if (!top.ok) throw std::runtime_error("q_power_moments: series did not converge");
        QKh = top.q_half;
        QKm = top.q_mhalf;
        err = top.rel_err;
        QB = -(4 * kk * kk - 1) * QKh / mu1w;
        DA = (2 * mu1w * QKm - 2 * (2 * kk + 1) * QKh) / mu2w;
        DB = (2 * mu1w * QB + 2 * (2 * kk - 1) * QKm) / mu2w;
      }
      const Wr sa[4] = {QKm, QKm_lo, DA, DA_lo};
      const Wr sb[4] = {QB, QB_lo, DB, DB_lo};
      rec.run(e, K, K, sa, sb);
      top_err = err;
      // mismatch of the unnormalised Q_0 with the exact values
      mismatch_a = abs(rec.qa[0] / Kell - 1);
      mismatch_b = abs(rec.qb[0] * mu1w / Eell - 1);
    } else {
      rec.run(e, K, plan.miller_top, nullptr, nullptr);
    }
    const Wr fa = Kell / rec.qa[0];
    const Wr fb = Eell / (mu1w * rec.qb[0]);
    qa.resize(K);
    qb.resize(K);
    for (std::size_t k = 0; k < K; ++k) {
      qa[k] = rec.qa[k] * fa;
      qb[k] = rec.qb[k] * fb;
    }
    qa[0] = Kell;
    qb[0] = Eell / mu1w;
  };
  if constexpr (is_mpfr_v<Real>) {
    working_precision guard(p_real + plan.extra_digits);
    body();
  } else {
    body();
  }

  // ---- outputs (rounded to Real) and the error bound
  auto& Qh = out.Q[0];
  auto& Qm = out.Q[1];
  auto& Q3 = out.Q[2];
  Qh.resize(K);
  Qm.resize(K);
  Q3.resize(K);
  auto to_real = [&](const Wr& v) -> Real {
    if constexpr (is_mpfr_v<Real>) {
      return Real(v, static_cast<unsigned>(p_real));
    } else {
      return static_cast<Real>(v);
    }
  };
  {
    auto body2 = [&]() {
      for (std::size_t k = 0; k < K; ++k) {
        Qm[k] = to_real(qa[k]);
        Q3[k] = to_real(qb[k]);
        const Wr kk = Wr(static_cast<double>(k));
        Qh[k] = to_real(k == 0 ? Eell : Wr(-mu1w * qb[k] / (4 * kk * kk - 1)));
      }
    };
    if constexpr (is_mpfr_v<Real>) {
      working_precision guard(p_real + plan.extra_digits);
      body2();
    } else {
      body2();
    }
  }
  // Bound (units of 1). In the wide type: start values (propagate with factor <= 3), the
  // recursion (compensated, or run with >= log10 sqrt(K) spare digits: ~16 roundings of the
  // wide type per element, plus 4 sqrt(K) for uncompensated sums), normalisation (Carlson
  // K, E), the Q_0 mismatch. Then the final rounding to Real (1/2 u_R per element, more for
  // the row s = 1/2 which takes two more operations).
  Real bound;
  {
    auto body3 = [&]() {
      const Wr uw = impl::unit_roundoff_of<Wr>();
      const Wr rec_terms =
          uw * (16 + (compensate ? 0.0 : 4 * std::sqrt(static_cast<double>(K))));
      const Wr mm = mismatch_a > mismatch_b ? mismatch_a : mismatch_b;
      bound = to_real(3 * top_err + rec_terms + mm) + Real(1.5) * u_R;
    };
    if constexpr (is_mpfr_v<Real>) {
      working_precision guard(p_real + plan.extra_digits);
      body3();
    } else {
      body3();
    }
  }
  out.relative_error = bound;
  return out;
}

}  // namespace pendavg::detail
