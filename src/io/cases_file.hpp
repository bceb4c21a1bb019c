// SPDX-License-Identifier: GPL-3.0-or-later
// src/io/cases_file.hpp -- the cases file (`pendavg average --cases FILE.csv`): one chain and
// state per row, located without parsing a number.
#pragma once

#include <cstddef>
#include <span>
#include <string>
#include <string_view>
#include <vector>

namespace pendavg::io {

/// Columns of a cases file for N particles, in their canonical (output) order:
/// beta, g, m1..mN, l1..lN; `state` replaces beta by energy or excitation (microcanonical).
std::vector<std::string> case_columns(std::size_t particles, std::string_view state = "beta");

/// One data row of a cases file: its 1-based line number and where its (trimmed) text lies in
/// CasesFile::text, as offsets (the text may move with the CasesFile).
struct CaseRow {
  std::size_t line = 0;
  std::size_t begin = 0, size = 0;
};

/// A cases file: N (from the header), where each field of a row goes, its rows and its text.
struct CasesFile {
  std::size_t particles = 0;
  std::string state = "beta";  ///< the state column: beta, energy or excitation
  /// For each field of a row (file order): its canonical column, or index_column.
  std::vector<std::size_t> positions;
  /// The position of a column left out: pandas' index (an unnamed first column of row numbers).
  static constexpr std::size_t index_column = static_cast<std::size_t>(-1);
  std::vector<CaseRow> rows;
  std::string text;  ///< the whole file
  std::string_view row_text(const CaseRow& row) const {
    return std::string_view(text).substr(row.begin, row.size);
  }
};

/// The longest line of a cases file (a header of N = 100,000 is ~1.4 MB, a row of it at 77
/// digits ~16 MB).
inline constexpr std::size_t max_case_line_bytes = std::size_t(64) << 20;

/// Reads a cases CSV. The header names the columns beta (or energy, or excitation: one of the
/// three), g, m1..mN and l1..lN (N >= 1, decided by the header), each exactly once, in any
/// order. Blank lines and lines starting with '#' are skipped. Rows are only located here:
/// case_fields splits them (no number is parsed here). Files as pandas writes them are read: a
/// UTF-8 byte order mark, quoted column names, and an unnamed first column of row numbers (the
/// DataFrame's index), which is left out. Refused: a file larger than half of this machine's
/// memory, or with a line longer than max_case_line_bytes.
CasesFile read_cases_file(const std::string& path);

/// Splits `row` into its fields, trimmed, into `fields` (size file.positions.size()) in the
/// canonical column order (beta or energy or excitation, g, m1..mN, l1..lN); views into
/// file.text, no allocation.
/// Throws bad_input "expected K fields, found J" for a row of the wrong length.
void case_fields(const CasesFile& file, const CaseRow& row, std::span<std::string_view> fields);

}  // namespace pendavg::io
