// src/cli/args.hpp -- input side of the pendavg CLI: the command line, strict decimal numbers
// (double and MPFR) and the `--cases` CSV file. Everything here reports bad input by throwing
// usage_error, which the CLI maps to exit code 2; nothing here computes physics.
#pragma once

#include "pendavg/chain.hpp"

#include <array>
#include <cstddef>
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

/// The options of one command, `--name value` or `--name=value`, each given at most once.
class Options {
 public:
  /// Parses `args` (everything after the command). Only names in `allowed` are accepted.
  Options(std::string_view command, std::span<const std::string_view> args,
          std::span<const std::string_view> allowed);

  bool has(std::string_view name) const { return values_.contains(name); }
  /// The value of --name, or `fallback` when it was not given.
  std::string_view get(std::string_view name, std::string_view fallback) const;
  /// The value of --name; throws usage_error "<command>: missing required option --name".
  std::string_view required(std::string_view name) const;
  const std::string& command() const { return command_; }

 private:
  std::string command_;
  std::map<std::string, std::string, std::less<>> values_;
};

/// True when any argument asks for help (--help or -h).
bool asks_for_help(std::span<const std::string_view> args);

/// Which values a physical parameter may take.
enum class Domain { positive, nonnegative };

/// Parses one decimal number strictly: [+-]digits[.digits][e[+-]digits], the whole token, finite,
/// inside `domain`. `what` names the quantity in the error message (e.g. "--beta").
/// For mpfr_real the caller must already hold a working_precision guard: the text is rounded
/// once, directly at working precision (0.1 never goes through double).
template <class Real>
Real parse_real(std::string_view text, std::string_view what, Domain domain);

/// A comma-separated list of numbers, each parsed by parse_real; empty elements are errors.
template <class Real>
std::vector<Real> parse_real_list(std::string_view text, std::string_view what, Domain domain);

/// A non-negative decimal integer in [lowest, highest], digits only.
long parse_integer(std::string_view text, std::string_view what, long lowest, long highest);

/// --digits: an integer in pendavg::min_digits..pendavg::max_digits.
int parse_digits(std::string_view text);

/// Index of `text` in `choices`; throws usage_error "unknown <what> '<text>' (expected a|b|c)".
std::size_t parse_choice(std::string_view text, std::string_view what,
                         std::span<const std::string_view> choices);

/// Columns of a cases file, in their canonical (output) order.
inline constexpr std::array<std::string_view, 6> case_columns{"beta", "g",  "m1",
                                                              "m2",   "l1", "l2"};

/// One data row of a cases file: its 1-based line number and its fields as written, in the
/// canonical column order.
struct CaseRow {
  std::size_t line = 0;
  std::array<std::string, case_columns.size()> fields;
};

/// Reads a cases CSV. The header names exactly the columns of case_columns, in any order.
/// Blank lines and lines starting with '#' are skipped. Fields are not parsed as numbers here.
std::vector<CaseRow> read_cases_file(const std::string& path);

}  // namespace pendavg::cli
