// SPDX-License-Identifier: GPL-3.0-or-later
// src/cli/args.hpp -- input side of the pendavg CLI: the command line, strict decimal numbers
// (double and MPFR) and the `--cases` CSV file. Everything here reports bad input by throwing
// usage_error, which the CLI maps to exit code 2; nothing here computes physics.
#pragma once

#include "pendavg/chain.hpp"

#include <cstddef>
#include <cstdint>
#include <functional>
#include <map>
#include <span>
#include <string>
#include <string_view>
#include <vector>

namespace pendavg::cli {

/// Bad input found by the CLI itself (option, number, file). Its message is one line. It is a
/// pendavg::invalid_input, so one handler covers the CLI's and the library's validation.
class usage_error : public invalid_input {
 public:
  using invalid_input::invalid_input;
};

/// 'text', for messages.
std::string in_quotes(std::string_view text);

/// The options of one command, `--name value` or `--name=value`, each given at most once, and
/// flags, `--name` alone (no value).
class Options {
 public:
  /// Parses `args` (everything after the command). Only names in `allowed` (options with a
  /// value) and `flags` (without one) are accepted; other arguments are operands (files) when
  /// `operands` is set, else refused.
  Options(std::string_view command, std::span<const std::string_view> args,
          std::span<const std::string_view> allowed,
          std::span<const std::string_view> flags = {}, bool operands = false);

  bool has(std::string_view name) const { return values_.contains(name); }
  /// The value of --name, or `fallback` when it was not given.
  std::string_view get(std::string_view name, std::string_view fallback) const;
  /// The value of --name; throws usage_error "<command>: missing required option --name".
  std::string_view required(std::string_view name) const;
  const std::string& command() const { return command_; }
  const std::vector<std::string>& operands() const { return operands_; }

 private:
  std::string command_;
  std::vector<std::string> operands_;
  std::map<std::string, std::string, std::less<>> values_;
};

/// True when any argument asks for help (--help or -h).
bool asks_for_help(std::span<const std::string_view> args);

/// Which values a physical parameter may take.
enum class Domain { positive, nonnegative, any };

/// Parses one decimal number strictly: [+-]digits[.digits][e[+-]digits], the whole token, finite,
/// inside `domain`. `what` names the quantity in the error message (e.g. "--beta").
/// For mpfr_real the text is rounded once, directly to this thread's working precision (0.1 never
/// goes through double): parse under the working_precision of the call the value is for.
/// Whether the running command takes --digits: a number out of double's range is then refused
/// with the advice "use --digits > 16" (set by run() for each command; on by default).
void set_digits_advice(bool command_takes_digits);
/// What set_digits_advice was last given.
bool command_takes_digits();

template <class Real>
Real parse_real(std::string_view text, std::string_view what, Domain domain);

/// A comma-separated list of numbers, each parsed by parse_real; empty elements are errors.
template <class Real>
std::vector<Real> parse_real_list(std::string_view text, std::string_view what, Domain domain);

/// A non-negative decimal integer in [lowest, highest], digits only.
long parse_integer(std::string_view text, std::string_view what, long lowest, long highest);

/// An unsigned 64-bit decimal integer, digits only (e.g. a seed).
std::uint64_t parse_unsigned(std::string_view text, std::string_view what);

/// --digits: an integer in pendavg::min_digits..pendavg::max_digits.
int parse_digits(std::string_view text);

/// Index of `text` in `choices`; throws usage_error "unknown <what> '<text>' (expected a|b|c)".
std::size_t parse_choice(std::string_view text, std::string_view what,
                         std::span<const std::string_view> choices);

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
/// Throws usage_error "expected K fields, found J" for a row of the wrong length.
void case_fields(const CasesFile& file, const CaseRow& row, std::span<std::string_view> fields);

}  // namespace pendavg::cli
