// SPDX-License-Identifier: GPL-3.0-or-later
// src/io/record.hpp -- one result as a record of named cells, and the writers that turn records
// into JSON, CSV and text. Every result type has ONE field table (src/io/results.hpp); its
// record is filled in that table's order, and every output -- JSON keys, CSV columns, the text
// report, the Python result objects -- is generated from the table, so a name is spelled once.
//
// The schema (README "Output schema"): a value X has X_error (an absolute error) and
// X_error_kind (bound | estimate | statistical); a per-particle field X is a JSON array and
// the CSV columns X1..XN (its error X1_error..XN_error: the error of X1); JSON numbers are
// JSON numbers when the run is in double (the shortest text that reads back as the same
// double) and decimal strings when it is in MPFR (more digits or range than a double).
#pragma once

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <span>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

namespace pendavg::io {

/// Version of the output schema: the `schema` key of JSON, the `# schema:` line of CSV.
inline constexpr int schema_version = 1;

/// What a field holds.
enum class Kind : unsigned char {
  real,   ///< a real number (a value, an input)
  error,  ///< an absolute error: error_digits significant digits, rounded up
  count,  ///< a non-negative integer
  text,   ///< a name: a method, an error kind, a unit
  flag,   ///< true or false
};

enum class Shape : unsigned char { scalar, per_particle };

/// One field of a result type's table.
struct Field {
  std::string_view name;     ///< the JSON key, the CSV column (per particle: its stem), Python's name
  Kind kind;
  Shape shape;
  std::string_view meaning;  ///< one line, for the naming table and the Python docs
};

/// One cell of a record.
struct Cell {
  enum class Tag : unsigned char {
    none,     ///< no value (a limit's <K_i>; <K1>/<K2> for N = 1): JSON null, empty CSV cell
    number,   ///< a double (values: shortest text; errors: error_digits up)
    decimal,  ///< decimal text (MPFR values and errors; inputs as written)
    integer,
    text,
    flag,
    input,    ///< a double run's input: CSV and text print it as written, JSON the double read
  };
  Tag tag = Tag::none;
  bool flag = false;
  std::uint32_t begin = 0, size = 0;  ///< decimal and text: where in Record::text
  const char* literal = nullptr;       ///< text: a static name (method, kind, unit), not copied
  double number = 0;
  /// number cells of values: how far the printed text may lie from `number` (printing_gap);
  /// of errors: their value's, which the printed error adds (covering)
  double gap = 0;
  long long integer = 0;
};

/// A number's exact binary value as plain data, usable without any MPFR precision (Python turns
/// it into an mpmath.mpf): mantissa * 2^exponent, the mantissa a signed integer in hex.
struct ExactNumber {
  std::string mantissa;  ///< empty: no exact value kept for this cell
  long exponent = 0;
  double rounded = 0;    ///< the value rounded to the nearest double (also nan and inf)
  bool finite = true;
  bool kept() const { return !mantissa.empty(); }
};

/// One result: its table's cells in order (a per-particle field gives `particles` consecutive
/// cells). Filled by a result type's builder; reused from row to row without reallocating.
class Record {
 public:
  Record() = default;
  Record(std::span<const Field> fields, std::size_t particles) { reset(fields, particles); }

  /// Empties the record for `fields` of a chain of `particles`.
  void reset(std::span<const Field> fields, std::size_t particles);

  std::span<const Field> fields() const { return fields_; }
  std::size_t particles() const { return particles_; }
  std::span<const Cell> cells() const { return cells_; }
  /// The cells of the k-th field (one, or `particles` for a per-particle field).
  std::span<const Cell> cells_of(std::size_t field) const;
  /// The index of the field called `name`, or fields().size().
  std::size_t find(std::string_view name) const;
  /// A cell's text (decimal or text cells).
  std::string_view text_of(const Cell& cell) const {
    return {cell.literal ? cell.literal : text_.data() + cell.begin, cell.size};
  }
  /// What cell c holds (its field's kind).
  Kind kind_of_cell(std::size_t c) const { return cell_kinds_[c]; }

  // Appenders, in the table's order (checked at the end of a builder by complete()).
  void none() { add(); }
  void number(double x) {
    Cell& c = add();
    c.tag = Cell::Tag::number;
    c.number = x;
  }
  /// A double value, printed as its shortest round-trip text (kept in the record) with its
  /// printing gap.
  void shortest(double x);
  void decimal(std::string_view text);
  /// Room for `size` characters of decimal text, then commit_decimal with its end.
  char* decimal_room(std::size_t size);
  void commit_decimal(const char* end);
  /// A double run's error e of a value whose printed text lies up to `gap` from it: the cell
  /// keeps e (what the library computed), its text covers the printed value (covering). A
  /// record filled without texts (Printing::texts) has deferred_gap there: the value's
  /// shortest_gap, for whoever prints it later (io's writers print records with texts).
  void error(double e, double gap) {
    Cell& c = add();
    c.tag = Cell::Tag::number;
    c.number = e;
    c.gap = gap;
  }
  void integer(long long n) {
    Cell& c = add();
    c.tag = Cell::Tag::integer;
    c.integer = n;
  }
  /// An input of a double run: `written` in CSV and text, x (shortest) in JSON.
  void input(double x, std::string_view written);
  void text(std::string_view name);
  /// A text cell of a static name (method_name(), error_kind_name(), ...): not copied.
  void name(const char* static_name);
  void flag(bool value) {
    Cell& c = add();
    c.tag = Cell::Tag::flag;
    c.flag = value;
  }
  /// Throws std::logic_error unless every field got its cells (a builder out of step with its
  /// table is a bug, caught by every test that prints).
  void complete() const;

  /// Exact values (off by default: the CLI prints only; the Python result objects keep them).
  /// When on, an MPFR run's builder hands the number behind each value and error cell -- what
  /// it printed, before printing rounded it -- to set_exact before appending the cell, and
  /// exact() then has one entry per cell (not kept(): a cell without one, e.g. a double run's,
  /// whose Cell::number is exact already).
  void keep_exact(bool on) { keep_exact_ = on; }
  bool keeps_exact() const { return keep_exact_; }
  void set_exact(ExactNumber x) { pending_exact_ = std::move(x); }
  std::span<const ExactNumber> exact() const { return exact_; }

 private:
  std::span<const Field> fields_;
  std::size_t particles_ = 0;
  std::vector<Cell> cells_;
  std::vector<std::uint32_t> first_cell_;  ///< per field
  std::vector<Kind> cell_kinds_;           ///< per cell
  std::string text_;
  std::size_t pending_ = 0;  ///< decimal_room's start
  bool keep_exact_ = false;
  std::vector<ExactNumber> exact_;  ///< with keep_exact_: one per cell
  ExactNumber pending_exact_;       ///< set_exact's, for the next cell
  /// The next cell (an empty one, filled in place), and its exact value when kept.
  Cell& add() {
    if (keep_exact_) push_exact();
    return cells_.emplace_back();
  }
  void push_exact();
};

/// The number of cells of `fields` for `particles`.
std::size_t cell_count(std::span<const Field> fields, std::size_t particles);

/// A field's CSV column for particle i (0-based): stem + (i + 1), the index before "_error" at
/// the end or before a qualifier (beta_K_error -> beta_K1_error, K_error_blocking ->
/// K1_error_blocking); a scalar field's name.
std::string column_name(const Field& field, std::size_t i);

/// The field whose error field k is (the schema's X for X_error, of the same shape), or
/// fields.size() when k is not such an error (equipartition_residual).
std::size_t value_of_error(std::span<const Field> fields, std::size_t k);

/// The CSV columns of `fields` for `particles`, cell by cell.
std::vector<std::string> column_names(std::span<const Field> fields, std::size_t particles);

// ---------------------------------------------------------------- writers

/// Appends `"name": value` for every field of `record`, separated by ", " (and one leading
/// ", " when `out` already holds a member): a per-particle field is a JSON array.
void append_json_members(std::string& out, const Record& record);
/// Appends one JSON member `"key": value` (value already JSON).
void append_json_member(std::string& out, std::string_view key, std::string_view json);
/// A JSON string literal.
std::string json_string(std::string_view text);
/// Appends `text` as a JSON string (quotes, backslashes and control characters escaped).
void append_json_string(std::string& out, std::string_view text);

/// Appends the cells `selection` (indices into record.cells(); all cells when empty) as CSV
/// fields, each followed by a comma (the caller ends the line).
void append_csv_cells(std::string& out, const Record& record,
                      std::span<const std::size_t> selection = {});
/// Writes one cell as CSV/JSON text (without quotes) at `out`; returns the end. Room:
/// max_cell_length(record, cell).
char* write_cell(char* out, const Record& record, const Cell& cell);
std::size_t max_cell_length(const Record& record, const Cell& cell);
/// Cell::gap of an error whose value was recorded without its text (Printing::texts): its
/// value's shortest_gap, made when the error is printed.
inline constexpr double deferred_gap = -1;

/// What a double run prints for an error e of a value printed up to `gap` from it: e + gap
/// rounded up (e itself when the value's text is exact).
inline double covering(double e, double gap) {
  return gap > 0 ? std::nextafter(e + gap, HUGE_VAL) : e;
}

/// The printing gap of a double value printed as its shortest text (what Record::shortest keeps
/// in a value's cell, and its error's text adds): for records filled without texts
/// (Printing::texts), printed later.
double shortest_gap(double value);

/// Writes a double of a field of `kind` as a number cell prints it: an error with error_digits
/// significant digits rounded up, any other number as the shortest decimal that reads back as
/// it. Room: 32 characters. Returns the end.
char* write_number(char* out, double x, Kind kind);

/// The text report of records of one table: the per-particle fields as an aligned table (one
/// row per particle, the field names as headers), then every scalar field as `name = value`,
/// a value X with X_error and X_error_kind as `X = v +- e (kind)`.
std::string text_report(const Record& record);

/// Each cell of `record` as the text report prints it ("-" for an absent value).
std::vector<std::string> text_cells(const Record& record);

/// Rows of cells as right-aligned columns separated by two spaces, one line per row.
std::string aligned(const std::vector<std::vector<std::string>>& rows);

/// --columns LIST: the cells of `columns` (a row's CSV column names) that LIST selects, in
/// LIST's order. An item is a column name (cos_phi2), a per-particle stem (cos_phi: cos_phi1..N;
/// cos_phi_error: cos_phi1_error..N) or a name of schema 0 (migration_name: error_K1). Throws
/// std::invalid_argument (the message without a flag name) for an empty list or item, an unknown
/// name, one of `inputs`, or a column selected twice. `headers` receives each selected column's
/// header: the name as LIST gave it (an old name keeps its old header).
std::vector<std::size_t> select_columns(std::string_view list,
                                        const std::vector<std::string>& columns,
                                        const std::vector<std::string>& inputs,
                                        std::size_t particles, std::vector<std::string>& headers);

}  // namespace pendavg::io
