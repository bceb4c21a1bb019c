// src/python/inputs.cpp -- see inputs.hpp.
#include "inputs.hpp"

#include "cli/average_options.hpp"

#include <pybind11/numpy.h>

#include <array>
#include <cmath>

namespace pendavg::python {

namespace {

/// repr(float): the shortest decimal that round-trips v ('0.1', '1e-05', '1.0', 'inf').
std::string float_repr(double v) {
  char* text = PyOS_double_to_string(v, 'r', 0, Py_DTSF_ADD_DOT_0, nullptr);
  if (!text) throw py::error_already_set();
  std::string out(text);
  PyMem_Free(text);
  return out;
}

bool is_type(py::handle x, const char* module_prefix, const char* name) {
  const py::handle type = reinterpret_cast<PyObject*>(Py_TYPE(x.ptr()));
  const std::string module = py::str(type.attr("__module__"));
  return module.rfind(module_prefix, 0) == 0 && std::string(py::str(type.attr("__name__"))) == name;
}

/// An mpmath.mpf's exact binary value as a decimal literal: (-1)^sign man * 2^exp = (-1)^sign
/// man * 5^-exp e exp, from its raw tuple _mpf_ = (sign, man, exp, bitcount) (mpf.man_exp holds
/// |man| only).
std::string mpf_text(py::handle x) {
  const py::tuple raw = x.attr("_mpf_");
  const bool negative = raw[0].cast<int>() != 0;
  const py::int_ man = raw[1];
  const py::int_ exponent = raw[2];
  const long e = exponent.cast<long>();
  if (man.cast<py::object>().equal(py::int_(0)) && e != 0)  // inf, nan: mpmath's specials
    return float_repr(py::float_(py::reinterpret_borrow<py::object>(x)).cast<double>());
  const std::string sign = negative ? "-" : "";
  if (e >= 0) return sign + std::string(py::str(man.attr("__lshift__")(exponent)));
  const py::object scaled = man * py::module_::import("builtins").attr("pow")(py::int_(5), -e);
  return sign + std::string(py::str(scaled)) + "e-" + std::to_string(-e);
}

}  // namespace

std::string number_text(py::handle x) {
  if (PyUnicode_Check(x.ptr())) return x.cast<std::string>();
  if (PyFloat_Check(x.ptr())) return float_repr(PyFloat_AS_DOUBLE(x.ptr()));
  if (PyLong_Check(x.ptr())) return py::str(x);  // bool too: 'True' is not a number
  if (is_type(x, "mpmath", "mpf")) return mpf_text(x);
  if (is_type(x, "decimal", "Decimal")) return py::str(x);
  if (PyIndex_Check(x.ptr())) return py::str(py::reinterpret_steal<py::object>(PyNumber_Index(x.ptr())));
  if (py::isinstance<py::array>(x) && py::reinterpret_borrow<py::array>(x).ndim() == 0)
    return number_text(x.attr("item")());
  return float_repr(py::float_(py::reinterpret_borrow<py::object>(x)).cast<double>());
}

double number_double(py::handle x, std::string_view what, cli::Domain domain) {
  if (PyFloat_Check(x.ptr())) {
    const double v = PyFloat_AS_DOUBLE(x.ptr());
    const bool inside = domain == cli::Domain::positive      ? v > 0
                        : domain == cli::Domain::nonnegative ? v >= 0
                                                             : true;
    if (std::isfinite(v) && inside) return v;
  }
  return cli::parse_real<double>(number_text(x), what, domain);
}

bool is_array_like(py::handle x) {
  if (PyList_Check(x.ptr()) || PyTuple_Check(x.ptr()) || PyRange_Check(x.ptr())) return true;
  return py::isinstance<py::array>(x) && py::reinterpret_borrow<py::array>(x).ndim() > 0;
}

std::vector<py::object> entries(py::handle x) {
  std::vector<py::object> out;
  if (PyUnicode_Check(x.ptr()) || !is_array_like(x)) {
    out.push_back(py::reinterpret_borrow<py::object>(x));
    return out;
  }
  for (py::handle item : x) out.push_back(py::reinterpret_borrow<py::object>(item));
  return out;
}

std::string choice_text(py::handle x) { return py::str(x); }

AverageOptions average_options(py::handle digits, py::handle method, py::handle tol,
                               py::handle samples, py::handle shifts, py::handle seed) {
  const bool default_digits = PyLong_CheckExact(digits.ptr()) && digits.cast<long>() == 16;
  const bool default_method = PyUnicode_Check(method.ptr()) && method.cast<std::string>() == "auto";
  if (default_digits && default_method && tol.is_none() && samples.is_none() && shifts.is_none() &&
      seed.is_none())
    return {};
  // The CLI's own reader on the texts of the given options (--name=value: a value may start
  // with "--").
  std::vector<std::string> texts;
  const auto add = [&](const char* name, py::handle value, bool as_choice) {
    if (value.is_none()) return;
    texts.push_back(std::string("--") + name + "=" +
                    (as_choice ? choice_text(value) : number_text(value)));
  };
  add("digits", digits, false);
  add("method", method, true);
  add("tol", tol, false);
  add("samples", samples, false);
  add("shifts", shifts, false);
  add("seed", seed, false);
  const std::vector<std::string_view> args(texts.begin(), texts.end());
  const cli::Options options("average", args, cli::average_option_names);
  return cli::parse_average_options(options, cli::average_option_names);
}

int digits_option(py::handle digits) { return cli::parse_digits(number_text(digits)); }

int hardware_threads() { return cli::hardware_threads(); }

}  // namespace pendavg::python
