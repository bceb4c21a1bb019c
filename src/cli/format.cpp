// SPDX-License-Identifier: GPL-3.0-or-later
// src/cli/format.cpp -- the CSV line writer of the pendavg CLI.
#include "format.hpp"

#include <string>

namespace pendavg::cli {

// ---------------------------------------------------------------- CSV and text

void append_csv_line(std::string& out, std::span<const std::string> fields) {
  for (std::size_t i = 0; i < fields.size(); ++i) {
    if (i) out += ',';
    out += fields[i];
  }
  out += '\n';
}

}  // namespace pendavg::cli
