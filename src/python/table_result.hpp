// SPDX-License-Identifier: GPL-3.0-or-later
// src/python/table_result.hpp -- the Python result objects, generated from the field tables of
// the front-end library (src/io/results.hpp): one point's result is filled into records by the
// same builders the CLI prints from (io::append_averages, ...), and a TableResult keeps the
// cells of every point of a call in pools by kind, a row per point, read as one column per
// field. Its attributes, .decimal (the CLI's text of each number, made when asked for) and the
// exact values of an MPFR run are made from the columns by the field's kind and shape alone: no
// field is named here.
//
// Python values, per field kind: real and error -> float (one point) or a float64 array (a
// grid), per-particle fields with a last axis of N; count -> int / int64 array; flag -> bool /
// bool array; text -> str / str array. An empty cell (a limit's <K_i>, <K1>/<K2> for N = 1) is
// NaN in a number array and None alone; a field empty at every point is None. The counts among
// a call's inputs (N, digits) are the call's: one int, also for a grid.
//
// A double run's numbers are the records' doubles (the library's, or a quotient as io divides
// it; an error as computed, before printing enlarges it); an MPFR run's are the exact values
// behind its decimal cells (Record::keep_exact), rounded to double, and kept exactly for mpmath.
#pragma once

#include "io/record.hpp"

#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <initializer_list>
#include <memory>
#include <span>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

namespace pendavg::python {

namespace py = pybind11;

/// One table of a result's records, and whether it holds the call's inputs.
struct Table {
  std::span<const io::Field> fields;
  bool inputs = false;
};

/// The fields a result class has: every field of `tables` once (by name), in order; with
/// whether it is one of the call's input counts (Column::call_wide).
struct ClassField {
  io::Field field;
  bool input = false;
  bool call_wide = false;
};
std::vector<ClassField> class_fields(std::initializer_list<Table> tables);

/// One field over every point of a call: `width` cells per point (1, or N per particle). A
/// point's cells are a row of each pool (point-major: a point is stored in one sweep); the
/// column's lie at `first` in the row of its kind's pool and at `present` in the presence row.
struct Column {
  io::Field field;
  std::size_t width = 1;
  bool input = false;                ///< a field of the inputs' table
  bool call_wide = false;            ///< an input count (N, digits): the call's, not a point's
  std::size_t present = 0;
  std::size_t first = 0;
  /// an error's: the column of its value (io::value_of_error), whose printing its text covers
  std::size_t value = static_cast<std::size_t>(-1);
  bool numeric() const {
    return field.kind == io::Kind::real || field.kind == io::Kind::error;
  }
};

/// A call's result: one point (shape ()) or a grid of points (shape S), each point's records
/// kept in columns.
class TableResult {
 public:
  std::vector<py::ssize_t> shape;  ///< the broadcast shape; empty for one point
  std::size_t particles = 0;
  int digits = 16;

  bool single() const { return shape.empty(); }
  std::size_t points() const { return points_; }
  /// Point k's wall time of the library call, and whether it stopped early (an error may then be
  /// +inf: a level's bound that was never checked).
  void set_run(std::size_t k, double seconds, bool interrupted) {
    doubles_[seconds_at_ + k] = seconds;
    bytes_[interrupted_at_ + k] = interrupted ? 1 : 0;
  }
  const double* seconds() const { return doubles_.data() + seconds_at_; }

  /// Lays out the columns of `tables` (each point's records come in this order) for the points
  /// of `shape` (set before), each of `particles` particles; `mpfr`: the records hold decimal
  /// text and exact values. An empty grid keeps room for one point: store_call() fills its
  /// call-wide fields.
  void layout(std::initializer_list<Table> tables, bool mpfr);
  /// Copies point k's records (in the tables' order) into the columns. Distinct points may be
  /// stored from different threads at once, without the GIL.
  void store(std::size_t k, std::span<const io::Record* const> records);
  /// The call-wide fields of an empty grid, from records of any point of the call.
  void store_call(std::span<const io::Record* const> records);

  /// The columns, in the tables' order.
  std::span<const Column> columns() const { return columns_; }
  /// The field `name` as a Python value (None: the result has no such field).
  py::object value(std::string_view name) const;
  /// {field: its cells as the CLI prints them} for every real and error field: str (None: an
  /// empty cell), a list of them per particle; numpy arrays of shape S (+ (N,)) for a grid.
  py::dict decimal() const;
  /// MPFR runs: {field: [(mantissa hex, exponent) | float (nan, inf) | None per cell, in C order
  /// over (points, cells)]} for every real and error field; None for a double run.
  py::object exact() const;
  /// Refuses a non-finite number (ValueError, one line naming the field, the particle and the
  /// grid index): "<command>: the result is not finite (name[i] = nan ...): <reason>". An
  /// error may be +inf at an interrupted point (a level's bound that was never checked).
  void require_finite(const std::string& command, const std::string& reason) const;

 private:
  /// Where a record's cell goes: its pool, its place in a point's row of it and of presence.
  struct CellPlan {
    io::Kind kind;
    bool call_wide;
    std::uint32_t at, present;
  };
  /// The columns of some tables for N particles, and where each cell of their records goes:
  /// made once per (tables, N) and shared by every result of that shape.
  struct Layout {
    std::vector<Column> columns;
    std::vector<std::vector<CellPlan>> plans;  ///< per table: each cell of its records
    std::size_t row_present = 0, row_numbers = 0, row_integers = 0, row_flags = 0, row_texts = 0;
  };
  static std::shared_ptr<const Layout> layout_of(std::initializer_list<Table> tables,
                                                 std::size_t particles);
  std::size_t points_ = 0;
  bool mpfr_ = false;
  std::shared_ptr<const Layout> layout_;
  std::span<const Column> columns_;
  // The cells of every column, pooled by kind, a row per point (a handful of allocations per
  // call, and a point's cells stored together).
  std::size_t row_present_ = 0, row_numbers_ = 0, row_integers_ = 0, row_flags_ = 0,
              row_texts_ = 0;
  // doubles_: numbers (real, error: the double; MPFR: exact, rounded), then a double run's
  // errors' gaps (what their texts add: Cell::gap), then each point's seconds; bytes_: present
  // (0: an empty cell, every column), flags, then each point's finite (every number finite:
  // require_finite) and interrupted.
  std::vector<double> doubles_;
  std::vector<std::uint8_t> bytes_;
  std::size_t gaps_at_ = 0, seconds_at_ = 0, flags_at_ = 0, finite_at_ = 0, interrupted_at_ = 0;
  std::vector<std::string> decimals_;  ///< real, error of an MPFR run: the printed text
  std::vector<io::ExactNumber> exact_;  ///< real, error of an MPFR run
  std::vector<std::int64_t> integers_;  ///< count
  std::vector<std::string> texts_;     ///< text
  const double* numbers() const { return doubles_.data(); }
  double* numbers() { return doubles_.data(); }
  const std::uint8_t* present() const { return bytes_.data(); }
  const std::uint8_t* flags() const { return bytes_.data() + flags_at_; }
  const Column* find(std::string_view name) const;
  /// Column c's cell i of point k in the row-major pool `pool` of row length `row`.
  static std::size_t cell(const Column& c, std::size_t row, std::size_t k, std::size_t i) {
    return k * row + c.first + i;
  }
  void put(std::size_t k, std::span<const io::Record* const> records, bool call_only);
};

/// real, error, count, text or flag.
const char* kind_name(io::Kind kind);

/// "index (i, j)" of flat index k in `shape` (C order).
std::string index_text(std::size_t k, const std::vector<py::ssize_t>& shape);

/// numpy.array(items).reshape(shape)
py::object numpy_array(const py::list& items, const std::vector<py::ssize_t>& shape,
                       const char* dtype = nullptr);

/// The fields of a result class as (name, kind, per_particle, meaning, input) tuples (the
/// Python package generates its conversions and documentation from them).
py::list field_tuples(const std::vector<ClassField>& fields);

/// Registers the base class of the result classes, pendavg._pendavg._TableResult: .shape,
/// .seconds, .decimal and ._exact_values() (the Python package adds the conversions to it).
void expose_table_result(py::module_& m);

/// The result class `Result` (a TableResult) as a subclass of _TableResult: a read-only
/// property for every field (its meaning as the docstring), which returns TableResult::value;
/// `fields()` lists the class's fields (field_tuples).
template <class Result>
py::class_<Result, TableResult> table_class(py::handle scope, const char* name, const char* doc,
                                            const std::vector<ClassField>& fields) {
  py::class_<Result, TableResult> c(scope, name, py::dynamic_attr(), doc);
  for (const ClassField& f : fields)
    c.def_property_readonly(
        f.field.name.data(),  // (the tables' names and meanings are NUL-terminated literals)
        [name = f.field.name](const Result& r) { return r.value(name); },
        f.field.meaning.data());
  c.def_static("fields", [fields]() { return field_tuples(fields); },
               "The result's fields: (name, kind, per_particle, meaning, input) tuples, kind one "
               "of real, error, count, text, flag.");
  return c;
}

}  // namespace pendavg::python
