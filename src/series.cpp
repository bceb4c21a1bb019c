// The paper's series for the double pendulum, eq. ave-K1-result, with a rigorous truncation
// bound (MATH.md Sec. 5).
//
//   beta<K1> = (mu1/2) N / D,   N = sum_{n>=0} c_n mu2^n R_n,   D = R_0 - sum_{n>=1} d_n mu2^n R_n,
//   c_n = (2n-1)!!/(n! 2^n),  d_n = (2n-3)!!/(n! 2^n) = c_{n-1}/(2n),
//   R_n = sum_{j=0}^{n} C(2n,2j) ((2(n-j)-1)!!)^2 D^{2j} f_{n-j}(a1) D^{2j} f_{n-j}(a2),
//   f_k(a) = I_k(a)/a^k.
// Using C(2n,2j) ((2k-1)!!)^2 = [(2n)!/(2j)!] c_k / k!^0 ... precisely
//   C(2n,2j) ((2k-1)!!)^2 = [(2n)! / (2j)!] * c_k   (k = n - j, since (2k)! = 2^k k! (2k-1)!!).
// The derivatives E(d,k) = D^d f_k follow from d/da f_k = a f_{k+1} by Leibniz' rule,
//   E(0,k) = f_k,  E(1,k) = a f_{k+1},  E(d,k) = a E(d-1,k+1) + (d-1) E(d-2,k+1),
// which generates MATH.md's closed form sum_r d!/(2^{d-r}(d-r)!(2r-d)!) a^{2r-d} f_{k+r}
// term by term (every term positive: nothing cancels), in O(1) per entry from one table
// f_0..f_{2M+2} per argument. Everything is scaled by e^{-(a1+a2)}; the scale cancels in N/D.
//
// Bound: R_n is positive and non-increasing and c_n, d_n <= c_{M+1} for n > M, so both tails
// are at most T_M = c_{M+1} R_{M+1} mu2^{M+1} / (1 - mu2). Hence
//   (mu1/2) N_M/D_M <= beta<K1> <= (mu1/2) (N_M + T_M)/(D_M - T_M).
#include "pendavg/double_pendulum.hpp"

#include "pendavg/bessel.hpp"

#include <boost/math/special_functions/fpclassify.hpp>

#include <algorithm>
#include <cmath>
#include <memory>

namespace pendavg {
namespace {

using std::abs;
using std::log;
using std::pow;

/// R_0 .. R_{count-1} (scaled by e^{-(a1+a2)}), from the Leibniz recurrence for D^d f_k.
template <class Real>
std::vector<Real> paper_R(const Real& a1, const Real& a2, std::size_t count) {
  const std::size_t Mx = count - 1;         // highest n
  const std::size_t width = 2 * Mx + 1;     // row d needs k = 0 .. 2 Mx - d
  const auto f1 = reduced_bessel_table(a1, width + 1);
  const auto f2 = reduced_bessel_table(a2, width + 1);
  std::vector<Real> R(count, Real(0));
  // Rolling rows E(d-2,.), E(d-1,.), E(d,.) for both arguments.
  std::vector<Real> p2a(width + 1), p1a(width + 1), cura(width + 1);
  std::vector<Real> p2b(width + 1), p1b(width + 1), curb(width + 1);
  Real tmp, coef, term;
  for (std::size_t d = 0; d <= 2 * Mx; ++d) {
    const std::size_t kmax = 2 * Mx - d;
    for (std::size_t k = 0; k <= kmax; ++k) {
      if (d == 0) {
        cura[k] = f1[k];
        curb[k] = f2[k];
      } else {
        cura[k] = p1a[k + 1];
        cura[k] *= a1;
        curb[k] = p1b[k + 1];
        curb[k] *= a2;
        if (d >= 2) {
          tmp = p2a[k + 1];
          tmp *= static_cast<unsigned long>(d - 1);
          cura[k] += tmp;
          tmp = p2b[k + 1];
          tmp *= static_cast<unsigned long>(d - 1);
          curb[k] += tmp;
        }
      }
    }
    if (d % 2 == 0) {
      // R_{j+k} += [(2(j+k))!/(2j)!] c_k E1(2j,k) E2(2j,k), k = 0 .. Mx - j.
      const std::size_t j = d / 2;
      coef = 1;  // (2j)!/(2j)! * c_0
      for (std::size_t k = 0; j + k <= Mx; ++k) {
        if (k > 0) {
          // times (2j+2k-1)(2j+2k) for the factorial ratio, times (2k-1)/(2k) for c_k.
          coef *= static_cast<unsigned long>((2 * (j + k) - 1) * (2 * (j + k)));
          coef *= static_cast<unsigned long>(2 * k - 1);
          coef /= static_cast<unsigned long>(2 * k);
        }
        term = cura[k];
        term *= curb[k];
        term *= coef;
        R[j + k] += term;
      }
    }
    std::swap(p2a, p1a);
    std::swap(p1a, cura);
    std::swap(p2b, p1b);
    std::swap(p1b, curb);
  }
  return R;
}

/// A priori number of terms that certainly reaches relative tolerance tol (uses R_n <= R_0):
/// rel. error <= mu2^{M+1} (1 + 1/mu1) / (mu1 (1 - mu2)).
template <class Real>
std::size_t a_priori_terms(const Real& mu1, const Real& mu2, const Real& tol) {
  const double num = -static_cast<double>(log(tol)) - 2.0 * static_cast<double>(log(mu1)) +
                     std::log(4.0);
  const double den = -static_cast<double>(log(mu2));
  if (!(den > 0)) return 1u << 30;
  return static_cast<std::size_t>(std::ceil(num / den)) + 2;
}

template <class Real>
int checked_digits(int digits) {
  if (digits < min_digits || digits > max_digits) {
    throw invalid_input("digits must be in " + std::to_string(min_digits) + ".." +
                        std::to_string(max_digits) + ", got " + std::to_string(digits));
  }
  return digits;
}

}  // namespace

template <class Real>
std::vector<SeriesRow<Real>> series_convergence(const Chain<Real>& chain, const Real& beta,
                                                int digits, std::size_t terms) {
  checked_digits<Real>(digits);
  std::unique_ptr<working_precision> guard;
  if constexpr (is_mpfr_v<Real>) guard = std::make_unique<working_precision>(digits + guard_digits);
  const auto p = double_pendulum_parameters(chain, beta);
  const Real tol = is_mpfr_v<Real> ? Real(pow(Real(10), -(digits + 1)))
                                   : Real(4 * unit_roundoff<Real>());
  std::size_t M = terms > 0 ? terms : a_priori_terms(p.mu1, p.mu2, tol);
  if (M > 200000) throw invalid_input("the series needs too many terms at this mu1; use the integral");
  const auto R = paper_R(p.a1, p.a2, M + 1);  // R_0 .. R_M (R_M for the bound after M-1)
  std::vector<SeriesRow<Real>> rows;
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
  return rows;
}

template <class Real>
Averages<Real> series_average(const Chain<Real>& chain, const Real& beta, int digits,
                              std::size_t max_terms) {
  checked_digits<Real>(digits);
  std::unique_ptr<working_precision> guard;
  if constexpr (is_mpfr_v<Real>) guard = std::make_unique<working_precision>(digits + guard_digits);
  const auto rows = series_convergence(chain, beta, digits, max_terms);
  const auto& last = rows.back();
  // The series gives beta<K1>; <cos phi_i> and Var K_i come from the reduced integral.
  Averages<Real> out = reduced_integral_average(chain, beta, is_mpfr_v<Real> ? digits : 16);
  const Real u = unit_roundoff<Real>();
  const Real half_width = last.bound / 2;
  const Real k1 = last.beta_kinetic1 + half_width;
  const Real rounding = 16 * u * Real(rows.size()) * k1;
  const Real k1_err = half_width + rounding;
  const Real k2 = 1 - k1;
  out.beta_kinetic = {k1, k2};
  out.beta_kinetic_error = {k1_err, k1_err + 2 * u};
  out.ratio = k1 / k2;
  out.ratio_error = out.ratio * (k1_err / k1 + k1_err / k2 + 4 * u);
  out.method = Method::series;
  out.evaluations = rows.size();
  const Real tol = is_mpfr_v<Real> ? Real(pow(Real(10), -(digits + 1)))
                                   : Real(4 * unit_roundoff<Real>());
  out.converged = last.bound <= tol * last.beta_kinetic1;
  return out;
}

#define PENDAVG_INSTANTIATE(Real)                                                             \
  template std::vector<SeriesRow<Real>> series_convergence<Real>(const Chain<Real>&, const Real&, \
                                                                 int, std::size_t);           \
  template Averages<Real> series_average<Real>(const Chain<Real>&, const Real&, int, std::size_t);
PENDAVG_INSTANTIATE(double)
PENDAVG_INSTANTIATE(mpfr_real)
#undef PENDAVG_INSTANTIATE

}  // namespace pendavg
