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

#include "io/exact_values.hpp"
#include "io/parse.hpp"

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

py::array_t<double> array(const std::vector<double>& v) {
  return py::array_t<double>(static_cast<py::ssize_t>(v.size()), v.data());
}

py::array_t<double> matrix(const std::vector<double>& v, std::size_t columns) {
  const auto rows = static_cast<py::ssize_t>(columns ? v.size() / columns : 0);
  return py::array_t<double>({rows, static_cast<py::ssize_t>(columns)}, v.data());
}

py::dict simulate(py::handle masses, py::handle lengths, py::handle g, py::handle theta,
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

  std::vector<double> k(n), k_error(n), kc(n), kc_error(n), tau(n), cosine(n), cosine_error(n);
  for (std::size_t i = 0; i < n; ++i) {
    k[i] = r.kinetic[i].value;
    k_error[i] = r.kinetic[i].error;
    kc[i] = r.kinetic_canonical[i].value;
    kc_error[i] = r.kinetic_canonical[i].error;
    tau[i] = r.kinetic[i].autocorrelation_time;
    cosine[i] = r.cos_angle[i].value;
    cosine_error[i] = r.cos_angle[i].error;
  }
  // No NaN or infinity reaches Python silently (ValueError, one line): every average and
  // energy is finite; an error bar (and what derives from it) may be NaN only when too few
  // blocks finished to estimate it, which error_reason then says. A run stopped by Ctrl-C before
  // its first sample has no average: KeyboardInterrupt.
  if (r.interrupted && r.samples == 0) {
    PyErr_SetString(PyExc_KeyboardInterrupt, "simulate: interrupted before the first sample");
    throw py::error_already_set();
  }
  const bool unknown_errors =
      std::any_of(k_error.begin(), k_error.end(), [](double e) { return !std::isfinite(e); });
  {
    const auto refuse = [](const std::string& name, double x) {
      throw invalid_input("simulate: the result is not finite (" + name + " = " +
                          (std::isnan(x) ? "nan" : x > 0 ? "inf" : "-inf") +
                          "): the trajectory left the finite numbers (try a smaller dt)");
    };
    const auto value = [&](const std::string& name, double x) {
      if (!std::isfinite(x)) refuse(name, x);
    };
    const auto bar = [&](const std::string& name, double x) {
      if (!std::isfinite(x) && !(unknown_errors && std::isnan(x))) refuse(name, x);
    };
    for (std::size_t i = 0; i < n; ++i) {
      const std::string at = "[" + std::to_string(i) + "]";
      value("K" + at, k[i]);
      value("Kc" + at, kc[i]);
      value("cos_phi" + at, cosine[i]);
      bar("K_error" + at, k_error[i]);
      bar("Kc_error" + at, kc_error[i]);
      bar("cos_phi_error" + at, cosine_error[i]);
      bar("K_autocorrelation_time" + at, tau[i]);
    }
    value("K_total", r.kinetic_total.value);
    value("potential", r.potential.value);
    bar("K_total_error", r.kinetic_total.error);
    bar("potential_error", r.potential.error);
    value("energy", energy);
    value("final_energy", r.final_energy);
    value("energy_drift", r.energy_drift);
    value("energy_error_max", r.energy_error_max);
    value("energy_error_rms", r.energy_error_rms);
    bar("energy_trend", r.energy_trend);
    value("constraint_residual", r.constraint_residual);
    if (reference) {
      for (std::size_t i = 0; i < n; ++i) {
        const std::string at = "[" + std::to_string(i) + "]";
        value("exact_K" + at, reference->kinetic[i]);
        value("exact_K_error" + at, reference->kinetic_error[i]);
        value("exact_cos_phi" + at, reference->cos_angle[i]);
        value("exact_cos_phi_error" + at, reference->cos_angle_error[i]);
      }
      value("exact_Kc", reference->kinetic_canonical);
      value("exact_Kc_error", reference->kinetic_canonical_error);
      if (!langevin) {
        value("exact_excitation", reference->excitation);
        for (std::size_t i = 0; i < n; ++i) {
          value("exact_var_K[" + std::to_string(i) + "]", reference->variance[i]);
          value("exact_var_K_error[" + std::to_string(i) + "]", reference->variance_error[i]);
        }
      }
    }
  }
  py::dict out;
  out["ensemble"] = langevin ? "canonical" : "microcanonical";
  out["integrator"] = langevin ? std::string("baoab-rattle")
                               : std::string(integrator_names[static_cast<std::size_t>(
                                     run.integrator.value_or(default_integrator))]);
  out["method"] = method_name(r.method);
  out["N"] = n;
  out["dt"] = run.time_step;
  out["time"] = r.simulated_time;
  out["energy"] = energy;
  out["K"] = array(k);
  out["K_error"] = array(k_error);
  out["Kc"] = array(kc);
  out["Kc_error"] = array(kc_error);
  out["K_autocorrelation_time"] = array(tau);
  out["cos_phi"] = array(cosine);
  out["cos_phi_error"] = array(cosine_error);
  out["K_total"] = r.kinetic_total.value;
  out["K_total_error"] = r.kinetic_total.error;
  out["potential"] = r.potential.value;
  out["potential_error"] = r.potential.error;
  out["error_kind"] = error_kind_name(ErrorKind::statistical);
  if (reference) {
    std::vector<double> deviation(n);
    for (std::size_t i = 0; i < n; ++i)
      deviation[i] = (k[i] - reference->kinetic[i]) / std::hypot(k_error[i], reference->kinetic_error[i]);
    out["exact_K"] = array(reference->kinetic);
    out["exact_K_error"] = array(reference->kinetic_error);
    out["exact_Kc"] = reference->kinetic_canonical;
    out["exact_Kc_error"] = reference->kinetic_canonical_error;
    out["exact_cos_phi"] = array(reference->cos_angle);
    out["exact_cos_phi_error"] = array(reference->cos_angle_error);
    out["K_deviation_sigmas"] = array(deviation);
    out["exact_method"] = reference->method;
    out["exact_error_kind"] = reference->error_kind;
  } else {
    for (const char* name : {"exact_K", "exact_K_error", "exact_Kc", "exact_Kc_error",
                             "exact_cos_phi", "exact_cos_phi_error", "K_deviation_sigmas",
                             "exact_method", "exact_error_kind"})
      out[name] = py::none();
  }
  // NVE: the microcanonical state as D = E - E_min (excitation form) and Var K_i, as the CLI.
  if (reference && !langevin) {
    out["exact_excitation"] = reference->excitation;
    out["exact_var_K"] = array(reference->variance);
    out["exact_var_K_error"] = array(reference->variance_error);
  } else {
    for (const char* name : {"exact_excitation", "exact_var_K", "exact_var_K_error"})
      out[name] = py::none();
  }
  out["error_reason"] =
      unknown_errors ? py::object(py::str(
                           "fewer than 16 averaging blocks finished (interrupted early, or time "
                           "too short for the block length): the error bars are unknown (NaN)"))
                     : py::none();
  out["beta"] = langevin ? py::object(py::float_(*run.beta)) : py::none();
  out["friction"] = langevin ? py::object(py::float_(run.friction.value_or(1))) : py::none();
  out["energy_drift"] = r.energy_drift;
  out["energy_error_max"] = r.energy_error_max;
  out["energy_error_rms"] = r.energy_error_rms;
  out["energy_trend"] = r.energy_trend;
  out["final_energy"] = r.final_energy;
  out["constraint_residual"] = r.constraint_residual;
  out["steps"] = r.steps;
  out["samples"] = r.samples;
  out["newton_solves"] = r.newton_solves;
  out["unconverged_stages"] = r.unconverged_stages;
  out["interrupted"] = r.interrupted;
  out["seconds"] = seconds;
  if (trajectory_every) {
    py::dict trajectory;
    trajectory["t"] = array(t);
    trajectory["E"] = array(e);
    trajectory["phi"] = matrix(phis, n);
    trajectory["phidot"] = matrix(phidots, n);
    out["trajectory"] = trajectory;
  } else {
    out["trajectory"] = py::none();
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
  const std::size_t count = section->points.size();
  py::array_t<std::int64_t> orbit(static_cast<py::ssize_t>(count));
  std::vector<double> phi2, p2, when;
  for (std::size_t k = 0; k < count; ++k) {
    const SectionPoint<double>& p = section->points[k];
    orbit.mutable_data()[k] = static_cast<std::int64_t>(p.orbit);
    phi2.push_back(p.phi2);
    p2.push_back(p.p2);
    when.push_back(p.time);
  }
  for (std::size_t k = 0; k < count; ++k)
    if (!std::isfinite(phi2[k]) || !std::isfinite(p2[k]) || !std::isfinite(when[k]))
      throw invalid_input("poincare: the result is not finite (crossing " + std::to_string(k) +
                          "): the trajectory left the finite numbers (try a smaller dt)");
  if (!std::isfinite(section->energy_error_max))
    throw invalid_input("poincare: the result is not finite (energy_error_max): the trajectory "
                        "left the finite numbers (try a smaller dt)");
  py::dict out;
  out["orbit"] = orbit;
  out["phi2"] = array(phi2);
  out["p2"] = array(p2);
  out["time"] = array(when);
  out["start_phi2"] = array(section->start_phi2);
  out["start_p2"] = array(section->start_p2);
  out["energy"] = section->energy;
  out["energy_error_max"] = section->energy_error_max;
  out["orbits"] = run.orbits;
  out["dt"] = run.time_step;
  out["steps"] = section->steps;
  out["interrupted"] = section->interrupted;
  out["seconds"] = seconds;
  return out;
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
        "A trajectory's time averages as a dict (see pendavg.simulate).");
  m.def("poincare",
        [](py::handle masses, py::handle lengths, py::handle g, py::handle energy,
           py::handle orbits, py::handle points, py::handle dt, const py::object& progress) {
          return without_digits_advice(&poincare)(masses, lengths, g, energy, orbits, points, dt,
                                                  progress);
        }, "masses"_a, "lengths"_a, "g"_a, "energy"_a, "orbits"_a, "points"_a,
        "dt"_a, "progress"_a, "The double pendulum's Poincare section as a dict (see pendavg.poincare).");
  m.def("dynamics_instruction_set", &dynamics_instruction_set,
        "'x86-64-v3' or 'base': the instruction set of the dynamics kernels on this CPU.");
}

}  // namespace pendavg::python
