// src/cli/simulate.cpp -- `pendavg simulate` (a trajectory's time averages beside the exact
// microcanonical or canonical values) and `pendavg poincare` (the double pendulum's section).
// Thin: parse, call the library (dynamics.hpp, microcanonical.hpp, the canonical engines),
// format. Progress goes to stderr; SIGINT/SIGTERM end a run early and the averages so far are
// still printed (with "interrupted": true); files are written atomically.
#include "simulate.hpp"

#include "average_options.hpp"
#include "files.hpp"
#include "format.hpp"
#include "interrupt.hpp"

#include "pendavg/pendavg.hpp"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <numbers>
#include <optional>
#include <string>
#include <vector>

#ifdef _OPENMP
#include <omp.h>
#endif

namespace pendavg::cli {

const std::string_view simulate_usage =
    "usage: pendavg simulate --masses M1,...,MN --lengths L1,...,LN [--g G]\n"
    "                        (--theta A | --phi P1,...,PN [--phidot W1,...,WN])\n"
    "                        --time T [--dt H] [--burn-in T0] [--integrator I]\n"
    "                        [--thermostat none|langevin --beta B [--friction G] [--seed S]]\n"
    "                        [--exact yes|no] [--format json|csv]\n"
    "                        [--trajectory FILE.csv --every K]\n"
    "\n"
    "Integrates the chain (RATTLE in Cartesian coordinates inside a symmetric composition) and\n"
    "prints the time averages <K_i> and <K_i^(c)> (canonical kinetic energy p_i phidot_i / 2)\n"
    "with 1-sigma error bars from blocking, next to the exact values of the run's ensemble:\n"
    "microcanonical at the initial energy (NVE, no thermostat) or canonical at beta (Langevin).\n"
    "  --theta A       all angles A (radians, or degrees with a 'deg' suffix: 90deg), at rest\n"
    "  --phi, --phidot angles from the downward vertical and angular velocities (default 0)\n"
    "  --dt H          time step (default 1e-3); --time T the averaging time; --burn-in T0\n"
    "                  extra time before averaging starts (default 0)\n"
    "  --integrator I  yoshida6 (default: 6th order, 7 stages, energy error ~1e-10 on the\n"
    "                  paper's runs), yoshida4 (the paper's: 4th order, 3 stages, ~1e-7),\n"
    "                  suzuki4, kahan-li6 (6th order, 9 stages), rattle2\n"
    "  --thermostat langevin  constrained BAOAB at --beta B, friction --friction G (default 1)\n"
    "  --exact no      skip the exact values (N >= 5 uses QMC for them: a few seconds)\n"
    "  --trajectory F  every K steps a CSV row t,E,phi_i...,phidot_i... (atomic file)\n"
    "Exact values (exact_*) carry 17 significant digits. The microcanonical ones are taken at\n"
    "the initial state's excitation D = E - E_min = K + sum_j 2 g S_j l_j sin^2(phi_j/2) (no\n"
    "cancellation near the bottom of the well; JSON key exact_excitation, with exact_var_K).\n"
    "Progress goes to stderr. Ctrl-C (SIGINT) or SIGTERM ends the run early; the averages so\n"
    "far are printed with \"interrupted\": true. Energies use the paper's U = -sum_j g S_j l_j\n"
    "cos phi_j (the hanging chain has the lowest energy).\n";

const std::string_view poincare_usage =
    "usage: pendavg poincare --masses M1,M2 --lengths L1,L2 [--g G] --energy E\n"
    "                        [--orbits K] [--points P] [--dt H] [--output FILE.csv]\n"
    "\n"
    "The double pendulum's Poincare section phi_1 = 0, phidot_1 > 0 (paper Appendix E) at\n"
    "energy E (paper's U convention; E > -(M l1 + m2 l2) g): K orbits (default 8) started on\n"
    "the section, P crossings each (default 500), time step H (default 1e-3). Writes CSV rows\n"
    "orbit,phi2,p2,time (p2 the canonical momentum) to stdout or atomically to FILE.\n";

namespace {

constexpr std::array<std::string_view, 5> integrator_names{"rattle2", "yoshida4", "suzuki4",
                                                           "kahan-li6", "yoshida6"};
constexpr std::array<std::string_view, 2> thermostat_names{"none", "langevin"};
constexpr std::array<std::string_view, 2> yes_no{"yes", "no"};
constexpr std::array<std::string_view, 2> simulate_formats{"json", "csv"};

/// Prints "[command] ..." to stderr at most every 2 s, starting after 2 s.
class Progress {
 public:
  explicit Progress(std::string command) : command_(std::move(command)) {}
  void operator()(double fraction, const std::string& detail = "") {
    const double elapsed =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count();
    if (elapsed - last_ < 2) return;
    last_ = elapsed;
    std::fprintf(stderr, "[%s] %3.0f%% %s(%.0f s)\n", command_.c_str(), 100 * fraction,
                 detail.c_str(), elapsed);
  }
  double seconds() const {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count();
  }

 private:
  std::string command_;
  std::chrono::steady_clock::time_point start_ = std::chrono::steady_clock::now();
  double last_ = 0;
};

Chain<double> parse_chain(const Options& options) {
  auto masses = parse_real_list<double>(options.required("masses"), "--masses", Domain::positive);
  auto lengths =
      parse_real_list<double>(options.required("lengths"), "--lengths", Domain::positive);
  if (masses.size() != lengths.size())
    throw usage_error(options.command() + ": " + std::to_string(masses.size()) + " masses but " +
                      std::to_string(lengths.size()) + " lengths");
  const double g = parse_real<double>(options.get("g", "1"), "--g", Domain::nonnegative);
  return Chain<double>(std::move(masses), std::move(lengths), g);
}

/// An angle: radians, or degrees with a "deg" suffix.
double parse_angle(std::string_view text, std::string_view what) {
  constexpr std::string_view suffix = "deg";
  if (text.size() > suffix.size() && text.ends_with(suffix)) {
    const double degrees =
        parse_real<double>(text.substr(0, text.size() - suffix.size()), what, Domain::any);
    return degrees * std::numbers::pi / 180;
  }
  return parse_real<double>(text, what, Domain::any);
}

std::vector<double> parse_angle_list(std::string_view text, std::string_view what) {
  std::vector<double> values;
  for (std::size_t begin = 0;;) {
    const std::size_t comma = std::min(text.find(',', begin), text.size());
    const std::string_view element = text.substr(begin, comma - begin);
    if (element.empty())
      throw usage_error(std::string(what) + ": empty element in list '" + std::string(text) + "'");
    values.push_back(parse_angle(element, what));
    if (comma == text.size()) return values;
    begin = comma + 1;
  }
}

/// Exact values of the run's ensemble, per particle, in energy units.
struct ExactValues {
  std::vector<double> kinetic, kinetic_error, cos_angle, cos_angle_error;
  std::vector<double> variance, variance_error;  ///< microcanonical Var K_i
  double kinetic_canonical = 0, kinetic_canonical_error = 0;
  double excitation = 0;  ///< microcanonical: D = E - E_min of the initial state
  std::string method, error_kind;
};

/// D = E - E_min of the state (phi, phidot) in the excitation form: its kinetic energy plus
/// U - U_min = sum_j 2 gamma_j sin^2(phi_j / 2), so a start near the bottom of the well keeps
/// its digits (E = K + U would lose them to the cancellation of U and E_min).
double initial_excitation(const Chain<double>& chain, const ChainState<double>& state,
                          const std::vector<double>& phi) {
  double potential = 0;
  for (std::size_t j = 0; j < chain.size(); ++j) {
    const double s = std::sin(phi[j] / 2);
    potential += 2 * chain.potential_coefficient(j) * s * s;
  }
  return observables(chain, state).kinetic_total + potential;
}

ExactValues microcanonical_values(const Chain<double>& chain, double excitation) {
  MicrocanonicalOptions options;
  options.threads = hardware_threads();
  const MicrocanonicalAverages<double> r =
      microcanonical_average_excitation(chain, excitation, options);
  ExactValues out;
  out.excitation = r.excitation;
  for (const Estimate<double>& v : r.kinetic_variance) {
    out.variance.push_back(v.value);
    out.variance_error.push_back(v.error);
  }
  for (const Estimate<double>& k : r.kinetic) {
    out.kinetic.push_back(k.value);
    out.kinetic_error.push_back(k.error);
  }
  for (const Estimate<double>& c : r.cos_angle) {
    out.cos_angle.push_back(c.value);
    out.cos_angle_error.push_back(c.error);
  }
  out.kinetic_canonical = r.kinetic_canonical.value;
  out.kinetic_canonical_error = r.kinetic_canonical.error;
  out.method = std::string(method_name(r.method)) + "/" + method_name(r.quadrature);
  out.error_kind = error_kind_name(r.error_kind);
  return out;
}

ExactValues canonical_values(const Chain<double>& chain, double beta) {
  AverageOptions options;
  options.threads = hardware_threads();
  const Averages<double> a = average(chain, beta, options);
  ExactValues out;
  for (std::size_t i = 0; i < chain.size(); ++i) {
    out.kinetic.push_back(a.beta_kinetic[i].value / beta);
    out.kinetic_error.push_back(a.beta_kinetic[i].error / beta);
    out.cos_angle.push_back(a.cos_angle[i].value);
    out.cos_angle_error.push_back(a.cos_angle[i].error);
  }
  // beta <K_i^(c)> = 1/2 exactly (MATH.md Sec. 4).
  out.kinetic_canonical = a.beta_kinetic_canonical.front().value / beta;
  out.method = method_name(a.method);
  out.error_kind = error_kind_name(a.error_kind);
  return out;
}

std::string number(double x) { return decimal(x, 10); }

/// Exact values: every digit of the double (17 significant).
std::string exact_number(double x) { return decimal(x, 17); }

/// The error of an exact value printed with 17 digits (3 digits, half a unit in the value's
/// last printed place included).
std::string exact_error(double value, double error) {
  return decimal(printed_error(value, error, 17), error_digits);
}

std::string number_array(const std::vector<double>& values) {
  std::string out = "[";
  for (std::size_t i = 0; i < values.size(); ++i) out += (i ? ", " : "") + number(values[i]);
  return out + "]";
}

std::string exact_array(const std::vector<double>& values) {
  std::string out = "[";
  for (std::size_t i = 0; i < values.size(); ++i) out += (i ? ", " : "") + exact_number(values[i]);
  return out + "]";
}

std::string exact_error_array(const std::vector<double>& values,
                              const std::vector<double>& errors) {
  std::string out = "[";
  for (std::size_t i = 0; i < values.size(); ++i)
    out += (i ? ", " : "") + exact_error(values[i], errors[i]);
  return out + "]";
}

}  // namespace

std::string simulate_command(const Options& options) {
  const Chain<double> chain = parse_chain(options);
  const std::size_t n = chain.size();
  // Initial condition.
  if (options.has("theta") == options.has("phi"))
    throw usage_error("simulate: give exactly one of --theta and --phi");
  std::vector<double> phi, phidot(n, 0.0);
  if (options.has("theta")) {
    if (options.has("phidot")) throw usage_error("simulate: --phidot goes with --phi");
    phi.assign(n, parse_angle(options.required("theta"), "--theta"));
  } else {
    phi = parse_angle_list(options.required("phi"), "--phi");
    if (phi.size() != n)
      throw usage_error("simulate: --phi has " + std::to_string(phi.size()) + " angles for " +
                        std::to_string(n) + " particles");
    if (options.has("phidot")) {
      phidot = parse_real_list<double>(options.required("phidot"), "--phidot", Domain::any);
      if (phidot.size() != n)
        throw usage_error("simulate: --phidot has " + std::to_string(phidot.size()) +
                          " values for " + std::to_string(n) + " particles");
    }
  }
  SimulationOptions run;
  run.duration = parse_real<double>(options.required("time"), "--time", Domain::positive);
  run.time_step = parse_real<double>(options.get("dt", "1e-3"), "--dt", Domain::positive);
  run.burn_in = parse_real<double>(options.get("burn-in", "0"), "--burn-in", Domain::nonnegative);
  if (run.duration / run.time_step > 1e13 || run.burn_in / run.time_step > 1e13)
    throw usage_error("simulate: more than 1e13 steps (--time / --dt)");
  if (run.duration / run.time_step < 1)
    throw usage_error("simulate: --time is shorter than one step --dt");
  run.integrator = static_cast<Integrator>(
      parse_choice(options.get("integrator", "yoshida6"), "integrator", integrator_names));
  run.thermostat = parse_choice(options.get("thermostat", "none"), "thermostat",
                                thermostat_names) == 1
                       ? Thermostat::langevin
                       : Thermostat::none;
  const bool langevin = run.thermostat == Thermostat::langevin;
  if (langevin) {
    run.beta = parse_real<double>(options.required("beta"), "--beta", Domain::positive);
    run.friction =
        parse_real<double>(options.get("friction", "1"), "--friction", Domain::positive);
    run.seed = parse_unsigned(options.get("seed", "1"), "--seed");
    if (options.has("integrator"))
      throw usage_error("simulate: --integrator is for NVE runs (Langevin uses BAOAB)");
  } else {
    for (const char* name : {"beta", "friction", "seed"})
      if (options.has(name))
        throw usage_error("simulate: --" + std::string(name) + " needs --thermostat langevin");
  }
  const bool exact = parse_choice(options.get("exact", "yes"), "--exact value", yes_no) == 0;
  const bool csv = parse_choice(options.get("format", "json"), "format", simulate_formats) == 1;
  if (options.has("trajectory") != options.has("every"))
    throw usage_error("simulate: --trajectory and --every go together");
  std::optional<AtomicFile> trajectory;
  DynamicsObserver<double> observer;
  std::string buffer;
  if (options.has("trajectory")) {
    observer.trajectory_every = static_cast<std::size_t>(
        parse_integer(options.required("every"), "--every", 1, 1000000000));
    trajectory.emplace(std::string(options.required("trajectory")), "simulate");
    buffer = "t,E";
    for (std::size_t i = 1; i <= n; ++i) buffer += ",phi" + std::to_string(i);
    for (std::size_t i = 1; i <= n; ++i) buffer += ",phidot" + std::to_string(i);
    buffer += "\n";
    observer.trajectory = [&](const ChainState<double>& state) {
      const ChainObservables<double> o = observables(chain, state);
      const auto add = [&](double value) {
        buffer += ',';
        append_decimal(buffer, value, 15);
      };
      append_decimal(buffer, state.time, 12);
      add(o.energy);
      for (const double v : o.phi) add(v);
      for (const double v : o.phidot) add(v);
      buffer += '\n';
      if (buffer.size() > (1 << 20)) {
        trajectory->append(buffer);
        buffer.clear();
      }
    };
  }

  ChainState<double> initial = state_from_angles(chain, phi, phidot);
  const double energy = total_energy(chain, initial);
  Progress progress("simulate");
  observer.progress = [&](double fraction) { progress(fraction); };
  StopOnSignal signals;
  observer.stop = &stop_flag();
  const SimulationResult<double> r = simulate(chain, initial, run, observer);
  const double seconds = progress.seconds();
  if (trajectory) {
    trajectory->append(buffer);
    trajectory->commit();
  }
  if (r.interrupted)
    std::fprintf(stderr, "[simulate] interrupted at t = %.6g: averages of the run so far\n",
                 r.simulated_time);

  std::optional<ExactValues> reference;
  if (exact)
    reference = langevin ? canonical_values(chain, run.beta)
                         : microcanonical_values(chain, initial_excitation(chain, initial, phi));

  std::vector<double> k(n), k_error(n), kc(n), kc_error(n), tau(n), cosine(n), cosine_error(n);
  for (std::size_t i = 0; i < n; ++i) {
    cosine[i] = r.cos_angle[i].value;
    cosine_error[i] = r.cos_angle[i].error;
    k[i] = r.kinetic[i].value;
    k_error[i] = r.kinetic[i].error;
    kc[i] = r.kinetic_canonical[i].value;
    kc_error[i] = r.kinetic_canonical[i].error;
    tau[i] = r.kinetic[i].autocorrelation_time;
  }
  const std::string ensemble = langevin ? "canonical" : "microcanonical";
  const std::string integrator = langevin ? "baoab-rattle"
                                          : std::string(integrator_names[static_cast<std::size_t>(
                                                run.integrator)]);
  if (csv) {
    std::string out = "# pendavg simulate: ensemble " + ensemble + ", integrator " + integrator +
                      ", dt " + number(run.time_step) + ", time " + number(r.simulated_time) +
                      ", steps " + std::to_string(r.steps) + (r.interrupted ? " (interrupted)" : "") +
                      "\n# energy " + number(energy) + ", energy_drift " +
                      decimal(r.energy_drift, 3) + ", energy_error_max " +
                      decimal(r.energy_error_max, 3) + ", constraint_residual " +
                      decimal(r.constraint_residual, 3) +
                      (reference ? ", exact " + reference->method : std::string()) + "\n";
    out += "i,K,K_error,Kc,Kc_error,exact_K,exact_K_error,exact_Kc,K_autocorrelation_time\n";
    for (std::size_t i = 0; i < n; ++i) {
      out += std::to_string(i + 1) + "," + number(k[i]) + "," + decimal(k_error[i], 3) + "," +
             number(kc[i]) + "," + decimal(kc_error[i], 3) + "," +
             (reference ? exact_number(reference->kinetic[i]) + "," +
                              exact_error(reference->kinetic[i], reference->kinetic_error[i]) +
                              "," + exact_number(reference->kinetic_canonical)
                        : std::string(",,")) +
             "," + decimal(tau[i], 3) + "\n";
    }
    return out;
  }
  JsonObject json;
  json.string("ensemble", ensemble)
      .string("integrator", integrator)
      .integer("particles", static_cast<long long>(n))
      .raw("dt", number(run.time_step))
      .raw("time", number(r.simulated_time))
      .raw("energy", number(energy))
      .raw("K", number_array(k))
      .raw("K_error", number_array(k_error))
      .raw("Kc", number_array(kc))
      .raw("Kc_error", number_array(kc_error))
      .raw("K_autocorrelation_time", number_array(tau))
      .raw("cos_phi", number_array(cosine))
      .raw("cos_phi_error", number_array(cosine_error))
      .string("error_kind", error_kind_name(ErrorKind::statistical));
  if (reference) {
    std::vector<double> deviation(n);
    for (std::size_t i = 0; i < n; ++i)
      deviation[i] = (k[i] - reference->kinetic[i]) /
                     std::hypot(k_error[i], reference->kinetic_error[i]);
    json.raw("exact_K", exact_array(reference->kinetic))
        .raw("exact_K_error", exact_error_array(reference->kinetic, reference->kinetic_error))
        .raw("exact_Kc", exact_number(reference->kinetic_canonical))
        .raw("exact_cos_phi", exact_array(reference->cos_angle))
        .raw("K_deviation_sigmas", number_array(deviation))
        .string("exact_method", reference->method)
        .raw("exact_Kc_error",
             exact_error(reference->kinetic_canonical, reference->kinetic_canonical_error))
        .raw("exact_cos_phi_error",
             exact_error_array(reference->cos_angle, reference->cos_angle_error))
        .string("exact_error_kind", reference->error_kind);
  } else {
    json.raw("exact_K", "null");
  }
  if (langevin) json.raw("beta", number(run.beta)).raw("friction", number(run.friction));
  json.raw("energy_drift", decimal(r.energy_drift, 3))
      .raw("energy_error_max", decimal(r.energy_error_max, 3))
      .raw("energy_error_rms", decimal(r.energy_error_rms, 3))
      .raw("constraint_residual", decimal(r.constraint_residual, 3))
      .integer("steps", static_cast<long long>(r.steps))
      .integer("newton_solves", static_cast<long long>(r.newton_solves))
      .boolean("interrupted", r.interrupted)
      .raw("seconds", seconds_text(seconds));
  if (reference && !langevin) {
    // appended: the microcanonical state as D = E - E_min (excitation form) and Var K_i
    json.raw("exact_excitation", exact_number(reference->excitation))
        .raw("exact_var_K", exact_array(reference->variance))
        .raw("exact_var_K_error",
             exact_error_array(reference->variance, reference->variance_error));
  }
  return json.str() + "\n";
}

std::string poincare_command(const Options& options) {
  const Chain<double> chain = parse_chain(options);
  if (chain.size() != 2) throw usage_error("poincare: the section is for N = 2 (two masses)");
  const double energy = parse_real<double>(options.required("energy"), "--energy", Domain::any);
  PoincareOptions run;
  run.orbits = static_cast<std::size_t>(
      parse_integer(options.get("orbits", "8"), "--orbits", 1, 10000));
  run.points = static_cast<std::size_t>(
      parse_integer(options.get("points", "500"), "--points", 1, 100000000));
  run.time_step = parse_real<double>(options.get("dt", "1e-3"), "--dt", Domain::positive);
  run.threads = hardware_threads();
  std::optional<std::string> output;
  if (options.has("output")) {
    output = std::string(options.required("output"));
    probe_output(*output, "poincare");
  }
  Progress progress("poincare");
  DynamicsObserver<double> observer;
  observer.progress = [&](double fraction) { progress(fraction, "of the orbits "); };
  StopOnSignal signals;
  observer.stop = &stop_flag();
  const PoincareSection<double> section = poincare_section(chain, energy, run, observer);
  if (section.interrupted) std::fprintf(stderr, "[poincare] interrupted: points so far\n");
  std::string out = "# pendavg poincare: section phi1 = 0, phidot1 > 0; energy " +
                    number(energy) + ", orbits " + std::to_string(run.orbits) +
                    ", dt " + number(run.time_step) + ", steps " +
                    std::to_string(section.steps) + ", energy_error_max " +
                    decimal(section.energy_error_max, 3) +
                    (section.interrupted ? ", interrupted" : "") + "\n";
  out += "orbit,phi2,p2,time\n";
  for (const SectionPoint<double>& p : section.points)
    out += std::to_string(p.orbit) + "," + decimal(p.phi2, 12) + "," + decimal(p.p2, 12) + "," +
           decimal(p.time, 10) + "\n";
  if (output) {
    write_atomically(*output, out, "poincare");
    return "";
  }
  return out;
}

}  // namespace pendavg::cli
