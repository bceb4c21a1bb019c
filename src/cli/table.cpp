// SPDX-License-Identifier: GPL-3.0-or-later
// src/cli/table.cpp -- `pendavg table`: every combination of swept parameters, one CSV row each.
// Every point is checked first; then the rows are generated from their index and computed by
// the sweep engine (sweep.hpp: every rank and thread, one thread per row, so the numbers do not
// depend on either), streamed in a fixed order to stdout or to a file written atomically
// (temporary file + rename), and an interrupted sweep can be resumed from its file.
#include "common.hpp"

#include "average_options.hpp"
#include "distribute.hpp"
#include "files.hpp"
#include "format.hpp"

#include "io/exact_decimal.hpp"
#include "io/record.hpp"
#include "io/results.hpp"
#include "io/sweep_rows.hpp"
#include "interrupt.hpp"
#include "sweep.hpp"
#include "shard.hpp"
#include "sweep_file.hpp"
#include "sweep_format.hpp"

#include "pendavg/mpfr.hpp"
#include "pendavg/pendavg.hpp"

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <charconv>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <ctime>
#include <exception>
#include <functional>
#include <optional>
#include <type_traits>
#include <utility>
#include <vector>

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

namespace pendavg::cli {

constexpr std::string_view table_usage =
    "usage: pendavg table --beta SPEC [--mu1 SPEC] [--l1 SPEC] [--l2 SPEC] [--g SPEC]\n"
    "                     [--digits LIST] [--method auto|integral|series]\n"
    "                     [--format csv|json|text] [--output FILE | --resume FILE] [--shard K/N]\n"
    "       pendavg table --chain LIST --beta SPEC [--g SPEC] [--digits LIST]\n"
    "                     [--method auto|torus-trapezoid|transfer|qmc] [--tol T] [--samples S]\n"
    "                     [--shifts R] [--seed K] [--format F] [--output FILE | --resume FILE]\n"
    "       pendavg table (--energy SPEC | --excitation SPEC) [--mu1 ...] [--chain LIST] ...\n"
    "\n"
    "A parameter sweep: one CSV row per combination of the values. SPEC is one of\n"
    "  log:A:B:N   N values log-spaced from A to B (N >= 2; the ends are A and B as written)\n"
    "  lin:A:B:N   N values equally spaced from A to B\n"
    "  list:X,Y,Z  or simply X,Y,Z (or one value X): the values as written\n"
    "LIST is list:X,Y,Z, X,Y,Z or X (integers, no ranges).\n"
    "Generated values are the shortest decimals that round-trip the double nearest the grid\n"
    "point; every value is then used as that exact decimal (also in MPFR).\n"
    "--digits LIST (16..1000 each, default 16): significant digits; 16 runs in double, more in\n"
    "MPFR. --g SPEC: gravity (>= 0, default 1).\n"
    "Double pendulum (default): masses m1 = mu1 and m2 = 1 - mu1 (computed in decimal, exactly;\n"
    "0 < mu1 < 1), lengths l1 (default 1) and l2 (default 1).\n"
    "--chain LIST: chains of N unit masses on unit links (3 <= N <= 16384); one table may mix N.\n"
    "--method auto runs torus-trapezoid for N <= 4 and transfer beyond; torus-trapezoid needs a\n"
    "feasible grid (8^(N-1) <= 1e9, N <= 10); qmc takes N <= 256. transfer and qmc run in\n"
    "double only, so with --method auto their N get rows at --digits 16 only (16 must then be\n"
    "listed). --tol T: the relative tolerance of the torus-trapezoid and transfer rows in double\n"
    "(defaults 1e-13 and 1e-10). qmc: --samples S points per shift (a power of two,\n"
    "1024..1048576, default 65536), --shifts R (4..1024, default 16), --seed K (default 1; every\n"
    "qmc row uses the same shifts). Options no row uses are refused.\n"
    "Rows: the loops nest N, digits, mu1, l1, l2, g, beta (outermost first), except that\n"
    "variables given as log:/lin: ranges are moved innermost, so a range varies fastest.\n"
    "Columns (M = the largest N; `pendavg help schema` names and explains each): the inputs N,\n"
    "digits, beta, g, m1..mM, l1..lM, then the averages as `average` prints them: method,\n"
    "beta_K1..M with beta_K1_error..M_error and beta_K_error_kind, K, ratio, cos_phi, var_K,\n"
    "beta2_var_K, beta_Kc (each with its errors and error kind), diagonal_approx,\n"
    "equipartition_residual, evaluations, work_unit, converged, interrupted. A row with N < M\n"
    "leaves its cells for particles N+1..M empty.\n"
    "The CSV starts with '# schema: 1', then '#' lines naming every swept value, the method (and\n"
    "qmc's samples, shifts and seed), the version and the UTC date.\n"
    "--format csv (the default), json or text: the same header, rows and values (the CSV's\n"
    "texts) in each. json: one document, {\"schema\": 1, \"command\": \"table\", \"header\": [the '#'\n"
    "lines], \"columns\": [...], \"rows\": [one object a row, keys = the columns; a double run's\n"
    "values are JSON numbers, an MPFR run's decimal strings, an empty cell null], \"failed\":\n"
    "[{\"row\": R, \"message\": M} for each failed point, R its 0-based row], \"interrupted\": null\n"
    "or the reason}, one line a row: pandas.DataFrame(doc[\"rows\"]) is the table. text: the '#'\n"
    "lines, then the columns right-aligned at fixed widths (the widest text each can hold),\n"
    "'-' for an empty cell. --resume and merge take files of the run's --format only.\n"
    "--output FILE: written through a temporary file in the same directory and renamed into\n"
    "place (nothing is left behind on error or on a signal); a symbolic link is followed, a\n"
    "device or FIFO is written in place; without --output the CSV goes to stdout. Rows are\n"
    "streamed as they finish (memory does not grow with the number of rows).\n"
    "Progress goes to stderr (\"[table] 120/366 points\") when a sweep runs for over 2 s.\n"
    "SIGINT/SIGTERM stop a sweep early: rows still running get half a second to finish, then\n"
    "every finished row is written, in order, followed by an '# interrupted: K of N points\n"
    "computed' line. --resume FILE continues such a file: FILE's header must match this sweep\n"
    "(parameters, method, digits, version; not the date), its rows are kept and the missing\n"
    "ones computed, and FILE is rewritten as an uninterrupted run writes it (a FILE that does\n"
    "not exist yet is simply written: a batch job can always pass --resume). A run killed\n"
    "outright (SIGKILL, the OOM killer) leaves the rows it had finished in FILE's temporary\n"
    "files; --resume FILE on the same host takes them too.\n"
    "A point that fails while it is computed becomes a '# failed: point (...): reason' line in\n"
    "its place; the sweep goes on and exits 3, naming the first; --resume computes it again\n"
    "(and any row cut short).\n"
    "Under mpirun/srun (pendavg built with MPI) the rows are shared by all ranks (OpenMP threads\n"
    "in each); rank 0 writes the file, which is the same for any number of ranks and threads.\n"
    "--shard K/N (a job array without MPI: K = 1..N) computes the K-th of N fixed shares of the\n"
    "points into its own file (--output, or --resume with the same --shard); 'pendavg merge'\n"
    "joins the N files into the file one run of the whole sweep writes.\n"
    "\n"
    "Microcanonical sweeps: --energy SPEC (any sign; every E must exceed the chain's E_min =\n"
    "-sum_j g S_j l_j) or --excitation SPEC (D = E - E_min > 0) instead of --beta, for the double\n"
    "pendulum and for --chain. --method auto (integral for N <= 4, qmc beyond), integral,\n"
    "torus-trapezoid or qmc (--samples 1024..65536, --shifts, --seed); --digits > 16 for N <= 4.\n"
    "Columns: N, digits, energy (or excitation), g, m1..mM, l1..lM, then the other of energy and\n"
    "excitation, ensemble, method, K1..M (<K_i>_E), Kc (<K_i^(c)>_E = <K>_E/N), cos_phi, var_K,\n"
    "K_total (<K>_E), density_of_states (Omega(E)), each with its errors and error kind,\n"
    "proposal_beta and effective_sample_fraction (qmc), evaluations, work_unit, converged.\n";

namespace {

/// 1 - mu1 as an exact decimal (src/io/exact_decimal.hpp), refused as bad input.
std::string one_minus_decimal(std::string_view x, std::string_view what) {
  try {
    return io::one_minus_decimal(x, what);
  } catch (const std::invalid_argument& bad) {
    throw usage_error(bad.what());
  }
}

constexpr long max_sweep_points = 100000;         // values of one swept variable
constexpr std::size_t max_sweep_rows = 100000000;  // rows of a table (they are streamed)

/// Shortest round-trip decimal of a double.
std::string shortest(double x) {
  char buffer[64];
  const auto end = std::to_chars(buffer, buffer + sizeof buffer, x).ptr;
  return std::string(buffer, end);
}

std::vector<std::string_view> split(std::string_view text, char separator) {
  std::vector<std::string_view> parts;
  std::size_t start = 0;
  for (;;) {
    const std::size_t end = text.find(separator, start);
    parts.push_back(text.substr(start, end == std::string_view::npos ? end : end - start));
    if (end == std::string_view::npos) return parts;
    start = end + 1;
  }
}

/// One swept variable: its values as decimal strings, and whether it was a range.
struct Sweep {
  std::string name;  // "beta", "mu1", "l1", "l2"
  std::string spec;  // as written
  std::vector<std::string> values;
  bool range = false;
};

Sweep parse_sweep(std::string_view name, std::string_view spec, Domain domain) {
  const std::string what = "--" + std::string(name);
  Sweep sweep{std::string(name), std::string(spec), {}, false};
  const auto bad = [&](const std::string& why) {
    return usage_error(what + ": bad sweep '" + std::string(spec) + "': " + why);
  };
  if (spec.starts_with("log:") || spec.starts_with("lin:")) {
    const bool log = spec.starts_with("log:");
    const auto parts = split(spec.substr(4), ':');
    if (parts.size() != 3)
      throw bad(std::string("expected ") + (log ? "log" : "lin") + ":A:B:N");
    const double a = parse_real<double>(parts[0], what, domain);
    const double b = parse_real<double>(parts[1], what, domain);
    const long n = parse_integer(parts[2], what + " point count", 2, max_sweep_points);
    if (!(a < b)) throw bad("A must be smaller than B");
    if (log && !(a > 0)) throw bad("a log range needs A > 0");
    sweep.range = true;
    for (long k = 0; k < n; ++k) {
      if (k == 0) { sweep.values.emplace_back(parts[0]); continue; }
      if (k == n - 1) { sweep.values.emplace_back(parts[1]); continue; }
      const long double t = static_cast<long double>(k) / static_cast<long double>(n - 1);
      const long double v =
          log ? std::pow(10.0L, std::log10(static_cast<long double>(a)) +
                                    t * (std::log10(static_cast<long double>(b)) -
                                         std::log10(static_cast<long double>(a))))
              : static_cast<long double>(a) + t * (static_cast<long double>(b) - a);
      const std::string text = shortest(static_cast<double>(v));
      parse_real<double>(text, what, domain);  // e.g. lin:0:1:3 with a positive domain
      sweep.values.push_back(text);
    }
    return sweep;
  }
  const std::string_view list = spec.starts_with("list:") ? spec.substr(5) : spec;
  if (list.empty()) throw bad("no values");
  for (const std::string_view value : split(list, ',')) {
    if (value.empty()) throw bad("empty value");
    parse_real<double>(value, what, domain);  // validates; the text is kept as written
    sweep.values.emplace_back(value);
  }
  if (static_cast<long>(sweep.values.size()) > max_sweep_points) throw bad("too many values");
  return sweep;
}

/// A list of integers in [lowest, highest] ("list:A,B" or "A,B" or "A"): --chain and --digits.
/// Ranges are refused: N and the digits are chosen, not sampled.
Sweep parse_integer_sweep(std::string_view name, std::string_view spec, long lowest, long highest) {
  const std::string what = "--" + std::string(name);
  Sweep sweep{std::string(name), std::string(spec), {}, false};
  const auto bad = [&](const std::string& why) {
    return usage_error(what + ": bad list '" + std::string(spec) + "': " + why);
  };
  if (spec.starts_with("log:") || spec.starts_with("lin:"))
    throw bad("expected integers X,Y,Z (no log:/lin: ranges)");
  const std::string_view list = spec.starts_with("list:") ? spec.substr(5) : spec;
  if (list.empty()) throw bad("no values");
  for (const std::string_view value : split(list, ',')) {
    if (value.empty()) throw bad("empty value");
    sweep.values.push_back(std::to_string(parse_integer(value, what, lowest, highest)));
  }
  if (static_cast<long>(sweep.values.size()) > max_sweep_points) throw bad("too many values");
  return sweep;
}

/// The longest chain a table takes (the transfer method's limit; qmc's lattices stop at 256).
constexpr long max_chain_particles = static_cast<long>(transfer_max_particles);

/// The sweep's settings that hold for every row.
struct TablePlan {
  bool chain = false;                    ///< --chain: unit masses and lengths
  std::string state = "beta";            ///< beta (canonical), energy or excitation
  bool microcanonical() const { return state != "beta"; }
  std::string method = "auto";           ///< as given
  AverageOptions options;                ///< method and the qmc options, as given
  std::size_t columns_particles = 2;     ///< the largest N: the per-particle columns
};

/// What runs for N particles (the library's rule) and the options a row of N passes: each
/// table-wide option goes to the rows whose method uses it (the library says which), so that one
/// sweep can mix methods.
struct RowMethod {
  AverageMethod method;
  AverageOptions options;
};
RowMethod row_method(const TablePlan& plan, std::size_t particles, int digits) {
  AverageOptions options = plan.options;
  options.samples.reset();
  options.shifts.reset();
  options.seed.reset();
  options.tolerance.reset();
  options.digits = min_digits;  // the method N runs does not depend on the digits
  options.threads = 1;          // one thread per row: the numbers do not depend on the count
  AverageMethod method{};
  std::function<bool(AverageOption)> uses;
  if (plan.microcanonical()) {
    const MicrocanonicalOptions::Rule rule = resolve_microcanonical_rule(
        particles, microcanonical_options(options, particles).rule);
    method = parse_average_method(microcanonical_rule_name(rule, particles));
    uses = [rule, digits](AverageOption o) {
      return microcanonical_rule_uses_option(rule, o, digits);
    };
  } else {
    method = resolve_average_method(particles, options);
    uses = [method, digits](AverageOption o) { return method_uses_option(method, o, digits); };
  }
  if (uses(AverageOption::tolerance)) options.tolerance = plan.options.tolerance;
  if (uses(AverageOption::samples)) options.samples = plan.options.samples;
  if (uses(AverageOption::shifts)) options.shifts = plan.options.shifts;
  if (uses(AverageOption::seed)) options.seed = plan.options.seed;
  options.digits = digits;
  if (plan.microcanonical())
    microcanonical_options(options, particles);  // refuses what the rule cannot do
  else
    resolve_average_method(particles, options);
  return {method, options};
}

std::string join_values(const std::vector<std::string>& values) {
  std::string out;
  for (const std::string& value : values) out += (out.empty() ? "" : ",") + value;
  return out;
}

/// One row's parameters, as decimal strings (used exactly, also in MPFR).
struct Point {
  std::size_t particles = 2;
  AverageOptions options;  ///< digits, method and its options for this row
  std::string state = "beta";  ///< what `beta` holds: beta, energy or excitation
  std::string beta, g;
  std::vector<std::string> masses, lengths;

  std::string describe() const {
    const auto join = join_values;
    return "N = " + std::to_string(particles) + ", digits = " + std::to_string(options.digits) +
           ", " + state + " = " + beta + ", g = " + g + ", masses " + join(masses) +
           ", lengths " + join(lengths);
  }
};

/// The chain of a row, read from its decimal strings (exactly, also in MPFR).
template <class Real>
Chain<Real> point_chain(const Point& point) {
  const Real g = parse_real<Real>(point.g, "--g", Domain::nonnegative);
  std::vector<Real> masses, lengths;
  for (const std::string& mass : point.masses)
    masses.push_back(parse_real<Real>(mass, "mass", Domain::positive));
  for (const std::string& length : point.lengths)
    lengths.push_back(parse_real<Real>(length, "length", Domain::positive));
  return Chain<Real>(std::move(masses), std::move(lengths), g);
}

/// A row's inputs as written: the state (beta, energy or excitation), g, m1..mN, l1..lN.
std::vector<std::string_view> point_texts(const Point& point, bool with_state) {
  std::vector<std::string_view> texts;
  if (with_state) texts.push_back(point.beta);
  texts.push_back(point.g);
  for (const std::string& mass : point.masses) texts.push_back(mass);
  for (const std::string& length : point.lengths) texts.push_back(length);
  return texts;
}

/// One row of a table: the inputs, then the averages, as table_columns names them, appended to
/// `out` in the format of `rows`.
template <class Real>
void table_row(std::string& out, const Point& point, const TablePlan& plan,
               const io::RowWriter& rows) {
  std::optional<working_precision> precision;  // each row of an MPFR sweep holds its own
  if constexpr (!std::is_same_v<Real, double>) precision.emplace(point.options.digits + guard_digits);
  const io::Printing printing{point.options.digits};
  const std::size_t width = plan.columns_particles;
  const Chain<Real> chain = point_chain<Real>(point);
  io::Record inputs, values;
  if (plan.microcanonical()) {
    const MicrocanonicalOptions options = microcanonical_options(point.options, point.particles);
    const Real state =
        microcanonical_state(chain, plan.state, point.beta, "--" + plan.state, options);
    const MicrocanonicalAverages<Real> averages =
        plan.state == "excitation" ? microcanonical_average_excitation(chain, state, options)
                                   : microcanonical_average(chain, state, options);
    inputs.reset(io::microcanonical_input_fields(plan.state), width);
    io::append_microcanonical_inputs(inputs, chain, state, printing, point_texts(point, true));
    values.reset(io::microcanonical_fields(plan.state), width);
    io::append_microcanonical(values, averages, printing);
  } else {
    const Real beta = parse_real<Real>(point.beta, "--beta", Domain::positive);
    const Averages<Real> averages = average(chain, beta, point.options);
    inputs.reset(io::canonical_input_fields(), width);
    io::append_canonical_inputs(inputs, chain, beta, printing, point_texts(point, true));
    values.reset(io::averages_fields(), width);
    io::append_averages(values, averages, &beta, printing);
  }
  const io::RowCells cells[] = {{&inputs}, {&values}};
  rows.append(out, {}, false, cells);
}

/// The rows of a sweep, generated one at a time from their index (never all at once: a chain of
/// 256 over 1e5 betas would be 1.6 GB of decimal strings). Rows are the (N, digits) pairs that
/// run (a qmc N has no MPFR rows), outermost, each with the product of the other sweeps; the
/// last sweep varies fastest.
class PointSpace {
 public:
  PointSpace(const TablePlan& plan, const std::vector<Sweep>& sweeps,
             const std::function<bool(std::size_t particles, int digits)>& runs)
      : plan_(plan) {
    // chain (with --chain) and digits are integer lists, never ranges: they lead the nesting.
    const std::size_t leading = plan.chain ? 2 : 1;
    const std::vector<std::string> default_n{"2"};
    const std::vector<std::string>& n_values = plan.chain ? sweeps[0].values : default_n;
    for (const std::string& n : n_values)
      for (const std::string& digits : sweeps[leading - 1].values)
        if (runs(std::stoul(n), std::stoi(digits)))
          pairs_.push_back({std::stoul(n), std::stoi(digits)});
    for (std::size_t s = leading; s < sweeps.size(); ++s) inner_.push_back(&sweeps[s]);
    per_pair_ = 1;
    for (const Sweep* sweep : inner_) per_pair_ *= sweep->values.size();
  }
  std::size_t count() const { return pairs_.size() * per_pair_; }

  /// Row `index`; `options(N, digits)` gives the options its row passes to the library.
  Point point(std::size_t index,
              const std::function<AverageOptions(std::size_t, int)>& options) const {
    const auto [particles, digits] = pairs_[index / per_pair_];
    std::size_t rest = index % per_pair_;
    Point point;
    point.particles = particles;
    std::string mu1 = "0.5", l1 = "1", l2 = "1";
    for (std::size_t s = inner_.size(); s-- > 0;) {
      const Sweep& sweep = *inner_[s];
      const std::string& value = sweep.values[rest % sweep.values.size()];
      rest /= sweep.values.size();
      if (sweep.name == plan_.state) point.beta = value;
      else if (sweep.name == "g") point.g = value;
      else if (sweep.name == "mu1") mu1 = value;
      else if (sweep.name == "l1") l1 = value;
      else l2 = value;
    }
    if (plan_.chain) {
      point.masses.assign(particles, "1");
      point.lengths.assign(particles, "1");
    } else {
      point.masses = {mu1, one_minus_decimal(mu1, "--mu1")};
      point.lengths = {l1, l2};
    }
    point.state = plan_.state;
    point.options = options(particles, digits);
    return point;
  }

 private:
  const TablePlan& plan_;
  std::vector<std::pair<std::size_t, int>> pairs_;
  std::vector<const Sweep*> inner_;
  std::size_t per_pair_ = 1;
};

/// Checks one point as the library will see it (numbers at the row's precision, the chain,
/// the method's domain), without computing it.
template <class Real>
void check_point(const Point& point) {
  std::optional<working_precision> precision;
  if constexpr (!std::is_same_v<Real, double>) precision.emplace(point.options.digits + guard_digits);
  const Real g = parse_real<Real>(point.g, "--g", Domain::nonnegative);
  std::vector<Real> masses, lengths;
  for (const std::string& mass : point.masses)
    masses.push_back(parse_real<Real>(mass, "mass", Domain::positive));
  for (const std::string& length : point.lengths)
    lengths.push_back(parse_real<Real>(length, "length", Domain::positive));
  Chain<Real> chain(std::move(masses), std::move(lengths), g);
  if (point.state != "beta") {  // microcanonical: the state against E_min, the rule's options
    microcanonical_state(chain, point.state, point.beta, "--" + point.state,
                         microcanonical_options(point.options, point.particles));
    return;
  }
  const Real beta = parse_real<Real>(point.beta, "--beta", Domain::positive);
  check_average(chain, beta, point.options);
  check_printed_quotients(beta);
}

/// The leading fields of a row (N, digits, beta, g, masses, lengths, padded to `width`): what
/// identifies it in a resumed file.
std::string row_key(const Point& point, std::size_t width) {
  std::vector<std::string> fields{std::to_string(point.particles),
                                  std::to_string(point.options.digits), point.beta, point.g};
  const auto add_padded = [&](const std::vector<std::string>& values) {
    fields.insert(fields.end(), values.begin(), values.end());
    fields.insert(fields.end(), width - values.size(), std::string());
  };
  add_padded(point.masses);
  add_padded(point.lengths);
  std::string key;
  append_csv_line(key, fields);
  key.pop_back();
  return key;
}

}  // namespace


namespace {

// ---------------------------------------------------------------- table_command's steps

/// The sweep as asked for: the settings of every row and the swept variables in their nesting
/// (outermost first; ranges moved innermost).
struct TableRequest {
  TablePlan plan;
  std::vector<Sweep> sweeps;
  std::size_t combinations = 1;  ///< the product of the sweeps' sizes

  const Sweep* sweep_named(std::string_view name) const {
    const auto found = std::ranges::find(sweeps, name, &Sweep::name);
    return found == sweeps.end() ? nullptr : &*found;
  }
};

/// Step 1, parse: the ensemble, the method and its options, and every swept variable (each
/// value checked against its domain).
TableRequest parse_table_request(const Options& options) {
  TableRequest request;
  TablePlan& plan = request.plan;
  plan.chain = options.has("chain");
  constexpr std::array<std::string_view, 4> read_names{"tol", "samples", "shifts", "seed"};
  plan.options = parse_average_options(options, read_names);
  {
    std::vector<std::string> given;
    for (const char* name : {"beta", "energy", "excitation"})
      if (options.has(name)) given.emplace_back(name);
    if (given.size() > 1)
      throw usage_error("table: give one of --beta, --energy, --excitation (not both --" +
                        given[0] + " and --" + given[1] + ")");
    if (!given.empty()) plan.state = given.front();
  }

  // Swept variables in their default nesting (outermost first); ranges are moved innermost.
  std::vector<Sweep>& sweeps = request.sweeps;
  if (plan.chain) {
    for (const std::string_view single : {"mu1", "l1", "l2"})
      if (options.has(single))
        throw usage_error("table: --chain has unit masses and lengths; --" +
                          std::string(single) + " is for the double pendulum");
    sweeps.push_back(parse_integer_sweep("chain", options.required("chain"), 3, max_chain_particles));
  }
  // Any method the library has; each row's N (and the ensemble) is checked against it below.
  plan.method = std::string(options.get("method", "auto"));
  try {
    plan.options.method = parse_average_method(plan.method.c_str());
  } catch (const invalid_input& bad) {
    throw usage_error(std::string("table: ") + bad.what());
  }
  sweeps.push_back(parse_integer_sweep("digits", options.get("digits", "16"), min_digits, max_digits));
  if (!plan.chain) {
    sweeps.push_back(parse_sweep("mu1", options.get("mu1", "0.5"), Domain::positive));
    for (const std::string& mu1 : sweeps.back().values) one_minus_decimal(mu1, "--mu1");
    sweeps.push_back(parse_sweep("l1", options.get("l1", "1"), Domain::positive));
    sweeps.push_back(parse_sweep("l2", options.get("l2", "1"), Domain::positive));
  }
  sweeps.push_back(parse_sweep("g", options.get("g", "1"), Domain::nonnegative));
  sweeps.push_back(parse_sweep(plan.state, options.required(plan.state),
                               plan.state == "energy" ? Domain::any : Domain::positive));
  // std::stable_partition, not std::ranges::: clang 14 cannot compile the latter with libstdc++ 12.
  std::stable_partition(sweeps.begin(), sweeps.end(), [](const Sweep& s) { return !s.range; });
  for (const Sweep& s : sweeps) {
    request.combinations *= s.values.size();
    if (request.combinations > max_sweep_rows)
      throw usage_error("table: more than " + std::to_string(max_sweep_rows) + " points");
  }
  return request;
}

/// Which method runs each N of the sweep (the library's rule), as the header and the messages
/// name them.
struct TableMethods {
  std::vector<std::size_t> particle_values{2};  ///< the N of the rows, as listed
  std::vector<std::string> torus_n, transfer_n, qmc_n;  ///< as listed, for messages and the header
  std::vector<std::string> double_only_n;              ///< transfer_n and qmc_n, as listed
  std::string chosen;              ///< what runs, in words ("--method auto, which runs ...")
  std::string double_only_method;  ///< "transfer", "qmc" or "transfer or qmc"
};

/// Whether N particles run a double-only method (qmc, transfer): no MPFR rows.
bool is_double_only(const TablePlan& plan, std::size_t particles) {
  return !method_supports_digits(row_method(plan, particles, min_digits).method, min_digits + 1);
}

/// Step 2, plan: the method of every N, checked (with every listed digits) before any work;
/// an option that no row's method uses is refused. Sets plan.columns_particles.
TableMethods plan_table_methods(const Options& options, TableRequest& request) {
  TablePlan& plan = request.plan;
  TableMethods m;
  // Which method runs each N (the library's rule, checked here for every N before any work);
  // qmc and transfer are double only, so their N get rows at digits 16 only.
  if (plan.chain) {
    m.particle_values.clear();
    for (const std::string& n : request.sweep_named("chain")->values)
      m.particle_values.push_back(std::stoul(n));
  }
  plan.columns_particles = std::ranges::max(m.particle_values);
  const auto method_of = [&](std::size_t n) { return row_method(plan, n, min_digits).method; };
  for (const std::size_t n : m.particle_values) {
    try {
      row_method(plan, n, min_digits);
    } catch (const invalid_input& bad) {
      throw usage_error(std::string("table: ") + bad.what());
    }
    if (!plan.chain && !plan.microcanonical()) continue;
    const AverageMethod method = method_of(n);
    std::vector<std::string>& names = method == AverageMethod::qmc        ? m.qmc_n
                                      : method == AverageMethod::transfer ? m.transfer_n
                                                                          : m.torus_n;
    for (std::vector<std::string>* list :
         {&names, is_double_only(plan, n) ? &m.double_only_n : nullptr})
      if (list && std::ranges::find(*list, std::to_string(n)) == list->end())
        list->push_back(std::to_string(n));
  }
  std::string automatic_runs;  // "torus-trapezoid for N = 3, transfer for N = 8, 16"
  for (const auto& [name, list] : {std::pair{"torus-trapezoid", &m.torus_n},
                                   std::pair{"transfer", &m.transfer_n},
                                   std::pair{"qmc", &m.qmc_n}})
    if (!list->empty())
      automatic_runs += (automatic_runs.empty() ? "" : ", ") + std::string(name) + " for N = " +
                        join_values(*list);
  m.chosen =
      plan.microcanonical()
          ? (plan.method != "auto" ? "--method " + plan.method
                                   : "--method auto, which runs the microcanonical integral "
                                     "rule for N = " + join_values(m.torus_n))
      : !plan.chain ? "the double-pendulum engines (--method " + plan.method + ")"
      : plan.method != "auto"
          ? "--method " + plan.method
          : "--method auto, which runs " + automatic_runs;
  // An option that no row's method uses would change nothing: refused.
  for (const AverageOption option : {AverageOption::tolerance, AverageOption::samples,
                                     AverageOption::shifts, AverageOption::seed}) {
    const std::string name = average_option_name(option);
    if (!options.has(name)) continue;
    const bool used = std::ranges::any_of(m.particle_values, [&](std::size_t n) {
      const AverageOptions row = row_method(plan, n, min_digits).options;
      return option == AverageOption::tolerance ? row.tolerance.has_value()
             : option == AverageOption::samples ? row.samples.has_value()
             : option == AverageOption::shifts  ? row.shifts.has_value()
                                                : row.seed.has_value();
    });
    if (!used) throw usage_error("table: --" + name + " is not used by " + m.chosen);
  }
  m.double_only_method = m.qmc_n.empty()        ? "transfer"
                         : m.transfer_n.empty() ? "qmc"
                                                : "transfer or qmc";
  const std::vector<std::string>& digit_values = request.sweep_named("digits")->values;
  for (const std::string& digits : digit_values) {
    const int d = std::stoi(digits);
    for (const std::size_t n : m.particle_values) {
      if (is_double_only(plan, n)) continue;  // qmc and transfer N: MPFR digits are skipped
      try {
        row_method(plan, n, d);
      } catch (const invalid_input& bad) {
        throw usage_error(std::string("table: ") + bad.what());
      }
    }
    if (d == min_digits || !m.torus_n.empty() || !plan.chain) continue;
    throw usage_error("table: --digits " + digits + " is not available with " +
                      m.double_only_method + " (double only; N = " + join_values(m.double_only_n) +
                      (plan.method == "auto" ? " with --method auto" : "") + " runs " +
                      m.double_only_method + ")");
  }
  if (!m.double_only_n.empty() &&
      std::ranges::find(digit_values, std::to_string(min_digits)) == digit_values.end())
    throw usage_error("table: N = " + join_values(m.double_only_n) + " runs " +
                      m.double_only_method + ", which is double only, but --digits has no 16");
  return m;
}

/// Where the rows go: --output FILE, or --resume FILE (continued and rewritten), or stdout.
struct TableTarget {
  std::string output, resume;
  std::string path;  ///< the file written (resume or output; empty: stdout)
};

TableTarget parse_table_target(const Options& options) {
  TableTarget t;
  t.output = std::string(options.get("output", ""));
  t.resume = std::string(options.get("resume", ""));
  if (options.has("output") && t.output.empty()) throw usage_error("table: --output needs a file name");
  if (options.has("resume") && t.resume.empty()) throw usage_error("table: --resume needs a file name");
  if (!t.resume.empty() && !t.output.empty() &&
      resolved_path(t.output, "table") != resolved_path(t.resume, "table"))
    throw usage_error("table: --resume FILE continues FILE and writes it; --output must name the "
                      "same file or be left out");
  t.path = t.resume.empty() ? t.output : t.resume;
  return t;
}

/// The column names of a table's rows: the inputs, then the averages (src/io/results.hpp).
std::vector<std::string> table_columns(const TablePlan& plan) {
  const std::size_t n = plan.columns_particles;
  std::vector<std::string> header = io::column_names(
      plan.microcanonical() ? io::microcanonical_input_fields(plan.state)
                            : io::canonical_input_fields(),
      n);
  for (std::string& name : io::column_names(
           plan.microcanonical() ? io::microcanonical_fields(plan.state) : io::averages_fields(),
           n))
    header.push_back(std::move(name));
  return header;
}

/// The rows in --format's layout: the columns, and (text) each one's width: an input's widest
/// value as written (the swept values; m2 = 1 - mu1 of each mu1), an output's widest text at
/// the sweep's digits (io::widest_cell). From the whole sweep, so that every shard's widths are
/// the merged file's.
io::RowWriter table_row_writer(const Options& options, const TableRequest& request,
                               const TableMethods& m) {
  const io::Format format = format_option(options, "csv", all_formats);
  const TablePlan& plan = request.plan;
  std::vector<std::string> columns = table_columns(plan);
  if (format != io::Format::text) return io::RowWriter(format, std::move(columns));
  const auto widest = [](const std::vector<std::string>& values) {
    std::size_t w = 0;
    for (const std::string& v : values) w = std::max(w, v.size());
    return w;
  };
  const auto sweep_width = [&](std::string_view name) {
    const Sweep* sweep = request.sweep_named(name);
    return sweep ? widest(sweep->values) : std::size_t(1);
  };
  std::vector<int> digits;
  for (const std::string& d : request.sweep_named("digits")->values) digits.push_back(std::stoi(d));
  const std::size_t n = plan.columns_particles;
  std::vector<std::size_t> widths;
  std::size_t particles = 1;
  for (const std::size_t p : m.particle_values) particles = std::max(particles, std::to_string(p).size());
  widths.push_back(particles);
  widths.push_back(sweep_width("digits"));
  widths.push_back(sweep_width(plan.state));
  widths.push_back(sweep_width("g"));
  if (plan.chain) {
    widths.insert(widths.end(), 2 * n, 1);  // "1", or "-" beyond a row's N
  } else {
    std::size_t m2 = 1;
    for (const std::string& mu1 : request.sweep_named("mu1")->values)
      m2 = std::max(m2, one_minus_decimal(mu1, "--mu1").size());
    for (const std::size_t w : {sweep_width("mu1"), m2, sweep_width("l1"), sweep_width("l2")})
      widths.push_back(w);
  }
  const auto outputs = plan.microcanonical() ? io::microcanonical_fields(plan.state)
                                             : io::averages_fields();
  for (const io::Field* field : io::cell_fields(outputs, n))
    widths.push_back(io::widest_cell(*field, digits));
  return io::RowWriter(format, std::move(columns), std::move(widths));
}

/// Step 3, format: the '#' lines that say what made the file (and that --resume checks), then
/// the column line.
std::string table_header(const TableRequest& request, const TableMethods& m,
                         std::size_t row_count) {
  const TablePlan& plan = request.plan;
  std::string out = io::schema_line();
  if (plan.chain) {
    out += "# pendavg table: chains of N = " + request.sweep_named("chain")->spec +
           " unit masses on unit links (m_i = l_i = 1)\n";
  } else {
    out += "# pendavg table: double pendulum (N = 2), m1 = mu1, m2 = 1 - mu1 (exact decimals), "
           "M = 1\n";
  }
  for (const Sweep& s : request.sweeps)
    out += "# " + (s.name == "chain" ? std::string("N") : s.name) + " = " + s.spec + " (" +
           std::to_string(s.values.size()) + (s.values.size() == 1 ? " value)\n" : " values)\n");
  std::string nesting;
  for (const Sweep& s : request.sweeps)
    nesting += (nesting.empty() ? "" : ", ") + (s.name == "chain" ? std::string("N") : s.name);
  out += "# rows = " + std::to_string(row_count) + ", nested " + nesting +
         " (outermost first; the last varies fastest)";
  if (row_count < request.combinations)
    out += "; " + m.double_only_method + " is double only, so N = " +
           join_values(m.double_only_n) + " has rows at digits = 16 only";
  out += "\n# method = " + plan.method;
  if (plan.microcanonical()) {
    out += " (microcanonical averages at fixed " + plan.state +
           (plan.method == "auto" ? "; integral for N <= 4, qmc beyond" : "") +
           (plan.options.tolerance
                ? "; tolerance " + shortest(*plan.options.tolerance) + " in double"
                : std::string("; tolerance 1e-13 for N <= 2, 1e-11 for N = 3, 1e-9 beyond in "
                              "double")) +
           ", 1e-D at D > 16 digits)\n";
    if (!m.qmc_n.empty())
      out += "# qmc (N = " + join_values(m.qmc_n) + "): " +
             std::to_string(plan.options.samples.value_or(MicrocanonicalOptions{}.points)) +
             " points x " +
             std::to_string(plan.options.shifts.value_or(MicrocanonicalOptions{}.shifts)) +
             " shifts, seed " + std::to_string(plan.options.seed.value_or(1)) +
             ", double only, statistical error bars (the 99.9% Student-t quantile of the "
             "standard error)\n";
  } else if (plan.chain) {
    const std::string torus =
        "torus-trapezoid (tolerance " +
        shortest(plan.options.tolerance.value_or(default_torus_tolerance)) +
        " in double, 1e-D at D > 16 digits)";
    const std::string transfer =
        "transfer (tolerance " +
        shortest(plan.options.tolerance.value_or(default_transfer_tolerance)) + ", double only)";
    if (plan.method == "auto")
      out += ": " + torus + " for N <= " + std::to_string(automatic_torus_max_particles) +
             ", " + transfer + " for N > " + std::to_string(automatic_torus_max_particles);
    else if (plan.method == "torus-trapezoid")
      out += ": " + torus;
    else if (plan.method == "transfer")
      out += ": " + transfer;
    out += "\n";
    if (!m.qmc_n.empty())
      out += "# qmc (N = " + join_values(m.qmc_n) + "): " +
             std::to_string(plan.options.samples.value_or(default_qmc_samples)) + " points x " +
             std::to_string(plan.options.shifts.value_or(default_qmc_shifts)) + " shifts, seed " +
             std::to_string(plan.options.seed.value_or(default_qmc_seed)) +
             " (the same shifts for every row), double only, statistical error bars (the 99.9% "
             "Student-t quantile of the standard error over the shifts)\n";
  } else {
    out += " (the double-pendulum engines)\n";
  }
  if (plan.columns_particles > 1 && m.particle_values.size() > 1 &&
      std::ranges::min(m.particle_values) < plan.columns_particles)
    out += "# per-particle columns run to N = " + std::to_string(plan.columns_particles) +
           "; a row of a shorter chain leaves the cells beyond its N empty\n";
  out += "# pendavg " + std::string(version()) + ", generated " + utc_timestamp() + " (UTC)\n";
  append_csv_line(out, table_columns(plan));
  return out;
}

/// Step 4, run: rank 0 checks the output (and reads a resumed file); then every rank computes
/// rows (sweep.hpp) and rank 0 streams them, in order, after `header`.
void run_table(const TableRequest& request, const PointSpace& space,
               const std::function<AverageOptions(std::size_t, int)>& row_options,
               const TableTarget& target, const io::RowWriter& rows_format,
               const std::string& header, int threads, const std::optional<Shard>& shard) {
  const TablePlan& plan = request.plan;
  const std::size_t row_count = shard ? shard->count() : space.count();
  // Row k of this run: the sweep's row k, or the shard's k-th.
  const auto point = [&](std::size_t k) { return space.point(shard ? shard->row(k) : k, row_options); };
  std::optional<ResumedRows> resumed;
  std::optional<SweepFile> file;
  on_root([&] {
    if (!target.path.empty()) probe_output(target.path, "table");
    if (!target.resume.empty())  // the file, or a killed run's temporary, or nothing yet
      resumed.emplace(target.resume, "table", header, rows_format, row_count,
                      4 + 2 * plan.columns_particles,
                      [&](std::size_t k) { return row_key(point(k), plan.columns_particles); });
    // Opened here, so that every rank learns it failed (a FIFO nobody reads, say).
    file.emplace(target.path, "table", header, resumed ? &*resumed : nullptr,
                 rows_format.format());
    if (shard) file->row_number = [&](std::size_t k) { return shard->row(k); };
  });
  input_checked("table");

  SweepRows rows;
  rows.count = row_count;
  rows.threads = threads;
  rows.progress = "table";
  rows.unit = "points";
  {
    int most_digits = min_digits;
    for (const std::string& d : request.sweep_named("digits")->values)
      most_digits = std::max(most_digits, std::stoi(d));
    const std::size_t m = plan.columns_particles;
    rows.row_bytes = (8 * m + 5) * (decimal_max_length(most_digits) + 1) +
                     (2 * m + 2) * 32 + 4 * m + 6 * 25 + 64;
    if (rows_format.format() == io::Format::json)  // its keys
      for (const std::string& name : rows_format.columns()) rows.row_bytes += name.size() + 6;
    rows.row_bytes += rows_format.text_line_length();  // text: its padding
  }
  rows.compute = [&](std::size_t k, int, std::string& text) {
    const Point p = point(k);
    if (p.options.digits == min_digits) table_row<double>(text, p, plan, rows_format);
    else table_row<mpfr_real>(text, p, plan, rows_format);
  };
  const auto point_context = [&](std::size_t k) {
    return "point (" + point(k).describe() + "): ";
  };
  // A point that fails once the sweep runs (the check passed it) does not cost the others: it
  // becomes a '# failed:' line in its place, and the run ends with rows_failed (exit 3).
  rows.failed_row = [&](std::size_t k, std::string_view reason) {
    return failed_row_line(point_context(k), reason);
  };
  run_sweep(rows, file ? &*file : nullptr, [&](const SweepOutcome& outcome) {
    if (outcome.failed) {
      file->discard();
      rethrow_failure(outcome, [&](std::size_t k) { return "table: " + point_context(k); });
    }
    if (outcome.written < row_count) {
      // Interrupted (SIGINT/SIGTERM): every finished row is kept; say so in the file and on
      // stderr. --resume FILE computes the others.
      file->end_rows(std::to_string(outcome.written) + " of " + std::to_string(row_count) +
                     " points computed; the rows of the others are left out");
      std::fprintf(stderr, "[table] interrupted: %zu of %zu points written\n", outcome.written,
                   row_count);
    } else {
      file->end_rows({});
    }
    file->commit();
    if (outcome.failed_rows > 0)
      throw rows_failed(failed_rows_message("table", outcome, "points", target.path,
                                            point_context(outcome.first_failed_row),
                                            rows_format.format()));
  });
}

}  // namespace

std::string run_table(const Options& options) {
  TableRequest request = parse_table_request(options);
  const TableMethods methods = plan_table_methods(options, request);
  const TableTarget target = parse_table_target(options);
  const TablePlan& plan = request.plan;

  // Every point is checked before any is computed (numbers, chain, the method's domain). From
  // here on SIGINT/SIGTERM stop the sweep (also while the points are being checked).
  const StopOnSignal signals;
  const PointSpace space(plan, request.sweeps, [&](std::size_t n, int digits) {
    return digits == min_digits || !is_double_only(plan, n);  // a qmc or transfer N: no MPFR rows
  });
  const std::function<AverageOptions(std::size_t, int)> row_options = [&](std::size_t n,
                                                                           int digits) {
    return row_method(plan, n, digits).options;
  };
  const std::optional<Shard> shard = shard_option(options, "table", space.count());
  const std::size_t row_count = shard ? shard->count() : space.count();
  const auto check = [&](std::size_t k, int /*thread*/) {
    const Point point = space.point(shard ? shard->row(k) : k, row_options);
    try {
      if (point.options.digits == min_digits) check_point<double>(point);
      else check_point<mpfr_real>(point);
    } catch (const invalid_input& bad) {
      throw usage_error("table: point (" + point.describe() + "): " + bad.what());
    }
  };
  const int threads = hardware_threads();
  if (const std::size_t bad = first_failing_row(row_count, threads, check, "table", "points");
      bad < row_count)
    check(bad, 0);  // throws the first bad point's error, on every rank

  const io::RowWriter rows_format = table_row_writer(options, request, methods);
  run_table(request, space, row_options, target, rows_format,
            sweep_header(rows_format, "table", marked(shard, table_header(request, methods,
                                                                          space.count()))),
            threads, shard);
  return {};
}

constexpr std::array<std::string_view, 18> table_options{
    "beta",    "mu1",    "l1",   "l2",     "g",      "chain",  "digits",     "method",
    "tol",     "samples", "shifts", "seed", "output", "resume", "energy", "excitation", "shard",
    "format"};
const Command table_command{"table", table_usage, table_options, run_table, {}, true};

}  // namespace pendavg::cli
