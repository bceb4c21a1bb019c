// src/cli/commands.cpp -- the pendavg commands: options -> Chain<Real> and beta -> library call ->
// formatted string. `digits` == 16 runs in double, more digits in MPFR under a working_precision
// guard that is installed before any number is parsed.
#include "commands.hpp"

#include "args.hpp"
#include "files.hpp"
#include "format.hpp"
#include "qmc_options.hpp"
#include "simulate.hpp"
#include "table.hpp"

#include "pendavg/double_pendulum.hpp"
#include "pendavg/torus.hpp"
#include "pendavg/trace_formula.hpp"

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
#include <utility>
#include <vector>

#if defined(_OPENMP)
#include <omp.h>
#endif

#ifndef PENDAVG_VERSION
#define PENDAVG_VERSION "unknown"
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
    "  pendavg average --cases FILE.csv [--digits D] [--method M] [method options] [--timing]\n"
    "  pendavg limit   --masses M1,M2 [--lengths L1,L2] [--g G] [--digits D] [--format F]\n"
    "  pendavg series  --masses M1,M2 --lengths L1,L2 [--g G] --beta B [--terms N] [options]\n"
    "  pendavg table   --beta SPEC [--mu1 SPEC] [--l2 SPEC] [--g SPEC] ... [--chain LIST] [--digits LIST] [--output FILE.csv]\n"
    "  pendavg simulate --masses ... --lengths ... (--theta A | --phi ...) --time T [options]\n"
    "  pendavg poincare --masses M1,M2 --lengths L1,L2 --energy E [--orbits K] [--points P]\n"
    "  pendavg help [COMMAND]     pendavg COMMAND --help     pendavg --version\n"
    "\n"
    "Numbers are plain decimals (0.5, 1e-3). --digits D (16..1000, default 16) is the number of\n"
    "significant digits requested: 16 runs in double, more in MPFR. Bad input exits with 2.\n";

constexpr std::string_view average_usage =
    "usage: pendavg average --masses M1,...,MN --lengths L1,...,LN [--g G] --beta B [--digits D]\n"
    "                       [--method M] [--tol T] [--samples S] [--shifts R] [--seed K]\n"
    "                       [--format json|csv|text]\n"
    "       pendavg average --cases FILE.csv [--digits D] [--method M] [method options]\n"
    "                       [--timing] [--timing-rows FILE]\n"
    "\n"
    "Thermal averages of an N-link pendulum (N = the number of masses = the number of lengths)\n"
    "at inverse temperature B, gravity G (default 1). --method M (default auto):\n"
    "  auto             N = 2: the double-pendulum engine; N = 1 or 3..4: torus-trapezoid;\n"
    "                   N >= 5: qmc\n"
    "  series, integral the double-pendulum engines (N = 2 only)\n"
    "  torus-trapezoid  exact quadrature on the reduced (N-1)-torus, any N (cost n^(N-1)), also\n"
    "                   in MPFR; --tol T: relative tolerance in double (default 1e-13; with\n"
    "                   --digits D > 16 it is 1e-D)\n"
    "  torus-gauss      the same with Gauss-Legendre nodes (a check)\n"
    "  qmc              randomized lattice QMC, double only, N <= 256, 3-sigma statistical error\n"
    "                   bars; --samples S points per shift (a power of two, 1024..1048576,\n"
    "                   default 65536), --shifts R (4..1024, default 16), --seed K (default 1)\n"
    "Options of a method that is not run are rejected.\n"
    "Output (default json): N, beta, digits, method, beta_K, K, error, ratio (<K1>/<K2>, null\n"
    "for N = 1), cos_phi, var_K, evaluations, seconds, converged, diagonal_approx (the paper's\n"
    "eq. ke-linear-tave-1) and beta_Kc (beta<K_i^(c)> = 1/2).\n"
    "--cases reads a CSV with the columns beta,g,m1..mN,l1..lN (any order, N from the header;\n"
    "blank lines and lines starting with # are skipped) and writes one CSV row per case: the\n"
    "input columns in that order, then beta_K1..N, error_K1..N, ratio, cos_phi1..N, method,\n"
    "evaluations. Rows run on all cores; the output does not depend on the thread count.\n"
    "--timing (with --cases) also prints one line on stderr: rows, the median, 90th percentile\n"
    "and worst thread CPU time per row in microseconds (from parsing the row to its formatted\n"
    "output line; the timer's own cost, timer_us, is measured and subtracted), the worst row\n"
    "(0-based data row and file line) and the thread count:\n"
    "  pendavg: timing: rows=R median_us=X p90_us=Y worst_us=Z worst_row=I worst_line=L\n"
    "  threads=T timer_us=U (...)\n"
    "--timing-rows FILE (with --cases) also writes every row's time as CSV row,line,us.\n";

constexpr std::string_view limit_usage =
    "usage: pendavg limit --masses M1,...,MN [--lengths L1,...,LN] [--g G] [--digits D]\n"
    "                     [--format json|text]\n"
    "\n"
    "The high-temperature (beta -> 0) and low-temperature (beta -> infinity) limits of\n"
    "beta<K_i>, their error estimates, <K1>/<K2> and beta^2 Var K_i. Lengths default to 1.\n"
    "N = 2: the paper's elliptic K/E formula. Any N: beta -> 0 is the torus average of the chain\n"
    "at g = 0 (tensor trapezoid for N <= 5, qmc with 3-sigma bars beyond, double only);\n"
    "beta -> infinity is exact: beta<K_i> = 1/2, beta^2 Var K_i = tr(X_i(0)^2)/2.\n";

constexpr std::string_view series_usage =
    "usage: pendavg series --masses M1,M2 --lengths L1,L2 [--g G] --beta B [--digits D]\n"
    "                      [--terms N] [--format text|csv|json]\n"
    "\n"
    "The paper's series for beta<K1>, term by term, in MPFR: n, R_n, term, numerator,\n"
    "denominator, value (partial beta<K1>) and the rigorous truncation bound. --terms 0\n"
    "(default) sums until the bound certifies the requested digits.\n";

// ---------------------------------------------------------------- shared helpers

/// Runs `body.operator()<Real>()` with Real = double for 16 digits and Real = mpfr_real (under a
/// working_precision guard held for the whole call, parsing included) for more.
template <class Body>
std::string with_number_type(int digits, Body&& body) {
  if (digits == min_digits) return body.template operator()<double>();
  const working_precision guard(digits + guard_digits);
  return body.template operator()<mpfr_real>();
}

int digits_option(const Options& options) { return parse_digits(options.get("digits", "16")); }

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

/// Appends each value and a trailing comma.
template <class Real>
void append_csv_values(std::string& out, const std::vector<Real>& values, int digits) {
  for (const Real& value : values) {
    append_decimal(out, value, digits);
    out += ',';
  }
}

// ---------------------------------------------------------------- average: methods and options

enum class AverageMethod { automatic, series, integral, torus_trapezoid, torus_gauss, qmc };
constexpr std::array<std::string_view, 6> average_method_names{
    "auto", "series", "integral", "torus-trapezoid", "torus-gauss", "qmc"};

/// --method auto runs the torus trapezoid up to this N (n^(N-1) nodes: milliseconds for N <= 4,
/// seconds for N = 5 at the default tolerance) and qmc beyond.
constexpr std::size_t auto_torus_max_particles = 4;

/// --tol: the torus rules' relative tolerance in double.
constexpr double default_tolerance = 1e-13;

/// What runs: the double-pendulum engine (N = 2), a torus rule or QMC.
enum class Solver { pendulum, torus, qmc };

/// The options of `average` that do not depend on N, parsed and range-checked.
struct AverageSettings {
  AverageMethod method = AverageMethod::automatic;
  int digits = min_digits;
  std::optional<double> tolerance;            ///< --tol, when given
  std::vector<std::string> qmc_options;  ///< which of --samples, --shifts, --seed were given
  QmcOptions qmc;                             ///< points, shifts, seed
};

/// The settings resolved for N particles: which solver and its options.
struct AveragePlan {
  Solver solver = Solver::pendulum;
  Engine engine = Engine::automatic;  ///< for Solver::pendulum
  TorusOptions torus;
  QmcOptions qmc;
};

int hardware_threads() {
#if defined(_OPENMP)
  return omp_get_max_threads();
#else
  return 1;
#endif
}

AverageSettings average_settings(const Options& options) {
  AverageSettings s;
  s.digits = digits_option(options);
  s.method = static_cast<AverageMethod>(
      parse_choice(options.get("method", "auto"), "method", average_method_names));
  if (options.has("tol")) {
    const std::string_view text = options.required("tol");
    s.tolerance = parse_real<double>(text, "--tol", Domain::positive);
    if (!(*s.tolerance < 1)) throw usage_error("--tol: '" + std::string(text) + "' must be < 1");
  }
  s.qmc_options = parse_qmc_options(options, s.qmc);
  return s;
}

/// Resolves --method for N particles and rejects options the chosen solver does not use.
/// `threads`: OpenMP threads for the torus and QMC engines (double only).
AveragePlan average_plan(const AverageSettings& s, std::size_t n, int threads) {
  AveragePlan plan;
  const std::string particles = "N = " + std::to_string(n);
  const std::string name(average_method_names[static_cast<std::size_t>(s.method)]);
  std::string chosen = "--method " + name;  // names the solver in error messages
  switch (s.method) {
    case AverageMethod::automatic:
      plan.solver = n == 2                           ? Solver::pendulum
                    : n <= auto_torus_max_particles ? Solver::torus
                                                     : Solver::qmc;
      chosen += std::string(", which runs ") +
                (plan.solver == Solver::pendulum ? "the double-pendulum engine"
                 : plan.solver == Solver::torus  ? "torus-trapezoid"
                                                 : "qmc") +
                " for " + particles;
      break;
    case AverageMethod::series:
    case AverageMethod::integral:
      if (n != 2)
        throw usage_error("average: --method " + name + " is a double-pendulum engine (N = 2), "
                          "not for " + particles + " (use auto, torus-trapezoid, torus-gauss "
                          "or qmc)");
      plan.solver = Solver::pendulum;
      plan.engine = s.method == AverageMethod::series ? Engine::series : Engine::integral;
      break;
    case AverageMethod::torus_trapezoid:
    case AverageMethod::torus_gauss:
      plan.solver = Solver::torus;
      plan.torus.rule = s.method == AverageMethod::torus_gauss ? TorusRule::gauss_legendre
                                                               : TorusRule::trapezoid;
      break;
    case AverageMethod::qmc: plan.solver = Solver::qmc; break;
  }

  if (s.tolerance && plan.solver != Solver::torus)
    throw usage_error("average: --tol is used by the torus methods only, not by " + chosen);
  for (const std::string& option : s.qmc_options)
    if (plan.solver != Solver::qmc)
      throw usage_error("average: --" + std::string(option) + " is used by qmc only, not by " +
                        chosen);
  if (plan.solver == Solver::torus) {
    if (s.tolerance && s.digits != min_digits)
      throw usage_error("average: --tol is for double runs (--digits 16); with --digits " +
                        std::to_string(s.digits) + " the torus tolerance is 1e-" +
                        std::to_string(s.digits));
    const double nodes = std::pow(static_cast<double>(plan.torus.min_points_per_dim),
                                  static_cast<double>(n - 1));
    if (nodes > plan.torus.max_grid_points)
      throw usage_error("average: " + particles + " is too long for a torus grid (" +
                        std::to_string(plan.torus.min_points_per_dim) + "^" +
                        std::to_string(n - 1) + " = " + decimal(nodes, 2) +
                        " nodes at the first level, over the cap of " +
                        decimal(plan.torus.max_grid_points, 1) + "); use --method qmc");
    plan.torus.tolerance = s.tolerance.value_or(default_tolerance);
    plan.torus.digits = s.digits == min_digits ? 0 : s.digits;
    plan.torus.threads = threads;
  }
  if (plan.solver == Solver::qmc) {
    if (s.digits != min_digits)
      throw usage_error("average: --digits " + std::to_string(s.digits) +
                        " is not available with " + chosen + " (qmc runs in double only)");
    if (n > detail::qmc::lattice_max_dimension)
      throw usage_error("average: qmc's built-in lattices cover N <= " +
                        std::to_string(detail::qmc::lattice_max_dimension) + ", not " +
                        particles + " (" + chosen + ")");
    plan.qmc = s.qmc;
    plan.qmc.threads = threads;
  }
  return plan;
}

/// The averages of one case and the any-N extras every solver reports.
template <class Real>
struct AverageResult {
  Averages<Real> averages;
  std::vector<Real> diagonal_approximation;  ///< eq. ke-linear-tave-1
  std::vector<Real> beta_kinetic_canonical;  ///< beta<K_i^(c)> = 1/2
};

template <class Real>
AverageResult<Real> compute_average(const Chain<Real>& chain, const Real& beta, int digits,
                                    const AveragePlan& plan) {
  switch (plan.solver) {
    case Solver::torus: {
      TorusAverages<Real> r = torus_average_full(chain, beta, plan.torus);
      return {std::move(r.averages), std::move(r.diagonal_approximation),
              std::move(r.beta_kinetic_canonical)};
    }
    case Solver::qmc: {
      QmcAverages<Real> r = qmc_average(chain, beta, plan.qmc);
      return {std::move(r.averages), std::move(r.diagonal_approximation),
              std::move(r.beta_kinetic_canonical)};
    }
    case Solver::pendulum: break;
  }
  // The double-pendulum engines: beta<K_i^(c)> = 1/2 holds exactly for every chain.
  return {pendavg::average(chain, beta, digits, plan.engine), diagonal_approximation(chain),
          std::vector<Real>(chain.size(), Real(1) / 2)};
}

// ---------------------------------------------------------------- average: output

struct AverageReport {
  std::size_t particles;
  std::string_view beta;
  int digits;
  AveragesText values;
  std::vector<std::string> diagonal_approx, beta_kinetic_canonical;
  double seconds;
};

std::string average_json(const AverageReport& r) {
  JsonObject json;
  json.integer("N", static_cast<long long>(r.particles))
      .string("beta", r.beta)
      .integer("digits", r.digits)
      .string("method", r.values.method)
      .strings("beta_K", r.values.beta_kinetic)
      .strings("K", r.values.kinetic)
      .strings("error", r.values.error);
  if (r.particles >= 2) {
    json.string("ratio", r.values.ratio);
  } else {
    json.raw("ratio", "null");  // <K1>/<K2> needs a second particle
  }
  return json.strings("cos_phi", r.values.cos_angle)
             .strings("var_K", r.values.variance)
             .integer("evaluations", static_cast<long long>(r.values.evaluations))
             .raw("seconds", seconds_text(r.seconds))
             .boolean("converged", r.values.converged)
             .strings("diagonal_approx", r.diagonal_approx)
             .strings("beta_Kc", r.beta_kinetic_canonical)
             .str() +
         "\n";
}

std::string average_csv(const AverageReport& r) {
  const std::size_t n = r.particles;
  std::vector<std::string> header{"N", "beta", "digits", "method"}, row{
      std::to_string(n), std::string(r.beta), std::to_string(r.digits), r.values.method};
  const auto add_array = [&](std::string_view stem, const std::vector<std::string>& values) {
    const auto names = indexed_names(stem, values.size());
    header.insert(header.end(), names.begin(), names.end());
    row.insert(row.end(), values.begin(), values.end());
  };
  const auto add = [&](std::string name, std::string value) {
    header.push_back(std::move(name));
    row.push_back(std::move(value));
  };
  add_array("beta_K", r.values.beta_kinetic);
  add_array("K", r.values.kinetic);
  add_array("error_K", r.values.error);
  add("ratio", n >= 2 ? r.values.ratio : "");
  add_array("cos_phi", r.values.cos_angle);
  add_array("var_K", r.values.variance);
  add("evaluations", std::to_string(r.values.evaluations));
  add("seconds", seconds_text(r.seconds));
  add("converged", r.values.converged ? "true" : "false");
  add_array("diagonal_approx", r.diagonal_approx);
  add_array("beta_Kc", r.beta_kinetic_canonical);
  std::string out;
  append_csv_line(out, header);
  append_csv_line(out, row);
  return out;
}

std::string average_text(const AverageReport& r) {
  std::vector<std::vector<std::string>> table{{"i", "beta<K_i>", "error", "<K_i>", "<cos phi_i>",
                                               "Var K_i", "diagonal approx", "beta<K_i^c>"}};
  for (std::size_t i = 0; i < r.values.beta_kinetic.size(); ++i)
    table.push_back({std::to_string(i + 1), r.values.beta_kinetic[i], r.values.error[i],
                     r.values.kinetic[i], r.values.cos_angle[i], r.values.variance[i],
                     r.diagonal_approx[i], r.beta_kinetic_canonical[i]});
  return "N = " + std::to_string(r.particles) + ", beta = " + std::string(r.beta) +
         ", digits = " + std::to_string(r.digits) + ", method = " + r.values.method + "\n" +
         aligned_table(table) +
         (r.particles >= 2 ? "<K1>/<K2> = " + r.values.ratio + "\n" : std::string()) +
         "evaluations = " + std::to_string(r.values.evaluations) +
         ", seconds = " + seconds_text(r.seconds) +
         ", converged = " + (r.values.converged ? "yes" : "no") + "\n";
}

template <class Real>
std::vector<std::string> decimals(const std::vector<Real>& values, int digits) {
  std::vector<std::string> out;
  out.reserve(values.size());
  for (const Real& value : values) out.push_back(decimal(value, digits));
  return out;
}

template <class Real>
std::string average_one(const Options& options, const AverageSettings& settings, Format format) {
  const std::string_view beta_text = options.required("beta");
  const Chain<Real> chain = chain_option<Real>(options, true);
  const AveragePlan plan = average_plan(settings, chain.size(), hardware_threads());
  const Real beta = parse_real<Real>(beta_text, "--beta", Domain::positive);
  const int digits = settings.digits;
  const Stopwatch stopwatch;
  const AverageResult<Real> result = compute_average(chain, beta, digits, plan);
  const double seconds = stopwatch.seconds();
  const AverageReport report{chain.size(),
                             beta_text,
                             digits,
                             averages_text(result.averages, digits, &beta),
                             decimals(result.diagonal_approximation, digits),
                             decimals(result.beta_kinetic_canonical, digits),
                             seconds};
  switch (format) {
    case Format::csv: return average_csv(report);
    case Format::text: return average_text(report);
    case Format::json: break;
  }
  return average_json(report);
}

/// Per-thread scratch of `average --cases`: reused from row to row.
struct CaseScratch {
  std::vector<std::string_view> fields;  ///< the row's fields in canonical order
};

/// Longest output line of a cases row: the row's text and a comma per field (at most one per
/// character), 3N + 1 numbers and their commas, the method (<= 24), the count and a newline.
std::size_t case_line_bound(const CaseRow& row, std::size_t particles, int digits) {
  return 2 * row.size + 1 + (3 * particles + 1) * (decimal_max_length(digits) + 1) + 24 + 24;
}

/// One output row of `average --cases`: the input fields as written, then the averages.
/// `columns` are the canonical column names (beta, g, m1..mN, l1..lN). The line is written at
/// `p` (room for case_line_bound characters); returns its end.
template <class Real>
char* write_case(char* p, const CasesFile& file, const CaseRow& row,
                 const std::vector<std::string>& columns, int digits, const AveragePlan& plan,
                 CaseScratch& scratch) {
  auto& fields = scratch.fields;
  fields.resize(columns.size());
  case_fields(file, row, fields);
  const std::size_t n = file.particles;
  const Real beta = parse_real<Real>(fields[0], columns[0], Domain::positive);
  std::vector<Real> masses, lengths;
  masses.reserve(n);
  lengths.reserve(n);
  for (std::size_t i = 0; i < n; ++i)
    masses.push_back(parse_real<Real>(fields[2 + i], columns[2 + i], Domain::positive));
  for (std::size_t i = 0; i < n; ++i)
    lengths.push_back(parse_real<Real>(fields[2 + n + i], columns[2 + n + i], Domain::positive));
  const Chain<Real> chain = make_chain<Real>(
      std::move(masses), std::move(lengths),
      parse_real<Real>(fields[1], columns[1], Domain::nonnegative));
  // The double-pendulum engines directly: the any-N extras (diagonal approximation,
  // beta<K_i^(c)>) are not printed here.
  const Averages<Real> averages = plan.solver == Solver::pendulum
                                      ? pendavg::average(chain, beta, digits, plan.engine)
                                      : compute_average(chain, beta, digits, plan).averages;
  const std::string_view method = method_name(averages.method);
  const auto put = [&p](std::string_view text) {
    std::memcpy(p, text.data(), text.size());
    p += text.size();
  };
  for (const std::string_view field : fields) {
    put(field);
    *p++ = ',';
  }
  for (const Real& value : averages.beta_kinetic) {
    p = write_decimal(p, value, digits);
    *p++ = ',';
  }
  for (std::size_t i = 0; i < averages.beta_kinetic.size(); ++i) {
    p = write_decimal(
        p, printed_error(averages.beta_kinetic[i], averages.beta_kinetic_error[i], digits),
        error_digits);
    *p++ = ',';
  }
  if (n >= 2) p = write_decimal(p, averages.ratio, digits);
  *p++ = ',';
  for (const Real& value : averages.cos_angle) {
    p = write_decimal(p, value, digits);
    *p++ = ',';
  }
  put(method);
  *p++ = ',';
  p = std::to_chars(p, p + 24, averages.evaluations).ptr;
  *p++ = '\n';
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

/// --timing: one line on stderr with the distribution of the rows' thread CPU times.
void report_case_timing(const std::vector<double>& row_us, const CasesFile& file,
                        double timer_us, int threads) {
  if (row_us.empty()) {
    std::fprintf(stderr, "pendavg: timing: rows=0\n");
    return;
  }
  std::vector<double> sorted = row_us;
  std::ranges::sort(sorted);
  const std::size_t count = sorted.size();
  const auto rank = [&](double p) {  // nearest rank
    const auto r = static_cast<std::size_t>(std::ceil(p * static_cast<double>(count)));
    return sorted[std::clamp<std::size_t>(r, 1, count) - 1];
  };
  const double median =
      count % 2 ? sorted[count / 2] : 0.5 * (sorted[count / 2 - 1] + sorted[count / 2]);
  const auto worst = static_cast<std::size_t>(std::ranges::max_element(row_us) - row_us.begin());
  std::fprintf(stderr,
               "pendavg: timing: rows=%zu median_us=%.3f p90_us=%.3f worst_us=%.3f "
               "worst_row=%zu worst_line=%zu threads=%d timer_us=%.3f (thread CPU time per row, "
               "parsing to formatted line, timer overhead subtracted)\n",
               count, median, rank(0.9), sorted.back(), worst, file.rows[worst].line, threads,
               timer_us);
}

/// Rows are independent: they are evaluated on all cores in blocks, each block into its own
/// stretch of the output, joined in file order (the output does not depend on the thread count). The first
/// bad row (in file order) is reported. Blocks hold 256 rows for the fast double-pendulum
/// engines and one row for the torus and QMC engines; a single block runs on one thread and
/// lets those engines use every core instead. `timing`: see report_case_timing.
template <class Real>
std::string average_cases(const CasesFile& file, const std::string& path,
                          const AverageSettings& settings, bool timing,
                          const std::string& timing_rows_path) {
  const std::vector<CaseRow>& rows = file.rows;
  const std::size_t n = file.particles;
  const std::vector<std::string> columns = case_columns(n);
  const int digits = settings.digits;
  AveragePlan plan = average_plan(settings, n, 1);
  const std::size_t block = plan.solver == Solver::pendulum ? 256 : 1;
  const std::size_t blocks = (rows.size() + block - 1) / block;
  if (blocks == 1) plan.torus.threads = plan.qmc.threads = hardware_threads();

  std::string out;
  append_csv_line(out, columns);
  out.pop_back();
  const auto add_names = [&](std::string_view stem) {
    for (const std::string& name : indexed_names(stem, n)) (out += ',') += name;
  };
  add_names("beta_K");
  add_names("error_K");
  out += ",ratio";
  add_names("cos_phi");
  out += ",method,evaluations\n";

  // One output buffer: each block writes into its own stretch (the sum of its rows' longest
  // lines), sized and zero-filled here, before any row runs; the blocks' texts are then moved
  // together in file order. No allocation while the rows run.
  std::vector<std::size_t> block_start(blocks + 1, out.size()), block_end(blocks);
  for (std::size_t b = 0; b < blocks; ++b) {
    std::size_t bytes = 0;
    for (std::size_t i = b * block; i < std::min(rows.size(), (b + 1) * block); ++i)
      bytes += case_line_bound(rows[i], n, digits);
    block_start[b + 1] = block_start[b] + bytes;
  }
  out.resize(block_start[blocks]);

  const double timer_us = timing ? timer_overhead_microseconds() : 0.0;
  std::vector<double> row_us(timing ? rows.size() : 0);
  std::vector<std::exception_ptr> errors(blocks);  // exceptions must not leave the region
  std::vector<std::size_t> error_row(blocks, rows.size());
  int threads = 1;
#pragma omp parallel if (blocks > 1)
  {
    CaseScratch scratch;
#if defined(_OPENMP)
#pragma omp single nowait
    threads = omp_get_num_threads();
#endif
#pragma omp for schedule(dynamic, 1)
    for (long b = 0; b < static_cast<long>(blocks); ++b) {
      const auto bu = static_cast<std::size_t>(b);
      const std::size_t first = bu * block;
      const std::size_t last = std::min(rows.size(), first + block);
      char* p = out.data() + block_start[bu];
      for (std::size_t i = first; i < last; ++i) {
        try {
          if (timing) {
            const double start = thread_cpu_microseconds();
            p = write_case<Real>(p, file, rows[i], columns, digits, plan, scratch);
            row_us[i] = thread_cpu_microseconds() - start - timer_us;
          } else {
            p = write_case<Real>(p, file, rows[i], columns, digits, plan, scratch);
          }
        } catch (...) {
          errors[bu] = std::current_exception();
          error_row[bu] = i;
          break;
        }
      }
      block_end[bu] = static_cast<std::size_t>(p - out.data());
    }
  }
  for (std::size_t b = 0; b < blocks; ++b) {
    if (error_row[b] < rows.size()) {
      try {
        std::rethrow_exception(errors[b]);
      } catch (const invalid_input& bad) {
        throw usage_error(path + " line " + std::to_string(rows[error_row[b]].line) + ": " +
                          bad.what());
      }
    }
  }
  std::size_t size = block_start[0];
  for (std::size_t b = 0; b < blocks; ++b) {
    const std::size_t length = block_end[b] - block_start[b];
    std::memmove(out.data() + size, out.data() + block_start[b], length);
    size += length;
  }
  out.resize(size);
  if (!timing_rows_path.empty()) {
    std::string rows_csv = "row,line,us\n";
    char number[32];
    for (std::size_t i = 0; i < rows.size(); ++i) {
      const int length = std::snprintf(number, sizeof number, "%.3f", row_us[i]);
      ((((rows_csv += std::to_string(i)) += ',') += std::to_string(rows[i].line)) += ',')
          .append(number, static_cast<std::size_t>(length)) += '\n';
    }
    write_atomically(timing_rows_path, rows_csv, "average");
  }
  if (timing) report_case_timing(row_us, file, timer_us, threads);
  return out;
}

std::string average_command(const Options& options) {
  const AverageSettings settings = average_settings(options);
  if (!options.has("cases")) {
    for (const std::string_view timing : {"timing", "timing-rows"})
      if (options.has(timing))
        throw usage_error("average: --" + std::string(timing) + " is for --cases only");
    constexpr std::array<std::string_view, 3> formats{"json", "csv", "text"};
    const Format format = format_option(options, "json", formats);
    return with_number_type(settings.digits, [&]<class Real>() {
      return average_one<Real>(options, settings, format);
    });
  }
  for (const std::string_view single : {"masses", "lengths", "g", "beta"})
    if (options.has(single))
      throw usage_error("average: --cases cannot be combined with --" + std::string(single));
  constexpr std::array<std::string_view, 1> formats{"csv"};
  format_option(options, "csv", formats);
  const std::string path(options.required("cases"));
  const std::string timing_rows(options.get("timing-rows", ""));
  if (options.has("timing-rows") && timing_rows.empty())
    throw usage_error("average: --timing-rows needs a file name");
  if (!timing_rows.empty()) probe_output(timing_rows, "average");
  const CasesFile file = read_cases_file(path);
  return with_number_type(settings.digits, [&]<class Real>() {
    return average_cases<Real>(file, path, settings,
                               options.has("timing") || !timing_rows.empty(), timing_rows);
  });
}

// ---------------------------------------------------------------- limit

std::string limit_json(const AveragesText& limit) {
  return JsonObject()
      .strings("beta_K", limit.beta_kinetic)
      .strings("error", limit.error)
      .string("ratio", limit.ratio)
      .strings("var_K_beta2", limit.beta2_variance)
      .str();
}

void add_limit_rows(std::vector<std::vector<std::string>>& table, std::string_view name,
                    const AveragesText& limit) {
  for (std::size_t i = 0; i < limit.beta_kinetic.size(); ++i)
    table.push_back({std::string(name), std::to_string(i + 1), limit.beta_kinetic[i],
                     limit.error[i], limit.beta2_variance[i], i == 0 ? limit.ratio : ""});
}

template <class Real>
std::string limit_report(const Options& options, int digits, Format format) {
  const Chain<Real> chain = chain_option<Real>(options, false);
  const std::size_t n = chain.size();
  constexpr std::size_t max_tensor_particles = 5;
  if (n > max_tensor_particles && digits != min_digits)
    throw usage_error("limit: N = " + std::to_string(n) + " > " +
                      std::to_string(max_tensor_particles) +
                      " uses qmc for beta -> 0, in double only (--digits 16)");
  Averages<Real> high_values, low_values;
  if (n == 2) {
    high_values = high_temperature_limit(chain, digits);  // elliptic K/E (paper eq. aveK1-beta0)
    low_values = low_temperature_limit(chain);
  } else {
    TorusOptions torus;
    torus.digits = digits == min_digits ? 0 : digits;
#ifdef _OPENMP
    torus.threads = omp_get_max_threads();
#endif
    QmcOptions qmc;
    qmc.threads = torus.threads;
    high_values = high_temperature_limit_any(chain, torus, qmc, max_tensor_particles);
    low_values = low_temperature_limit_any(chain);
  }
  const AveragesText high =
      averages_text(high_values, digits, static_cast<const Real*>(nullptr));
  const AveragesText low = averages_text(low_values, digits, static_cast<const Real*>(nullptr));
  if (format == Format::text) {
    std::vector<std::vector<std::string>> table{
        {"limit", "i", "beta<K_i>", "error", "beta^2 Var K_i", "<K1>/<K2>"}};
    add_limit_rows(table, "beta -> 0", high);
    add_limit_rows(table, "beta -> inf", low);
    return "N = " + std::to_string(chain.size()) + ", digits = " + std::to_string(digits) +
           "\n" + aligned_table(table);
  }
  return JsonObject()
             .integer("N", static_cast<long long>(chain.size()))
             .integer("digits", digits)
             .raw("high_temperature", limit_json(high))
             .raw("low_temperature", limit_json(low))
             .str() +
         "\n";
}

std::string limit_command(const Options& options) {
  const int digits = digits_option(options);
  constexpr std::array<std::string_view, 2> formats{"json", "text"};
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
  const int digits = digits_option(options);
  constexpr std::array<std::string_view, 3> formats{"json", "csv", "text"};
  const Format format = format_option(options, "text", formats);
  const auto terms = static_cast<std::size_t>(
      parse_integer(options.get("terms", "0"), "--terms", 0, 1'000'000));
  const working_precision guard(digits + guard_digits);
  const std::string_view beta_text = options.required("beta");
  const Chain<mpfr_real> chain = chain_option<mpfr_real>(options, true);
  const mpfr_real beta = parse_real<mpfr_real>(beta_text, "--beta", Domain::positive);
  const auto rows = series_convergence(chain, beta, digits, terms);
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
};

constexpr std::array<std::string_view, 13> average_options{
    "masses", "lengths", "g",   "beta",    "digits", "method",
    "format", "cases",   "tol", "samples", "shifts", "seed", "timing-rows"};
constexpr std::array<std::string_view, 1> average_flags{"timing"};
constexpr std::array<std::string_view, 5> limit_options{"masses", "lengths", "g", "digits",
                                                        "format"};
constexpr std::array<std::string_view, 7> series_options{"masses", "lengths", "g",     "beta",
                                                         "digits", "terms",   "format"};

const std::array<Command, 6> commands{{
    {"average", average_usage, average_options, average_command, average_flags},
    {"limit", limit_usage, limit_options, limit_command},
    {"series", series_usage, series_options, series_command},
    {"table", table_usage, table_options, table_command},
    {"simulate", simulate_usage, simulate_options, simulate_command},
    {"poincare", poincare_usage, poincare_options, poincare_command},
}};

const Command& find_command(std::string_view name) {
  const auto found = std::ranges::find(commands, name, &Command::name);
  if (found == commands.end())
    throw usage_error("unknown command '" + std::string(name) + "' (try 'pendavg --help')");
  return *found;
}

}  // namespace

std::string run(std::span<const std::string_view> args) {
  if (args.empty()) throw usage_error("no command given (try 'pendavg --help')");
  const std::string_view name = args.front();
  const auto rest = args.subspan(1);
  if (name == "--help" || name == "-h" || (name == "help" && rest.empty()))
    return std::string(general_usage);
  if (name == "help") return std::string(find_command(rest.front()).usage);
  if (name == "--version") return PENDAVG_VERSION "\n";
  const Command& command = find_command(name);
  if (asks_for_help(rest)) return std::string(command.usage);
  return command.run(Options(name, rest, command.options, command.flags));
}

}  // namespace pendavg::cli
