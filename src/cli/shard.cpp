// SPDX-License-Identifier: GPL-3.0-or-later
// src/cli/shard.cpp -- see shard.hpp.
#include "shard.hpp"

#include "common.hpp"

#include "files.hpp"
#include "interrupt.hpp"
#include "sweep.hpp"
#include "sweep_file.hpp"
#include "sweep_format.hpp"

#include <cerrno>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <algorithm>
#include <filesystem>
#include <map>
#include <memory>
#include <utility>
#include <vector>

#include <sys/resource.h>

namespace pendavg::cli {

namespace {

constexpr std::size_t blocks_per_shard = 16;
/// Beyond any sweep: a shard line claiming more is not one --shard wrote.
constexpr unsigned long long max_shards = 999'999'999, max_rows = 1ull << 53;

[[noreturn]] void refuse(const std::string& what) {
  // A signal that cut a read short (a shard from a pipe that waits, a FIFO being opened) is the
  // signal's, not the shard's.
  if (stop_flag().load()) throw interrupted("merge: stopped by a signal; nothing written");
  throw usage_error("merge: " + what);
}

/// One shard's file being merged: its header without the shard line, then its rows on demand.
struct ShardFile {
  std::string path;
  /// stdio, not a stream: a read that a signal interrupts returns (std::ifstream reads again).
  std::unique_ptr<std::FILE, int (*)(std::FILE*)> file;
  bool json = false;
  std::vector<std::string> header;  ///< up to the column line (JSON: the "rows": [ line)
  unsigned long long number = 0, shards = 0, rows = 0, block = 0;
  std::map<std::size_t, std::string> failed;  ///< JSON: the failed rows' entries not merged yet
  std::optional<RowReader> reader;  ///< checks each row whole, as --resume does

  explicit ShardFile(const std::string& file_path)
      : path(file_path), file(std::fopen(file_path.c_str(), "rb"), &std::fclose) {
    if (!file)
      refuse("cannot read '" + path + "': " + std::strerror(errno) +
             (errno == EMFILE ? " (more shards than this process may open: see ulimit -n)" : ""));
    if (std::filesystem::is_directory(path)) refuse("'" + path + "' is a directory, not a shard");
    std::string line, shard;  // the shard line: after '# schema: 1', JSON's first header item
    bool rows_begin = false;
    while (!rows_begin && read_line(file.get(), line)) {
      json = json || (header.empty() && shard.empty() && line.starts_with("{\"schema\": "));
      if (shard.empty() && line.starts_with(json ? "\"shard " : "# shard ")) {
        shard = line.substr(json ? 1 : 2);
        continue;
      }
      header.push_back(line);
      rows_begin = json ? line == "\"rows\": [" : !line.starts_with('#');
    }
    if (shard.empty())
      refuse("'" + path + "' is not a shard (it has no line '# shard K/N ...', or JSON header "
             "item 'shard K/N ...', written by table or average --cases with --shard K/N)");
    // The line --shard writes: K/N as --shard takes them, B as the rule makes it of N and rows.
    if (std::sscanf(shard.c_str(), "shard %llu/%llu: blocks of %llu of the %llu rows", &number,
                    &shards, &block, &rows) != 4 || number < 1 || number > shards ||
        shards > max_shards || rows > max_rows || block != Shard(1, shards, rows).block())
      refuse("'" + path + "': its shard line '" + shard.substr(0, 120) + "' is not one that "
             "--shard K/N writes");
    if (!rows_begin) refuse("'" + path + "' ends before its rows begin");
    if (json) read_json_end();
    reader.emplace(row_writer_of(format(), header[header.size() - 1 - json]));
  }

  /// JSON: the failed rows' entries and the interruption follow the rows: read first, and
  /// checked to be the end the writer gives a complete shard (json_end) byte for byte.
  void read_json_end() {
    const off_t rows_at = ftello(file.get());
    if (rows_at < 0)  // before anything is read: a pipe that waits would hold up a signal
      refuse("'" + path + "' cannot be read twice (a pipe?): a JSON shard must be a file");
    std::string line, end;
    while (read_line(file.get(), line) && !line.starts_with(']')) {
    }
    end = line + "\n";
    char buffer[1 << 16];
    for (std::size_t n; !std::ferror(file.get()) &&
                        (n = std::fread(buffer, 1, sizeof buffer, file.get())) > 0;)
      end.append(buffer, n);
    if (std::ferror(file.get())) refuse("cannot read '" + path + "': " + std::strerror(errno));
    std::vector<std::string> entries;
    for (std::size_t at = end.find("\n{\"row\": "); at != std::string::npos;
         at = end.find("\n{\"row\": ", at + 1)) {
      std::string entry = end.substr(at + 1, end.find('\n', at + 1) - at - 1);
      if (entry.ends_with(',')) entry.pop_back();
      const std::size_t row = std::strtoull(entry.c_str() + 8, nullptr, 10);
      if (!failed.empty() && row <= failed.rbegin()->first) break;  // out of order: refused below
      failed.emplace(row, entry);
      entries.push_back(std::move(entry));
    }
    if (end != json_end(entries, {})) {
      if (!line.starts_with(']')) incomplete("it ends before its document does");
      if (const std::size_t at = end.find("\n\"interrupted\": \""); at != std::string::npos)
        incomplete("interrupted: " +
                   end.substr(at + 16, std::min<std::size_t>(80, end.find("\"}", at) - at - 15)));
      refuse("'" + path + "': what follows its rows is not the end of a shard pendavg writes");
    }
    if (fseeko(file.get(), rows_at, SEEK_SET) != 0)
      refuse("cannot read '" + path + "' again: " + std::strerror(errno));
  }

  io::Format format() const {
    return json ? io::Format::json
           : header.back().find(',') == std::string::npos ? io::Format::text : io::Format::csv;
  }

  [[noreturn]] void incomplete(const std::string& why) const {
    refuse("'" + path + "' is incomplete (" + why + "): complete it with --resume '" + path +
           "' and the same --shard, then merge");
  }

  /// The next row (a data line, or a '# failed:' line in place of a row); false at the end.
  bool next_row(std::string& line) {
    bool ended = false;
    if (!read_line(file.get(), line, &ended)) {
      if (std::ferror(file.get())) refuse("cannot read '" + path + "': " + std::strerror(errno));
      return false;
    }
    if (json && line.starts_with(']')) return false;
    if (line.starts_with("# interrupted")) incomplete(line.substr(2));
    if (json ? !line.starts_with('{') && !line.starts_with(",{")
             : line.starts_with('#') && !line.starts_with("# failed: "))
      refuse("'" + path + "' has a line that is not a row: '" + line.substr(0, 80) + "'");
    if (!ended) refuse("'" + path + "' ends in the middle of a row");
    if (!line.starts_with('#') && !reader->read(line, true))
      refuse("'" + path + "' has a damaged row: '" + line.substr(0, 80) + "' (--resume it with its "
             "--shard to compute the row again)");
    if (json && !line.starts_with(',')) line.insert(0, 1, ',');  // SweepFile drops the first's
    return true;
  }
};

}  // namespace

Shard::Shard(std::size_t number, std::size_t shards, std::size_t rows)
    : number_(number), shards_(shards), rows_(rows),
      block_(std::max<std::size_t>(1, rows / (blocks_per_shard * shards) +
                                          (rows % (blocks_per_shard * shards) != 0))) {
  for (std::size_t b = number - 1; b * block_ < rows; b += shards)
    count_ += std::min(block_, rows - b * block_);
}

std::string Shard::marked(std::string header) const {
  return header.insert(header.find('\n') + 1,
                       "# shard " + std::to_string(number_) + "/" +
                           std::to_string(shards_) + ": blocks of " + std::to_string(block_) +
                           " of the " + std::to_string(rows_) + " rows, those numbered " +
                           std::to_string(number_ - 1) + " mod " + std::to_string(shards_) +
                           " (pendavg merge joins the shards)\n");
}

std::optional<Shard> shard_option(const Options& options, std::string_view command,
                                  std::size_t rows) {
  if (!options.has("shard")) return std::nullopt;
  // K/N: digits only, at most 9 each (N <= max_shards), nothing after them.
  const std::string text(options.get("shard", ""));
  unsigned long k = 0, n = 0;
  int length = 0;
  if (text.find_first_not_of("0123456789/") != std::string::npos ||
      std::sscanf(text.c_str(), "%9lu/%9lu%n", &k, &n, &length) != 2 ||
      length != static_cast<int>(text.size()) || k < 1 || k > n)
    throw usage_error(std::string(command) + ": --shard takes K/N with 1 <= K <= N <= " +
                      std::to_string(max_shards) + " (e.g. 3/8), not '" + text + "'");
  for (const std::string_view timing : {"timing", "timing-rows"})
    if (options.has(timing))
      throw usage_error(std::string(command) + ": --shard and --" + std::string(timing) +
                        " cannot be combined");
  return Shard(k, n, rows);
}

constexpr std::string_view merge_usage =
    "usage: pendavg merge --output FILE SHARD...\n"
    "\n"
    "Joins the files of the shards of one sweep (pendavg table or average with a cases file, run\n"
    "as shard K of N for K = 1..N, e.g. the tasks of a job array: see their help) into FILE,\n"
    "written atomically: the header (shard 1's, without the shard line: its date) and\n"
    "every row in the order of the whole sweep, the file one run of the sweep writes. Refuses\n"
    "shards of different sweeps (any other header line differing), a shard given twice, one\n"
    "missing, and a shard that is incomplete (interrupted: resume it as the same shard first)\n"
    "or has extra rows, and shards of different formats (csv, json or text: the merged file\n"
    "has the shards' format). A '# failed:' line (a row that failed; JSON: its entry in\n"
    "\"failed\") is kept in its place; the merge then exits 3.\n";

std::string run_merge(const Options& options) {
  const std::string output(options.required("output"));
  if (output.empty()) refuse("--output needs a file name");
  if (options.operands().empty())
    refuse("no shard files given (pendavg merge --output FILE SHARD...)");
  const StopOnSignal signals;
  // Every shard stays open (the rows interleave by blocks): as many files as the system allows.
  if (rlimit limit{}; getrlimit(RLIMIT_NOFILE, &limit) == 0 && limit.rlim_cur < limit.rlim_max) {
    limit.rlim_cur = limit.rlim_max;
    setrlimit(RLIMIT_NOFILE, &limit);
  }
  std::vector<std::unique_ptr<ShardFile>> files;
  for (const std::string& path : options.operands()) {
    // A signal while the shards before were read ends the merge (refuse: interrupted) before an
    // open that may wait (a FIFO).
    if (stop_flag().load()) refuse("");
    refuse_same_file(output, "output", path, "a shard", "merge");
    files.push_back(std::make_unique<ShardFile>(path));
  }
  // One sweep: the same N, rows and blocks, the same header (up to the date), each K once. A
  // shard of another format or output schema has another header line: the refusal names it.
  const ShardFile& first = *files.front();
  std::map<unsigned long long, ShardFile*> numbered;
  for (const auto& f : files) {
    if (f->shards != first.shards || f->rows != first.rows)
      refuse("'" + f->path + "' is shard " + std::to_string(f->number) + "/" +
             std::to_string(f->shards) + " of " + std::to_string(f->rows) + " rows, '" +
             first.path + "' of " + std::to_string(first.shards) + " shards of " +
             std::to_string(first.rows) + " rows: not shards of one sweep");
    if (f->format() != first.format())
      refuse("'" + f->path + "' is a " + std::string(format_name(f->format())) + " shard, '" +
             first.path + "' a " + std::string(format_name(first.format())) +
             " shard: one sweep's shards have one format");
    const auto [theirs, ours] =
        std::ranges::mismatch(f->header, first.header, [](const auto& a, const auto& b) {
          return same_header_line(b, a);
        });
    if (theirs != f->header.end() || ours != first.header.end())
      refuse("'" + f->path + "' and '" + first.path + "' are shards of different sweeps: the "
             "line '" + (theirs == f->header.end() ? "" : theirs->substr(0, 100)) + "' of one "
             "is '" + (ours == first.header.end() ? "" : ours->substr(0, 100)) + "' in the other");
    if (const auto [at, added] = numbered.emplace(f->number, f.get()); !added)
      refuse("'" + at->second->path + "' and '" + f->path + "' are both shard " +
             std::to_string(f->number) + "/" + std::to_string(f->shards) + " (overlapping rows)");
  }
  if (numbered.size() != first.shards) {  // the first number not given
    unsigned long long missing = 1;
    for (auto at = numbered.begin(); at != numbered.end() && at->first == missing; ++at) ++missing;
    refuse("shard " + std::to_string(missing) + "/" + std::to_string(first.shards) +
           " is missing (its rows would be missing)");
  }
  std::string header, line;  // the header: shard 1's (its date, its cases file's path)
  for (const std::string& header_line : numbered.at(1)->header) (header += header_line) += '\n';
  SweepFile out(output, "merge", header, nullptr, first.format());
  std::size_t failed = 0;
  for (std::size_t r = 0; r < first.rows; ++r) {
    if (stop_flag().load(std::memory_order_relaxed))
      throw interrupted("merge: stopped by a signal; nothing written to '" + output + "'");
    ShardFile& f = *numbered.at(r / first.block % first.shards + 1);
    if (const auto entry = f.failed.find(r); entry != f.failed.end()) {
      out.add_failed(std::move(f.failed.extract(entry).mapped()));
      ++failed;
      continue;
    }
    if (!f.next_row(line))
      refuse("'" + f.path + "' ends before its rows do (row " + std::to_string(r) +
             " of the sweep is missing)");
    failed += line.starts_with('#');
    out.write_rows(r, 1, line += '\n', {});
  }
  for (const auto& f : files)
    if (f->next_row(line) || !f->failed.empty())
      refuse("'" + f->path + "' has more rows than its shard's blocks");
  out.end_rows({});
  out.commit();
  if (failed > 0)
    throw rows_failed("merge: " + std::to_string(failed) + " of " + std::to_string(first.rows) +
                      " rows failed while they were computed; '" + output + "' has " +
                      (first.json ? "an entry in \"failed\" for each"
                                  : "a '# failed:' line in place of each") +
                      "; --resume the shards that have them, then merge again");
  return {};
}

constexpr std::array<std::string_view, 1> merge_options{"output"};
const Command merge_command{"merge", merge_usage, merge_options, run_merge, {}, false, true};

}  // namespace pendavg::cli
