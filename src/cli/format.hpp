// SPDX-License-Identifier: GPL-3.0-or-later
// src/cli/format.hpp -- output side of the pendavg CLI: numbers as decimal strings (double and
// MPFR alike, `digits` significant digits), and the CSV line writer.
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

/// Joins `fields` with commas and ends the line.
void append_csv_line(std::string& out, std::span<const std::string> fields);

using io::seconds_text;

}  // namespace pendavg::cli
