// src/cli/commands.hpp -- the pendavg commands (average, limit, series, help, --version): parse
// and validate the options, call the library, format the result as one string for stdout.
#pragma once

#include <span>
#include <string>
#include <string_view>

namespace pendavg::cli {

/// Runs the command in `args` (argv without the program name) and returns everything it prints
/// on stdout. Nothing is printed here. Bad input throws pendavg::invalid_input (usage_error
/// included); any other exception is an internal error.
std::string run(std::span<const std::string_view> args);

}  // namespace pendavg::cli
