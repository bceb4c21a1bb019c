// SPDX-License-Identifier: GPL-3.0-or-later
// src/python/expose_series.cpp -- pendavg.series: the paper's series for beta<K_1> term by term
// (eq. ave-K1-result; pendavg/series.hpp), as `pendavg series` computes it (src/cli/series.cpp):
// always in MPFR at digits + guard digits, whatever the digits. The inputs, the run and each term
// are filled into the records `pendavg series` prints (io::series_run_fields,
// io::series_row_fields), from which the result's fields are made (table_result.hpp): the
// call's as single values, the terms' as arrays with one entry per term.
#include "bindings.hpp"
#include "inputs.hpp"
#include "parallel.hpp"
#include "table_result.hpp"

#include "io/results.hpp"

#include "pendavg/mpfr.hpp"
#include "pendavg/pendavg.hpp"

#include <pybind11/numpy.h>
#include <pybind11/stl.h>

#include <array>
#include <atomic>
#include <string>
#include <string_view>
#include <vector>

namespace pendavg::python {

namespace {

using io::Domain;

/// The series' own fields after its inputs, and each term's (the CLI's tables).
std::vector<ClassField> call_fields() {
  return class_fields({{io::canonical_input_fields(), true}, {io::series_run_fields(), false}});
}
std::vector<ClassField> term_fields() { return class_fields({{io::series_row_fields(), false}}); }

py::dict series(py::handle masses, py::handle lengths, py::handle beta, py::handle g,
                py::handle digits, py::handle terms, const py::object& progress) {
  const int d = digits_option(digits);
  const auto term_count = static_cast<std::size_t>(io::parse_integer(
      number_text(terms, "terms"), "terms", 0, static_cast<long>(max_series_terms)));
  std::vector<std::string> mass_texts, length_texts;
  for (const py::object& x : entries(masses)) mass_texts.push_back(number_text(x, "masses"));
  for (const py::object& x : entries(lengths)) length_texts.push_back(number_text(x, "lengths"));
  const std::string g_text = number_text(g, "g"), beta_text = number_text(beta, "beta");
  // The call (its inputs and run: one point) and the terms (a grid of one point per term).
  TableResult call, rows;
  call.digits = rows.digits = d;
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
      m.push_back(io::parse_real<mpfr_real>(x, "masses", Domain::positive));
    for (const std::string& x : length_texts)
      l.push_back(io::parse_real<mpfr_real>(x, "lengths", Domain::positive));
    mpfr_real gravity = io::parse_real<mpfr_real>(g_text, "g", Domain::nonnegative);
    if (m.size() != l.size())
      throw io::bad_input(std::to_string(m.size()) + " masses but " + std::to_string(l.size()) +
                          " lengths");
    const Chain<mpfr_real> chain(std::move(m), std::move(l), std::move(gravity));
    const mpfr_real b = io::parse_real<mpfr_real>(beta_text, "beta", Domain::positive);
    const auto taken = series_convergence(chain, b, d, term_count, control);
    // As `pendavg series` prints them: a 16-digit run whose numbers fit a double in double
    // (the inputs as written read as doubles), else decimals of `digits` digits.
    const io::Printing printing{d};
    const bool doubles = printing.in_double() && io::series_fits_double(taken, chain, b);
    const std::size_t n = chain.size();
    call.particles = rows.particles = n;
    call.layout({{io::canonical_input_fields(), true}, {io::series_run_fields(), false}}, true);
    io::Record inputs, run, term;
    for (io::Record* r : {&inputs, &run, &term}) r->keep_exact(true);
    inputs.reset(io::canonical_input_fields(), n);
    if (doubles) {
      const auto read = [](const std::string& x) {
        return io::parse_real<double>(x, "", Domain::any);  // (fits: series_fits_double)
      };
      std::vector<double> md, ld;
      for (const std::string& x : mass_texts) md.push_back(read(x));
      for (const std::string& x : length_texts) ld.push_back(read(x));
      io::append_canonical_inputs(inputs, Chain<double>(std::move(md), std::move(ld), read(g_text)),
                                  read(beta_text), io::Printing{});
    } else {
      std::vector<std::string_view> written{beta_text, g_text};
      written.insert(written.end(), mass_texts.begin(), mass_texts.end());
      written.insert(written.end(), length_texts.begin(), length_texts.end());
      io::append_canonical_inputs(inputs, chain, b, printing, written);
    }
    run.reset(io::series_run_fields(), n);
    io::append_series_run(run, taken.size(), io::series_certifies(taken, d));
    const std::array<const io::Record*, 2> call_records{&inputs, &run};
    call.store(0, call_records);
    rows.shape = {static_cast<py::ssize_t>(taken.size())};
    rows.layout({{io::series_row_fields(), false}}, true);
    for (std::size_t k = 0; k < taken.size(); ++k) {
      term.reset(io::series_row_fields(), n);
      io::append_series_row(term, taken[k], printing, doubles);
      const std::array<const io::Record*, 1> row{&term};
      rows.store(k, row);
    }
  }, stop, fraction, progress);
  // No NaN or infinity reaches Python (ValueError, one line).
  rows.require_finite("series", "the series cannot be evaluated for this chain");
  py::dict out, decimal;
  const py::dict call_decimal = call.decimal(), row_decimal = rows.decimal();
  for (const ClassField& f : call_fields()) {
    const std::string name(f.field.name);
    out[name.c_str()] = call.value(f.field.name);
    if (call_decimal.contains(name)) decimal[name.c_str()] = call_decimal[name.c_str()];
  }
  const py::object row_exact = rows.exact();
  py::dict exact;
  for (const ClassField& f : term_fields()) {
    const std::string name(f.field.name);
    out[name.c_str()] = rows.value(f.field.name);
    if (row_decimal.contains(name)) {
      decimal[name.c_str()] = row_decimal[name.c_str()].attr("tolist")();
      exact[name.c_str()] = row_exact[name.c_str()];
    }
  }
  out["decimal"] = decimal;
  out["exact"] = exact;
  return out;
}

}  // namespace

void expose_series(py::module_& m) {
  using namespace pybind11::literals;
  m.def("series", &series, "masses"_a, "lengths"_a, "beta"_a, "g"_a, "digits"_a, "terms"_a,
        "progress"_a,
        "The paper's series term by term as a dict of arrays (see pendavg.series).");
  m.def("series_fields", [] {
    return py::make_tuple(field_tuples(call_fields()), field_tuples(term_fields()));
  }, "(the series' fields, its terms' fields) as (name, kind, per_particle, meaning, input) "
     "tuples.");
}

}  // namespace pendavg::python
