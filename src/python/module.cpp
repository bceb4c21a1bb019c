// SPDX-License-Identifier: GPL-3.0-or-later
// src/python/module.cpp -- the extension module pendavg._pendavg. Bad input is a
// pendavg::invalid_input (a std::invalid_argument), raised as ValueError with the library's or
// the CLI's one-line message (a long quoted text in it shortened: abbreviated); a Python
// argument of the wrong type is a TypeError naming the argument (inputs.hpp);
// pendavg::interrupted (a run stopped on Ctrl-C before it finished anything) is
// KeyboardInterrupt; any other C++ exception becomes a Python exception too (RuntimeError,
// MemoryError), never a crash.
#include "bindings.hpp"
#include "inputs.hpp"
#include "table_result.hpp"

#include "io/exact_decimal.hpp"
#include "io/migration.hpp"
#include "io/parse.hpp"
#include "io/results.hpp"

#include "pendavg/mpfr.hpp"
#include "pendavg/result.hpp"
#include "pendavg/version.hpp"

#include <stdexcept>
#include <string>
#include <vector>

PYBIND11_MODULE(_pendavg, m) {
  m.doc() = "pendavg's C++ core; use the package pendavg (its __init__ documents the API).";
  m.attr("__version__") = pendavg::version();
  // Messages name Python's arguments: "(use digits > 16)", as "beta: '0' must be > 0".
  pendavg::io::set_digits_option_name("digits");
  // A run stopped on Ctrl-C before it finished anything it could report (RunControl).
  pybind11::register_exception_translator([](std::exception_ptr error) {
    try {
      if (error) std::rethrow_exception(error);
    } catch (const pendavg::interrupted& stopped) {
      PyErr_SetString(PyExc_KeyboardInterrupt, stopped.what());
    } catch (const std::invalid_argument& bad) {  // pendavg::invalid_input, io::bad_input
      PyErr_SetString(PyExc_ValueError, pendavg::python::abbreviated(bad.what()).c_str());
    }
  });
  // The decimal text a number is read as (pendavg.sweep forms m2 = 1 - mu1 from it).
  m.def("number_text", [](pybind11::handle x, const std::string& what) {
    return pendavg::python::number_text(x, what);
  });
  // A number checked as the CLI checks it at `digits` (pendavg.sweep checks every value of an
  // axis under the axis's own name before the grid runs).
  m.def("check_number", [](pybind11::handle x, const std::string& what, const std::string& domain,
                           pybind11::handle digits) {
    using pendavg::io::Domain;
    const int d = pendavg::python::digits_option(digits);
    const Domain kind = domain == "positive"      ? Domain::positive
                        : domain == "nonnegative" ? Domain::nonnegative
                                                  : Domain::any;
    if (d == pendavg::min_digits) {
      pendavg::python::number_double(x, what, kind);
      return;
    }
    const std::string text = pendavg::python::number_text(x, what);
    const pendavg::working_precision precision(d + pendavg::guard_digits);
    pendavg::io::parse_real<pendavg::mpfr_real>(text, what, kind);
  });
  // 1 - x as an exact decimal (pendavg.sweep's m2 = 1 - mu1, as `pendavg table` forms it).
  m.def("one_minus_decimal", [](const std::string& x, const std::string& what) {
    return pendavg::io::one_minus_decimal(x, what);
  });
  // Every field table of the output schema (io::all_tables): {table: [(name, kind,
  // per_particle, meaning)]}, what the result classes are generated from.
  m.def("tables", [] {
    pybind11::dict out;
    for (const pendavg::io::NamedTable& t : pendavg::io::all_tables()) {
      pybind11::list fields;
      for (const pendavg::io::Field& f : t.fields) {
        fields.append(pybind11::make_tuple(std::string(f.name), pendavg::python::kind_name(f.kind),
                                           f.shape == pendavg::io::Shape::per_particle,
                                           std::string(f.meaning)));
      }
      out[std::string(t.result).c_str()] = fields;
    }
    return out;
  });
  // The names of schema 0 that schema 1 renamed (src/io/migration.cpp): (old, new,
  // per_particle, python, where) tuples; `python`: the result class of pendavg 0.2 that had the
  // old name as an attribute ('' none; the package keeps it there as a deprecated alias).
  m.def("renames", [] {
    pybind11::list out;
    for (const pendavg::io::Rename& r : pendavg::io::schema0_renames())
      out.append(pybind11::make_tuple(std::string(r.old_name), std::string(r.new_name),
                                      r.per_particle, std::string(r.python),
                                      std::string(r.where)));
    return out;
  });
  pendavg::python::expose_table_result(m);  // (the result classes' base, registered first)
  pendavg::python::expose_average(m);
  pendavg::python::expose_series(m);
  pendavg::python::expose_microcanonical(m);
  pendavg::python::expose_dynamics(m);
}
