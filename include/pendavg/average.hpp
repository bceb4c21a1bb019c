// SPDX-License-Identifier: GPL-3.0-or-later
// pendavg/average.hpp -- the one entry point for canonical averages of any chain (N = 1..16384):
// beta<K_i>, <cos phi_i>, beta^2 Var K_i, <K_1>/<K_2>, beta<K_i^(c)> and the paper's diagonal
// approximation, each with its error and the kind of guarantee the error carries
// (result.hpp), and the beta -> 0 and beta -> infinity limits.
//
// Methods (AverageMethod; `automatic` picks for you):
//   * integral         N = 2: the exact 1-D reduced integral (src/engine/double_pendulum/), by
//                      finite Graf sums or sinh-mapped Clenshaw-Curtis nodes; fast in double (README,
//                      "Measurements behind the design choices"), any digits in MPFR. Error
//                      kind: estimate. automatic for N = 2.
//   * series           N = 2: the paper's series (eq. ave-K1-result) in MPFR with its rigorous
//                      tail bound (kind bound for beta<K_i>; <cos phi_i>, Var K_i come from the
//                      integral). Slow when mu1 = m1/M is small (geometric in mu2).
//   * torus_trapezoid  any N: the periodic trapezoid rule on the reduced (N-1)-torus, refined
//                      until `tolerance` (double) or 10^-digits (MPFR); cost n^(N-1), so N <= ~6.
//                      automatic for N = 1, 3, 4. Error kind: estimate.
//   * torus_gauss      the same with Gauss-Legendre nodes: an independent check.
//   * transfer         any N (1..transfer_max_particles): the transfer operator along the chain
//                      (README, "Large N"), refined until `tolerance` (default 1e-10; double
//                      only); error geometric in the nodes, cost O(N) per node (timings in
//                      the README). automatic for N >= 5. Error kind: estimate.
//   * qmc              any N <= 256: randomized rank-1 lattice QMC, statistical bars (the 99.9%
//                      Student-t quantile of the standard error over the shifts: 4.07 sigma for
//                      16 shifts; double only): the independent check of transfer.
// Options a method does not use are refused (invalid_input), so a typo cannot silently change
// nothing. `digits` selects the precision: 16 is double (Real = double); 17..1000 need
// Real = mpfr_real (include pendavg/mpfr.hpp), computed at digits + guard_digits.
//
// Workspaces. average() with an AverageWorkspace reuses its buffers from call to call (one
// workspace per thread; Pinocchio's Data); the overload without one makes a temporary. Constant
// tables (quadrature rules, Bessel coefficients) are shared, immutable, by every call.
// Calls are thread-safe and give the same bits on any thread; the torus, QMC and transfer
// methods use `threads` OpenMP threads inside one call with results independent of their number.
#pragma once

#include "pendavg/export.hpp"
#include "pendavg/chain.hpp"
#include "pendavg/result.hpp"

#include <cstddef>
#include <cstdint>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <vector>

namespace pendavg {

enum class AverageMethod { automatic, integral, series, torus_trapezoid, torus_gauss, qmc, transfer };

/// "auto", "integral", "series", "torus-trapezoid", "torus-gauss", "qmc", "transfer" (the CLI's
/// names).
PENDAVG_EXPORT const char* average_method_name(AverageMethod method);

/// Parses one of average_method_name's names; throws invalid_input for anything else.
PENDAVG_EXPORT AverageMethod parse_average_method(const char* name);

/// The defaults of AverageOptions' unset optionals, and the automatic rule's torus limit.
inline constexpr double default_torus_tolerance = 1e-13;
inline constexpr std::size_t default_qmc_samples = std::size_t(1) << 16;
inline constexpr std::size_t default_qmc_shifts = 16;
inline constexpr std::uint64_t default_qmc_seed = 1;
inline constexpr double default_transfer_tolerance = 1e-10;
/// automatic: torus_trapezoid for N = 1 and 3..automatic_torus_max_particles, transfer beyond.
inline constexpr std::size_t automatic_torus_max_particles = 4;
/// The longest chain the transfer method takes (its memory grows like N n m: ~15 MB at 1024).
inline constexpr std::size_t transfer_max_particles = 16384;

/// Several processes computing one qmc average together (the CLI's MPI ranks; the library itself
/// has no MPI). Part p of P computes the shifts [R p / P, R (p + 1) / P) of the R shifts and
/// all_gather() hands every part the packed sums of all parts, in part order, so that each shift
/// is combined in shift order as in an undivided run: the result is bit-identical for every P
/// (each shift is summed by one thread, in point order). Every part must make the same calls.
class PENDAVG_EXPORT ShiftPartition {
 public:
  virtual ~ShiftPartition() = default;
  virtual int part() const = 0;   ///< 0..parts()-1
  virtual int parts() const = 0;  ///< >= 1
  /// Every part's `local` values, concatenated in part order (an all-gather; sizes may differ).
  virtual std::vector<double> all_gather(std::span<const double> local) const = 0;
};

/// How average() computes. Unset optionals mean "the method's default"; setting one that the
/// chosen method does not use is an error.
struct AverageOptions {
  AverageMethod method = AverageMethod::automatic;
  /// Significant digits requested: 16 (double) or 17..1000 (mpfr_real).
  int digits = 16;
  /// torus and transfer methods in double: relative tolerance (default default_torus_tolerance,
  /// default_transfer_tolerance; with digits > 16 the torus' is 10^-digits and may not be set).
  std::optional<double> tolerance;
  /// qmc: lattice points per shift, a power of two in [2^10, 2^20] (default 2^16).
  std::optional<std::size_t> samples;
  /// qmc: independent random shifts, 4..1024 (default 16).
  std::optional<std::size_t> shifts;
  /// qmc: seed of the shifts (default 1).
  std::optional<std::uint64_t> seed;
  /// OpenMP threads for the torus, qmc and transfer methods in double (results do not depend on
  /// it).
  int threads = 1;
  /// Progress (of each torus or transfer level, of the qmc shifts) and a stop request
  /// (RunControl, pendavg/result.hpp): a torus run stopped after its first level returns that
  /// level's values, a transfer run after two levels the first of them verified by the second,
  /// a qmc run the shifts it finished (interrupted = true, converged = false, errors still hold);
  /// before, average() throws `interrupted`.
  RunControl control;
  /// qmc: share the shifts with other processes (see ShiftPartition); null: compute them all.
  const ShiftPartition* partition = nullptr;
  /// N = 2 (method automatic or integral) and the N = 2 beta -> 0 limit: certified enclosures,
  /// every error a proven bound (kind bound, method certified-integral; src/engine/certified.md)
  /// for the inputs as the exact binary numbers given. Needs a build with Arb
  /// (certified_available()); refused otherwise, and for other N and methods.
  bool certified = false;
};

/// Whether this build can compute certified enclosures (AverageOptions::certified): Arb was
/// found at configure time.
PENDAVG_EXPORT bool certified_available();

/// What the certified enclosures run on: "Arb 2.23.0" (the run-time library), or, in a build
/// without Arb, why they are unavailable.
PENDAVG_EXPORT std::string certified_backend();

/// The optional settings of AverageOptions that only some methods use.
enum class AverageOption { tolerance, samples, shifts, seed };

/// "tol", "samples", "shifts", "seed": the names in messages (and the CLI's options).
PENDAVG_EXPORT const char* average_option_name(AverageOption option);

/// Whether `method` (a resolved method, not automatic) uses `option` in a run at `digits`:
/// the tolerance the torus rules (double only: with more digits it is 10^-digits) and transfer,
/// samples, shifts and seed qmc. Front ends that spread one set of options over rows of
/// different methods (pendavg table) ask this instead of knowing the methods.
PENDAVG_EXPORT bool method_uses_option(AverageMethod method, AverageOption option, int digits);

/// Whether `method` (resolved, not automatic) runs at `digits` > 16 (MPFR): every method but
/// transfer and qmc, which are double only.
PENDAVG_EXPORT bool method_supports_digits(AverageMethod method, int digits);

/// Which method average() runs for N particles under `options`, after checking every option
/// against it (invalid_input otherwise, naming the option and the method). Pure; cheap.
PENDAVG_EXPORT AverageMethod resolve_average_method(std::size_t particles,
                                                    const AverageOptions& options);

namespace detail {
template <class Real>
struct AverageWorkspaceData;
}

/// Buffers of average(), reused from call to call. Not thread-safe: one per thread.
template <class Real>
class PENDAVG_EXPORT AverageWorkspace {
 public:
  AverageWorkspace();
  ~AverageWorkspace();
  AverageWorkspace(AverageWorkspace&&) noexcept;
  AverageWorkspace& operator=(AverageWorkspace&&) noexcept;
  AverageWorkspace(const AverageWorkspace&) = delete;
  AverageWorkspace& operator=(const AverageWorkspace&) = delete;

  detail::AverageWorkspaceData<Real>& data() { return *data_; }

 private:
  std::unique_ptr<detail::AverageWorkspaceData<Real>> data_;
};

/// Checks, without computing, everything average(chain, beta, options) checks before its work:
/// the options against the method, digits, beta, and the chosen engine's domain (e.g. the
/// double-pendulum engine's range of beta g M l in double, the joints' stiffnesses of the torus
/// and qmc methods). Throws the invalid_input average() would throw. Cheap (no quadrature).
/// For mpfr_real it checks at digits + guard_digits on the calling thread, as average() computes
/// (see pendavg/mpfr.hpp); the caller holds nothing.
template <class Real>
PENDAVG_EXPORT void check_average(const Chain<Real>& chain, const Real& beta,
                                  const AverageOptions& options);

/// The canonical averages of `chain` at inverse temperature `beta` (finite, > 0).
/// Throws invalid_input for bad input or options.
template <class Real>
PENDAVG_EXPORT Averages<Real> average(const Chain<Real>& chain, const Real& beta,
                                      const AverageOptions& options = {});
template <class Real>
PENDAVG_EXPORT Averages<Real> average(const Chain<Real>& chain, const Real& beta,
                                      const AverageOptions& options,
                                      AverageWorkspace<Real>& workspace);

/// beta -> 0 (src/engine/README.md, 'Reduction'): N = 2 the paper's elliptic K/E formula (eq.
/// aveK1-beta0, kind bound); any N the average of the same chain at g = 0 (tensor trapezoid for N
/// <= 5, to `tolerance` or 10^-digits; transfer beyond, double only). <cos phi_i> -> 0 exactly.
/// `options.method` must be automatic; the torus or transfer options apply as for average().
template <class Real>
PENDAVG_EXPORT Averages<Real> high_temperature_limit(const Chain<Real>& chain,
                                                     const AverageOptions& options = {});

/// beta -> infinity: beta<K_i> -> 1/2, <cos phi_i> -> 1, beta^2 Var K_i -> tr(X_i(0)^2) / 2 in
/// closed form (kind bound). Only `digits` (and method automatic) may be set.
template <class Real>
PENDAVG_EXPORT Averages<Real> low_temperature_limit(const Chain<Real>& chain,
                                                    const AverageOptions& options = {});

}  // namespace pendavg
