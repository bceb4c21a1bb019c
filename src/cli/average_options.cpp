// SPDX-License-Identifier: GPL-3.0-or-later
// src/cli/average_options.cpp -- see average_options.hpp.
#include "average_options.hpp"

#include <algorithm>
#include <optional>
#include <string_view>

namespace pendavg::cli {

AverageOptions parse_average_options(const Options& options,
                                     std::span<const std::string_view> read) {
  const auto text = [&](std::string_view name) -> std::optional<std::string_view> {
    if (std::ranges::find(read, name) == read.end() || !options.has(name)) return std::nullopt;
    return options.required(name);
  };
  io::AverageOptionTexts texts;
  texts.method = text("method");
  texts.digits = text("digits");
  texts.tol = text("tol");
  texts.samples = text("samples");
  texts.shifts = text("shifts");
  texts.seed = text("seed");
  return io::parse_average_options(texts, "--");
}

}  // namespace pendavg::cli
