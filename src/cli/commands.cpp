// src/cli/commands.cpp -- the pendavg commands: options -> Chain<Real> and beta -> library call ->
// formatted string. `digits` == 16 runs in double, more digits in MPFR under a working_precision
// guard that is installed before any number is parsed.
#include "commands.hpp"

#include "args.hpp"
#include "format.hpp"

#include "pendavg/double_pendulum.hpp"

#include <algorithm>
#include <array>
#include <chrono>
#include <exception>
#include <utility>
#include <vector>

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
    "  pendavg average --masses M1,M2 --lengths L1,L2 [--g G] --beta B [options]\n"
    "  pendavg average --cases FILE.csv [--digits D] [--method M]\n"
    "  pendavg limit   --masses M1,M2 [--lengths L1,L2] [--g G] [--digits D] [--format F]\n"
    "  pendavg series  --masses M1,M2 --lengths L1,L2 [--g G] --beta B [--terms N] [options]\n"
    "  pendavg help [COMMAND]     pendavg COMMAND --help     pendavg --version\n"
    "\n"
    "Numbers are plain decimals (0.5, 1e-3). --digits D (16..1000, default 16) is the number of\n"
    "significant digits requested: 16 runs in double, more in MPFR. Bad input exits with 2.\n";

constexpr std::string_view average_usage =
    "usage: pendavg average --masses M1,M2 --lengths L1,L2 [--g G] --beta B\n"
    "                       [--digits D] [--method auto|series|integral] [--format json|csv|text]\n"
    "       pendavg average --cases FILE.csv [--digits D] [--method auto|series|integral]\n"
    "\n"
    "Thermal averages of the double pendulum (N = 2) at inverse temperature B, gravity G\n"
    "(default 1). Output (default json): N, beta, digits, method, beta_K, K, error, ratio,\n"
    "cos_phi, var_K, evaluations, seconds, converged.\n"
    "--cases reads a CSV with the columns beta,g,m1,m2,l1,l2 (any order; blank lines and lines\n"
    "starting with # are skipped) and writes one CSV row per case: the input columns, then\n"
    "beta_K1,beta_K2,error_K1,error_K2,ratio,cos_phi1,cos_phi2,method,evaluations.\n";

constexpr std::string_view limit_usage =
    "usage: pendavg limit --masses M1,M2 [--lengths L1,L2] [--g G] [--digits D]\n"
    "                     [--format json|text]\n"
    "\n"
    "The high-temperature (beta -> 0) and low-temperature (beta -> infinity) limits of\n"
    "beta<K_i>, their error estimates, <K1>/<K2> and beta^2 Var K_i. Lengths default to 1.\n";

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

Engine method_option(const Options& options) {
  constexpr std::array<std::string_view, 3> names{"auto", "series", "integral"};
  constexpr std::array<Engine, 3> engines{Engine::automatic, Engine::series, Engine::integral};
  return engines[parse_choice(options.get("method", "auto"), "method", names)];
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

// ---------------------------------------------------------------- average

struct AverageReport {
  std::size_t particles;
  std::string_view beta;
  int digits;
  AveragesText values;
  double seconds;
};

std::string average_json(const AverageReport& r) {
  return JsonObject()
             .integer("N", static_cast<long long>(r.particles))
             .string("beta", r.beta)
             .integer("digits", r.digits)
             .string("method", r.values.method)
             .strings("beta_K", r.values.beta_kinetic)
             .strings("K", r.values.kinetic)
             .strings("error", r.values.error)
             .string("ratio", r.values.ratio)
             .strings("cos_phi", r.values.cos_angle)
             .strings("var_K", r.values.variance)
             .integer("evaluations", static_cast<long long>(r.values.evaluations))
             .raw("seconds", seconds_text(r.seconds))
             .boolean("converged", r.values.converged)
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
  add("ratio", r.values.ratio);
  add_array("cos_phi", r.values.cos_angle);
  add_array("var_K", r.values.variance);
  add("evaluations", std::to_string(r.values.evaluations));
  add("seconds", seconds_text(r.seconds));
  add("converged", r.values.converged ? "true" : "false");
  std::string out;
  append_csv_line(out, header);
  append_csv_line(out, row);
  return out;
}

std::string average_text(const AverageReport& r) {
  std::vector<std::vector<std::string>> table{
      {"i", "beta<K_i>", "error", "<K_i>", "<cos phi_i>", "Var K_i"}};
  for (std::size_t i = 0; i < r.values.beta_kinetic.size(); ++i)
    table.push_back({std::to_string(i + 1), r.values.beta_kinetic[i], r.values.error[i],
                     r.values.kinetic[i], r.values.cos_angle[i], r.values.variance[i]});
  return "N = " + std::to_string(r.particles) + ", beta = " + std::string(r.beta) +
         ", digits = " + std::to_string(r.digits) + ", method = " + r.values.method + "\n" +
         aligned_table(table) + "<K1>/<K2> = " + r.values.ratio + "\n" +
         "evaluations = " + std::to_string(r.values.evaluations) +
         ", seconds = " + seconds_text(r.seconds) +
         ", converged = " + (r.values.converged ? "yes" : "no") + "\n";
}

template <class Real>
std::string average_one(const Options& options, int digits, Engine engine, Format format) {
  const std::string_view beta_text = options.required("beta");
  const Chain<Real> chain = chain_option<Real>(options, true);
  if (chain.size() != 2) throw usage_error("average: only N = 2 is supported so far");
  const Real beta = parse_real<Real>(beta_text, "--beta", Domain::positive);
  const Stopwatch stopwatch;
  const Averages<Real> averages = pendavg::average(chain, beta, digits, engine);
  const double seconds = stopwatch.seconds();
  const AverageReport report{chain.size(), beta_text, digits,
                             averages_text(averages, digits, &beta), seconds};
  switch (format) {
    case Format::csv: return average_csv(report);
    case Format::text: return average_text(report);
    case Format::json: break;
  }
  return average_json(report);
}

/// One output row of `average --cases`: the input fields as written, then the averages.
template <class Real>
void append_case(std::string& out, const CaseRow& row, int digits, Engine engine) {
  const auto& [beta_text, g, m1, m2, l1, l2] = row.fields;
  const Real beta = parse_real<Real>(beta_text, "beta", Domain::positive);
  const Chain<Real> chain = make_chain<Real>(
      {parse_real<Real>(m1, "m1", Domain::positive), parse_real<Real>(m2, "m2", Domain::positive)},
      {parse_real<Real>(l1, "l1", Domain::positive), parse_real<Real>(l2, "l2", Domain::positive)},
      parse_real<Real>(g, "g", Domain::nonnegative));
  const Averages<Real> averages = pendavg::average(chain, beta, digits, engine);
  for (const std::string& field : row.fields) (out += field) += ',';
  append_csv_values(out, averages.beta_kinetic, digits);
  append_csv_values(out, averages.beta_kinetic_error, error_digits);
  append_decimal(out, averages.ratio, digits);
  out += ',';
  append_csv_values(out, averages.cos_angle, digits);
  ((out += method_name(averages.method)) += ',') += std::to_string(averages.evaluations);
  out += '\n';
}

/// Rows are independent: they are evaluated on all cores in blocks, each block into its own
/// string, and joined in file order. The first bad row (in file order) is reported.
template <class Real>
std::string average_cases(const std::vector<CaseRow>& rows, const std::string& path, int digits,
                          Engine engine) {
  std::string out;
  for (const std::string_view column : case_columns) (out += column) += ',';
  out += "beta_K1,beta_K2,error_K1,error_K2,ratio,cos_phi1,cos_phi2,method,evaluations\n";
  constexpr std::size_t block = 256;
  const std::size_t blocks = (rows.size() + block - 1) / block;
  std::vector<std::string> texts(blocks);
  std::vector<std::exception_ptr> errors(blocks);  // exceptions must not leave the region
  std::vector<std::size_t> error_row(blocks, rows.size());
#pragma omp parallel for schedule(dynamic, 1)
  for (long b = 0; b < static_cast<long>(blocks); ++b) {
    const std::size_t first = static_cast<std::size_t>(b) * block;
    const std::size_t last = std::min(rows.size(), first + block);
    std::string& text = texts[static_cast<std::size_t>(b)];
    text.reserve((last - first) * (8 * static_cast<std::size_t>(digits) + 120));
    for (std::size_t i = first; i < last; ++i) {
      try {
        append_case<Real>(text, rows[i], digits, engine);
      } catch (...) {
        errors[static_cast<std::size_t>(b)] = std::current_exception();
        error_row[static_cast<std::size_t>(b)] = i;
        break;
      }
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
  std::size_t size = out.size();
  for (const auto& text : texts) size += text.size();
  out.reserve(size);
  for (const auto& text : texts) out += text;
  return out;
}

std::string average_command(const Options& options) {
  const int digits = digits_option(options);
  const Engine engine = method_option(options);
  if (!options.has("cases")) {
    constexpr std::array<std::string_view, 3> formats{"json", "csv", "text"};
    const Format format = format_option(options, "json", formats);
    return with_number_type(digits, [&]<class Real>() {
      return average_one<Real>(options, digits, engine, format);
    });
  }
  for (const std::string_view single : {"masses", "lengths", "g", "beta"})
    if (options.has(single))
      throw usage_error("average: --cases cannot be combined with --" + std::string(single));
  constexpr std::array<std::string_view, 1> formats{"csv"};
  format_option(options, "csv", formats);
  const std::string path(options.required("cases"));
  const std::vector<CaseRow> rows = read_cases_file(path);
  return with_number_type(digits, [&]<class Real>() {
    return average_cases<Real>(rows, path, digits, engine);
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
  const AveragesText high = averages_text(high_temperature_limit(chain, digits), digits,
                                          static_cast<const Real*>(nullptr));
  const AveragesText low =
      averages_text(low_temperature_limit(chain), digits, static_cast<const Real*>(nullptr));
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
};

constexpr std::array<std::string_view, 8> average_options{
    "masses", "lengths", "g", "beta", "digits", "method", "format", "cases"};
constexpr std::array<std::string_view, 5> limit_options{"masses", "lengths", "g", "digits",
                                                        "format"};
constexpr std::array<std::string_view, 7> series_options{"masses", "lengths", "g",     "beta",
                                                         "digits", "terms",   "format"};

constexpr std::array<Command, 3> commands{{
    {"average", average_usage, average_options, average_command},
    {"limit", limit_usage, limit_options, limit_command},
    {"series", series_usage, series_options, series_command},
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
  return command.run(Options(name, rest, command.options));
}

}  // namespace pendavg::cli
