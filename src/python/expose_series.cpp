// SPDX-License-Identifier: GPL-3.0-or-later
// src/python/expose_series.cpp -- pendavg.series: the paper's series for beta<K_1> term by term
// (eq. ave-K1-result; pendavg/series.hpp), as `pendavg series` computes it (src/cli/commands.cpp,
// series_command): always in MPFR at digits + guard digits, whatever the digits.
#include "bindings.hpp"
#include "exact.hpp"
#include "inputs.hpp"
#include "parallel.hpp"

#include "cli/format.hpp"

#include "pendavg/mpfr.hpp"
#include "pendavg/pendavg.hpp"

#include <pybind11/numpy.h>
#include <pybind11/stl.h>

#include <array>
#include <atomic>
#include <string>
#include <vector>

namespace pendavg::python {

namespace {

using cli::Domain;

constexpr std::array<const char*, 6> series_fields{"R_n",         "term",  "numerator",
                                                   "denominator", "value", "bound"};

/// Everything of the rows that outlives the working precision.
struct SeriesTable {
  std::vector<std::int64_t> n;
  std::array<std::vector<double>, 6> values;
  std::array<std::vector<std::string>, 6> text;
  std::array<std::vector<ExactNumber>, 6> exact;
  bool certified = false;
  std::size_t particles = 0;
};

py::dict series(py::handle masses, py::handle lengths, py::handle beta, py::handle g,
                py::handle digits, py::handle terms, const py::object& progress) {
  const int d = digits_option(digits);
  const auto term_count = static_cast<std::size_t>(
      cli::parse_integer(number_text(terms, "--terms"), "--terms", 0, static_cast<long>(max_series_terms)));
  std::vector<std::string> mass_texts, length_texts;
  for (const py::object& x : entries(masses)) mass_texts.push_back(number_text(x, "--masses"));
  for (const py::object& x : entries(lengths)) length_texts.push_back(number_text(x, "--lengths"));
  const std::string g_text = number_text(g, "--g"), beta_text = number_text(beta, "--beta");
  SeriesTable table;
  // The Bessel table reports its progress and stops on Ctrl-C (RunControl; no row exists before
  // it is complete, so a stop raises KeyboardInterrupt).
  std::atomic<bool> stop{false};
  std::atomic<double> fraction{0};
  RunControl control;
  control.stop = &stop;
  control.progress = [&](double f) { fraction.store(f); };
  run_interruptible([&] {
    const working_precision precision(d + guard_digits);
    std::vector<mpfr_real> m, l;
    for (const std::string& x : mass_texts)
      m.push_back(cli::parse_real<mpfr_real>(x, "--masses", Domain::positive));
    for (const std::string& x : length_texts)
      l.push_back(cli::parse_real<mpfr_real>(x, "--lengths", Domain::positive));
    mpfr_real gravity = cli::parse_real<mpfr_real>(g_text, "--g", Domain::nonnegative);
    if (m.size() != l.size())
      throw cli::usage_error(std::to_string(m.size()) + " masses but " + std::to_string(l.size()) +
                             " lengths");
    const Chain<mpfr_real> chain(std::move(m), std::move(l), std::move(gravity));
    table.particles = chain.size();
    const mpfr_real b = cli::parse_real<mpfr_real>(beta_text, "--beta", Domain::positive);
    const auto rows = series_convergence(chain, b, d, term_count, control);
    for (const SeriesRow<mpfr_real>& row : rows) {
      table.n.push_back(static_cast<std::int64_t>(row.n));
      const std::array<const mpfr_real*, 6> fields{&row.R_n,         &row.term,
                                                   &row.numerator,   &row.denominator,
                                                   &row.beta_kinetic1, &row.bound};
      for (std::size_t f = 0; f < fields.size(); ++f) {
        table.values[f].push_back(static_cast<double>(*fields[f]));
        table.text[f].push_back(cli::decimal(*fields[f], d));
        table.exact[f].push_back(exact_number(*fields[f]));
      }
    }
    // As the CLI: the last bound is at most 10^-digits relative to its value.
    table.certified = !rows.empty() && rows.back().bound <= abs(rows.back().beta_kinetic1) *
                                                                 pow(mpfr_real(10), -d);
  }, stop, fraction, progress);
  // No NaN or infinity reaches Python (ValueError, one line).
  for (std::size_t f = 0; f < series_fields.size(); ++f)
    for (std::size_t k = 0; k < table.exact[f].size(); ++k)
      if (!table.exact[f][k].finite)
        throw invalid_input(std::string("series: the result is not finite (") + series_fields[f] +
                            " of term " + std::to_string(k) + "): the series cannot be evaluated "
                            "for this chain");
  py::dict out;
  out["N"] = table.particles;
  out["digits"] = d;
  out["n"] = py::array_t<std::int64_t>(static_cast<py::ssize_t>(table.n.size()), table.n.data());
  py::dict decimal, exact;
  for (std::size_t f = 0; f < series_fields.size(); ++f) {
    out[series_fields[f]] = py::array_t<double>(static_cast<py::ssize_t>(table.values[f].size()),
                                                table.values[f].data());
    decimal[series_fields[f]] = py::cast(table.text[f]);
    py::list values;
    for (const ExactNumber& x : table.exact[f]) {
      if (x.finite) values.append(py::make_tuple(x.mantissa, x.exponent));
      else values.append(py::float_(x.rounded));
    }
    exact[series_fields[f]] = values;
  }
  out["decimal"] = decimal;
  out["exact"] = exact;
  out["certified"] = table.certified;
  out["terms"] = table.n.size();
  out["error_kind"] = error_kind_name(ErrorKind::bound);
  return out;
}

}  // namespace

void expose_series(py::module_& m) {
  using namespace pybind11::literals;
  m.def("series", &series, "masses"_a, "lengths"_a, "beta"_a, "g"_a, "digits"_a, "terms"_a,
        "progress"_a,
        "The paper's series term by term as a dict of arrays (see pendavg.series).");
}

}  // namespace pendavg::python
