// SPDX-License-Identifier: GPL-3.0-or-later
// The domain module (domain.hpp): scales as logarithms, guards that fail closed, the result check.
#include "domain.hpp"

#include "engine/numerics/precision.hpp"
#include "engine/numerics/text.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>

namespace pendavg::domain {
namespace {

constexpr double log2_of_10 = 3.321928094887362;

/// 2^l2 as short decimal text, for any l2 (long double holds 1e+-4931; beyond, "1e+N").
std::string power_text(double l2) {
  if (!(std::fabs(l2) < 16000)) {
    if (std::isnan(l2)) return "nan";
    const double l10 = l2 / log2_of_10;
    if (!std::isfinite(l10)) return l10 > 0 ? "inf" : "0";
    return "1e" + std::to_string(static_cast<long long>(std::floor(l10)));
  }
  return short_decimal(std::exp2(static_cast<long double>(l2)));
}

std::string link_text(std::size_t j) { return "link " + std::to_string(j + 1); }

}  // namespace

template <class Real>
double log2_magnitude(const Real& x) {
  if constexpr (is_mpfr_v<Real>) {
    if (mpfr_nan_p(x.backend().data())) return std::numeric_limits<double>::quiet_NaN();
    if (mpfr_zero_p(x.backend().data())) return -std::numeric_limits<double>::infinity();
    if (mpfr_inf_p(x.backend().data())) return std::numeric_limits<double>::infinity();
    long exponent = 0;
    const double mantissa = mpfr_get_d_2exp(&exponent, x.backend().data(), MPFR_RNDN);
    return static_cast<double>(exponent) + std::log2(std::fabs(mantissa));
  } else {
    return static_cast<double>(std::log2(std::fabs(static_cast<long double>(x))));
  }
}

template <class Real>
ChainScales chain_scales(const Chain<Real>& chain, const Real* beta) {
  const std::size_t n = chain.size();
  ChainScales s;
  const double log_total = log2_magnitude(chain.total_mass());
  const double log_beta = beta ? log2_magnitude(*beta) : 0.0;
  s.gravity = log2_magnitude(chain.gravity());
  s.lightest_mass = s.shortest_length = std::numeric_limits<double>::infinity();
  s.heaviest_mass = s.longest_length = -std::numeric_limits<double>::infinity();
  s.stiffness.resize(n);
  s.largest_stiffness = -std::numeric_limits<double>::infinity();
  for (std::size_t j = 0; j < n; ++j) {
    const double m = log2_magnitude(chain.mass(j)), l = log2_magnitude(chain.length(j));
    // NaN-proof minima and maxima: a NaN scale (never from a valid Chain) poisons them.
    const auto lower = [](double& a, double b) { a = (b < a || std::isnan(b)) ? b : a; };
    const auto upper = [](double& a, double b) { a = (b > a || std::isnan(b)) ? b : a; };
    lower(s.lightest_mass, m);
    upper(s.heaviest_mass, m);
    lower(s.shortest_length, l);
    upper(s.longest_length, l);
    s.stiffness[j] = log_beta + s.gravity + log2_magnitude(chain.tail_mass(j)) + l;
    upper(s.largest_stiffness, s.stiffness[j]);
  }
  s.lightest_fraction = s.lightest_mass - log_total;
  s.heaviest_ratio = log_total - s.lightest_mass;
  // log2 sum_j 2^stiffness_j, by the largest term (no overflow for any exponent).
  if (std::isfinite(s.largest_stiffness)) {
    double sum = 0;
    for (double l : s.stiffness) sum += std::exp2(l - s.largest_stiffness);
    s.total_stiffness = s.largest_stiffness + std::log2(sum);
  } else {
    s.total_stiffness = s.largest_stiffness;
  }
  return s;
}

template <class Real>
void check_double_scales(const Chain<Real>& chain, const Real* beta, const char* command) {
  if (!beta) {
    // Fast path for every ordinary chain (the N = 2 double call takes ~1 us): masses, lengths
    // and g within 1e-100..1e99 and N <= 16384 give m_min / M >= 1e-100 / (16384 1e99), normal,
    // and sum_j g S_j l_j <= 16384 1e99 (16384 1e99) 1e99 = 2.7e305 < 1e307: nothing to
    // compute. NaN is never inside.
    const auto inside = [](const Real& x) { return x >= Real(1e-100) && x <= Real(1e99); };
    bool ordinary = chain.size() <= 16384 && (chain.gravity() == 0 || inside(chain.gravity()));
    for (std::size_t j = 0; ordinary && j < chain.size(); ++j)
      ordinary = inside(chain.mass(j)) && inside(chain.length(j));
    if (ordinary) return;
  }
  const ChainScales s = chain_scales(chain, beta);
  if (!(s.lightest_fraction >= log2_double_min))
    throw invalid_input(std::string(command) + ": the lightest mass is " +
                        power_text(s.lightest_fraction) +
                        " of the total, below double's normal range (2.2e-308)");
  // The potential's coefficients gamma_j = g S_j l_j (every link, the last too) are formed in
  // double by every engine, whatever beta: their sum must stay finite with room to spare. With
  // beta, the same for alpha_j = beta gamma_j (the engines that form it at the given beta).
  const ChainScales potential = beta ? chain_scales(chain, static_cast<const Real*>(nullptr)) : s;
  for (const ChainScales* scales : {&potential, beta ? &s : nullptr}) {
    if (!scales || scales->total_stiffness <= log2_double_stiffness_max) continue;
    std::size_t stiffest = 0;
    for (std::size_t j = 0; j < scales->stiffness.size(); ++j)
      if (!(scales->stiffness[j] <= scales->stiffness[stiffest])) stiffest = j;
    const bool with_beta = scales == &s && beta;
    throw invalid_input(std::string(command) + ": the joints' " +
                        (with_beta ? "stiffnesses beta g S_j l_j" : "coefficients g S_j l_j") +
                        " sum to " + power_text(scales->total_stiffness) + " (" +
                        link_text(stiffest) + ": " + power_text(scales->stiffness[stiffest]) +
                        "), beyond double's range for the engines (1e307)");
  }
}

template <class Real>
void check_trace_formula_mass_range(const Chain<Real>& chain, const char* command) {
  const ChainScales s = chain_scales(chain, static_cast<const Real*>(nullptr));
  if (!(s.heaviest_ratio <= log2_double_trace_mass_ratio_max))
    throw invalid_input(std::string(command) + ": the total mass is " +
                        power_text(s.heaviest_ratio) +
                        " times the lightest mass, beyond double's range of the trace formula "
                        "(1e150)");
}

template <class Real>
void check_dynamics_scales(const Chain<Real>& chain, const char* command) {
  const ChainScales s = chain_scales(chain, static_cast<const Real*>(nullptr));
  // 1e50: m l^2 phidot and the energies m g l stay far inside double (masses 2e89 and lengths
  // 1e86 passed 1e100 and made non-finite momenta after 2 s).
  constexpr double limit = 166.09640474436813;  // log2(1e50)
  const auto inside = [](double l) { return l >= -limit && l <= limit; };
  const auto refuse = [&](const char* what, double l) {
    throw invalid_input(std::string(command) + ": " + what + " " + power_text(l) +
                        " is outside 1e-50..1e50, where the trajectory's positions, momenta "
                        "and frequencies leave double's range; choose units nearer 1");
  };
  if (!inside(s.lightest_mass)) refuse("a mass of", s.lightest_mass);
  if (!inside(s.heaviest_mass)) refuse("a mass of", s.heaviest_mass);
  if (!inside(s.shortest_length)) refuse("a length of", s.shortest_length);
  if (!inside(s.longest_length)) refuse("a length of", s.longest_length);
  if (chain.gravity() > 0 && !inside(s.gravity)) refuse("g =", s.gravity);
}

/// Refuses a time step beyond the integrators' stability limit, before any work. The fastest
/// motion is estimated per particle as a transverse oscillation between its two links:
/// omega_i^2 = (T_i / l_i + T_{i+1} / l_{i+1}) / m_i with the links' tensions T_j up to the weight
/// below, g S_j, plus the centrifugal share of the kinetic energy available, 2 K / l_j. The
/// compositions (Yoshida, Suzuki, Kahan-Li) and BAOAB are linearly stable for h omega below ~1.5;
/// h omega > 1 is refused.
template <class Real>
void check_stable_time_step(const Chain<Real>& chain, double time_step, long double kinetic,
                            const char* command, double duration, double max_steps) {
  using Wide = long double;
  const std::size_t n = chain.size();
  Wide omega2 = 0;
  const Wide g = static_cast<Wide>(chain.gravity());
  // Fail closed: a NaN energy (std::max(NaN, 0) is NaN, std::max(0, NaN) is 0) must not read
  // as a motionless chain whose every time step is stable.
  if (std::isnan(kinetic))
    throw invalid_input(std::string(command) + ": the initial energy is not a number for this "
                        "input; choose units nearer 1");
  const Wide k = kinetic > 0 ? kinetic : Wide(0);
  for (std::size_t i = 0; i < n; ++i) {
    const Wide li = static_cast<Wide>(chain.length(i));
    Wide stiffness = (g * static_cast<Wide>(chain.tail_mass(i)) + 2 * k / li) / li;
    if (i + 1 < n) {
      const Wide lj = static_cast<Wide>(chain.length(i + 1));
      stiffness += (g * static_cast<Wide>(chain.tail_mass(i + 1)) + 2 * k / lj) / lj;
    }
    const Wide own = stiffness / static_cast<Wide>(chain.mass(i));
    if (!(own <= omega2)) omega2 = own;  // a NaN stays, and is refused below
  }
  const Wide omega = std::sqrt(omega2);
  if (!std::isfinite(omega))
    throw invalid_input(std::string(command) + ": the fastest motion's angular frequency "
                        "overflows (masses, lengths, g and the energy far apart); choose units "
                        "nearer 1");
  if (!(static_cast<Wide>(time_step) * omega <= 1)) {
    // The advised step only where it fits the run's step cap; beyond it the scales are the cause.
    const Wide advised = Wide(0.05) / omega;
    const bool fits = !(static_cast<Wide>(duration) / advised > static_cast<Wide>(max_steps));
    throw invalid_input(std::string(command) + ": a time step of " + short_decimal(time_step) +
                        " is beyond the integrator's stability limit (the fastest motion has "
                        "angular frequency ~" + short_decimal(omega) + "); " +
                        (fits ? "use --dt " + short_decimal(advised) + " or smaller"
                              : "a stable step would need more than " + short_decimal(max_steps) +
                                    " steps for this run: choose units nearer 1"));
  }
}

std::string more_digits_advice(const Chain<double>& chain, const double* beta,
                               const AverageOptions& options) {
  // The series is never the method to advise (it refuses light particles beyond its term cap;
  // the integral is the N = 2 default), nor are transfer and qmc (double only: check_average
  // refuses them at 17 digits).
  if (options.method == AverageMethod::series) return "";
  // The MPFR checks below ask whether the double checks take the same chain (the stiffness
  // message's "at 16 digits"), whose refusal asks for this advice again: without this guard the
  // two recursed until the stack overflowed (once a cap of 64 nested working precisions ended
  // it by accident). Inside, only whether double refuses matters: no advice.
  thread_local bool advising = false;
  if (advising) return "";
  struct Advising {
    Advising() { advising = true; }
    ~Advising() { advising = false; }
    Advising(const Advising&) = delete;
    Advising& operator=(const Advising&) = delete;
  } const inside;
  AverageOptions wider = options;
  wider.digits = min_digits + 1;
  wider.tolerance.reset();  // the torus' tolerance is 10^-digits in MPFR (may not be set)
  try {
    const precision_guard<mpfr_real> precision(wider.digits + guard_digits);
    const Chain<mpfr_real> wide = chain.cast<mpfr_real>();
    if (beta) {
      check_average(wide, mpfr_real(*beta), wider);
    } else {
      // the limits: only the chain itself is checked (both limits run in MPFR for any N <= 5)
      if (chain.size() > 5) return "";
    }
  } catch (const std::exception&) {
    return "";
  }
  return "; request 17 or more digits (MPFR)";
}

template <class Real>
void check_finite_value(const Real& x, const char* command, const char* what) {
  using std::isfinite;
  if (!isfinite(x))
    throw invalid_input(std::string(command) + ": the result " + what +
                        " is not finite for this input (outside the engine's domain; please "
                        "report it)");
}

template <class Real>
void check_finite_estimate(const Estimate<Real>& e, const char* command, const char* what) {
  check_finite_value(e.value, command, what);
  check_finite_value(e.error, command, what);
}

template <class Real>
void check_result(const Averages<Real>& a, const char* command, const std::string& advice,
                  bool cos_positive) {
  using std::isfinite;
  const auto bad = [](const Estimate<Real>& e) {
    return !isfinite(e.value) || !isfinite(e.error) || !(e.error >= 0);
  };
  // A value below double's normal range carries fewer digits than printed (and 1e-320 is
  // off by 1e-3 relative): refused like an overflow. So is one within 2^53 of it: the N = 2
  // integral's <cos phi_2> at 5e-305 was off by 1.5e-12 relative (terms ~1e-8 of it passed
  // through the subnormals), its error claiming 1e-14.
  constexpr double smallest_normal = std::numeric_limits<double>::min();
  const auto underflowed = [](const Estimate<Real>& e) {
    if constexpr (std::is_same_v<Real, double>)
      return e.value != 0 && std::fabs(e.value) < 0x1p53 * smallest_normal;
    else
      return false;
  };
  const char* which = nullptr;
  bool tiny = false;
  for (auto [name, field] : {std::pair{"beta<K_i>", &a.beta_kinetic},
                             std::pair{"<cos phi_i>", &a.cos_angle},
                             std::pair{"beta^2 Var K_i", &a.beta2_kinetic_variance},
                             std::pair{"beta<K_i^(c)>", &a.beta_kinetic_canonical}}) {
    for (const Estimate<Real>& e : *field) {
      if (which) break;
      if (bad(e)) which = name;
      else if (underflowed(e)) which = name, tiny = true;
      // With gravity every <cos phi_i> is positive: a 0 in double underflowed.
      else if (std::is_same_v<Real, double> && cos_positive && field == &a.cos_angle &&
               e.value == 0)
        which = name, tiny = true;
    }
  }
  if (!which && a.ratio) {
    if (bad(*a.ratio)) which = "<K1>/<K2>";
    else if (underflowed(*a.ratio)) which = "<K1>/<K2>", tiny = true;
  }
  if (!which)
    for (const Real& d : a.diagonal_approximation)
      if (!isfinite(d)) which = "diagonal approximation";
  if (!which && !isfinite(a.equipartition_residual)) which = "equipartition residual";
  if (!which) return;
  if (tiny)
    throw invalid_input(std::string(command) + ": " + method_name(a.method) + " gives " + which +
                        " below double's normal range (2.2e-308), or within 2^53 of it, for this "
                        "input, where it loses digits" + advice);
  throw invalid_input(std::string(command) + ": " + method_name(a.method) +
                      " produced a non-finite " + which +
                      " for this input, outside its domain (please report it)" + advice);
}

#define PENDAVG_INSTANTIATE_DOMAIN(Real)                                                     \
  template double log2_magnitude<Real>(const Real&);                                         \
  template ChainScales chain_scales<Real>(const Chain<Real>&, const Real*);                  \
  template void check_double_scales<Real>(const Chain<Real>&, const Real*, const char*);    \
  template void check_trace_formula_mass_range<Real>(const Chain<Real>&, const char*);      \
  template void check_dynamics_scales<Real>(const Chain<Real>&, const char*);               \
  template void check_result<Real>(const Averages<Real>&, const char*, const std::string&, \
                                    bool);                                                  \
  template void check_finite_estimate<Real>(const Estimate<Real>&, const char*, const char*); \
  template void check_finite_value<Real>(const Real&, const char*, const char*);            \
  template void check_stable_time_step<Real>(const Chain<Real>&, double, long double, const char*, \
                                             double, double);
PENDAVG_INSTANTIATE_DOMAIN(double)
PENDAVG_INSTANTIATE_DOMAIN(long double)
PENDAVG_INSTANTIATE_DOMAIN(mpfr_real)
#undef PENDAVG_INSTANTIATE_DOMAIN

}  // namespace pendavg::domain
