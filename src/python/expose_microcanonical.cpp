// src/python/expose_microcanonical.cpp -- pendavg.microcanonical: exact fixed-energy averages
// <K_i>_E, <K_i^(c)>_E, <cos phi_i>_E and the density of states (pendavg/microcanonical.hpp;
// MATH.md Sec. 7), in double, with the options named as pendavg.average names them.
#include "bindings.hpp"
#include "inputs.hpp"

#include "cli/average_options.hpp"

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
                        py::handle seed, py::handle excitation) {
  std::vector<double> m, l;
  for (const py::object& x : entries(masses)) m.push_back(number_double(x, "--masses", Domain::positive));
  for (const py::object& x : entries(lengths)) l.push_back(number_double(x, "--lengths", Domain::positive));
  const double gravity = number_double(g, "--g", Domain::nonnegative);
  if (m.size() != l.size())
    throw cli::usage_error(std::to_string(m.size()) + " masses but " + std::to_string(l.size()) +
                           " lengths");
  const Chain<double> chain(std::move(m), std::move(l), gravity);
  // The options as `pendavg average --energy/--excitation` reads them (one rule for both).
  const AverageOptions settings = average_options(py::none(), method, tol, samples, shifts, seed);
  MicrocanonicalOptions options;
  try {
    options = microcanonical_options(settings, chain.size());
  } catch (const invalid_input& bad) {
    throw cli::usage_error("average: " + std::string(bad.what()));  // the CLI's message
  }
  options.threads = hardware_threads();
  if (energy.is_none() == excitation.is_none())
    throw cli::usage_error("microcanonical: give one of energy and excitation");
  const bool by_excitation = !excitation.is_none();
  const std::string what = by_excitation ? "--excitation" : "--energy";
  const double state = cli::microcanonical_state(
      chain, by_excitation ? "excitation" : "energy",
      number_text(by_excitation ? excitation : energy), what);
  MicrocanonicalAverages<double> r;
  double seconds = 0;
  {
    py::gil_scoped_release release;
    const Stopwatch watch;
    r = by_excitation ? microcanonical_average_excitation(chain, state, options)
                      : microcanonical_average(chain, state, options);
    seconds = watch.seconds();
  }
  py::dict out;
  out["N"] = chain.size();
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
        "tol"_a, "samples"_a, "shifts"_a, "seed"_a, "excitation"_a,
        "Microcanonical averages at one energy as a dict (see pendavg.microcanonical).");
}

}  // namespace pendavg::python
