// src/cli/table.cpp -- `pendavg table`: every combination of swept parameters, one CSV row each,
// computed in parallel across points (one thread per point, so the numbers do not depend on the
// thread count), rows in a fixed order, written atomically (temporary file + rename).
#include "table.hpp"

#include "files.hpp"
#include "format.hpp"

#include "pendavg/double_pendulum.hpp"
#include "pendavg/torus.hpp"
#include "pendavg/trace_formula.hpp"

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
#include <filesystem>
#include <utility>
#include <vector>

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#ifndef PENDAVG_VERSION
#define PENDAVG_VERSION "unknown"
#endif

namespace pendavg::cli {

const std::string_view table_usage =
    "usage: pendavg table --beta SPEC [--mu1 SPEC] [--l1 SPEC] [--l2 SPEC] [--g G]\n"
    "                     [--digits D] [--method auto|integral|series] [--output FILE.csv]\n"
    "       pendavg table --chain N --beta SPEC [--g G] [--digits D]\n"
    "                     [--method auto|torus-trapezoid|qmc] [--output FILE.csv]\n"
    "\n"
    "A parameter sweep: one CSV row per combination of the values. SPEC is one of\n"
    "  log:A:B:N   N values log-spaced from A to B (N >= 2; the ends are A and B as written)\n"
    "  lin:A:B:N   N values equally spaced from A to B\n"
    "  list:X,Y,Z  or simply X,Y,Z (or one value X): the values as written\n"
    "Generated values are the shortest decimals that round-trip the double nearest the grid\n"
    "point; every value is then used as that exact decimal (also in MPFR).\n"
    "Double pendulum (default): masses m1 = mu1 and m2 = 1 - mu1 (computed in decimal, exactly;\n"
    "0 < mu1 < 1), lengths l1 (default 1) and l2 (default 1), gravity G (default 1).\n"
    "--chain N (3..8): unit masses and lengths, only --beta is swept; --method auto runs\n"
    "torus-trapezoid for N <= 4 and qmc (2^16 points x 16 shifts, seed 1, double only) beyond.\n"
    "Rows: the loops nest mu1, l1, l2, beta (outermost first), except that variables given as\n"
    "log:/lin: ranges are moved innermost, so a range varies fastest.\n"
    "Columns: beta,g,m1..mN,l1..lN (as for average --cases), beta_K1..N, error_K1..N, ratio,\n"
    "cos_phi1..N, var_K1..N, [diagonal_approx1..N for --chain], method, evaluations, converged.\n"
    "The CSV starts with '#' lines naming the sweep, method, digits, version and UTC date.\n"
    "--output FILE: written through a temporary file in the same directory and renamed into\n"
    "place (nothing is left behind on error); without --output the CSV goes to stdout.\n"
    "Progress goes to stderr (\"[table] 120/366 points\") when a sweep runs for over 2 s.\n";

namespace {

constexpr long max_sweep_points = 100000;
constexpr int max_decimal_scale = 4000;  // digits after the point in one_minus_decimal

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

/// One row's parameters: beta, g, m1..mN, l1..lN as decimal strings.
using Point = std::vector<std::string>;

enum class ChainSolver { torus, qmc };

struct TablePlan {
  std::size_t particles = 2;
  int digits = min_digits;
  std::string method = "auto";
  Engine engine = Engine::automatic;    // N = 2
  ChainSolver solver = ChainSolver::torus;  // chains
};

template <class Real>
std::string table_row(const Point& point, const TablePlan& plan) {
  const std::size_t n = plan.particles;
  const Real beta = parse_real<Real>(point[0], "--beta", Domain::positive);
  const Real g = parse_real<Real>(point[1], "--g", Domain::nonnegative);
  std::vector<Real> masses, lengths;
  for (std::size_t i = 0; i < n; ++i)
    masses.push_back(parse_real<Real>(point[2 + i], "mass", Domain::positive));
  for (std::size_t i = 0; i < n; ++i)
    lengths.push_back(parse_real<Real>(point[2 + n + i], "length", Domain::positive));
  const Chain<Real> chain(std::move(masses), std::move(lengths), g);

  Averages<Real> averages;
  std::vector<Real> diagonal;
  if (n == 2) {
    averages = pendavg::average(chain, beta, plan.digits, plan.engine);
  } else if (plan.solver == ChainSolver::torus) {
    TorusOptions options;
    options.digits = plan.digits == min_digits ? 0 : plan.digits;
    options.threads = 1;
    TorusAverages<Real> r = torus_average_full(chain, beta, options);
    averages = std::move(r.averages);
    diagonal = std::move(r.diagonal_approximation);
  } else {
    QmcOptions options;
    options.points = std::size_t(1) << detail::qmc::lattice_table_max_log2;
    options.threads = 1;
    QmcAverages<Real> r = qmc_average(chain, beta, options);
    averages = std::move(r.averages);
    diagonal = std::move(r.diagonal_approximation);
  }
  const AveragesText text = averages_text(averages, plan.digits, &beta);
  std::vector<std::string> fields(point.begin(), point.end());
  const auto add = [&](const std::vector<std::string>& values) {
    fields.insert(fields.end(), values.begin(), values.end());
  };
  add(text.beta_kinetic);
  add(text.error);
  fields.push_back(text.ratio);
  add(text.cos_angle);
  add(text.variance);
  for (const Real& value : diagonal) fields.push_back(decimal(value, plan.digits));
  fields.push_back(text.method);
  fields.push_back(std::to_string(text.evaluations));
  fields.push_back(text.converged ? "true" : "false");
  std::string out;
  append_csv_line(out, fields);
  return out;
}

/// Evaluates every point on all cores; rows come back in point order. The first failing point
/// (in point order) is reported.
template <class Real>
std::vector<std::string> table_rows(const std::vector<Point>& points, const TablePlan& plan) {
  const std::size_t count = points.size();
  std::vector<std::string> rows(count);
  std::vector<std::exception_ptr> errors(count);
  std::atomic<std::size_t> done{0};
  const auto start = std::chrono::steady_clock::now();
  double last_report = 0;
  bool reported = false;
#pragma omp parallel for schedule(dynamic, 1)
  for (long i = 0; i < static_cast<long>(count); ++i) {
    const auto k = static_cast<std::size_t>(i);
    try {
      rows[k] = table_row<Real>(points[k], plan);
    } catch (...) {
      errors[k] = std::current_exception();
    }
    const std::size_t finished = ++done;
    const double elapsed =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
#pragma omp critical(pendavg_table_progress)
    if (elapsed - last_report >= 2 || (reported && finished == count)) {
      std::fprintf(stderr, "[table] %zu/%zu points\n", finished, count);
      last_report = elapsed;
      reported = true;
    }
  }
  for (std::size_t k = 0; k < count; ++k) {
    if (!errors[k]) continue;
    try {
      std::rethrow_exception(errors[k]);
    } catch (const invalid_input& bad) {
      std::string where;
      for (std::size_t j = 0; j < points[k].size(); ++j) where += (j ? "," : "") + points[k][j];
      throw usage_error("table: point (" + where + "): " + bad.what());
    }
  }
  return rows;
}

std::string utc_now() {
  const std::time_t now = std::time(nullptr);
  std::tm tm{};
  gmtime_r(&now, &tm);
  char buffer[32];
  std::strftime(buffer, sizeof buffer, "%Y-%m-%dT%H:%M:%SZ", &tm);
  return buffer;
}

}  // namespace

std::string one_minus_decimal(std::string_view x, std::string_view what) {
  const std::string name(what);
  const auto fail = [&] { return usage_error(name + ": '" + std::string(x) + "' must be < 1"); };
  std::string_view text = x;
  if (text.starts_with('+')) text.remove_prefix(1);
  long exponent = 0;
  if (const auto e = text.find_first_of("eE"); e != std::string_view::npos) {
    std::string_view exponent_text = text.substr(e + 1);
    if (exponent_text.starts_with('+')) exponent_text.remove_prefix(1);
    const auto [ptr, ec] = std::from_chars(exponent_text.data(),
                                           exponent_text.data() + exponent_text.size(), exponent);
    if (ec != std::errc() || ptr != exponent_text.data() + exponent_text.size() ||
        std::labs(exponent) > max_decimal_scale)
      throw usage_error(name + ": '" + std::string(x) + "' has too many digits for 1 - " + name);
    text = text.substr(0, e);
  }
  std::string digits;
  long scale = 0;  // x = digits * 10^-scale
  const auto point = text.find('.');
  digits = std::string(text.substr(0, point));
  if (point != std::string_view::npos) {
    digits += text.substr(point + 1);
    scale = static_cast<long>(text.size() - point - 1);
  }
  scale -= exponent;
  digits.erase(0, std::min(digits.find_first_not_of('0'), digits.size()));
  if (digits.empty()) throw usage_error(name + ": '" + std::string(x) + "' must be > 0");
  if (scale > max_decimal_scale)
    throw usage_error(name + ": '" + std::string(x) + "' has too many digits for 1 - " + name);
  if (scale <= 0 || static_cast<long>(digits.size()) > scale) throw fail();  // x >= 1
  digits.insert(0, static_cast<std::size_t>(scale) - digits.size(), '0');
  // 10^scale - D = (999...9 - D) + 1
  std::string result(digits.size(), '0');
  for (std::size_t i = 0; i < digits.size(); ++i) result[i] = static_cast<char>('9' - (digits[i] - '0'));
  for (std::size_t i = result.size(); i-- > 0;) {
    if (result[i] == '9') { result[i] = '0'; continue; }
    ++result[i];
    break;
  }
  result.erase(result.find_last_not_of('0') + 1);  // D > 0, so some digit is non-zero
  return "0." + result;
}

std::string table_command(const Options& options) {
  TablePlan plan;
  plan.digits = parse_digits(options.get("digits", "16"));
  const bool chain = options.has("chain");
  if (chain) {
    plan.particles = static_cast<std::size_t>(parse_integer(options.required("chain"), "--chain", 3, 8));
    for (const std::string_view single : {"mu1", "l1", "l2"})
      if (options.has(single))
        throw usage_error("table: --chain has unit masses and lengths; --" +
                          std::string(single) + " is for the double pendulum");
    constexpr std::array<std::string_view, 3> methods{"auto", "torus-trapezoid", "qmc"};
    plan.method = std::string(methods[parse_choice(options.get("method", "auto"), "method", methods)]);
    plan.solver = plan.method == "qmc" || (plan.method == "auto" && plan.particles > 4)
                      ? ChainSolver::qmc
                      : ChainSolver::torus;
    if (plan.solver == ChainSolver::qmc && plan.digits != min_digits)
      throw usage_error("table: --digits " + std::to_string(plan.digits) +
                        " is not available with qmc (double only; N = " +
                        std::to_string(plan.particles) + " with --method auto runs qmc)");
  } else {
    constexpr std::array<std::string_view, 3> methods{"auto", "integral", "series"};
    const std::size_t m = parse_choice(options.get("method", "auto"), "method", methods);
    plan.method = std::string(methods[m]);
    plan.engine = m == 0 ? Engine::automatic : m == 1 ? Engine::integral : Engine::series;
  }
  const std::string g(options.get("g", "1"));
  parse_real<double>(g, "--g", Domain::nonnegative);

  // Swept variables in their default nesting (outermost first); ranges are moved innermost.
  std::vector<Sweep> sweeps;
  if (!chain) {
    sweeps.push_back(parse_sweep("mu1", options.get("mu1", "0.5"), Domain::positive));
    for (const std::string& mu1 : sweeps.back().values) one_minus_decimal(mu1, "--mu1");
    sweeps.push_back(parse_sweep("l1", options.get("l1", "1"), Domain::positive));
    sweeps.push_back(parse_sweep("l2", options.get("l2", "1"), Domain::positive));
  }
  sweeps.push_back(parse_sweep("beta", options.required("beta"), Domain::positive));
  std::ranges::stable_partition(sweeps, [](const Sweep& s) { return !s.range; });
  std::size_t count = 1;
  for (const Sweep& s : sweeps) {
    count *= s.values.size();
    if (count > static_cast<std::size_t>(max_sweep_points))
      throw usage_error("table: more than " + std::to_string(max_sweep_points) + " points");
  }

  const std::string output(options.get("output", ""));
  if (options.has("output")) {
    if (output.empty()) throw usage_error("table: --output needs a file name");
    probe_output(output, "table");
  }

  // Points in row order: the last sweep varies fastest.
  const std::size_t n = plan.particles;
  std::vector<Point> points;
  points.reserve(count);
  std::vector<std::size_t> index(sweeps.size(), 0);
  for (std::size_t k = 0; k < count; ++k) {
    std::string beta, mu1 = "1", l1 = "1", l2 = "1";
    for (std::size_t s = 0; s < sweeps.size(); ++s) {
      const std::string& value = sweeps[s].values[index[s]];
      if (sweeps[s].name == "beta") beta = value;
      else if (sweeps[s].name == "mu1") mu1 = value;
      else if (sweeps[s].name == "l1") l1 = value;
      else l2 = value;
    }
    Point point{beta, g};
    if (chain) {
      point.insert(point.end(), 2 * n, "1");
    } else {
      point.insert(point.end(), {mu1, one_minus_decimal(mu1, "--mu1"), l1, l2});
    }
    points.push_back(std::move(point));
    for (std::size_t s = sweeps.size(); s-- > 0;) {
      if (++index[s] < sweeps[s].values.size()) break;
      index[s] = 0;
    }
  }

  std::string out;
  if (chain) {
    out += "# pendavg table: chain of N = " + std::to_string(n) +
           " unit masses on unit links (m_i = l_i = 1)\n";
  } else {
    out += "# pendavg table: double pendulum (N = 2), m1 = mu1, m2 = 1 - mu1 (exact decimals), "
           "M = 1\n";
  }
  for (const Sweep& s : sweeps)
    out += "# " + s.name + " = " + s.spec + " (" + std::to_string(s.values.size()) +
           (s.values.size() == 1 ? " value)\n" : " values)\n");
  out += "# g = " + g + "\n";
  std::string nesting;
  for (const Sweep& s : sweeps) nesting += (nesting.empty() ? "" : ", ") + s.name;
  out += "# rows = " + std::to_string(count) + ", nested " + nesting +
         " (outermost first; the last varies fastest)\n";
  out += "# method = " + plan.method +
         (chain ? (plan.solver == ChainSolver::qmc
                       ? " (qmc: 65536 points x 16 shifts, seed 1, 3-sigma error bars)"
                       : " (torus-trapezoid, tolerance 1e-13)")
                : "") +
         ", digits = " + std::to_string(plan.digits) + "\n";
  out += "# pendavg " PENDAVG_VERSION ", generated " + utc_now() + " (UTC)\n";
  std::vector<std::string> header = case_columns(n);
  for (const std::string_view stem :
       {std::string_view("beta_K"), std::string_view("error_K"), std::string_view(""),
        std::string_view("cos_phi"), std::string_view("var_K"),
        std::string_view("diagonal_approx")}) {
    if (stem.empty()) { header.push_back("ratio"); continue; }
    if (stem == "diagonal_approx" && !chain) continue;
    const auto names = indexed_names(stem, n);
    header.insert(header.end(), names.begin(), names.end());
  }
  header.insert(header.end(), {"method", "evaluations", "converged"});
  append_csv_line(out, header);

  const auto compute = [&]<class Real>() {
    for (const std::string& row : table_rows<Real>(points, plan)) out += row;
    return std::string();
  };
  if (plan.digits == min_digits) {
    compute.template operator()<double>();
  } else {
    const working_precision guard(plan.digits + guard_digits);
    compute.template operator()<mpfr_real>();
  }
  if (output.empty()) return out;
  write_atomically(output, out, "table");
  return {};
}

}  // namespace pendavg::cli
