// SPDX-License-Identifier: GPL-3.0-or-later
// The paper's series for the double pendulum, eq. ave-K1-result, with a rigorous truncation
// bound (src/engine/double_pendulum/README.md, 'Series').
//
//   beta<K1> = (mu1/2) N / D,   N = sum_{n>=0} c_n mu2^n R_n,   D = R_0 - sum_{n>=1} d_n mu2^n R_n,
//   c_n = (2n-1)!!/(n! 2^n),  d_n = (2n-3)!!/(n! 2^n) = c_{n-1}/(2n),
//   R_n = sum_{j=0}^{n} C(2n,2j) ((2(n-j)-1)!!)^2 D^{2j} f_{n-j}(a1) D^{2j} f_{n-j}(a2),
//   f_k(a) = I_k(a)/a^k.
// Using C(2n,2j) ((2k-1)!!)^2 = [(2n)!/(2j)!] c_k / k!^0 ... precisely
//   C(2n,2j) ((2k-1)!!)^2 = [(2n)! / (2j)!] * c_k   (k = n - j, since (2k)! = 2^k k! (2k-1)!!).
// The derivatives E(d,k) = D^d f_k follow from d/da f_k = a f_{k+1} by Leibniz' rule,
//   E(0,k) = f_k,  E(1,k) = a f_{k+1},  E(d,k) = a E(d-1,k+1) + (d-1) E(d-2,k+1),
// which generates the closed form sum_r d!/(2^{d-r}(d-r)!(2r-d)!) a^{2r-d} f_{k+r}
// term by term (every term positive: nothing cancels), in O(1) per entry from one table
// f_0..f_{2M+2} per argument. Everything is scaled by e^{-(a1+a2)}; the scale cancels in N/D.
//
// Bound: R_n is positive and non-increasing and c_n, d_n <= c_{M+1} for n > M, so both tails
// are at most T_M = c_{M+1} R_{M+1} mu2^{M+1} / (1 - mu2). Hence
//   (mu1/2) N_M/D_M <= beta<K1> <= (mu1/2) (N_M + T_M)/(D_M - T_M).
#include "engine/double_pendulum/double_pendulum.hpp"
#include "engine/numerics/parallel.hpp"
#include "engine/numerics/text.hpp"

#include "engine/numerics/bessel.hpp"

#include <boost/math/special_functions/fpclassify.hpp>

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>

namespace pendavg {
namespace {

using std::abs;
using std::log;
using std::pow;

/// R_0 .. R_{count-1} (scaled by e^{-(a1+a2)}), from the Leibniz recurrence for D^d f_k.
/// Rows d = 0 .. 2 Mx of E(d, k) are generated in place (row d needs k = 0 .. 2 Mx - d);
/// at even d = 2j row d contributes [(2(j+k))!/(2j)!] c_k E1(2j,k) E2(2j,k) to R_{j+k}.
/// The arithmetic goes through `SeriesKernel`, which for MPFR calls mpfr_mul and friends on
/// preallocated numbers (no temporaries): this O(M^2) loop is the whole cost of the series.
template <class Real>
struct SeriesKernel {
  // E = a * P1 + m * P2
  static void leibniz(Real& E, const Real& a, const Real& P1, unsigned long m, const Real& P2,
                      Real& tmp) {
    tmp = P2;
    tmp *= m;
    E = P1;
    E *= a;
    E += tmp;
  }
  // R += coef * E1 * E2
  static void accumulate(Real& R, const Real& coef, const Real& E1, const Real& E2, Real& tmp) {
    tmp = E1;
    tmp *= E2;
    tmp *= coef;
    R += tmp;
  }
  static void scale(Real& x, unsigned long num, unsigned long den) {
    x *= num;
    x /= den;
  }
};

template <>
struct SeriesKernel<mpfr_real> {
  static void leibniz(mpfr_real& E, const mpfr_real& a, const mpfr_real& P1, unsigned long m,
                      const mpfr_real& P2, mpfr_real& tmp) {
    mpfr_mul_ui(tmp.backend().data(), P2.backend().data(), m, MPFR_RNDN);
    mpfr_mul(E.backend().data(), a.backend().data(), P1.backend().data(), MPFR_RNDN);
    mpfr_add(E.backend().data(), E.backend().data(), tmp.backend().data(), MPFR_RNDN);
  }
  static void accumulate(mpfr_real& R, const mpfr_real& coef, const mpfr_real& E1,
                         const mpfr_real& E2, mpfr_real& tmp) {
    mpfr_mul(tmp.backend().data(), E1.backend().data(), E2.backend().data(), MPFR_RNDN);
    mpfr_mul(tmp.backend().data(), tmp.backend().data(), coef.backend().data(), MPFR_RNDN);
    mpfr_add(R.backend().data(), R.backend().data(), tmp.backend().data(), MPFR_RNDN);
  }
  static void scale(mpfr_real& x, unsigned long num, unsigned long den) {
    mpfr_mul_ui(x.backend().data(), x.backend().data(), num, MPFR_RNDN);
    mpfr_div_ui(x.backend().data(), x.backend().data(), den, MPFR_RNDN);
  }
};

template <class Real>
std::vector<Real> paper_R(const Real& a1, const Real& a2, std::size_t count,
                          const RunControl& control) {
  using K = SeriesKernel<Real>;
  const std::size_t Mx = count - 1;      // highest n
  const std::size_t width = 2 * Mx + 1;  // row d needs k = 0 .. 2 Mx - d
  const std::array<std::vector<Real>, 2> f = {reduced_bessel_table(a1, width + 1),
                                               reduced_bessel_table(a2, width + 1)};
  const std::array<const Real*, 2> a = {&a1, &a2};
  std::vector<Real> R(count, Real(0));
  // Three rolling rows E(d-2,.), E(d-1,.), E(d,.) per argument, addressed by d mod 3.
  std::array<std::array<std::vector<Real>, 3>, 2> rows;
  for (auto& per_argument : rows)
    for (auto& row : per_argument) row.assign(width + 1, Real(0));
  // The two arguments' tables are independent: one thread each; the accumulation (~15% of
  // the work) runs on one thread in a fixed order, so results do not depend on threads.
  bool stopped = false;  // written in `omp single` only; read after its barrier
  // An exception may not leave the parallel region: the first one is kept and rethrown after
  // it; failed() is set before a barrier, so every thread sees it at the same d, as `stopped`.
  ParallelErrors errors;
  const int digits10 = current_digits10<Real>();
#pragma omp parallel num_threads(2) if (Mx > 48)
  {
    // MPFR's precision is per thread: the scratch numbers take the caller's.
    const precision_guard<Real> precision(digits10);
    Real tmp = 0, coef = 0;
    for (std::size_t d = 0; d <= 2 * Mx; ++d) {
      if (stopped || errors.failed()) break;  // every thread sees the same value at the same d
      const std::size_t kmax = 2 * Mx - d;
#pragma omp for schedule(static, 1)
      for (int arg = 0; arg < 2; ++arg) {
        errors.capture([&] {
          auto& cur = rows[arg][d % 3];
          if (d == 0) {
            for (std::size_t k = 0; k <= kmax; ++k) cur[k] = f[arg][k];
          } else {
            // E(d,k) = a E(d-1,k+1) + (d-1) E(d-2,k+1); E(-1, .) = 0.
            const auto& p1 = rows[arg][(d + 2) % 3];
            const auto& p2 = rows[arg][(d + 1) % 3];
            const unsigned long m = (d >= 2) ? static_cast<unsigned long>(d - 1) : 0ul;
            for (std::size_t k = 0; k <= kmax; ++k) K::leibniz(cur[k], *a[arg], p1[k + 1], m, p2[k + 1], tmp);
          }
        });
      }
      if (d % 2 == 0) {
        const std::size_t j = d / 2;
        const auto& e1 = rows[0][d % 3];
        const auto& e2 = rows[1][d % 3];
        // R_{j+k} += [(2(j+k))!/(2j)!] c_k E1(2j,k) E2(2j,k), with the coefficient as a
        // running product: one thread (the implicit barrier ends the row).
#pragma omp single
        errors.capture([&] {
          coef = 1;  // (2j)!/(2j)! c_0
          for (std::size_t k = 0; j + k <= Mx; ++k) {
            if (k > 0) {
              // times (2j+2k-1)(2j+2k)(2k-1)/(2k): the factorial ratio and c_k / c_{k-1}.
              const unsigned long n2 = static_cast<unsigned long>(2 * (j + k));
              K::scale(coef, (n2 - 1) * n2 * (2 * k - 1), 2 * k);
            }
            K::accumulate(R[j + k], coef, e1[k], e2[k], tmp);
          }
          // Row d costs ~ (2 Mx - d): the fraction done is 1 - ((2 Mx - d) / 2 Mx)^2.
          const double left = Mx > 0 ? double(2 * Mx - d) / double(2 * Mx) : 0.0;
          control.report(1 - left * left);
          if (control.stop_requested()) stopped = true;
        });
      }
    }
  }
  errors.rethrow();
  if (stopped) throw interrupted("series: stopped while building the Bessel table (no term is complete)");
  return R;
}

/// The guard digits of a series of M terms: every term of the series and of R_n is positive, so
/// rounding errors only add up along the O(M) operations of a path: log10(4M) + 3 digits (not
/// the global guard_digits; fewer limbs make the O(M^2) loop faster). The sums' rounding bound
/// (series_average) uses the unit of this precision, not the caller's finer one.
int series_guard_digits(std::size_t M) {
  return 3 + static_cast<int>(std::ceil(std::log10(4.0 * static_cast<double>(M) + 4.0)));
}

/// A priori number of terms M that certainly reaches relative tolerance tol, from the bound
/// with R_n <= R_0: rel. error <= c_{M+1} mu2^{M+1} (1 + 1/mu1) / (mu1 (1 - mu2)), where
/// c_n <= 1/sqrt(pi n) (Wallis). Computed in double from log(mu1), log(mu2); a double, since
/// a light particle (mu1 = 1e-12: ~4e13 terms) may need more than any run could compute (the
/// caller only compares it with its caps and names it). Infinity when mu2 rounds to 1.
inline double a_priori_terms(double log_mu1, double log_mu2, double log_tol) {
  if (!(log_mu2 < 0)) return std::numeric_limits<double>::infinity();
  const double rhs = log_tol + 2.0 * log_mu1 - std::log(2.0);  // (1 + 1/mu1)/mu1 <= 2/mu1^2
  // c_{M+1} mu2^{M+1} <= tol mu1^2 / 2: increase M geometrically, then bisect (to the integer,
  // or to 1e-12 relative beyond 2^40).
  auto ok = [&](double m) { return -0.5 * std::log(3.14159265 * (m + 1)) + (m + 1) * log_mu2 <= rhs; };
  double hi = 1;
  while (!ok(hi)) {
    hi *= 2;
    if (hi > 1e300) return std::numeric_limits<double>::infinity();
  }
  double lo = hi / 2;
  while (hi - lo > std::max(1.0, 1e-12 * hi)) {
    const double mid = std::floor((lo + hi) / 2);
    (ok(mid) ? hi : lo) = mid;
  }
  return hi + 1;
}

/// Terms the automatic mode computes at most (the work grows like M^2); beyond it the result
/// comes back with converged = false and its rigorous bound. An explicit `terms` may exceed it.
constexpr std::size_t max_automatic_terms = 6000;

/// The refusal of an automatic run that needs `estimate` terms, beyond max_automatic_terms.
[[noreturn]] void refuse_automatic_terms(double log_mu1, double log_mu2, double estimate,
                                         int digits) {
  // mu2 = 1 - mu1 for a light first particle (printed as 1 by a short decimal)
  const double mu1 = std::exp(log_mu1);
  // mu1 from its logarithm: exp underflows to 0 below 1e-308 ("1 - 0" was printed)
  const std::string mu1_text =
      mu1 > 0 ? short_decimal(mu1)
              : "1e" + std::to_string(static_cast<long long>(std::floor(log_mu1 / std::log(10.0))));
  const std::string mu2_text =
      mu1 < 1e-3 ? "1 - " + mu1_text : short_decimal(std::exp(log_mu2));
  const std::string terms_text = !std::isfinite(estimate) ? "more than 1e300"
                                 : estimate < 1e15
                                     ? "about " + std::to_string(static_cast<long long>(estimate))
                                     : "about " + short_decimal(estimate);
  throw invalid_input("series: mu2 = " + mu2_text + " converges like mu2^n: " + terms_text +
                      " terms for " + std::to_string(digits) +
                      " digits, beyond the automatic cap of " +
                      std::to_string(max_automatic_terms) +
                      " (work grows like terms^2); use the integral method, or give the "
                      "number of terms explicitly");
}

}  // namespace

template <class Real>
std::vector<SeriesRow<Real>> series_convergence(const Chain<Real>& chain_argument,
                                                const Real& beta_argument, int digits,
                                                std::size_t terms, const RunControl& control) {
  if constexpr (!is_mpfr_v<Real>) {
    const Chain<Real>& chain = chain_argument;
    const Real& beta = beta_argument;
    // The series' coefficients (2n)!/(2j)! and derivatives f_k leave double's range after a
    // hundred terms: evaluate in MPFR at 16 digits and round the rows to double.
    working_precision precision(16 + guard_digits);
    const auto rows =
        series_convergence(chain.template cast<mpfr_real>(), mpfr_real(beta), 16, terms, control);
    std::vector<SeriesRow<Real>> out(rows.size());
    for (std::size_t i = 0; i < rows.size(); ++i) {
      out[i] = {rows[i].n,
                static_cast<Real>(rows[i].R_n),
                static_cast<Real>(rows[i].term),
                static_cast<Real>(rows[i].numerator),
                static_cast<Real>(rows[i].denominator),
                static_cast<Real>(rows[i].beta_kinetic1),
                static_cast<Real>(rows[i].bound)};
    }
    return out;
  }
  check_digits<Real>(digits);
  // The rows come back at the caller's precision, digits + guard_digits; so do the inputs.
  const precision_guard<Real> caller_precision(digits + guard_digits);
  const Chain<Real> chain = at_working_precision(chain_argument);
  const Real beta = at_working_precision(beta_argument);
  double_pendulum_parameters(chain, beta);  // validates N = 2 and beta
  const double log_tol = is_mpfr_v<Real> ? -(digits + 1) * std::log(10.0)
                                         : std::log(4 * std::numeric_limits<double>::epsilon());
  const double log_mu1 = static_cast<double>(log(chain.mass_fraction(0)));
  const double log_mu2 = static_cast<double>(log(chain.mass_fraction(1)));
  const double estimate = terms > 0 ? double(terms) : a_priori_terms(log_mu1, log_mu2, log_tol);
  if (terms == 0 && !(estimate <= double(max_automatic_terms))) {
    refuse_automatic_terms(log_mu1, log_mu2, estimate, is_mpfr_v<Real> ? digits : 16);
  }
  const std::size_t M = terms > 0 ? terms : static_cast<std::size_t>(estimate);
  if (M > max_series_terms)
    throw invalid_input("at most " + std::to_string(max_series_terms) +
                        " series terms can be requested");
  const int series_guard = series_guard_digits(M);
  std::vector<SeriesRow<Real>> rows;
  {
  // The inputs keep the caller's precision while the sums run at digits + series_guard (an
  // operation on both computes at the higher: mpfr_precision_rule), and the rows are rounded to
  // the caller's precision (exactly: it is the higher one) when they are done.
  const precision_guard<Real> precision(digits + series_guard);
  const auto p = double_pendulum_parameters(chain, beta);
  const Real tol = is_mpfr_v<Real> ? Real(pow(Real(10), -(digits + 1)))
                                   : Real(4 * unit_roundoff<Real>());
  const auto R = paper_R(p.a1, p.a2, M + 1, control);  // R_0 .. R_M (R_M for the bound after M-1)
  Real c = 1, mu2n = 1, N = 0, D = 0;
  for (std::size_t n = 0; n + 1 <= M; ++n) {
    if (n > 0) {
      const Real d_n = c / static_cast<unsigned long>(2 * n);  // d_n = c_{n-1}/(2n)
      c *= static_cast<unsigned long>(2 * n - 1);
      c /= static_cast<unsigned long>(2 * n);
      mu2n *= p.mu2;
      D -= d_n * mu2n * R[n];
    } else {
      D = R[0];
    }
    SeriesRow<Real> row;
    row.n = n;
    row.R_n = R[n];
    row.term = c * mu2n * R[n];
    N += row.term;
    row.numerator = N;
    row.denominator = D;
    row.beta_kinetic1 = p.mu1 / 2 * N / D;
    // Tail bound with c_{n+1} R_{n+1} mu2^{n+1} / (1 - mu2).
    const Real c_next = c * static_cast<unsigned long>(2 * n + 1) / static_cast<unsigned long>(2 * n + 2);
    const Real T = c_next * R[n + 1] * mu2n * p.mu2 / p.mu1;  // 1 - mu2 = mu1
    if (D > T) {
      row.bound = p.mu1 / 2 * (N + T) / (D - T) - row.beta_kinetic1;
    } else {
      row.bound = std::numeric_limits<double>::infinity();
    }
    const bool done = terms == 0 && row.bound <= tol * row.beta_kinetic1;
    rows.push_back(std::move(row));
    if (done) break;
  }
  }
  for (SeriesRow<Real>& row : rows) {
    for (Real* x : {&row.R_n, &row.term, &row.numerator, &row.denominator, &row.beta_kinetic1,
                    &row.bound})
      *x = at_working_precision(*x);
  }
  return rows;
}

template <class Real>
Averages<Real> series_average(const Chain<Real>& chain, const Real& beta, int digits,
                              std::size_t max_terms) {
  if constexpr (!is_mpfr_v<Real>) {
    // As series_convergence: evaluate in MPFR at 16 digits, round to double.
    working_precision precision(16 + guard_digits);
    const auto m = series_average(chain.template cast<mpfr_real>(), mpfr_real(beta), 16, max_terms);
    const Real u = unit_roundoff<Real>();
    auto convert = [u](const std::vector<Estimate<mpfr_real>>& from,
                       std::vector<Estimate<Real>>& to) {
      to.resize(from.size());
      for (std::size_t i = 0; i < from.size(); ++i) {
        const Real v = static_cast<Real>(from[i].value);
        to[i] = {v, static_cast<Real>(from[i].error) + u * std::abs(v), from[i].kind};
      }
    };
    Averages<Real> out;
    convert(m.beta_kinetic, out.beta_kinetic);
    convert(m.cos_angle, out.cos_angle);
    convert(m.beta2_kinetic_variance, out.beta2_kinetic_variance);
    const Real ratio = static_cast<Real>(m.ratio->value);
    out.ratio = Estimate<Real>{ratio, static_cast<Real>(m.ratio->error) + u * std::abs(ratio),
                               m.ratio->kind};
    out.method = m.method;
    out.error_kind = m.error_kind;
    out.work_unit = m.work_unit;
    out.evaluations = m.evaluations;
    out.converged = m.converged;
    return out;
  }
  check_digits<Real>(digits);
  const precision_guard<Real> precision(digits + guard_digits);
  const auto rows = series_convergence(chain, beta, digits, max_terms);
  const auto& last = rows.back();
  // The series gives beta<K1>; <cos phi_i> and Var K_i come from the reduced integral.
  Averages<Real> out = reduced_integral_average(chain, beta, is_mpfr_v<Real> ? digits : 16);
  const Real u = unit_roundoff<Real>();
  // The sums ran at digits + series_guard_digits(M), M >= rows.size() the terms planned: the
  // unit at digits + series_guard_digits(rows.size()) is at least theirs.
  Real sums_unit;
  {
    const precision_guard<Real> sums(digits + series_guard_digits(rows.size()));
    sums_unit = unit_roundoff<Real>();
  }
  const Real half_width = last.bound / 2;
  const Real k1 = last.beta_kinetic1 + half_width;
  const Real rounding = 16 * (sums_unit + u) * Real(rows.size()) * k1;
  const Real k1_err = half_width + rounding;
  const Real k2 = 1 - k1;
  constexpr ErrorKind bound = ErrorKind::bound;
  out.beta_kinetic = {{k1, k1_err, bound}, {k2, k1_err + 2 * u, bound}};
  const Real ratio = k1 / k2;
  out.ratio = Estimate<Real>{ratio, ratio * (k1_err / k1 + k1_err / k2 + 4 * u), bound};
  out.method = Method::series;
  out.error_kind = bound;
  out.work_unit = WorkUnit::terms;
  out.evaluations = rows.size();
  const Real tol = is_mpfr_v<Real> ? Real(pow(Real(10), -(digits + 1)))
                                   : Real(4 * unit_roundoff<Real>());
  out.converged = last.bound <= tol * last.beta_kinetic1;
  return out;
}

#define PENDAVG_INSTANTIATE(Real)                                                \
  template PENDAVG_EXPORT std::vector<SeriesRow<Real>> series_convergence<Real>( \
      const Chain<Real>&, const Real&, int, std::size_t, const RunControl&);     \
  template Averages<Real> series_average<Real>(const Chain<Real>&, const Real&, int, std::size_t);
PENDAVG_INSTANTIATE(double)
PENDAVG_INSTANTIATE(mpfr_real)
#undef PENDAVG_INSTANTIATE

}  // namespace pendavg
