// SPDX-License-Identifier: GPL-3.0-or-later
// src/cli/average.cpp -- `pendavg average`: thermal averages at one beta (or energy) and of a cases file: options ->
// Chain<Real> -> one library call -> a record (src/io) -> JSON, CSV or text; --cases streams rows
// through the sweep engine. 16 digits run in double, more in MPFR.
#include "common.hpp"

#include "average_options.hpp"
#include "distribute.hpp"
#include "files.hpp"
#include "interrupt.hpp"
#include "one_line.hpp"
#include "shard.hpp"
#include "sweep.hpp"
#include "sweep_file.hpp"
#include "sweep_format.hpp"
#include "version_info.hpp"

#include "io/record.hpp"
#include "io/report.hpp"
#include "io/results.hpp"
#include "io/sweep_rows.hpp"

#include "pendavg/mpfr.hpp"
#include "pendavg/pendavg.hpp"

#include <algorithm>
#include <array>
#include <charconv>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <ctime>
#include <optional>
#include <string>
#include <string_view>
#include <type_traits>
#include <utility>
#include <vector>

#if defined(_OPENMP)
#include <omp.h>
#endif

namespace pendavg::cli {

namespace {

constexpr std::string_view average_usage =
    "usage: pendavg average --masses M1,...,MN --lengths L1,...,LN [--g G] --beta B [--digits D]\n"
    "                       [--method M] [--tol T] [--samples S] [--shifts R] [--seed K]\n"
    "                       [--certified] [--format json|csv|text] [--output FILE]\n"
    "       pendavg average --masses ... --lengths ... [--g G] (--energy E | --excitation D)\n"
    "                       [--digits D] [--method M] [method options] [--format json|csv|text]\n"
    "       pendavg average --cases FILE.csv [--digits D] [--method M] [method options]\n"
    "                       [--columns LIST] [--format json|csv|text]\n"
    "                       [--output FILE | --resume FILE] [--timing] [--timing-rows FILE]\n"
    "                       [--shard K/N]\n"
    "\n"
    "Thermal averages of an N-link pendulum (N = the number of masses = the number of lengths)\n"
    "at inverse temperature B, gravity G (default 1). --method M (default auto):\n"
    "  auto             N = 2: the double-pendulum engine; N = 1 or 3..4: torus-trapezoid;\n"
    "                   N >= 5: transfer\n"
    "  series, integral the double-pendulum engines (N = 2 only)\n"
    "  torus-trapezoid  exact quadrature on the reduced (N-1)-torus, any N (cost n^(N-1)), also\n"
    "                   in MPFR; --tol T: relative tolerance in double (default 1e-13; with\n"
    "                   --digits D > 16 it is 1e-D)\n"
    "  torus-gauss      the same with Gauss-Legendre nodes (a check)\n"
    "  transfer         the transfer operator along the chain, double only, any N <= 16384\n"
    "                   (cost O(N)); --tol T: relative tolerance (default 1e-10)\n"
    "  qmc              randomized lattice QMC, double only, N <= 256, statistical error bars\n"
    "                   (the 99.9% Student-t quantile of the standard error over the shifts:\n"
    "                   4.07 sigma for 16); --samples S points per shift (a power of two,\n"
    "                   1024..1048576, default 65536), --shifts R (4..1024, default 16), --seed K\n"
    "                   (default 1)\n"
    "Options of a method that is not run are rejected.\n"
    "--certified (N = 2, method auto or integral, --beta or --cases): certified enclosures --\n"
    "every error is a proven bound (error_kind bound, method certified-integral): the exact\n"
    "average for the inputs as parsed (decimals rounded to double, or to MPFR at the working\n"
    "precision) lies within value +- error, printed errors rounded up. converged false: the\n"
    "requested digits were not reached within the work limit (the bound still holds). Needs a\n"
    "build with Arb (the version text says whether this one has it).\n"
    "Output (--format csv, the default; json; text; --output FILE writes it atomically): the\n"
    "inputs N, digits, beta, g, m, l, then method, beta_K (beta<K_i>), K (<K_i>), ratio\n"
    "(<K1>/<K2>, empty for N = 1), cos_phi, var_K (Var K_i), beta2_var_K (beta^2 Var K_i),\n"
    "beta_Kc (beta<K_i^(c)> = 1/2), each X with X_error and X_error_kind (bound | estimate |\n"
    "statistical), diagonal_approx (the paper's eq. ke-linear-tave-1), equipartition_residual\n"
    "(|sum beta<K_i> - N/2|), evaluations, work_unit, converged, interrupted, seconds; JSON adds\n"
    "run (the torus grid, the qmc points, shifts and effective sample fraction, or the transfer\n"
    "operator's nodes and levels). Per-particle values are JSON arrays and the CSV columns\n"
    "X1..XN (errors X1_error..XN_error). `pendavg help schema` explains every field. A double\n"
    "run prints each value exactly (the shortest decimal of the double; JSON numbers); an MPFR\n"
    "run prints the digits asked for (JSON strings); errors have 3 digits rounded up and cover\n"
    "the printed value.\n"
    "--cases reads a CSV with the columns beta,g,m1..mN,l1..lN (any order, N from the header;\n"
    "blank lines and lines starting with # are skipped) and writes one row per case: the\n"
    "input columns in that order, then the output columns above from method on. Every row is\n"
    "checked before the first is computed. --columns LIST prints only the listed output\n"
    "columns, in that order, after the input columns: names as in the header, a per-particle\n"
    "stem (cos_phi: cos_phi1..N; cos_phi_error: cos_phi1_error..N_error) or a name of pendavg 0.2\n"
    "(`pendavg help migration`: printed under its old header), e.g. --columns\n"
    "beta_K,beta_K_error,ratio (smaller files, faster rows; --resume needs the same LIST). Rows\n"
    "run on all cores (and, under mpirun/srun with pendavg built with MPI, on all ranks); the output does not depend\n"
    "on the thread or rank count. Rows are streamed in file order as they finish.\n"
    "--output FILE writes the CSV atomically to FILE, after '#' lines naming the cases (by a\n"
    "hash of the file), digits, method, version and date. SIGINT/SIGTERM stop early: every\n"
    "finished row is written, then an '# interrupted: K of N rows computed' line; --resume\n"
    "FILE continues such a file (same cases, digits, method and version) and rewrites it as an\n"
    "uninterrupted run does (a FILE that does not exist yet is simply written; the rows of a\n"
    "run killed outright, in FILE's temporary, are taken too). A row that\n"
    "fails while it is computed becomes a '# failed: FILE line L: reason' line in its place;\n"
    "the others are kept and the run exits 3, naming the first; --resume computes it again.\n"
    "--shard K/N (a job array without MPI: K = 1..N; not with --timing) computes the K-th of N\n"
    "fixed shares of the rows into its own file; 'pendavg merge' joins the N files into the\n"
    "file one run of all the rows writes.\n"
    "--format (with --cases): csv (the default), json or text, with the same header, rows and\n"
    "values (the CSV's texts) in each. json: one document {\"schema\": 1, \"command\": \"average\",\n"
    "\"header\": [the '#' lines], \"columns\": [...], \"rows\": [an object a row, keys = the\n"
    "columns; double: JSON numbers, MPFR: decimal strings, an empty cell null], \"failed\":\n"
    "[{\"row\": R, \"message\": M}, R the failed row's 0-based row], \"interrupted\": null or the\n"
    "reason}, written a row a line as the rows finish: pandas.DataFrame(doc[\"rows\"]) is the\n"
    "table. text: the '#' lines and the columns right-aligned at fixed widths, '-' for an empty\n"
    "cell. --resume and merge take files of the run's --format only.\n"
    "A cases file written by pandas (df.to_csv(): its unnamed index column) is read.\n"
    "A single qmc point (without --cases) shares its shifts between the MPI ranks; the result\n"
    "is the same for any number of ranks.\n"
    "--timing (with --cases) also prints one line on stderr: rows, the median, 90th percentile\n"
    "and worst thread CPU time per row in microseconds (the row's computation and formatted\n"
    "output line, and parsing it unless the check before the run kept its numbers, as it does\n"
    "for double rows; the timer's own cost, timer_us, is measured and subtracted), the worst row\n"
    "(0-based data row and file line) and the thread count:\n"
    "  pendavg: timing: rows=R median_us=X p90_us=Y worst_us=Z worst_row=I worst_line=L\n"
    "  threads=T timer_us=U (...)\n"
    "--timing-rows FILE (with --cases) also writes every row's time as CSV row,line,us.\n"
    "\n"
    "Microcanonical averages at fixed energy: --energy E (instead of --beta) or --excitation D\n"
    "(D = E - E_min > 0, E_min = -sum_j g S_j l_j: how to state an energy near the bottom of the\n"
    "well without losing digits). They give <K_i>_E, <K_i^(c)>_E = <K>_E/N, <cos phi_i>_E and\n"
    "Var K_i, each with its error, and <K>_E and the density of states Omega(E). --method auto\n"
    "(integral for N <= 4, qmc beyond), integral, torus-trapezoid (N <= 5, a check) or qmc;\n"
    "--tol T for integral/torus-trapezoid (default 1e-13 for N <= 2, 1e-11 for N = 3, 1e-9\n"
    "beyond); qmc: --samples S (1024..65536), --shifts R, --seed K. --digits D > 16 runs in MPFR\n"
    "for N <= 4 with the integral rule (N = 2: milliseconds; N = 3 at 30 digits: about a\n"
    "minute); qmc is double only, torus-trapezoid only for N = 2. Output: the inputs N, digits,\n"
    "energy (or excitation, as given), g, m, l, then the other of energy and excitation,\n"
    "ensemble, method, K (<K_i>_E), Kc, cos_phi, var_K, K_total (<K>_E), density_of_states\n"
    "(Omega(E)), each with X_error and X_error_kind, proposal_beta and effective_sample_fraction\n"
    "(qmc), evaluations, work_unit, converged, seconds. An energy at or below E_min is refused.\n"
    "--cases takes an energy or excitation column instead of beta; its rows then have these\n"
    "output columns after the input ones.\n";

/// `average`'s options (method, digits, tol, samples, shifts, seed).
AverageOptions average_settings(const Options& options) {
  AverageOptions settings = parse_average_options(options, average_option_names);
  settings.certified = options.has("certified");
  return settings;
}

template <class Real>
std::string average_one(const Options& options, const AverageOptions& settings, Format format) {
  const std::string_view beta_text = options.required("beta");
  const Chain<Real> chain = chain_option<Real>(options, true);
  AverageOptions run = settings;
  run.threads = hardware_threads();
  resolve_average_method(chain.size(), run);  // every option checked before any work
  const Real beta = parse_real<Real>(beta_text, "--beta", Domain::positive);
  check_average(chain, beta, run);  // and the method's domain
  check_printed_quotients(beta);
  input_checked("average");
  if (ranks() > 1) {
    // Under MPI one qmc point shares its shifts between the ranks (the same bits for any
    // number of ranks); another method runs on rank 0 alone.
    if (resolve_average_method(chain.size(), run) == AverageMethod::qmc)
      run.partition = shift_partition();
    else if (!is_root())
      return {};
  }
  const int digits = settings.digits;
  const Stopwatch stopwatch;
  Progress progress("average");
  StopOnSignal signals;  // a torus run stopped after its first level reports the last one, a
                         // qmc run its finished shifts
  const AverageMethod method = resolve_average_method(chain.size(), run);
  const std::string unit = method == AverageMethod::qmc ? std::string("of the qmc points ")
                                                        : std::string("of a ") +
                                                              average_method_name(method) +
                                                              " level ";
  run.control.progress = [&](double fraction) { progress(fraction, unit); };
  run.control.stop = &stop_flag();
  const Averages<Real> result = average(chain, beta, run);
  const double seconds = stopwatch.seconds();
  if (result.interrupted)
    std::fprintf(stderr, "[average] interrupted: the last finished level (torus; transfer: "
                         "the last verified one; qmc: the shifts finished) is reported\n");
  const io::Printing printing{digits};
  const auto texts = input_texts(options, "beta", chain.size());
  io::Record inputs(io::canonical_input_fields(), chain.size());
  io::append_canonical_inputs(inputs, chain, beta, printing, texts);
  io::Record values(io::averages_fields(), chain.size());
  io::append_averages(values, result, &beta, printing);
  io::Report report{"average", {&inputs}, {{"", {&values}, run_json(result)}}, {}, seconds};
  return io::format_report(report, format);
}

// ---------------------------------------------------------------- average --energy/--excitation

/// The state option of `average`: beta (canonical), energy or excitation (microcanonical).
/// Throws usage_error when more than one is given.
std::string_view state_option(const Options& options) {
  std::vector<std::string_view> given;
  for (const std::string_view name : {"beta", "energy", "excitation"})
    if (options.has(name)) given.push_back(name);
  if (given.size() > 1)
    throw usage_error("average: give one of --beta, --energy, --excitation (not both --" +
                      std::string(given[0]) + " and --" + std::string(given[1]) + ")");
  return given.empty() ? std::string_view("beta") : given.front();
}

/// The microcanonical averages of `chain` at `x`, the value of the state `state` (energy or
/// excitation) checked by microcanonical_state.
template <class Real>
MicrocanonicalAverages<Real> microcanonical_at(const Chain<Real>& chain, std::string_view state,
                                               const Real& x, const MicrocanonicalOptions& options) {
  return state == "excitation" ? microcanonical_average_excitation(chain, x, options)
                               : microcanonical_average(chain, x, options);
}

template <class Real>
std::string microcanonical_one(const Options& options, const AverageOptions& settings,
                               std::string_view state, Format format) {
  const std::string_view state_text = options.required(state);
  const Chain<Real> chain = chain_option<Real>(options, true);
  AverageOptions run = settings;
  run.threads = hardware_threads();
  MicrocanonicalOptions micro;
  try {
    micro = microcanonical_options(run, chain.size());
  } catch (const invalid_input& bad) {
    throw usage_error("average: " + std::string(bad.what()));
  }
  const Real x =
      microcanonical_state(chain, state, state_text, "--" + std::string(state), micro);
  input_checked("average");
  const Stopwatch stopwatch;
  // Progress on stderr, and SIGINT/SIGTERM stop the run (no partial result: exit 130).
  Progress progress("average");
  StopOnSignal signals;
  const std::string unit = std::string("of the microcanonical ") +
                           microcanonical_rule_name(micro.rule, chain.size()) +
                           (resolve_microcanonical_rule(chain.size(), micro.rule) ==
                                    MicrocanonicalOptions::Rule::qmc
                                ? " shifts "
                                : " rule's outer pieces ");
  micro.control.progress = [&](double fraction) { progress(fraction, unit); };
  micro.control.stop = &stop_flag();
  const MicrocanonicalAverages<Real> result = microcanonical_at(chain, state, x, micro);
  const double seconds = stopwatch.seconds();
  const io::Printing printing{settings.digits};
  const auto texts = input_texts(options, state, chain.size());
  io::Record inputs(io::microcanonical_input_fields(state), chain.size());
  io::append_microcanonical_inputs(inputs, chain, x, printing, texts);
  io::Record values(io::microcanonical_fields(state), chain.size());
  io::append_microcanonical(values, result, printing);
  io::Report report{"average", {&inputs}, {{"", {&values}, "null"}}, {}, seconds};
  return io::format_report(report, format);
}

/// The chain of one cases row (masses, lengths and g in canonical order after the state).
template <class Real>
Chain<Real> case_chain(const std::vector<std::string_view>& fields,
                       const std::vector<std::string>& columns, std::size_t n,
                       std::vector<Real>& masses, std::vector<Real>& lengths) {
  masses.clear();
  lengths.clear();
  for (std::size_t i = 0; i < n; ++i)
    masses.push_back(parse_real<Real>(fields[2 + i], columns[2 + i], Domain::positive));
  for (std::size_t i = 0; i < n; ++i)
    lengths.push_back(parse_real<Real>(fields[2 + n + i], columns[2 + n + i], Domain::positive));
  return make_chain<Real>(masses, lengths,
                          parse_real<Real>(fields[1], columns[1], Domain::nonnegative));
}

/// One row of `average --cases` with an energy or excitation column (the input fields as
/// written, then the `chosen` cells of the microcanonical record), appended to `line`.
template <class Real>
void microcanonical_case(std::string& line, const CasesFile& file, const CaseRow& row,
                         const std::vector<std::string>& columns,
                         std::span<const std::size_t> chosen, const MicrocanonicalOptions& micro,
                         int digits, io::Record& record, const io::RowWriter& rows) {
  std::optional<working_precision> precision;  // each row of an MPFR run holds its own
  if constexpr (!std::is_same_v<Real, double>) precision.emplace(digits + guard_digits);
  std::vector<std::string_view> fields(columns.size());
  case_fields(file, row, fields);
  std::vector<Real> masses, lengths;
  const Chain<Real> chain = case_chain<Real>(fields, columns, file.particles, masses, lengths);
  const MicrocanonicalAverages<Real> r = microcanonical_at(
      chain, file.state, microcanonical_state(chain, file.state, fields[0], columns[0], micro),
      micro);
  record.reset(io::microcanonical_fields(file.state), file.particles);
  io::append_microcanonical(record, r, io::Printing{digits});
  const io::RowCells cells[] = {{&record, chosen}};
  rows.append(line, fields, std::is_same_v<Real, double>, cells);
}

/// Checks one microcanonical cases row (fields, numbers at the working precision, the chain, the
/// state against E_min) without computing it.
template <class Real>
void check_microcanonical_case(const CasesFile& file, const CaseRow& row,
                               const std::vector<std::string>& columns, int digits,
                               const MicrocanonicalOptions& options) {
  std::optional<working_precision> precision;
  if constexpr (!std::is_same_v<Real, double>) precision.emplace(digits + guard_digits);
  std::vector<std::string_view> fields(columns.size());
  case_fields(file, row, fields);
  std::vector<Real> masses, lengths;
  const Chain<Real> chain = case_chain<Real>(fields, columns, file.particles, masses, lengths);
  microcanonical_state(chain, file.state, fields[0], columns[0], options);
}

/// The numbers of the cases rows this rank checked, in a double run: the check parses each row
/// once and keeps beta, g, m1..mN, l1..lN here for the row's computation (rows checked on
/// another rank, every row of an MPFR run, and every row of a file whose numbers would take more
/// than checked_numbers_budget, are parsed again). 8 (2N + 2) bytes a row.
constexpr std::size_t checked_numbers_budget = std::size_t(256) << 20;
struct CheckedNumbers {
  std::size_t per_row = 0;
  std::vector<double> values;         ///< row-major, per_row numbers a row
  std::vector<unsigned char> stored;  ///< 1 where `values` hold the row (threads write distinct rows)
  CheckedNumbers(std::size_t rows, std::size_t particles)
      : per_row(2 * particles + 2), values(rows * per_row), stored(rows, 0) {}
  std::span<double> row(std::size_t k) { return {values.data() + k * per_row, per_row}; }
  std::span<const double> row_if_stored(std::size_t k) const {
    if (!stored[k]) return {};
    return {values.data() + k * per_row, per_row};
  }
};

/// Per-thread scratch of `average --cases`: reused from row to row.
template <class Real>
struct CaseScratch {
  std::vector<std::string_view> fields;  ///< the row's fields in canonical order
  std::vector<Real> masses, lengths;
  AverageWorkspace<Real> workspace;
  io::Record record;  ///< the row's averages
};

/// One output row of `average --cases`: the input fields as written, then the `chosen` cells of
/// the averages' record, appended to `line` in the format of `rows`. `columns` are the canonical
/// column names (beta, g, m1..mN, l1..lN).
template <class Real>
void write_case(std::string& line, const CasesFile& file, const CaseRow& row,
                const std::vector<std::string>& columns, std::span<const std::size_t> chosen,
                const AverageOptions& options, CaseScratch<Real>& scratch,
                const io::RowWriter& rows, std::span<const double> checked = {}) {
  std::optional<working_precision> precision;  // each row of an MPFR run holds its own
  if constexpr (!std::is_same_v<Real, double>) precision.emplace(options.digits + guard_digits);
  auto& fields = scratch.fields;
  fields.resize(columns.size());
  case_fields(file, row, fields);
  const std::size_t n = file.particles;
  Real beta;
  std::optional<Chain<Real>> parsed;
  if constexpr (std::is_same_v<Real, double>) {
    if (!checked.empty()) {  // the check's numbers: beta, g, m1..mN, l1..lN
      beta = checked[0];
      scratch.masses.assign(checked.begin() + 2, checked.begin() + 2 + static_cast<long>(n));
      scratch.lengths.assign(checked.begin() + 2 + static_cast<long>(n), checked.end());
      parsed.emplace(make_chain<Real>(scratch.masses, scratch.lengths, checked[1]));
    }
  }
  if (!parsed) {
    beta = parse_real<Real>(fields[0], columns[0], Domain::positive);
    parsed.emplace(case_chain<Real>(fields, columns, n, scratch.masses, scratch.lengths));
  }
  const Averages<Real> averages = average(*parsed, beta, options, scratch.workspace);
  scratch.record.reset(io::averages_fields(), n);
  io::append_averages(scratch.record, averages, &beta, io::Printing{options.digits});
  const io::RowCells cells[] = {{&scratch.record, chosen}};
  rows.append(line, fields, std::is_same_v<Real, double>, cells);
}

/// Thread CPU time in microseconds (CLOCK_THREAD_CPUTIME_ID: a system call, ~0.5 us).
double thread_cpu_microseconds() {
  timespec ts{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
  return 1e6 * static_cast<double>(ts.tv_sec) + 1e-3 * static_cast<double>(ts.tv_nsec);
}

/// --timing: the median cost of reading the timer twice (an empty interval), subtracted from
/// every row's time and printed beside it.
double timer_overhead_microseconds() {
  std::vector<double> empty(201);
  for (double& t : empty) {
    const double start = thread_cpu_microseconds();
    t = thread_cpu_microseconds() - start;
  }
  std::ranges::nth_element(empty, empty.begin() + 100);
  return empty[100];
}

/// --timing: one line on stderr with the distribution of the rows' thread CPU times (rows not
/// computed in this run, kept or interrupted, have a negative time and are left out).
void report_case_timing(const std::vector<double>& row_us, const CasesFile& file,
                        double timer_us, int threads) {
  std::vector<double> sorted;
  std::size_t worst = 0;
  for (std::size_t i = 0; i < row_us.size(); ++i) {
    if (row_us[i] < 0) continue;
    if (sorted.empty() || row_us[i] > row_us[worst]) worst = i;
    sorted.push_back(row_us[i]);
  }
  if (sorted.empty()) {
    std::fprintf(stderr, "pendavg: timing: rows=0\n");
    return;
  }
  std::ranges::sort(sorted);
  const std::size_t count = sorted.size();
  const auto rank = [&](double p) {  // nearest rank
    const auto r = static_cast<std::size_t>(std::ceil(p * static_cast<double>(count)));
    return sorted[std::clamp<std::size_t>(r, 1, count) - 1];
  };
  const double median =
      count % 2 ? sorted[count / 2] : 0.5 * (sorted[count / 2 - 1] + sorted[count / 2]);
  std::fprintf(stderr,
               "pendavg: timing: rows=%zu median_us=%.3f p90_us=%.3f worst_us=%.3f "
               "worst_row=%zu worst_line=%zu threads=%d timer_us=%.3f (thread CPU time per row, "
               "row to formatted line, timer overhead subtracted)\n",
               count, median, rank(0.9), sorted.back(), worst, file.rows[worst].line, threads,
               timer_us);
}

/// Checks one cases row as the library will see it (fields, numbers at the working precision,
/// the chain, the method's domain), without computing it.
/// A double run keeps the row's numbers in `numbers` (beta, g, m1..mN, l1..lN) when it passes.
template <class Real>
void check_case(const CasesFile& file, const CaseRow& row, const std::vector<std::string>& columns,
                const AverageOptions& options, CaseScratch<Real>& scratch,
                std::span<double> numbers = {}) {
  std::optional<working_precision> precision;
  if constexpr (!std::is_same_v<Real, double>) precision.emplace(options.digits + guard_digits);
  scratch.fields.resize(columns.size());
  case_fields(file, row, scratch.fields);
  const Real beta = parse_real<Real>(scratch.fields[0], columns[0], Domain::positive);
  const Chain<Real> chain =
      case_chain<Real>(scratch.fields, columns, file.particles, scratch.masses, scratch.lengths);
  check_average(chain, beta, options);
  check_printed_quotients(beta);
  if constexpr (std::is_same_v<Real, double>) {
    if (!numbers.empty()) {
      numbers[0] = beta;
      numbers[1] = chain.gravity();
      std::ranges::copy(chain.masses(), numbers.begin() + 2);
      std::ranges::copy(chain.lengths(), numbers.begin() + 2 + static_cast<long>(chain.size()));
    }
  }
}

/// Where --cases writes, and what it keeps from an earlier run.
struct CasesOutput {
  std::optional<std::string> columns;  ///< --columns (none: every output column)
  std::string path;       ///< --output or --resume (empty: stdout)
  std::string resume;     ///< --resume
  std::string timing_rows;  ///< --timing-rows
  bool timing = false;
  std::optional<Shard> shard;  ///< --shard K/N
  io::Format format = io::Format::csv;  ///< --format
};

// ---------------------------------------------------------------- average_cases' steps

/// Step 1, plan: the options every row passes to the library (the method resolved, or the
/// microcanonical rule), checked before any row. A single row runs on one thread and lets the
/// torus and QMC methods use every core instead.
struct CasesPlan {
  bool microcanonical = false;  ///< an energy or excitation column
  AverageOptions options;
  MicrocanonicalOptions micro;
};

CasesPlan plan_cases(const CasesFile& file, const AverageOptions& settings, int threads) {
  CasesPlan plan;
  plan.microcanonical = file.state != "beta";
  plan.options = settings;
  if (file.rows.size() == 1 && ranks() == 1) plan.options.threads = threads;
  if (plan.microcanonical) {  // checked before any row
    try {
      plan.micro = microcanonical_options(plan.options, file.particles);
    } catch (const invalid_input& bad) {
      throw usage_error("average: " + std::string(bad.what()));
    }
  } else {
    resolve_average_method(file.particles, plan.options);
  }
  return plan;
}

/// Step 2, format: with --output, the '#' lines that say what made the file (and that --resume
/// checks): the cases (by content), digits, method and its options, version; then the column
/// line (the input columns, then `output_names`).
std::string cases_header(const CasesFile& file, const std::string& path,
                         const AverageOptions& settings, const std::vector<std::string>& columns,
                         const std::vector<std::string>& output_names, bool provenance) {
  const std::size_t n = file.particles;
  std::string header = io::schema_line();
  if (provenance) {
    header += "# pendavg average --cases: " + std::to_string(file.rows.size()) +
              " rows of N = " + std::to_string(n) + ", cases file fnv1a-64 " +
              fnv1a_hex(file.text) + "\n";
    header += "# digits = " + std::to_string(settings.digits) + ", method = " +
              average_method_name(settings.method);
    if (settings.tolerance) header += ", tol = " + decimal(*settings.tolerance, 17);
    if (settings.samples) header += ", samples = " + std::to_string(*settings.samples);
    if (settings.shifts) header += ", shifts = " + std::to_string(*settings.shifts);
    if (settings.seed) header += ", seed = " + std::to_string(*settings.seed);
    header += "\n# pendavg " + std::string(version()) + ", generated " + utc_timestamp() +
              " (UTC) from " + escaped_line(path) + "\n";  // a line, whatever the name
  }
  append_csv_line(header, columns);
  header.pop_back();
  for (const std::string& name : output_names) (header += ',') += name;
  header += '\n';
  return header;
}

/// The rows in --format's layout: the input columns, then `output_names` (the cells `chosen`
/// of the output fields) and (text) each one's width: an input's widest text in the whole file
/// (every shard's widths are the merged file's), an output's widest at `digits`.
io::RowWriter cases_row_writer(const CasesFile& file, const std::vector<std::string>& columns,
                               const std::vector<std::string>& output_names,
                               std::span<const std::size_t> chosen, int digits, bool microcanonical,
                               io::Format format) {
  std::vector<std::string> names = columns;
  names.insert(names.end(), output_names.begin(), output_names.end());
  if (format != io::Format::text) return io::RowWriter(format, std::move(names));
  std::vector<std::size_t> widths(columns.size(), 1);
  std::vector<std::string_view> fields(columns.size());
  for (const CaseRow& row : file.rows) {
    case_fields(file, row, fields);
    for (std::size_t k = 0; k < fields.size(); ++k) widths[k] = std::max(widths[k], fields[k].size());
  }
  const std::vector<const io::Field*> cells = io::cell_fields(
      microcanonical ? io::microcanonical_fields(file.state) : io::averages_fields(), file.particles);
  const int run_digits[] = {digits};
  for (const std::size_t c : chosen) widths.push_back(io::widest_cell(*cells[c], run_digits));
  return io::RowWriter(format, std::move(names), std::move(widths));
}

/// Step 3: rank 0 checks the outputs and reads a resumed file into `resumed`; every rank learns
/// the verdict (a usage_error on every rank when the outputs cannot be written or the file does
/// not match).
void open_cases_outputs(const CasesFile& file, const std::vector<CaseRow>& rows,
                        const std::vector<std::string>& columns, const io::RowWriter& row_format,
                        const std::string& header, const CasesOutput& where,
                        std::optional<ResumedRows>& resumed,
                        std::optional<AtomicFile>& timing_file, std::optional<SweepFile>& output) {
  on_root([&] {
    if (!where.path.empty()) probe_output(where.path, "average");
    if (!where.timing_rows.empty()) {
      // Opened, and its column line written, now: a target that cannot take it (a full disk,
      // /dev/full) fails the run before any row went to stdout.
      timing_file.emplace(where.timing_rows, "average");
      timing_file->append("row,line,us\n");
    }
    if (!where.resume.empty()) {  // the file, or a killed run's temporary, or nothing yet
      std::vector<std::string_view> fields(columns.size());
      resumed.emplace(where.resume, "average", header, row_format, rows.size(), columns.size(),
                      [&](std::size_t k) {
                        case_fields(file, rows[k], fields);
                        std::string key;
                        for (const std::string_view field : fields)
                          (key += key.empty() ? "" : ",") += field;
                        return key;
                      });
    }
    // Opened here, so that every rank learns it failed (a FIFO nobody reads, say).
    output.emplace(where.path, "average", header, resumed ? &*resumed : nullptr,
                   row_format.format());
    if (where.shard) output->row_number = [&](std::size_t k) { return where.shard->row(k); };
  });
  input_checked("average");
}

/// --timing-rows FILE: every computed row's time as CSV row,line,us, appended to `text` as the
/// rows are written (rows first..first+us.size()-1; a kept or failed row has a negative time and
/// is left out), and written to the file (atomically: committed at the end) in pieces of 64 kB.
void add_timing_rows(std::string& text, std::size_t first, std::span<const double> us,
                     const std::vector<CaseRow>& rows, AtomicFile& target, bool last = false) {
  char number[32];
  for (std::size_t k = 0; k < us.size(); ++k) {
    if (us[k] < 0) continue;
    const std::size_t i = first + k;
    const int length = std::snprintf(number, sizeof number, "%.3f", us[k]);
    ((((text += std::to_string(i)) += ',') += std::to_string(rows[i].line)) += ',')
        .append(number, static_cast<std::size_t>(length)) += '\n';
  }
  if (last || text.size() >= (64u << 10)) {
    target.append(text);
    text.clear();
  }
}

/// Every row is checked first; then the rows are computed by the sweep engine (sweep.hpp: all
/// ranks and threads, one thread per row, so the output does not depend on their number) and
/// streamed in file order. The first bad row (in file order) is reported. `timing`: see
/// report_case_timing.
template <class Real>
std::string average_cases(const CasesFile& file, const std::string& path,
                          const AverageOptions& settings, const CasesOutput& where) {
  // The rows of this run: the file's, or those of the shard (plan_cases and the header still see
  // the whole file: a shard's rows run as in the whole sweep, and its header names the sweep).
  std::vector<CaseRow> shard_rows;
  for (std::size_t k = 0; where.shard && k < where.shard->count(); ++k)
    shard_rows.push_back(file.rows[where.shard->row(k)]);
  const std::vector<CaseRow>& rows = where.shard ? shard_rows : file.rows;
  const std::size_t n = file.particles;
  const std::vector<std::string> columns = case_columns(n, file.state);
  const int digits = settings.digits;
  const int threads = hardware_threads();
  const CasesPlan plan = plan_cases(file, settings, threads);
  // The output columns after the input ones: all of them, or --columns' choice.
  const std::vector<std::string> all_names = io::column_names(
      plan.microcanonical ? io::microcanonical_fields(file.state) : io::averages_fields(), n);
  std::vector<std::size_t> chosen;
  std::vector<std::string> output_names;
  if (where.columns) {
    try {
      chosen = io::select_columns(*where.columns, all_names, columns, n, output_names);
    } catch (const std::invalid_argument& bad) {
      throw usage_error("average: --columns: " + std::string(bad.what()));
    }
  } else {
    chosen.resize(all_names.size());
    for (std::size_t k = 0; k < chosen.size(); ++k) chosen[k] = k;
    output_names = all_names;
  }

  const auto line_context = [&](std::size_t k) {
    return path + " line " + std::to_string(rows[k].line) + ": ";
  };
  const StopOnSignal signals;  // from here on SIGINT/SIGTERM stop the sweep
  // Per-thread scratch (fields, numbers, the engine's workspace), reused from row to row by the
  // check below and by the sweep.
  std::vector<std::optional<CaseScratch<Real>>> scratch(static_cast<std::size_t>(threads));
  const auto scratch_of = [&](int thread) -> CaseScratch<Real>& {
    std::optional<CaseScratch<Real>>& mine = scratch[static_cast<std::size_t>(thread)];
    if (!mine) mine.emplace();
    return *mine;
  };
  std::optional<CheckedNumbers> checked;  // at most checked_numbers_budget bytes, else parse again
  if (std::is_same_v<Real, double> && !plan.microcanonical &&
      rows.size() * (2 * n + 2) * sizeof(double) <= checked_numbers_budget)
    checked.emplace(rows.size(), n);
  const auto check = [&](std::size_t k, int thread) {
    try {
      if (plan.microcanonical) {
        check_microcanonical_case<Real>(file, rows[k], columns, digits, plan.micro);
      } else {
        check_case<Real>(file, rows[k], columns, plan.options, scratch_of(thread),
                         checked ? checked->row(k) : std::span<double>{});
        if (checked) checked->stored[k] = 1;
      }
    } catch (const invalid_input& bad) {
      throw usage_error(line_context(k) + bad.what());
    }
  };
  if (const std::size_t bad = first_failing_row(rows.size(), threads, check, "average", "rows");
      bad < rows.size())
    check(bad, 0);  // throws the first bad row's error, on every rank

  const io::RowWriter row_format = cases_row_writer(file, columns, output_names, chosen, settings.digits,
                                                   plan.microcanonical, where.format);
  const std::string header = sweep_header(
      row_format, "average",
      marked(where.shard,
             cases_header(file, path, settings, columns, output_names, !where.path.empty())));
  std::optional<ResumedRows> resumed;
  std::optional<AtomicFile> timing_file;  // --timing-rows, on rank 0
  std::string timing_text;                // its lines not yet written
  std::optional<SweepFile> output;
  open_cases_outputs(file, rows, columns, row_format, header, where, resumed, timing_file, output);

  // Step 4, run: the sweep engine computes the rows; rank 0 writes them in order.
  const double timer_us = where.timing ? timer_overhead_microseconds() : 0.0;
  std::vector<double> row_us(where.timing && is_root() ? rows.size() : 0, -1.0);
  if (is_root()) {
    output->on_timing = [&](std::size_t first, std::span<const double> us) {
      for (std::size_t k = 0; k < us.size(); ++k) row_us[first + k] = us[k] - timer_us;
      if (timing_file)
        add_timing_rows(timing_text, first,
                        std::span<const double>(row_us).subspan(first, us.size()), rows,
                        *timing_file);
    };
  }
  SweepRows sweep;
  sweep.count = rows.size();
  sweep.threads = plan.options.threads > 1 ? 1 : threads;
  sweep.timing = where.timing;
  sweep.progress = "average";
  sweep.row_bytes = 1;
  for (const CaseRow& row : rows)
    sweep.row_bytes = std::max(sweep.row_bytes, 2 * row.size + 1 + all_names.size() *
                                                    (decimal_max_length(digits) + 1));
  if (where.format == io::Format::json)  // its keys
    for (const std::string& name : row_format.columns()) sweep.row_bytes += name.size() + 6;
  sweep.row_bytes += row_format.text_line_length();  // text: its padding
  std::vector<std::optional<io::Record>> micro_records(static_cast<std::size_t>(threads));
  sweep.compute = [&](std::size_t k, int thread, std::string& text) {
    if (plan.microcanonical) {
      auto& record = micro_records[static_cast<std::size_t>(thread)];
      if (!record) record.emplace();
      microcanonical_case<Real>(text, file, rows[k], columns, chosen, plan.micro, digits, *record,
                                row_format);
      return;
    }
    write_case<Real>(text, file, rows[k], columns, chosen, plan.options, scratch_of(thread),
                     row_format,
                     checked ? checked->row_if_stored(k) : std::span<const double>{});
  };
  // A row that fails once the sweep runs (the check above passed it) does not cost the others:
  // it becomes a '# failed:' line in its place, and the run ends with rows_failed (exit 3).
  sweep.failed_row = [&](std::size_t k, std::string_view reason) {
    return failed_row_line(line_context(k), reason);
  };
  run_sweep(sweep, output ? &*output : nullptr, [&](const SweepOutcome& outcome) {
    if (outcome.failed) {
      output->discard();
      rethrow_failure(outcome, line_context);
    }
    if (outcome.written < rows.size()) {
      output->end_rows(std::to_string(outcome.written) + " of " + std::to_string(rows.size()) +
                       " rows computed; the rows of the others are left out");
      std::fprintf(stderr, "[average] interrupted: %zu of %zu rows written\n", outcome.written,
                   rows.size());
    } else {
      output->end_rows({});
    }
    output->commit();
    if (timing_file) {
      add_timing_rows(timing_text, 0, {}, rows, *timing_file, true);
      timing_file->commit();
    }
    if (where.timing) report_case_timing(row_us, file, timer_us, outcome.threads);
    if (outcome.failed_rows > 0)
      throw rows_failed(failed_rows_message("average", outcome, "rows", where.path,
                                            line_context(outcome.first_failed_row),
                                            where.format));
  });
  return {};
}

std::string run_average(const Options& options) {
  const AverageOptions settings = average_settings(options);
  if (!options.has("cases")) {
    for (const std::string_view cases_only :
         {"timing", "timing-rows", "resume", "columns", "shard"})
      if (options.has(cases_only))
        throw usage_error("average: --" + std::string(cases_only) + " is for --cases only");
    const Format format = format_option(options, "csv", all_formats);
    const std::string_view state = state_option(options);
    if (state != "beta" && settings.certified)
      throw usage_error("average: --certified is for canonical averages (--beta), not --" +
                        std::string(state));
    check_output_option(options, "average");
    if (state != "beta")
      return deliver(options, "average", with_number_type(settings.digits, [&]<class Real>() {
                       return microcanonical_one<Real>(options, settings, state, format);
                     }));
    return deliver(options, "average", with_number_type(settings.digits, [&]<class Real>() {
                     return average_one<Real>(options, settings, format);
                   }));
  }
  for (const std::string_view single : {"masses", "lengths", "g", "beta", "energy", "excitation"})
    if (options.has(single))
      throw usage_error("average: --cases cannot be combined with --" + std::string(single));
  const std::string path(options.required("cases"));
  CasesOutput where;
  where.timing_rows = std::string(options.get("timing-rows", ""));
  if (options.has("columns")) where.columns = std::string(options.get("columns", ""));
  where.resume = std::string(options.get("resume", ""));
  where.path = std::string(options.get("output", ""));
  for (const std::string_view name : {"timing-rows", "output", "resume"})
    if (options.has(name) && options.get(name, "").empty())
      throw usage_error("average: --" + std::string(name) + " needs a file name");
  if (!where.resume.empty() && !where.path.empty() &&
      resolved_path(where.path, "average") != resolved_path(where.resume, "average"))
    throw usage_error("average: --resume FILE continues FILE and writes it; --output must name "
                      "the same file or be left out");
  if (!where.resume.empty()) where.path = where.resume;
  const std::string_view output_option = options.has("resume") ? "resume" : "output";
  if (!where.path.empty()) refuse_same_file(where.path, output_option, path, "cases", "average");
  if (!where.timing_rows.empty()) {
    refuse_same_file(where.timing_rows, "timing-rows", path, "cases", "average");
    if (!where.path.empty())
      refuse_same_file(where.timing_rows, "timing-rows", where.path, output_option, "average");
  }
  const CasesFile file = read_cases_file(path);
  where.timing = options.has("timing") || !where.timing_rows.empty();
  where.shard = shard_option(options, "average", file.rows.size());
  where.format = format_option(options, "csv", all_formats);
  if (settings.digits == min_digits) return average_cases<double>(file, path, settings, where);
  return average_cases<mpfr_real>(file, path, settings, where);
}

}  // namespace

constexpr std::array<std::string_view, 19> average_options{
    "masses", "lengths", "g",      "beta",   "digits",      "method", "format",
    "cases",  "tol",     "samples", "shifts", "seed",       "timing-rows", "output",
    "resume", "energy",  "excitation", "columns", "shard"};
constexpr std::array<std::string_view, 2> average_flags{"timing", "certified"};
const Command average_command{"average", average_usage, average_options, run_average,
                              average_flags, true};

}  // namespace pendavg::cli
