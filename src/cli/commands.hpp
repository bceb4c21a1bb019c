// SPDX-License-Identifier: GPL-3.0-or-later
// src/cli/commands.hpp -- the pendavg commands (average, limit, series, help, --version): parse
// and validate the options, call the library, format the result as one string for stdout.
#pragma once

#include <functional>
#include <span>
#include <string>
#include <string_view>

namespace pendavg::cli {

/// Runs the command in `args` (argv without the program name) and returns everything it prints
/// on stdout. Nothing is printed here. Bad input throws pendavg::invalid_input (usage_error
/// included); any other exception is an internal error.
std::string run(std::span<const std::string_view> args);

/// Every command calls this once all of its input is checked, just before its first unit of work
/// (a library computation, or writing to an output; a sweep's output is opened as part of the
/// check, and an uncommitted output leaves nothing): bad input must be refused before this point
/// (README "Reliability"). It runs the hook set by set_input_checked_hook, if any, and
/// otherwise does nothing. The fuzz targets (tests/fuzz) set a hook that throws, so that they run
/// every check of a command and none of its work.
void input_checked(std::string_view command);
void set_input_checked_hook(std::function<void(std::string_view command)> hook);

}  // namespace pendavg::cli
