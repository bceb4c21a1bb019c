// SPDX-License-Identifier: GPL-3.0-or-later
// src/python/expose_dynamics.cpp -- pendavg.simulate (time averages along a RATTLE or Langevin
// trajectory beside the exact values of its ensemble) and pendavg.poincare (the double
// pendulum's section), as `pendavg simulate` and `pendavg poincare` run them
// (src/cli/simulate.cpp): the same checks and messages, the same library calls.
//
// The run goes through the library's DynamicsObserver: `stop` (polled by the library every 1024
// steps) ends it early with the averages so far, `progress` reports the fraction done. The
// calling thread waits with the GIL released and polls Python every 50 ms (parallel.hpp): Ctrl-C
// (KeyboardInterrupt) sets `stop`, and the averages so far come back with interrupted = True, as
// the CLI prints them after SIGINT; a progress callback runs on the calling thread.
#include "bindings.hpp"
#include "inputs.hpp"
#include "parallel.hpp"
#include "table_result.hpp"

#include "io/exact_values.hpp"
#include "io/parse.hpp"
#include "io/results.hpp"

#include "pendavg/pendavg.hpp"

#include <pybind11/numpy.h>
#include <pybind11/stl.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <cmath>
#include <numbers>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace pendavg::cli {
// The front-end library's parsing under the names this file has used (the CLI's args.hpp spells
// them so): src/python includes nothing from src/cli.
using io::Domain;
using io::parse_choice;
using io::parse_integer;
using io::parse_real;
using io::parse_unsigned;
using usage_error = io::bad_input;
}  // namespace pendavg::cli

namespace pendavg::python {

namespace {

using cli::Domain;
using io::ExactValues;

constexpr std::array<std::string_view, 5> integrator_names{"rattle2", "yoshida4", "suzuki4",
                                                           "kahan-li6", "yoshida6"};
constexpr std::array<std::string_view, 2> thermostat_names{"none", "langevin"};
constexpr std::array<std::string_view, 2> yes_no{"yes", "no"};

/// As the CLI's parse_chain: masses, lengths, their counts ("<command>: ..."), then g.
Chain<double> dynamics_chain(py::handle masses, py::handle lengths, py::handle g,
                             const std::string& command) {
  std::vector<double> m, l;
  for (const py::object& x : entries(masses)) m.push_back(number_double(x, "--masses", Domain::positive));
  for (const py::object& x : entries(lengths)) l.push_back(number_double(x, "--lengths", Domain::positive));
  if (m.size() != l.size())
    throw cli::usage_error(command + ": " + std::to_string(m.size()) + " masses but " +
                           std::to_string(l.size()) + " lengths");
  const double gravity = number_double(g, "--g", Domain::nonnegative);
  return Chain<double>(std::move(m), std::move(l), gravity);
}

/// An angle: radians, or a str with a 'deg' suffix in degrees ('90deg'), as the CLI reads it.
double angle(py::handle x, std::string_view what) {
  if (PyUnicode_Check(x.ptr())) {
    const std::string text = utf8_text(x, what);
    constexpr std::string_view suffix = "deg";
    if (text.size() > suffix.size() && text.ends_with(suffix))
      return cli::parse_real<double>(std::string_view(text).substr(0, text.size() - suffix.size()),
                                     what, Domain::any) *
             std::numbers::pi / 180;
  }
  return number_double(x, what, Domain::any);
}

double option_double(py::handle x, const char* fallback, std::string_view what, Domain domain) {
  if (x.is_none()) return cli::parse_real<double>(fallback, what, domain);
  return number_double(x, what, domain);
}

/// The Python class SimulationResult: the run's records (table_result.hpp) and the trajectory.
struct SimulationTable : TableResult {
  py::object trajectory = py::none();  ///< {t, E, phi, phidot} every `every` steps, or None
};

py::array_t<double> array(const std::vector<double>& v) {
  return py::array_t<double>(static_cast<py::ssize_t>(v.size()), v.data());
}

py::array_t<double> matrix(const std::vector<double>& v, std::size_t columns) {
  const auto rows = static_cast<py::ssize_t>(columns ? v.size() / columns : 0);
  return py::array_t<double>({rows, static_cast<py::ssize_t>(columns)}, v.data());
}

SimulationTable simulate(py::handle masses, py::handle lengths, py::handle g, py::handle theta,
                  py::handle phi, py::handle phidot, py::handle time, py::handle dt,
                  py::handle burn_in, py::handle integrator, py::handle thermostat,
                  py::handle beta, py::handle friction, py::handle seed, py::handle exact,
                  py::handle every, const py::object& progress) {
  const Chain<double> chain = dynamics_chain(masses, lengths, g, "simulate");
  const std::size_t n = chain.size();
  if (theta.is_none() == phi.is_none())
    throw cli::usage_error("simulate: give exactly one of --theta and --phi");
  std::vector<double> angles, rates(n, 0.0);
  if (!theta.is_none()) {
    if (!phidot.is_none()) throw cli::usage_error("simulate: --phidot goes with --phi");
    angles.assign(n, angle(theta, "--theta"));
  } else {
    for (const py::object& x : entries(phi)) angles.push_back(angle(x, "--phi"));
    if (angles.size() != n)
      throw cli::usage_error("simulate: --phi has " + std::to_string(angles.size()) +
                             " angles for " + std::to_string(n) + " particles");
    if (!phidot.is_none()) {
      rates.clear();
      for (const py::object& x : entries(phidot)) rates.push_back(number_double(x, "--phidot", Domain::any));
      if (rates.size() != n)
        throw cli::usage_error("simulate: --phidot has " + std::to_string(rates.size()) +
                               " values for " + std::to_string(n) + " particles");
    }
  }
  // Read as the CLI reads them; the library checks the run (steps, and which settings the
  // thermostat uses), with the CLI's messages.
  SimulationOptions run;
  if (time.is_none()) throw cli::usage_error("simulate: missing required option --time");
  run.duration = number_double(time, "--time", Domain::positive);
  run.time_step = option_double(dt, "1e-3", "--dt", Domain::positive);
  run.burn_in = option_double(burn_in, "0", "--burn-in", Domain::nonnegative);
  if (!integrator.is_none())
    run.integrator = static_cast<Integrator>(
        cli::parse_choice(choice_text(integrator, "integrator"), "integrator", integrator_names));
  const bool langevin =
      cli::parse_choice(thermostat.is_none() ? "none" : choice_text(thermostat, "thermostat"), "thermostat",
                        thermostat_names) == 1;
  run.thermostat = langevin ? Thermostat::langevin : Thermostat::none;
  if (langevin && beta.is_none()) throw cli::usage_error("simulate: missing required option --beta");
  if (!beta.is_none()) run.beta = number_double(beta, "--beta", Domain::positive);
  if (!friction.is_none()) run.friction = number_double(friction, "--friction", Domain::positive);
  if (!seed.is_none()) {
    const std::uint64_t value = cli::parse_unsigned(number_text(seed, "--seed"), "--seed");
    // The CLI's message (its NVE --seed is for --replicas, which this function does not run).
    if (!langevin)
      throw cli::usage_error("simulate: --seed needs --thermostat langevin or --replicas R > 1");
    run.seed = value;
  }
  try {
    check_simulation_options(run);
  } catch (const invalid_input& bad) {
    throw cli::usage_error(bad.what());
  }
  if (!PyBool_Check(exact.ptr()) && !PyUnicode_Check(exact.ptr()))
    throw py::type_error("exact: expected True, False, 'yes' or 'no', got " +
                         std::string(Py_TYPE(exact.ptr())->tp_name));
  const bool with_exact =
      PyBool_Check(exact.ptr())
          ? exact.ptr() == Py_True
          : cli::parse_choice(choice_text(exact, "exact"), "--exact value", yes_no) == 0;
  std::size_t trajectory_every = 0;
  if (!every.is_none())
    trajectory_every = static_cast<std::size_t>(
        cli::parse_integer(number_text(every, "--every"), "--every", 1, 1000000000));

  ChainState<double> initial = state_from_angles(chain, angles, rates);
  const double energy = total_energy(chain, initial);
  // The exact values first, as the CLI: a request they cannot serve is refused before any
  // integration, and an interrupted run still has them.
  std::optional<ExactValues> reference;
  if (with_exact) {
    py::gil_scoped_release release;
    reference = langevin ? io::canonical_values(chain, *run.beta)
                         : io::microcanonical_values(
                               chain, io::initial_excitation(chain, initial, angles));
  }
  std::vector<double> t, e, phis, phidots;  // the trajectory, filled by the run's thread
  DynamicsObserver<double> observer;
  std::atomic<bool> stop{false};
  std::atomic<double> fraction{0};
  observer.stop = &stop;
  observer.progress = [&](double f) { fraction.store(f); };
  if (trajectory_every) {
    observer.trajectory_every = trajectory_every;
    observer.trajectory = [&](const ChainState<double>& state) {
      const ChainObservables<double> o = observables(chain, state);
      t.push_back(state.time);
      e.push_back(o.energy);
      phis.insert(phis.end(), o.phi.begin(), o.phi.end());
      phidots.insert(phidots.end(), o.phidot.begin(), o.phidot.end());
    };
  }
  std::optional<SimulationResult<double>> result;
  const Stopwatch watch;
  run_interruptible([&] { result = pendavg::simulate(chain, initial, run, observer); }, stop, fraction,
               progress);
  const double seconds = watch.seconds();
  const SimulationResult<double>& r = *result;

  // A run stopped by Ctrl-C before its first sample has no average: KeyboardInterrupt. The
  // library refused any other result that is not finite (check_simulation_result).
  if (r.interrupted && r.samples == 0) {
    PyErr_SetString(PyExc_KeyboardInterrupt, "simulate: interrupted before the first sample");
    throw py::error_already_set();
  }
  // The records `pendavg simulate` prints (io::append_simulation_inputs, io::append_simulation).
  SimulationTable out;
  out.particles = n;
  out.layout({{io::simulation_input_fields(), true}, {io::simulation_fields(), false}}, false);
  io::Record inputs(io::simulation_input_fields(), n), values(io::simulation_fields(), n);
  io::append_simulation_inputs(
      inputs, chain, run,
      langevin ? std::string_view("baoab-rattle")
               : integrator_names[static_cast<std::size_t>(run.integrator.value_or(default_integrator))]);
  io::append_simulation(values, r, energy, reference ? &*reference : nullptr, langevin);
  const std::array<const io::Record*, 2> records{&inputs, &values};
  out.store(0, records);
  out.set_run(0, seconds, r.interrupted);
  out.require_finite("simulate", "the trajectory left the finite numbers (try a smaller dt)");
  if (trajectory_every) {
    // In the trajectory table's order (io/results.hpp): t, E, phi, phidot.
    const auto fields = io::trajectory_fields();
    py::dict trajectory;
    trajectory[py::str(std::string(fields[0].name))] = array(t);
    trajectory[py::str(std::string(fields[1].name))] = array(e);
    trajectory[py::str(std::string(fields[2].name))] = matrix(phis, n);
    trajectory[py::str(std::string(fields[3].name))] = matrix(phidots, n);
    out.trajectory = trajectory;
  }
  return out;
}

py::dict poincare(py::handle masses, py::handle lengths, py::handle g, py::handle energy,
                  py::handle orbits, py::handle points, py::handle dt, const py::object& progress) {
  const Chain<double> chain = dynamics_chain(masses, lengths, g, "poincare");
  if (chain.size() != 2) throw cli::usage_error("poincare: the section is for N = 2 (two masses)");
  if (energy.is_none()) throw cli::usage_error("poincare: missing required option --energy");
  const double e = number_double(energy, "--energy", Domain::any);
  PoincareOptions run;
  run.orbits = static_cast<std::size_t>(cli::parse_integer(
      orbits.is_none() ? "8" : number_text(orbits, "--orbits"), "--orbits", 1, 10000));
  run.points = static_cast<std::size_t>(cli::parse_integer(
      points.is_none() ? "500" : number_text(points, "--points"), "--points", 1, 100000000));
  run.time_step = option_double(dt, "1e-3", "--dt", Domain::positive);
  run.threads = hardware_threads();
  DynamicsObserver<double> observer;
  std::atomic<bool> stop{false};
  std::atomic<double> fraction{0};
  observer.stop = &stop;
  observer.progress = [&](double f) { fraction.store(f); };
  std::optional<PoincareSection<double>> section;
  const Stopwatch watch;
  run_interruptible([&] { section = poincare_section(chain, e, run, observer); }, stop, fraction,
               progress);
  const double seconds = watch.seconds();
  // The records `pendavg poincare` prints (io::append_poincare, io::append_section_point), and
  // the orbits' starts (io::append_orbit_start): the call's fields single values, the crossings'
  // and the starts' arrays. The library refused a point that is not finite.
  const std::size_t n = chain.size();
  TableResult call, crossings, starts;
  call.particles = crossings.particles = starts.particles = n;
  call.layout({{io::poincare_fields(), false}}, false);
  io::Record record(io::poincare_fields(), n);
  io::append_poincare(record, chain, run, *section);
  call.store(0, std::array<const io::Record*, 1>{&record});
  crossings.shape = {static_cast<py::ssize_t>(section->points.size())};
  crossings.layout({{io::section_point_fields(), false}}, false);
  for (std::size_t k = 0; k < section->points.size(); ++k) {
    record.reset(io::section_point_fields(), n);
    io::append_section_point(record, section->points[k]);
    crossings.store(k, std::array<const io::Record*, 1>{&record});
  }
  starts.shape = {static_cast<py::ssize_t>(section->start_phi2.size())};
  starts.layout({{io::orbit_start_fields(), false}}, false);
  for (std::size_t k = 0; k < section->start_phi2.size(); ++k) {
    record.reset(io::orbit_start_fields(), n);
    io::append_orbit_start(record, *section, k);
    starts.store(k, std::array<const io::Record*, 1>{&record});
  }
  for (const TableResult* part : {&call, &crossings, &starts})
    part->require_finite("poincare", "the trajectory left the finite numbers (try a smaller dt)");
  py::dict out, decimal;
  for (const TableResult* part : {&call, &crossings, &starts}) {
    const py::dict strings = part->decimal();
    for (const Column& c : part->columns()) {
      const std::string name(c.field.name);
      out[name.c_str()] = part->value(c.field.name);
      if (strings.contains(name))
        decimal[name.c_str()] = part->single() ? strings[name.c_str()]
                                               : strings[name.c_str()].attr("tolist")();
    }
  }
  out["seconds"] = seconds;
  out["decimal"] = decimal;
  return out;
}

/// The fields of pendavg.PoincareSection: the call's, each crossing's, each orbit's start.
py::tuple poincare_fields() {
  return py::make_tuple(field_tuples(class_fields({{io::poincare_fields(), false}})),
                        field_tuples(class_fields({{io::section_point_fields(), false}})),
                        field_tuples(class_fields({{io::orbit_start_fields(), false}})));
}

/// The fields of SimulationResult: the run's inputs, then its result (the CLI's tables).
const std::vector<ClassField>& simulation_class_fields() {
  static const std::vector<ClassField> fields =
      class_fields({{io::simulation_input_fields(), true}, {io::simulation_fields(), false}});
  return fields;
}

std::string simulation_doc() {
  std::string doc =
      "Time averages along one trajectory beside the exact values of its ensemble: the result "
      "of pendavg.simulate.\n\n"
      "Per-particle fields are arrays of shape (N,), the others Python scalars; index i is\n"
      "particle i + 1; a value that does not exist is None (an error bar of too few blocks,\n"
      "the exact values of exact=False), with a *_reason field where the run says why. The\n"
      "fields (the CLI's JSON keys of `pendavg simulate`, from the output schema's field\n"
      "tables):\n\n";
  for (const ClassField& f : simulation_class_fields())
    doc += "  " + std::string(f.field.name) +
           (f.field.shape == io::Shape::per_particle ? " (per particle)" : "") + ": " +
           std::string(f.field.meaning) + "\n";
  doc += "\nBesides: shape (()), seconds (the run's wall time), trajectory, decimal (the CLI's\n"
         "strings), mpf (exact mpmath values), to_dict(), to_dataframe(), to_xarray().";
  return doc;
}

/// The CLI's messages without its advice to use --digits > 16 (a number beyond double's range):
/// simulate and poincare run in double only, as `pendavg simulate` says (set_digits_advice).
template <class Function>
auto without_digits_advice(Function function) {
  return [function](auto... arguments) {
    try {
      return function(arguments...);
    } catch (const invalid_input& bad) {
      const std::string advice = io::digits_advice();  // " (use digits > 16)"
      const std::string_view message = bad.what();
      if (!message.ends_with(advice)) throw;
      throw invalid_input(std::string(message.substr(0, message.size() - advice.size())));
    }
  };
}

}  // namespace

void expose_dynamics(py::module_& m) {
  using namespace pybind11::literals;
  auto c = table_class<SimulationTable>(m, "SimulationResult", simulation_doc().c_str(),
                                        simulation_class_fields());
  c.def_property_readonly(
      "trajectory", [](const SimulationTable& r) { return r.trajectory; },
      "The trajectory every `every` steps: {'t': times, 'E': energies, 'phi': (T, N) angles, "
      "'phidot': (T, N) angular velocities} (numpy arrays; as `pendavg simulate --trajectory`), "
      "or None.");
  m.def("simulate",
        [](py::handle masses, py::handle lengths, py::handle g, py::handle theta, py::handle phi,
           py::handle phidot, py::handle time, py::handle dt, py::handle burn_in,
           py::handle integrator, py::handle thermostat, py::handle beta, py::handle friction,
           py::handle seed, py::handle exact, py::handle every, const py::object& progress) {
          return without_digits_advice(&simulate)(masses, lengths, g, theta, phi, phidot, time,
                                                  dt, burn_in, integrator, thermostat, beta,
                                                  friction, seed, exact, every, progress);
        }, "masses"_a, "lengths"_a, "g"_a, "theta"_a, "phi"_a, "phidot"_a,
        "time"_a, "dt"_a, "burn_in"_a, "integrator"_a, "thermostat"_a, "beta"_a, "friction"_a,
        "seed"_a, "exact"_a, "every"_a, "progress"_a,
        "A trajectory's time averages (see pendavg.simulate).");
  m.def("poincare",
        [](py::handle masses, py::handle lengths, py::handle g, py::handle energy,
           py::handle orbits, py::handle points, py::handle dt, const py::object& progress) {
          return without_digits_advice(&poincare)(masses, lengths, g, energy, orbits, points, dt,
                                                  progress);
        }, "masses"_a, "lengths"_a, "g"_a, "energy"_a, "orbits"_a, "points"_a,
        "dt"_a, "progress"_a, "The double pendulum's Poincare section as a dict (see pendavg.poincare).");
  m.def("poincare_fields", &poincare_fields,
        "(the section's fields, each crossing's, each orbit start's) as (name, kind, "
        "per_particle, meaning, input) tuples.");
  m.def("dynamics_instruction_set", &dynamics_instruction_set,
        "'x86-64-v3' or 'base': the instruction set of the dynamics kernels on this CPU.");
}

}  // namespace pendavg::python
