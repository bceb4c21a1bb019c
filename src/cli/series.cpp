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
#include <cstdlib>
#include <cstring>
#include <ctime>
#include <optional>
#include <span>
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
    "                      [--terms N] [--format csv|json|text] [--output FILE]\n"
    "\n"
    "The paper's series for beta<K1>, term by term, in MPFR at D digits (default 16) with the\n"
    "rigorous truncation bound. --terms 0 (default) sums until the bound certifies the requested\n"
    "digits.\n"
    "Output (schema 1, README: Output schema): the run -- N, digits, beta, g, m, l, terms,\n"
    "certified (the last bound certifies D digits), beta_K1_error_kind (bound), seconds -- and\n"
    "one record per term: n, R_n, term, numerator, denominator (the scaled partial sums), beta_K1\n"
    "(beta<K1> summed to term n) and beta_K1_error (its truncation bound, 3 digits rounded up;\n"
    "empty/null while no bound exists yet). CSV (default): a '# schema: 1' line, a\n"
    "'# pendavg series' line, the header, one row per term (the run's columns first, the same\n"
    "on every row); JSON: the run's keys and \"rows\": an array of the terms; text: the run,\n"
    "then the terms as a table. --output FILE writes it atomically (nothing on stdout).\n"
    "Numbers: with --digits D > 16 decimal strings of D digits (inputs as written); at 16 digits\n"
    "the values rounded to double (JSON numbers, the shortest text that reads back as the same\n"
    "double; each bound enlarged by its value's rounding), unless a value or input leaves\n"
    "double's normal range -- then every number is a 16-digit decimal string, as in MPFR runs.\n";

/// The inputs of a 16-digit run whose numbers fit a double: the decimals as written read as
/// doubles (JSON prints those doubles, CSV and text the text as written).
void append_double_inputs(io::Record& record, std::span<const std::string_view> texts,
                          std::size_t n) {
  const auto read = [](std::string_view text) { return std::strtod(std::string(text).c_str(), nullptr); };
  std::vector<double> masses, lengths;
  for (std::size_t i = 0; i < n; ++i) {
    masses.push_back(read(texts[2 + i]));
    lengths.push_back(read(texts[2 + n + i]));
  }
  const Chain<double> chain(std::move(masses), std::move(lengths), read(texts[1]));
  io::append_canonical_inputs(record, chain, read(texts[0]), io::Printing{}, texts);
}

std::string run_series(const Options& options) {
  const int digits = parse_digits(options.get("digits", "16"));
  const Format format = format_option(options, "csv", all_formats);
  const auto terms = static_cast<std::size_t>(
      parse_integer(options.get("terms", "0"), "--terms", 0, static_cast<long>(max_series_terms)));
  check_output_option(options, "series");
  const working_precision guard(digits + guard_digits);
  const std::string_view beta_text = options.required("beta");
  const Chain<mpfr_real> chain = chain_option<mpfr_real>(options, true);
  const mpfr_real beta = parse_real<mpfr_real>(beta_text, "--beta", Domain::positive);
  input_checked("series");
  const Stopwatch stopwatch;
  Progress progress("series");
  StopOnSignal signals;
  RunControl control;
  control.progress = [&](double fraction) { progress(fraction, "Bessel table "); };
  control.stop = &stop_flag();
  const auto rows = series_convergence(chain, beta, digits, terms, control);
  const bool certified = io::series_certifies(rows, digits);
  const double seconds = stopwatch.seconds();

  const io::Printing printing{digits};
  const bool doubles = printing.in_double() && io::series_fits_double(rows, chain, beta);
  const auto texts = input_texts(options, "beta", chain.size());
  io::Record inputs(io::canonical_input_fields(), chain.size());
  if (doubles) append_double_inputs(inputs, texts, chain.size());
  else io::append_canonical_inputs(inputs, chain, beta, printing, texts);
  io::Record run(io::series_run_fields(), chain.size());
  io::append_series_run(run, rows.size(), certified);
  const io::ListReport report{
      "series",
      {&inputs, &run},
      "rows",
      io::series_row_fields(),
      rows.size(),
      [&](std::size_t k, io::Record& row) {
        io::append_series_row(row, rows[k], printing, doubles);
      },
      seconds};
  return deliver(options, "series", io::format_list_report(report, format));
}

}  // namespace

constexpr std::array<std::string_view, 8> series_options{
    "masses", "lengths", "g", "beta", "digits", "terms", "format", "output"};
const Command series_command{"series", series_usage, series_options, run_series};

}  // namespace pendavg::cli
