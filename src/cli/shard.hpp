// SPDX-License-Identifier: GPL-3.0-or-later
// src/cli/shard.hpp -- a sweep split over the tasks of a job array without MPI: `--shard K/N`
// (table, average --cases) computes shard K of N into its own file, and `pendavg merge` joins the
// N files into the file one run of the whole sweep writes.
//
// The rows are cut into blocks of B consecutive rows, B = ceil(rows / (16 N)) (so that each
// shard gets ~16 blocks spread over the sweep, whose cost often grows along it); shard K takes
// blocks K-1, K-1+N, K-1+2N, ... A pure function of the row count and N: no timing, no
// coordination. A shard's file is the sweep's file (header, column line, its rows in order) with
// one more header line after '# schema: 1' (JSON: the first header item) naming the shard, which
// --resume and merge check.
#pragma once

#include "args.hpp"

#include <cstddef>
#include <optional>
#include <string>
#include <string_view>
#include <utility>

namespace pendavg::cli {

class Shard {
 public:
  /// Shard `number` (1..shards) of a sweep of `rows` rows.
  Shard(std::size_t number, std::size_t shards, std::size_t rows);
  std::size_t count() const { return count_; }  ///< rows of this shard
  std::size_t block() const { return block_; }  ///< rows of a block
  /// The sweep's row of this shard's row `local` (0..count()-1).
  std::size_t row(std::size_t local) const {
    return (number_ - 1 + shards_ * (local / block_)) * block_ + local % block_;
  }
  /// The sweep's CSV header `header` with the shard's line after its first line (the schema's).
  std::string marked(std::string header) const;

 private:
  std::size_t number_, shards_, rows_, block_, count_ = 0;
};

/// `header` as a shard's file has it (Shard::marked), or as it is without a shard.
inline std::string marked(const std::optional<Shard>& shard, std::string header) {
  return shard ? shard->marked(std::move(header)) : header;
}

/// --shard K/N of `command` (nothing when not given) for a sweep of `rows` rows; usage_error for
/// a malformed value or K outside 1..N.
std::optional<Shard> shard_option(const Options& options, std::string_view command,
                                  std::size_t rows);

}  // namespace pendavg::cli
