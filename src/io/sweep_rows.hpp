// SPDX-License-Identifier: GPL-3.0-or-later
// src/io/sweep_rows.hpp -- one row of a streamed sweep (pendavg table, average --cases) in each
// output format, written by the thread that computed it:
//   CSV:  the cells' texts joined by commas (record.hpp's append_csv_cells);
//   JSON: one object {"column": value, ...} on one line, after a comma (the document's writer
//         drops the first row's), keys = the CSV columns in their order, values = the CSV
//         texts: numbers as JSON numbers in a double run, decimal strings in an MPFR run, names
//         as strings, true/false, null for an empty cell;
//   text: every cell right-aligned in its column's width, "-" for an empty cell, two spaces
//         between columns. A width is fixed before the first row (rows are streamed): the
//         column's name and the widest text its values can have (widest_cell).
// The texts are the CSV's in every format, so that a sweep converted from one format to
// another holds the same numbers, digit for digit.
#pragma once

#include "io/record.hpp"
#include "io/report.hpp"

#include <cstddef>
#include <span>
#include <string>
#include <string_view>
#include <vector>

namespace pendavg::io {

/// The cells of one record of a row: `selection` (indices into record->cells()), or every cell
/// when empty.
struct RowCells {
  const Record* record = nullptr;
  std::span<const std::size_t> selection = {};
};

class RowWriter {
 public:
  /// CSV (no column names needed to write a row).
  RowWriter() = default;
  /// `columns`: the row's column names; `widths` (text only): each column's width.
  RowWriter(Format format, std::vector<std::string> columns, std::vector<std::size_t> widths = {});

  Format format() const { return format_; }
  const std::vector<std::string>& columns() const { return columns_; }
  const std::vector<std::size_t>& widths() const { return widths_; }

  /// Appends one row and its newline: the texts `written` (inputs as written, decimal literals:
  /// JSON numbers when `numbers`, else strings), then the cells of `records`.
  void append(std::string& out, std::span<const std::string_view> written, bool numbers,
              std::span<const RowCells> records) const;
  /// The column line of a text file: the names right-aligned in their widths (with newline).
  std::string text_column_line() const;
  /// The length of every text row (without its newline).
  std::size_t text_line_length() const;

 private:
  void add_json(std::string& out, std::size_t& column) const;
  void add_text(std::string& out, std::size_t& column, std::string_view text) const;
  Format format_ = Format::csv;
  std::vector<std::string> columns_;
  std::vector<std::size_t> widths_;
  std::vector<std::string> keys_;  ///< JSON: the text before each value (",{" or ", ", the key)
};

/// Appends a decimal literal ([+-]digits[.digits][e[+-]digits], as the CLI reads numbers) as a
/// JSON number of the same exact value: a leading '+' and leading zeros dropped, a missing
/// digit before or after the point written as 0 (".5" -> 0.5, "+1." -> 1.0, "007" -> 7).
void append_json_number(std::string& out, std::string_view literal);

/// The field of each cell of a record of `fields` for `particles` (cell order).
std::vector<const Field*> cell_fields(std::span<const Field> fields, std::size_t particles);

/// The widest text a cell of `field` can have in a sweep whose rows run at the listed `digits`
/// (16: double; more: MPFR): a value's digits, point, sign and exponent (the longest exponent
/// of the numbers that row type prints), an error's, the largest count, the longest name.
std::size_t widest_cell(const Field& field, std::span<const int> digits);

}  // namespace pendavg::io
