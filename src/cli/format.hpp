// SPDX-License-Identifier: GPL-3.0-or-later
// src/cli/format.hpp -- output side of the pendavg CLI: numbers as decimal strings (double and
// MPFR alike, `digits` significant digits), and small JSON, CSV and aligned-text writers.
// Everything builds strings; the caller writes them to stdout once, after all work succeeded.
#pragma once

#include "pendavg/microcanonical.hpp"
#include "pendavg/result.hpp"
#include "io/number_text.hpp"
#include "io/report.hpp"

#include <cstddef>
#include <span>
#include <string>
#include <string_view>
#include <type_traits>
#include <vector>

namespace pendavg::cli {

using io::append_decimal;
using io::check_printed_quotients;
using io::decimal;
using io::decimal_max_length;
using io::error_digits;
using io::printed_error;
using io::quotient_t;
using io::upward_errors;
using io::write_decimal;
using io::write_quotient;

using io::Format;

/// A JSON object written key by key, in insertion order.
class JsonObject {
 public:
  JsonObject& raw(std::string_view key, std::string_view json);  ///< value is already JSON
  JsonObject& string(std::string_view key, std::string_view value);
  JsonObject& integer(std::string_view key, long long value);
  JsonObject& boolean(std::string_view key, bool value);
  std::string str() const { return "{" + body_ + "}"; }

 private:
  std::string body_;
};

/// Joins `fields` with commas and ends the line.
void append_csv_line(std::string& out, std::span<const std::string> fields);

using io::seconds_text;

}  // namespace pendavg::cli
