// SPDX-License-Identifier: GPL-3.0-or-later
// src/io/migration.hpp -- the names of schema 0 (pendavg 0.2) that schema 1 renamed: one table,
// from which --columns accepts the old names (an old column set, old headers included, can be
// reproduced) and the README's migration table is checked.
#pragma once

#include <cstddef>
#include <span>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

namespace pendavg::io {

/// One renamed key or column family of schema 0.
struct Rename {
  std::string_view old_name;  ///< schema 0's key, or its per-particle stem (error_K: error_K1..N)
  std::string_view new_name;  ///< schema 1's field (empty: a column that went away)
  bool per_particle;          ///< CSV: old_name + i -> column_name(new field, i)
  std::string_view where;     ///< the outputs that used the old name
  /// The Python result class of pendavg 0.2 that had old_name as an attribute (Averages,
  /// SimulationResult; empty: none): the package keeps it there as a deprecated alias of
  /// new_name (where the class has that field).
  std::string_view python = {};
};

/// Every rename of schema 0 -> 1.
std::span<const Rename> schema0_renames();

/// The CSV columns (old name, new name) an old column name or old per-particle stem stands for,
/// for a chain of `particles`; empty when `old_name` is not a renamed schema-0 column.
std::vector<std::pair<std::string, std::string>> schema0_columns(std::string_view old_name,
                                                                 std::size_t particles);

}  // namespace pendavg::io
