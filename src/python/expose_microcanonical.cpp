// SPDX-License-Identifier: GPL-3.0-or-later
// src/python/expose_microcanonical.cpp -- pendavg.microcanonical: exact fixed-energy averages
// <K_i>_E, <K_i^(c)>_E, <cos phi_i>_E, Var K_i and the density of states
// (pendavg/microcanonical.hpp), as `pendavg average --energy E | --excitation D [--digits D]`
// computes them (src/cli/average.cpp, microcanonical_one): the options read by the front-end
// library's reader and turned into MicrocanonicalOptions by the library
// (microcanonical_options(AverageOptions, N)), the state checked by io::microcanonical_state; in
// double the chain from the same doubles, with digits 17..1000 (integral rule N <= 4,
// torus-trapezoid N <= 2) everything parsed and computed in MPFR under the working precision, as
// the CLI does; the result filled into the records the CLI prints (io::append_microcanonical),
// from which the class MicrocanonicalResult is generated (table_result.hpp).
//
// The run gets no RunControl here (MicrocanonicalOptions::control: left for later): it reports no
// progress and cannot be stopped, so it runs with the GIL released and a Ctrl-C is raised when it
// returns.
#include "bindings.hpp"
#include "inputs.hpp"
#include "table_result.hpp"

#include "io/results.hpp"

#include "pendavg/mpfr.hpp"
#include "pendavg/pendavg.hpp"

#include <pybind11/numpy.h>
#include <pybind11/stl.h>

#include <array>
#include <string>
#include <string_view>
#include <vector>

namespace pendavg::python {

namespace {

using io::Domain;

/// The Python class MicrocanonicalResult: one point's records (the inputs', then the averages').
struct MicrocanonicalResult : TableResult {};

/// Its fields: those of a run at a given energy and of one at a given excitation (each has
/// both energy and excitation, in another order).
const std::vector<ClassField>& microcanonical_class_fields() {
  static const std::vector<ClassField> fields = class_fields(
      {{io::microcanonical_input_fields("energy"), true},
       {io::microcanonical_input_fields("excitation"), true},
       {io::microcanonical_fields("energy"), false},
       {io::microcanonical_fields("excitation"), false}});
  return fields;
}

template <class Real>
Chain<Real> parse_chain(const std::vector<std::string>& masses,
                        const std::vector<std::string>& lengths, const std::string& g) {
  std::vector<Real> mv, lv;
  for (const std::string& x : masses) mv.push_back(io::parse_real<Real>(x, "masses", Domain::positive));
  for (const std::string& x : lengths) lv.push_back(io::parse_real<Real>(x, "lengths", Domain::positive));
  Real gravity = io::parse_real<Real>(g, "g", Domain::nonnegative);
  if (mv.size() != lv.size())
    throw io::bad_input(std::to_string(mv.size()) + " masses but " + std::to_string(lv.size()) +
                        " lengths");
  return Chain<Real>(std::move(mv), std::move(lv), std::move(gravity));
}

/// The run of `state` (energy or excitation) at `text`, parsed, checked, computed and filled into
/// `result` (an MPFR run under its working precision, which the caller holds). `texts`: the
/// inputs as written (the state, g, m1..mN, l1..lN), how an MPFR run prints them.
template <class Real>
void run(MicrocanonicalResult& result, const AverageOptions& settings, std::string_view state,
         const std::string& text, const std::vector<std::string>& masses,
         const std::vector<std::string>& lengths, const std::string& g) {
  const Chain<Real> chain = parse_chain<Real>(masses, lengths, g);
  // the library's options for the chain (its message "microcanonical: ..." when it refuses them;
  // the CLI prefixes its command, "average: ")
  const MicrocanonicalOptions options = microcanonical_options(settings, chain.size());
  const Real x = io::microcanonical_state(chain, state, text, state, options, "");
  result.particles = chain.size();
  const bool mpfr = !std::is_same_v<Real, double>;
  result.layout({{io::microcanonical_input_fields(state), true},
                 {io::microcanonical_fields(state), false}},
                mpfr);
  const Stopwatch watch;
  const MicrocanonicalAverages<Real> r = state == "excitation"
                                             ? microcanonical_average_excitation(chain, x, options)
                                             : microcanonical_average(chain, x, options);
  result.set_run(0, watch.seconds(), false);
  const io::Printing printing{settings.digits, false};  // (texts when .decimal asks)
  io::Record inputs, values;
  inputs.keep_exact(mpfr);
  values.keep_exact(mpfr);
  inputs.reset(io::microcanonical_input_fields(state), chain.size());
  values.reset(io::microcanonical_fields(state), chain.size());
  std::vector<std::string_view> written;
  if (mpfr) {
    written.push_back(text);
    written.push_back(g);
    written.insert(written.end(), masses.begin(), masses.end());
    written.insert(written.end(), lengths.begin(), lengths.end());
  }
  io::append_microcanonical_inputs(inputs, chain, x, printing, written);
  io::append_microcanonical(values, r, printing);
  const std::array<const io::Record*, 2> records{&inputs, &values};
  result.store(0, records);
}

MicrocanonicalResult microcanonical(py::handle masses, py::handle lengths, py::handle energy,
                                    py::handle g, py::handle digits, py::handle method,
                                    py::handle tol, py::handle samples, py::handle shifts,
                                    py::handle seed, py::handle excitation) {
  // The options as `pendavg average --energy/--excitation` reads them (one reader for both
  // ensembles), read first as the CLI reads them.
  AverageOptions settings = average_options(digits, method, tol, samples, shifts, seed);
  settings.threads = hardware_threads();
  const std::vector<py::object> m = entries(masses), l = entries(lengths);
  const bool by_excitation = !excitation.is_none();
  const std::string_view state = by_excitation ? "excitation" : "energy";
  if (energy.is_none() == excitation.is_none())  // as the CLI refuses --energy with --excitation
    throw io::bad_input("microcanonical: give one of energy and excitation");
  const std::string state_text = number_text(by_excitation ? excitation : energy, state);
  std::vector<std::string> mass_texts, length_texts;
  for (const py::object& x : m) mass_texts.push_back(number_text(x, "masses"));
  for (const py::object& x : l) length_texts.push_back(number_text(x, "lengths"));
  const std::string g_text = number_text(g, "g");
  MicrocanonicalResult result;
  result.digits = settings.digits;
  {
    py::gil_scoped_release release;
    if (settings.digits == min_digits) {
      run<double>(result, settings, state, state_text, mass_texts, length_texts, g_text);
    } else {
      // Parsed and computed under the working precision (as `pendavg average --digits D`
      // holds one for the whole call).
      const working_precision precision(settings.digits + guard_digits);
      run<mpfr_real>(result, settings, state, state_text, mass_texts, length_texts, g_text);
    }
  }
  result.require_finite("microcanonical", "the rule cannot evaluate this chain at this energy");
  return result;
}

std::string microcanonical_doc() {
  std::string doc =
      "Exact averages at fixed energy E: the result of pendavg.microcanonical.\n\n"
      "Per-particle fields are arrays of shape (N,), the others Python scalars; index i is\n"
      "particle i + 1. The fields (the CLI's JSON keys of `pendavg average --energy E`, from\n"
      "the output schema's field tables):\n\n";
  for (const ClassField& f : microcanonical_class_fields())
    doc += "  " + std::string(f.field.name) +
           (f.field.shape == io::Shape::per_particle ? " (per particle)" : "") + ": " +
           std::string(f.field.meaning) + "\n";
  doc += "\nBesides: shape (()), seconds (the library call's wall time), decimal (the CLI's\n"
         "strings), mpf (exact mpmath values), to_dict(), to_dataframe().";
  return doc;
}

}  // namespace

void expose_microcanonical(py::module_& m) {
  using namespace pybind11::literals;
  table_class<MicrocanonicalResult>(m, "MicrocanonicalResult", microcanonical_doc().c_str(),
                                    microcanonical_class_fields());
  m.def("microcanonical", &microcanonical, "masses"_a, "lengths"_a, "energy"_a, "g"_a,
        "digits"_a, "method"_a, "tol"_a, "samples"_a, "shifts"_a, "seed"_a, "excitation"_a,
        "Microcanonical averages at one energy (see pendavg.microcanonical).");
}

}  // namespace pendavg::python
