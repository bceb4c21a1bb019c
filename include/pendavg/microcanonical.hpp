// SPDX-License-Identifier: GPL-3.0-or-later
// pendavg/microcanonical.hpp -- exact microcanonical averages at fixed energy E
// (src/engine/microcanonical/README.md): the values that NVE time averages along a trajectory
// (dynamics) must reproduce.
//
// What it computes. For an N-link chain (H = (1/2) p^T A^{-1} p + U, U = -sum_j gamma_j cos phi_j,
// gamma_j = g S_j l_j, paper eq. potential-energy; the minimum energy is E_min = -sum_j gamma_j):
//   * <K_i>_E      -- per-particle kinetic energies (energy units, not beta-scaled);
//   * <K>_E        = sum_i <K_i>_E = E - <U>_E;
//   * <K_i^(c)>_E  = <K>_E / N for every i (microcanonical generalized equipartition);
//   * <cos phi_i>_E;
//   * Var K_i      = <K_i^2>_E - <K_i>_E^2;
//   * Omega(E)     = ∫ delta(E - H) d^N phi d^N p, the density of states, whose Laplace transform
//                    is the canonical partition function (ensemble equivalence, tested).
// Per angle node the momenta are uniform on the ellipsoid p^T A^{-1} p / 2 = E - U, so
//     weight      sqrt(det A) (E - U)_+^{N/2 - 1}  (times (2 pi)^{N/2} / Gamma(N/2)),
//     <K_i | phi, E> = tr(X_i) (E - U) / N,   <K_i^(c) | phi, E> = (E - U) / N,
//     <K_i^2 | phi, E> = (E - U)^2 [(tr X_i)^2 + 2 tr(X_i^2)] / (N (N + 2)).
// (With p = L y, A^{-1} = L^{-T} L^{-1}, y is uniform on the sphere |y|^2 = 2 (E - U) in R^N and
// K_i = y^T C_i y / 2 with tr C_i = tr X_i, tr C_i^2 = tr X_i^2; the sphere's fourth moments
// <y_a y_b y_c y_d> = r^4 (d_ab d_cd + d_ac d_bd + d_ad d_bc) / (N (N + 2)) give the last line.)
//
// Two entry points, one shape: microcanonical_average(chain, E) and
// microcanonical_average_excitation(chain, D) with the excitation D = E - E_min > 0. Near the
// bottom of the well D is how a state is stated without losing digits: an energy E in double
// near E_min carries only ~u |E_min| / D relative accuracy in D once E_min is rounded, so
// microcanonical_average(chain, E) forms D = E + sum_j g S_j l_j in double-double from the
// chain's stored (binary) parameters, and both entry points then evaluate every E - U below
// E = 0 in the excitation form
//     E - U = D - (U - U_min),   U - U_min = sum_j gamma_j (1 - cos phi_j) >= 0,
// in which nothing cancels near the bottom: E + rho = D - (S - rho) with S - rho = sum_j gamma_j
// (1 - cos(theta_j - arg z)) (S = sum_j gamma_j), and likewise the critical radii of the cuts and
// the test for empty fibres below. (Above E = 0 the plain E + rho is the accurate form: there
// S - rho can be ~S while E + rho is ~rho, for a folded chain with z ~ 0.) The cuts of the
// nested integral, which near the bottom sit within ~sqrt(D) of 0, are kept to relative (not
// absolute) accuracy too. Relative accuracy then stays near the tolerance down to D = 1e-12
// |E_min| (tests/engine/microcanonical/test_microcanonical.cpp, the near-minimum ladder, against an independent
// long-double quadrature of the definition) and far below (D = 1e-250 |E_min| for N = 2, against
// the harmonic limit).
// Harmonic limit (D -> 0): H -> (1/2) phidot^T A_0 phidot + (1/2) phi^T Gamma phi. On the energy
// shell of N oscillators the 2N normal coordinates (momenta and frequency-scaled positions) are
// uniform on a sphere, so each mode carries kinetic energy D/(2N) on average and, with the
// modes' velocity shapes v_k (V^T A_0 V = 1, V V^T = A_0^{-1}),
//     <K_i>_E -> (D / (2N)) sum_k v_k^T A^(i)(0) v_k = (D / (2N)) tr X_i(0) = D / (2N)
// for every particle, whatever the masses and lengths: tr X_i(0) = m_i c_i^T A_0^{-1} c_i = 1
// with A_0 = C^T diag(m) C, c_i^T = e_i^T C. The positions give <phi_i^2>_E -> D / (N gamma_i),
// i.e. 1 - <cos phi_i>_E -> D / (2 N gamma_i), and the sphere's fourth moments give
// Var K_i -> D^2 [(1 + 2 tr X_i(0)^2) / (4 N (N + 1)) - 1 / (4 N^2)]. Corrections are O(D).
//
// Shell integrals (detail::microcanonical::ShellIntegrals, every p in {-1/2, 0, 1/2, 1, ...}).
// Integration by parts gives the three-term recurrence
//     (p + 1) F_{p+1} = (2p + 1) E F_p + p (rho^2 - E^2) F_{p-1},
// seeded from F_0, F_1 (elementary) or F_{-1/2}, F_{1/2} (complete elliptic integrals, as Carlson's
// R_F, R_D, R_G with the complementary parameter given directly). It is evaluated in the form
// in which it is stable:
//   * E >= rho (every psi accessible): F_p = 2 pi (E + rho)^p L_p(m'), m' = 2 rho / (E + rho),
//     L_p = (2/pi) ∫_0^{pi/2} (1 - m' sin^2 v)^p dv; the recurrence runs forward on the dominant
//     solution. G_p: for E >= 2 rho the series G_p = pi p E^{p-1} rho 2F1((1-p)/2, 1-p/2; 2; rho^2/E^2)
//     (no cancellation as rho/E -> 0); below, G_p = (F_{p+1} - E F_p) / rho.
//   * |E| < rho (a cap of the circle): sin(u/2) = sqrt(m) s, m = (E + rho)/(2 rho), gives
//     F_p = 4 sqrt(m) (E + rho)^p J_p(m), J_p = ∫_0^1 (1 - s^2)^p (1 - m s^2)^{-1/2} ds. For m >= 1/2
//     (E >= 0) the recurrence for J has only non-negative terms; for m < 1/2 it would amplify
//     rounding by ((1-m)/m)^p, so J_p = (1/2) B(1/2, p+1) 2F1(1/2, 1/2; p + 3/2; m) is summed
//     instead (positive terms, ratio <= m <= 1/2). Relative accuracy is thus kept down to the
//     bottom of the well (E + rho -> 0), where every term of the naive closed forms cancels.
// All F_p are returned divided by W^p, W = E + sum_j gamma_j (the largest E - U), so nothing
// overflows for any N. Tested against adaptive quadrature of the definitions (1e-13 relative).
//
// Rules on the (N-1)-torus of the relative angles theta:
//   * `integral` (automatic for N <= 4): nested 1-D double-exponential (tanh-sinh) quadrature,
//     theta_2 outermost (over [0, pi], doubled: the integrand is even under theta -> -theta).
//     F_p(E, rho(theta)) is not smooth where rho = |E| (the edge of the accessible region for
//     E < 0, the cap/full-circle transition for E > 0; a (rho - |E|)^{p+1/2} singularity, with a
//     log for half-integer p). Each circle is cut at every point where the remaining integral can
//     be singular, found in closed form: with v = sum_{k<=j} gamma_k e^{i theta_k}, the integral
//     over theta_{j+1..N} changes analytically except where |v| equals a critical value
//     | |E| + sum_{k>j} eps_k gamma_k | (eps_k = +-1; rho is critical when every later link is
//     parallel to z), and |v|^2 = |v_{j-1}|^2 + gamma_j^2 + 2 gamma_j |v_{j-1}| cos(theta_j - arg
//     v_{j-1}) is solved for theta_j. For a light particle (m_j/S_j < 0.09) the circle is also
//     cut at delta = 0, pi, where det A nearly vanishes. Each piece is then analytic with
//     algebraic end singularities, which tanh-sinh integrates at a double-exponential rate.
//     Levels h = 1, 1/2, 1/4, ... per piece; error estimate d_L (d_L / d_{L-1}) once the
//     differences contract tenfold (quadratic convergence), d_L before that; inner errors are
//     integrated and carried outwards. Pieces where the whole fibre is inaccessible are skipped.
//   * `torus`: the plain tensor periodic trapezoid rule on the (N-1)-torus, refined n -> 2n,
//     error = last difference. The kinks limit it to algebraic convergence (~n^-2 for N = 3):
//     an independent cross-check for N <= 4, not a production rule.
//   * `qmc` (automatic for N >= 5): randomized rank-1 lattice QMC (the qmc engine's lattices) over the
//     N absolute angles drawn from the product of von Mises laws exp(beta* gamma_j cos phi_j),
//     through Best-Fisher's wrapped-Cauchy inverse CDF with the exact acceptance ratio as weight.
//     The psi marginal of that proposal is 2 pi I0(beta* rho), so each point carries the weight
//     r(phi) sqrt(det A) F_p(E, rho) / I0(beta* rho) and the psi integral stays analytic.
//     beta* solves N/(2 beta) - sum_j gamma_j I1(beta gamma_j)/I0(beta gamma_j) = E (the proposal's
//     mean energy with equipartition kinetic energy equals E). Error = sigmas x the jackknife
//     standard error over the random shifts (a statistical bar, not a bound; sigmas is by
//     default the 99.9% Student-t quantile, 4.07 for 16 shifts: see src/engine/qmc/README.md on why not 3).
//
// Cost: the integral rule's nodes grow steeply with N (N = 4 is its practical limit); the qmc
// bars shrink about like n^-1/2 (the kink at rho = |E| and the dimension). beta* is the matched
// value (scanning it did not help).
// Why: README, Design notes, 'Measurements behind the design choices'
// (microcanonical: nodes, times and bars for N = 2, 3, 4, 7, 16; the beta* scan).
// Cross-checks (tests/engine/microcanonical/test_microcanonical.cpp): N = 2 against a 2-D brute-force quadrature of
// the definition (dense A, exact phi_1 limits; 1e-11); integral vs QMC vs torus trapezoid vs a
// 3-angle brute force for N = 3; Laplace transforms of Omega(E) <K_i>_E against the canonical
// engines (N = 2: 1e-9; N = 3: 1e-7, slow test) and of Omega against Z(beta) of N = 1 (1e-9); the
// near-minimum ladder (relative errors <= 1.1e-15 at D = 1e-4..1e-12 |E_min| for N = 2, 3, bars
// 5e-15 (N = 2) and 5e-14 (N = 3) relative); double against long double at every separatrix
// energy and above the top; MPFR (30 digits) against double.
// Precision: double, long double and mpfr_real (pendavg/mpfr.hpp). With options.digits > 16
// (MPFR only) the integral and torus rules run at digits + guard_digits with tolerance
// 10^-digits; qmc is statistical and runs in double or long double only (refused with digits).
// QMC weights are kept as exp(log w - log_scale) with a running reference per shift, so they
// neither under- nor overflow for any N or D; a non-finite value is never reported as converged.
// Limitations: the `integral` rule costs ~(pieces x nodes)^(N-1) and is for N <= 4; QMC bars are
// statistical, and the proposal ignores sqrt(det A), so efficiency falls with N (the reported
// effective_sample_fraction shows it). E exactly on a separatrix of N = 1 (E = gamma_1) gives
// F_{-1/2} = infinity (<K> = 0, the infinite-period orbit). The library does no I/O.
#pragma once

#include "pendavg/export.hpp"
#include "pendavg/average.hpp"
#include "pendavg/chain.hpp"
#include "pendavg/result.hpp"

#include <cstddef>
#include <cstdint>
#include <optional>
#include <vector>

namespace pendavg {

/// Options of microcanonical_average.
struct MicrocanonicalOptions {
  /// automatic: N <= 4 integral, N >= 5 qmc.
  enum class Rule { automatic, integral, torus, qmc } rule = Rule::automatic;
  /// Relative target of the deterministic rules (integral, torus) in double; unset:
  /// default_microcanonical_tolerance(N). With digits > 16 it is 10^-digits.
  std::optional<double> tolerance;
  int max_level = 10;        ///< integral: tanh-sinh levels per piece (h = 2^-level), 2..12
  std::size_t max_points_per_dim = 4096;  ///< torus: refinement cap
  // qmc
  std::size_t points = std::size_t(1) << 14;  ///< lattice points per shift: 2^10..2^16
  std::size_t shifts = 16;                    ///< independent random shifts (>= 4)
  std::uint64_t seed = 1;                     ///< shifts from std::mt19937_64(seed)
  /// error = sigmas x jackknife standard error; 0 (default): the 99.9% two-sided Student-t
  /// quantile for shifts - 1 degrees of freedom (4.07 for 16 shifts), as in qmc_average.
  double sigmas = 0;
  double proposal_beta = 0;  ///< qmc: beta* of the von Mises proposal; 0: automatic (see header)
  int threads = 1;  ///< OpenMP threads (results bitwise independent of the count; MPFR: 1)
  /// Progress (integral: the outermost angle's pieces; torus: each level's rows; qmc: the
  /// shifts) and a stop request, polled within a fraction of a second: a stopped run throws
  /// `interrupted` (no partial result carries an error estimate).
  RunControl control;
  /// 0: run at the caller's precision with `tolerance`. > 0: check_digits<Real>(digits) (16 for
  /// double; 17..1000 for mpfr_real, run at digits + guard_digits with tolerance 10^-digits;
  /// the integral and torus rules only).
  int digits = 0;
};

/// Microcanonical averages of one chain at one energy. Arrays have one entry per particle.
template <class Real>
struct MicrocanonicalAverages {
  Real energy{};      ///< E (from the excitation: E_min + D, rounded)
  Real excitation{};  ///< D = E - E_min > 0 (from the energy: formed in double-double)
  std::vector<Estimate<Real>> kinetic;  ///< <K_i>_E (energy units)
  Estimate<Real> kinetic_canonical;     ///< <K_i^(c)>_E = <K>_E / N (every i)
  Estimate<Real> kinetic_total;         ///< <K>_E = E - <U>_E
  std::vector<Estimate<Real>> cos_angle;  ///< <cos phi_i>_E
  std::vector<Estimate<Real>> kinetic_variance;  ///< Var K_i = <K_i^2>_E - <K_i>_E^2
  /// Omega(E) = ∫ delta(E - H) d^N phi d^N p = (2 pi)^{N/2} / Gamma(N/2) ∫ sqrt(det A)
  /// (E - U)_+^{N/2-1} d^N phi: the normalizer; ∫ Omega(E) e^{-beta E} dE = Z(beta).
  Estimate<Real> density_of_states;
  Method method = Method::microcanonical;
  Method quadrature = Method::reduced_integral;  ///< reduced_integral, torus_trapezoid or qmc
  /// estimate (integral, torus) or statistical (qmc): the kind of every error above.
  ErrorKind error_kind = ErrorKind::estimate;
  std::size_t evaluations = 0;  ///< work done, in `work_unit`
  WorkUnit work_unit = WorkUnit::nodes;  ///< nodes (integral, torus) or samples (qmc)
  bool converged = true;        ///< false: the tolerance was not reached (bars still valid)
  // qmc only
  Real proposal_beta{};              ///< beta* of the von Mises proposal
  Real effective_sample_fraction{};  ///< (sum w)^2 / (n sum w^2) over all points
};

/// The microcanonical averages at energy E. Throws invalid_input for a non-finite E,
/// E <= E_min = -sum_j gamma_j (no accessible states) or bad options.
template <class Real>
PENDAVG_EXPORT MicrocanonicalAverages<Real> microcanonical_average(
    const Chain<Real>& chain, const Real& energy, const MicrocanonicalOptions& options = {});

/// The same at the excitation D = E - E_min (> 0, finite): the way to state an energy near the
/// bottom of the well without losing digits (see the header comment).
template <class Real>
PENDAVG_EXPORT MicrocanonicalAverages<Real> microcanonical_average_excitation(
    const Chain<Real>& chain, const Real& excitation, const MicrocanonicalOptions& options = {});

/// Checks, without computing, everything microcanonical_average(chain, energy, options) checks
/// before its work (options, the state, the rule against N and digits, the engine's double
/// range); throws the invalid_input it would throw. Cheap: a sweep checks every row with it
/// before the first. For mpfr_real with options.digits = 0 it checks at this thread's current
/// precision, as microcanonical_average() would compute (see pendavg/mpfr.hpp).
template <class Real>
PENDAVG_EXPORT void check_microcanonical(const Chain<Real>& chain, const Real& energy,
                                         const MicrocanonicalOptions& options = {});

/// The same for microcanonical_average_excitation.
template <class Real>
PENDAVG_EXPORT void check_microcanonical_excitation(const Chain<Real>& chain,
                                                    const Real& excitation,
                                                    const MicrocanonicalOptions& options = {});

/// E_min = -sum_j g S_j l_j of the chain's stored parameters (double-double sum, rounded once).
template <class Real>
PENDAVG_EXPORT Real minimum_energy(const Chain<Real>& chain);

/// D = E - E_min, formed in double-double (relative error ~u however close E is to E_min).
template <class Real>
PENDAVG_EXPORT Real excitation_energy(const Chain<Real>& chain, const Real& energy);

/// The rule `rule` runs for N = `particles`: automatic is integral for N <= 4 and qmc beyond;
/// any other rule is itself.
PENDAVG_EXPORT MicrocanonicalOptions::Rule resolve_microcanonical_rule(
    std::size_t particles, MicrocanonicalOptions::Rule rule);

/// "integral", "torus-trapezoid" or "qmc": the name of the rule `rule` resolves to for N =
/// `particles` (the names average_method_name gives the same methods).
PENDAVG_EXPORT const char* microcanonical_rule_name(MicrocanonicalOptions::Rule rule,
                                                    std::size_t particles);

/// Whether the microcanonical rule `rule` (resolved, not automatic) uses `option` in a run at
/// `digits`: the tolerance the integral and torus rules in double, samples, shifts and seed qmc.
PENDAVG_EXPORT bool microcanonical_rule_uses_option(MicrocanonicalOptions::Rule rule,
                                                    AverageOption option, int digits);

/// The default relative tolerance of the deterministic rules (integral, torus) in double for N
/// particles, used when MicrocanonicalOptions::tolerance is unset: 1e-13 for N <= 2, 1e-11 for
/// N = 3, 1e-9 beyond (their cost grows like (nodes per angle)^(N-1)).
PENDAVG_EXPORT double default_microcanonical_tolerance(std::size_t particles);

/// The microcanonical run that average()'s options select for N particles, so that one set of
/// options (AverageOptions: method, digits, tolerance, samples, shifts, seed, threads) serves
/// both ensembles: method automatic (integral for N <= 4, qmc beyond), integral,
/// torus_trapezoid or qmc; tolerance for integral and torus_trapezoid in double; samples (a
/// power of two in 1024..65536), shifts (4..1024) and seed for qmc; digits > 16 (MPFR) for
/// integral (N <= 4) and torus_trapezoid (N <= 2: it converges only algebraically). Throws
/// invalid_input naming an option the chosen rule does not use, or a method the microcanonical
/// engine does not have. Pure; cheap.
PENDAVG_EXPORT MicrocanonicalOptions microcanonical_options(const AverageOptions& options,
                                                            std::size_t particles);

/// Solves N/(2 beta) - sum_j gamma_j I1(beta gamma_j)/I0(beta gamma_j) = E for beta (qmc
/// proposal), in the excitation form N/(2 beta) + sum_j gamma_j (1 - I1/I0) = E - E_min.
template <class Real>
PENDAVG_EXPORT Real matched_beta(const Chain<Real>& chain, const Real& energy);

}  // namespace pendavg
