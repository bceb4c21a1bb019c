// SPDX-License-Identifier: GPL-3.0-or-later
// src/cli/commands.cpp -- the pendavg commands average, limit and series: options -> Chain<Real>
// and beta -> one library call (pendavg::average, the limits, series_convergence) -> formatted
// string. `digits` == 16 runs in double, more digits in MPFR under a working_precision held
// while the numbers are parsed (MPFR's precision is per thread: a parallel loop takes one per
// row instead).
#include "commands.hpp"

#include "args.hpp"
#include "distribute.hpp"
#include "files.hpp"
#include "format.hpp"
#include "average_options.hpp"
#include "case_columns.hpp"
#include "interrupt.hpp"
#include "simulate.hpp"
#include "sweep.hpp"
#include "shard.hpp"
#include "sweep_file.hpp"
#include "table.hpp"
#include "version_info.hpp"

#include "pendavg/mpfr.hpp"
#include "pendavg/pendavg.hpp"

#include <algorithm>
#include <array>
#include <charconv>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <ctime>
#include <exception>
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

// ---------------------------------------------------------------- usage

constexpr std::string_view general_usage =
    "pendavg -- thermal averages of the kinetic energy of a planar multiple pendulum\n"
    "(Konishi & Yanagita): beta<K_i>, <cos phi_i>, Var K_i, with error estimates.\n"
    "\n"
    "usage:\n"
    "  pendavg average --masses M1,...,MN --lengths L1,...,LN [--g G] --beta B [options]\n"
    "  pendavg average --masses ... --lengths ... (--energy E | --excitation D) [options]\n"
    "  pendavg average --cases FILE.csv [--digits D] [--method M] [method options] [--columns LIST] [--timing]\n"
    "  pendavg limit   --masses M1,M2 [--lengths L1,L2] [--g G] [--digits D] [--format F]\n"
    "  pendavg series  --masses M1,M2 --lengths L1,L2 [--g G] --beta B [--terms N] [options]\n"
    "  pendavg table   --beta SPEC [--mu1 SPEC] [--l2 SPEC] [--g SPEC] ... [--chain LIST] [--digits LIST] [--output FILE.csv]\n"
    "  pendavg table   (--energy SPEC | --excitation SPEC) ...: microcanonical sweeps\n"
    "  pendavg simulate --masses ... --lengths ... (--theta A | --phi ...) --time T [options]\n"
    "  pendavg poincare --masses M1,M2 --lengths L1,L2 --energy E [--orbits K] [--points P]\n"
    "  pendavg merge   --output FILE SHARD...: the files of table/average --cases --shard K/N\n"
    "  pendavg help [COMMAND]     pendavg COMMAND --help     pendavg --version\n"
    "\n"
    "Numbers are plain decimals (0.5, 1e-3). --digits D (16..1000, default 16) is the number of\n"
    "significant digits requested: 16 runs in double, more in MPFR. Bad input exits with 2.\n";

constexpr std::string_view average_usage =
    "usage: pendavg average --masses M1,...,MN --lengths L1,...,LN [--g G] --beta B [--digits D]\n"
    "                       [--method M] [--tol T] [--samples S] [--shifts R] [--seed K]\n"
    "                       [--certified] [--format json|csv|text]\n"
    "       pendavg average --masses ... --lengths ... [--g G] (--energy E | --excitation D)\n"
    "                       [--digits D] [--method M] [method options] [--format json|csv|text]\n"
    "       pendavg average --cases FILE.csv [--digits D] [--method M] [method options]\n"
    "                       [--columns LIST] [--output FILE | --resume FILE] [--timing]\n"
    "                       [--timing-rows FILE] [--shard K/N]\n"
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
    "Output (default json): N, beta, digits, method, beta_K, K, error, ratio (<K1>/<K2>, null\n"
    "for N = 1), cos_phi, var_K, evaluations, seconds, converged, diagonal_approx (the paper's\n"
    "eq. ke-linear-tave-1), beta_Kc (beta<K_i^(c)> = 1/2), then every other error: error_kind\n"
    "(bound | estimate | statistical: what the errors of beta_K and ratio promise), K_error,\n"
    "ratio_error, cos_phi_error, var_K_error, error_kinds (per observable), work_unit (terms,\n"
    "nodes or samples: what evaluations counts), equipartition_residual (|sum beta<K_i> - N/2|)\n"
    "and run (the torus grid, the qmc points, shifts and effective sample fraction, or the\n"
    "transfer operator's final angle and pivot nodes and levels). Printed\n"
    "errors include half a unit in the last printed digit of their value.\n"
    "--cases reads a CSV with the columns beta,g,m1..mN,l1..lN (any order, N from the header;\n"
    "blank lines and lines starting with # are skipped) and writes one CSV row per case: the\n"
    "input columns in that order, then beta_K1..N, error_K1..N, ratio, cos_phi1..N, method,\n"
    "evaluations, ratio_error, cos_phi_error1..N, var_K1..N, var_K_error1..N, error_kind,\n"
    "converged, then cos_phi_error_kind, var_K_error_kind (what those errors promise: a series\n"
    "row's beta_K error is a bound, its cos_phi and var_K errors estimates), work_unit,\n"
    "equipartition_residual, beta_Kc1..N, beta_Kc_error1..N, beta_Kc_error_kind. Every row is\n"
    "checked before the first is computed. --columns LIST prints only the listed output\n"
    "columns, in that order, after the input columns: names as above, or a per-particle stem\n"
    "(cos_phi: cos_phi1..N), e.g. --columns beta_K,error_K,ratio (smaller files, faster\n"
    "rows; --resume needs the same LIST). Rows run on all cores (and,\n"
    "under mpirun/srun with pendavg built with MPI, on all ranks); the output does not depend\n"
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
    "minute); qmc is double only, torus-trapezoid only for N = 2. Output keys: N, energy,\n"
    "excitation, digits, ensemble (microcanonical), method, K, K_error, Kc, Kc_error, cos_phi,\n"
    "cos_phi_error, var_K, var_K_error, K_total, K_total_error, density_of_states,\n"
    "density_of_states_error, error_kind, evaluations, work_unit, seconds, converged, run. An\n"
    "energy at or below E_min is refused. --cases takes an energy or excitation column instead of\n"
    "beta; its rows then have K1..N, K_error1..N, Kc, cos_phi1..N, method, evaluations, Kc_error,\n"
    "cos_phi_error1..N, var_K1..N, var_K_error1..N, error_kind, converged, then excitation (or\n"
    "energy), the other way of stating the row's state, then K_total, K_total_error,\n"
    "density_of_states, density_of_states_error and work_unit.\n";

constexpr std::string_view limit_usage =
    "usage: pendavg limit --masses M1,...,MN [--lengths L1,...,LN] [--g G] [--digits D]\n"
    "                     [--certified] [--format json|csv|text]\n"
    "\n"
    "The high-temperature (beta -> 0) and low-temperature (beta -> infinity) limits of\n"
    "beta<K_i>, their error estimates, <K1>/<K2> and beta^2 Var K_i. Lengths default to 1.\n"
    "N = 2: the paper's elliptic K/E formula. Any N: beta -> 0 is the torus average of the chain\n"
    "at g = 0 (tensor trapezoid for N <= 5, transfer beyond, double only);\n"
    "beta -> infinity is exact: beta<K_i> = 1/2, beta^2 Var K_i = tr(X_i(0)^2)/2.\n"
    "--certified (N = 2): beta -> 0 in ball arithmetic, every error a proven bound (as for\n"
    "`pendavg average`).\n"
    "JSON (default): N, digits, and per limit (high_temperature, low_temperature) beta_K, error,\n"
    "ratio, var_K_beta2, method, error_kind, ratio_error, cos_phi, cos_phi_error,\n"
    "var_K_beta2_error, error_kinds, evaluations, work_unit, then converged, run (the torus\n"
    "grid or the transfer operator's resolution, as `average` prints it, or null),\n"
    "equipartition_residual, beta_Kc and beta_Kc_error; then seconds (both limits). --format\n"
    "csv: one row per limit with the columns of `average --format csv` (beta, K_i and var_K_i\n"
    "empty: no finite beta; seconds the limit's own), then limit, beta2_var_K1..N,\n"
    "beta2_var_K_error1..N, beta_Kc_error1..N, beta_Kc_error_kind.\n";

constexpr std::string_view series_usage =
    "usage: pendavg series --masses M1,M2 --lengths L1,L2 [--g G] --beta B [--digits D]\n"
    "                      [--terms N] [--format text|csv|json]\n"
    "\n"
    "The paper's series for beta<K1>, term by term, in MPFR: n, R_n, term, numerator,\n"
    "denominator, value (partial beta<K1>) and the rigorous truncation bound. --terms 0\n"
    "(default) sums until the bound certifies the requested digits.\n";

// ---------------------------------------------------------------- shared helpers

/// Runs `body.operator()<Real>()` with Real = double for 16 digits and Real = mpfr_real (under a
/// working_precision held for the whole call, parsing included) for more. Not for commands whose
/// rows run in a parallel loop: each row holds its own working precision there.
template <class Body>
std::string with_number_type(int digits, Body&& body) {
  if (digits == min_digits) return body.template operator()<double>();
  const working_precision guard(digits + guard_digits);
  return body.template operator()<mpfr_real>();
}

Format format_option(const Options& options, std::string_view fallback,
                     std::span<const std::string_view> allowed) {
  const std::string_view name = options.get("format", fallback);
  parse_choice(name, "format", allowed);
  constexpr std::array<std::string_view, 3> names{"json", "csv", "text"};
  return static_cast<Format>(std::ranges::find(names, name) - names.begin());
}

template <class Real>
Chain<Real> make_chain(std::vector<Real> masses, std::vector<Real> lengths, Real g) {
  if (masses.size() != lengths.size())
    throw usage_error(std::to_string(masses.size()) + " masses but " +
                      std::to_string(lengths.size()) + " lengths");
  return Chain<Real>(std::move(masses), std::move(lengths), std::move(g));
}

/// The chain of --masses, --lengths (all 1 when optional and absent) and --g (default 1).
template <class Real>
Chain<Real> chain_option(const Options& options, bool lengths_required) {
  auto masses = parse_real_list<Real>(options.required("masses"), "--masses", Domain::positive);
  auto lengths = lengths_required || options.has("lengths")
                     ? parse_real_list<Real>(options.required("lengths"), "--lengths",
                                             Domain::positive)
                     : std::vector<Real>(masses.size(), Real(1));
  Real g = parse_real<Real>(options.get("g", "1"), "--g", Domain::nonnegative);
  return make_chain(std::move(masses), std::move(lengths), std::move(g));
}

class Stopwatch {
 public:
  double seconds() const {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count();
  }

 private:
  std::chrono::steady_clock::time_point start_ = std::chrono::steady_clock::now();
};

/// `average`'s options (method, digits, tol, samples, shifts, seed).
AverageOptions average_settings(const Options& options) {
  AverageOptions settings = parse_average_options(options, average_option_names);
  settings.certified = options.has("certified");
  return settings;
}

// ---------------------------------------------------------------- average: output

struct AverageReport {
  std::size_t particles;
  std::string_view beta;
  int digits;
  AveragesText values;
  std::string run;  ///< the torus or qmc run as a JSON object, or "null"
  double seconds;
};

std::string average_json(const AverageReport& r) {
  const AveragesText& v = r.values;
  JsonObject json;
  json.integer("N", static_cast<long long>(r.particles))
      .string("beta", r.beta)
      .integer("digits", r.digits)
      .string("method", v.method)
      .strings("beta_K", v.beta_kinetic)
      .strings("K", v.kinetic)
      .strings("error", v.error)
      .raw("ratio", json_nullable(v.ratio))  // <K1>/<K2> needs a second particle
      .strings("cos_phi", v.cos_angle)
      .strings("var_K", v.variance)
      .integer("evaluations", static_cast<long long>(v.evaluations))
      .raw("seconds", seconds_text(r.seconds))
      .boolean("converged", v.converged)
      .strings("diagonal_approx", v.diagonal_approximation)
      .strings("beta_Kc", v.beta_kinetic_canonical)
      .string("error_kind", v.error_kind)
      .strings("K_error", v.kinetic_error)
      .raw("ratio_error", json_nullable(v.ratio_error))
      .strings("cos_phi_error", v.cos_angle_error)
      .strings("var_K_error", v.variance_error)
      .raw("error_kinds", JsonObject()
                              .string("beta_K", v.error_kind)
                              .string("ratio", v.error_kind)
                              .string("cos_phi", v.cos_angle_error_kind)
                              .string("var_K", v.variance_error_kind)
                              .str())
      .string("work_unit", v.work_unit)
      .string("equipartition_residual", v.equipartition_residual)
      .raw("run", r.run);
  return json.str() + "\n";
}

/// One CSV line's column names and cells, built side by side.
struct CsvLine {
  std::vector<std::string> header, row;
  void add(std::string name, std::string value) {
    header.push_back(std::move(name));
    row.push_back(std::move(value));
  }
  /// stem1..stem`count`; cells past the end of `values` are empty (an array a report does not
  /// have, e.g. <K_i> of a limit).
  void add_array(std::string_view stem, const std::vector<std::string>& values,
                 std::size_t count) {
    const auto names = indexed_names(stem, count);
    header.insert(header.end(), names.begin(), names.end());
    for (std::size_t i = 0; i < count; ++i) row.push_back(i < values.size() ? values[i] : "");
  }
};

/// The columns of `average --format csv` for one report; `limit --format csv` writes the same
/// for each limit (beta, <K_i> and Var K_i empty there) and adds its own after them.
CsvLine average_csv_line(const AverageReport& r) {
  const std::size_t n = r.particles;
  const AveragesText& v = r.values;
  CsvLine line;
  line.add("N", std::to_string(n));
  line.add("beta", std::string(r.beta));
  line.add("digits", std::to_string(r.digits));
  line.add("method", v.method);
  line.add_array("beta_K", v.beta_kinetic, n);
  line.add_array("K", v.kinetic, n);
  line.add_array("error_K", v.error, n);
  line.add("ratio", v.ratio);
  line.add_array("cos_phi", v.cos_angle, n);
  line.add_array("var_K", v.variance, n);
  line.add("evaluations", std::to_string(v.evaluations));
  line.add("seconds", seconds_text(r.seconds));
  line.add("converged", v.converged ? "true" : "false");
  line.add_array("diagonal_approx", v.diagonal_approximation, n);
  line.add_array("beta_Kc", v.beta_kinetic_canonical, n);
  line.add("error_kind", v.error_kind);
  line.add_array("K_error", v.kinetic_error, n);
  line.add("ratio_error", v.ratio_error);
  line.add_array("cos_phi_error", v.cos_angle_error, n);
  line.add_array("var_K_error", v.variance_error, n);
  line.add("cos_phi_error_kind", v.cos_angle_error_kind);
  line.add("var_K_error_kind", v.variance_error_kind);
  line.add("work_unit", v.work_unit);
  line.add("equipartition_residual", v.equipartition_residual);
  return line;
}

std::string average_csv(const AverageReport& r) {
  const CsvLine line = average_csv_line(r);
  std::string out;
  append_csv_line(out, line.header);
  append_csv_line(out, line.row);
  return out;
}

/// The lines after a text table: what the errors promise, and the work done.
std::string errors_and_work_text(const AveragesText& v, double seconds,
                                 std::string_view variance) {
  return "errors: beta<K_i> and <K1>/<K2> " + v.error_kind + ", <cos phi_i> " +
         v.cos_angle_error_kind + ", " + std::string(variance) + " " + v.variance_error_kind +
         "\n" + "evaluations = " + std::to_string(v.evaluations) + " " + v.work_unit +
         ", seconds = " + seconds_text(seconds) +
         ", converged = " + (v.converged ? "yes" : "no") + "\n";
}

std::string average_text(const AverageReport& r) {
  const AveragesText& v = r.values;
  std::vector<std::vector<std::string>> table{{"i", "beta<K_i>", "error", "<K_i>", "<cos phi_i>",
                                               "error", "Var K_i", "error", "diagonal approx",
                                               "beta<K_i^c>"}};
  for (std::size_t i = 0; i < v.beta_kinetic.size(); ++i)
    table.push_back({std::to_string(i + 1), v.beta_kinetic[i], v.error[i], v.kinetic[i],
                     v.cos_angle[i], v.cos_angle_error[i], v.variance[i], v.variance_error[i],
                     v.diagonal_approximation[i], v.beta_kinetic_canonical[i]});
  return "N = " + std::to_string(r.particles) + ", beta = " + std::string(r.beta) +
         ", digits = " + std::to_string(r.digits) + ", method = " + v.method + "\n" +
         aligned_table(table) +
         (r.particles >= 2 ? "<K1>/<K2> = " + v.ratio + " +- " + v.ratio_error + "\n"
                           : std::string()) +
         errors_and_work_text(v, r.seconds, "Var K_i");
}

/// The torus grid, the qmc run or the transfer operator's resolution of `a` as a JSON object,
/// "null" for the other methods.
template <class Real>
std::string run_json(const Averages<Real>& a) {
  if (a.torus)
    return JsonObject()
        .integer("points_per_dim", static_cast<long long>(a.torus->points_per_dim))
        .integer("levels", static_cast<long long>(a.torus->levels))
        .raw("grid_points", seconds_text(a.torus->grid_points))
        .str();
  if (a.qmc)
    return JsonObject()
        .integer("points", static_cast<long long>(a.qmc->points))
        .integer("shifts", static_cast<long long>(a.qmc->shifts))
        .raw("sigmas", seconds_text(a.qmc->sigmas))
        .string("effective_sample_fraction",
                decimal(a.qmc->effective_sample_fraction, error_digits))
        .str();
  if (a.transfer)
    return JsonObject()
        .integer("angle_nodes", static_cast<long long>(a.transfer->angle_nodes))
        .integer("pivot_nodes", static_cast<long long>(a.transfer->pivot_nodes))
        .integer("levels", static_cast<long long>(a.transfer->levels))
        .str();
  return "null";
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
  const AverageReport report{chain.size(), beta_text, digits,
                             averages_text(result, digits, &beta), run_json(result), seconds};
  switch (format) {
    case Format::csv: return average_csv(report);
    case Format::text:
      return average_text(report) +
             (result.interrupted ? "interrupted: the finished part of the run is reported\n" : "");
    case Format::json: break;
  }
  std::string json = average_json(report);
  if (result.interrupted) json.insert(json.rfind('}'), ", \"interrupted\": true");
  return json;
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

struct MicrocanonicalReport {
  std::size_t particles;
  std::string_view state, state_text;  ///< the option given and its text as written
  int digits;
  MicrocanonicalText values;
  double seconds;
};

std::string microcanonical_run_json(const MicrocanonicalText& v) {
  if (v.proposal_beta.empty()) return "null";
  return JsonObject()
      .string("proposal_beta", v.proposal_beta)
      .string("effective_sample_fraction", v.effective_sample_fraction)
      .str();
}

std::string microcanonical_json(const MicrocanonicalReport& r) {
  const MicrocanonicalText& v = r.values;
  JsonObject json;
  json.integer("N", static_cast<long long>(r.particles))
      .string("energy", r.state == "energy" ? std::string(r.state_text) : v.energy)
      .string("excitation", r.state == "excitation" ? std::string(r.state_text) : v.excitation)
      .integer("digits", r.digits)
      .string("ensemble", "microcanonical")
      .string("method", v.method)
      .strings("K", v.kinetic)
      .strings("K_error", v.kinetic_error)
      .string("Kc", v.kinetic_canonical)
      .string("Kc_error", v.kinetic_canonical_error)
      .strings("cos_phi", v.cos_angle)
      .strings("cos_phi_error", v.cos_angle_error)
      .strings("var_K", v.variance)
      .strings("var_K_error", v.variance_error)
      .string("K_total", v.kinetic_total)
      .string("K_total_error", v.kinetic_total_error)
      .string("density_of_states", v.density_of_states)
      .string("density_of_states_error", v.density_of_states_error)
      .string("error_kind", v.error_kind)
      .integer("evaluations", static_cast<long long>(v.evaluations))
      .string("work_unit", v.work_unit)
      .raw("seconds", seconds_text(r.seconds))
      .boolean("converged", v.converged)
      .raw("run", microcanonical_run_json(v));
  return json.str() + "\n";
}

std::string microcanonical_csv(const MicrocanonicalReport& r) {
  const MicrocanonicalText& v = r.values;
  std::vector<std::string> header{"N", "energy", "excitation", "digits", "ensemble", "method"};
  std::vector<std::string> row{std::to_string(r.particles),
                               r.state == "energy" ? std::string(r.state_text) : v.energy,
                               r.state == "excitation" ? std::string(r.state_text) : v.excitation,
                               std::to_string(r.digits), "microcanonical", v.method};
  const auto add_array = [&](std::string_view stem, const std::vector<std::string>& values) {
    const auto names = indexed_names(stem, values.size());
    header.insert(header.end(), names.begin(), names.end());
    row.insert(row.end(), values.begin(), values.end());
  };
  const auto add = [&](std::string name, std::string value) {
    header.push_back(std::move(name));
    row.push_back(std::move(value));
  };
  add_array("K", v.kinetic);
  add_array("K_error", v.kinetic_error);
  add("Kc", v.kinetic_canonical);
  add("Kc_error", v.kinetic_canonical_error);
  add_array("cos_phi", v.cos_angle);
  add_array("cos_phi_error", v.cos_angle_error);
  add_array("var_K", v.variance);
  add_array("var_K_error", v.variance_error);
  add("K_total", v.kinetic_total);
  add("K_total_error", v.kinetic_total_error);
  add("density_of_states", v.density_of_states);
  add("density_of_states_error", v.density_of_states_error);
  add("error_kind", v.error_kind);
  add("evaluations", std::to_string(v.evaluations));
  add("work_unit", v.work_unit);
  add("seconds", seconds_text(r.seconds));
  add("converged", v.converged ? "true" : "false");
  std::string out;
  append_csv_line(out, header);
  append_csv_line(out, row);
  return out;
}

std::string microcanonical_text_report(const MicrocanonicalReport& r) {
  const MicrocanonicalText& v = r.values;
  std::vector<std::vector<std::string>> table{
      {"i", "<K_i>_E", "error", "<cos phi_i>_E", "error", "Var K_i", "error"}};
  for (std::size_t i = 0; i < v.kinetic.size(); ++i)
    table.push_back({std::to_string(i + 1), v.kinetic[i], v.kinetic_error[i], v.cos_angle[i],
                     v.cos_angle_error[i], v.variance[i], v.variance_error[i]});
  const std::string energy = r.state == "energy" ? std::string(r.state_text) : v.energy;
  const std::string excitation =
      r.state == "excitation" ? std::string(r.state_text) : v.excitation;
  return "N = " + std::to_string(r.particles) + ", E = " + energy + ", E - E_min = " +
         excitation + ", digits = " + std::to_string(r.digits) +
         ", microcanonical, method = " + v.method + "\n" + aligned_table(table) +
         "<K_i^(c)>_E = <K>_E/N = " + v.kinetic_canonical + " +- " + v.kinetic_canonical_error +
         "\n<K>_E = " + v.kinetic_total + " +- " + v.kinetic_total_error +
         "\nOmega(E) = " + v.density_of_states + " +- " + v.density_of_states_error +
         "\nerrors: " + v.error_kind + "\nevaluations = " + std::to_string(v.evaluations) + " " +
         v.work_unit + ", seconds = " + seconds_text(r.seconds) +
         ", converged = " + (v.converged ? "yes" : "no") + "\n";
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
  const MicrocanonicalReport report{chain.size(), state, state_text, settings.digits,
                                    microcanonical_text(result, settings.digits), seconds};
  switch (format) {
    case Format::csv: return microcanonical_csv(report);
    case Format::text: return microcanonical_text_report(report);
    case Format::json: break;
  }
  return microcanonical_json(report);
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

/// The output columns of `average --cases` with an energy or excitation column, after the input
/// columns: K1..N, K_error1..N, Kc, cos_phi1..N, method, evaluations, Kc_error,
/// cos_phi_error1..N, var_K1..N, var_K_error1..N, error_kind, converged, the other state
/// (excitation for an energy column, energy for an excitation column), then K_total,
/// K_total_error, density_of_states, density_of_states_error and work_unit.
std::vector<std::string> microcanonical_case_columns(std::size_t n, std::string_view state) {
  std::vector<std::string> header;
  const auto add_names = [&](std::string_view stem) {
    const auto names = indexed_names(stem, n);
    header.insert(header.end(), names.begin(), names.end());
  };
  add_names("K");
  add_names("K_error");
  header.push_back("Kc");
  add_names("cos_phi");
  header.insert(header.end(), {"method", "evaluations", "Kc_error"});
  add_names("cos_phi_error");
  add_names("var_K");
  add_names("var_K_error");
  header.insert(header.end(),
                {"error_kind", "converged", state == "energy" ? "excitation" : "energy",
                 "K_total", "K_total_error", "density_of_states", "density_of_states_error",
                 "work_unit"});
  return header;
}

/// One row of `average --cases` with an energy or excitation column (the input fields as
/// written, then the `chosen` positions of microcanonical_case_columns), appended to `line`.
template <class Real>
void microcanonical_case(std::string& line, const CasesFile& file, const CaseRow& row,
                         const std::vector<std::string>& columns,
                         std::span<const std::size_t> chosen, const MicrocanonicalOptions& micro,
                         int digits) {
  std::optional<working_precision> precision;  // each row of an MPFR run holds its own
  if constexpr (!std::is_same_v<Real, double>) precision.emplace(digits + guard_digits);
  std::vector<std::string_view> fields(columns.size());
  case_fields(file, row, fields);
  std::vector<Real> masses, lengths;
  const Chain<Real> chain = case_chain<Real>(fields, columns, file.particles, masses, lengths);
  const MicrocanonicalAverages<Real> r = microcanonical_at(
      chain, file.state, microcanonical_state(chain, file.state, fields[0], columns[0], micro),
      micro);
  const MicrocanonicalText v = microcanonical_text(r, digits);
  std::vector<std::string> out(fields.begin(), fields.end());
  const auto add = [&](const std::vector<std::string>& values) {
    out.insert(out.end(), values.begin(), values.end());
  };
  add(v.kinetic);
  add(v.kinetic_error);
  out.push_back(v.kinetic_canonical);
  add(v.cos_angle);
  out.push_back(v.method);
  out.push_back(std::to_string(v.evaluations));
  out.push_back(v.kinetic_canonical_error);
  add(v.cos_angle_error);
  add(v.variance);
  add(v.variance_error);
  out.push_back(v.error_kind);
  out.push_back(v.converged ? "true" : "false");
  out.push_back(file.state == "energy" ? v.excitation : v.energy);
  out.insert(out.end(), {v.kinetic_total, v.kinetic_total_error, v.density_of_states,
                         v.density_of_states_error, v.work_unit});
  std::vector<std::string> selected(fields.begin(), fields.end());  // the input, then --columns'
  for (const std::size_t k : chosen) selected.push_back(std::move(out[fields.size() + k]));
  append_csv_line(line, selected);
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
  std::string variance_text;  ///< a row's Var K_i and errors, "value,error" per particle
  std::vector<std::size_t> variance_at;  ///< where each starts, its comma, then the end
};

/// Longest output line of a cases row: the row's text and a comma per field (at most one per
/// character), 8N + 3 numbers and their commas, the method, the count, four error kinds and
/// the work unit (<= 24 each, with their commas), "false" and a newline.
std::size_t case_line_bound(const CaseRow& row, std::size_t particles, int digits) {
  return 2 * row.size + 1 + (8 * particles + 3) * (decimal_max_length(digits) + 1) + 7 * 25 + 8;
}

/// One output row of `average --cases`: the input fields as written, then the averages.
/// `columns` are the canonical column names (beta, g, m1..mN, l1..lN). The line is written at
/// `p` (room for case_line_bound characters); returns its end.
template <class Real>
char* write_case(char* p, const CasesFile& file, const CaseRow& row,
                 const std::vector<std::string>& columns, std::span<const CaseColumn> output,
                 const AverageOptions& options, CaseScratch<Real>& scratch,
                 std::span<const double> checked = {}) {
  std::optional<working_precision> precision;  // each row of an MPFR run holds its own
  if constexpr (!std::is_same_v<Real, double>) precision.emplace(options.digits + guard_digits);
  auto& fields = scratch.fields;
  fields.resize(columns.size());
  case_fields(file, row, fields);
  const std::size_t n = file.particles;
  const int digits = options.digits;
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
  const Chain<Real>& chain = *parsed;
  const Averages<Real> averages = average(chain, beta, options, scratch.workspace);
  const auto put = [&p](std::string_view text) {
    std::memcpy(p, text.data(), text.size());
    p += text.size();
  };
  for (const std::string_view field : fields) {
    put(field);
    *p++ = ',';
  }
  // An observable of particle i (an engine that left it out leaves the field empty).
  const auto value = [&](const std::vector<Estimate<Real>>& estimates, std::size_t i) {
    if (i < estimates.size()) p = write_decimal(p, estimates[i].value, digits);
  };
  const bool upward = upward_errors(averages);
  const auto error = [&](const std::vector<Estimate<Real>>& estimates, std::size_t i) {
    if (i < estimates.size())
      p = write_decimal(p, printed_error(estimates[i].value, estimates[i].error, digits, upward),
                        error_digits);
  };
  const auto kind_of = [&](const std::vector<Estimate<Real>>& estimates) {
    return error_kind_name(estimates.empty() ? averages.error_kind : estimates.front().kind);
  };
  // Var K_i = beta^2 Var K_i / beta^2 and its error, printed as averages_text prints them
  // (write_quotient), so that these columns equal table's and `average`'s: formed once a row,
  // at the first of its columns, as "value,error" for each particle.
  std::string& variance_text = scratch.variance_text;
  std::vector<std::size_t>& variance_at = scratch.variance_at;  // start, comma of particle i
  variance_at.clear();
  const auto variance = [&](std::size_t i, bool of_error) {
    if (variance_at.empty()) {
      const quotient_t<Real> beta2 = quotient_t<Real>(beta) * quotient_t<Real>(beta);
      variance_text.resize(n * 2 * (decimal_max_length(digits) + 1));
      char* v = variance_text.data();
      for (const Estimate<Real>& e : averages.beta2_kinetic_variance) {
        char* const first = v;
        v = write_quotient(v, e.value, e.error, beta2, digits, ',', upward);
        variance_at.push_back(static_cast<std::size_t>(first - variance_text.data()));
        variance_at.push_back(
            static_cast<std::size_t>(std::find(first, v, ',') - variance_text.data()));
      }
      variance_at.push_back(static_cast<std::size_t>(v - variance_text.data()));
    }
    if (2 * i + 2 >= variance_at.size()) return;
    const std::size_t begin = of_error ? variance_at[2 * i + 1] + 1 : variance_at[2 * i];
    const std::size_t end = of_error ? variance_at[2 * i + 2] : variance_at[2 * i + 1];
    put(std::string_view(variance_text.data() + begin, end - begin));
  };
  for (const CaseColumn& column : output) {
    const std::size_t i = column.particle;
    switch (column.field) {
      case CaseField::beta_kinetic: value(averages.beta_kinetic, i); break;
      case CaseField::beta_kinetic_error: error(averages.beta_kinetic, i); break;
      case CaseField::ratio:
        if (averages.ratio) p = write_decimal(p, averages.ratio->value, digits);
        break;
      case CaseField::cos_angle: value(averages.cos_angle, i); break;
      case CaseField::method: put(method_name(averages.method)); break;
      case CaseField::evaluations: p = std::to_chars(p, p + 24, averages.evaluations).ptr; break;
      case CaseField::ratio_error:
        if (averages.ratio)
          p = write_decimal(
              p, printed_error(averages.ratio->value, averages.ratio->error, digits, upward),
              error_digits);
        break;
      case CaseField::cos_angle_error: error(averages.cos_angle, i); break;
      case CaseField::variance: variance(i, false); break;
      case CaseField::variance_error: variance(i, true); break;
      case CaseField::error_kind: put(error_kind_name(averages.error_kind)); break;
      case CaseField::converged: put(averages.converged ? "true" : "false"); break;
      case CaseField::cos_angle_error_kind: put(kind_of(averages.cos_angle)); break;
      case CaseField::variance_error_kind: put(kind_of(averages.beta2_kinetic_variance)); break;
      case CaseField::work_unit: put(work_unit_name(averages.work_unit)); break;
      case CaseField::equipartition_residual:
        p = write_decimal(p, averages.equipartition_residual, error_digits);
        break;
      case CaseField::kinetic_canonical: value(averages.beta_kinetic_canonical, i); break;
      case CaseField::kinetic_canonical_error: error(averages.beta_kinetic_canonical, i); break;
      case CaseField::kinetic_canonical_error_kind:
        put(kind_of(averages.beta_kinetic_canonical));
        break;
    }
    *p++ = ',';
  }
  p[-1] = '\n';
  return p;
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
  std::string header;
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
              " (UTC) from " + path + "\n";
  }
  append_csv_line(header, columns);
  header.pop_back();
  for (const std::string& name : output_names) (header += ',') += name;
  header += '\n';
  return header;
}

/// Step 3: rank 0 checks the outputs and reads a resumed file into `resumed`; every rank learns
/// the verdict (a usage_error on every rank when the outputs cannot be written or the file does
/// not match).
void open_cases_outputs(const CasesFile& file, const std::vector<CaseRow>& rows,
                        const std::vector<std::string>& columns,
                        const std::string& header, const CasesOutput& where,
                        std::optional<ResumedRows>& resumed,
                        std::optional<AtomicFile>& timing_file, std::optional<SweepFile>& output) {
  std::string verdict;
  if (is_root()) {
    try {
      if (!where.path.empty()) probe_output(where.path, "average");
      if (!where.timing_rows.empty()) {
        // Opened, and its column line written, now: a target that cannot take it (a full disk,
        // /dev/full) fails the run before any row went to stdout.
        timing_file.emplace(where.timing_rows, "average");
        timing_file->append("row,line,us\n");
      }
      if (!where.resume.empty()) {  // the file, or a killed run's temporary, or nothing yet
        std::vector<std::string_view> fields(columns.size());
        resumed.emplace(where.resume, "average", header, rows.size(), columns.size(),
                        [&](std::size_t k) {
                          case_fields(file, rows[k], fields);
                          std::string key;
                          for (const std::string_view field : fields)
                            (key += key.empty() ? "" : ",") += field;
                          return key;
                        });
      }
      // Opened here, so that every rank learns it failed (a FIFO nobody reads, say).
      output.emplace(where.path, "average", header, resumed ? &*resumed : nullptr);
    } catch (const invalid_input& bad) {
      verdict = bad.what();
    }
  }
  verdict = broadcast_from_root(verdict);
  if (!verdict.empty()) throw usage_error(verdict);
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
  const std::vector<std::string> all_names =
      plan.microcanonical ? microcanonical_case_columns(n, file.state)
                          : canonical_case_column_names(n);
  std::vector<std::size_t> chosen;
  if (where.columns) {
    chosen = select_case_columns(*where.columns, all_names, columns, n);
  } else {
    chosen.resize(all_names.size());
    for (std::size_t k = 0; k < chosen.size(); ++k) chosen[k] = k;
  }
  std::vector<std::string> output_names;
  for (const std::size_t k : chosen) output_names.push_back(all_names[k]);
  std::vector<CaseColumn> printed;
  if (!plan.microcanonical) {
    const std::vector<CaseColumn> all = canonical_case_columns(n);
    for (const std::size_t k : chosen) printed.push_back(all[k]);
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

  const std::string header =
      (where.shard ? where.shard->header_line() : "") +
      cases_header(file, path, settings, columns, output_names, !where.path.empty());
  std::optional<ResumedRows> resumed;
  std::optional<AtomicFile> timing_file;  // --timing-rows, on rank 0
  std::string timing_text;                // its lines not yet written
  std::optional<SweepFile> output;
  open_cases_outputs(file, rows, columns, header, where, resumed, timing_file, output);

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
    sweep.row_bytes = std::max(sweep.row_bytes, case_line_bound(row, n, digits) +
                                                     decimal_max_length(digits) + 1);
  sweep.compute = [&](std::size_t k, int thread, std::string& text) {
    if (plan.microcanonical) {
      microcanonical_case<Real>(text, file, rows[k], columns, chosen, plan.micro, digits);
      return;
    }
    const std::size_t start = text.size();
    text.resize(start + case_line_bound(rows[k], n, digits));
    char* end = write_case<Real>(text.data() + start, file, rows[k], columns, printed,
                                 plan.options, scratch_of(thread),
                                 checked ? checked->row_if_stored(k) : std::span<const double>{});
    text.resize(static_cast<std::size_t>(end - text.data()));
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
      output->append("# interrupted: " + std::to_string(outcome.written) + " of " +
                     std::to_string(rows.size()) +
                     " rows computed; the rows of the others are left out\n");
      std::fprintf(stderr, "[average] interrupted: %zu of %zu rows written\n", outcome.written,
                   rows.size());
    }
    output->commit();
    if (timing_file) {
      add_timing_rows(timing_text, 0, {}, rows, *timing_file, true);
      timing_file->commit();
    }
    if (where.timing) report_case_timing(row_us, file, timer_us, outcome.threads);
    if (outcome.failed_rows > 0)
      throw rows_failed(failed_rows_message("average", outcome, "rows", where.path,
                                            line_context(outcome.first_failed_row)));
  });
  return {};
}

std::string average_command(const Options& options) {
  const AverageOptions settings = average_settings(options);
  if (!options.has("cases")) {
    for (const std::string_view cases_only :
         {"timing", "timing-rows", "output", "resume", "columns"})
      if (options.has(cases_only))
        throw usage_error("average: --" + std::string(cases_only) + " is for --cases only");
    constexpr std::array<std::string_view, 3> formats{"json", "csv", "text"};
    const Format format = format_option(options, "json", formats);
    const std::string_view state = state_option(options);
    if (state != "beta" && settings.certified)
      throw usage_error("average: --certified is for canonical averages (--beta), not --" +
                        std::string(state));
    if (state != "beta")
      return with_number_type(settings.digits, [&]<class Real>() {
        return microcanonical_one<Real>(options, settings, state, format);
      });
    return with_number_type(settings.digits, [&]<class Real>() {
      return average_one<Real>(options, settings, format);
    });
  }
  for (const std::string_view single : {"masses", "lengths", "g", "beta", "energy", "excitation"})
    if (options.has(single))
      throw usage_error("average: --cases cannot be combined with --" + std::string(single));
  constexpr std::array<std::string_view, 1> formats{"csv"};
  format_option(options, "csv", formats);
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
  if (settings.digits == min_digits) return average_cases<double>(file, path, settings, where);
  return average_cases<mpfr_real>(file, path, settings, where);
}

// ---------------------------------------------------------------- limit

/// One limit as `limit` reports it: its values as text, its run and its wall time.
struct LimitReport {
  std::string_view name;  ///< high_temperature or low_temperature (the JSON key)
  std::string_view label; ///< "beta -> 0" or "beta -> inf" (text)
  AveragesText values;
  std::string run;  ///< the torus or transfer run as a JSON object, or "null"
  double seconds;
};

std::string limit_json(const LimitReport& r) {
  const AveragesText& limit = r.values;
  return JsonObject()
      .strings("beta_K", limit.beta_kinetic)
      .strings("error", limit.error)
      .raw("ratio", json_nullable(limit.ratio))
      .strings("var_K_beta2", limit.beta2_variance)
      .string("method", limit.method)
      .string("error_kind", limit.error_kind)
      .raw("ratio_error", json_nullable(limit.ratio_error))
      .strings("cos_phi", limit.cos_angle)
      .strings("cos_phi_error", limit.cos_angle_error)
      .strings("var_K_beta2_error", limit.beta2_variance_error)
      .raw("error_kinds", JsonObject()
                              .string("beta_K", limit.error_kind)
                              .string("ratio", limit.error_kind)
                              .string("cos_phi", limit.cos_angle_error_kind)
                              .string("var_K_beta2", limit.variance_error_kind)
                              .string("beta_Kc", limit.beta_kinetic_canonical_error_kind)
                              .str())
      .integer("evaluations", static_cast<long long>(limit.evaluations))
      .string("work_unit", limit.work_unit)
      // as `average` prints them (the wall time of both limits is the top level's seconds)
      .boolean("converged", limit.converged)
      .raw("run", r.run)
      .string("equipartition_residual", limit.equipartition_residual)
      .strings("beta_Kc", limit.beta_kinetic_canonical)
      .strings("beta_Kc_error", limit.beta_kinetic_canonical_error)
      .str();
}

/// `limit --format csv`: a row per limit with `average --format csv`'s columns (beta, <K_i>
/// and Var K_i empty: a limit has no finite beta), then limit (its JSON key), beta^2 Var K_i
/// with its errors, and the errors of beta<K_i^(c)> with their kind.
std::string limit_csv(std::size_t particles, int digits, const std::vector<LimitReport>& limits) {
  std::string out;
  for (const LimitReport& limit : limits) {
    const AveragesText& v = limit.values;
    CsvLine line = average_csv_line(AverageReport{particles, "", digits, v, limit.run,
                                                  limit.seconds});
    line.add("limit", std::string(limit.name));
    line.add_array("beta2_var_K", v.beta2_variance, particles);
    line.add_array("beta2_var_K_error", v.beta2_variance_error, particles);
    line.add_array("beta_Kc_error", v.beta_kinetic_canonical_error, particles);
    line.add("beta_Kc_error_kind", v.beta_kinetic_canonical_error_kind);
    if (out.empty()) append_csv_line(out, line.header);
    append_csv_line(out, line.row);
  }
  return out;
}

void add_limit_rows(std::vector<std::vector<std::string>>& table, std::string_view name,
                    const AveragesText& limit) {
  for (std::size_t i = 0; i < limit.beta_kinetic.size(); ++i)
    table.push_back({std::string(name), std::to_string(i + 1), limit.beta_kinetic[i],
                     limit.error[i], limit.beta2_variance[i], limit.beta2_variance_error[i],
                     i == 0 ? limit.ratio : "", limit.error_kind});
}

/// `limit --format text`: both limits in one table, then per limit what its errors promise,
/// the work done, the equipartition residual and beta<K_i^(c)>.
std::string limit_text(std::size_t particles, int digits, const std::vector<LimitReport>& limits) {
  std::vector<std::vector<std::string>> table{{"limit", "i", "beta<K_i>", "error",
                                               "beta^2 Var K_i", "error", "<K1>/<K2>",
                                               "error kind"}};
  for (const LimitReport& limit : limits) add_limit_rows(table, limit.label, limit.values);
  std::string out = "N = " + std::to_string(particles) + ", digits = " + std::to_string(digits) +
                    "\n" + aligned_table(table);
  for (const LimitReport& limit : limits) {
    const AveragesText& v = limit.values;
    const std::string prefix = std::string(limit.label) + ": ";
    const std::string lines = errors_and_work_text(v, limit.seconds, "beta^2 Var K_i");
    for (std::size_t begin = 0; begin < lines.size();) {
      const std::size_t end = lines.find('\n', begin) + 1;
      out += prefix + lines.substr(begin, end - begin);
      begin = end;
    }
    out += prefix + "|sum_i beta<K_i> - N/2| = " + v.equipartition_residual +
           ", beta<K_i^(c)> = " +
           (v.beta_kinetic_canonical.empty() ? "" : v.beta_kinetic_canonical.front()) + " (" +
           v.beta_kinetic_canonical_error_kind + ")\n";
  }
  return out;
}

template <class Real>
std::string limit_report(const Options& options, int digits, Format format) {
  const Chain<Real> chain = chain_option<Real>(options, false);
  input_checked("limit");
  AverageOptions settings;
  settings.digits = digits;
  settings.certified = options.has("certified");
  settings.threads = hardware_threads();
  Progress progress("limit");
  StopOnSignal signals;  // the beta -> 0 limit of N >= 3 is a torus run at g = 0
  const char* unit = chain.size() <= 5 ? "of a torus level " : "of a transfer level ";
  settings.control.progress = [&](double fraction) { progress(fraction, unit); };
  settings.control.stop = &stop_flag();
  const Stopwatch high_watch;
  const Averages<Real> high_values = high_temperature_limit(chain, settings);
  const double high_seconds = high_watch.seconds();
  if (high_values.interrupted)
    std::fprintf(stderr, "[limit] interrupted: the last finished level is reported\n");
  const Stopwatch low_watch;
  const Averages<Real> low_values = low_temperature_limit(chain, settings);
  const double low_seconds = low_watch.seconds();
  const Real* no_beta = nullptr;
  const std::vector<LimitReport> limits{
      {"high_temperature", "beta -> 0", averages_text(high_values, digits, no_beta),
       run_json(high_values), high_seconds},
      {"low_temperature", "beta -> inf", averages_text(low_values, digits, no_beta),
       run_json(low_values), low_seconds}};
  if (format == Format::text)
    return limit_text(chain.size(), digits, limits) +
           (high_values.interrupted
                ? "interrupted: the beta -> 0 limit's last finished level is reported\n"
                : "");
  if (format == Format::csv) return limit_csv(chain.size(), digits, limits);
  std::string json = JsonObject()
                         .integer("N", static_cast<long long>(chain.size()))
                         .integer("digits", digits)
                         .raw("high_temperature", limit_json(limits[0]))
                         .raw("low_temperature", limit_json(limits[1]))
                         .raw("seconds", seconds_text(high_seconds + low_seconds))
                         .str();
  if (high_values.interrupted) json.insert(json.rfind('}'), ", \"interrupted\": true");
  return json + "\n";
}

std::string limit_command(const Options& options) {
  const int digits = parse_digits(options.get("digits", "16"));
  constexpr std::array<std::string_view, 3> formats{"json", "csv", "text"};
  const Format format = format_option(options, "json", formats);
  return with_number_type(
      digits, [&]<class Real>() { return limit_report<Real>(options, digits, format); });
}

// ---------------------------------------------------------------- series

const std::vector<std::string> series_columns{"n",           "R_n",   "term", "numerator",
                                              "denominator", "value", "bound"};

std::vector<std::string> series_fields(const SeriesRow<mpfr_real>& row, int digits) {
  return {std::to_string(row.n),           decimal(row.R_n, digits),
          decimal(row.term, digits),       decimal(row.numerator, digits),
          decimal(row.denominator, digits), decimal(row.beta_kinetic1, digits),
          decimal(row.bound, digits)};
}

/// True when the last row's bound is at most 10^-digits relative to its value.
bool certifies(const std::vector<SeriesRow<mpfr_real>>& rows, int digits) {
  if (rows.empty()) return false;
  const SeriesRow<mpfr_real>& last = rows.back();
  return last.bound <= abs(last.beta_kinetic1) * pow(mpfr_real(10), -digits);
}

std::string series_command(const Options& options) {
  const int digits = parse_digits(options.get("digits", "16"));
  constexpr std::array<std::string_view, 3> formats{"json", "csv", "text"};
  const Format format = format_option(options, "text", formats);
  const auto terms = static_cast<std::size_t>(
      parse_integer(options.get("terms", "0"), "--terms", 0, static_cast<long>(max_series_terms)));
  const working_precision guard(digits + guard_digits);
  const std::string_view beta_text = options.required("beta");
  const Chain<mpfr_real> chain = chain_option<mpfr_real>(options, true);
  const mpfr_real beta = parse_real<mpfr_real>(beta_text, "--beta", Domain::positive);
  input_checked("series");
  Progress progress("series");
  StopOnSignal signals;
  RunControl control;
  control.progress = [&](double fraction) { progress(fraction, "Bessel table "); };
  control.stop = &stop_flag();
  const auto rows = series_convergence(chain, beta, digits, terms, control);
  const bool certified = certifies(rows, digits);

  if (format == Format::json) {
    std::string json_rows;
    for (const auto& row : rows) {
      const auto fields = series_fields(row, digits);
      JsonObject object;
      object.integer("n", static_cast<long long>(row.n));
      for (std::size_t i = 1; i < fields.size(); ++i) object.string(series_columns[i], fields[i]);
      json_rows += (json_rows.empty() ? "" : ", ") + object.str();
    }
    return JsonObject()
               .integer("N", static_cast<long long>(chain.size()))
               .string("beta", beta_text)
               .integer("digits", digits)
               .integer("terms", static_cast<long long>(rows.size()))
               .boolean("certified", certified)
               .raw("rows", "[" + json_rows + "]")
               .string("error_kind", error_kind_name(ErrorKind::bound))  // each row's bound
               .str() +
           "\n";
  }
  if (format == Format::csv) {
    std::string out;
    append_csv_line(out, series_columns);
    for (const auto& row : rows) append_csv_line(out, series_fields(row, digits));
    return out;
  }
  std::vector<std::vector<std::string>> table{series_columns};
  for (const auto& row : rows) table.push_back(series_fields(row, std::min(digits, 20)));
  const std::string bound = rows.empty() ? "none" : decimal(rows.back().bound, error_digits);
  return aligned_table(table) + std::to_string(rows.size()) + " terms, bound " + bound +
         (certified ? " certifies " : " does not certify ") + std::to_string(digits) +
         " digits\n";
}

// ---------------------------------------------------------------- dispatch

struct Command {
  std::string_view name;
  std::string_view usage;
  std::span<const std::string_view> options;
  std::string (*run)(const Options&);
  std::span<const std::string_view> flags = {};  ///< options without a value
  bool distributed = false;  ///< runs on every MPI rank; the others run on rank 0 alone
  bool operands = false;     ///< takes file names besides its options
};

constexpr std::array<std::string_view, 19> average_options{
    "masses", "lengths", "g",      "beta",   "digits",      "method", "format",
    "cases",  "tol",     "samples", "shifts", "seed",       "timing-rows", "output",
    "resume", "energy",  "excitation", "columns", "shard"};
constexpr std::array<std::string_view, 1> merge_options{"output"};
constexpr std::array<std::string_view, 2> average_flags{"timing", "certified"};
constexpr std::array<std::string_view, 1> limit_flags{"certified"};
constexpr std::array<std::string_view, 5> limit_options{"masses", "lengths", "g", "digits",
                                                        "format"};
constexpr std::array<std::string_view, 7> series_options{"masses", "lengths", "g",     "beta",
                                                         "digits", "terms",   "format"};

const std::array<Command, 7> commands{{
    {"average", average_usage, average_options, average_command, average_flags, true},
    {"limit", limit_usage, limit_options, limit_command, limit_flags},
    {"series", series_usage, series_options, series_command},
    {"table", table_usage, table_options, table_command, {}, true},
    {"simulate", simulate_usage, simulate_options, simulate_command, {}, true},
    {"poincare", poincare_usage, poincare_options, poincare_command},
    {"merge", merge_usage, merge_options, merge_command, {}, false, true},
}};

const Command& find_command(std::string_view name) {
  const auto found = std::ranges::find(commands, name, &Command::name);
  if (found == commands.end())
    throw usage_error("unknown command '" + std::string(name) + "' (try 'pendavg --help')");
  return *found;
}

std::function<void(std::string_view)>& input_checked_hook() {
  static std::function<void(std::string_view)> hook;
  return hook;
}

}  // namespace

void input_checked(std::string_view command) {
  if (input_checked_hook()) input_checked_hook()(command);
}

void set_input_checked_hook(std::function<void(std::string_view command)> hook) {
  input_checked_hook() = std::move(hook);
}

std::string run(std::span<const std::string_view> args) {
  if (args.empty()) throw usage_error("no command given (try 'pendavg --help')");
  const std::string_view name = args.front();
  const auto rest = args.subspan(1);
  if (name == "--help" || name == "-h" || (name == "help" && rest.empty()))
    return std::string(general_usage);
  if (name == "help") return std::string(find_command(rest.front()).usage);
  if (name == "--version") return version_text();
  const Command& command = find_command(name);
  if (asks_for_help(rest)) return std::string(command.usage);
  set_digits_advice(std::ranges::find(command.options, "digits") != command.options.end());
  const Options options(name, rest, command.options, command.flags, command.operands);
  if (!command.distributed && !is_root()) return {};
  return command.run(options);
}

}  // namespace pendavg::cli
