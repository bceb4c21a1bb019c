// SPDX-License-Identifier: GPL-3.0-or-later
// src/cli/series.cpp -- `pendavg series`: the paper's series for beta<K1> term by term, with its bound.
#include "common.hpp"

#include "average_options.hpp"
#include "distribute.hpp"
#include "interrupt.hpp"

#include "io/record.hpp"
#include "io/report.hpp"
#include "io/results.hpp"

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

constexpr std::string_view series_usage =
    "usage: pendavg series --masses M1,M2 --lengths L1,L2 [--g G] --beta B [--digits D]\n"
    "                      [--terms N] [--format text|csv|json]\n"
    "\n"
    "The paper's series for beta<K1>, term by term, in MPFR: n, R_n, term, numerator,\n"
    "denominator, value (partial beta<K1>) and the rigorous truncation bound. --terms 0\n"
    "(default) sums until the bound certifies the requested digits.\n";

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

std::string run_series(const Options& options) {
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

}  // namespace

constexpr std::array<std::string_view, 7> series_options{"masses", "lengths", "g",     "beta",
                                                         "digits", "terms",   "format"};
const Command series_command{"series", series_usage, series_options, run_series};

}  // namespace pendavg::cli
