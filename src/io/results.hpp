// SPDX-License-Identifier: GPL-3.0-or-later
// src/io/results.hpp -- the field table of every result type, and the builders that fill a
// record from a result. These tables ARE the output schema: the CLI's JSON, CSV and text and
// the Python result objects are generated from them (src/io/record.hpp).
#pragma once

#include "io/record.hpp"

#include "pendavg/chain.hpp"
#include "pendavg/mpfr.hpp"
#include "pendavg/microcanonical.hpp"
#include "pendavg/result.hpp"
#include "pendavg/series.hpp"

#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

namespace pendavg::io {

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

// ---------------------------------------------------------------- microcanonical averages

/// MicrocanonicalAverages<Real> (`average --energy/--excitation`, `table --energy`), after the
/// inputs of `state` (energy or excitation): the state not given comes first.
std::span<const Field> microcanonical_fields(std::string_view state);

template <class Real>
void append_microcanonical(Record& record, const MicrocanonicalAverages<Real>& averages,
                           Printing printing);

// ---------------------------------------------------------------- the paper's series

/// The series for beta<K_1> term by term (`series`, pendavg.series): one record per term.
std::span<const Field> series_term_fields();
/// Fills a term's record (always MPFR: `printing` digits).
void append_series_term(Record& record, const SeriesRow<mpfr_real>& row, Printing printing);

/// The series' summary after its inputs: the terms taken, whether they certify the digits, what
/// each term's bound promises.
std::span<const Field> series_fields();
/// True when the last term's bound is at most 10^-digits relative to its value.
bool series_certifies(const std::vector<SeriesRow<mpfr_real>>& rows, int digits);
void append_series(Record& record, const std::vector<SeriesRow<mpfr_real>>& rows, int digits);

// ---------------------------------------------------------------- the naming table

/// Every field of every table once, for the README's naming table and `pendavg schema`.
struct NamedTable {
  std::string_view result;  ///< e.g. "averages"
  std::span<const Field> fields;
};
std::span<const NamedTable> all_tables();
/// The series' tables (series_fields, series_term_fields): used by Python's pendavg.series; not
/// yet in all_tables (`pendavg help schema`), since the CLI's `series` still prints its own
/// columns (the same names).
std::span<const NamedTable> series_tables();

/// The naming table as Markdown: every table's fields (name, kind, per particle, meaning), the
/// naming rules first. `pendavg help schema` prints it; src/io/README.md holds it.
std::string schema_text();

/// The renames of schema 0 -> 1 as Markdown (`pendavg help migration`).
std::string migration_text();

}  // namespace pendavg::io
