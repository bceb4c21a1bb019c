// SPDX-License-Identifier: GPL-3.0-or-later
// tests/fuzz/fuzz_cases.cpp -- libFuzzer target: the `--cases` reader. The input is one line of
// extra `average` options (separated by spaces; may be empty), then the cases file itself.
//
// 1. read_cases_file and case_fields against a plain reference reader written here: the same
//    rows (line numbers and text), and every field in the column the header names (the header's
//    names are the canonical column names case_columns(N, state) in the file's order).
// 2. `average --cases FILE <options>` up to input_checked(): every row checked (numbers, chain,
//    the method's domain) as the command does before its work.
// No crash, leak or undefined behaviour; bad input is refused with pendavg::invalid_input.
// The file lives in memory (memfd), read through /proc/self/fd.
#include "fuzz_common.hpp"

#include "cli/args.hpp"

#include <algorithm>
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include <sys/mman.h>
#include <unistd.h>

namespace {

using pendavg::fuzz::fail;

std::string_view trimmed(std::string_view text) {
  while (!text.empty() && (text.front() == ' ' || text.front() == '\t' || text.front() == '\r'))
    text.remove_prefix(1);
  while (!text.empty() && (text.back() == ' ' || text.back() == '\t' || text.back() == '\r'))
    text.remove_suffix(1);
  return text;
}

struct ReferenceRow {
  std::size_t line;
  std::string text;
};

/// The cases file as the usage text describes it: lines, trimmed; blank lines and lines starting
/// with '#' skipped; the first other line is the header, the rest are rows.
std::optional<std::string> reference_rows(std::string_view contents,
                                          std::vector<ReferenceRow>& rows) {
  std::optional<std::string> header;
  std::size_t line_number = 0;
  for (const std::string& raw : pendavg::fuzz::split(contents, '\n')) {
    ++line_number;
    const std::string_view line = trimmed(raw);
    if (line.empty() || line.front() == '#') continue;
    if (!header) header = std::string(line);
    else rows.push_back({line_number, std::string(line)});
  }
  return header;
}

/// A path that reads `contents`: an in-memory file, rewritten for every input.
std::string cases_path(std::string_view contents) {
  static const int fd = memfd_create("cases.csv", 0);
  if (fd < 0) fail("memfd_create failed");
  if (ftruncate(fd, 0) != 0 ||
      pwrite(fd, contents.data(), contents.size(), 0) != static_cast<ssize_t>(contents.size()))
    fail("cannot write the in-memory cases file");
  return "/proc/self/fd/" + std::to_string(fd);
}

void check_reader(const std::string& path, std::string_view contents, std::string_view input) {
  pendavg::cli::CasesFile file;
  try {
    file = pendavg::cli::read_cases_file(path);
  } catch (const pendavg::cli::usage_error& refused) {
    pendavg::fuzz::check_message(refused.what(), input);
    return;
  }
  std::vector<ReferenceRow> rows;
  const std::optional<std::string> header = reference_rows(contents, rows);
  if (!header) fail("a cases file without a header line was accepted", input);
  if (file.text != contents) fail("the cases file's text differs from the file", input);

  // The header: N >= 1, each of the 2N + 2 columns exactly once, each where the header names it.
  const std::size_t n = file.particles;
  const std::vector<std::string> columns = pendavg::cli::case_columns(n, file.state);
  const std::vector<std::string> names = pendavg::fuzz::split(*header, ',');
  if (n < 1 || file.positions.size() != columns.size() || names.size() != columns.size())
    fail("the header gives " + std::to_string(file.positions.size()) + " positions for N = " +
             std::to_string(n),
         input);
  std::vector<bool> seen(columns.size(), false);
  for (std::size_t k = 0; k < names.size(); ++k) {
    const std::size_t position = file.positions[k];
    if (position >= columns.size() || seen[position])
      fail("header position " + std::to_string(position) + " out of range or repeated", input);
    seen[position] = true;
    if (trimmed(names[k]) != columns[position])
      fail("header field '" + names[k] + "' put in column " + columns[position], input);
  }

  // The rows: the same lines, and their fields where the header puts them.
  if (file.rows.size() != rows.size())
    fail(std::to_string(file.rows.size()) + " rows read, the reference reads " +
             std::to_string(rows.size()),
         input);
  std::vector<std::string_view> fields(columns.size());
  for (std::size_t r = 0; r < rows.size(); ++r) {
    const pendavg::cli::CaseRow& row = file.rows[r];
    if (row.begin + row.size > file.text.size() || row.line != rows[r].line ||
        file.row_text(row) != rows[r].text)
      fail("row " + std::to_string(r) + " differs from the reference's line " +
               std::to_string(rows[r].line),
           input);
    const std::vector<std::string> expected = pendavg::fuzz::split(rows[r].text, ',');
    try {
      pendavg::cli::case_fields(file, row, fields);
    } catch (const pendavg::cli::usage_error& refused) {
      pendavg::fuzz::check_message(refused.what(), input);
      if (expected.size() == columns.size())
        fail("row " + std::to_string(r) + " of the right length refused: " + refused.what(),
             input);
      continue;
    }
    if (expected.size() != columns.size())
      fail("row " + std::to_string(r) + " with " + std::to_string(expected.size()) +
               " fields accepted",
           input);
    for (std::size_t k = 0; k < expected.size(); ++k)
      if (fields[file.positions[k]] != trimmed(expected[k]))
        fail("row " + std::to_string(r) + " field " + std::to_string(k) + " read as '" +
                 std::string(fields[file.positions[k]]) + "'",
             input);
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string_view input(reinterpret_cast<const char*>(data), size);
  const std::size_t newline = input.find('\n');
  if (newline == std::string_view::npos) return -1;
  const std::string_view options = input.substr(0, newline);
  const std::string_view contents = input.substr(newline + 1);
  std::vector<std::string> args{"average", "--cases", cases_path(contents)};
  if (options.find('\0') != std::string_view::npos) return -1;  // argv strings end at NUL
  for (const std::string& option : pendavg::fuzz::split(options, ' ')) {
    if (option.empty()) continue;
    if (pendavg::fuzz::names_a_file(option)) return -1;
    args.push_back(option);
  }
  if (args.size() > 16) return -1;
  check_reader(args[2], contents, input);
  pendavg::fuzz::run_command(args, input);
  return 0;
}
