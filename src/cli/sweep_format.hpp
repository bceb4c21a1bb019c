// SPDX-License-Identifier: GPL-3.0-or-later
// src/cli/sweep_format.hpp -- a streamed sweep's file (pendavg table, average --cases) in each
// output format (--format csv, json or text), written and read back line by line:
//
//   csv   '#' lines (the header), the column line, one line per row, a '# failed: ...' line in
//         place of a row that failed, an '# interrupted: ...' line at the end of an interrupted
//         run;
//   text  the same '#' lines, the column names and every row right-aligned in fixed-width
//         columns ("-" for an empty cell; src/io/sweep_rows.hpp), '# failed:' and
//         '# interrupted:' lines as in CSV;
//   json  one document, one line per header item and per row:
//           {"schema": 1, "command": "table",
//           "header": [
//           "pendavg table: ...",          <- the CSV '#' lines after '# schema:', without '# '
//           ...
//           ],
//           "columns": ["N", "digits", ...],
//           "rows": [
//           {"N": 2, "digits": 16, ...}    <- one object per row, in row order
//           ,{"N": 2, ...}                 <- (the separating comma leads the line, so that
//           ],                                every row written is a whole line at once)
//           "failed": [
//           {"row": 5, "message": "..."}   <- a failed row: its 0-based row of the sweep and
//           ],                                the CSV '# failed:' line's text
//           "interrupted": null}           <- or the CSV '# interrupted:' line's text
//
// --resume reads any of them back (RowReader: the rows whole, in order) and refuses a file of
// another format; pendavg merge joins shards of one format.
#pragma once

#include "io/report.hpp"
#include "io/sweep_rows.hpp"

#include <cstddef>
#include <cstdio>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

namespace pendavg::cli {

/// Reads one line (without its newline) into `line`; false at the end of the file. `ended`
/// (when given) says whether the line had its newline (the last line of a file cut short has
/// none).
bool read_line(std::FILE* file, std::string& line, bool* ended = nullptr);

/// "csv", "json" or "text".
std::string_view format_name(io::Format format);

/// The header of a sweep file in `rows`' format, from the CSV header `csv` ('#' lines and the
/// column line, as CSV writes them): CSV's is `csv`; text's its '#' lines and the aligned column
/// line; JSON's the document up to and including the "rows": [ line.
std::string sweep_header(const io::RowWriter& rows, std::string_view command, std::string_view csv);

/// The rows' writer of a sweep file whose column line is `line` (CSV, text; JSON: its
/// "columns" line), as sweep_header wrote it: what its rows are read back with (RowReader) when
/// the file is all there is (pendavg merge).
io::RowWriter row_writer_of(io::Format format, std::string_view line);

/// JSON: a failed row's entry (without separator or newline): {"row": ROW, "message": "..."}.
std::string json_failed_entry(std::size_t row, std::string_view message);
/// JSON: the end of the document after the rows: the failed entries and the interruption
/// (`interrupted` empty: null).
std::string json_end(std::span<const std::string> failed, std::string_view interrupted);

/// What an existing sweep file is, from its first lines (the file is left at its start).
struct SweepFileKind {
  std::optional<io::Format> format;  ///< none: it ends before a header says
  std::string schema;                ///< JSON: its "schema" value
};
SweepFileKind sweep_file_kind(std::FILE* file);

/// The rows of a sweep file read back, in its format.
class RowReader {
 public:
  explicit RowReader(const io::RowWriter& rows);
  io::Format format() const { return format_; }
  /// Whether `line` (without its newline) holds a row: not a '#' line, a blank line or JSON's
  /// other lines.
  bool is_row(std::string_view line) const;
  /// JSON: the line after the last row (what follows are not rows).
  bool ends_rows(std::string_view line) const { return format_ == io::Format::json && line.starts_with(']'); }
  /// Reads the row `line` (`ended`: it had its newline): false when it is not whole -- cut short,
  /// another number of columns, a cell that is not a number, a word or empty (text: out of its
  /// column; JSON: not an object of the columns in their order). The line must outlive the
  /// calls below.
  bool read(std::string_view line, bool ended);
  /// After read(): whether its first `count` cells are `key` (CSV texts joined by commas).
  bool has_key(std::string_view key, std::size_t count) const;
  /// After read(): its first `count` cells as CSV texts joined by commas.
  std::string leading(std::size_t count) const;

 private:
  struct Value {
    std::string_view text;
    bool number = false;  ///< JSON: a number (its text as JSON writes it)
  };
  io::Format format_;
  std::vector<std::string> columns_;
  std::vector<std::size_t> widths_;
  std::size_t line_length_ = 0;
  std::string_view line_;
  std::vector<Value> values_;  ///< text and JSON
  mutable std::string scratch_;
};

}  // namespace pendavg::cli
