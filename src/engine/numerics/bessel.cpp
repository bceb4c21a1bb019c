// SPDX-License-Identifier: GPL-3.0-or-later
// Scaled modified Bessel functions: GSL in double, series/asymptotic generic, Miller tables.
#include "engine/numerics/bessel.hpp"

#include "engine/numerics/constant_cache.hpp"
#include "engine/numerics/precision.hpp"

#include <gsl/gsl_errno.h>
#include <gsl/gsl_sf_bessel.h>

#include <algorithm>
#include <memory>
#include <cmath>
#include <stdexcept>
#include <utility>

namespace pendavg {
namespace {

using std::exp;
using std::log;
using std::sqrt;

/// -ln(unit roundoff) as a double. For MPFR from the precision in bits (no MPFR log: this is
/// called once per Bessel evaluation, where an MPFR log would cost as much as the series).
template <class Real>
double log_inverse_roundoff() {
  if constexpr (is_mpfr_v<Real>) {
    const double bits = static_cast<double>(
        boost::multiprecision::detail::digits10_2_2(mpfr_real::thread_default_precision()));
    return (bits - 1.0) * 0.6931471805599453;  // unit_roundoff = 2^(1 - bits)
  } else {
    using std::log;
    return -static_cast<double>(log(unit_roundoff<Real>()));
  }
}

/// Hankel's asymptotic series in double with a fixed, argument-chosen number of terms,
/// evaluated by Horner's rule in y = 1/x (one division instead of a division per term):
///   e^{-x} I_nu(x) = (2 pi x)^{-1/2} sum_k t_k(nu) y^k,  t_k = t_{k-1} ((2k-1)^2 - 4 nu^2) / (8k).
/// Used for x >= hankel_double_min, where the smallest term (~e^{-2x}) is far below the roundoff.
/// The series is cut after the first n terms with c_n y^n < 2^-60 (I0: every term positive;
/// I1: |d_k| <= 3 c_k, every term after the first negative), so the cut is below 2^-58.
constexpr double hankel_double_min = 25.0;
constexpr int hankel_double_terms = 60;
struct HankelDoubleTables {
  double c[hankel_double_terms + 1];  // nu = 0
  double d[hankel_double_terms + 1];  // nu = 1
  double x_min[hankel_double_terms + 1];  // n terms suffice for x >= x_min[n]
  HankelDoubleTables() {
    long double ck = 1, dk = 1;
    c[0] = d[0] = 1;
    x_min[0] = 1e300;
    for (int k = 1; k <= hankel_double_terms; ++k) {
      const long double odd2 = static_cast<long double>((2 * k - 1) * (2 * k - 1));
      ck *= odd2 / (8.0L * k);
      dk *= (odd2 - 4) / (8.0L * k);
      c[k] = static_cast<double>(ck);
      d[k] = static_cast<double>(dk);
      // c_k y^k < 2^-60  <=>  x > (c_k 2^60)^{1/k}
      x_min[k] = static_cast<double>(std::pow(ck * 1.152921504606846976e18L, 1.0L / k));
    }
  }
};
const HankelDoubleTables& hankel_double_tables() {
  static const HankelDoubleTables tables;
  return tables;
}

ScaledBesselI01<double> scaled_bessel_i01_hankel_double(double x) {
  const auto& h = hankel_double_tables();
  int n = 1;
  while (n < hankel_double_terms && x < h.x_min[n]) ++n;
  const double y = 1.0 / x;
  double s0 = h.c[n], s1 = h.d[n];
  for (int k = n - 1; k >= 0; --k) {
    s0 = s0 * y + h.c[k];
    s1 = s1 * y + h.d[k];
  }
  // (2 pi x)^{-1/2} = sqrt(y) (2 pi)^{-1/2}, the constant as a two-double sum: its rounding
  // would otherwise bias every value by +0.6e-16 relative (a bias, unlike the unbiased sqrt).
  const double root_y = std::sqrt(y);
  const double pre = std::fma(root_y, 0.3989422804014327, root_y * -2.49232720227773e-17);
  return {pre * s0, pre * s1};
}

/// Above this argument the Hankel series' smallest term (~ e^{-2x}) is below the roundoff.
template <class Real>
double asymptotic_threshold() {
  return 0.5 * log_inverse_roundoff<Real>() + 8.0;
}

/// Miller start index: beyond `count` by enough that e^{-a} I_m(a) has decayed by roughly
/// sqrt(roundoff) more (Miller's error at m ~ (I_start/I_m)^2), with a safety margin. The
/// ratio I_m/I_{m-1} is about e^{-asinh(m/a)}, so past `count` each step gains at least
/// asinh(count/a); for large a the Gaussian decay exp(-m^2/(2a)) bounds it instead.
template <class Real>
std::size_t miller_start(double a, std::size_t count) {
  const double lnu = log_inverse_roundoff<Real>();
  const double target = 0.5 * lnu + 8.0;
  const double gaussian = 12.0 + std::sqrt((a + 1.0) * (lnu + 10.0));
  const double c = static_cast<double>(std::max<std::size_t>(count, 1));
  const double per_step = (a > 0) ? std::asinh(c / a) : 1e9;
  const double geometric = 4.0 + target / per_step;
  return count + static_cast<std::size_t>(std::min({gaussian, geometric, 1e9}));
}

/// Forward recurrence from I0, I1 amplifies rounding by about exp(m^2/a) (for m << a both
/// solutions behave like e^{+-a}): use it for large arguments, where Miller's start index
/// would grow like sqrt(a), while the amplification stays below e^2 (double, long double)
/// or e^14 (MPFR, whose guard digits absorb it).
template <class Real>
bool forward_recurrence_is_stable(double a, std::size_t count) {
  const double c = static_cast<double>(count);
  const double max_exponent = is_mpfr_v<Real> ? 14.0 : 2.0;
  return c * c <= max_exponent * a && a > 4.0 * log_inverse_roundoff<Real>();
}

/// Hankel's series in MPFR as polynomials in y = 1/x with coefficients tabulated once per
/// precision (shared by all threads, never changed): c_k = prod_{j<=k} (2j-1)^2/(8j) (nu = 0)
/// and d_k = -c_k (2k+1)/(2k-1) (nu = 1; the ratio of the two products telescopes). Horner's
/// rule then costs two multiplications and two additions per term instead of a division-laden
/// recurrence. The number of terms n is the first with c_n y^n <= u/16 (|d_n| <= 3 c_n), found
/// in double from the tabulated ln c_k: the same stopping rule as the term-by-term loop, one term
/// later at most. The table runs to the count needed at the smallest argument the series is used
/// for (asymptotic_threshold), plus a margin.
struct HankelMpfrTable {
  std::vector<mpfr_real> c, d;
  std::vector<double> log_c;

  HankelMpfrTable() {
    const double target = -log_inverse_roundoff<mpfr_real>() - std::log(16.0);
    const double log_x = std::log(asymptotic_threshold<mpfr_real>());
    for (std::size_t k = 0;; ++k) {
      append(k);
      if (log_c[k] - static_cast<double>(k) * log_x <= target) {
        for (std::size_t extra = 1; extra <= 16; ++extra) append(k + extra);
        break;
      }
      if (k > 100000) throw std::domain_error("scaled_bessel_i01: Hankel series did not converge");
    }
  }

 private:
  void append(std::size_t k) {
    if (k == 0) {
      c.emplace_back(1);
      d.emplace_back(1);
      log_c.push_back(0.0);
      return;
    }
    const unsigned long odd = 2 * k - 1;
    mpfr_real ck = c.back();
    ck *= odd * odd;
    ck /= 8 * k;
    mpfr_real dk = ck;
    dk *= 2 * k + 1;
    dk /= odd;
    dk = -dk;
    log_c.push_back(log_c.back() + std::log(static_cast<double>(odd * odd) / (8.0 * k)));
    c.push_back(std::move(ck));
    d.push_back(std::move(dk));
  }
};

std::shared_ptr<const HankelMpfrTable> hankel_mpfr_table() {
  static ConstantCache<HankelMpfrTable> cache;
  return cache.get(0, mpfr_real::thread_default_precision());
}

/// Hankel terms for x >= asymptotic_threshold: the first n with c_n x^{-n} <= u/16.
std::size_t hankel_mpfr_terms(const HankelMpfrTable& table, const mpfr_real& x) {
  const double target = -log_inverse_roundoff<mpfr_real>() - std::log(16.0);
  const double xd = static_cast<double>(x);
  const double log_x = std::isfinite(xd) ? std::log(xd) : 710.0;
  for (std::size_t n = 1; n < table.log_c.size(); ++n) {
    if (table.log_c[n] - static_cast<double>(n) * log_x <= target) return n;
  }
  throw std::domain_error("scaled_bessel_i01: Hankel series did not converge");
}

ScaledBesselI01<mpfr_real> hankel_mpfr(const mpfr_real& x) {
  const auto table = hankel_mpfr_table();
  const HankelMpfrTable& cache = *table;
  const std::size_t n = hankel_mpfr_terms(cache, x);
  const mpfr_real y = 1 / x;
  mpfr_real s0 = cache.c[n], s1 = cache.d[n];
  for (std::size_t k = n; k-- > 0;) {
    s0 *= y;
    s0 += cache.c[k];
    s1 *= y;
    s1 += cache.d[k];
  }
  mpfr_real pre = y;
  pre /= 2 * boost::math::constants::pi<mpfr_real>();
  pre = sqrt(pre);
  s0 *= pre;
  s1 *= pre;
  return {std::move(s0), std::move(s1)};
}

}  // namespace

template <class Real>
ScaledBesselI01Range<Real> scaled_bessel_i01_range(const Real& x_min, const Real& x_max) {
  ScaledBesselI01Range<Real> out;
  if constexpr (is_mpfr_v<Real>) {
    if (!(x_min >= Real(asymptotic_threshold<Real>())) || !(x_max >= x_min)) return out;
    const auto table = hankel_mpfr_table();
    const HankelMpfrTable& cache = *table;
    // Hankel's polynomials of degree n in y = 1/x (the term count of scaled_bessel_i01 at
    // x_min, hence at least as many terms as it takes anywhere in the range).
    const std::size_t n = hankel_mpfr_terms(cache, x_min);
    out.y0 = 1 / x_max;
    const Real delta_max = 1 / x_min - out.y0;  // 0 <= y - y0 <= delta_max
    // Taylor shift to y0 (Horner's synthetic division, exact re-expansion up to rounding):
    // sum_k c_k y^k = sum_j d_j (y - y0)^j.
    std::vector<Real> d0(cache.c.begin(), cache.c.begin() + static_cast<long>(n) + 1);
    std::vector<Real> d1(cache.d.begin(), cache.d.begin() + static_cast<long>(n) + 1);
    Real tmp;
    for (std::size_t j = 0; j < n; ++j) {
      for (std::size_t k = n; k-- > j;) {
        tmp = d0[k + 1];
        tmp *= out.y0;
        d0[k] += tmp;
        tmp = d1[k + 1];
        tmp *= out.y0;
        d1[k] += tmp;
      }
    }
    // Cut the shifted series after J + 1 terms when sum_{j>J} |d_j| delta_max^j <= u/64. The
    // sums are >= 1/2 (s0 >= 1; s1 >= 1 - 3 y/8 - ... >= 0.9 at x >= asymptotic_threshold),
    // so this adds at most u/32 relative to the Hankel truncation error (u/16 per term count).
    const Real cut = unit_roundoff<Real>() / 64;
    Real tail = 0, power = 1;
    std::vector<Real> tail_from(n + 2, Real(0));  // tail_from[j] = sum_{i>=j} |d_i| delta^i
    std::vector<Real> powers(n + 1);
    for (std::size_t j = 0; j <= n; ++j) {
      powers[j] = power;
      power *= delta_max;
    }
    for (std::size_t j = n + 1; j-- > 0;) {
      tmp = abs(d0[j]) > abs(d1[j]) ? abs(d0[j]) : abs(d1[j]);
      tmp *= powers[j];
      tail += tmp;
      tail_from[j] = tail;
    }
    std::size_t J = n;
    while (J > 0 && tail_from[J] <= cut) --J;
    d0.resize(J + 1);
    d1.resize(J + 1);
    out.c0 = std::move(d0);
    out.c1 = std::move(d1);
    out.inv_sqrt_two_pi = 1 / sqrt(2 * boost::math::constants::pi<Real>());
    out.valid = true;
  } else {
    (void)x_min;
    (void)x_max;
  }
  return out;
}

template <class Real>
ScaledBesselI01<Real> scaled_bessel_i01_generic(const Real& x) {
  using std::exp;
  using std::sqrt;
  using std::abs;
  const Real u = unit_roundoff<Real>();
  if (x < Real(asymptotic_threshold<Real>())) {
    // Power series, every term positive: I0 = sum h^k/(k!)^2, I1 = (x/2) sum h^k/(k!(k+1)!).
    const Real h = x * x / 4;
    Real t0 = 1, s0 = 1, t1 = 1, s1 = 1;
    for (unsigned long k = 1;; ++k) {
      t0 *= h;
      t0 /= k * k;
      s0 += t0;
      t1 *= h;
      t1 /= k * (k + 1);
      s1 += t1;
      if (t0 <= u * s0 / 4 && Real(k * k) > h) break;
    }
    const Real e = exp(-x);
    return {s0 * e, x / 2 * s1 * e};
  }
  // Hankel asymptotic series: I_nu e^{-x} ~ (2 pi x)^{-1/2} sum_k t_k,
  // t_k = t_{k-1} ((2k-1)^2 - 4 nu^2) / (8 k x).
  if constexpr (is_mpfr_v<Real>) return hankel_mpfr(x);
  Real t0 = 1, s0 = 1, t1 = 1, s1 = 1;
  const Real inv_eight_x = 1 / (8 * x);
  for (unsigned long k = 1; k < 100000; ++k) {
    const long odd2 = static_cast<long>((2 * k - 1) * (2 * k - 1));
    t0 *= odd2;
    t0 *= inv_eight_x;
    t0 /= k;
    t1 *= (odd2 - 4);
    t1 *= inv_eight_x;
    t1 /= k;
    s0 += t0;
    s1 += t1;
    if (abs(t0) <= u * s0 / 4 && abs(t1) <= u * abs(s1) / 4) break;
  }
  const Real pre = 1 / sqrt(2 * boost::math::constants::pi<Real>() * x);
  return {pre * s0, pre * s1};
}

template <class Real>
ScaledBesselI01<Real> scaled_bessel_i01(const Real& x) {
  if constexpr (std::is_same_v<Real, double>) {
    // GSL 2.7's gsl_sf_bessel_I1_scaled returns x/2 without the e^{-x} factor for
    // x < 2 sqrt(eps) (relative error up to 3e-8); the power series is exact and cheap there.
    // Above x = 25 Hankel's series with a fixed number of terms (Horner) is faster than GSL.
    // Why: README, Design notes, 'Measurements behind the design choices' (N = 2).
    if (x >= hankel_double_min) return scaled_bessel_i01_hankel_double(x);
    if (x < 1e-3) return scaled_bessel_i01_generic(x);
    gsl_sf_result r0, r1;
    const int s0 = gsl_sf_bessel_I0_scaled_e(x, &r0);
    const int s1 = gsl_sf_bessel_I1_scaled_e(x, &r1);
    if (s0 != GSL_SUCCESS && s0 != GSL_EUNDRFLW) throw std::domain_error("gsl I0_scaled failed");
    if (s1 != GSL_SUCCESS && s1 != GSL_EUNDRFLW) throw std::domain_error("gsl I1_scaled failed");
    return {r0.val, r1.val};
  } else {
    return scaled_bessel_i01_generic(x);
  }
}

namespace {

/// Miller's algorithm in ratio form, overflow-free at any a >= 0 (including a = 0):
/// r_m = e^{-a}I_m / e^{-a}I_{m-1} = a / (2m + a r_{m+1}), from r_{start+1} = 0.
/// Returns r_1 .. r_{count-1} (index m) and e^{-a} I_0(a) from the sum rule
/// sum_m eps_m e^{-a} I_m(a) = 1, i.e. I~_0 = 1 / (1 + 2 sum_{m>=1} r_1 ... r_m).
template <class Real>
Real miller_ratios(const Real& a, std::size_t count, std::vector<Real>& r) {
  const std::size_t start = miller_start<Real>(static_cast<double>(a), count);
  r.assign(std::max<std::size_t>(count, 1), Real(0));
  Real next = 0, cur = 0, denominator = 0;
  // The products r_1 ... r_m for m >= count enter only the normalisation; accumulate the
  // tail sum S_m = r_m (1 + S_{m+1}) on the way down. In-place operations: no temporaries.
  Real tail = 0;
  if constexpr (is_mpfr_v<Real>) {
    // The same steps with MPFR's own calls: 2m as a value of the working precision (Boost's
    // `+= unsigned long` goes through mpfr_add_ui, whose mixed precisions miss MPFR's
    // same-precision fast path and took ~1000 instructions a step at 50 digits; mpfr_fma for the
    // tail's (tail + 1) r_m costs more than an addition and a product). Half the instructions
    // per step; the
    // long runs of large arguments (a = 1000: ~500 steps) made this half the cost of the
    // N = 2 sums at 38 digits.
    Real two_m = static_cast<unsigned long>(2 * start);  // exact: 2m < 2^64 fits any precision
    const Real two = 2, one = 1;
    for (std::size_t m = start; m >= 1; --m) {
      mpfr_mul(denominator.backend().data(), next.backend().data(), a.backend().data(),
               MPFR_RNDN);
      mpfr_add(denominator.backend().data(), denominator.backend().data(),
               two_m.backend().data(), MPFR_RNDN);
      mpfr_div(cur.backend().data(), a.backend().data(), denominator.backend().data(),
               MPFR_RNDN);
      if (m < count) r[m] = cur;
      mpfr_add(tail.backend().data(), tail.backend().data(), one.backend().data(), MPFR_RNDN);
      mpfr_mul(tail.backend().data(), tail.backend().data(), cur.backend().data(), MPFR_RNDN);
      mpfr_swap(next.backend().data(), cur.backend().data());
      mpfr_sub(two_m.backend().data(), two_m.backend().data(), two.backend().data(),
               MPFR_RNDN);  // exact
    }
    tail *= 2;
    tail += 1;
    return 1 / tail;
  }
  for (std::size_t m = start; m >= 1; --m) {
    denominator = next;
    denominator *= a;
    denominator += static_cast<unsigned long>(2 * m);
    cur = a;
    cur /= denominator;
    if (m < count) r[m] = cur;
    tail += 1;
    tail *= cur;
    next = cur;
  }
  tail *= 2;
  tail += 1;
  return 1 / tail;
}

}  // namespace

template <class Real>
double scaled_bessel_table_error_ulps(double a, std::size_t count, std::size_t m) {
  const double mm = static_cast<double>(m);
  // Forward recurrence: I0e(a), I1e(a) to a few ulps, amplified by exp(m^2/a).
  if (forward_recurrence_is_stable<Real>(a, count)) return 4.0 * std::exp(mm * mm / a) + 2.0;
  // Miller: each ratio r_j = a/(2j + a r_{j+1}) carries <= ~4 ulps (errors of r_{j+1} are
  // damped by a r_{j+1}/(2j + a r_{j+1}) < 1), and I~_m / I~_0 is a product of m of them.
  return 4.0 * mm + 2.0;
}

template <class Real>
std::size_t scaled_bessel_table_steps(double a, std::size_t count) {
  if (count == 0) return 0;
  if (forward_recurrence_is_stable<Real>(a, count)) return count;
  return miller_start<Real>(a, count);
}

template <class Real>
std::vector<Real> scaled_bessel_i_table(const Real& a, std::size_t count) {
  std::vector<Real> out(count, Real(0));
  if (count == 0) return out;
  if (forward_recurrence_is_stable<Real>(static_cast<double>(a), count)) {
    const auto b = scaled_bessel_i01(a);
    out[0] = b.i0e;
    if (count > 1) out[1] = b.i1e;
    const Real two_over_a = 2 / a;
    Real step = 0;
    for (std::size_t m = 1; m + 1 < count; ++m) {
      step = out[m];
      step *= two_over_a;
      step *= static_cast<unsigned long>(m);
      out[m + 1] = out[m - 1];
      out[m + 1] -= step;
    }
    return out;
  }
  if constexpr (is_mpfr_v<Real>) {
    // Miller's algorithm in its classic form, from the same start: v_{m-1} = v_{m+1} + (2m/a) v_m
    // with v_{start+1} = 0, v_start = 1, then e^{-a} I_m = v_m / (v_0 + 2 sum_{m>=1} v_m). All
    // terms are positive; MPFR's exponent range holds the unnormalised v (they grow like
    // I_0(a) / I_start(a)). No division per step (the ratio form's r_m = a / (2m + a r_{m+1}) costs
    // one, ~900 instructions at 50 digits, three times the rest of a step): the long runs of
    // large arguments (a = 1000: ~500 steps at 38 digits) dominated the N = 2 sums. A rounding
    // at step j scales the v_i below j alike (a common factor, cancelled by the normalisation)
    // and adds a component of the other solution, which decays downwards; so entry m relative
    // to entry 0 carries ~3 roundings per step between them, within the ratio form's bound
    // (scaled_bessel_table_error_ulps: 4m + 2).
    // (a = 0, g = 0: the ratio form below, exact there.)
    const std::size_t start = a > 0 ? miller_start<Real>(static_cast<double>(a), count) : 0;
    const Real inv_a = a > 0 ? Real(1 / a) : Real(0);
    Real v_next = 0, v = 1, v_prev, coefficient, sum = 0;
    for (std::size_t m = start; m >= 1; --m) {
      if (m < count) out[m] = v;
      mpfr_add(sum.backend().data(), sum.backend().data(), v.backend().data(), MPFR_RNDN);
      mpfr_mul_ui(coefficient.backend().data(), inv_a.backend().data(),
                  static_cast<unsigned long>(2 * m), MPFR_RNDN);  // 2m / a
      mpfr_mul(v_prev.backend().data(), coefficient.backend().data(), v.backend().data(),
               MPFR_RNDN);
      mpfr_add(v_prev.backend().data(), v_prev.backend().data(), v_next.backend().data(),
               MPFR_RNDN);
      mpfr_swap(v_next.backend().data(), v.backend().data());   // v_next <- v_m
      mpfr_swap(v.backend().data(), v_prev.backend().data());   // v <- v_{m-1}
    }
    // v = v_0: normalisation 1 / (v_0 + 2 sum_{m>=1} v_m).
    sum *= 2;
    sum += v;
    // Beyond MPFR's exponent range (only for arguments far outside any pendulum's, e.g. a <
    // 1e-(10^7)): the ratio form below, which stays within [0, 1].
    if (a > 0 && mpfr_number_p(sum.backend().data()) && sum > 0) {
      const Real scale = 1 / sum;
      out[0] = v;
      for (std::size_t m = 0; m < count; ++m) out[m] *= scale;
      return out;
    }
  }
  std::vector<Real> r;
  out[0] = miller_ratios(a, count, r);
  for (std::size_t m = 1; m < count; ++m) out[m] = out[m - 1] * r[m];
  return out;
}

template <class Real>
std::vector<Real> reduced_bessel_table(const Real& a, std::size_t count) {
  std::vector<Real> out(count, Real(0));
  if (count == 0) return out;
  if (a > 0 && forward_recurrence_is_stable<Real>(static_cast<double>(a), count)) {
    const auto I = scaled_bessel_i_table(a, count);
    Real scale = 1;
    for (std::size_t k = 0; k < count; ++k) {
      out[k] = I[k] / scale;
      scale *= a;
    }
    return out;
  }
  // f_k / f_{k-1} = r_k / a = 1 / (2k + a r_{k+1}): no division by a, exact at a = 0.
  std::vector<Real> r;
  out[0] = miller_ratios(a, count + 1, r);
  for (std::size_t k = 1; k < count; ++k) {
    const Real next = (k + 1 < r.size()) ? r[k + 1] : Real(0);
    out[k] = out[k - 1] / (2 * Real(k) + a * next);
  }
  return out;
}

#define PENDAVG_INSTANTIATE(Real)                                                   \
  template ScaledBesselI01<Real> scaled_bessel_i01<Real>(const Real&);             \
  template ScaledBesselI01<Real> scaled_bessel_i01_generic<Real>(const Real&);     \
  template std::vector<Real> scaled_bessel_i_table<Real>(const Real&, std::size_t); \
  template double scaled_bessel_table_error_ulps<Real>(double, std::size_t, std::size_t); \
  template std::size_t scaled_bessel_table_steps<Real>(double, std::size_t);           \
  template std::vector<Real> reduced_bessel_table<Real>(const Real&, std::size_t);
PENDAVG_INSTANTIATE(double)
template ScaledBesselI01Range<mpfr_real> scaled_bessel_i01_range<mpfr_real>(const mpfr_real&,
                                                                          const mpfr_real&);
PENDAVG_INSTANTIATE(long double)
PENDAVG_INSTANTIATE(mpfr_real)
#undef PENDAVG_INSTANTIATE

}  // namespace pendavg
