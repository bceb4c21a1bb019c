// SPDX-License-Identifier: GPL-3.0-or-later
// src/cli/limit.cpp -- `pendavg limit`: the beta -> 0 and beta -> infinity limits of a chain.
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

constexpr std::string_view limit_usage =
    "usage: pendavg limit --masses M1,...,MN [--lengths L1,...,LN] [--g G] [--digits D]\n"
    "                     [--certified] [--format json|csv|text] [--output FILE]\n"
    "\n"
    "The high-temperature (beta -> 0) and low-temperature (beta -> infinity) limits of\n"
    "beta<K_i>, their error estimates, <K1>/<K2> and beta^2 Var K_i. Lengths default to 1.\n"
    "N = 2: the paper's elliptic K/E formula. Any N: beta -> 0 is the torus average of the chain\n"
    "at g = 0 (tensor trapezoid for N <= 5, transfer beyond, double only);\n"
    "beta -> infinity is exact: beta<K_i> = 1/2, beta^2 Var K_i = tr(X_i(0)^2)/2.\n"
    "--certified (N = 2): beta -> 0 in ball arithmetic, every error a proven bound (as for\n"
    "`pendavg average`).\n"
    "Output (--format csv, the default; json; text; --output FILE): the inputs N, digits, g, m,\n"
    "l, then per limit the fields of `pendavg average` (K and var_K empty: no finite beta;\n"
    "beta2_var_K = beta^2 Var K_i is finite): CSV one row per limit, its first column `limit`\n"
    "(high_temperature, low_temperature); JSON one object per limit under those keys, each with\n"
    "its run; seconds for both. `pendavg help schema` explains every field.\n";

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
  const io::Printing printing{digits};
  io::Record inputs(io::chain_input_fields(), chain.size());
  io::append_chain_inputs(inputs, chain, printing, input_texts(options, "", chain.size()));
  io::Record high(io::averages_fields(), chain.size()), low(io::averages_fields(), chain.size());
  io::append_averages(high, high_values, no_beta, printing);
  io::append_averages(low, low_values, no_beta, printing);
  const io::Report report{"limit",
                          {&inputs},
                          {{"high_temperature", {&high}, run_json(high_values)},
                           {"low_temperature", {&low}, run_json(low_values)}},
                          "limit",
                          high_seconds + low_seconds};
  return io::format_report(report, format);
}

std::string run_limit(const Options& options) {
  const int digits = parse_digits(options.get("digits", "16"));
  const Format format = format_option(options, "csv", all_formats);
  check_output_option(options, "limit");
  return deliver(options, "limit", with_number_type(digits, [&]<class Real>() {
                   return limit_report<Real>(options, digits, format);
                 }));
}

}  // namespace

constexpr std::array<std::string_view, 1> limit_flags{"certified"};
constexpr std::array<std::string_view, 6> limit_options{"masses", "lengths", "g", "digits",
                                                        "format", "output"};
const Command limit_command{"limit", limit_usage, limit_options, run_limit, limit_flags};

}  // namespace pendavg::cli
