// src/python/expose_microcanonical.cpp -- pendavg.microcanonical: exact fixed-energy averages
// <K_i>_E, <K_i^(c)>_E, <cos phi_i>_E and the density of states (pendavg/microcanonical.hpp;
// MATH.md Sec. 7), in double, with the options named as pendavg.average names them.
#include "bindings.hpp"
#include "inputs.hpp"

#include "pendavg/pendavg.hpp"

#include <pybind11/numpy.h>
#include <pybind11/stl.h>

#include <array>
#include <string>
#include <vector>

namespace pendavg::python {

namespace {

using cli::Domain;

py::array_t<double> values(const std::vector<Estimate<double>>& v, bool errors) {
  py::array_t<double> out(static_cast<py::ssize_t>(v.size()));
  for (std::size_t i = 0; i < v.size(); ++i) out.mutable_data()[i] = errors ? v[i].error : v[i].value;
  return out;
}

py::dict microcanonical(py::handle masses, py::handle lengths, py::handle energy, py::handle g,
                        py::handle method, py::handle tol, py::handle samples, py::handle shifts,
                        py::handle seed) {
  std::vector<double> m, l;
  for (const py::object& x : entries(masses)) m.push_back(number_double(x, "--masses", Domain::positive));
  for (const py::object& x : entries(lengths)) l.push_back(number_double(x, "--lengths", Domain::positive));
  const double gravity = number_double(g, "--g", Domain::nonnegative);
  if (m.size() != l.size())
    throw cli::usage_error(std::to_string(m.size()) + " masses but " + std::to_string(l.size()) +
                           " lengths");
  const Chain<double> chain(std::move(m), std::move(l), gravity);
  MicrocanonicalOptions options;
  constexpr std::array<std::string_view, 4> rules{"auto", "integral", "torus-trapezoid", "qmc"};
  const std::string rule_text = choice_text(method);
  options.rule = static_cast<MicrocanonicalOptions::Rule>(cli::parse_choice(rule_text, "method", rules));
  const std::string chosen = "method " + rule_text;
  const bool qmc = options.rule == MicrocanonicalOptions::Rule::qmc ||
                   (options.rule == MicrocanonicalOptions::Rule::automatic && chain.size() >= 5);
  if (!tol.is_none()) {
    if (qmc) throw invalid_input("microcanonical: tol is used by integral and torus-trapezoid, not by qmc");
    const std::string text = number_text(tol);
    options.tolerance = cli::parse_real<double>(text, "--tol", Domain::positive);
    if (!(options.tolerance < 1)) throw cli::usage_error("--tol: '" + text + "' must be < 1");
  }
  for (const auto& [value, name] : {std::pair{samples, "samples"}, std::pair{shifts, "shifts"},
                                     std::pair{seed, "seed"}})
    if (!value.is_none() && !qmc)
      throw invalid_input(std::string("microcanonical: ") + name + " is used by qmc only, not by " +
                          (options.rule == MicrocanonicalOptions::Rule::automatic
                               ? chosen + " (integral for N <= 4)"
                               : chosen));
  if (!samples.is_none())
    options.points = static_cast<std::size_t>(
        cli::parse_integer(number_text(samples), "--samples", 1, 1L << 40));
  if (!shifts.is_none())
    options.shifts = static_cast<std::size_t>(
        cli::parse_integer(number_text(shifts), "--shifts", 1, 1L << 40));
  if (!seed.is_none()) options.seed = cli::parse_unsigned(number_text(seed), "--seed");
  options.threads = hardware_threads();
  const double e = number_double(energy, "--energy", Domain::any);
  MicrocanonicalAverages<double> r;
  double seconds = 0;
  {
    py::gil_scoped_release release;
    const Stopwatch watch;
    r = microcanonical_average(chain, e, options);
    seconds = watch.seconds();
  }
  py::dict out;
  out["N"] = chain.size();
  out["energy"] = r.energy;
  out["K"] = values(r.kinetic, false);
  out["K_error"] = values(r.kinetic, true);
  out["Kc"] = r.kinetic_canonical.value;
  out["Kc_error"] = r.kinetic_canonical.error;
  out["K_total"] = r.kinetic_total.value;
  out["K_total_error"] = r.kinetic_total.error;
  out["cos_phi"] = values(r.cos_angle, false);
  out["cos_phi_error"] = values(r.cos_angle, true);
  out["density_of_states"] = r.density_of_states.value;
  out["density_of_states_error"] = r.density_of_states.error;
  out["method"] = std::string(method_name(r.method)) + "/" + method_name(r.quadrature);
  out["error_kind"] = error_kind_name(r.error_kind);
  out["evaluations"] = r.evaluations;
  out["converged"] = r.converged;
  out["proposal_beta"] = r.proposal_beta;
  out["effective_sample_fraction"] = r.effective_sample_fraction;
  out["seconds"] = seconds;
  return out;
}

}  // namespace

void expose_microcanonical(py::module_& m) {
  using namespace pybind11::literals;
  m.def("microcanonical", &microcanonical, "masses"_a, "lengths"_a, "energy"_a, "g"_a, "method"_a,
        "tol"_a, "samples"_a, "shifts"_a, "seed"_a,
        "Microcanonical averages at one energy as a dict (see pendavg.microcanonical).");
}

}  // namespace pendavg::python
