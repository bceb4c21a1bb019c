// SPDX-License-Identifier: GPL-3.0-or-later
// tests/fuzz/fuzz_common.hpp -- what the libFuzzer targets share: running one command up to
// input_checked() (its checks, none of its work), and the contract every refusal keeps.
#pragma once

#include "cli/commands.hpp"
#include "pendavg/chain.hpp"

#include <cstdio>
#include <cstdlib>
#include <exception>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace pendavg::fuzz {

/// Reports a broken invariant and aborts (libFuzzer saves the input as a crash).
[[noreturn]] inline void fail(const std::string& what, std::string_view input = {}) {
  std::fprintf(stderr, "pendavg fuzz: %s\n", what.c_str());
  if (!input.empty())
    std::fprintf(stderr, "  input: %.*s\n", static_cast<int>(input.size()), input.data());
  std::abort();
}

/// A refusal's message is not empty (the CLI prints it as one line "pendavg: error: <message>",
/// any newline in it replaced: distribute.cpp).
inline void check_message(const char* message, std::string_view input) {
  if (std::string_view(message).empty()) fail("a refusal with an empty message", input);
}

/// Thrown by the input_checked() hook: the command accepted its input and would start work.
struct InputAccepted {};

/// Runs `args` (argv without the program name) through pendavg::cli::run: up to the command's
/// input_checked(), or to its end when `compute` (for requests whose work the caller knows to be
/// short). Bad input must be refused with pendavg::invalid_input (exit code 2); any other
/// exception is an internal error, which the CLI would report with exit code 1: a finding.
/// Returns the command's output when it ran to its end, nullopt otherwise.
inline std::optional<std::string> run_command(const std::vector<std::string>& args,
                                              std::string_view input, bool compute = false) {
  static bool computing = false;
  static const bool hooked = [] {
    pendavg::cli::set_input_checked_hook([](std::string_view) {
      if (!computing) throw InputAccepted{};
    });
    return true;
  }();
  (void)hooked;
  computing = compute;
  const std::vector<std::string_view> views(args.begin(), args.end());
  try {
    return pendavg::cli::run(views);  // help, usage and --version return without work
  } catch (const InputAccepted&) {
    return std::nullopt;
  } catch (const pendavg::invalid_input& refused) {
    check_message(refused.what(), input);
    return std::nullopt;
  } catch (const std::exception& other) {
    fail(std::string("not a one-line refusal but an internal error: ") + other.what(), input);
  }
}

/// Options that name files (read or written): the targets never pass them with fuzzed values.
inline bool names_a_file(std::string_view arg) {
  for (const std::string_view option :
       {"--output", "--resume", "--timing-rows", "--trajectory", "--cases"})
    if (arg.starts_with(option)) return true;
  return false;
}

/// `text` split at `separator` (every part kept, empty ones too).
inline std::vector<std::string> split(std::string_view text, char separator) {
  std::vector<std::string> parts;
  for (std::size_t begin = 0;;) {
    const std::size_t end = text.find(separator, begin);
    parts.emplace_back(text.substr(begin, end == std::string_view::npos ? end : end - begin));
    if (end == std::string_view::npos) return parts;
    begin = end + 1;
  }
}

}  // namespace pendavg::fuzz
