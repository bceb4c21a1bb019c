// SPDX-License-Identifier: GPL-3.0-or-later
// src/python/inputs.hpp -- Python arguments as the front-end library reads a request. Every
// number becomes the decimal text a user would have typed (in double, a valid float is taken as
// it is: the same double its repr parses to) and is checked by the front-end library's parsers
// (src/io/parse.hpp, src/io/requests.hpp) under the argument's own name ("beta: '-1' must be >
// 0"), so the module accepts what the CLI accepts, refuses it with the CLI's one-line message
// spelled with Python's names (pendavg::invalid_input -> ValueError), and computes with the same
// numbers, bit for bit.
#pragma once

#include "io/parse.hpp"
#include "io/requests.hpp"

#include "pendavg/average.hpp"

#include <pybind11/pybind11.h>

#include <chrono>
#include <string>
#include <string_view>
#include <vector>

namespace pendavg::python {

namespace py = pybind11;

/// The decimal text of a Python number: a str as given; an int (or numpy integer) exactly; a
/// float by repr() (the shortest decimal that round-trips it: what was typed, so 0.1 is 1/10 at
/// any digits); a decimal.Decimal by str(); an mpmath.mpf by its binary value (exactly as
/// M*5^k e-k while that is at most 20000 digits, else rounded so that it reads back as the same
/// binary number; a binary exponent outside MPFR's range is refused); any other real number by
/// repr(float(x)). Never builds a huge integer, so every conversion is quick. Anything else
/// (None, a str-less object, a complex) is a TypeError naming `what` (e.g. "beta").
std::string number_text(py::handle x, std::string_view what);

/// A number in double, checked as io::parse_real<double> checks its text (the message names it,
/// e.g. "beta: '0.0' must be > 0").
double number_double(py::handle x, std::string_view what, io::Domain domain);

/// True for an argument holding several values: a numpy array with ndim >= 1, a list, a tuple
/// or a range.
bool is_array_like(py::handle x);

/// The entries of a list argument (masses, lengths, phi, ...): a list, tuple, range or 1-D+
/// numpy array (its first axis). A single number is one entry.
std::vector<py::object> entries(py::handle x);

/// AverageOptions read and checked by io::parse_average_options, as the CLI reads --digits,
/// --method, --tol, --samples, --shifts and --seed; None means "not given".
AverageOptions average_options(py::handle digits, py::handle method, py::handle tol,
                               py::handle samples, py::handle shifts, py::handle seed);

/// digits, read as the CLI reads --digits (an integer in 16..1000).
int digits_option(py::handle digits);

/// A str's UTF-8 text; a str that has none (a lone surrogate) or holds a NUL character is a
/// ValueError naming `what`.
std::string utf8_text(py::handle text, std::string_view what);

/// A str argument that picks one of several names (method, integrator, ...); anything but a str
/// is a TypeError naming `what`.
std::string choice_text(py::handle x, std::string_view what);

/// A message with every quoted text longer than 80 characters shortened to its first 40 and
/// last 16 characters and its length: a 1 MB number string is not echoed whole into an
/// exception (the CLI's messages quote the text they refuse).
std::string abbreviated(std::string_view message);

/// OpenMP threads available to one call (io::hardware_threads).
inline int hardware_threads() { return io::hardware_threads(); }

/// Wall time of a library call, as the CLI measures its `seconds`.
class Stopwatch {
 public:
  double seconds() const {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count();
  }

 private:
  std::chrono::steady_clock::time_point start_ = std::chrono::steady_clock::now();
};

}  // namespace pendavg::python
