// SPDX-License-Identifier: GPL-3.0-or-later
// src/cli/args.cpp -- strict parsing of the pendavg command line, numbers and cases files.
#include "args.hpp"

#include "engine/numerics/precision.hpp"

#include <algorithm>
#include <cerrno>
#include <charconv>
#include <cstring>
#include <cmath>
#include <optional>
#include <system_error>
#include <utility>

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

namespace pendavg::cli {

namespace {
bool digits_advice = true;  // set_digits_advice
}  // namespace

void set_digits_advice(bool command_takes_digits) { digits_advice = command_takes_digits; }
bool command_takes_digits() { return digits_advice; }

std::string in_quotes(std::string_view text) {
  std::string quoted;  // appended piecewise: "'" + std::string(text) trips GCC 12's -Wrestrict
  quoted.reserve(text.size() + 2);
  quoted += '\'';
  quoted += text;
  quoted += '\'';
  return quoted;
}

namespace {

/// Length of the leading run of decimal digits of `text`.
std::size_t digit_run(std::string_view text) {
  return static_cast<std::size_t>(std::find_if(text.begin(), text.end(), [](char c) {
                                    return c < '0' || c > '9';
                                  }) -
                                  text.begin());
}

/// True for [+-]digits[.digits][(e|E)[+-]digits] with at least one mantissa digit. This one
/// grammar is applied before both parsers, so double and MPFR accept exactly the same tokens
/// (no nan, inf, hex floats or whitespace).
bool is_decimal_literal(std::string_view text) {
  if (!text.empty() && (text.front() == '+' || text.front() == '-')) text.remove_prefix(1);
  std::size_t mantissa_digits = digit_run(text);
  text.remove_prefix(mantissa_digits);
  if (!text.empty() && text.front() == '.') {
    text.remove_prefix(1);
    const std::size_t fraction_digits = digit_run(text);
    mantissa_digits += fraction_digits;
    text.remove_prefix(fraction_digits);
  }
  if (mantissa_digits == 0) return false;
  if (text.empty()) return true;
  if (text.front() != 'e' && text.front() != 'E') return false;
  text.remove_prefix(1);
  if (!text.empty() && (text.front() == '+' || text.front() == '-')) text.remove_prefix(1);
  const std::size_t exponent_digits = digit_run(text);
  return exponent_digits > 0 && exponent_digits == text.size();
}

double to_double(std::string_view text, std::string_view what) {
  if (text.front() == '+') text.remove_prefix(1);  // from_chars takes no '+'
  double value = 0;
  const auto [end, status] = std::from_chars(text.data(), text.data() + text.size(), value);
  if (status == std::errc::result_out_of_range)  // MPFR helps physical inputs, not a tolerance
    throw usage_error(std::string(what) + ": " + in_quotes(text) +
                      " is out of the range of double" +
                      (what == "--tol" || !digits_advice ? "" : " (use --digits > 16)"));
  if (status != std::errc() || end != text.data() + text.size())
    throw usage_error(std::string(what) + ": malformed number " + in_quotes(text));
  return value;
}

mpfr_real to_mpfr(std::string_view text, std::string_view what) {
  const std::string terminated(text);
  mpfr_real value;  // at the caller's working precision
  if (mpfr_set_str(value.backend().data(), terminated.c_str(), 10, MPFR_RNDN) != 0)
    throw usage_error(std::string(what) + ": malformed number " + in_quotes(text));
  return value;
}

}  // namespace

// ---------------------------------------------------------------- options

Options::Options(std::string_view command, std::span<const std::string_view> args,
                 std::span<const std::string_view> allowed,
                 std::span<const std::string_view> flags, bool operands)
    : command_(command) {
  for (std::size_t i = 0; i < args.size(); ++i) {
    std::string_view arg = args[i];
    if (operands && !arg.starts_with("--")) {
      operands_.emplace_back(arg);
      continue;
    }
    if (!arg.starts_with("--") || arg.size() == 2)
      throw usage_error(command_ + ": unexpected argument " + in_quotes(arg));
    arg.remove_prefix(2);
    std::string_view name = arg, value;
    if (std::ranges::find(flags, name) != flags.end()) {  // a flag: no value
      if (!values_.emplace(std::string(name), std::string()).second)
        throw usage_error(command_ + ": option --" + std::string(name) + " given twice");
      continue;
    }
    if (const auto equals = arg.find('='); equals != std::string_view::npos) {
      if (std::ranges::find(flags, arg.substr(0, equals)) != flags.end())
        throw usage_error(command_ + ": option --" + std::string(arg.substr(0, equals)) +
                          " takes no value");
      name = arg.substr(0, equals);
      value = arg.substr(equals + 1);
    } else if (i + 1 < args.size() && !args[i + 1].starts_with("--")) {
      value = args[++i];
    } else if (std::ranges::find(allowed, name) != allowed.end()) {
      throw usage_error(command_ + ": option --" + std::string(name) + " needs a value");
    }
    if (std::ranges::find(allowed, name) == allowed.end())
      throw usage_error(command_ + ": unknown option --" + std::string(name));
    if (!values_.emplace(std::string(name), std::string(value)).second)
      throw usage_error(command_ + ": option --" + std::string(name) + " given twice");
  }
}

std::string_view Options::get(std::string_view name, std::string_view fallback) const {
  const auto found = values_.find(name);
  return found == values_.end() ? fallback : std::string_view(found->second);
}

std::string_view Options::required(std::string_view name) const {
  const auto found = values_.find(name);
  if (found == values_.end())
    throw usage_error(command_ + ": missing required option --" + std::string(name));
  return found->second;
}

bool asks_for_help(std::span<const std::string_view> args) {
  return std::ranges::any_of(args, [](std::string_view a) { return a == "--help" || a == "-h"; });
}

// ---------------------------------------------------------------- numbers

template <class Real>
Real parse_real(std::string_view text, std::string_view what, Domain domain) {
  if (text.empty()) throw usage_error(std::string(what) + ": empty number");
  if (!is_decimal_literal(text))
    throw usage_error(std::string(what) + ": malformed number " + in_quotes(text) +
                      " (expected a finite decimal number)");
  Real value;
  if constexpr (is_mpfr_v<Real>) {
    value = to_mpfr(text, what);
  } else {
    value = to_double(text, what);
  }
  using std::isfinite;
  if (!isfinite(value))
    throw usage_error(std::string(what) + ": " + in_quotes(text) + " is not finite");
  if (domain == Domain::positive && !(value > 0))
    throw usage_error(std::string(what) + ": " + in_quotes(text) + " must be > 0");
  if (domain == Domain::nonnegative && value < 0)
    throw usage_error(std::string(what) + ": " + in_quotes(text) + " must be >= 0");
  return value;
}

template <class Real>
std::vector<Real> parse_real_list(std::string_view text, std::string_view what, Domain domain) {
  std::vector<Real> values;
  for (std::size_t begin = 0;;) {
    const std::size_t comma = std::min(text.find(',', begin), text.size());
    const std::string_view element = text.substr(begin, comma - begin);
    if (element.empty())
      throw usage_error(std::string(what) + ": empty element in list " + in_quotes(text));
    values.push_back(parse_real<Real>(element, what, domain));
    if (comma == text.size()) return values;
    begin = comma + 1;
  }
}

template double parse_real<double>(std::string_view, std::string_view, Domain);
template mpfr_real parse_real<mpfr_real>(std::string_view, std::string_view, Domain);
template std::vector<double> parse_real_list<double>(std::string_view, std::string_view, Domain);
template std::vector<mpfr_real> parse_real_list<mpfr_real>(std::string_view, std::string_view,
                                                           Domain);

long parse_integer(std::string_view text, std::string_view what, long lowest, long highest) {
  long value = 0;
  const auto [end, status] = std::from_chars(text.data(), text.data() + text.size(), value);
  if (text.empty() || digit_run(text) != text.size() || status != std::errc() ||
      end != text.data() + text.size() || value < lowest || value > highest)
    throw usage_error(std::string(what) + ": " + in_quotes(text) + " is not an integer in " +
                      std::to_string(lowest) + ".." + std::to_string(highest));
  return value;
}

std::uint64_t parse_unsigned(std::string_view text, std::string_view what) {
  std::uint64_t value = 0;
  const auto [end, status] = std::from_chars(text.data(), text.data() + text.size(), value);
  if (text.empty() || digit_run(text) != text.size() || status != std::errc() ||
      end != text.data() + text.size())
    throw usage_error(std::string(what) + ": " + in_quotes(text) +
                      " is not an unsigned integer in 0..18446744073709551615");
  return value;
}

int parse_digits(std::string_view text) {
  return static_cast<int>(parse_integer(text, "--digits", min_digits, max_digits));
}

std::size_t parse_choice(std::string_view text, std::string_view what,
                         std::span<const std::string_view> choices) {
  const auto found = std::ranges::find(choices, text);
  if (found != choices.end()) return static_cast<std::size_t>(found - choices.begin());
  std::string expected;
  for (const std::string_view choice : choices)
    (expected += expected.empty() ? "" : "|") += choice;
  throw usage_error("unknown " + std::string(what) + " " + in_quotes(text) + " (expected " +
                    expected + ")");
}

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
    if (!column) throw usage_error(where + ": unknown column " + in_quotes(name));
    if (column->kind == 'b') {
      if (state == name) throw usage_error(where + ": column " + in_quotes(name) + " given twice");
      if (!state.empty())
        throw usage_error(where + ": columns " + in_quotes(state) + " and " + in_quotes(name) +
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
      throw usage_error(where + ": column " + in_quotes(names[k]) + " given twice");
    seen[position] = true;
    header.positions.push_back(position);
  }
  const std::vector<std::string> canonical = case_columns(particles, state);
  for (std::size_t position = 0; position < seen.size(); ++position)
    if (!seen[position])
      throw usage_error(where + ": missing column " + in_quotes(canonical[position]));
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
  const usage_error unreadable("cannot read cases file " + in_quotes(path));
  const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) throw unreadable;
  struct Descriptor {
    int fd;
    ~Descriptor() { ::close(fd); }
  } const descriptor{fd};
  const std::size_t most = max_cases_file_bytes();
  const auto too_large = [&] {
    return usage_error("cases file " + in_quotes(path) + " is larger than " +
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
      throw usage_error("cases file " + in_quotes(path) + " line " +
                        std::to_string(1 + std::count(std::as_const(contents).data(),
                                                      static_cast<const char*>(nul), '\n')) +
                        " holds a NUL byte: not a text file");
    // The start of the last line so far: a line longer than max_case_line_bytes (no newline in
    // 64 MB) is refused without reading on.
    if (const void* newline = memrchr(contents.data() + size, '\n', static_cast<std::size_t>(n)))
      line_start = static_cast<std::size_t>(static_cast<const char*>(newline) - contents.data()) + 1;
    size += static_cast<std::size_t>(n);
    if (size - line_start > max_case_line_bytes)
      throw usage_error("cases file " + in_quotes(path) + " line " +
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
  if (!header) throw usage_error("cases file " + in_quotes(path) + " has no header line");
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
        throw usage_error("the first column (no name in the header: pandas' index) must be a "
                          "row number, found " + in_quotes(field));
      }
    }
    ++count;
    if (i == size) break;
    begin = i + 1;
  }
  if (count != expected)
    throw usage_error("expected " + std::to_string(expected) + " fields, found " +
                      std::to_string(count));
}

}  // namespace pendavg::cli
