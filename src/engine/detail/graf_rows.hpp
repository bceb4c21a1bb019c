// SPDX-License-Identifier: GPL-3.0-or-later
// engine/detail/graf_rows.hpp -- how many rows the N = 2 exact sums need (pure, in double): the
// Graf orders of the Boltzmann weight's cosine series (graf_orders_needed) and the rows beyond
// which the Fourier moments of q^s alone make the tail negligible (moment_sum_terms). Shared by
// the reduced integral (engine/double_pendulum.cpp), which uses them as its plan, and the
// certified engine (engine/certified.cpp), which uses them only as a first guess: its tails are
// bounded a posteriori (engine/certified.md).
#pragma once

#include <algorithm>
#include <cmath>
#include <cstddef>

namespace pendavg {

/// Number of Graf orders m for which e^{-a1} I_m(a1) e^{-a2} I_m(a2) is above e^{-L} of the
/// m = 0 term, from the exponent of the uniform (Debye) asymptotics of I_m(a) / I_0(a):
///   -ln(I_m(a) / I_0(a)) ~ a phi(m/a),  phi(x) = x asinh x - sqrt(1 + x^2) + 1
/// (the Gaussian m^2/(2a) for m << a, ln(m!) - m ln(a/2) - a for m >> a); the prefactors only
/// make the true products smaller. Solves a1 phi(m/a1) + a2 phi(m/a2) = L for m by Newton's
/// method (f is convex and increasing: from the Gaussian start, which lies below the root, the
/// first step lands above it and the rest descend monotonically). It tracks the trimmed row
/// lengths closely from above, where graf_terms_estimate can miss by tens of orders (README,
/// "The N = 2 cost model").
inline double graf_orders_needed(double a1, double a2, double L) {
  if (!(a1 > 0 && a2 > 0) || !(L > 0)) return 1.0;
  // asinh(m/a), also where m/a overflows (a subnormal scale: a tiny mass or length at large
  // digits): ln(2m/a) there. (The overflow once made the orders NaN.)
  const auto asinh_ratio = [](double m, double a) {
    const double x = m / a;
    return std::isfinite(x) ? std::asinh(x) : std::log(2.0) + std::log(m) - std::log(a);
  };
  // a phi(m/a) = m asinh(m/a) - m^2 / (sqrt(a^2 + m^2) + a): no cancellation, no a^2 overflow.
  const auto f = [&](double m) {
    double v = 0;
    for (const double a : {a1, a2}) v += m * asinh_ratio(m, a) - m * m / (std::hypot(a, m) + a);
    return v;
  };
  const double harmonic = a1 / (a1 + a2) * a2;
  double m = std::sqrt(2.0 * L * harmonic);  // f(m) <= m^2 / (2 harmonic): at or below the root
  for (int iteration = 0; iteration < 40; ++iteration) {
    const double slope = asinh_ratio(m, a1) + asinh_ratio(m, a2);
    if (!(slope > 0)) {
      m = 1.0;  // m = 0 start (tiny harmonic): one unit step, then Newton
      continue;
    }
    const double step = (L - f(m)) / slope;
    m += step;
    if (std::abs(step) < 0.25 || !(m < 1e9)) break;
  }
  return std::isnan(m) ? 1e9 : std::min(std::max(m, 1.0), 1e9);  // NaN: never a row count
}

/// Rows K of the exact sums beyond which the Fourier moments alone make the tail negligible:
/// with r = e^{-2d} = (1 - sqrt mu1)/(1 + sqrt mu1) (detail/fourier_moments.hpp), the moments of
/// every row s = 1/2, -1/2, -3/2 obey |Q_k(s)| <= (k + 1) r^k Q_0(s). (q^s = C^s |1 - r e^{i
/// theta}|^{2s}, theta = 2t, has Fourier coefficients sum_l b_{l+k} b_l r^{2l+k} with b_j =
/// (-s)_j / j!: for s = -1/2 all positive with ratio Q_k / Q_{k-1} <= r, since b_{j+1} < b_j; for
/// s = -3/2 the ratio is <= r (k + 1/2)/k, and prod_{j<=k} (1 + 1/(2j)) <= sqrt(e k) <= k + 1;
/// Q_k(1/2) = -mu1 Q_k(-3/2) / (4k^2 - 1) and Q_0(1/2) = mu1 Q_0(-3/2).) The Graf coefficients
/// are at most twice their first (c_k <= 2 c_0: eps_{2k} = 4 against 2, and e^{-a} I_m(a)
/// decreases in m; likewise c1, c2, whose I_m' = (I_{m-1} + I_{m+1})/2 <= I_{m-1}). So the
/// rows k >= K add at most 2 c_0 Q_0 sum_{k>=K} (k + 1) r^k <= 2 c_0 Q_0 (K + 1) r^K / (1 - r)^2,
/// below e^{-L} c_0 |Q_0| <= e^{-L} times the sum's L1 norm: the cut Graf tail the error bound
/// of graf_moment_integrals already counts. Returns 0 (no cut) when that needs over 10^6 rows.
inline std::size_t moment_sum_terms(double mu1, double L) {
  if (!(mu1 > 0 && mu1 < 1) || !(L > 0)) return 0;
  const double root = std::sqrt(mu1);
  // r rounded up (a relative 1e-12 above double's few roundings).
  const double r = (1 - root) / (1 + root) * (1 + 1e-12);
  const double log_r = std::log(r);
  if (!(log_r < 0)) return 0;
  const double log_scale = std::log(2.0) - 2 * std::log1p(-r);  // 2 / (1 - r)^2
  // (K + 1) r^K 2 / (1 - r)^2 <= e^{-L}: start from K = (L + log_scale) / -ln r, then step up.
  double K = std::ceil((L + log_scale) / -log_r);
  for (int step = 0; step < 64 && K <= 1e6; ++step) {
    if (std::log(K + 1) + K * log_r + log_scale <= -L) return static_cast<std::size_t>(K);
    K += std::ceil(std::log(K + 1) / -log_r) + 1;
  }
  return 0;
}

}  // namespace pendavg
