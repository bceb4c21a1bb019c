// SPDX-License-Identifier: GPL-3.0-or-later
// src/cli/simulate.cpp -- `pendavg simulate`: a trajectory's time averages beside the exact
// microcanonical or canonical values. Thin: parse, call the library (dynamics.hpp,
// microcanonical.hpp, the canonical engines), fill records (src/io) -> CSV, JSON or text.
// Progress goes to stderr; SIGINT/SIGTERM end a run early and the averages so far are still
// printed (interrupted true); files are written atomically.
#include "common.hpp"

#include "average_options.hpp"
#include "distribute.hpp"
#include "io/exact_values.hpp"
#include "files.hpp"
#include "interrupt.hpp"
#include "sweep.hpp"

#include "io/record.hpp"
#include "io/report.hpp"
#include "io/results.hpp"

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

namespace pendavg::cli {

namespace {

constexpr std::string_view simulate_usage =
    "usage: pendavg simulate --masses M1,...,MN --lengths L1,...,LN [--g G]\n"
    "                        (--theta A | --phi P1,...,PN [--phidot W1,...,WN])\n"
    "                        --time T [--dt H] [--burn-in T0] [--integrator I]\n"
    "                        [--thermostat none|langevin --beta B [--friction G] [--seed S]]\n"
    "                        [--exact yes|no] [--format csv|json|text] [--output FILE]\n"
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
    "  --trajectory F  every K steps a CSV row t,E,phi_i...,phidot_i... (atomic file, after a\n"
    "                  '# schema: 1' line)\n"
    "  --replicas R    R independent trajectories on all cores (and all MPI ranks under\n"
    "                  mpirun/srun), pooled: Langevin replicas differ by their noise (seeds\n"
    "                  mixed from --seed), NVE replicas by their start (every angle moved by up\n"
    "                  to --perturb EPS radians, default 1e-6, at most 0.1, from --seed; replica 0\n"
    "                  unmoved), then brought back to the run's energy (rates scaled, or the\n"
    "                  angles moved along grad U when at rest), so all sample one shell.\n"
    "                  K_error is then the larger of the blocking error of the mean and the\n"
    "                  standard error of the spread between replicas (both printed, as\n"
    "                  K_error_blocking and K_error_replicas); the result is the same for any\n"
    "                  number of ranks and threads.\n"
    "Output (schema 1; names and meanings: README, Output schema): CSV (default: '# schema: 1',\n"
    "'# pendavg simulate', a header, one row), JSON or text; --output FILE writes it atomically\n"
    "(nothing on stdout). The inputs (N, g, m, l, ensemble, integrator, dt, beta, friction),\n"
    "then the time averages X = K, Kc, cos_phi, K_total (<K>), potential (<U>) with X_error\n"
    "(1 sigma) and X_error_kind, the exact values exact_X of the run's ensemble with theirs (NVE:\n"
    "at exact_excitation, D = E - E_min = K + sum_j 2 g S_j l_j sin^2(phi_j/2)), the energy\n"
    "diagnostics (energy_*, constraint_residual), the work (steps, samples, newton_solves) and,\n"
    "with --replicas, X_error_blocking and X_error_replicas. A per-particle X is a JSON array\n"
    "and the CSV columns X1..XN (errors X1_error..XN_error). Values are the shortest decimals\n"
    "that read back as the same double, errors 3 digits rounded up; a value that does not exist\n"
    "is null (an empty cell), with a *_reason key where the run can say why.\n"
    "Progress goes to stderr. Ctrl-C (SIGINT) or SIGTERM ends the run early; the averages so\n"
    "far are printed with interrupted true. Energies use the paper's U = -sum_j g S_j l_j\n"
    "cos phi_j (the hanging chain has the lowest energy).\n";

constexpr std::array<std::string_view, 5> integrator_names{"rattle2", "yoshida4", "suzuki4",
                                                           "kahan-li6", "yoshida6"};
constexpr std::array<std::string_view, 2> thermostat_names{"none", "langevin"};
constexpr std::array<std::string_view, 2> yes_no{"yes", "no"};

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

using io::ReplicaSpread;

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
  // A replica stops within milliseconds and reports its averages so far; under MPI the file must
  // be written before mpirun kills the ranks, 1 s after it forwarded the signal (sweep.hpp).
  rows.grace_seconds = ranks() > 1 ? 0.5 : 5;
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
  Format format = Format::csv;  ///< --format
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
  request.format = format_option(options, "csv", all_formats);
  if (options.has("trajectory") != options.has("every"))
    throw usage_error("simulate: --trajectory and --every go together");
  if (request.replicas > 1 && options.has("trajectory"))
    throw usage_error("simulate: --trajectory records one run; it does not go with --replicas");
  if (options.has("every"))
    request.every = static_cast<std::size_t>(
        parse_integer(options.required("every"), "--every", 1, 1000000000));
  return request;
}

/// --trajectory FILE --every K: after the "# schema: 1" and "# pendavg simulate --trajectory"
/// lines and the header, every K steps a CSV row t,E,phi_i...,phidot_i..., buffered and written
/// atomically (commit() after the run).
class TrajectoryFile {
 public:
  TrajectoryFile(const Options& options, std::size_t every, const Chain<double>& chain)
      : chain_(chain), every_(every) {
    if (!options.has("trajectory")) return;
    file_.emplace(std::string(options.required("trajectory")), "simulate");
    buffer_ = io::schema_line() + "# pendavg simulate --trajectory\n";
    for (const std::string& column : io::column_names(io::trajectory_fields(), chain.size()))
      (buffer_ += column) += ',';
    buffer_.back() = '\n';
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
  std::optional<io::ExactValues> reference;    ///< --exact yes
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
              ? io::canonical_values(chain, *request.run.beta)
              : io::microcanonical_values(chain, io::initial_excitation(chain, initial, request.phi));
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

/// The name of the scheme that ran.
std::string_view integrator_name(const SimulateRequest& request) {
  if (request.langevin) return "baoab-rattle";
  return integrator_names[static_cast<std::size_t>(
      request.run.integrator.value_or(default_integrator))];
}

/// Step 3, format: the inputs and the (pooled) result as records (src/io/results.hpp), one
/// report in CSV, JSON or text.
std::string simulate_report(const Options& options, const Chain<double>& chain,
                            const SimulateRequest& request, const SimulateOutcome& outcome) {
  const std::size_t n = chain.size();
  io::Record inputs(io::simulation_input_fields(), n);
  io::append_simulation_inputs(inputs, chain, request.run, integrator_name(request),
                               input_texts(options, "", n));
  io::Record result(io::simulation_fields(), n);
  io::append_simulation(result, outcome.result, outcome.energy,
                        outcome.reference ? &*outcome.reference : nullptr, request.langevin);
  io::Report report{"simulate", {&inputs}, {{"", {&result}, ""}}, {}, outcome.seconds};
  io::Record replicas;
  if (outcome.spread) {
    replicas.reset(io::replica_fields(), n);
    io::append_replicas(replicas, *outcome.spread, request.run.duration);
    report.rows[0].records.push_back(&replicas);
  }
  return io::format_report(report, request.format);
}

std::string run_simulate(const Options& options) {
  const Chain<double> chain = dynamics_chain_option(options);
  const SimulateRequest request = parse_simulate_request(options, chain.size());
  if (request.replicas == 1 && !is_root()) return {};  // one trajectory: rank 0 alone
  check_output_option(options, "simulate");
  input_checked("simulate");
  TrajectoryFile trajectory(options, request.every, chain);
  const std::optional<SimulateOutcome> outcome = run_simulation(chain, request, trajectory);
  if (!outcome) return {};  // another rank's share of the replicas
  return deliver(options, "simulate", simulate_report(options, chain, request, *outcome));
}

}  // namespace

constexpr std::array<std::string_view, 21> simulate_options{
    "masses",     "lengths", "g",    "theta",  "phi",      "phidot",     "time",
    "dt",         "burn-in", "integrator", "thermostat", "beta", "friction", "seed",
    "exact",      "format",  "output", "trajectory", "every", "replicas", "perturb"};
const Command simulate_command{"simulate", simulate_usage, simulate_options, run_simulate, {}, true};

}  // namespace pendavg::cli
