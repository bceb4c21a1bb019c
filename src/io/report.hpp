// SPDX-License-Identifier: GPL-3.0-or-later
// src/io/report.hpp -- a command's result as JSON, CSV or text, from records (record.hpp): the
// one place that lays out a report, so every command's output has the same shape:
//   JSON: {"schema": 1, "command": C, <head>, <row> or "<label>": {<row>}..., "seconds": s}
//   CSV:  "# schema: 1" and "# pendavg C" lines, a header, one line per row
//   text: the head, each row (a per-particle table, then `name = value` lines), seconds
#pragma once

#include "io/record.hpp"

#include <optional>
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
    std::string run = "null";            ///< JSON only: the method's run diagnostics (an object)
  };
  std::vector<Row> rows;
  std::string_view row_key;        ///< with several rows: the CSV column naming each row's label
  std::optional<double> seconds;   ///< wall time of the whole command
};

std::string format_report(const Report& report, Format format);

/// A wall time in seconds with 6 significant digits.
std::string seconds_text(double seconds);

/// The `# schema: 1` line (with its newline) that starts every CSV pendavg writes.
std::string schema_line();

}  // namespace pendavg::io
