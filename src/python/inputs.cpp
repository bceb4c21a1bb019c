// SPDX-License-Identifier: GPL-3.0-or-later
// src/python/inputs.cpp -- see inputs.hpp.
#include "inputs.hpp"

#include <pybind11/numpy.h>

#include "pendavg/mpfr.hpp"

#include <gmp.h>
#include <mpfr.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <optional>

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

std::string type_name(py::handle x) { return Py_TYPE(x.ptr())->tp_name; }

}  // namespace

std::string utf8_text(py::handle text, std::string_view what) {
  Py_ssize_t size = 0;
  const char* data = PyUnicode_AsUTF8AndSize(text.ptr(), &size);
  if (!data) {  // a lone surrogate ('\ud800') has no UTF-8
    if (!PyErr_ExceptionMatches(PyExc_UnicodeError)) throw py::error_already_set();
    PyErr_Clear();
    throw py::value_error(std::string(what) + ": the text is not valid Unicode (it holds a lone "
                          "surrogate)");
  }
  if (std::memchr(data, '\0', static_cast<std::size_t>(size)))  // would end a C string early
    throw py::value_error(std::string(what) + ": the text holds a NUL character");
  return std::string(data, static_cast<std::size_t>(size));
}

namespace {

/// "<what>: expected a number ..., got <type>" as a TypeError.
[[noreturn]] void not_a_number(py::handle x, std::string_view what) {
  throw py::type_error(std::string(what) +
                       ": expected a number (float, int, str, decimal.Decimal or mpmath.mpf), got " +
                       type_name(x));
}

/// The hex digits of a non-negative Python int, for GMP (power-of-two bases have no digit
/// limit, unlike str(int), and cost linear time).
std::string hex_digits(py::handle magnitude) {
  const py::object hex = py::reinterpret_steal<py::object>(PyNumber_ToBase(magnitude.ptr(), 16));
  if (!hex) throw py::error_already_set();
  return hex.cast<std::string>().substr(2);  // without '0x'
}

/// Longest exact decimal written for a binary number (an mpf, a huge int): beyond it (|x| below
/// about 1e-8600 or above 1e20000 for a 53-bit mantissa) the text is rounded, see binary_text.
constexpr double exact_text_limit = 20000;

/// The decimal text of (-1)^negative man 2^exponent, bits = bit length of man > 0.
///
/// Exactly (man * 5^-exponent 'e' exponent, or the integer man * 2^exponent) while that text has
/// at most exact_text_limit digits, which covers double's whole range (subnormals included).
/// Beyond, the exact text would be huge (2e8 digits for mpf('1e-100000000')), so the value is
/// written correctly rounded to enough significant digits that it reads back as the same binary
/// number at every working precision that holds `bits` bits (10^(n-1) > 2^max(bits, p_max)):
/// the module reads it exactly whenever the mpf fits the working precision (mpmath's default 53
/// bits always do). Binary exponents outside MPFR's range are refused: MPFR would turn them
/// into 0 or infinity.
std::string binary_text(bool negative, py::handle man, py::handle exponent_object, long bits,
                        std::string_view what) {
  int overflow = 0;
  const long long exponent = PyLong_AsLongLongAndOverflow(exponent_object.ptr(), &overflow);
  if (exponent == -1 && PyErr_Occurred()) throw py::error_already_set();
  // Binary exponent of the value: |x| in [2^(top - 1), 2^top).
  const long double top = overflow ? (overflow > 0 ? 1e30L : -1e30L)
                                   : static_cast<long double>(exponent) + bits;
  if (top > static_cast<long double>(mpfr_get_emax()) ||
      top < static_cast<long double>(mpfr_get_emin()))
    throw invalid_input(std::string(what) + ": the number's binary exponent " +
                        (overflow ? std::string(overflow > 0 ? "(over 2^63)" : "(below -2^63)")
                                  : std::to_string(static_cast<long long>(top))) +
                        " is outside the range of MPFR numbers (" +
                        std::to_string(mpfr_get_emin()) + ".." + std::to_string(mpfr_get_emax()) +
                        ")");
  const std::string sign = negative ? "-" : "";
  constexpr long double log10_2 = 0.30102999566398119521L, log10_5 = 0.69897000433601880479L;
  const long double exact_digits =
      exponent >= 0 ? (static_cast<long double>(bits) + exponent) * log10_2
                    : bits * log10_2 + static_cast<long double>(-exponent) * log10_5;
  const std::string hex = hex_digits(man);  // (Python work first: nothing to free if it fails)
  mpz_t z;
  mpz_init_set_str(z, hex.c_str(), 16);
  const auto release = [](char* text) {
    void (*free_function)(void*, size_t) = nullptr;
    mp_get_memory_functions(nullptr, nullptr, &free_function);
    free_function(text, std::strlen(text) + 1);
  };
  std::string out;
  if (exact_digits <= exact_text_limit) {
    if (exponent >= 0) {
      mpz_mul_2exp(z, z, static_cast<mp_bitcnt_t>(exponent));
    } else {
      mpz_t five;
      mpz_init(five);
      mpz_ui_pow_ui(five, 5, static_cast<unsigned long>(-exponent));
      mpz_mul(z, z, five);
      mpz_clear(five);
    }
    char* digits = mpz_get_str(nullptr, 10, z);
    out = sign + digits + (exponent < 0 ? "e" + std::to_string(exponent) : std::string());
    release(digits);
  } else {
    // Significant digits that identify a binary number of max(bits, p_max) bits, p_max the
    // precision of the largest working precision (max_digits + guard_digits).
    const long p_max = static_cast<long>(
        boost::multiprecision::detail::digits10_2_2(max_digits + guard_digits));
    const long significant =
        static_cast<long>(std::ceil(static_cast<long double>(std::max(bits, p_max)) * log10_2)) + 2;
    mpfr_t value;
    mpfr_init2(value, std::max<long>(bits, MPFR_PREC_MIN));
    mpfr_set_z_2exp(value, z, static_cast<mpfr_exp_t>(exponent), MPFR_RNDN);  // exact
    mpfr_exp_t decimal_exponent = 0;
    // mpfr_get_str writes plain digits (no radix character, whatever the locale).
    char* digits = mpfr_get_str(nullptr, &decimal_exponent, 10, static_cast<size_t>(significant),
                                value, MPFR_RNDN);
    // value = 0.DIGITS * 10^decimal_exponent = DIGITS * 10^(decimal_exponent - significant)
    out = sign + digits + "e" +
          std::to_string(static_cast<long long>(decimal_exponent) - significant);
    mpfr_free_str(digits);
    mpfr_clear(value);
  }
  mpz_clear(z);
  return out;
}

/// An mpmath.mpf's value as a decimal literal, from its raw tuple _mpf_ = (sign, man, exp,
/// bitcount) (mpf.man_exp holds |man| only): see binary_text.
std::string mpf_text(py::handle x, std::string_view what) {
  const py::tuple raw = x.attr("_mpf_");
  const bool negative = PyObject_IsTrue(raw[0].ptr()) == 1;
  const py::object man = raw[1], exponent = raw[2], bits = raw[3];
  if (!PyObject_IsTrue(man.ptr())) {  // zero, or mpmath's specials inf, -inf, nan
    if (!PyObject_IsTrue(exponent.ptr())) return negative ? "-0" : "0";
    return float_repr(py::float_(py::reinterpret_borrow<py::object>(x)).cast<double>());
  }
  int overflow = 0;
  const long bit_length = PyLong_AsLongAndOverflow(bits.ptr(), &overflow);
  if (overflow || bit_length <= 0) not_a_number(x, what);
  return binary_text(negative, man, exponent, bit_length, what);
}

/// An int's decimal text: str() while it is short, else binary_text (str() refuses ints of
/// over 4300 digits).
std::string integer_text(py::handle x, std::string_view what) {
  const py::int_ value = py::reinterpret_borrow<py::int_>(x);
  const long bit_length = value.attr("bit_length")().cast<long>();  // (at most ~2^60 bits)
  if (bit_length <= 10000) return std::string(py::str(py::handle(value)));
  const bool negative = PyObject_RichCompareBool(value.ptr(), py::int_(0).ptr(), Py_LT) == 1;
  const py::object magnitude = py::reinterpret_steal<py::object>(PyNumber_Absolute(value.ptr()));
  return binary_text(negative, magnitude, py::int_(0), bit_length, what);
}

}  // namespace

std::string number_text(py::handle x, std::string_view what) {
  if (PyUnicode_Check(x.ptr())) return utf8_text(x, what);
  if (PyFloat_Check(x.ptr())) return float_repr(PyFloat_AS_DOUBLE(x.ptr()));
  if (PyBool_Check(x.ptr())) not_a_number(x, what);  // True is not a number here
  if (PyLong_Check(x.ptr())) return integer_text(x, what);
  if (is_type(x, "mpmath", "mpf")) return mpf_text(x, what);
  if (is_type(x, "decimal", "Decimal")) return py::str(x);
  if (py::isinstance<py::array>(x)) {
    const py::array a = py::reinterpret_borrow<py::array>(x);
    if (a.ndim() == 0) return number_text(a.attr("item")(), what);
    not_a_number(x, what);
  }
  if (x.is_none() || PyBytes_Check(x.ptr()) || PyComplex_Check(x.ptr()))
    not_a_number(x, what);
  if (PyIndex_Check(x.ptr())) {
    const py::object index = py::reinterpret_steal<py::object>(PyNumber_Index(x.ptr()));
    if (!index) throw py::error_already_set();
    return integer_text(index, what);
  }
  // Any other real number (fractions.Fraction, numpy.float32, ...) by its float value; an
  // object float() refuses is a TypeError naming the argument (its own error chained).
  PyObject* value = PyNumber_Float(x.ptr());
  if (!value) {
    if (!PyErr_ExceptionMatches(PyExc_Exception)) throw py::error_already_set();  // Ctrl-C
    const py::error_already_set cause;
    const std::string message = std::string(what) + ": expected a real number, got " +
                                type_name(x) + " (float() failed: " + cause.what() + ")";
    PyErr_Clear();
    if (cause.matches(PyExc_OverflowError))
      throw py::value_error(std::string(what) + ": " + type_name(x) + " is out of the range of double");
    throw py::type_error(message);
  }
  const double v = PyFloat_AS_DOUBLE(value);
  Py_DECREF(value);
  return float_repr(v);
}

double number_double(py::handle x, std::string_view what, io::Domain domain) {
  if (PyFloat_Check(x.ptr())) {
    const double v = PyFloat_AS_DOUBLE(x.ptr());
    const bool inside = domain == io::Domain::positive      ? v > 0
                        : domain == io::Domain::nonnegative ? v >= 0
                                                            : true;
    if (std::isfinite(v) && inside) return v;
  }
  return io::parse_real<double>(number_text(x, what), what, domain);
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

std::string choice_text(py::handle x, std::string_view what) {
  if (!PyUnicode_Check(x.ptr()))
    throw py::type_error(std::string(what) + ": expected a str, got " + type_name(x));
  return utf8_text(x, what);
}

AverageOptions average_options(py::handle digits, py::handle method, py::handle tol,
                               py::handle samples, py::handle shifts, py::handle seed) {
  // digits and method have defaults in the Python signatures: None is not one of their values.
  if (digits.is_none()) not_a_number(digits, "digits");
  if (method.is_none()) choice_text(method, "method");
  int overflow = 0;  // (an int beyond long is no default, and is refused by digits below)
  const bool default_digits = PyLong_CheckExact(digits.ptr()) &&
                              PyLong_AsLongAndOverflow(digits.ptr(), &overflow) == 16 && !overflow;
  const bool default_method =
      PyUnicode_Check(method.ptr()) && PyUnicode_CompareWithASCIIString(method.ptr(), "auto") == 0;
  if (default_digits && default_method && tol.is_none() && samples.is_none() && shifts.is_none() &&
      seed.is_none())
    return {};
  // The front-end library's reader on the texts of the given options, named as Python names them.
  std::string texts[6];
  io::AverageOptionTexts given;
  const auto add = [&](std::optional<std::string_view>& slot, std::string& text, const char* name,
                       py::handle value, bool as_choice) {
    if (value.is_none()) return;
    text = as_choice ? choice_text(value, name) : number_text(value, name);
    slot = text;
  };
  add(given.digits, texts[0], "digits", digits, false);
  add(given.method, texts[1], "method", method, true);
  add(given.tol, texts[2], "tol", tol, false);
  add(given.samples, texts[3], "samples", samples, false);
  add(given.shifts, texts[4], "shifts", shifts, false);
  add(given.seed, texts[5], "seed", seed, false);
  return io::parse_average_options(given, "");
}

int digits_option(py::handle digits) {
  return io::parse_digits(number_text(digits, "digits"), "digits");
}

std::string abbreviated(std::string_view message) {
  constexpr std::size_t longest = 80, head = 40, tail = 16;
  std::string out;
  std::size_t k = 0;
  while (k < message.size()) {
    const std::size_t open = message.find('\'', k);
    const std::size_t close = open == std::string_view::npos ? open : message.find('\'', open + 1);
    if (close == std::string_view::npos) {
      out += message.substr(k);
      break;
    }
    const std::string_view quoted = message.substr(open + 1, close - open - 1);
    out += message.substr(k, open + 1 - k);
    if (quoted.size() <= longest) {
      out += quoted;
      out += '\'';
    } else {
      // cut between UTF-8 characters (a continuation byte is 10xxxxxx)
      const auto continuation = [&](std::size_t i) {
        return (static_cast<unsigned char>(quoted[i]) & 0xc0) == 0x80;
      };
      std::size_t head_end = head, tail_start = quoted.size() - tail;
      while (head_end > 0 && continuation(head_end)) --head_end;
      while (tail_start < quoted.size() && continuation(tail_start)) ++tail_start;
      out += quoted.substr(0, head_end);
      out += "...";
      out += quoted.substr(tail_start);
      const auto characters = std::count_if(quoted.begin(), quoted.end(), [](char c) {
        return (static_cast<unsigned char>(c) & 0xc0) != 0x80;
      });
      out += "' (" + std::to_string(characters) + " characters)";
    }
    k = close + 1;
  }
  // One line, whole: control characters of a quoted text (a newline, a NUL that would end the
  // C string) are shown escaped.
  std::string escaped;
  for (const char c : out) {
    const auto u = static_cast<unsigned char>(c);
    if (u < 0x20 || u == 0x7f) {
      constexpr char hex[] = "0123456789abcdef";
      escaped += "\\x";
      escaped += hex[u >> 4];
      escaped += hex[u & 15];
    } else {
      escaped += c;
    }
  }
  out = std::move(escaped);
  // A long text outside quotes (none of the messages has one today) is cut as well.
  if (out.size() > 1000) out = out.substr(0, 600) + " ... (" + std::to_string(out.size()) + " characters)";
  return out;
}

}  // namespace pendavg::python
