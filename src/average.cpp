// SPDX-License-Identifier: GPL-3.0-or-later
// The one entry point for canonical averages (include/pendavg/average.hpp): validate the options
// against the method they select, set the working precision, hand over to an engine, and add
// what every method reports (beta<K_i^(c)>, the diagonal approximation, the equipartition
// residual).
#include "pendavg/average.hpp"

#include "domain.hpp"
#include "engine/transfer/chain_transfer.hpp"
#include "engine/certified.hpp"
#include "engine/double_pendulum/double_pendulum.hpp"
#include "engine/numerics/estimates.hpp"
#include "engine/numerics/precision.hpp"
#include "engine/numerics/text.hpp"
#include "engine/limits/limits.hpp"
#include "engine/limits/low_temperature.hpp"
#include "engine/qmc/qmc.hpp"
#include "engine/torus/torus.hpp"

#include <boost/math/policies/error_handling.hpp>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <functional>
#include <limits>
#include <stdexcept>
#include <string>
#include <tuple>
#include <vector>

namespace pendavg {

namespace detail {
template <class Real>
struct AverageWorkspaceData {
  IntegralWorkspace<Real> integral;
};
}  // namespace detail

namespace {

using namespace detail::limits;

// automatic runs the torus trapezoid up to automatic_torus_max_particles (n^(N-1) nodes:
// milliseconds for N <= 4, seconds for N = 5 at the default tolerance) and transfer beyond.
/// The beta -> 0 limit runs the torus trapezoid (at g = 0) up to this N, transfer beyond.
constexpr std::size_t limit_torus_max_particles = 5;
constexpr std::size_t max_shifts = 1024;
constexpr double min_tolerance = 1e-15;

constexpr std::array<const char*, 7> method_names{
    "auto", "integral", "series", "torus-trapezoid", "torus-gauss", "qmc", "transfer"};

std::string particles_text(std::size_t n) { return "N = " + std::to_string(n); }

/// "method auto (integral for N = 2)" or "method qmc": names the method in messages.
std::string method_text(AverageMethod requested, AverageMethod resolved, std::size_t n) {
  std::string text = std::string("method ") + average_method_name(requested);
  if (requested == AverageMethod::automatic)
    text += std::string(" (") + average_method_name(resolved) + " for " + particles_text(n) + ")";
  return text;
}

bool is_torus(AverageMethod m) {
  return m == AverageMethod::torus_trapezoid || m == AverageMethod::torus_gauss;
}

/// Refuses every option the resolved method does not use, and out-of-range values. `chosen()`
/// names what runs, for the messages (called only to build one: a valid call allocates nothing).
template <class ChosenText>
void check_options(const AverageOptions& o, AverageMethod resolved, std::size_t n,
                   const char* what, const ChosenText& chosen) {
  const auto refuse = [what](const std::string& message) {
    throw invalid_input(std::string(what) + ": " + message);
  };
  if (o.digits < min_digits || o.digits > max_digits)
    refuse("digits must be in " + std::to_string(min_digits) + ".." +
           std::to_string(max_digits) + ", got " + std::to_string(o.digits));
  if (o.threads < 1) refuse("threads must be >= 1");
  if (!method_supports_digits(resolved, o.digits))
    refuse("digits " + std::to_string(o.digits) + " is not available with " + chosen() + " (" +
           average_method_name(resolved) + " runs in double only)");
  if (o.tolerance) {
    if (!method_uses_option(resolved, AverageOption::tolerance, min_digits))
      refuse("tol is used by the torus and transfer methods only, not by " + chosen());
    if (!method_uses_option(resolved, AverageOption::tolerance, o.digits))
      refuse("tol is for double runs (digits 16); with digits " + std::to_string(o.digits) +
             " the torus tolerance is 1e-" + std::to_string(o.digits));
    // Below ~5 ulps a double run cannot resolve the relative error asked for: the Gauss rule's
    // levels, which do not nest, then refined until their grid limit (minutes) for --tol 1e-300.
    if (!(*o.tolerance >= min_tolerance && *o.tolerance < 1))
      refuse("tol must be in [1e-15, 1) (a double run resolves no finer relative error)");
  }
  for (const auto& [given, option] : {std::pair{o.samples.has_value(), AverageOption::samples},
                                      std::pair{o.shifts.has_value(), AverageOption::shifts},
                                      std::pair{o.seed.has_value(), AverageOption::seed}}) {
    if (given && !method_uses_option(resolved, option, o.digits))
      refuse(std::string(average_option_name(option)) + " is used by qmc only, not by " +
             chosen());
  }
  if (resolved == AverageMethod::transfer && n > transfer_max_particles)
    refuse("transfer takes N <= " + std::to_string(transfer_max_particles) + ", not " +
           particles_text(n));
  if (resolved == AverageMethod::qmc) {
    if (n > detail::qmc::lattice_max_dimension)
      refuse("qmc's built-in lattices cover N <= " +
             std::to_string(detail::qmc::lattice_max_dimension) + ", not " + particles_text(n));
    if (o.samples) {
      const std::size_t s = *o.samples;
      if (s < 1024 || s > (std::size_t(1) << 20) || (s & (s - 1)) != 0)
        refuse("samples must be a power of two in 1024..1048576, got " + std::to_string(s));
    }
    if (o.shifts && (*o.shifts < 4 || *o.shifts > max_shifts))
      refuse("shifts must be in 4.." + std::to_string(max_shifts) + ", got " +
             std::to_string(*o.shifts));
  }
}

/// The torus' work cap (TorusOptions::max_evaluations): the node evaluations that take about 10 s
/// of one core (N = 3 at 77 digits and beta = 2, 131,074 nodes, still converges), so that no
/// torus run is unbounded (a particle of 1e-100 of the chain's mass with
/// gravity took hours in MPFR; soft interior links between stiff ones ~100 s in double). Beyond
/// it the refinement stops with converged = false and the last level's errors. The cost of one
/// node per particle (user time over evaluations of `pendavg average --method torus-trapezoid`,
/// one core, N = 3..5): ~0.07 us in double, ~15 + 0.12
/// digits us in MPFR (N = 3: 51, 72, 79 us per node at 17, 38, 77 digits). A run split into
/// `runs` torus runs (the low-temperature extrapolation's three references) shares the cap.
double torus_evaluation_budget(std::size_t n, int digits, int runs) {
  constexpr double seconds = 10;
  const double per_particle = digits == min_digits ? 7e-8 : (15 + 0.12 * digits) * 1e-6;
  return seconds / (per_particle * static_cast<double>(n) * runs);
}

TorusOptions torus_options(const AverageOptions& o, AverageMethod method, std::size_t n,
                           const char* what, int runs = 1) {
  TorusOptions torus;
  torus.max_evaluations = torus_evaluation_budget(n, o.digits, runs);
  torus.rule = method == AverageMethod::torus_gauss ? TorusRule::gauss_legendre
                                                     : TorusRule::trapezoid;
  const double nodes =
      std::pow(static_cast<double>(torus.min_points_per_dim), static_cast<double>(n - 1));
  if (nodes > torus.max_grid_points)
    throw invalid_input(std::string(what) + ": " + particles_text(n) +
                        " is too long for a torus grid (" +
                        std::to_string(torus.min_points_per_dim) + "^" + std::to_string(n - 1) +
                        " nodes at the first level, over the cap of 1e9); use method qmc");
  torus.tolerance = o.tolerance.value_or(default_torus_tolerance);
  torus.digits = o.digits == min_digits ? 0 : o.digits;
  torus.threads = o.threads;
  torus.control = &o.control;
  return torus;
}

/// The transfer operator's work cap (TransferOptions::max_kernel_evaluations): 4e6 kernel
/// evaluations per particle, ~0.6 s of one core (0.15 us each), 13-30 times what ordinary chains
/// take to converge (N = 8 and 64 at beta = 1: 1.6e5 and 3e5 per particle; N = 1024 at beta = 100:
/// 1.3e5), while links alternating between 1e-118 and 1e118 refined past a minute at N = 8.
TransferOptions transfer_options(const AverageOptions& o, std::size_t n) {
  TransferOptions transfer;
  transfer.max_kernel_evaluations = 4e6 * static_cast<double>(n);
  transfer.tolerance = o.tolerance.value_or(default_transfer_tolerance);
  transfer.threads = o.threads;
  transfer.control = &o.control;
  return transfer;
}

QmcOptions qmc_options(const AverageOptions& o) {
  QmcOptions qmc;
  qmc.points = o.samples.value_or(default_qmc_samples);
  qmc.shifts = o.shifts.value_or(default_qmc_shifts);
  qmc.seed = o.seed.value_or(default_qmc_seed);
  qmc.threads = o.threads;
  qmc.partition = o.partition;
  qmc.control = &o.control;
  return qmc;
}

/// More digits advised for a double refusal only where the MPFR checks of the same method accept
/// the input (domain::more_digits_advice); nothing for MPFR runs.
template <class Real>
std::string advice_for(const Chain<Real>& chain, const Real& beta, AverageMethod method) {
  if constexpr (std::is_same_v<Real, double>) {
    AverageOptions o;
    o.method = method;
    return domain::more_digits_advice(chain, &beta, o);
  } else {
    (void)chain, (void)beta, (void)method;
    return "";
  }
}

/// The trace formula's pivots carry ratios up to M / m_min and their squares (src/engine/README.md,
/// 'Isserlis'): in double they stay finite only for M / m_min <= 1e150.
template <class Real>
void check_double_mass_range(const Chain<Real>& chain, const Real& beta, AverageMethod method) {
  const auto lightest = *std::min_element(chain.masses().begin(), chain.masses().end());
  const long double ratio = static_cast<long double>(static_cast<double>(chain.total_mass())) /
                            static_cast<double>(lightest);
  if (ratio > 1e150L)
    throw invalid_input("average: the total mass is " + short_decimal(ratio) +
                        " times the lightest mass, beyond double's range for the torus and qmc "
                        "methods (1e150)" + advice_for(chain, beta, method));
}


/// The method that takes a chain the torus and qmc methods cannot: the double-pendulum integral
/// or the transfer operator (which follows the peaks at any beta), advised only when its own
/// checks accept the chain (a particle of 1e-16 of the mass is beyond the transfer operator).
template <class Real>
std::string other_method_advice(const Chain<Real>& chain, const Real& beta) {
  AverageOptions other;
  other.method = chain.size() == 2 ? AverageMethod::integral : AverageMethod::transfer;
  try {
    check_average(chain, beta, other);
  } catch (const invalid_input&) {
    return "";
  }
  return chain.size() == 2 ? "; use method integral (the default for N = 2)"
                           : "; use method transfer (the default for N >= 5)";
}

/// Whether the same chain and beta, rounded to double, pass the double torus' checks: the advice
/// "at 16 digits pendavg extrapolates" is given only then (beta = 1e400 is no double).
template <class Real>
bool double_torus_accepts(const Chain<Real>& chain, const Real& beta) {
  if constexpr (is_mpfr_v<Real>) {
    try {
      const auto narrow = [](const Real& x) {
        const double d = x.template convert_to<double>();
        if (!std::isfinite(d) || Real(d) != x) throw invalid_input("not a double");
        return d;
      };
      std::vector<double> m, l;
      for (std::size_t i = 0; i < chain.size(); ++i) {
        m.push_back(narrow(chain.mass(i)));
        l.push_back(narrow(chain.length(i)));
      }
      AverageOptions torus;
      torus.method = AverageMethod::torus_trapezoid;
      check_average(Chain<double>(m, l, narrow(chain.gravity())), narrow(beta), torus);
      return true;
    } catch (const std::exception&) {
      return false;
    }
  } else {
    (void)chain, (void)beta;
    return false;
  }
}

/// A link below the first whose own stiffness alpha_j = beta g S_j l_j exceeds the softest
/// joint's by more than ~10^(1.25 W) (W the working digits) is beyond what the torus and qmc
/// methods resolve: measured on N = 3 chains with one long link (double: l_3 = 1e20 converges in
/// 0.2 s, 1e24 never; MPFR at 32 working digits: 1e40 in 1 s, 1e60 never), the weight's
/// relative angles then lose their digits. The first link is exempt (theta_1 = 0 is the
/// reference: l_1 = 1e24 converges as fast as 1). Refused before any work, with the digits
/// that would resolve it when MPFR can.
template <class Real>
void check_stiffness_spread(const Chain<Real>& chain, const Real& beta,
                            const JointStiffness& stiffness, bool runs_in_mpfr) {
  if (!(stiffness.smallest > 0) || chain.size() < 2) return;  // g = 0: no peak at all
  const domain::ChainScales scales = domain::chain_scales(chain, &beta);
  constexpr double log10_of_2 = 0.30102999566398120;
  const double softest = static_cast<double>(std::log10(stiffness.smallest));
  const int working = is_mpfr_v<Real> ? current_digits10<Real>() : min_digits;
  for (std::size_t j = 1; j < chain.size(); ++j) {
    const double spread = scales.stiffness[j] * log10_of_2 - softest;  // log10 alpha_j / kappa
    if (!(spread <= 1.25 * working)) {
      const double needed = std::ceil(spread / 1.25) - guard_digits;
      std::string advice;
      // advised only where the MPFR torus is practical (measured: 45 digits on such a chain
      // took over 20 s)
      if (runs_in_mpfr && needed <= 30 && stiffness.largest <= stiffness_resolved_mpfr)
        advice = "; request " + std::to_string(std::max(17, static_cast<int>(needed))) +
                 " or more digits";
      throw invalid_input("average: the stiffness beta g S_j l_j of link " +
                          std::to_string(j + 1) + " is 1e" +
                          std::to_string(static_cast<long long>(std::floor(spread))) +
                          " times the softest joint's, beyond what the torus and qmc methods "
                          "resolve at " + std::to_string(working) + " working digits" + advice);
    }
  }
}

/// What the torus and qmc methods do at `beta`: run directly, or extrapolate to low temperature
/// (every joint effectively stiffer than stiffness_extrapolated, double only). Throws invalid_input when the
/// stiffnesses are outside what either resolves.
enum class StiffnessPlan { direct, extrapolate };
template <class Real>
StiffnessPlan check_stiffness(const Chain<Real>& chain, const Real& beta, AverageMethod method) {
  const JointStiffness stiffness = joint_stiffness(chain, beta);
  check_stiffness_spread(chain, beta, stiffness, method != AverageMethod::qmc);
  if constexpr (!is_mpfr_v<Real>) {
    check_double_mass_range(chain, beta, method);
    // Extrapolate when every joint is effectively stiff, or when a joint is too stiff to resolve
    // directly and the others are at least beyond the references (1e3..4e3).
    if (stiffness.smallest_effective >= stiffness_extrapolated ||
        (stiffness.largest > stiffness_resolved &&
         stiffness.smallest_effective >= 10 * stiffness_reference)) {
      // The references run at 1, 2, 4 x beta_1, where the smallest effective stiffness is 1e3.
      if (stiffness.largest / stiffness.smallest_effective * 4 * stiffness_reference >
          stiffness_resolved)
        throw invalid_input(
            "average: the joints' stiffnesses beta g S l (" + short_decimal(stiffness.largest) +
            ", and an effective " + short_decimal(stiffness.smallest_effective) +
            " where a light particle meets a heavy tail or on a soft link) differ by more than "
            "2.5e9, beyond what the low-temperature extrapolation resolves" +
            other_method_advice(chain, beta));
      return StiffnessPlan::extrapolate;
    }
    if (stiffness.largest > stiffness_resolved)
      throw invalid_input("average: a joint's stiffness beta g S l = " +
                          short_decimal(stiffness.largest) + " is beyond what the torus and "
                          "qmc methods resolve (1e13) while another joint is soft (effective "
                          "stiffness " + short_decimal(stiffness.smallest_effective) + ")" +
                          other_method_advice(chain, beta));
  } else if (stiffness.largest > stiffness_resolved_mpfr) {
    throw invalid_input("average: a joint's stiffness beta g S l = " +
                        short_decimal(stiffness.largest) + " is beyond what the torus "
                        "resolves in MPFR (1e9)" +
                        (double_torus_accepts(chain, beta)
                             ? "; at 16 digits pendavg extrapolates to low temperature (every "
                               "joint stiffer than 1e7)"
                             : ""));
  }
  return StiffnessPlan::direct;
}

/// The engines, for a chain and beta already at the working precision.
template <class Real>
Averages<Real> run_average(const Chain<Real>& chain, const Real& beta, const AverageOptions& o,
                           AverageMethod method, AverageWorkspace<Real>& workspace) {
  Averages<Real> out;
  switch (method) {
    case AverageMethod::integral:
      out = reduced_integral_average(chain, beta, o.digits, IntegralOptions{},
                                     workspace.data().integral);
      break;
    case AverageMethod::series: out = series_average(chain, beta, o.digits); break;
    case AverageMethod::transfer:
      // Any beta: the engine's angle windows shrink with the Boltzmann peaks (width
      // alpha_j^-1/2), so neither the stiffness limits nor the low-temperature extrapolation of
      // the torus and qmc methods (below) apply; alpha_j beyond the double range is refused.
      if constexpr (is_mpfr_v<Real>) {
        throw invalid_input("average: transfer runs in double only");  // refused by check_options
      } else {
        return chain_transfer_average(chain, beta, transfer_options(o, chain.size()));
      }
    case AverageMethod::torus_trapezoid:
    case AverageMethod::torus_gauss:
    case AverageMethod::qmc: {
      const StiffnessPlan plan = check_stiffness(chain, beta, method);
      const int runs = plan == StiffnessPlan::extrapolate ? 3 : 1;
      const std::function<Averages<Real>(const Real&)> run = [&](const Real& b) {
        return method == AverageMethod::qmc
                   ? qmc_average(chain, b, qmc_options(o))
                   : torus_average(chain, b,
                                   torus_options(o, method, chain.size(), "average", runs));
      };
      if (plan == StiffnessPlan::extrapolate)
        return low_temperature_extrapolation(chain, beta, joint_stiffness(chain, beta), run);
      return run(beta);
    }
    case AverageMethod::automatic: break;  // resolved before
  }
  add_chain_extras(out, chain);
  return out;
}

}  // namespace

const char* average_method_name(AverageMethod method) {
  return method_names[static_cast<std::size_t>(method)];
}

AverageMethod parse_average_method(const char* name) {
  for (std::size_t m = 0; m < method_names.size(); ++m)
    if (std::strcmp(name, method_names[m]) == 0) return static_cast<AverageMethod>(m);
  throw invalid_input(std::string("unknown method '") + name +
                      "' (auto, integral, series, torus-trapezoid, torus-gauss, qmc or transfer)");
}

const char* average_option_name(AverageOption option) {
  switch (option) {
    case AverageOption::tolerance: return "tol";
    case AverageOption::samples: return "samples";
    case AverageOption::shifts: return "shifts";
    case AverageOption::seed: return "seed";
  }
  return "?";
}

bool method_uses_option(AverageMethod method, AverageOption option, int digits) {
  if (option == AverageOption::tolerance)
    return method == AverageMethod::transfer || (is_torus(method) && digits == min_digits);
  return method == AverageMethod::qmc;
}

bool method_supports_digits(AverageMethod method, int digits) {
  return digits == min_digits ||
         (method != AverageMethod::transfer && method != AverageMethod::qmc);
}

AverageMethod resolve_average_method(std::size_t n, const AverageOptions& options) {
  if (n == 0) throw invalid_input("average: a chain needs at least one mass");
  AverageMethod method = options.method;
  switch (options.method) {
    case AverageMethod::automatic:
      method = n == 2                               ? AverageMethod::integral
               : n <= automatic_torus_max_particles ? AverageMethod::torus_trapezoid
                                                    : AverageMethod::transfer;
      break;
    case AverageMethod::integral:
    case AverageMethod::series:
      if (n != 2)
        throw invalid_input(std::string("average: method ") + average_method_name(options.method) +
                            " is a double-pendulum engine (N = 2), not for " + particles_text(n) +
                            " (use auto, torus-trapezoid, torus-gauss, transfer or qmc)");
      break;
    default: break;
  }
  check_options(options, method, n, "average",
                [&] { return method_text(options.method, method, n); });
  if (is_torus(method)) torus_options(options, method, n, "average");  // the grid's size
  return method;
}

template <class Real>
AverageWorkspace<Real>::AverageWorkspace()
    : data_(std::make_unique<detail::AverageWorkspaceData<Real>>()) {}
template <class Real>
AverageWorkspace<Real>::~AverageWorkspace() = default;
template <class Real>
AverageWorkspace<Real>::AverageWorkspace(AverageWorkspace&&) noexcept = default;
template <class Real>
AverageWorkspace<Real>& AverageWorkspace<Real>::operator=(AverageWorkspace&&) noexcept = default;

template <class Real>
Averages<Real> average(const Chain<Real>& chain, const Real& beta, const AverageOptions& options) {
  AverageWorkspace<Real> workspace;
  return average(chain, beta, options, workspace);
}

/// The last line of defence (domain::check_result): every value and error an engine returns is
/// finite and, in double, of a normal magnitude. The domain checks before the work are meant to
/// make this unreachable; if an engine still meets a case they miss, the caller gets one clear
/// error instead of a NaN (never converged = true with it). The advice to request more digits is
/// given only when the MPFR checks accept the same input.
template <class Real>
void check_finite(const Averages<Real>& a, const char* command, const Chain<Real>& chain,
                  const Real* beta, const AverageOptions& options) {
  const bool cos_positive = chain.gravity() > 0;
  try {
    domain::check_result(a, command, "", cos_positive);
  } catch (const invalid_input&) {
    if constexpr (std::is_same_v<Real, double>)
      domain::check_result(a, command, domain::more_digits_advice(chain, beta, options),
                           cos_positive);
    throw;
  }
}

/// A dependency's own refusal (Boost.Math's domain, pole, overflow and evaluation errors) inside
/// an engine becomes the same one-line invalid_input as every other refusal.
template <class Body>
decltype(auto) translating_dependency_errors(const char* command, Body&& body) {
  const auto refuse = [command](const std::exception& e) {
    std::string what = e.what();
    std::replace(what.begin(), what.end(), '\n', ' ');
    return invalid_input(std::string(command) +
                         ": a special function is outside its domain for this input (" + what +
                         ")");
  };
  try {
    return body();
  } catch (const std::domain_error& e) {
    throw refuse(e);
  } catch (const std::overflow_error& e) {
    throw refuse(e);
  } catch (const std::underflow_error& e) {
    throw refuse(e);
  } catch (const boost::math::evaluation_error& e) {
    throw refuse(e);
  } catch (const boost::math::rounding_error& e) {
    throw refuse(e);
  }
}

/// The domain checks every method of average() shares (domain.hpp): in double, the lightest mass
/// fraction in the normal range and every joint's stiffness (the last link's too) at most 1e300.
template <class Real>
void check_average_domain(const Chain<Real>& chain, const Real& beta, const AverageOptions& options,
                          AverageMethod method) {
  if constexpr (std::is_same_v<Real, double>) {
    try {
      // The torus and qmc methods extrapolate at large beta (they run at a beta where alpha_j
      // is 1e3) and the N = 2 engines check a1 + a2 themselves: only transfer forms alpha_j at
      // the given beta.
      domain::check_double_scales(chain, method == AverageMethod::transfer ? &beta : nullptr,
                                  "average");
    } catch (const invalid_input& e) {
      throw invalid_input(e.what() + domain::more_digits_advice(chain, &beta, options));
    }
  } else {
    (void)chain, (void)beta, (void)options, (void)method;
  }
}

/// The certified engine's scope (src/engine/certified.md): N = 2 with method automatic or
/// integral, in a build with Arb. `what`: the command, for the message.
void check_certified(std::size_t n, const AverageOptions& o, const char* what) {
  if (!o.certified) return;
  const auto refuse = [what](const std::string& message) {
    throw invalid_input(std::string(what) + ": --certified " + message);
  };
  if (!certified_available()) refuse(std::string("is unavailable: ") + certified_unavailable_reason());
  if (n != 2) refuse("covers N = 2 only, not " + particles_text(n));
  if (o.method != AverageMethod::automatic && o.method != AverageMethod::integral)
    refuse(std::string("runs the N = 2 integral (method auto or integral), not method ") +
           average_method_name(o.method));
}

template <class Real>
Averages<Real> average(const Chain<Real>& chain, const Real& beta, const AverageOptions& options,
                       AverageWorkspace<Real>& workspace) {
  const AverageMethod method = resolve_average_method(chain.size(), options);
  check_certified(chain.size(), options, "average");
  if (options.certified) {
    check_digits<Real>(options.digits);
    check_beta(beta);
    return translating_dependency_errors("average", [&] {
      // The inputs as given (not rounded to the working precision): the enclosure is for them.
      const precision_guard<Real> precision(options.digits + guard_digits);
      double_pendulum_parameters(at_working_precision(chain), at_working_precision(beta));
      Averages<Real> out = certified_double_pendulum_average(chain, beta, options.digits);
      add_chain_extras(out, chain);
      check_finite(out, "average", chain, &beta, options);
      return out;
    });
  }
  check_digits<Real>(options.digits);
  check_beta(beta);
  check_average_domain(chain, beta, options, method);
  // The engine's result is checked in place and returned as is (no copy of its vectors).
  return translating_dependency_errors("average", [&] {
    if constexpr (is_mpfr_v<Real>) {
      const working_precision precision(options.digits + guard_digits);
      Averages<Real> out = run_average(at_working_precision(chain), at_working_precision(beta),
                                       options, method, workspace);
      check_finite(out, "average", chain, &beta, options);
      return out;
    } else {
      Averages<Real> out = run_average(chain, beta, options, method, workspace);
      check_finite(out, "average", chain, &beta, options);
      return out;
    }
  });
}

/// The MPFR torus on a chain without gravity (g = 0, also the beta -> 0 limit of N >= 3) and a
/// particle lighter than 1e-6 of the tail it carries (m_i / S_i): measured unbounded (masses 1,
/// 1e20, 1 at 17 digits ran for minutes; 1e5 takes 3.5 s), while the double torus takes the same
/// chain in seconds. Refused before any work.
template <class Real>
void check_mpfr_free_light_particles(const Chain<Real>& chain, const char* command,
                                     AverageMethod method, bool double_takes_it) {
  if constexpr (is_mpfr_v<Real>) {
    // The Gauss-Legendre rule (the independent check) in MPFR stalls on such a particle with
    // gravity too (masses 1.33, 1.2e175 at 25 digits: unbounded; the trapezoid: 0.3 s).
    const bool gauss = method == AverageMethod::torus_gauss;
    if ((!gauss && chain.gravity() != 0) || chain.size() < 2) return;
    for (std::size_t i = 0; i < chain.size(); ++i)
      if (!(chain.mass(i) / chain.tail_mass(i) >= Real(1e-6)))
        throw invalid_input(std::string(command) + ": particle " + std::to_string(i + 1) +
                            " carries a tail more than 1e6 times its mass, which the torus " +
                            std::string(gauss ? "Gauss-Legendre rule does not resolve in MPFR"
                                              : "does not resolve in MPFR without gravity (g = 0)") +
                            std::string(double_takes_it ? "; at 16 digits it does" : ""));
  } else {
    (void)chain, (void)command, (void)method, (void)double_takes_it;
  }
}

/// The chosen engine's own domain (cheap: no quadrature).
template <class Real>
void check_method_domain(const Chain<Real>& chain, const Real& beta, AverageMethod method) {
  switch (method) {
    case AverageMethod::series:
      if constexpr (!is_mpfr_v<Real>) {  // the series runs in MPFR at 16 digits
        const working_precision series_precision(min_digits + guard_digits);
        double_pendulum_parameters(chain.template cast<mpfr_real>(), mpfr_real(beta));
        break;
      }
      [[fallthrough]];
    case AverageMethod::integral:
      double_pendulum_parameters(at_working_precision(chain), at_working_precision(beta));
      break;
    case AverageMethod::torus_trapezoid:
    case AverageMethod::torus_gauss:
    case AverageMethod::qmc:
      if ((method == AverageMethod::torus_trapezoid && chain.gravity() == 0) ||
          method == AverageMethod::torus_gauss)
        check_mpfr_free_light_particles(chain, "average", method,
                                        double_torus_accepts(chain, beta));
      check_stiffness(at_working_precision(chain), at_working_precision(beta), method);
      break;
    case AverageMethod::transfer:
      // double only (check_options refuses more digits): the engine's own domain check
      if constexpr (!is_mpfr_v<Real>) check_transfer_domain(chain, beta);
      break;
    case AverageMethod::automatic: break;  // resolved above
  }
}

template <class Real>
void check_average(const Chain<Real>& chain, const Real& beta, const AverageOptions& options) {
  const AverageMethod method = resolve_average_method(chain.size(), options);
  check_certified(chain.size(), options, "average");
  check_digits<Real>(options.digits);
  check_beta(beta);
  check_average_domain(chain, beta, options, method);
  const precision_guard<Real> precision(options.digits + guard_digits);
  translating_dependency_errors("average", [&] { check_method_domain(chain, beta, method); });
}

/// The limits' domain (domain.hpp): in double, the lightest mass fraction in the normal range
/// and, for the trace formula (the beta -> infinity limit of any N, the beta -> 0 limit of
/// N >= 3), M / m_min <= 1e150. More digits are advised for N = 2 only, where both limits are
/// closed forms in MPFR.
template <class Real>
void check_limit_domain(const Chain<Real>& chain, bool trace_formula, bool torus_at_zero_g) {
  if constexpr (std::is_same_v<Real, double>) {
    (void)torus_at_zero_g;
    try {
      domain::check_double_scales(chain, static_cast<const Real*>(nullptr), "limit");
      if (trace_formula) domain::check_trace_formula_mass_range(chain, "limit");
    } catch (const invalid_input& e) {
      throw invalid_input(std::string(e.what()) +
                          (chain.size() == 2 ? "; request 17 or more digits (MPFR)" : ""));
    }
  } else {
    // the beta -> 0 limit of N >= 3 is the torus at g = 0
    (void)trace_formula;
    if (torus_at_zero_g) {
      const Chain<Real> free(chain.masses(), chain.lengths(), Real(0));
      check_mpfr_free_light_particles(free, "limit", AverageMethod::torus_trapezoid, false);
    }
  }
}

template <class Real>
Averages<Real> checked_limit(const Chain<Real>& chain, Averages<Real> out) {
  domain::check_result(out, "limit",
                       chain.size() == 2 && std::is_same_v<Real, double>
                           ? "; request 17 or more digits (MPFR)"
                           : "");
  return out;
}

template <class Real>
Averages<Real> high_temperature_limit_unchecked(const Chain<Real>& chain, const AverageOptions& options) {
  const std::size_t n = chain.size();
  if (options.method != AverageMethod::automatic)
    throw invalid_input(std::string("limit: method ") + average_method_name(options.method) +
                        " cannot be chosen; the limits pick their own");
  // N = 2: the elliptic formula, which takes no method options (resolved as "automatic").
  const AverageMethod method = n == 2                           ? AverageMethod::automatic
                               : n <= limit_torus_max_particles ? AverageMethod::torus_trapezoid
                                                                : AverageMethod::transfer;
  check_options(options, method, n, "limit", [&] {
    return n == 2 ? std::string("the beta -> 0 limit of N = 2 (the elliptic formula)")
                  : std::string("the beta -> 0 limit of ") + particles_text(n) + " (" +
                        average_method_name(method) + " at g = 0)";
  });
  check_digits<Real>(options.digits);
  check_certified(n, options, "limit");
  const precision_guard<Real> precision(options.digits + guard_digits);
  if (n == 2 && options.certified) {
    Averages<Real> out = certified_high_temperature_limit(chain, options.digits);
    add_chain_extras(out, chain);
    return out;
  }
  if (n == 2) {
    Averages<Real> out = elliptic_high_temperature_limit(at_working_precision(chain), options.digits);
    add_chain_extras(out, chain);
    return out;
  }
  if (method == AverageMethod::transfer) {
    if constexpr (is_mpfr_v<Real>) {
      throw invalid_input("limit: transfer runs in double only");  // refused by check_options
    } else {
      // The same chain at g = 0, where <cos phi_i> = 0 by symmetry (phi -> phi + const).
      const Chain<Real> free(chain.masses(), chain.lengths(), Real(0));
      Averages<Real> out =
          chain_transfer_average(free, Real(1), transfer_options(options, free.size()));
      for (Estimate<Real>& c : out.cos_angle) c = {Real(0), Real(0), ErrorKind::bound};
      add_chain_extras(out, chain);
      return out;
    }
  }
  const TorusOptions torus = torus_options(options, method, n, "limit");
  return high_temperature_limit_any(at_working_precision(chain), torus, QmcOptions{},
                                    limit_torus_max_particles);
}

template <class Real>
Averages<Real> low_temperature_limit_unchecked(const Chain<Real>& chain, const AverageOptions& options) {
  if (options.method != AverageMethod::automatic)
    throw invalid_input(std::string("limit: method ") + average_method_name(options.method) +
                        " cannot be chosen; the limits pick their own");
  check_options(options, AverageMethod::automatic, chain.size(), "limit",
                [] { return std::string("the beta -> infinity limit (a closed form)"); });
  check_digits<Real>(options.digits);
  // certified: the closed form's values for N = 2 (1/2, 1, 1/2) are exact (kind bound)
  check_certified(chain.size(), options, "limit");
  const precision_guard<Real> precision(options.digits + guard_digits);
  return low_temperature_limit_any(at_working_precision(chain));
}

template <class Real>
Averages<Real> high_temperature_limit(const Chain<Real>& chain, const AverageOptions& options) {
  check_limit_domain(chain, chain.size() >= 3, chain.size() >= 3);
  return checked_limit(chain, translating_dependency_errors("limit", [&] {
    return high_temperature_limit_unchecked(chain, options);
  }));
}

template <class Real>
Averages<Real> low_temperature_limit(const Chain<Real>& chain, const AverageOptions& options) {
  check_limit_domain(chain, true, false);
  return checked_limit(chain, translating_dependency_errors("limit", [&] {
    return low_temperature_limit_unchecked(chain, options);
  }));
}

#define PENDAVG_INSTANTIATE_AVERAGE(Real)                                                     \
  template class PENDAVG_EXPORT AverageWorkspace<Real>;                                       \
  template PENDAVG_EXPORT void check_average<Real>(const Chain<Real>&, const Real&,           \
                                                   const AverageOptions&);                    \
  template PENDAVG_EXPORT Averages<Real> average<Real>(const Chain<Real>&, const Real&,       \
                                                       const AverageOptions&);                \
  template PENDAVG_EXPORT Averages<Real> average<Real>(                                       \
      const Chain<Real>&, const Real&, const AverageOptions&, AverageWorkspace<Real>&);       \
  template PENDAVG_EXPORT Averages<Real> high_temperature_limit<Real>(const Chain<Real>&,     \
                                                                      const AverageOptions&); \
  template PENDAVG_EXPORT Averages<Real> low_temperature_limit<Real>(const Chain<Real>&,      \
                                                                     const AverageOptions&);
PENDAVG_INSTANTIATE_AVERAGE(double)
PENDAVG_INSTANTIATE_AVERAGE(mpfr_real)
#undef PENDAVG_INSTANTIATE_AVERAGE

}  // namespace pendavg
