// The one entry point for canonical averages (include/pendavg/average.hpp): validate the options
// against the method they select, set the working precision, hand over to an engine, and add
// what every method reports (beta<K_i^(c)>, the diagonal approximation, the equipartition
// residual).
#include "pendavg/average.hpp"

#include "engine/double_pendulum.hpp"
#include "engine/estimates.hpp"
#include "engine/precision.hpp"
#include "engine/torus.hpp"

#include <array>
#include <cmath>
#include <cstring>
#include <string>

namespace pendavg {

namespace detail {
template <class Real>
struct AverageWorkspaceData {
  IntegralWorkspace<Real> integral;
};
}  // namespace detail

namespace {

// automatic runs the torus trapezoid up to automatic_torus_max_particles (n^(N-1) nodes:
// milliseconds for N <= 4, seconds for N = 5 at the default tolerance) and qmc beyond.
/// The beta -> 0 limit runs the torus trapezoid (at g = 0) up to this N, qmc beyond.
constexpr std::size_t limit_torus_max_particles = 5;
constexpr std::size_t max_shifts = 1024;

constexpr std::array<const char*, 6> method_names{"auto",           "integral",    "series",
                                                  "torus-trapezoid", "torus-gauss", "qmc"};

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

/// Refuses every option the resolved method does not use, and out-of-range values. `chosen`
/// names what runs, for the messages.
void check_options(const AverageOptions& o, AverageMethod resolved, std::size_t n,
                   const char* what, const std::string& chosen) {
  const std::string context = std::string(what) + ": ";
  if (o.digits < min_digits || o.digits > max_digits)
    throw invalid_input(context + "digits must be in " + std::to_string(min_digits) + ".." +
                        std::to_string(max_digits) + ", got " + std::to_string(o.digits));
  if (o.threads < 1) throw invalid_input(context + "threads must be >= 1");
  if (o.tolerance) {
    if (!is_torus(resolved))
      throw invalid_input(context + "tol is used by the torus methods only, not by " + chosen);
    if (o.digits != min_digits)
      throw invalid_input(context + "tol is for double runs (digits 16); with digits " +
                          std::to_string(o.digits) + " the torus tolerance is 1e-" +
                          std::to_string(o.digits));
    if (!(*o.tolerance > 0 && *o.tolerance < 1))
      throw invalid_input(context + "tol must be in (0, 1)");
  }
  for (const auto& [given, name] : {std::pair{o.samples.has_value(), "samples"},
                                    std::pair{o.shifts.has_value(), "shifts"},
                                    std::pair{o.seed.has_value(), "seed"}}) {
    if (given && resolved != AverageMethod::qmc)
      throw invalid_input(context + name + " is used by qmc only, not by " + chosen);
  }
  if (resolved == AverageMethod::qmc) {
    if (o.digits != min_digits)
      throw invalid_input(context + "digits " + std::to_string(o.digits) +
                          " is not available with " + chosen + " (qmc runs in double only)");
    if (n > detail::qmc::lattice_max_dimension)
      throw invalid_input(context + "qmc's built-in lattices cover N <= " +
                          std::to_string(detail::qmc::lattice_max_dimension) + ", not " +
                          particles_text(n));
    if (o.samples) {
      const std::size_t s = *o.samples;
      if (s < 1024 || s > (std::size_t(1) << 20) || (s & (s - 1)) != 0)
        throw invalid_input(context + "samples must be a power of two in 1024..1048576, got " +
                            std::to_string(s));
    }
    if (o.shifts && (*o.shifts < 4 || *o.shifts > max_shifts))
      throw invalid_input(context + "shifts must be in 4.." + std::to_string(max_shifts) +
                          ", got " + std::to_string(*o.shifts));
  }
}

TorusOptions torus_options(const AverageOptions& o, AverageMethod method, std::size_t n,
                           const char* what) {
  TorusOptions torus;
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
  return torus;
}

QmcOptions qmc_options(const AverageOptions& o) {
  QmcOptions qmc;
  qmc.points = o.samples.value_or(default_qmc_samples);
  qmc.shifts = o.shifts.value_or(default_qmc_shifts);
  qmc.seed = o.seed.value_or(default_qmc_seed);
  qmc.threads = o.threads;
  return qmc;
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
    case AverageMethod::torus_trapezoid:
    case AverageMethod::torus_gauss:
      return torus_average(chain, beta, torus_options(o, method, chain.size(), "average"));
    case AverageMethod::qmc: return qmc_average(chain, beta, qmc_options(o));
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
                      "' (auto, integral, series, torus-trapezoid, torus-gauss or qmc)");
}

AverageMethod resolve_average_method(std::size_t n, const AverageOptions& options) {
  if (n == 0) throw invalid_input("average: a chain needs at least one mass");
  AverageMethod method = options.method;
  switch (options.method) {
    case AverageMethod::automatic:
      method = n == 2                          ? AverageMethod::integral
               : n <= automatic_torus_max_particles ? AverageMethod::torus_trapezoid
                                               : AverageMethod::qmc;
      break;
    case AverageMethod::integral:
    case AverageMethod::series:
      if (n != 2)
        throw invalid_input(std::string("average: method ") + average_method_name(options.method) +
                            " is a double-pendulum engine (N = 2), not for " + particles_text(n) +
                            " (use auto, torus-trapezoid, torus-gauss or qmc)");
      break;
    default: break;
  }
  check_options(options, method, n, "average", method_text(options.method, method, n));
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

template <class Real>
Averages<Real> average(const Chain<Real>& chain, const Real& beta, const AverageOptions& options,
                       AverageWorkspace<Real>& workspace) {
  const AverageMethod method = resolve_average_method(chain.size(), options);
  check_digits<Real>(options.digits);
  check_beta(beta);
  if constexpr (is_mpfr_v<Real>) {
    const working_precision precision(options.digits + guard_digits);
    return run_average(at_working_precision(chain), at_working_precision(beta), options, method,
                       workspace);
  } else {
    return run_average(chain, beta, options, method, workspace);
  }
}

template <class Real>
Averages<Real> high_temperature_limit(const Chain<Real>& chain, const AverageOptions& options) {
  const std::size_t n = chain.size();
  if (options.method != AverageMethod::automatic)
    throw invalid_input(std::string("limit: method ") + average_method_name(options.method) +
                        " cannot be chosen; the limits pick their own");
  // N = 2: the elliptic formula, which takes no method options (resolved as "automatic").
  const AverageMethod method = n == 2                           ? AverageMethod::automatic
                               : n <= limit_torus_max_particles ? AverageMethod::torus_trapezoid
                                                                : AverageMethod::qmc;
  check_options(options, method, n, "limit",
                n == 2 ? std::string("the beta -> 0 limit of N = 2 (the elliptic formula)")
                       : std::string("the beta -> 0 limit of ") + particles_text(n) + " (" +
                             average_method_name(method) + " at g = 0)");
  check_digits<Real>(options.digits);
  const precision_guard<Real> precision(options.digits + guard_digits);
  if (n == 2) {
    Averages<Real> out = elliptic_high_temperature_limit(at_working_precision(chain), options.digits);
    add_chain_extras(out, chain);
    return out;
  }
  TorusOptions torus;
  if (method == AverageMethod::torus_trapezoid)
    torus = torus_options(options, method, n, "limit");
  return high_temperature_limit_any(at_working_precision(chain), torus, qmc_options(options),
                                    limit_torus_max_particles);
}

template <class Real>
Averages<Real> low_temperature_limit(const Chain<Real>& chain, const AverageOptions& options) {
  if (options.method != AverageMethod::automatic)
    throw invalid_input(std::string("limit: method ") + average_method_name(options.method) +
                        " cannot be chosen; the limits pick their own");
  check_options(options, AverageMethod::automatic, chain.size(), "limit",
                "the beta -> infinity limit (a closed form)");
  check_digits<Real>(options.digits);
  const precision_guard<Real> precision(options.digits + guard_digits);
  return low_temperature_limit_any(at_working_precision(chain));
}

#define PENDAVG_INSTANTIATE_AVERAGE(Real)                                                      \
  template class AverageWorkspace<Real>;                                                        \
  template Averages<Real> average<Real>(const Chain<Real>&, const Real&, const AverageOptions&); \
  template Averages<Real> average<Real>(const Chain<Real>&, const Real&, const AverageOptions&, \
                                        AverageWorkspace<Real>&);                               \
  template Averages<Real> high_temperature_limit<Real>(const Chain<Real>&,                      \
                                                       const AverageOptions&);                  \
  template Averages<Real> low_temperature_limit<Real>(const Chain<Real>&, const AverageOptions&);
PENDAVG_INSTANTIATE_AVERAGE(double)
PENDAVG_INSTANTIATE_AVERAGE(mpfr_real)
#undef PENDAVG_INSTANTIATE_AVERAGE

}  // namespace pendavg
