// SPDX-License-Identifier: GPL-3.0-or-later
// src/cli/args.cpp -- strict parsing of the pendavg command line, numbers and cases files.
#include "args.hpp"


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

}  // namespace pendavg::cli
