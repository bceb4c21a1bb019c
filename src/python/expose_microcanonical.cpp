// SPDX-License-Identifier: GPL-3.0-or-later
// src/python/expose_microcanonical.cpp -- pendavg.microcanonical: exact fixed-energy averages
// <K_i>_E, <K_i^(c)>_E, <cos phi_i>_E, Var K_i and the density of states
// (pendavg/microcanonical.hpp), as `pendavg average --energy E | --excitation D
// [--digits D]` computes them (src/cli/commands.cpp, microcanonical_one): the options read by the
// CLI's reader and turned into MicrocanonicalOptions by the library
// (microcanonical_options(AverageOptions, N)); in double the chain from the same doubles, with
// digits 17..1000 (integral rule N <= 4, torus-trapezoid N <= 2) everything parsed and computed
// in MPFR under the working precision, as the CLI does; the CLI's strings from
// cli::microcanonical_text. So every number is the library's, bit for bit.
//
// The library's microcanonical run takes no RunControl: it reports no progress and cannot be
// stopped, so it runs with the GIL released and a Ctrl-C is raised when it returns.
#include "bindings.hpp"
#include "exact.hpp"
#include "inputs.hpp"

#include "cli/average_options.hpp"
#include "cli/format.hpp"

#include "pendavg/mpfr.hpp"
#include "pendavg/pendavg.hpp"

#include <pybind11/numpy.h>
#include <pybind11/stl.h>

#include <array>
#include <cmath>
#include <string>
#include <vector>

namespace pendavg::python {

namespace {

using cli::Domain;

/// The exact values of an MPFR run (per particle: K, cos_phi, var_K and their errors).
constexpr std::array<const char*, 16> exact_fields{
    "energy",  "excitation",    "K",       "K_error",       "Kc",
    "Kc_error", "K_total",      "K_total_error", "cos_phi", "cos_phi_error",
    "var_K",   "var_K_error",   "density_of_states", "density_of_states_error",
    "proposal_beta", "effective_sample_fraction"};

/// Everything of one run that outlives an MPFR working precision.
struct MicrocanonicalRecord {
  std::size_t particles = 0;
  int digits = 16;
  MicrocanonicalAverages<double> values;  ///< the library's result; an MPFR run's rounded
  cli::MicrocanonicalText text;           ///< the CLI's strings
  std::vector<std::vector<ExactNumber>> exact;  ///< MPFR: exact_fields
  double seconds = 0;
};

Estimate<double> rounded(const Estimate<mpfr_real>& e) {
  return {static_cast<double>(e.value), static_cast<double>(e.error), e.kind};
}

std::vector<Estimate<double>> rounded(const std::vector<Estimate<mpfr_real>>& v) {
  std::vector<Estimate<double>> out;
  for (const auto& e : v) out.push_back(rounded(e));
  return out;
}

MicrocanonicalAverages<double> rounded(const MicrocanonicalAverages<mpfr_real>& a) {
  MicrocanonicalAverages<double> d;
  d.energy = static_cast<double>(a.energy);
  d.excitation = static_cast<double>(a.excitation);
  d.kinetic = rounded(a.kinetic);
  d.kinetic_canonical = rounded(a.kinetic_canonical);
  d.kinetic_total = rounded(a.kinetic_total);
  d.cos_angle = rounded(a.cos_angle);
  d.kinetic_variance = rounded(a.kinetic_variance);
  d.density_of_states = rounded(a.density_of_states);
  d.method = a.method;
  d.quadrature = a.quadrature;
  d.error_kind = a.error_kind;
  d.evaluations = a.evaluations;
  d.work_unit = a.work_unit;
  d.converged = a.converged;
  d.proposal_beta = static_cast<double>(a.proposal_beta);
  d.effective_sample_fraction = static_cast<double>(a.effective_sample_fraction);
  return d;
}

/// Keeps an MPFR result's doubles, strings and exact values. Runs under the working precision.
void keep_mpfr(MicrocanonicalRecord& out, const MicrocanonicalAverages<mpfr_real>& a) {
  out.values = rounded(a);
  out.text = cli::microcanonical_text(a, out.digits);
  out.exact.assign(exact_fields.size(), {});
  const auto keep = [&](std::size_t field, const mpfr_real& x) {
    out.exact[field].push_back(exact_number(x));
  };
  const auto keep_estimate = [&](std::size_t field, const Estimate<mpfr_real>& e) {
    keep(field, e.value);
    keep(field + 1, e.error);
  };
  keep(0, a.energy);
  keep(1, a.excitation);
  for (const auto& e : a.kinetic) keep_estimate(2, e);
  keep_estimate(4, a.kinetic_canonical);
  keep_estimate(6, a.kinetic_total);
  for (const auto& e : a.cos_angle) keep_estimate(8, e);
  for (const auto& e : a.kinetic_variance) keep_estimate(10, e);
  keep_estimate(12, a.density_of_states);
  keep(14, a.proposal_beta);
  keep(15, a.effective_sample_fraction);
}

/// The library's options for the chain (the CLI's message when it refuses them).
MicrocanonicalOptions rule_options(const AverageOptions& settings, std::size_t particles) {
  try {
    return microcanonical_options(settings, particles);
  } catch (const invalid_input& bad) {
    throw cli::usage_error("average: " + std::string(bad.what()));  // the CLI's message
  }
}

template <class Real>
MicrocanonicalAverages<Real> run_at(const Chain<Real>& chain, bool by_excitation,
                                    const Real& state, const MicrocanonicalOptions& options) {
  return by_excitation ? microcanonical_average_excitation(chain, state, options)
                       : microcanonical_average(chain, state, options);
}

py::array_t<double> values(const std::vector<Estimate<double>>& v, bool errors) {
  py::array_t<double> out(static_cast<py::ssize_t>(v.size()));
  for (std::size_t i = 0; i < v.size(); ++i) out.mutable_data()[i] = errors ? v[i].error : v[i].value;
  return out;
}

py::object exact_values(const MicrocanonicalRecord& r) {
  if (r.exact.empty()) return py::none();  // double: the floats are exact already
  py::dict out;
  for (std::size_t f = 0; f < exact_fields.size(); ++f) {
    py::list items;
    for (const ExactNumber& x : r.exact[f]) {
      if (x.finite) items.append(py::make_tuple(x.mantissa, x.exponent));
      else items.append(py::float_(x.rounded));
    }
    out[exact_fields[f]] = items;
  }
  return out;
}

/// The CLI's strings (`pendavg average --energy ... --format json`): energy and excitation as
/// the CLI prints them (the given one as written), the run's qmc details when it has them.
py::dict decimal_strings(const MicrocanonicalRecord& r, bool by_excitation,
                         const std::string& state_text) {
  const cli::MicrocanonicalText& t = r.text;
  py::dict d;
  d["energy"] = by_excitation ? t.energy : state_text;
  d["excitation"] = by_excitation ? state_text : t.excitation;
  d["K"] = py::cast(t.kinetic);
  d["K_error"] = py::cast(t.kinetic_error);
  d["Kc"] = t.kinetic_canonical;
  d["Kc_error"] = t.kinetic_canonical_error;
  d["cos_phi"] = py::cast(t.cos_angle);
  d["cos_phi_error"] = py::cast(t.cos_angle_error);
  d["var_K"] = py::cast(t.variance);
  d["var_K_error"] = py::cast(t.variance_error);
  d["K_total"] = t.kinetic_total;
  d["K_total_error"] = t.kinetic_total_error;
  d["density_of_states"] = t.density_of_states;
  d["density_of_states_error"] = t.density_of_states_error;
  if (!t.proposal_beta.empty()) {
    d["proposal_beta"] = t.proposal_beta;
    d["effective_sample_fraction"] = t.effective_sample_fraction;
  }
  return d;
}

/// Refuses a result with a NaN or an infinity (ValueError, one line) before it reaches Python;
/// an MPFR run's exact values are checked as well.
void require_finite(const MicrocanonicalRecord& record) {
  const MicrocanonicalAverages<double>& r = record.values;
  const auto check = [](const std::string& name, double x) {
    if (!std::isfinite(x))
      throw invalid_input("microcanonical: the result is not finite (" + name + " = " +
                          (std::isnan(x) ? "nan" : x > 0 ? "inf" : "-inf") +
                          "): the rule cannot evaluate this chain at this energy");
  };
  const auto estimates = [&](const char* name, const std::vector<Estimate<double>>& v) {
    for (std::size_t i = 0; i < v.size(); ++i) {
      check(std::string(name) + "[" + std::to_string(i) + "]", v[i].value);
      check(std::string(name) + "_error[" + std::to_string(i) + "]", v[i].error);
    }
  };
  const auto estimate = [&](const char* name, const Estimate<double>& e) {
    check(name, e.value);
    check(std::string(name) + "_error", e.error);
  };
  check("energy", r.energy);
  check("excitation", r.excitation);
  estimates("K", r.kinetic);
  estimates("cos_phi", r.cos_angle);
  estimates("var_K", r.kinetic_variance);
  estimate("Kc", r.kinetic_canonical);
  estimate("K_total", r.kinetic_total);
  estimate("density_of_states", r.density_of_states);
  check("proposal_beta", r.proposal_beta);
  check("effective_sample_fraction", r.effective_sample_fraction);
  for (std::size_t f = 0; f < record.exact.size(); ++f)
    for (const ExactNumber& x : record.exact[f])
      if (!x.finite) check(exact_fields[f], x.rounded);
}

py::dict microcanonical(py::handle masses, py::handle lengths, py::handle energy, py::handle g,
                        py::handle digits, py::handle method, py::handle tol, py::handle samples,
                        py::handle shifts, py::handle seed, py::handle excitation) {
  // The options as `pendavg average --energy/--excitation` reads them (one reader for both
  // ensembles), read first as the CLI reads them.
  AverageOptions settings = average_options(digits, method, tol, samples, shifts, seed);
  settings.threads = hardware_threads();
  const std::vector<py::object> m = entries(masses), l = entries(lengths);
  const bool by_excitation = !excitation.is_none();
  const char* state = by_excitation ? "excitation" : "energy";
  const std::string what = by_excitation ? "--excitation" : "--energy";
  if (energy.is_none() == excitation.is_none())  // as the CLI refuses --energy with --excitation
    throw cli::usage_error("microcanonical: give one of energy and excitation");
  const std::string state_text = number_text(by_excitation ? excitation : energy, what);
  MicrocanonicalRecord record;
  record.digits = settings.digits;
  if (settings.digits == min_digits) {
    std::vector<double> mv, lv;
    for (const py::object& x : m) mv.push_back(number_double(x, "--masses", Domain::positive));
    for (const py::object& x : l) lv.push_back(number_double(x, "--lengths", Domain::positive));
    const double gravity = number_double(g, "--g", Domain::nonnegative);
    if (mv.size() != lv.size())
      throw cli::usage_error(std::to_string(mv.size()) + " masses but " +
                             std::to_string(lv.size()) + " lengths");
    const Chain<double> chain(std::move(mv), std::move(lv), gravity);
    const MicrocanonicalOptions options = rule_options(settings, chain.size());
    const double x = cli::microcanonical_state(chain, state, state_text, what, options);
    record.particles = chain.size();
    py::gil_scoped_release release;
    const Stopwatch watch;
    record.values = run_at(chain, by_excitation, x, options);
    record.seconds = watch.seconds();
    record.text = cli::microcanonical_text(record.values, settings.digits);
  } else {
    std::vector<std::string> mass_texts, length_texts;
    for (const py::object& x : m) mass_texts.push_back(number_text(x, "--masses"));
    for (const py::object& x : l) length_texts.push_back(number_text(x, "--lengths"));
    const std::string g_text = number_text(g, "--g");
    // Parsed and computed under the working precision, without the GIL (as `pendavg average
    // --digits D` holds one for the whole call).
    py::gil_scoped_release release;
    const working_precision precision(settings.digits + guard_digits);
    std::vector<mpfr_real> mv, lv;
    for (const std::string& x : mass_texts)
      mv.push_back(cli::parse_real<mpfr_real>(x, "--masses", Domain::positive));
    for (const std::string& x : length_texts)
      lv.push_back(cli::parse_real<mpfr_real>(x, "--lengths", Domain::positive));
    mpfr_real gravity = cli::parse_real<mpfr_real>(g_text, "--g", Domain::nonnegative);
    if (mv.size() != lv.size())
      throw cli::usage_error(std::to_string(mv.size()) + " masses but " +
                             std::to_string(lv.size()) + " lengths");
    const Chain<mpfr_real> chain(std::move(mv), std::move(lv), std::move(gravity));
    const MicrocanonicalOptions options = rule_options(settings, chain.size());
    const mpfr_real x = cli::microcanonical_state(chain, state, state_text, what, options);
    record.particles = chain.size();
    const Stopwatch watch;
    const MicrocanonicalAverages<mpfr_real> r = run_at(chain, by_excitation, x, options);
    record.seconds = watch.seconds();
    keep_mpfr(record, r);
  }
  require_finite(record);
  const MicrocanonicalAverages<double>& r = record.values;
  py::dict out;
  out["N"] = record.particles;
  out["digits"] = record.digits;
  out["energy"] = r.energy;
  out["excitation"] = r.excitation;
  out["K"] = values(r.kinetic, false);
  out["K_error"] = values(r.kinetic, true);
  out["Kc"] = r.kinetic_canonical.value;
  out["Kc_error"] = r.kinetic_canonical.error;
  out["K_total"] = r.kinetic_total.value;
  out["K_total_error"] = r.kinetic_total.error;
  out["cos_phi"] = values(r.cos_angle, false);
  out["cos_phi_error"] = values(r.cos_angle, true);
  out["var_K"] = values(r.kinetic_variance, false);
  out["var_K_error"] = values(r.kinetic_variance, true);
  out["density_of_states"] = r.density_of_states.value;
  out["density_of_states_error"] = r.density_of_states.error;
  out["method"] = std::string(method_name(r.method)) + "/" + method_name(r.quadrature);
  out["error_kind"] = error_kind_name(r.error_kind);
  out["evaluations"] = r.evaluations;
  out["work_unit"] = work_unit_name(r.work_unit);
  out["converged"] = r.converged;
  out["proposal_beta"] = r.proposal_beta;
  out["effective_sample_fraction"] = r.effective_sample_fraction;
  out["seconds"] = record.seconds;
  out["decimal"] = decimal_strings(record, by_excitation, state_text);
  out["exact"] = exact_values(record);
  return out;
}

}  // namespace

void expose_microcanonical(py::module_& m) {
  using namespace pybind11::literals;
  m.def("microcanonical", &microcanonical, "masses"_a, "lengths"_a, "energy"_a, "g"_a,
        "digits"_a, "method"_a, "tol"_a, "samples"_a, "shifts"_a, "seed"_a, "excitation"_a,
        "Microcanonical averages at one energy as a dict (see pendavg.microcanonical).");
}

}  // namespace pendavg::python
