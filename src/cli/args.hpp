// SPDX-License-Identifier: GPL-3.0-or-later
// src/cli/args.hpp -- the command line of the pendavg CLI (options and flags); the numbers and
// the cases file are read by the front-end library (src/io/parse.hpp, cases_file.hpp). Bad input
// throws usage_error, which the CLI maps to exit code 2.
#pragma once

#include "io/cases_file.hpp"
#include "io/parse.hpp"

#include <cstddef>
#include <cstdint>
#include <functional>
#include <map>
#include <span>
#include <string>
#include <string_view>
#include <vector>

namespace pendavg::cli {

/// Bad input found by the CLI or the front-end library (option, number, file).
using usage_error = io::bad_input;

using io::CaseRow;
using io::CasesFile;
using io::Domain;
using io::case_columns;
using io::case_fields;
using io::command_takes_digits;
using io::in_quotes;
using io::max_case_line_bytes;
using io::parse_choice;
using io::parse_digits;
using io::parse_integer;
using io::parse_real;
using io::parse_real_list;
using io::parse_unsigned;
using io::read_cases_file;
using io::set_digits_advice;

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

}  // namespace pendavg::cli
