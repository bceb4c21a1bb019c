// SPDX-License-Identifier: GPL-3.0-or-later
// tests/oracle/definition_2d.hpp -- an independent test oracle: the ORIGINAL definition of the
// double pendulum's thermal averages, evaluated by brute force on the 2-torus.
//
// What it is: paper eq. ave-Ki-linear-pi-trace-varphi for N = 2, taken literally,
//
//     beta <K_i> = (1/2) ∫ tr(A^(i) A^{-1}) sqrt(det A) e^{-beta U} d^2phi
//                        / ∫ sqrt(det A) e^{-beta U} d^2phi,
//
// with A from eq. a-ij, A^(i) from its definition below eq. Ki-linear-dotvarphi-Ai and U from
// eq. potential-energy. The 2x2 matrices are built and inverted with Eigen at every node; no
// closed form for the traces or the determinant (eqs. trA1Ainv-dp, detA) and none of the reductions
// of src/engine/README.md, 'Reduction' are used, so this file shares no algebra with the library it
// checks. The momenta are Gaussian given the angles, so (Isserlis, src/engine/README.md,
// 'Isserlis')
//
//     beta^2 <K_i^2 | phi> = [ (tr X_i)^2 + 2 tr(X_i X_i) ] / 4,    X_i = A^(i) A^{-1}.
//
// How: a tensor Gauss-Legendre rule on P equal panels per angle with n nodes each. The nodes are
// computed here (Newton on the Legendre three-term recurrence), generically in Real, so the same
// code runs in double and in MPFR. The integrand is periodic and analytic; its nearest
// singularities are the zeros of det A (src/engine/torus/README.md, 'Node maps': about
// asinh(sqrt(mu1/mu2)) off the real axis in phi2 - phi1), and exp(-beta U) grows off the real axis
// like exp(alpha cosh y), so the rule converges geometrically with a rate set by those two. U is
// summed literally at every node and shifted by its minimum U(0) (exp(-beta (U - U(0))) <= 1), so
// nothing overflows.
//
// When to use it: ONLY as a test oracle for moderate parameters (mu1 in ~[0.2, 0.8], beta*M*g*l
// up to ~20, l2/l1 in ~[0.5, 2]). It costs P^2 n^2 node evaluations and is hopeless for
// mu1 -> 0 or beta -> infinity; that is what the library's mapped 1-D integral is for. A caller
// must check the oracle's own convergence (e.g. n against 1.5 n) before trusting it; the helper
// `definition_average_2d_checked` does that and reports the observed difference.
#pragma once

#include <boost/multiprecision/eigen.hpp>
#include <boost/multiprecision/mpfr.hpp>

#include <Eigen/Dense>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstddef>
#include <limits>
#include <stdexcept>
#include <type_traits>
#include <vector>

namespace pendavg::oracle {

/// Gauss-Legendre rule on [-1, 1]: nodes in increasing order and their weights.
template <class Real>
struct GaussLegendreRule {
  std::vector<Real> nodes;
  std::vector<Real> weights;
};

/// P_n(x) and P_{n-1}(x) by the three-term recurrence (k+1) P_{k+1} = (2k+1) x P_k - k P_{k-1}.
template <class Real>
void legendre_pair(int n, const Real& x, Real& p_n, Real& p_nm1) {
  Real p_prev = 1;  // P_0
  Real p = x;       // P_1
  if (n == 0) {
    p_n = p_prev;
    p_nm1 = 0;
    return;
  }
  for (int k = 1; k < n; ++k) {
    Real p_next = (Real(2 * k + 1) * x * p - Real(k) * p_prev) / Real(k + 1);
    p_prev = p;
    p = p_next;
  }
  p_n = p;
  p_nm1 = p_prev;
}

/// The n-point Gauss-Legendre rule, converged to the precision of Real (for MPFR: the current
/// default precision). Newton's method from the Chebyshev-like guesses cos(pi (i - 1/4)/(n + 1/2)),
/// which lie inside the basin of each root; symmetric nodes are mirrored. For double the work is
/// done in long double and rounded once, and 1 - x^2 is formed as (1 - x)(1 + x): the weights
/// 2 / ((1 - x^2) P_n'(x)^2) are otherwise off by ~n^2 eps relative near the ends.
template <class Real>
GaussLegendreRule<Real> gauss_legendre(int n) {
  if (n < 1) throw std::invalid_argument("gauss_legendre: n must be >= 1");
  using Work = std::conditional_t<std::is_same_v<Real, double>, long double, Real>;
  using std::abs;
  using std::cos;
  const Work eps = std::numeric_limits<Work>::epsilon();
  const Work pi = boost::math::constants::pi<Work>();
  GaussLegendreRule<Real> rule;
  rule.nodes.assign(static_cast<std::size_t>(n), Real(0));
  rule.weights.assign(static_cast<std::size_t>(n), Real(0));
  const int half = (n + 1) / 2;
  for (int i = 1; i <= half; ++i) {
    // Largest root first: x_i ~ cos(pi (i - 1/4) / (n + 1/2)).
    Work x = cos(pi * (Work(i) - Work(0.25)) / (Work(n) + Work(0.5)));
    Work p_n, p_nm1, dp;
    bool done = false;
    for (int iter = 0; iter < 200; ++iter) {
      legendre_pair(n, x, p_n, p_nm1);
      dp = Work(n) * (p_nm1 - x * p_n) / ((Work(1) - x) * (Work(1) + x));
      const Work dx = p_n / dp;
      x -= dx;
      if (done) break;  // one polishing step after the Newton step fell below roundoff
      if (abs(dx) <= Work(4) * eps * (abs(x) + Work(1))) done = true;
    }
    if (!done) throw std::runtime_error("gauss_legendre: Newton iteration did not converge");
    legendre_pair(n, x, p_n, p_nm1);
    const Work one_minus_x2 = (Work(1) - x) * (Work(1) + x);
    dp = Work(n) * (p_nm1 - x * p_n) / one_minus_x2;
    const Work w = Work(2) / (one_minus_x2 * dp * dp);
    const std::size_t lo = static_cast<std::size_t>(i - 1);
    const std::size_t hi = static_cast<std::size_t>(n - i);
    if (lo == hi) {
      rule.nodes[lo] = 0;  // odd n: the middle root is exactly zero
    } else {
      rule.nodes[lo] = Real(-x);
      rule.nodes[hi] = Real(x);
    }
    rule.weights[lo] = Real(w);
    rule.weights[hi] = Real(w);
  }
  return rule;
}

/// A double pendulum given by its physical parameters only (no library types, on purpose).
template <class Real>
struct Pendulum2 {
  Real m1, m2;  ///< masses
  Real l1, l2;  ///< link lengths
  Real g;       ///< gravity
};

/// The averages eq. ave-Ki-linear-pi-trace-varphi defines, plus bookkeeping.
template <class Real>
struct DefinitionAverages {
  std::array<Real, 2> beta_kinetic;            ///< beta <K_i>
  std::array<Real, 2> cos_angle;               ///< <cos phi_i>
  std::array<Real, 2> beta2_kinetic_variance;  ///< beta^2 Var K_i
  Real trace_sum_deviation;  ///< max over nodes of |tr X_1 + tr X_2 - 2| (eq. mat-A-i sanity)
  std::size_t nodes = 0;     ///< number of torus nodes used
};

/// Matrix A(phi) of eq. a-ij: A_nk = (sum_{i >= max(n,k)} m_i) l_n l_k cos(phi_n - phi_k).
/// `cos_diff` is cos(phi_2 - phi_1) = cos(phi_1 - phi_2).
template <class Real>
Eigen::Matrix<Real, 2, 2> matrix_a(const Pendulum2<Real>& p, const Real& cos_diff) {
  const std::array<Real, 2> mass{p.m1, p.m2};
  const std::array<Real, 2> len{p.l1, p.l2};
  Eigen::Matrix<Real, 2, 2> a;
  for (int n = 0; n < 2; ++n) {
    for (int k = 0; k < 2; ++k) {
      Real tail = 0;
      for (int i = std::max(n, k); i < 2; ++i) tail += mass[static_cast<std::size_t>(i)];
      const Real c = (n == k) ? Real(1) : cos_diff;
      a(n, k) = tail * len[static_cast<std::size_t>(n)] * len[static_cast<std::size_t>(k)] * c;
    }
  }
  return a;
}

/// Matrix A^(i)(phi) (0-based particle index i): A^(i)_jk = m_i l_j l_k cos(phi_j - phi_k) for
/// j, k <= i, and 0 otherwise.
template <class Real>
Eigen::Matrix<Real, 2, 2> matrix_a_particle(const Pendulum2<Real>& p, int i, const Real& cos_diff) {
  const std::array<Real, 2> mass{p.m1, p.m2};
  const std::array<Real, 2> len{p.l1, p.l2};
  Eigen::Matrix<Real, 2, 2> a;
  for (int j = 0; j < 2; ++j) {
    for (int k = 0; k < 2; ++k) {
      if (j <= i && k <= i) {
        const Real c = (j == k) ? Real(1) : cos_diff;
        a(j, k) = mass[static_cast<std::size_t>(i)] * len[static_cast<std::size_t>(j)] *
                  len[static_cast<std::size_t>(k)] * c;
      } else {
        a(j, k) = 0;
      }
    }
  }
  return a;
}

/// Neumaier's compensated sum: the torus sums have 10^4..10^6 positive terms, and naive
/// summation would cost the double oracle ~1e-14 relative.
template <class Real>
class CompensatedSum {
 public:
  void add(const Real& x) {
    using std::abs;
    const Real t = sum_ + x;
    if (abs(sum_) >= abs(x)) {
      carry_ += (sum_ - t) + x;
    } else {
      carry_ += (x - t) + sum_;
    }
    sum_ = t;
  }
  Real value() const { return sum_ + carry_; }

 private:
  Real sum_ = 0;
  Real carry_ = 0;
};

/// Brute-force torus quadrature of the definition with `panels` equal panels per angle and
/// `nodes_per_panel` Gauss-Legendre nodes on each. Runs at the current precision of Real.
template <class Real>
DefinitionAverages<Real> definition_average_2d(const Pendulum2<Real>& p, const Real& beta,
                                               int panels, int nodes_per_panel) {
  using std::abs;
  using std::cos;
  using std::exp;
  using std::sin;
  using std::sqrt;
  if (panels < 1) throw std::invalid_argument("definition_average_2d: panels must be >= 1");
  const GaussLegendreRule<Real> rule = gauss_legendre<Real>(nodes_per_panel);
  const Real two_pi = boost::math::constants::two_pi<Real>();
  const Real h = two_pi / Real(panels);

  // Potential, eq. potential-energy, summed literally at every node:
  //     U(phi) = -sum_i m_i g sum_{j <= i} l_j cos phi_j.
  // Its minimum (all cos phi_j = 1) is U_min = -sum_i m_i g sum_{j <= i} l_j; the weight uses
  // exp(-beta (U - U_min)) <= 1, the same constant factor in numerator and denominator.
  const std::array<Real, 2> mass{p.m1, p.m2};
  const std::array<Real, 2> len{p.l1, p.l2};
  auto potential = [&](const Real& cos1, const Real& cos2) {
    const std::array<Real, 2> c{cos1, cos2};
    Real u = 0;
    for (std::size_t i = 0; i < 2; ++i) {
      Real height = 0;  // sum_{j <= i} l_j cos phi_j = -y_i (eq. y-by-varphi)
      for (std::size_t j = 0; j <= i; ++j) height += len[j] * c[j];
      u -= mass[i] * p.g * height;
    }
    return u;
  };
  const Real u_min = potential(Real(1), Real(1));

  // One-angle tables (the same grid for both angles).
  const std::size_t per_dim = static_cast<std::size_t>(panels) * rule.nodes.size();
  std::vector<Real> angle_cos(per_dim), angle_sin(per_dim), angle_weight(per_dim);
  for (int pi_ = 0; pi_ < panels; ++pi_) {
    for (std::size_t k = 0; k < rule.nodes.size(); ++k) {
      const std::size_t idx = static_cast<std::size_t>(pi_) * rule.nodes.size() + k;
      const Real phi = h * (Real(pi_) + (rule.nodes[k] + Real(1)) / Real(2));
      angle_cos[idx] = cos(phi);
      angle_sin[idx] = sin(phi);
      angle_weight[idx] = h / Real(2) * rule.weights[k];
    }
  }

  CompensatedSum<Real> z;
  std::array<CompensatedSum<Real>, 2> trace_sum, second_sum, cos_sum;
  Real worst_trace_sum = 0;
  for (std::size_t a = 0; a < per_dim; ++a) {      // phi_1
    for (std::size_t b = 0; b < per_dim; ++b) {    // phi_2
      const Real cos_diff = angle_cos[a] * angle_cos[b] + angle_sin[a] * angle_sin[b];
      const Eigen::Matrix<Real, 2, 2> mat_a = matrix_a(p, cos_diff);
      const Eigen::Matrix<Real, 2, 2> a_inv = mat_a.inverse();
      const Real det = mat_a.determinant();
      const Real boltzmann = exp(-beta * (potential(angle_cos[a], angle_cos[b]) - u_min));
      const Real w = angle_weight[a] * angle_weight[b] * sqrt(det) * boltzmann;
      z.add(w);
      cos_sum[0].add(w * angle_cos[a]);
      cos_sum[1].add(w * angle_cos[b]);
      Real traces = 0;
      for (int i = 0; i < 2; ++i) {
        const Eigen::Matrix<Real, 2, 2> x = matrix_a_particle(p, i, cos_diff) * a_inv;
        const Real tr = x.trace();
        const Real tr_sq = (x * x).trace();
        trace_sum[static_cast<std::size_t>(i)].add(w * tr);
        second_sum[static_cast<std::size_t>(i)].add(w * (tr * tr + Real(2) * tr_sq));
        traces += tr;
      }
      const Real dev = abs(traces - Real(2));
      if (dev > worst_trace_sum) worst_trace_sum = dev;
    }
  }

  DefinitionAverages<Real> out;
  for (std::size_t i = 0; i < 2; ++i) {
    const Real norm = z.value();
    out.beta_kinetic[i] = trace_sum[i].value() / norm / Real(2);
    out.cos_angle[i] = cos_sum[i].value() / norm;
    const Real second = second_sum[i].value() / norm / Real(4);  // beta^2 <K_i^2>
    out.beta2_kinetic_variance[i] = second - out.beta_kinetic[i] * out.beta_kinetic[i];
  }
  out.trace_sum_deviation = worst_trace_sum;
  out.nodes = per_dim * per_dim;
  return out;
}

/// Number of Gauss-Legendre nodes per panel that the geometric-convergence estimate says
/// suffices for `digits` digits with `panels` panels: the panel half-width is h/2 = pi/panels, the
/// nearest singularity of the integrand is at imaginary distance d = asinh(sqrt(mu1/mu2)) (zeros
/// of det A, in phi_1 at fixed real phi_2 and vice versa), and an n-point rule then errs by about
/// rho^{-2n} with rho = s + sqrt(s^2 + 1), s = d / (h/2). d is divided by sqrt(2) as a safety
/// margin (observed: the result is then converged to ~1e-36 already with 2n/3 nodes at 42 digits).
/// The exponential factor is entire; its growth is covered by requiring at least
/// ~ e * alpha * h / 4 + 8 nodes per panel. Callers still check n against 1.5 n.
inline int definition_nodes_per_panel(double mu1, double mu2, double alpha_max, int panels,
                                      int digits) {
  const double half_width = 3.14159265358979323846 / panels;
  const double d = std::asinh(std::sqrt(mu1 / mu2)) / std::sqrt(2.0);
  const double s = d / half_width;
  const double rho = s + std::sqrt(s * s + 1.0);
  const double n_sing = (digits + 2) * std::log(10.0) / (2.0 * std::log(rho));
  const double n_exp = 2.718281828 * alpha_max * 2.0 * half_width / 4.0 + 8.0;
  return static_cast<int>(std::ceil(std::max(n_sing, n_exp)));
}

/// The oracle with its own convergence check: evaluates with n and with ceil(1.5 n) nodes per
/// panel and returns the finer result; `refinement_difference` is the largest relative difference
/// between the two over beta<K_i> (and the absolute one over <cos phi_i>, beta^2 Var K_i).
template <class Real>
struct CheckedDefinitionAverages {
  DefinitionAverages<Real> fine;
  DefinitionAverages<Real> coarse;
  Real refinement_difference;
  int panels = 0, nodes_per_panel = 0;
};

template <class Real>
CheckedDefinitionAverages<Real> definition_average_2d_checked(const Pendulum2<Real>& p,
                                                              const Real& beta, int panels,
                                                              int nodes_per_panel) {
  using std::abs;
  CheckedDefinitionAverages<Real> out;
  out.panels = panels;
  out.nodes_per_panel = (3 * nodes_per_panel + 1) / 2;
  out.coarse = definition_average_2d(p, beta, panels, nodes_per_panel);
  out.fine = definition_average_2d(p, beta, panels, out.nodes_per_panel);
  Real diff = 0;
  for (std::size_t i = 0; i < 2; ++i) {
    const Real rk = abs(out.fine.beta_kinetic[i] - out.coarse.beta_kinetic[i]) /
                    abs(out.fine.beta_kinetic[i]);
    const Real rc = abs(out.fine.cos_angle[i] - out.coarse.cos_angle[i]);
    const Real rv = abs(out.fine.beta2_kinetic_variance[i] - out.coarse.beta2_kinetic_variance[i]);
    diff = std::max<Real>(diff, std::max<Real>(rk, std::max<Real>(rc, rv)));
  }
  out.refinement_difference = diff;
  return out;
}

}  // namespace pendavg::oracle
