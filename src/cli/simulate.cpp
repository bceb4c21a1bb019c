// SPDX-License-Identifier: GPL-3.0-or-later
// src/cli/simulate.cpp -- `pendavg simulate` (a trajectory's time averages beside the exact
// microcanonical or canonical values) and `pendavg poincare` (the double pendulum's section).
// Thin: parse, call the library (dynamics.hpp, microcanonical.hpp, the canonical engines),
// format. Progress goes to stderr; SIGINT/SIGTERM end a run early and the averages so far are
// still printed (with "interrupted": true); files are written atomically.
#include "common.hpp"

#include "average_options.hpp"
#include "distribute.hpp"
#include "exact_values.hpp"
#include "files.hpp"
#include "format.hpp"
#include "interrupt.hpp"
#include "sweep.hpp"

#include "pendavg/pendavg.hpp"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <limits>
#include <numbers>
#include <random>
#include <optional>
#include <string>
#include <vector>

#ifdef _OPENMP
#include <omp.h>
#endif

namespace pendavg::cli {

constexpr std::string_view simulate_usage =
    "usage: pendavg simulate --masses M1,...,MN --lengths L1,...,LN [--g G]\n"
    "                        (--theta A | --phi P1,...,PN [--phidot W1,...,WN])\n"
    "                        --time T [--dt H] [--burn-in T0] [--integrator I]\n"
    "                        [--thermostat none|langevin --beta B [--friction G] [--seed S]]\n"
    "                        [--exact yes|no] [--format json|csv]\n"
    "                        [--trajectory FILE.csv --every K]\n"
    "                        [--replicas R [--seed S] [--perturb EPS]]\n"
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
    "  --replicas R    R independent trajectories on all cores (and all MPI ranks under\n"
    "                  mpirun/srun), combined: Langevin replicas differ by their noise (seeds\n"
    "                  mixed from --seed), NVE replicas by their start (every angle moved by up\n"
    "                  to --perturb EPS radians, default 1e-6, at most 0.1, from --seed; replica 0\n"
    "                  unmoved), then brought back to the run's energy (rates scaled, or the\n"
    "                  angles moved along grad U when at rest), so all sample one shell.\n"
    "                  K_error is then the larger of the blocking error of the mean and the\n"
    "                  standard error of the spread between replicas (both printed, as\n"
    "                  K_error_blocking and K_error_replicas); the result is the same for any\n"
    "                  number of ranks and threads.\n"
    "Exact values (exact_*) carry 17 significant digits. The microcanonical ones are taken at\n"
    "the initial state's excitation D = E - E_min = K + sum_j 2 g S_j l_j sin^2(phi_j/2) (no\n"
    "cancellation near the bottom of the well; JSON key exact_excitation, with exact_var_K).\n"
    "JSON also has, after seconds: K_total and potential (<K> and <U> over time) with their\n"
    "errors, energy_trend (NVE: the least-squares change of E over the run / the energy scale;\n"
    "null with energy_trend_reason under Langevin), unconverged_stages, samples, exact_var_K for\n"
    "Langevin runs (canonical Var K_i), exact_error_kinds (what each exact error promises) and,\n"
    "with --replicas, K_total_error_blocking/replicas and potential_error_blocking/replicas.\n"
    "CSV columns: i, K, K_error, Kc, Kc_error, exact_K, exact_K_error, exact_Kc,\n"
    "K_autocorrelation_time [, K_error_blocking, K_error_replicas], then cos_phi, cos_phi_error,\n"
    "error_kind, exact_cos_phi, exact_cos_phi_error, exact_Kc_error, exact_var_K,\n"
    "exact_var_K_error, exact_error_kind, exact_Kc_error_kind, exact_cos_phi_error_kind,\n"
    "exact_var_K_error_kind [, Kc_error_blocking, Kc_error_replicas, cos_phi_error_blocking,\n"
    "cos_phi_error_replicas] (cells that do not exist are empty).\n"
    "Progress goes to stderr. Ctrl-C (SIGINT) or SIGTERM ends the run early; the averages so\n"
    "far are printed with \"interrupted\": true. Energies use the paper's U = -sum_j g S_j l_j\n"
    "cos phi_j (the hanging chain has the lowest energy).\n";

constexpr std::string_view poincare_usage =
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

/// A JSON number; null for a value that does not exist (an unknown error bar).
std::string number(double x) { return std::isfinite(x) ? decimal(x, 10) : std::string("null"); }

/// An error-sized JSON number (3 digits); null when it does not exist.
std::string error_number(double x) {
  return std::isfinite(x) ? decimal(x, 3) : std::string("null");
}

/// A CSV cell: empty for a value that does not exist.
std::string cell(double x, int digits) { return std::isfinite(x) ? decimal(x, digits) : std::string(); }

/// Exact values: every digit of the double (17 significant).
std::string exact_number(double x) { return decimal(x, 17); }

/// The error of an exact value printed with 17 digits (3 digits, half a unit in the value's
/// last printed place included).
std::string exact_error(double value, double error) {
  return decimal(printed_error(value, error, 17), error_digits);
}

/// An exact value as a JSON number, null when it is not finite (e.g. Var K_i beyond double's
/// range at a tiny beta).
std::string exact_json(double x) { return std::isfinite(x) ? exact_number(x) : "null"; }

/// An exact value's error as JSON (null beside a value that is not finite).
std::string exact_error_json(double value, double error) {
  return std::isfinite(value) && std::isfinite(error) ? exact_error(value, error) : "null";
}

/// CSV cells of an exact value and its error: empty when they do not exist.
std::string exact_cell(double x) { return std::isfinite(x) ? exact_number(x) : std::string(); }
std::string exact_error_cell(double value, double error) {
  return std::isfinite(value) && std::isfinite(error) ? exact_error(value, error) : std::string();
}

std::string number_array(const std::vector<double>& values) {
  std::string out = "[";
  for (std::size_t i = 0; i < values.size(); ++i) out += (i ? ", " : "") + number(values[i]);
  return out + "]";
}

constexpr long max_replicas = 100000;
constexpr double max_perturbation = 0.1;  ///< radians (--perturb)

/// A replica's seed: replica 0 runs with --seed itself (as a single run does), the others with
/// seeds mixed from it (splitmix64), so their noise streams and perturbations are independent.
std::uint64_t replica_seed(std::uint64_t seed, std::size_t replica) {
  if (replica == 0) return seed;
  std::uint64_t z = seed + 0x9e3779b97f4a7c15ull * static_cast<std::uint64_t>(replica);
  z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ull;
  z = (z ^ (z >> 27)) * 0x94d049bb133111ebull;
  return z ^ (z >> 31);
}

/// What --replicas adds to a run's report: the two error bars of every average (blocking within
/// the replicas; the spread between them) and how far the replicas' energies lie apart.
struct ReplicaSpread {
  std::size_t replicas = 0, requested = 0;  ///< finished (also when interrupted), asked for
  std::vector<double> kinetic_blocking, kinetic_replicas, canonical_blocking, canonical_replicas,
      cosine_blocking, cosine_replicas;
  double total_blocking = 0, total_replicas = 0;          ///< of <K>
  double potential_blocking = 0, potential_replicas = 0;  ///< of <U>
  double energy_spread = 0;  ///< largest |E_r - E| over the replicas (NVE perturbed starts)
};

/// Weighted mean over replicas in replica order (West's update: the same bits for any split of
/// the replicas between ranks), with the blocking error of the mean and the standard error of
/// the spread between replicas.
struct ReplicaMean {
  double weight = 0, mean = 0, spread_sum = 0, blocking_sum = 0, tau_sum = 0;
  void add(double w, const TimeAverage<double>& x) {
    weight += w;
    const double delta = x.value - mean;
    mean += w / weight * delta;
    spread_sum += w * delta * (x.value - mean);
    blocking_sum += w * w * x.error * x.error;
    tau_sum += w * x.autocorrelation_time;
  }
  double blocking() const { return std::sqrt(blocking_sum) / weight; }
  double replica_error(std::size_t replicas) const {
    const double r = static_cast<double>(replicas);
    return replicas > 1 ? std::sqrt(spread_sum / weight * r / (r - 1) / r) : 0.0;
  }
};

/// Doubles in one replica's packed result: 3 per time average (3n + 2 of them) and 10 more.
std::size_t packed_replica_doubles(std::size_t n) { return 9 * n + 18; }

/// One replica's result as bytes (the sweep engine moves rows as text).
std::string pack_replica(const SimulationResult<double>& r) {
  std::vector<double> v;
  for (const auto* list : {&r.kinetic, &r.kinetic_canonical, &r.cos_angle})
    for (const TimeAverage<double>& x : *list) v.insert(v.end(), {x.value, x.error, x.autocorrelation_time});
  for (const TimeAverage<double>* x : {&r.kinetic_total, &r.potential})
    v.insert(v.end(), {x->value, x->error, x->autocorrelation_time});
  v.insert(v.end(), {r.initial_energy, r.energy_drift, r.energy_error_max, r.energy_error_rms,
                     r.constraint_residual, r.simulated_time, static_cast<double>(r.steps),
                     static_cast<double>(r.samples), static_cast<double>(r.newton_solves),
                     r.interrupted ? 1.0 : 0.0, r.energy_trend,
                     static_cast<double>(r.unconverged_stages)});
  return std::string(reinterpret_cast<const char*>(v.data()), v.size() * sizeof(double));
}

SimulationResult<double> unpack_replica(std::string_view bytes, std::size_t n) {
  std::vector<double> v(bytes.size() / sizeof(double));
  std::memcpy(v.data(), bytes.data(), v.size() * sizeof(double));
  SimulationResult<double> r;
  std::size_t k = 0;
  for (auto* list : {&r.kinetic, &r.kinetic_canonical, &r.cos_angle}) {
    list->resize(n);
    for (TimeAverage<double>& x : *list) {
      x.value = v[k++];
      x.error = v[k++];
      x.autocorrelation_time = v[k++];
    }
  }
  for (TimeAverage<double>* x : {&r.kinetic_total, &r.potential}) {
    x->value = v[k++];
    x->error = v[k++];
    x->autocorrelation_time = v[k++];
  }
  r.initial_energy = v[k++];
  r.energy_drift = v[k++];
  r.energy_error_max = v[k++];
  r.energy_error_rms = v[k++];
  r.constraint_residual = v[k++];
  r.simulated_time = v[k++];
  r.steps = static_cast<std::size_t>(v[k++]);
  r.samples = static_cast<std::size_t>(v[k++]);
  r.newton_solves = static_cast<std::size_t>(v[k++]);
  r.interrupted = v[k++] != 0;
  r.energy_trend = v[k++];
  r.unconverged_stages = static_cast<std::size_t>(v[k++]);
  return r;
}

/// Rank 0's side of the replicas: each finished replica (in order) joins the means.
class ReplicaCombiner : public SweepOutput {
 public:
  ReplicaCombiner(std::size_t n, double energy)
      : n_(n), energy_(energy), kinetic_(n), canonical_(n), cosine_(n), total_(1), potential_(1) {}
  void write_rows(std::size_t, std::size_t count, std::string_view text,
                  std::span<const double>) override {
    const std::size_t size = text.size() / count;
    for (std::size_t k = 0; k < count; ++k) add(unpack_replica(text.substr(k * size, size), n_));
  }
  /// The combined run (averages, summed work, largest errors) and the spread.
  SimulationResult<double> result(ReplicaSpread& spread) const {
    SimulationResult<double> out = totals_;
    spread.replicas = replicas_;
    spread.energy_spread = energy_spread_;
    const auto fill = [&](const std::vector<ReplicaMean>& means, std::vector<TimeAverage<double>>& to,
                          std::vector<double>& blocking, std::vector<double>& replicas) {
      const std::size_t count = means.size();
      to.resize(count);
      blocking.resize(count);
      replicas.resize(count);
      for (std::size_t i = 0; i < count; ++i) {
        blocking[i] = means[i].blocking();  // NaN when a replica's blocking error is unknown
        replicas[i] = replicas_ > 1 ? means[i].replica_error(replicas_)
                                    : std::numeric_limits<double>::quiet_NaN();
        to[i].value = means[i].mean;
        // The larger of the two that are known (NaN, printed null, when neither is).
        to[i].error = std::isnan(blocking[i])   ? replicas[i]
                      : std::isnan(replicas[i]) ? blocking[i]
                                                : std::max(blocking[i], replicas[i]);
        to[i].autocorrelation_time = means[i].tau_sum / means[i].weight;
      }
    };
    fill(kinetic_, out.kinetic, spread.kinetic_blocking, spread.kinetic_replicas);
    fill(canonical_, out.kinetic_canonical, spread.canonical_blocking, spread.canonical_replicas);
    fill(cosine_, out.cos_angle, spread.cosine_blocking, spread.cosine_replicas);
    const auto fill_one = [&](const std::vector<ReplicaMean>& mean, TimeAverage<double>& to,
                              double& blocking, double& replicas) {
      std::vector<TimeAverage<double>> one;
      std::vector<double> b, r;
      fill(mean, one, b, r);
      to = one[0];
      blocking = b[0];
      replicas = r[0];
    };
    fill_one(total_, out.kinetic_total, spread.total_blocking, spread.total_replicas);
    fill_one(potential_, out.potential, spread.potential_blocking, spread.potential_replicas);
    return out;
  }
  std::size_t replicas() const { return replicas_; }

 private:
  void add(const SimulationResult<double>& r) {
    const double w = static_cast<double>(std::max<std::size_t>(r.samples, 1));
    for (std::size_t i = 0; i < n_; ++i) {
      kinetic_[i].add(w, r.kinetic[i]);
      canonical_[i].add(w, r.kinetic_canonical[i]);
      cosine_[i].add(w, r.cos_angle[i]);
    }
    total_[0].add(w, r.kinetic_total);
    potential_[0].add(w, r.potential);
    const auto larger = [](double a, double b) { return std::abs(b) > std::abs(a) ? b : a; };
    totals_.energy_drift = larger(totals_.energy_drift, r.energy_drift);
    totals_.energy_trend = larger(totals_.energy_trend, r.energy_trend);
    totals_.energy_error_max = std::max(totals_.energy_error_max, r.energy_error_max);
    totals_.energy_error_rms = std::max(totals_.energy_error_rms, r.energy_error_rms);
    totals_.constraint_residual = std::max(totals_.constraint_residual, r.constraint_residual);
    totals_.simulated_time += r.simulated_time;
    totals_.steps += r.steps;
    totals_.samples += r.samples;
    totals_.newton_solves += r.newton_solves;
    totals_.unconverged_stages += r.unconverged_stages;
    totals_.interrupted = totals_.interrupted || r.interrupted;
    energy_spread_ = std::max(energy_spread_, std::abs(r.initial_energy - energy_));
    ++replicas_;
  }
  std::size_t n_;
  double energy_;
  std::vector<ReplicaMean> kinetic_, canonical_, cosine_;
  std::vector<ReplicaMean> total_, potential_;  ///< <K> and <U> (one each)
  SimulationResult<double> totals_;
  std::size_t replicas_ = 0;
  double energy_spread_ = 0;
};

/// R independent trajectories on every rank and thread (sweep.hpp): Langevin runs from the same
/// start with their own noise (replica_seed), NVE runs from the start with every angle moved by
/// up to `perturbation` (uniform, from replica_seed; replica 0 unmoved). Rank 0 returns the
/// spread and sets `combined` to the combined run.
ReplicaSpread simulate_replicas(const Chain<double>& chain, const std::vector<double>& phi,
                                const std::vector<double>& phidot, const SimulationOptions& run,
                                std::uint64_t seed, std::size_t replicas, double perturbation,
                                double energy, SimulationResult<double>& combined) {
  const std::size_t n = chain.size();
  SweepRows rows;
  rows.count = replicas;
  rows.threads = hardware_threads();
  rows.row_bytes = packed_replica_doubles(n) * sizeof(double);
  rows.grace_seconds = 5;  // a replica stops within 1024 steps and reports its averages so far
  rows.progress = "simulate";
  rows.unit = "replicas";
  rows.compute = [&](std::size_t replica, int, std::string& out) {
    SimulationOptions options = run;
    const std::uint64_t own_seed = replica_seed(seed, replica);
    if (run.thermostat == Thermostat::langevin) options.seed = own_seed;
    std::vector<double> start = phi;
    ChainState<double> initial;
    if (run.thermostat == Thermostat::none && replica > 0) {
      std::mt19937_64 random(own_seed);
      for (double& angle : start)
        angle += perturbation * (2 * (static_cast<double>(random() >> 11) * 0x1.0p-53) - 1);
      // Replicas of an NVE run sample one energy shell: the perturbed start is brought back to
      // the run's energy (combining averages at different energies would mix ensembles).
      initial = state_at_energy(chain, start, phidot, energy);
    } else {
      initial = state_from_angles(chain, start, phidot);
    }
    DynamicsObserver<double> observer;
    observer.stop = &stop_flag();
    out += pack_replica(simulate(chain, std::move(initial), options, observer));
  };
  const StopOnSignal signals;
  std::optional<ReplicaCombiner> combiner;
  if (is_root()) combiner.emplace(n, energy);
  ReplicaSpread spread;
  spread.requested = replicas;
  run_sweep(rows, combiner ? &*combiner : nullptr, [&](const SweepOutcome& outcome) {
    rethrow_failure(outcome, [](std::size_t replica) {
      return "simulate: replica " + std::to_string(replica) + ": ";
    });
    if (combiner->replicas() == 0)
      throw usage_error("simulate: interrupted before any replica reported");
    combined = combiner->result(spread);
    combined.interrupted = combined.interrupted || outcome.interrupted;
  });
  return spread;
}

std::string exact_array(const std::vector<double>& values) {
  std::string out = "[";
  for (std::size_t i = 0; i < values.size(); ++i) out += (i ? ", " : "") + exact_json(values[i]);
  return out + "]";
}

std::string exact_error_array(const std::vector<double>& values,
                              const std::vector<double>& errors) {
  std::string out = "[";
  for (std::size_t i = 0; i < values.size(); ++i)
    out += (i ? ", " : "") + exact_error_json(values[i], errors[i]);
  return out + "]";
}

// ---------------------------------------------------------------- simulate_command's steps

/// A `simulate` run as asked for: the start, the library's options and the CLI's own.
struct SimulateRequest {
  std::vector<double> phi, phidot;  ///< the initial angles and rates
  SimulationOptions run;
  bool langevin = false;
  std::size_t replicas = 1;
  std::uint64_t seed = 1;     ///< --seed: the Langevin noise, or the replicas' perturbed starts
  double perturbation = 0;    ///< --perturb (NVE replicas)
  bool exact = true;          ///< --exact yes
  bool csv = false;           ///< --format csv
  std::size_t every = 0;      ///< --every K (with --trajectory)
};

/// Step 1, parse: the initial condition (--theta or --phi [--phidot]), then the run.
SimulateRequest parse_simulate_request(const Options& options, std::size_t n) {
  SimulateRequest request;
  // Initial condition.
  if (options.has("theta") == options.has("phi"))
    throw usage_error("simulate: give exactly one of --theta and --phi");
  std::vector<double>& phi = request.phi;
  std::vector<double>& phidot = request.phidot;
  phidot.assign(n, 0.0);
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
  // The library checks the run (steps, and which settings the thermostat uses) before any work;
  // only the replicas' use of --seed and --perturb is the CLI's own.
  SimulationOptions& run = request.run;
  run.duration = parse_real<double>(options.required("time"), "--time", Domain::positive);
  run.time_step = parse_real<double>(options.get("dt", "1e-3"), "--dt", Domain::positive);
  run.burn_in = parse_real<double>(options.get("burn-in", "0"), "--burn-in", Domain::nonnegative);
  if (options.has("integrator"))
    run.integrator = static_cast<Integrator>(
        parse_choice(options.required("integrator"), "integrator", integrator_names));
  run.thermostat = parse_choice(options.get("thermostat", "none"), "thermostat",
                                thermostat_names) == 1
                       ? Thermostat::langevin
                       : Thermostat::none;
  const bool langevin = request.langevin = run.thermostat == Thermostat::langevin;
  request.replicas = static_cast<std::size_t>(
      parse_integer(options.get("replicas", "1"), "--replicas", 1, max_replicas));
  if (langevin && !options.has("beta")) throw usage_error("simulate: missing required option --beta");
  if (options.has("beta"))
    run.beta = parse_real<double>(options.required("beta"), "--beta", Domain::positive);
  if (options.has("friction"))
    run.friction = parse_real<double>(options.required("friction"), "--friction", Domain::positive);
  // --seed: the Langevin noise, or (NVE) the replicas' perturbed starts.
  request.seed = parse_unsigned(options.get("seed", "1"), "--seed");
  if (langevin) {
    if (options.has("seed")) run.seed = request.seed;
    if (options.has("perturb"))
      throw usage_error("simulate: --perturb is for NVE replicas (Langevin replicas differ by "
                        "their noise)");
  } else if (request.replicas == 1) {
    for (const char* name : {"seed", "perturb"})
      if (options.has(name))
        throw usage_error("simulate: --" + std::string(name) +
                          " needs --thermostat langevin or --replicas R > 1");
  }
  try {
    check_simulation_options(run);
  } catch (const invalid_input& bad) {
    throw usage_error(bad.what());
  }
  request.perturbation =
      parse_real<double>(options.get("perturb", "1e-6"), "--perturb", Domain::positive);
  // A perturbation decorrelates replicas; beyond 0.1 rad the starts are different runs, and the
  // energy correction (state_at_energy) has no nearby state to reach.
  if (!(request.perturbation <= max_perturbation))
    throw usage_error("simulate: --perturb must be in (0, 0.1] radians");
  request.exact = parse_choice(options.get("exact", "yes"), "--exact value", yes_no) == 0;
  request.csv = parse_choice(options.get("format", "json"), "format", simulate_formats) == 1;
  if (options.has("trajectory") != options.has("every"))
    throw usage_error("simulate: --trajectory and --every go together");
  if (request.replicas > 1 && options.has("trajectory"))
    throw usage_error("simulate: --trajectory records one run; it does not go with --replicas");
  if (options.has("every"))
    request.every = static_cast<std::size_t>(
        parse_integer(options.required("every"), "--every", 1, 1000000000));
  return request;
}

/// --trajectory FILE --every K: every K steps a CSV row t,E,phi_i...,phidot_i..., buffered and
/// written atomically (commit() after the run).
class TrajectoryFile {
 public:
  TrajectoryFile(const Options& options, std::size_t every, const Chain<double>& chain)
      : chain_(chain), every_(every) {
    if (!options.has("trajectory")) return;
    file_.emplace(std::string(options.required("trajectory")), "simulate");
    buffer_ = "t,E";
    for (std::size_t i = 1; i <= chain.size(); ++i) buffer_ += ",phi" + std::to_string(i);
    for (std::size_t i = 1; i <= chain.size(); ++i) buffer_ += ",phidot" + std::to_string(i);
    buffer_ += "\n";
  }
  TrajectoryFile(const TrajectoryFile&) = delete;
  TrajectoryFile& operator=(const TrajectoryFile&) = delete;

  /// Makes `observer` record into this file (nothing without --trajectory).
  void attach(DynamicsObserver<double>& observer) {
    if (!file_) return;
    observer.trajectory_every = every_;
    observer.trajectory = [this](const ChainState<double>& state) { record(state); };
  }
  void commit() {
    if (!file_) return;
    file_->append(buffer_);
    file_->commit();
  }

 private:
  void record(const ChainState<double>& state) {
    const ChainObservables<double> o = observables(chain_, state);
    const auto add = [&](double value) {
      buffer_ += ',';
      append_decimal(buffer_, value, 15);
    };
    append_decimal(buffer_, state.time, 12);
    add(o.energy);
    for (const double v : o.phi) add(v);
    for (const double v : o.phidot) add(v);
    buffer_ += '\n';
    if (buffer_.size() > (1 << 20)) {
      file_->append(buffer_);
      buffer_.clear();
    }
  }
  const Chain<double>& chain_;
  std::size_t every_ = 0;
  std::optional<AtomicFile> file_;
  std::string buffer_;
};

/// What a run produced: the (combined) time averages, the replicas' spread, the exact values.
struct SimulateOutcome {
  SimulationResult<double> result;
  std::optional<ReplicaSpread> spread;     ///< --replicas R > 1
  std::optional<ExactValues> reference;    ///< --exact yes
  double energy = 0;                       ///< E of the initial state
  double seconds = 0;                      ///< the trajectories' wall time
};

/// Step 2, run: the run's own checks (check_simulation), then the exact values (a request they
/// cannot serve, e.g. the chain at rest at the bottom with no accessible states, is refused
/// before any integration, and a run stopped by a signal still prints them), then one trajectory
/// or the replicas. Only rank 0 returns an outcome.
std::optional<SimulateOutcome> run_simulation(const Chain<double>& chain,
                                              const SimulateRequest& request,
                                              TrajectoryFile& trajectory) {
  SimulateOutcome out;
  const ChainState<double> initial = state_from_angles(chain, request.phi, request.phidot);
  // Everything the run refuses is refused first, before the exact values (seconds for N >= 4).
  check_simulation(chain, initial, request.run);
  out.energy = total_energy(chain, initial);
  if (request.exact) {
    try {
      out.reference =
          request.langevin
              ? canonical_values(chain, *request.run.beta)
              : microcanonical_values(chain, initial_excitation(chain, initial, request.phi));
    } catch (const invalid_input& e) {
      // The exact values' refusal, without its advice to request digits (simulate has no
      // --digits): the way out here is --exact no.
      std::string why = e.what();
      const std::size_t advice = why.find("; request ");
      if (advice != std::string::npos) why.erase(advice);
      throw invalid_input(why + "; --exact no runs the trajectory without the exact values");
    }
  }
  Progress progress("simulate");
  SimulationResult<double>& r = out.result;
  if (request.replicas == 1) {
    DynamicsObserver<double> observer;
    trajectory.attach(observer);
    observer.progress = [&](double fraction) { progress(fraction); };
    StopOnSignal signals;
    observer.stop = &stop_flag();
    r = simulate(chain, initial, request.run, observer);
  } else {
    out.spread = simulate_replicas(chain, request.phi, request.phidot, request.run, request.seed,
                                   request.replicas, request.perturbation, out.energy, r);
    if (!is_root()) return std::nullopt;
  }
  out.seconds = progress.seconds();
  trajectory.commit();
  if (r.interrupted)
    std::fprintf(stderr, "[simulate] interrupted at t = %.6g: averages of the run so far\n",
                 r.simulated_time);
  return out;
}

/// The averages of a run as the formats print them, per particle.
struct SimulateColumns {
  std::vector<double> k, k_error, kc, kc_error, tau, cosine, cosine_error;
  std::string ensemble, integrator;
};

SimulateColumns simulate_columns(const SimulateRequest& request, const SimulationResult<double>& r) {
  const std::size_t n = r.kinetic.size();
  SimulateColumns c;
  for (std::vector<double>* v : {&c.k, &c.k_error, &c.kc, &c.kc_error, &c.tau, &c.cosine,
                                 &c.cosine_error})
    v->resize(n);
  for (std::size_t i = 0; i < n; ++i) {
    c.cosine[i] = r.cos_angle[i].value;
    c.cosine_error[i] = r.cos_angle[i].error;
    c.k[i] = r.kinetic[i].value;
    c.k_error[i] = r.kinetic[i].error;
    c.kc[i] = r.kinetic_canonical[i].value;
    c.kc_error[i] = r.kinetic_canonical[i].error;
    c.tau[i] = r.kinetic[i].autocorrelation_time;
  }
  c.ensemble = request.langevin ? "canonical" : "microcanonical";
  c.integrator = request.langevin
                     ? "baoab-rattle"
                     : std::string(integrator_names[static_cast<std::size_t>(
                           request.run.integrator.value_or(default_integrator))]);
  return c;
}

/// Step 3, format (--format csv): '#' lines with the run, then one row per particle: the
/// original columns, then (added later, at the end) <cos phi_i> and the other exact values with
/// every error and what it promises.
std::string simulate_csv(const SimulateRequest& request, const SimulateOutcome& outcome) {
  const SimulationResult<double>& r = outcome.result;
  const std::optional<ExactValues>& reference = outcome.reference;
  const std::optional<ReplicaSpread>& spread = outcome.spread;
  const SimulateColumns c = simulate_columns(request, r);
  std::string out = "# pendavg simulate: ensemble " + c.ensemble + ", integrator " +
                    c.integrator + ", dt " + number(request.run.time_step) + ", time " +
                    number(r.simulated_time) + ", steps " + std::to_string(r.steps) +
                    (r.interrupted ? " (interrupted)" : "") + "\n# energy " +
                    number(outcome.energy) + ", energy_drift " + decimal(r.energy_drift, 3) +
                    ", energy_error_max " + decimal(r.energy_error_max, 3) +
                    ", constraint_residual " + decimal(r.constraint_residual, 3) +
                    (reference ? ", exact " + reference->method : std::string()) + "\n";
  if (spread)
    out += "# replicas " + std::to_string(spread->replicas) + " of " +
           std::to_string(spread->requested) + ": K_error is the larger of the blocking and the "
           "replica-spread errors\n";
  out += "i,K,K_error,Kc,Kc_error,exact_K,exact_K_error,exact_Kc,K_autocorrelation_time";
  if (spread) out += ",K_error_blocking,K_error_replicas";
  out += ",cos_phi,cos_phi_error,error_kind,exact_cos_phi,exact_cos_phi_error,exact_Kc_error,"
         "exact_var_K,exact_var_K_error,exact_error_kind,exact_Kc_error_kind,"
         "exact_cos_phi_error_kind,exact_var_K_error_kind";
  if (spread)
    out += ",Kc_error_blocking,Kc_error_replicas,cos_phi_error_blocking,cos_phi_error_replicas";
  out += "\n";
  for (std::size_t i = 0; i < c.k.size(); ++i) {
    out += std::to_string(i + 1) + "," + cell(c.k[i], 10) + "," + cell(c.k_error[i], 3) + "," +
           cell(c.kc[i], 10) + "," + cell(c.kc_error[i], 3) + "," +
           (reference ? exact_number(reference->kinetic[i]) + "," +
                            exact_error(reference->kinetic[i], reference->kinetic_error[i]) +
                            "," + exact_number(reference->kinetic_canonical)
                      : std::string(",,")) +
           "," + cell(c.tau[i], 3);
    if (spread)
      out += "," + cell(spread->kinetic_blocking[i], 3) + "," +
             cell(spread->kinetic_replicas[i], 3);
    out += "," + cell(c.cosine[i], 10) + "," + cell(c.cosine_error[i], 3) + "," +
           error_kind_name(ErrorKind::statistical);
    if (reference) {
      const ExactValues& e = *reference;
      out += "," + exact_cell(e.cos_angle[i]) + "," +
             exact_error_cell(e.cos_angle[i], e.cos_angle_error[i]) + "," +
             exact_error_cell(e.kinetic_canonical, e.kinetic_canonical_error) + "," +
             exact_cell(e.variance[i]) + "," + exact_error_cell(e.variance[i], e.variance_error[i]) +
             "," + e.error_kind + "," + e.kinetic_canonical_error_kind + "," +
             e.cos_angle_error_kind + "," + e.variance_error_kind;
    } else {
      out += ",,,,,,,,,";
    }
    if (spread)
      out += "," + cell(spread->canonical_blocking[i], 3) + "," +
             cell(spread->canonical_replicas[i], 3) + "," + cell(spread->cosine_blocking[i], 3) +
             "," + cell(spread->cosine_replicas[i], 3);
    out += "\n";
  }
  return out;
}

/// The JSON keys added after the original ones (after seconds): <K> and <U> over time (the
/// same blocking errors), the secular energy trend (NVE), the work, the canonical Var K_i beside
/// a Langevin run, what each exact error promises, and the replicas' errors of <K> and <U>.
void add_totals_and_kinds(JsonObject& json, const SimulateRequest& request,
                          const SimulateOutcome& outcome) {
  const SimulationResult<double>& r = outcome.result;
  const std::optional<ExactValues>& reference = outcome.reference;
  const std::optional<ReplicaSpread>& spread = outcome.spread;
  json.raw("K_total", number(r.kinetic_total.value))
      .raw("K_total_error", error_number(r.kinetic_total.error))
      .raw("potential", number(r.potential.value))
      .raw("potential_error", error_number(r.potential.error));
  if (request.langevin)
    json.raw("energy_trend", "null")
        .string("energy_trend_reason",
                "a Langevin run exchanges energy with its bath: the trend of E(t) is reported "
                "for fixed-energy (NVE) runs only");
  else
    json.raw("energy_trend", error_number(r.energy_trend));
  json.integer("unconverged_stages", static_cast<long long>(r.unconverged_stages))
      .integer("samples", static_cast<long long>(r.samples));
  if (reference) {
    if (request.langevin)
      json.raw("exact_var_K", exact_array(reference->variance))
          .raw("exact_var_K_error",
               exact_error_array(reference->variance, reference->variance_error));
    if (std::ranges::any_of(reference->variance, [](double v) { return !std::isfinite(v); }))
      json.string("exact_var_K_reason",
                  "Var K_i = beta^2 Var K_i / beta^2 is outside the double range at this beta");
    json.raw("exact_error_kinds", JsonObject()
                                      .string("K", reference->error_kind)
                                      .string("Kc", reference->kinetic_canonical_error_kind)
                                      .string("cos_phi", reference->cos_angle_error_kind)
                                      .string("var_K", reference->variance_error_kind)
                                      .str());
  }
  if (spread)
    json.raw("K_total_error_blocking", error_number(spread->total_blocking))
        .raw("K_total_error_replicas", error_number(spread->total_replicas))
        .raw("potential_error_blocking", error_number(spread->potential_blocking))
        .raw("potential_error_replicas", error_number(spread->potential_replicas));
}

/// Step 3, format (JSON, the default): one object; the keys added after the original ones come
/// last (after seconds).
std::string simulate_json(const SimulateRequest& request, const SimulateOutcome& outcome) {
  const SimulationResult<double>& r = outcome.result;
  const std::optional<ExactValues>& reference = outcome.reference;
  const std::optional<ReplicaSpread>& spread = outcome.spread;
  const SimulationOptions& run = request.run;
  const SimulateColumns c = simulate_columns(request, r);
  const std::size_t n = c.k.size();
  JsonObject json;
  json.string("ensemble", c.ensemble)
      .string("integrator", c.integrator)
      .integer("particles", static_cast<long long>(n))
      .raw("dt", number(run.time_step))
      .raw("time", number(r.simulated_time))
      .raw("energy", number(outcome.energy))
      .raw("K", number_array(c.k))
      .raw("K_error", number_array(c.k_error))
      .raw("Kc", number_array(c.kc))
      .raw("Kc_error", number_array(c.kc_error))
      .raw("K_autocorrelation_time", number_array(c.tau))
      .raw("cos_phi", number_array(c.cosine))
      .raw("cos_phi_error", number_array(c.cosine_error))
      .string("error_kind", error_kind_name(ErrorKind::statistical));
  if (reference) {
    std::vector<double> deviation(n);
    for (std::size_t i = 0; i < n; ++i)
      deviation[i] = (c.k[i] - reference->kinetic[i]) /
                     std::hypot(c.k_error[i], reference->kinetic_error[i]);
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
  if (std::any_of(c.k_error.begin(), c.k_error.end(), [](double e) { return !std::isfinite(e); }))
    json.string("error_reason",
                "fewer than 16 averaging blocks finished (interrupted early, or --time too short "
                "for the block length): the error bars are unknown");
  if (request.langevin)
    json.raw("beta", number(*run.beta)).raw("friction", number(run.friction.value_or(1)));
  json.raw("energy_drift", error_number(r.energy_drift))
      .raw("energy_error_max", error_number(r.energy_error_max))
      .raw("energy_error_rms", error_number(r.energy_error_rms))
      .raw("constraint_residual", error_number(r.constraint_residual))
      .integer("steps", static_cast<long long>(r.steps))
      .integer("newton_solves", static_cast<long long>(r.newton_solves))
      .boolean("interrupted", r.interrupted);
  if (spread) {
    // Replicas: K_error (and Kc_error, cos_phi_error) is the larger of the two below; time,
    // steps and newton_solves add up over the replicas, the energy errors are the largest.
    json.integer("replicas", static_cast<long long>(spread->replicas))
        .integer("replicas_requested", static_cast<long long>(spread->requested))
        .raw("K_error_blocking", number_array(spread->kinetic_blocking))
        .raw("K_error_replicas", number_array(spread->kinetic_replicas))
        .raw("Kc_error_blocking", number_array(spread->canonical_blocking))
        .raw("Kc_error_replicas", number_array(spread->canonical_replicas))
        .raw("cos_phi_error_blocking", number_array(spread->cosine_blocking))
        .raw("cos_phi_error_replicas", number_array(spread->cosine_replicas))
        .raw("replica_time", number(run.duration))
        .raw("replica_energy_spread", decimal(spread->energy_spread, 3));
    if (spread->replicas < 2)
      json.string("replicas_error_reason", "fewer than two replicas finished");
  }
  if (reference && !request.langevin) {
    // the microcanonical state as D = E - E_min (excitation form) and Var K_i
    json.raw("exact_excitation", exact_number(reference->excitation))
        .raw("exact_var_K", exact_array(reference->variance))
        .raw("exact_var_K_error",
             exact_error_array(reference->variance, reference->variance_error));
  }
  json.raw("seconds", seconds_text(outcome.seconds));
  add_totals_and_kinds(json, request, outcome);
  return json.str() + "\n";
}

}  // namespace

std::string run_simulate(const Options& options) {
  const Chain<double> chain = parse_chain(options);
  const SimulateRequest request = parse_simulate_request(options, chain.size());
  if (request.replicas == 1 && !is_root()) return {};  // one trajectory: rank 0 alone
  input_checked("simulate");
  TrajectoryFile trajectory(options, request.every, chain);
  const std::optional<SimulateOutcome> outcome = run_simulation(chain, request, trajectory);
  if (!outcome) return {};  // another rank's share of the replicas
  return request.csv ? simulate_csv(request, *outcome) : simulate_json(request, *outcome);
}

std::string run_poincare(const Options& options) {
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
  input_checked("poincare");
  Progress progress("poincare");
  DynamicsObserver<double> observer;
  observer.progress = [&](double fraction) { progress(fraction, "of the section points "); };
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

constexpr std::array<std::string_view, 20> simulate_options{
    "masses",     "lengths", "g",    "theta",  "phi",      "phidot",     "time",
    "dt",         "burn-in", "integrator", "thermostat", "beta", "friction", "seed",
    "exact",      "format",  "trajectory", "every", "replicas", "perturb"};
constexpr std::array<std::string_view, 8> poincare_options{
    "masses", "lengths", "g", "energy", "orbits", "points", "dt", "output"};
const Command simulate_command{"simulate", simulate_usage, simulate_options, run_simulate, {}, true};
const Command poincare_command{"poincare", poincare_usage, poincare_options, run_poincare};

}  // namespace pendavg::cli
