// SPDX-License-Identifier: GPL-3.0-or-later
// src/io/results.hpp -- the field table of every result type, and the builders that fill a
// record from a result. These tables ARE the output schema: the CLI's JSON, CSV and text and
// the Python result objects are generated from them (src/io/record.hpp).
#pragma once

#include "io/record.hpp"

#include "pendavg/chain.hpp"
#include "pendavg/dynamics.hpp"
#include "pendavg/microcanonical.hpp"
#include "pendavg/mpfr.hpp"
#include "pendavg/result.hpp"
#include "pendavg/series.hpp"

#include <cstddef>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

namespace pendavg::io {

struct ExactValues;  // src/io/exact_values.hpp: the exact values beside a trajectory

/// How a run's reals are printed: `digits` = 16 is a double run (shortest round-trip numbers);
/// more is MPFR (`digits` significant digits, decimal text).
struct Printing {
  int digits = 16;
  /// false: a double run's values keep their number only, without their shortest text and its
  /// printing gap (so their errors' cells carry no gap either), for a front end that prints
  /// later, if at all (Python's .decimal: shortest_gap then gives what the text adds).
  bool texts = true;
  bool in_double() const { return digits <= 16; }
};

/// x's exact binary value (Record::keep_exact).
ExactNumber exact_number(const mpfr_real& x);

// ---------------------------------------------------------------- inputs

/// A canonical state's inputs: N, digits, beta, g, m, l.
std::span<const Field> canonical_input_fields();
/// A chain's inputs without a temperature (microcanonical averages, limits): N, digits, g, m, l.
std::span<const Field> chain_input_fields();

/// Fills the inputs (beta only for the canonical table). `texts`, when not empty, are the
/// numbers as written (beta, g, m1..mN, l1..lN; microcanonical: g, m.., l..): an MPFR run
/// prints them as written; a double run prints the doubles they were read as.
template <class Real>
void append_canonical_inputs(Record& record, const Chain<Real>& chain, const Real& beta,
                             Printing printing, std::span<const std::string_view> texts = {});
/// A microcanonical state's inputs: N, digits, the state given (energy or excitation), g, m, l.
std::span<const Field> microcanonical_input_fields(std::string_view state);
/// Fills them: `state` is the energy or excitation as read; texts (when given): the state, g,
/// m1..mN, l1..lN as written.
template <class Real>
void append_microcanonical_inputs(Record& record, const Chain<Real>& chain, const Real& state,
                                  Printing printing, std::span<const std::string_view> texts = {});
template <class Real>
void append_chain_inputs(Record& record, const Chain<Real>& chain, Printing printing,
                                  std::span<const std::string_view> texts = {});

// ---------------------------------------------------------------- canonical averages

/// Averages<Real> (`average --beta`, `table --beta`, `average --cases`, `limit`).
std::span<const Field> averages_fields();

/// Fills `record` (reset to averages_fields()) from `averages`. `beta` (null for the limits)
/// adds <K_i> = beta<K_i>/beta and Var K_i = beta^2 Var K_i/beta^2 (null cells without it).
/// Every printed error covers its printed value.
template <class Real>
void append_averages(Record& record, const Averages<Real>& averages, const Real* beta,
                     Printing printing);

// ---------------------------------------------------------------- the run diagnostics

/// How the method of canonical averages ran (the JSON `run` object of `average --beta` and
/// `limit`, Python's Averages.run), one table per kind of run: the torus rule's final grid, the
/// qmc run, the transfer operator's final resolution.
std::span<const Field> torus_run_fields();
std::span<const Field> qmc_run_fields();
std::span<const Field> transfer_run_fields();

/// The table of the run of `averages` (empty: a method without run diagnostics).
template <class Real>
std::span<const Field> run_fields(const Averages<Real>& averages);

/// Fills `record` (reset to run_fields(averages), not empty).
template <class Real>
void append_run(Record& record, const Averages<Real>& averages);

// ---------------------------------------------------------------- microcanonical averages

/// MicrocanonicalAverages<Real> (`average --energy/--excitation`, `table --energy`), after the
/// inputs of `state` (energy or excitation): the state not given comes first.
std::span<const Field> microcanonical_fields(std::string_view state);

template <class Real>
void append_microcanonical(Record& record, const MicrocanonicalAverages<Real>& averages,
                           Printing printing);

// ---------------------------------------------------------------- simulate

/// A trajectory's inputs (`simulate`): N, g, m, l, ensemble, integrator, dt, beta, friction.
std::span<const Field> simulation_input_fields();

/// Fills them: `integrator` is the name of the scheme that ran (baoab-rattle under Langevin);
/// `texts` (when given) g, m1..mN, l1..lN as written; beta and friction only under Langevin.
void append_simulation_inputs(Record& record, const Chain<double>& chain,
                              const SimulationOptions& run, std::string_view integrator,
                              std::span<const std::string_view> texts = {});

/// SimulationResult<double> beside the exact values of its ensemble (`simulate`): the time
/// averages with their statistical errors, the exact values with theirs, the energy diagnostics
/// and the work. A value that does not exist (an error bar of too few blocks, the exact values
/// of --exact no) is null, with a *_reason field where a run can say why.
std::span<const Field> simulation_fields();

/// Fills `record` (reset to simulation_fields()): `energy` is E of the initial state, `exact`
/// the exact values (null: none), `langevin` whether a thermostat ran.
void append_simulation(Record& record, const SimulationResult<double>& result, double energy,
                       const io::ExactValues* exact, bool langevin);

/// What --replicas R adds: the two error bars of every average (blocking within the replicas;
/// the spread between them) and how far the replicas' energies lie apart.
struct ReplicaSpread {
  std::size_t replicas = 0, requested = 0;  ///< finished (also when interrupted), asked for
  std::vector<double> kinetic_blocking, kinetic_replicas, canonical_blocking, canonical_replicas,
      cosine_blocking, cosine_replicas;
  double total_blocking = 0, total_replicas = 0;          ///< of <K>
  double potential_blocking = 0, potential_replicas = 0;  ///< of <U>
  double energy_spread = 0;  ///< largest |E_r - E| over the replicas (NVE perturbed starts)
};

/// The replicas' fields of a pooled run (after simulation_fields()).
std::span<const Field> replica_fields();

/// Fills them: `replica_time` is each replica's averaging time (--time).
void append_replicas(Record& record, const ReplicaSpread& spread, double replica_time);

// ---------------------------------------------------------------- poincare

/// The section's inputs and run (`poincare`): N, g, m, l, energy, orbits, points_per_orbit, dt,
/// then steps, energy_error_max, interrupted.
std::span<const Field> poincare_fields();

void append_poincare(Record& record, const Chain<double>& chain, const PoincareOptions& options,
                     const PoincareSection<double>& section,
                     std::span<const std::string_view> texts = {});

/// One point of the section: orbit, phi2, p2, time.
std::span<const Field> section_point_fields();

void append_section_point(Record& record, const SectionPoint<double>& point);

/// Where each orbit starts on the section: start_phi2, start_p2 (Python's PoincareSection; the
/// CLI prints the crossings only).
std::span<const Field> orbit_start_fields();

/// A trajectory's samples (simulate --trajectory, Python's SimulationResult.trajectory): t, E,
/// phi, phidot.
std::span<const Field> trajectory_fields();

void append_orbit_start(Record& record, const PoincareSection<double>& section,
                        std::size_t orbit);

// ---------------------------------------------------------------- series

/// The series run's own fields after the canonical inputs (`series`): terms, certified,
/// beta_K1_error_kind.
std::span<const Field> series_run_fields();

void append_series_run(Record& record, std::size_t terms, bool certified);

/// True when the last row's bound is at most 10^-digits relative to its value (`certified`).
bool series_certifies(const std::vector<SeriesRow<mpfr_real>>& rows, int digits);

/// One term of the series: n, R_n, term, numerator, denominator, beta_K1 (the partial sum) and
/// beta_K1_error (the rigorous truncation bound; null while none exists).
std::span<const Field> series_row_fields();

/// Whether every number of the rows and of the inputs rounds to a double without leaving
/// double's normal range: a 16-digit series run then prints its values as doubles (the shortest
/// text that reads back as the same double), else as 16-digit decimals (as MPFR runs print).
bool series_fits_double(const std::vector<SeriesRow<mpfr_real>>& rows,
                        const Chain<mpfr_real>& chain, const mpfr_real& beta);

/// Fills `record` (reset to series_row_fields()) with `row`: as doubles (`doubles`: the value
/// rounded to nearest, its error enlarged by that rounding) or as decimals of `printing.digits`.
void append_series_row(Record& record, const SeriesRow<mpfr_real>& row, Printing printing,
                       bool doubles);

// ---------------------------------------------------------------- the naming table

/// Every field of every table once, for the README's naming table and `pendavg schema`.
struct NamedTable {
  std::string_view result;  ///< e.g. "averages"
  std::span<const Field> fields;
};
std::span<const NamedTable> all_tables();

/// The naming table as Markdown: every table's fields (name, kind, per particle, meaning), the
/// naming rules first. `pendavg help schema` prints it; src/io/README.md holds it.
std::string schema_text();

/// The renames of schema 0 -> 1 as Markdown (`pendavg help migration`).
std::string migration_text();

}  // namespace pendavg::io
