// SPDX-License-Identifier: GPL-3.0-or-later
// src/io/report.hpp -- a command's result as JSON, CSV or text, from records (record.hpp): the
// one place that lays out a report, so every command's output has the same shape:
//   JSON: {"schema": 1, "command": C, <head>, <row> or "<label>": {<row>}..., "seconds": s}
//   CSV:  "# schema: 1" and "# pendavg C" lines, a header, one line per row
//   text: the head, each row (a per-particle table, then `name = value` lines), seconds
#pragma once

#include "io/record.hpp"

#include <functional>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

namespace pendavg::io {

enum class Format { json, csv, text };

/// Parses json, csv or text; throws std::invalid_argument naming the choices.
Format parse_format(std::string_view name);

struct Report {
  std::string_view command;
  std::vector<const Record*> head;  ///< shared by every row (the inputs)
  struct Row {
    std::string_view label;              ///< with several rows: the JSON key, the `row_key` cell
    std::vector<const Record*> records;  ///< the row's results
    std::string run = "null";  ///< JSON only: the method's run diagnostics (an object; empty: none)
  };
  std::vector<Row> rows;
  std::string_view row_key;        ///< with several rows: the CSV column naming each row's label
  std::optional<double> seconds;   ///< wall time of the whole command
};

std::string format_report(const Report& report, Format format);

/// A result that is a list of rows of one table (series' terms, poincare's section points):
///   JSON: {"schema": 1, "command": C, <head>, "<list_key>": [{<row>}, ...], "seconds": s}
///   CSV:  the "# schema: 1" and "# pendavg C" lines, a header, one line per row: the head's
///         cells (the same on every line), then the row's
///   text: the head, then the rows as an aligned table under their field names, then seconds
/// The rows are filled one at a time into one record (a long list is never held as records).
struct ListReport {
  std::string_view command;
  std::vector<const Record*> head;
  std::string_view list_key;          ///< JSON: the key of the array of rows
  std::span<const Field> row_fields;  ///< the rows' table (scalar fields)
  std::size_t rows = 0;
  /// Fills `record` (reset to row_fields) with row k.
  std::function<void(std::size_t k, Record& record)> fill_row;
  std::optional<double> seconds;  ///< wall time of the whole command
};

std::string format_list_report(const ListReport& report, Format format);

/// A wall time in seconds with 6 significant digits.
std::string seconds_text(double seconds);

/// The `# schema: 1` line (with its newline) that starts every CSV pendavg writes.
std::string schema_line();

}  // namespace pendavg::io
