// SPDX-License-Identifier: GPL-3.0-or-later
// src/io/cases_file.cpp -- the cases file of `average --cases`.
#include "io/cases_file.hpp"

#include "io/parse.hpp"

#include <algorithm>
#include <charconv>
#include <cerrno>
#include <cstring>
#include <optional>
#include <system_error>
#include <utility>

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

namespace pendavg::io {

namespace {

/// Length of the leading run of decimal digits of `text`.
std::size_t digit_run(std::string_view text) {
  return static_cast<std::size_t>(std::find_if(text.begin(), text.end(), [](char c) {
                                    return c < '0' || c > '9';
                                  }) -
                                  text.begin());
}

}  // namespace

// ---------------------------------------------------------------- cases file

namespace {

std::string_view trimmed(std::string_view text) {
  constexpr std::string_view space = " \t\r";
  const auto first = text.find_first_not_of(space);
  if (first == std::string_view::npos) return {};
  return text.substr(first, text.find_last_not_of(space) - first + 1);
}

std::vector<std::string_view> split_fields(std::string_view line) {
  std::vector<std::string_view> fields;
  for (std::size_t begin = 0;;) {
    const std::size_t comma = std::min(line.find(',', begin), line.size());
    fields.push_back(trimmed(line.substr(begin, comma - begin)));
    if (comma == line.size()) return fields;
    begin = comma + 1;
  }
}

/// Largest particle index accepted in a column name (m<k>, l<k>).
constexpr std::size_t max_column_index = 100000;

/// A header name: beta (or energy, excitation), g, or m<k> / l<k> with k = 1..max_column_index
/// (no leading zeros).
struct ColumnName {
  char kind = 0;        ///< 'b' (beta, energy or excitation), 'g', 'm' or 'l'
  std::size_t index = 0;  ///< k for m<k> and l<k>
};

std::optional<ColumnName> column_name(std::string_view name) {
  if (name == "beta" || name == "energy" || name == "excitation") return ColumnName{'b', 0};
  if (name == "g") return ColumnName{'g', 0};
  if (name.size() < 2 || (name.front() != 'm' && name.front() != 'l')) return std::nullopt;
  const std::string_view digits = name.substr(1);
  if (digits.front() == '0' || digits.size() > 6 || digit_run(digits) != digits.size())
    return std::nullopt;
  std::size_t index = 0;
  std::from_chars(digits.data(), digits.data() + digits.size(), index);
  if (index > max_column_index) return std::nullopt;
  return ColumnName{name.front(), index};
}

struct Header {
  std::size_t particles = 0;
  std::string state = "beta";          ///< beta, energy or excitation
  std::vector<std::size_t> positions;  ///< for each header field, its canonical column
};

/// N and, for each header field, the index of its column in case_columns(N, state). Linear in
/// the number of columns (a header may have 2 + 2 * 100000 of them).
Header parse_header(std::string_view line, const std::string& where) {
  auto names = split_fields(line);
  // As pandas writes them: a name may be quoted ("beta", with quoting=QUOTE_ALL or
  // QUOTE_NONNUMERIC), and DataFrame.to_csv() writes its index first, under an empty name
  // (",beta,g,..."): that column is the rows' numbers, not a parameter, and is left out.
  for (std::string_view& name : names)
    if (name.size() >= 2 && name.front() == '"' && name.back() == '"')
      name = trimmed(name.substr(1, name.size() - 2));
  const bool index_column = names.size() > 1 && names.front().empty();
  if (index_column) names.erase(names.begin());
  std::vector<ColumnName> columns;
  columns.reserve(names.size());
  std::size_t particles = 0;
  std::string state;
  for (const std::string_view name : names) {
    const auto column = column_name(name);
    if (!column) throw bad_input(where + ": unknown column " + in_quotes(name));
    if (column->kind == 'b') {
      if (state == name) throw bad_input(where + ": column " + in_quotes(name) + " given twice");
      if (!state.empty())
        throw bad_input(where + ": columns " + in_quotes(state) + " and " + in_quotes(name) +
                          " both given (one of beta, energy, excitation)");
      state = std::string(name);
    }
    columns.push_back(*column);
    particles = std::max(particles, column->index);
  }
  particles = std::max<std::size_t>(particles, 1);
  if (state.empty()) state = "beta";  // reported missing below
  Header header{particles, state, {}};
  header.positions.reserve(columns.size() + 1);
  if (index_column) header.positions.push_back(CasesFile::index_column);
  std::vector<bool> seen(2 + 2 * particles, false);
  for (std::size_t k = 0; k < columns.size(); ++k) {
    const ColumnName& column = columns[k];
    std::size_t position = 0;
    switch (column.kind) {
      case 'b': position = 0; break;
      case 'g': position = 1; break;
      case 'm': position = 1 + column.index; break;
      default: position = 1 + particles + column.index; break;
    }
    if (seen[position])
      throw bad_input(where + ": column " + in_quotes(names[k]) + " given twice");
    seen[position] = true;
    header.positions.push_back(position);
  }
  const std::vector<std::string> canonical = case_columns(particles, state);
  for (std::size_t position = 0; position < seen.size(); ++position)
    if (!seen[position])
      throw bad_input(where + ": missing column " + in_quotes(canonical[position]));
  return header;
}

}  // namespace

namespace {

/// The most a cases file may hold: half of this machine's memory (the whole file is kept while
/// its rows are computed), and at most max_case_line_bytes on one line. A file beyond either is
/// refused as it is read (`--cases /dev/zero` would otherwise read until memory ran out), as is
/// a NUL byte (no text file holds one).
std::size_t max_cases_file_bytes() {
  const long pages = sysconf(_SC_PHYS_PAGES), page = sysconf(_SC_PAGESIZE);
  if (pages <= 0 || page <= 0) return std::size_t(1) << 32;
  return static_cast<std::size_t>(pages) / 2 * static_cast<std::size_t>(page);
}

std::string read_file(const std::string& path) {
  // read(2) into a string sized from fstat (a cases file may hold millions of rows: no
  // character-by-character stream, no regrowth copies); grows for files that are not regular.
  const bad_input unreadable("cannot read cases file " + in_quotes(path));
  const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) throw unreadable;
  struct Descriptor {
    int fd;
    ~Descriptor() { ::close(fd); }
  } const descriptor{fd};
  const std::size_t most = max_cases_file_bytes();
  const auto too_large = [&] {
    return bad_input("cases file " + in_quotes(path) + " is larger than " +
                       std::to_string(most >> 20) +
                       " MB, half of this machine's memory (the whole file is kept while its "
                       "rows are computed): split it");
  };
  struct stat status {};
  std::size_t expected = 0;
  if (::fstat(fd, &status) == 0 && S_ISREG(status.st_mode))
    expected = static_cast<std::size_t>(status.st_size);
  if (expected > most) throw too_large();
  std::string contents(expected + 1, '\0');  // one more byte: the end shows in one read
  std::size_t size = 0, line_start = 0;
  for (;;) {
    if (size == contents.size()) contents.resize(std::max<std::size_t>(65536, 2 * size));
    const ssize_t n = ::read(fd, contents.data() + size, contents.size() - size);
    if (n < 0) {
      if (errno == EINTR) continue;
      throw unreadable;  // e.g. a directory (EISDIR)
    }
    if (n == 0) break;
    // A NUL byte: not a text file (/dev/urandom, a binary file named by mistake): refused at
    // once rather than after reading up to the limit.
    if (const void* nul = std::memchr(contents.data() + size, '\0', static_cast<std::size_t>(n)))
      throw bad_input("cases file " + in_quotes(path) + " line " +
                        std::to_string(1 + std::count(std::as_const(contents).data(),
                                                      static_cast<const char*>(nul), '\n')) +
                        " holds a NUL byte: not a text file");
    // The start of the last line so far: a line longer than max_case_line_bytes (no newline in
    // 64 MB) is refused without reading on.
    if (const void* newline = memrchr(contents.data() + size, '\n', static_cast<std::size_t>(n)))
      line_start = static_cast<std::size_t>(static_cast<const char*>(newline) - contents.data()) + 1;
    size += static_cast<std::size_t>(n);
    if (size - line_start > max_case_line_bytes)
      throw bad_input("cases file " + in_quotes(path) + " line " +
                        std::to_string(1 + std::count(contents.data(),
                                                      contents.data() + line_start, '\n')) +
                        " is longer than " + std::to_string(max_case_line_bytes >> 20) +
                        " MB (not a cases file?)");
    if (size > most) throw too_large();
  }
  contents.resize(size);
  return contents;
}

}  // namespace

std::vector<std::string> case_columns(std::size_t particles, std::string_view state) {
  std::vector<std::string> columns{std::string(state), "g"};
  for (const char kind : {'m', 'l'})
    for (std::size_t i = 1; i <= particles; ++i) columns.push_back(kind + std::to_string(i));
  return columns;
}

CasesFile read_cases_file(const std::string& path) {
  CasesFile file;
  file.text = read_file(path);
  const std::string_view contents = file.text;
  bool header = false;  // set by the header line
  std::size_t line_number = 0;
  // A UTF-8 byte order mark (pandas' encoding="utf-8-sig", Excel's "CSV UTF-8") is not part of
  // the first column's name.
  const std::size_t start = contents.starts_with("\xEF\xBB\xBF") ? 3 : 0;
  for (std::size_t begin = start; begin < contents.size();) {
    const std::size_t newline = std::min(contents.find('\n', begin), contents.size());
    const std::string_view line = trimmed(contents.substr(begin, newline - begin));
    begin = newline + 1;
    ++line_number;
    if (line.empty() || line.front() == '#') continue;
    if (!header) {
      Header parsed = parse_header(line, path + " line " + std::to_string(line_number));
      file.particles = parsed.particles;
      file.state = parsed.state;
      file.positions = std::move(parsed.positions);
      header = true;
      continue;
    }
    file.rows.push_back({line_number, static_cast<std::size_t>(line.data() - contents.data()),
                         line.size()});
  }
  if (!header) throw bad_input("cases file " + in_quotes(path) + " has no header line");
  return file;
}

void case_fields(const CasesFile& file, const CaseRow& row, std::span<std::string_view> fields) {
  // One pass over the characters (this runs once per row of a possibly long file).
  const char* const text = file.text.data() + row.begin;
  const std::size_t size = row.size;
  const std::size_t expected = file.positions.size();
  const auto is_space = [](char c) { return c == ' ' || c == '\t' || c == '\r'; };
  std::size_t count = 0, begin = 0;
  for (std::size_t i = 0;; ++i) {
    if (i < size && text[i] != ',') continue;
    if (count < expected) {
      std::size_t first = begin, last = i;
      while (first < last && is_space(text[first])) ++first;
      while (last > first && is_space(text[last - 1])) --last;
      const std::string_view field(text + first, last - first);
      if (file.positions[count] != CasesFile::index_column) {
        fields[file.positions[count]] = field;
      } else if (field.empty() || field.find_first_not_of("0123456789") != field.npos) {
        // pandas' index: the row's number; anything else means the columns are not pandas'
        throw bad_input("the first column (no name in the header: pandas' index) must be a "
                          "row number, found " + in_quotes(field));
      }
    }
    ++count;
    if (i == size) break;
    begin = i + 1;
  }
  if (count != expected)
    throw bad_input("expected " + std::to_string(expected) + " fields, found " +
                      std::to_string(count));
}

}  // namespace pendavg::io
