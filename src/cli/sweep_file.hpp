// SPDX-License-Identifier: GPL-3.0-or-later
// src/cli/sweep_file.hpp -- where a sweep's rows go (sweep.hpp's SweepOutput on rank 0): stdout
// or an atomically written file (files.hpp), after a header, streamed in row order; and the rows
// of an earlier, interrupted run of the same sweep (--resume), which are kept instead of being
// computed again.
//
// A sweep file (CSV; text and JSON alike, line by line: sweep_format.hpp) is '#' lines (the
// header), the column line, the rows, and possibly an '# interrupted: ...' line at the end. Resuming checks the earlier file's header and column
// line against this run's (everything but the date of its "# pendavg VERSION, generated DATE"
// line: the parameters, method, digits and version must agree) and finds each earlier row's
// index from its leading fields (its parameters), in order, so rows missing anywhere are
// computed and the finished file is the one an uninterrupted run writes. A row is kept only when
// it is whole (its newline, the column line's number of fields, each a number, a word or empty);
// a damaged one, and a '# failed:' line (a row that failed), are computed again. A run killed
// outright (SIGKILL) leaves its rows in its temporary (files.hpp), written in order as they were
// finished, and the rows it had finished ahead of an unfinished one in a second temporary
// (SweepFile::keep_ahead: the same header, those rows in index order); --resume takes them from
// both.
#pragma once

#include "files.hpp"
#include "sweep.hpp"
#include "sweep_format.hpp"

#include <cstdint>
#include <cstdio>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace pendavg::cli {

/// The rows of earlier outputs of the same sweep: the file itself, and the temporaries of it
/// that writers killed outright left on this host (files.hpp: dead_temporaries; a SIGKILL, the
/// OOM killer: the rows they had written, in order, the last one possibly cut short). Each is
/// checked as the file is (a temporary cut short within its header has no rows and is passed
/// over); a row any of them holds whole is kept.
class ResumedRows {
 public:
  /// Reads `path` (when it exists) and its dead writers' temporaries and checks them against
  /// `header` (this run's header as written: '#' lines and column line, or JSON's lines up to
  /// its rows) and `rows` (this run's format, columns and widths; a file of another format is
  /// refused); `key(index)` is row `index`'s
  /// leading `key_fields` fields joined by commas (a row that produces no line returns an empty
  /// key). Throws usage_error (one line, naming `command` and the option) on a mismatch.
  ResumedRows(const std::string& path, std::string_view command, const std::string& header,
              const io::RowWriter& rows, std::size_t count, std::size_t key_fields,
              const std::function<std::string(std::size_t)>& key);
  ResumedRows(const ResumedRows&) = delete;
  ResumedRows& operator=(const ResumedRows&) = delete;

  bool kept(std::size_t index) const { return from_[index] != 0; }
  std::size_t kept_count() const { return kept_count_; }
  /// Kept row `index`'s line (with its newline); asked for in index order.
  const std::string& row(std::size_t index);

 private:
  struct Source {
    std::string path;
    std::unique_ptr<std::FILE, int (*)(std::FILE*)> file{nullptr, &std::fclose};
    std::vector<bool> used;  ///< for each of its whole rows: kept from here
    std::size_t next = 0;    ///< its whole rows read so far (row())
  };
  /// Reads one source's header and rows; false for a temporary cut short within its header.
  bool read_source(Source& source, std::size_t number, const std::vector<std::string_view>& header,
                   std::size_t key_fields, const std::function<std::string(std::size_t)>& key);
  std::string path_, command_;
  std::vector<Source> sources_;
  std::vector<std::uint8_t> from_;  ///< per row: 1 + the source it is kept from, 0: not kept
  std::size_t kept_count_ = 0;
  RowReader reader_;  ///< the rows in this run's format
  std::string line_;
};

/// A sweep's output: the header at once, then the rows in order (SweepOutput), then commit().
class SweepFile : public SweepOutput {
 public:
  /// `path` empty: stdout. `resumed` (may be null) supplies kept rows. `format`: the rows'
  /// (JSON: each row's line starts with the comma that separates it from the one before, which
  /// the first row written drops; a '# failed:' line goes to the "failed" list at the end).
  SweepFile(const std::string& path, std::string_view command, const std::string& header,
            ResumedRows* resumed, io::Format format = io::Format::csv);
  bool kept(std::size_t index) const override { return resumed_ && resumed_->kept(index); }
  std::size_t kept_count() const override { return resumed_ ? resumed_->kept_count() : 0; }
  void write_kept(std::size_t index) override;
  void write_rows(std::size_t first, std::size_t count, std::string_view text,
                  std::span<const double> row_us) override;
  /// Called with every computed row's times (SweepRows::timing).
  std::function<void(std::size_t first, std::span<const double> row_us)> on_timing;

  /// JSON: the sweep's row (the one a failed row's entry names) of row `index` of this run
  /// (a shard's rows are the sweep's rows shard.row(index)); unset: `index`.
  std::function<std::size_t(std::size_t index)> row_number;

  void append(std::string_view text);
  /// JSON: a failed row's entry as a shard holds it (merge), for the "failed" list at the end.
  void add_failed(std::string entry) { failed_.push_back(std::move(entry)); }
  /// After the last row: the format's end (CSV and text: an '# interrupted: ' line when
  /// `interrupted` is not empty; JSON: the failed rows, the interruption and the closing brace).
  void end_rows(std::string_view interrupted);
  /// Writes out what is buffered (SweepOutput: rank 0 is about to wait).
  void flush() override;
  /// A file's rows that wait ahead of an unfinished one go to a second temporary of the target
  /// (the header and those rows), which --resume reads as it reads the file's own temporary
  /// after a SIGKILL; each call replaces it (a new one written before the old one is removed).
  void keep_ahead(std::string_view rows) override;
  /// Flushes; a file is renamed into place.
  void commit();
  /// A file's temporary is removed (nothing is written); stdout keeps what it got.
  void discard();

 private:
  void write_out(std::string_view text);
  /// JSON: rows first.. as computed (a row a line, each after its comma; a '# failed:' line in
  /// place of a failed row).
  void json_rows(std::size_t first, std::string_view text);
  std::optional<AtomicFile> file_;
  std::unique_ptr<AtomicFile> ahead_;  ///< never committed: removed when replaced or done
  bool ahead_failed_ = false;          ///< a copy could not be written: no more are tried
  ResumedRows* resumed_ = nullptr;
  std::string command_, header_, buffer_;
  bool json_ = false;
  bool first_row_ = true;            ///< JSON: no row written yet (its comma is dropped)
  std::vector<std::string> failed_;  ///< JSON: the failed rows' entries, until the end
};

/// The header lines of a sweep as this run writes them, for ResumedRows: '#' lines and the
/// column line. Lines containing ", generated " compare only up to it.
bool same_header_line(std::string_view expected, std::string_view found);

/// The line of a row that failed once the sweep ran (SweepRows::failed_row): "# failed: " and
/// `context` (which row) and `reason`, as one line (control characters escaped, long values cut:
/// one_line.hpp). A CSV reader that skips '#' lines skips it; --resume computes the row again.
std::string failed_row_line(std::string_view context, std::string_view reason);

/// The error of a sweep that completed with failed rows: how many of how many `unit`, where
/// they are (`path`, or stdout when empty), the first one (`first_context`, its reason) and
/// that --resume computes them again.
std::string failed_rows_message(std::string_view command, const SweepOutcome& outcome,
                                std::string_view unit, const std::string& path,
                                std::string_view first_context,
                                io::Format format = io::Format::csv);

/// FNV-1a 64-bit hash of `text` as 16 hex digits (identifies an input file in a header).
std::string fnv1a_hex(std::string_view text);

}  // namespace pendavg::cli
