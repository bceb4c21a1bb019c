// SPDX-License-Identifier: GPL-3.0-or-later
// src/io/results.cpp -- the result types' field tables and record builders.
#include "io/results.hpp"

#include "io/migration.hpp"
#include "io/number_text.hpp"

#include "io/exact_values.hpp"

#include "engine/numerics/precision.hpp"
#include "engine/numerics/text.hpp"
#include "pendavg/average.hpp"

#include <gmp.h>
#include <mpfr.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <stdexcept>
#include <string>
#include <type_traits>

namespace pendavg::io {

namespace {

using K = Kind;
constexpr Shape one = Shape::scalar, each = Shape::per_particle;

constexpr Field canonical_inputs[] = {
    {"N", K::count, one, "the number of particles (links) of the chain"},
    {"digits", K::count, one, "significant digits requested (16: a double run; more: MPFR)"},
    {"beta", K::real, one, "the inverse temperature beta = 1/(k_B T)"},
    {"g", K::real, one, "the gravitational acceleration"},
    {"m", K::real, each, "the masses m_i"},
    {"l", K::real, each, "the link lengths l_i"},
};

constexpr Field chain_inputs[] = {
    canonical_inputs[0], canonical_inputs[1], canonical_inputs[3], canonical_inputs[4],
    canonical_inputs[5],
};

constexpr Field averages_table[] = {
    {"method", K::text, one, "the method that computed the averages"},
    {"beta_K", K::real, each, "beta<K_i>: the mean kinetic energy of particle i in units of k_B T"},
    {"beta_K_error", K::error, each, "its absolute error"},
    {"beta_K_error_kind", K::text, one, "what beta_K_error promises: bound, estimate or statistical"},
    {"K", K::real, each, "<K_i> = beta<K_i>/beta, in energy units (empty for a limit)"},
    {"K_error", K::error, each, "its absolute error"},
    {"K_error_kind", K::text, one, "what K_error promises"},
    {"ratio", K::real, one, "<K_1>/<K_2> (empty for N = 1)"},
    {"ratio_error", K::error, one, "its absolute error"},
    {"ratio_error_kind", K::text, one, "what ratio_error promises"},
    {"cos_phi", K::real, each, "<cos phi_i>: the mean cosine of link i's angle from the vertical"},
    {"cos_phi_error", K::error, each, "its absolute error"},
    {"cos_phi_error_kind", K::text, one, "what cos_phi_error promises"},
    {"var_K", K::real, each, "Var K_i = <K_i^2> - <K_i>^2, in energy units squared (empty for a limit)"},
    {"var_K_error", K::error, each, "its absolute error"},
    {"var_K_error_kind", K::text, one, "what var_K_error promises"},
    {"beta2_var_K", K::real, each, "beta^2 Var K_i (dimensionless; finite in the limits)"},
    {"beta2_var_K_error", K::error, each, "its absolute error"},
    {"beta2_var_K_error_kind", K::text, one, "what beta2_var_K_error promises"},
    {"beta_Kc", K::real, each,
     "beta<K_i^(c)>, K_i^(c) = p_i phidot_i / 2: 1/2 exactly (generalized equipartition), a built-in check"},
    {"beta_Kc_error", K::error, each, "its absolute error"},
    {"beta_Kc_error_kind", K::text, one, "what beta_Kc_error promises (bound)"},
    {"diagonal_approx", K::real, each,
     "the paper's diagonal approximation of beta<K_i> (an approximation: no error)"},
    {"equipartition_residual", K::error, one, "|sum_i beta<K_i> - N/2| after the computation"},
    {"evaluations", K::count, one, "work done, in work_unit"},
    {"work_unit", K::text, one, "what evaluations counts: terms, nodes, samples or steps"},
    {"converged", K::flag, one, "false: the requested accuracy was not reached (a bound still holds; an estimate is the last refinement's and can fall short of the true error)"},
    {"interrupted", K::flag, one, "true: stopped early by a signal; the finished part is reported"},
};

// The microcanonical averages after the state given (energy or excitation): the other one first.
#define PENDAVG_MICROCANONICAL_FIELDS \
  {"ensemble", K::text, one, "microcanonical: averages on the energy shell H = E"}, \
  {"method", K::text, one, "the quadrature of the microcanonical averages"}, \
  {"K", K::real, each, "<K_i>_E: the mean kinetic energy of particle i at energy E"}, \
  {"K_error", K::error, each, "its absolute error"}, \
  {"K_error_kind", K::text, one, "what K_error promises"}, \
  {"Kc", K::real, one, "<K_i^(c)>_E = <K>_E / N (the same for every particle)"}, \
  {"Kc_error", K::error, one, "its absolute error"}, \
  {"Kc_error_kind", K::text, one, "what Kc_error promises"}, \
  {"cos_phi", K::real, each, "<cos phi_i>_E"}, \
  {"cos_phi_error", K::error, each, "its absolute error"}, \
  {"cos_phi_error_kind", K::text, one, "what cos_phi_error promises"}, \
  {"var_K", K::real, each, "Var K_i on the energy shell"}, \
  {"var_K_error", K::error, each, "its absolute error"}, \
  {"var_K_error_kind", K::text, one, "what var_K_error promises"}, \
  {"K_total", K::real, one, "<K>_E = E - <U>_E"}, \
  {"K_total_error", K::error, one, "its absolute error"}, \
  {"K_total_error_kind", K::text, one, "what K_total_error promises"}, \
  {"density_of_states", K::real, one, "Omega(E), the normalizer of the shell average"}, \
  {"density_of_states_error", K::error, one, "its absolute error"}, \
  {"density_of_states_error_kind", K::text, one, "what density_of_states_error promises"}, \
  {"proposal_beta", K::real, one, "qmc: beta* of the von Mises proposal (empty otherwise)"}, \
  {"effective_sample_fraction", K::real, one, "qmc: (sum w)^2 / (n sum w^2) (empty otherwise)"}, \
  {"evaluations", K::count, one, "work done, in work_unit"}, \
  {"work_unit", K::text, one, "what evaluations counts"}, \
  {"converged", K::flag, one, "false: the tolerance was not reached (a bound still holds; an estimate is the last refinement's and can fall short of the true error)"}, \

constexpr Field energy_field{"energy", K::real, one, "the energy E"};
constexpr Field excitation_field{
    "excitation", K::real, one, "D = E - E_min, E_min = -sum_j g S_j l_j the bottom of the well"};

constexpr Field microcanonical_after_energy[] = {excitation_field, PENDAVG_MICROCANONICAL_FIELDS};
constexpr Field microcanonical_after_excitation[] = {energy_field, PENDAVG_MICROCANONICAL_FIELDS};
#undef PENDAVG_MICROCANONICAL_FIELDS

constexpr Field energy_inputs[] = {canonical_inputs[0], canonical_inputs[1], energy_field,
                                   canonical_inputs[3], canonical_inputs[4], canonical_inputs[5]};
constexpr Field excitation_inputs[] = {canonical_inputs[0], canonical_inputs[1], excitation_field,
                                       canonical_inputs[3], canonical_inputs[4],
                                       canonical_inputs[5]};

// ---------------------------------------------------------------- the run diagnostics

constexpr Field torus_run_table[] = {
    {"points_per_dim", K::count, one, "torus: n, the nodes per angle of the final level"},
    {"levels", K::count, one, "the refinement levels evaluated"},
    {"grid_points", K::count, one, "n^(N-1), the nodes of the final level (before the mirror halving)"},
};

constexpr Field qmc_run_table[] = {
    {"points", K::count, one, "qmc: the lattice points per shift"},
    {"shifts", K::count, one, "the independent random shifts"},
    {"sigmas", K::real, one,
     "the errors are sigmas times the jackknife standard error over the shifts (by default the "
     "99.9% two-sided Student-t quantile)"},
    {"effective_sample_fraction", K::real, one,
     "(sum w)^2 / (n sum w^2) of the weights of all points * shifts samples (Kish)"},
};

constexpr Field transfer_run_table[] = {
    {"angle_nodes", K::count, one, "transfer: n, the nodes per angle of the final level"},
    {"pivot_nodes", K::count, one, "m, the Chebyshev nodes per pivot u_j of the final level"},
    {"levels", K::count, one, "the levels evaluated (the angle ladder and the pivot checks)"},
};

// ---------------------------------------------------------------- simulate and poincare

constexpr Field simulation_inputs[] = {
    canonical_inputs[0], canonical_inputs[3], canonical_inputs[4], canonical_inputs[5],
    {"ensemble", K::text, one,
     "microcanonical (no thermostat: the energy is conserved) or canonical (Langevin at beta)"},
    {"integrator", K::text, one,
     "the scheme: yoshida6, yoshida4, suzuki4, kahan-li6, rattle2 or baoab-rattle (Langevin)"},
    {"dt", K::real, one, "the time step"},
    {"beta", K::real, one, "Langevin: the bath's inverse temperature (empty without a thermostat)"},
    {"friction", K::real, one, "Langevin: the friction gamma (empty without a thermostat)"},
};

constexpr std::string_view statistical_kind = "what the error promises: statistical (1 sigma)";

constexpr Field simulation_table[] = {
    {"time", K::real, one, "the averaging time simulated (summed over replicas)"},
    {"energy", K::real, one, "E of the initial state"},
    {"K", K::real, each, "<K_i> over time: the mean kinetic energy of particle i"},
    {"K_error", K::error, each, "its error bar (one standard error, from blocking)"},
    {"K_error_kind", K::text, one, statistical_kind},
    {"Kc", K::real, each, "<K_i^(c)> over time, K_i^(c) = p_i phidot_i / 2"},
    {"Kc_error", K::error, each, "its error bar"},
    {"Kc_error_kind", K::text, one, statistical_kind},
    {"K_autocorrelation_time", K::real, each, "the integrated autocorrelation time of K_i"},
    {"cos_phi", K::real, each, "<cos phi_i> over time"},
    {"cos_phi_error", K::error, each, "its error bar"},
    {"cos_phi_error_kind", K::text, one, statistical_kind},
    {"K_total", K::real, one, "<K> over time"},
    {"K_total_error", K::error, one, "its error bar"},
    {"K_total_error_kind", K::text, one, statistical_kind},
    {"potential", K::real, one, "<U> over time"},
    {"potential_error", K::error, one, "its error bar"},
    {"potential_error_kind", K::text, one, statistical_kind},
    {"error_reason", K::text, one, "why error bars are empty (too few blocks finished)"},
    {"exact_method", K::text, one, "the method of the exact values (empty with --exact no)"},
    {"exact_excitation", K::real, one,
     "microcanonical: D = E - E_min of the initial state, where the exact values are taken"},
    {"exact_K", K::real, each, "the exact <K_i> of the run's ensemble"},
    {"exact_K_error", K::error, each, "its absolute error"},
    {"exact_K_error_kind", K::text, one, "what exact_K_error promises"},
    {"exact_Kc", K::real, one, "the exact <K_i^(c)> (the same for every particle)"},
    {"exact_Kc_error", K::error, one, "its absolute error"},
    {"exact_Kc_error_kind", K::text, one, "what exact_Kc_error promises"},
    {"exact_cos_phi", K::real, each, "the exact <cos phi_i>"},
    {"exact_cos_phi_error", K::error, each, "its absolute error"},
    {"exact_cos_phi_error_kind", K::text, one, "what exact_cos_phi_error promises"},
    {"exact_var_K", K::real, each, "the exact Var K_i (energy units squared)"},
    {"exact_var_K_error", K::error, each, "its absolute error"},
    {"exact_var_K_error_kind", K::text, one, "what exact_var_K_error promises"},
    {"exact_var_K_reason", K::text, one, "why exact_var_K is empty (outside double's range)"},
    {"K_deviation_sigmas", K::real, each,
     "(K_i - exact_K_i) / hypot(K_error_i, exact_K_error_i)"},
    {"energy_drift", K::real, one, "(E(T) - E(0)) / the energy scale (sum m) g (sum l)"},
    {"energy_error_max", K::error, one, "max_t |E(t) - E(0)| / the energy scale"},
    {"energy_error_rms", K::error, one, "the root mean square of (E(t) - E(0)) / the energy scale"},
    {"energy_trend", K::real, one,
     "no thermostat: the least-squares change of E over the run / the energy scale"},
    {"energy_trend_reason", K::text, one, "why energy_trend is empty (a Langevin run)"},
    {"constraint_residual", K::error, one, "max over the run of max_i | |r_i| - l_i | / l_i"},
    {"steps", K::count, one, "time steps taken (summed over replicas)"},
    {"samples", K::count, one, "samples averaged (summed over replicas)"},
    {"newton_solves", K::count, one, "Newton solves of the constraints (summed over replicas)"},
    {"unconverged_stages", K::count, one, "constraint solves that did not converge"},
    {"interrupted", K::flag, one, "true: stopped early by a signal; the averages so far"},
};

constexpr Field replica_table[] = {
    {"replicas", K::count, one, "the replicas that finished (also when interrupted)"},
    {"replicas_requested", K::count, one, "the replicas asked for (--replicas)"},
    {"replica_time", K::real, one, "each replica's averaging time (--time)"},
    {"replica_energy_spread", K::error, one, "the largest |E_r - E| over the replicas"},
    {"K_error_blocking", K::error, each, "the blocking error of the pooled <K_i>"},
    {"K_error_replicas", K::error, each, "the standard error of the spread between replicas"},
    {"Kc_error_blocking", K::error, each, "the same for <K_i^(c)>"},
    {"Kc_error_replicas", K::error, each, "the same for <K_i^(c)>"},
    {"cos_phi_error_blocking", K::error, each, "the same for <cos phi_i>"},
    {"cos_phi_error_replicas", K::error, each, "the same for <cos phi_i>"},
    {"K_total_error_blocking", K::error, one, "the same for <K>"},
    {"K_total_error_replicas", K::error, one, "the same for <K>"},
    {"potential_error_blocking", K::error, one, "the same for <U>"},
    {"potential_error_replicas", K::error, one, "the same for <U>"},
    {"replicas_error_reason", K::text, one, "why the replicas' errors are empty"},
};

constexpr Field poincare_table[] = {
    canonical_inputs[0], canonical_inputs[3], canonical_inputs[4], canonical_inputs[5],
    {"energy", K::real, one, "the energy E of every orbit"},
    {"orbits", K::count, one, "orbits started on the section"},
    {"points_per_orbit", K::count, one, "crossings asked for per orbit"},
    {"dt", K::real, one, "the time step"},
    {"steps", K::count, one, "time steps taken (all orbits)"},
    {"energy_error_max", K::error, one, "max over the orbits of |E(t) - E| / (sum m) g (sum l)"},
    {"interrupted", K::flag, one, "true: stopped early by a signal; the points so far"},
};

constexpr Field section_point_table[] = {
    {"orbit", K::count, one, "the orbit (0-based)"},
    {"phi2", K::real, one, "phi_2 in (-pi, pi] where the orbit crosses phi_1 = 0 upward"},
    {"p2", K::real, one, "the canonical momentum p_2 there"},
    {"time", K::real, one, "the time of the crossing"},
};

constexpr Field orbit_start_table[] = {
    {"start_phi2", K::real, one, "phi_2 where the orbit starts on the section"},
    {"start_p2", K::real, one, "p_2 where the orbit starts on the section"},
};

constexpr Field trajectory_table[] = {
    {"t", K::real, one, "the time"},
    {"E", K::real, one, "the total energy (its drift from E(0) measures the integration error)"},
    {"phi", K::real, each, "the angle phi_i of link i from the downward vertical"},
    {"phidot", K::real, each, "the angular velocity dphi_i/dt"},
};

// ---------------------------------------------------------------- series

constexpr Field series_run_table[] = {
    {"terms", K::count, one, "the rows (terms summed)"},
    {"certified", K::flag, one, "true: the last bound certifies the requested digits"},
    {"beta_K1_error_kind", K::text, one, "what beta_K1_error promises: bound"},
};

constexpr Field series_row_table[] = {
    {"n", K::count, one, "the term's index"},
    {"R_n", K::real, one, "R_n(a1, a2), scaled by exp(-(a1 + a2))"},
    {"term", K::real, one, "c_n mu2^n R_n, the n-th numerator term (scaled)"},
    {"numerator", K::real, one, "the numerator's partial sum (scaled)"},
    {"denominator", K::real, one, "the denominator's partial sum (scaled)"},
    {"beta_K1", K::real, one, "beta<K1> summed to term n: (mu1/2) numerator / denominator"},
    {"beta_K1_error", K::error, one,
     "the rigorous bound on |beta<K1> - beta_K1| from the tails (empty while none exists)"},
};

constexpr NamedTable tables[] = {
    {"canonical inputs", canonical_inputs},
    {"chain inputs (limit)", chain_inputs},
    {"microcanonical inputs (--energy)", energy_inputs},
    {"microcanonical inputs (--excitation)", excitation_inputs},
    {"canonical averages", averages_table},
    {"torus run (the run of canonical averages and limits by a torus rule)", torus_run_table},
    {"qmc run (the run of canonical averages by qmc)", qmc_run_table},
    {"transfer run (the run of canonical averages and limits by the transfer operator)",
     transfer_run_table},
    {"microcanonical averages (after --energy)", microcanonical_after_energy},
    {"microcanonical averages (after --excitation)", microcanonical_after_excitation},
    {"simulation inputs", simulation_inputs},
    {"simulation", simulation_table},
    {"simulation replicas", replica_table},
    {"poincare section", poincare_table},
    {"section point", section_point_table},
    {"orbit start (Python's PoincareSection; the CLI prints the crossings)", orbit_start_table},
    {"trajectory (simulate --trajectory FILE --every K; Python's SimulationResult.trajectory)",
     trajectory_table},
    {"series run (after the canonical inputs)", series_run_table},
    {"series row", series_row_table},
};

// ---------------------------------------------------------------- cells

/// An MPFR run's number behind the next cell, when the record keeps them (a double run's cells
/// hold their doubles).
template <class Real>
void keep_exact(Record& r, const Real& x) {
  if constexpr (!std::is_same_v<Real, double>) {
    if (r.keeps_exact()) r.set_exact(exact_number(x));
  } else {
    (void)r;
    (void)x;
  }
}

template <class Real>
void put_value(Record& r, const Real& v, Printing p) {
  if constexpr (std::is_same_v<Real, double>) {
    if (p.texts) r.shortest(v);
    else r.number(v);
  } else {
    keep_exact(r, v);
    char* at = r.decimal_room(decimal_max_length(p.digits));
    r.commit_decimal(write_decimal(at, v, p.digits));
  }
}

/// The error of a value printed by put_value, covering the printed text: a double run adds
/// `gap` (printing_gap of the value's shortest text: 0 when it is the double's exact decimal),
/// an MPFR run what printing with p.digits digits moves the value by (printed_error).
template <class Real>
void put_error(Record& r, const Real& value, const Real& e, Printing p, double gap = 0) {
  if constexpr (std::is_same_v<Real, double>) {
    (void)value;
    r.error(e, p.texts ? gap : deferred_gap);  // printed as e + gap rounded up (covering)
  } else {
    keep_exact(r, e);
    char* at = r.decimal_room(decimal_max_length(error_digits));
    r.commit_decimal(write_error(at, printed_error(value, e, p.digits)));
  }
}

/// Values of a per-particle field (none past the end: an engine that left it out).
template <class Real>
void put_values(Record& r, const std::vector<Estimate<Real>>& es, std::size_t n, Printing p) {
  for (std::size_t i = 0; i < n; ++i) {
    if (i < es.size()) put_value(r, es[i].value, p);
    else r.none();
  }
}

/// The printing gap of the value k cells back (put_value's, just before its error).
double gap_back(const Record& r, std::size_t k) {
  return r.cells()[r.cells().size() - k].gap;
}

/// The errors of the n values put_values wrote just before.
template <class Real>
void put_errors(Record& r, const std::vector<Estimate<Real>>& es, std::size_t n, Printing p) {
  for (std::size_t i = 0; i < n; ++i) {
    if (i < es.size()) put_error(r, es[i].value, es[i].error, p, gap_back(r, n));
    else r.none();
  }
}

/// value / divisor and its error (error / divisor plus the quotient's rounding): a double run
/// divides in long double (beta < 1e-154 leaves double's range for Var K_i's divisor) and rounds
/// to double; a quotient outside double's normal range is refused rather than printed as 0.
template <class Real>
void put_quotients(Record& r, const std::vector<Estimate<Real>>& es, std::size_t n,
                   const quotient_t<Real>& divisor, Printing p, bool errors) {
  using Wide = quotient_t<Real>;
  for (std::size_t i = 0; i < n; ++i) {
    if (i >= es.size()) {
      r.none();
      continue;
    }
    const Wide q = Wide(es[i].value) / divisor;
    Wide e = Wide(es[i].error) / divisor;
    if constexpr (std::is_same_v<Real, double>) {
      const double qd = static_cast<double>(q);
      if (es[i].value != 0 && !std::isnormal(qd))
        throw invalid_input("<K_i> = beta<K_i>/beta or Var K_i = beta^2 Var K_i/beta^2 is " +
                            short_decimal(q) +
                            ", outside double's normal range (2.2e-308..1.8e308) at this beta");
      if (!errors) {
        if (p.texts) r.shortest(qd);
        else r.number(qd);
        continue;
      }
      // the division in long double and the rounding to double: < 2^-52 |qd|; then the
      // printing of qd (its value cell is n cells back)
      e += std::fabs(static_cast<long double>(qd)) * std::ldexp(1.0L, -52);
      double ed = static_cast<double>(e);
      if (static_cast<long double>(ed) < e) ed = std::nextafter(ed, HUGE_VAL);
      put_error(r, qd, ed, p, gap_back(r, n));
    } else {
      if (!errors) {
        put_value(r, q, p);
        continue;
      }
      // the quotient's rounding in MPFR: <= 2^(1-prec) |q|
      Real rounding = abs(q);
      mpfr_mul_2si(rounding.backend().data(), rounding.backend().data(),
                   1 - static_cast<long>(mpfr_get_prec(q.backend().data())), MPFR_RNDU);
      put_error(r, q, Real(e + rounding), p);
    }
  }
}

template <class Real>
ErrorKind kind_of(const std::vector<Estimate<Real>>& es, ErrorKind fallback) {
  return es.empty() ? fallback : es.front().kind;
}

/// An input: as written in an MPFR run (when given), else the number it was read as.
template <class Real>
void put_input(Record& r, const Real& value, std::span<const std::string_view> texts,
               std::size_t k, Printing p) {
  if (k < texts.size()) {
    keep_exact(r, value);
    if constexpr (std::is_same_v<Real, double>) r.input(value, texts[k]);
    else r.decimal(texts[k]);
    return;
  }
  put_value(r, value, p);
}

/// g, m_i, l_i; cells past the chain's N (a table row shorter than its widest) are empty.
template <class Real>
void put_chain(Record& r, const Chain<Real>& chain, std::span<const std::string_view> texts,
               std::size_t first, Printing p) {
  const std::size_t n = chain.size();
  put_input(r, chain.gravity(), texts, first, p);
  for (std::size_t i = 0; i < r.particles(); ++i) {
    if (i < n) put_input(r, chain.mass(i), texts, first + 1 + i, p);
    else r.none();
  }
  for (std::size_t i = 0; i < r.particles(); ++i) {
    if (i < n) put_input(r, chain.length(i), texts, first + 1 + n + i, p);
    else r.none();
  }
}

}  // namespace

ExactNumber exact_number(const mpfr_real& x) {
  ExactNumber out;
  const mpfr_srcptr p = x.backend().data();
  out.rounded = mpfr_get_d(p, MPFR_RNDN);
  if (!mpfr_number_p(p)) {
    out.finite = false;
    out.mantissa.push_back('0');
    return out;
  }
  if (mpfr_zero_p(p)) {
    out.mantissa.push_back('0');
    return out;
  }
  mpz_t mantissa;
  mpz_init(mantissa);
  out.exponent = static_cast<long>(mpfr_get_z_2exp(mantissa, p));
  char* digits = mpz_get_str(nullptr, 16, mantissa);
  const std::size_t length = std::strlen(digits);
  out.mantissa.assign(digits, length);
  void (*release)(void*, size_t) = nullptr;
  mp_get_memory_functions(nullptr, nullptr, &release);
  release(digits, length + 1);
  mpz_clear(mantissa);
  return out;
}

std::span<const Field> canonical_input_fields() { return canonical_inputs; }
std::span<const Field> chain_input_fields() { return chain_inputs; }
std::span<const Field> averages_fields() { return averages_table; }
std::span<const Field> microcanonical_input_fields(std::string_view state) {
  if (state == "energy") return energy_inputs;
  if (state == "excitation") return excitation_inputs;
  throw std::logic_error("pendavg internal error: microcanonical state " + std::string(state));
}
std::span<const Field> microcanonical_fields(std::string_view state) {
  return state == "energy" ? std::span<const Field>(microcanonical_after_energy)
                           : std::span<const Field>(microcanonical_after_excitation);
}
std::span<const NamedTable> all_tables() { return tables; }

std::span<const Field> torus_run_fields() { return torus_run_table; }
std::span<const Field> qmc_run_fields() { return qmc_run_table; }
std::span<const Field> transfer_run_fields() { return transfer_run_table; }

template <class Real>
std::span<const Field> run_fields(const Averages<Real>& a) {
  if (a.torus) return torus_run_table;
  if (a.qmc) return qmc_run_table;
  if (a.transfer) return transfer_run_table;
  return {};
}

template <class Real>
void append_run(Record& r, const Averages<Real>& a) {
  const auto count = [&](std::size_t n) { r.integer(static_cast<long long>(n)); };
  if (a.torus) {
    count(a.torus->points_per_dim);
    count(a.torus->levels);
    r.integer(static_cast<long long>(a.torus->grid_points));  // (at most max_grid_points, 1e9)
  } else if (a.qmc) {
    count(a.qmc->points);
    count(a.qmc->shifts);
    r.number(a.qmc->sigmas);
    r.number(static_cast<double>(a.qmc->effective_sample_fraction));  // (qmc runs in double)
  } else if (a.transfer) {
    count(a.transfer->angle_nodes);
    count(a.transfer->pivot_nodes);
    count(a.transfer->levels);
  }
  r.complete();
}
template <class Real>
void append_canonical_inputs(Record& r, const Chain<Real>& chain, const Real& beta,
                             Printing p, std::span<const std::string_view> texts) {
  r.integer(static_cast<long long>(chain.size()));
  r.integer(p.digits);
  put_input(r, beta, texts, 0, p);
  put_chain(r, chain, texts, 1, p);
}

template <class Real>
void append_chain_inputs(Record& r, const Chain<Real>& chain, Printing p,
                                  std::span<const std::string_view> texts) {
  r.integer(static_cast<long long>(chain.size()));
  r.integer(p.digits);
  put_chain(r, chain, texts, 0, p);
}

template <class Real>
void append_microcanonical_inputs(Record& r, const Chain<Real>& chain, const Real& state,
                                  Printing p, std::span<const std::string_view> texts) {
  r.integer(static_cast<long long>(chain.size()));
  r.integer(p.digits);
  put_input(r, state, texts, 0, p);
  put_chain(r, chain, texts, 1, p);
}

template <class Real>
void append_averages(Record& r, const Averages<Real>& a, const Real* beta, Printing p) {
  const std::size_t n = r.particles();  // cells per particle field; beyond the chain's N, empty
  // An error is printed rounded up, after printed_error added what printing the value moved it
  // by: a bound (certified, Method::certified_integral) stays a bound.
  const auto errors = [&](const std::vector<Estimate<Real>>& es) { put_errors(r, es, n, p); };
  const auto kind = [&](ErrorKind k) { r.name(error_kind_name(k)); };
  r.name(method_name(a.method));
  put_values(r, a.beta_kinetic, n, p);
  errors(a.beta_kinetic);
  kind(a.error_kind);
  using Wide = quotient_t<Real>;
  if (beta) {
    const Wide b = Wide(*beta);
    put_quotients(r, a.beta_kinetic, n, b, p, false);
    put_quotients(r, a.beta_kinetic, n, b, p, true);
  } else {
    for (std::size_t i = 0; i < 2 * n; ++i) r.none();
  }
  if (beta) kind(a.error_kind);
  else r.none();
  if (a.ratio) {
    put_value(r, a.ratio->value, p);
    put_error(r, a.ratio->value, a.ratio->error, p, gap_back(r, 1));
  } else {
    r.none();
    r.none();
  }
  if (a.ratio) kind(a.error_kind);
  else r.none();
  put_values(r, a.cos_angle, n, p);
  errors(a.cos_angle);
  kind(kind_of(a.cos_angle, a.error_kind));
  if (beta) {
    const Wide b2 = Wide(*beta) * Wide(*beta);
    put_quotients(r, a.beta2_kinetic_variance, n, b2, p, false);
    put_quotients(r, a.beta2_kinetic_variance, n, b2, p, true);
  } else {
    for (std::size_t i = 0; i < 2 * n; ++i) r.none();
  }
  if (beta) kind(kind_of(a.beta2_kinetic_variance, a.error_kind));
  else r.none();
  put_values(r, a.beta2_kinetic_variance, n, p);
  errors(a.beta2_kinetic_variance);
  kind(kind_of(a.beta2_kinetic_variance, a.error_kind));
  put_values(r, a.beta_kinetic_canonical, n, p);
  errors(a.beta_kinetic_canonical);
  kind(kind_of(a.beta_kinetic_canonical, ErrorKind::bound));
  for (std::size_t i = 0; i < n; ++i) {
    if (i < a.diagonal_approximation.size()) put_value(r, a.diagonal_approximation[i], p);
    else r.none();
  }
  if constexpr (std::is_same_v<Real, double>) {
    r.number(a.equipartition_residual);
  } else {
    keep_exact(r, a.equipartition_residual);
    char* at = r.decimal_room(decimal_max_length(error_digits));
    r.commit_decimal(write_error(at, a.equipartition_residual));
  }
  r.integer(static_cast<long long>(a.evaluations));
  r.name(work_unit_name(a.work_unit));
  r.flag(a.converged);
  r.flag(a.interrupted);
  r.complete();
}

template <class Real>
void append_microcanonical(Record& r, const MicrocanonicalAverages<Real>& a, Printing p) {
  const std::size_t n = r.particles();  // cells per particle field; beyond the chain's N, empty
  const auto kind = [&] { r.name(error_kind_name(a.error_kind)); };
  const auto scalar = [&](const Estimate<Real>& e) {
    put_value(r, e.value, p);
    put_error(r, e.value, e.error, p, gap_back(r, 1));
    kind();
  };
  const auto array = [&](const std::vector<Estimate<Real>>& es) {
    put_values(r, es, n, p);
    put_errors(r, es, n, p);
    kind();
  };
  // the state not given (the table's first field)
  put_value(r, r.fields()[0].name == "energy" ? a.energy : a.excitation, p);
  r.name("microcanonical");
  r.name(method_name(a.quadrature));
  array(a.kinetic);
  scalar(a.kinetic_canonical);
  array(a.cos_angle);
  array(a.kinetic_variance);
  scalar(a.kinetic_total);
  scalar(a.density_of_states);
  if (a.quadrature == Method::qmc) {
    put_value(r, a.proposal_beta, p);
    put_value(r, a.effective_sample_fraction, p);
  } else {
    r.none();
    r.none();
  }
  r.integer(static_cast<long long>(a.evaluations));
  r.name(work_unit_name(a.work_unit));
  r.flag(a.converged);
  r.complete();
}

std::string schema_text() {
  std::string out =
      "Output schema " + std::to_string(schema_version) +
      " of pendavg: one name per concept in JSON, CSV, text and Python.\n"
      "- A value X has X_error (its absolute error, 3 significant digits rounded up: never\n"
      "  below the computed error) and X_error_kind: bound (proven), estimate (from\n"
      "  refinement, checked against independent methods) or statistical (qmc: the 99.9%\n"
      "  Student-t interval over the random shifts; time averages: 1 standard error).\n"
      "- A per-particle field X is a JSON array [X_1, ..., X_N] and the CSV columns X1..XN;\n"
      "  its errors are X1_error..XN_error.\n"
      "- JSON: a run in double (16 digits) writes every real as a JSON number, the shortest\n"
      "  decimal that reads back as the same double; an MPFR run (more digits) writes reals as\n"
      "  decimal strings with the digits asked for. A value that does not exist is null (an\n"
      "  empty CSV cell). JSON starts with \"schema\": " +
      std::to_string(schema_version) + ", CSV with the line `# schema: " +
      std::to_string(schema_version) +
      "`.\n"
      "- Inputs in CSV and text are printed as written; in JSON as read.\n";
  constexpr const char* kinds[] = {"real", "error", "count", "text", "flag"};
  for (const NamedTable& table : all_tables()) {
    out += "\n## " + std::string(table.result) + "\n\n| name | kind | per particle | meaning |\n";
    out += "|---|---|---|---|\n";
    for (const Field& f : table.fields)
      out += "| " + std::string(f.name) + " | " + kinds[static_cast<int>(f.kind)] + " | " +
             (f.shape == Shape::per_particle ? "yes" : "") + " | " + std::string(f.meaning) +
             " |\n";
  }
  return out;
}

std::string migration_text() {
  std::string out = "Schema 0 (pendavg 0.2) -> schema " + std::to_string(schema_version) +
                    ": renamed keys and columns. `average --cases --columns` still accepts the "
                    "old column names (printed under their old headers).\n\n"
                    "Also: every command's default --format is csv (average and limit wrote json);\n"
                    "JSON reals of a double run are numbers (they were strings); a double run\n"
                    "prints each value exactly, as the shortest decimal of the double (it printed\n"
                    "16 significant digits), and its errors no longer add half a unit of that\n"
                    "16th digit; every error is rounded up to 3 digits (it was rounded to\n"
                    "nearest); new fields: K_error_kind, ratio_error_kind, beta2_var_K (in\n"
                    "average, table, --cases), beta_Kc_error (average JSON), interrupted, g, m, l\n"
                    "(average, limit).\n\n"
                    "| schema 0 | schema 1 | where |\n|---|---|---|\n";
  for (const Rename& r : schema0_renames()) {
    const std::string old_name =
        std::string(r.old_name) + (r.per_particle ? std::string("1..N") : std::string());
    std::string new_name(r.new_name);
    if (r.per_particle)
      new_name = column_name(Field{r.new_name, Kind::real, Shape::per_particle, {}}, 0) + "..";
    out += "| " + old_name + " | " + new_name + " | " + std::string(r.where) + " |\n";
  }
  return out;
}

// ---------------------------------------------------------------- simulate and poincare

std::span<const Field> simulation_input_fields() { return simulation_inputs; }
std::span<const Field> simulation_fields() { return simulation_table; }
std::span<const Field> replica_fields() { return replica_table; }
std::span<const Field> poincare_fields() { return poincare_table; }
std::span<const Field> section_point_fields() { return section_point_table; }
std::span<const Field> orbit_start_fields() { return orbit_start_table; }
std::span<const Field> trajectory_fields() { return trajectory_table; }

namespace {

/// A value of a trajectory: absent (null) when it does not exist (NaN: an unknown error bar).
void put_finite(Record& r, double x) {
  if (std::isfinite(x)) r.number(x);
  else r.none();
}

/// An error beside `value`: absent when either does not exist.
void put_error_of(Record& r, double value, double error) {
  if (std::isfinite(value) && std::isfinite(error)) r.number(error);
  else r.none();
}

void put_reason(Record& r, bool applies, std::string_view reason) {
  if (applies) r.text(reason);
  else r.none();
}

}  // namespace

void append_simulation_inputs(Record& r, const Chain<double>& chain, const SimulationOptions& run,
                              std::string_view integrator, std::span<const std::string_view> texts) {
  const bool langevin = run.thermostat == Thermostat::langevin;
  r.integer(static_cast<long long>(chain.size()));
  put_chain(r, chain, texts, 0, Printing{});
  r.text(langevin ? "canonical" : "microcanonical");
  r.text(integrator);
  r.number(run.time_step);
  if (langevin && run.beta) r.number(*run.beta);
  else r.none();
  if (langevin) r.number(run.friction.value_or(1));
  else r.none();
  r.complete();
}

void append_simulation(Record& r, const SimulationResult<double>& s, double energy,
                       const io::ExactValues* exact, bool langevin) {
  const std::size_t n = r.particles();
  const std::string_view statistical = error_kind_name(ErrorKind::statistical);
  const auto averages = [&](const std::vector<TimeAverage<double>>& xs) {
    for (std::size_t i = 0; i < n; ++i) put_finite(r, i < xs.size() ? xs[i].value : NAN);
    for (std::size_t i = 0; i < n; ++i)
      if (i < xs.size()) put_error_of(r, xs[i].value, xs[i].error);
      else r.none();
    r.text(statistical);
  };
  const auto average = [&](const TimeAverage<double>& x) {
    put_finite(r, x.value);
    put_error_of(r, x.value, x.error);
    r.text(statistical);
  };
  r.number(s.simulated_time);
  r.number(energy);
  averages(s.kinetic);
  averages(s.kinetic_canonical);
  for (std::size_t i = 0; i < n; ++i)
    put_finite(r, i < s.kinetic.size() ? s.kinetic[i].autocorrelation_time : NAN);
  averages(s.cos_angle);
  average(s.kinetic_total);
  average(s.potential);
  bool unknown = false;
  for (const auto* list : {&s.kinetic, &s.kinetic_canonical, &s.cos_angle})
    for (const TimeAverage<double>& x : *list) unknown = unknown || !std::isfinite(x.error);
  put_reason(r, unknown,
             "fewer than 16 averaging blocks finished (an early interrupt or a run time too short "
             "for the block length): the error bars are unknown");
  // the exact values (all empty with --exact no)
  const auto values = [&](const std::vector<double>* v, const std::vector<double>* e,
                          const std::string* kind) {
    for (std::size_t i = 0; i < n; ++i) put_finite(r, v && i < v->size() ? (*v)[i] : NAN);
    for (std::size_t i = 0; i < n; ++i)
      if (v && i < v->size()) put_error_of(r, (*v)[i], (*e)[i]);
      else r.none();
    if (kind) r.text(*kind);
    else r.none();
  };
  const io::ExactValues* x = exact;
  if (x) r.text(x->method);
  else r.none();
  if (x && !langevin) r.number(x->excitation);
  else r.none();
  values(x ? &x->kinetic : nullptr, x ? &x->kinetic_error : nullptr,
         x ? &x->error_kind : nullptr);
  if (x) {
    put_finite(r, x->kinetic_canonical);
    put_error_of(r, x->kinetic_canonical, x->kinetic_canonical_error);
    r.text(x->kinetic_canonical_error_kind);
  } else {
    r.none();
    r.none();
    r.none();
  }
  values(x ? &x->cos_angle : nullptr, x ? &x->cos_angle_error : nullptr,
         x ? &x->cos_angle_error_kind : nullptr);
  values(x ? &x->variance : nullptr, x ? &x->variance_error : nullptr,
         x ? &x->variance_error_kind : nullptr);
  put_reason(r, x && std::ranges::any_of(x->variance, [](double v) { return !std::isfinite(v); }),
             "Var K_i = beta^2 Var K_i / beta^2 is outside the double range at this beta");
  for (std::size_t i = 0; i < n; ++i) {
    if (!x || i >= s.kinetic.size()) {
      r.none();
      continue;
    }
    put_finite(r, (s.kinetic[i].value - x->kinetic[i]) /
                      std::hypot(s.kinetic[i].error, x->kinetic_error[i]));
  }
  // the energy diagnostics and the work
  put_finite(r, s.energy_drift);
  put_error_of(r, 0.0, s.energy_error_max);
  put_error_of(r, 0.0, s.energy_error_rms);
  if (langevin) r.none();
  else put_finite(r, s.energy_trend);
  put_reason(r, langevin,
             "a Langevin run exchanges energy with its bath: the trend of E(t) is reported for "
             "fixed-energy (NVE) runs only");
  put_error_of(r, 0.0, s.constraint_residual);
  r.integer(static_cast<long long>(s.steps));
  r.integer(static_cast<long long>(s.samples));
  r.integer(static_cast<long long>(s.newton_solves));
  r.integer(static_cast<long long>(s.unconverged_stages));
  r.flag(s.interrupted);
  r.complete();
}

void append_replicas(Record& r, const ReplicaSpread& spread, double replica_time) {
  const std::size_t n = r.particles();
  r.integer(static_cast<long long>(spread.replicas));
  r.integer(static_cast<long long>(spread.requested));
  r.number(replica_time);
  put_error_of(r, 0.0, spread.energy_spread);
  for (const std::vector<double>* v :
       {&spread.kinetic_blocking, &spread.kinetic_replicas, &spread.canonical_blocking,
        &spread.canonical_replicas, &spread.cosine_blocking, &spread.cosine_replicas})
    for (std::size_t i = 0; i < n; ++i) put_error_of(r, 0.0, i < v->size() ? (*v)[i] : NAN);
  for (const double e : {spread.total_blocking, spread.total_replicas, spread.potential_blocking,
                         spread.potential_replicas})
    put_error_of(r, 0.0, e);
  put_reason(r, spread.replicas < 2, "fewer than two replicas finished");
  r.complete();
}

void append_poincare(Record& r, const Chain<double>& chain, const PoincareOptions& options,
                     const PoincareSection<double>& section,
                     std::span<const std::string_view> texts) {
  r.integer(static_cast<long long>(chain.size()));
  // texts: the energy, then g, m1..mN, l1..lN (input_texts' order)
  put_chain(r, chain, texts, 1, Printing{});
  put_input(r, section.energy, texts, 0, Printing{});
  r.integer(static_cast<long long>(options.orbits));
  r.integer(static_cast<long long>(options.points));
  r.number(options.time_step);
  r.integer(static_cast<long long>(section.steps));
  put_error_of(r, 0.0, section.energy_error_max);
  r.flag(section.interrupted);
  r.complete();
}

void append_section_point(Record& r, const SectionPoint<double>& p) {
  r.integer(static_cast<long long>(p.orbit));
  r.number(p.phi2);
  r.number(p.p2);
  r.number(p.time);
  r.complete();
}

void append_orbit_start(Record& r, const PoincareSection<double>& section, std::size_t orbit) {
  r.number(section.start_phi2[orbit]);
  r.number(section.start_p2[orbit]);
  r.complete();
}

// ---------------------------------------------------------------- series

std::span<const Field> series_run_fields() { return series_run_table; }
std::span<const Field> series_row_fields() { return series_row_table; }

bool series_certifies(const std::vector<SeriesRow<mpfr_real>>& rows, int digits) {
  if (rows.empty()) return false;
  const SeriesRow<mpfr_real>& last = rows.back();
  return last.bound <= abs(last.beta_kinetic1) * pow(mpfr_real(10), -digits);
}

void append_series_run(Record& r, std::size_t terms, bool certified) {
  r.integer(static_cast<long long>(terms));
  r.flag(certified);
  r.text(error_kind_name(ErrorKind::bound));
  r.complete();
}

namespace {

/// x rounded to nearest double is 0 exactly when x is, and otherwise a normal double.
bool fits_double(const mpfr_real& x) {
  if (x == 0) return true;
  const double d = mpfr_get_d(x.backend().data(), MPFR_RNDN);
  return std::isnormal(d);
}

}  // namespace

bool series_fits_double(const std::vector<SeriesRow<mpfr_real>>& rows,
                        const Chain<mpfr_real>& chain, const mpfr_real& beta) {
  if (!fits_double(beta) || !fits_double(chain.gravity())) return false;
  for (std::size_t i = 0; i < chain.size(); ++i)
    if (!fits_double(chain.mass(i)) || !fits_double(chain.length(i))) return false;
  for (const SeriesRow<mpfr_real>& row : rows) {
    for (const mpfr_real* x :
         {&row.R_n, &row.term, &row.numerator, &row.denominator, &row.beta_kinetic1})
      if (!fits_double(*x)) return false;
    // the bound, rounded up (and enlarged by the value's rounding), must stay below DBL_MAX
    if (isfinite(row.bound) && !(row.bound < mpfr_real(1e300))) return false;
  }
  return true;
}

void append_series_row(Record& r, const SeriesRow<mpfr_real>& row, Printing p, bool doubles) {
  r.integer(static_cast<long long>(row.n));
  const mpfr_real* values[] = {&row.R_n, &row.term, &row.numerator, &row.denominator,
                               &row.beta_kinetic1};
  for (const mpfr_real* x : values) {
    if (doubles) {
      keep_exact(r, *x);  // (for a front end that keeps them: the value before its rounding)
      r.number(mpfr_get_d(x->backend().data(), MPFR_RNDN));
    } else {
      put_value(r, *x, p);
    }
  }
  if (!isfinite(row.bound)) {
    r.none();  // no bound yet
  } else if (doubles) {
    // the bound plus the rounding of beta_K1 to double, rounded up: it covers the printed value
    const mpfr_real& v = row.beta_kinetic1;
    const mpfr_real rounded(mpfr_get_d(v.backend().data(), MPFR_RNDN));
    const mpfr_real e = row.bound + abs(v - rounded);
    keep_exact(r, e);
    r.number(mpfr_get_d(e.backend().data(), MPFR_RNDU));
  } else {
    put_error(r, row.beta_kinetic1, row.bound, p);
  }
  r.complete();
}

#define PENDAVG_IO_RESULTS(Real)                                                                 \
  template void append_canonical_inputs<Real>(Record&, const Chain<Real>&, const Real&, Printing, \
                                              std::span<const std::string_view>);                \
  template void append_chain_inputs<Real>(Record&, const Chain<Real>&, Printing,        \
                                                   std::span<const std::string_view>);           \
  template void append_microcanonical_inputs<Real>(Record&, const Chain<Real>&, const Real&,      \
                                                   Printing, std::span<const std::string_view>); \
  template void append_averages<Real>(Record&, const Averages<Real>&, const Real*, Printing);    \
  template void append_microcanonical<Real>(Record&, const MicrocanonicalAverages<Real>&, Printing); \
  template std::span<const Field> run_fields<Real>(const Averages<Real>&);                        \
  template void append_run<Real>(Record&, const Averages<Real>&);
PENDAVG_IO_RESULTS(double)
PENDAVG_IO_RESULTS(mpfr_real)
#undef PENDAVG_IO_RESULTS

}  // namespace pendavg::io
