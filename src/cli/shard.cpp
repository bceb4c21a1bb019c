// SPDX-License-Identifier: GPL-3.0-or-later
// src/cli/shard.cpp -- see shard.hpp.
#include "shard.hpp"

#include "common.hpp"

#include "files.hpp"
#include "sweep.hpp"
#include "sweep_file.hpp"
#include "sweep_format.hpp"

#include <cerrno>
#include <charconv>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <memory>
#include <utility>
#include <vector>

namespace pendavg::cli {

namespace {

constexpr std::size_t blocks_per_shard = 16;
constexpr std::string_view shard_prefix = "# shard ";

/// "K/N" as two integers (at most 9 digits each), or nothing.
std::optional<std::pair<std::size_t, std::size_t>> parse_fraction(std::string_view text) {
  std::size_t k = 0, n = 0;
  const char* const end = text.data() + text.size();
  const auto [slash, k_error] = std::from_chars(text.data(), end, k);
  if (k_error != std::errc() || slash == end || *slash != '/' || slash - text.data() > 9)
    return std::nullopt;
  const auto [last, n_error] = std::from_chars(slash + 1, end, n);
  if (n_error != std::errc() || last != end || last - slash > 10) return std::nullopt;
  return std::pair{k, n};
}

[[noreturn]] void refuse(const std::string& what) { throw usage_error("merge: " + what); }

/// A failed row of a JSON shard: its row of the sweep and its entry.
struct FailedEntry {
  std::size_t row = 0;
  std::string entry;
};

/// One shard file being merged: its header, then its rows on demand.
struct ShardFile {
  std::string path;
  std::ifstream in;
  io::Format format = io::Format::csv;
  std::string schema;               ///< its output schema ("0": before schema 1)
  std::string shard_line;           ///< its shard line, as CSV writes it
  std::vector<std::string> header;  ///< the header without the shard line (up to the column
                                    ///< line; JSON: up to the "rows": [ line)
  std::vector<FailedEntry> failed;  ///< JSON: its failed rows (in order)
  std::size_t next_failed = 0;
  std::size_t number = 0, shards = 0, rows = 0, block = 0;
};

constexpr std::string_view json_start = "{\"schema\": ";

/// JSON: reads the failed rows and the interruption after the rows (then returns to them).
void read_json_end(ShardFile& f) {
  const std::streampos rows_at = f.in.tellg();
  std::string line;
  while (std::getline(f.in, line) && !line.starts_with(']')) {
  }
  constexpr std::string_view row_prefix = "{\"row\": ";
  bool in_failed = false;
  while (std::getline(f.in, line)) {
    if (line == "\"failed\": [") {
      in_failed = true;
    } else if (in_failed && line.starts_with(row_prefix)) {
      if (line.ends_with(',')) line.pop_back();
      const std::size_t row = std::strtoull(line.c_str() + row_prefix.size(), nullptr, 10);
      if (!f.failed.empty() && row <= f.failed.back().row)
        refuse("'" + f.path + "': its failed rows are out of order");
      f.failed.push_back({row, line});
    } else if (line.starts_with("\"interrupted\": ")) {
      if (line != "\"interrupted\": null}")
        refuse("'" + f.path + "' is incomplete (interrupted: " + line.substr(15, 80) +
               "): complete it with --resume '" + f.path + "' and the same --shard, then merge");
      f.in.clear();
      f.in.seekg(rows_at);
      return;
    } else {
      in_failed = false;
    }
  }
  refuse("'" + f.path + "' ends before its document does (a shard cut short: --resume it)");
}

void open_shard(ShardFile& f) {
  f.in.open(f.path, std::ios::binary);
  if (!f.in) refuse("cannot read '" + f.path + "': " + std::strerror(errno));
  std::string first;
  std::getline(f.in, first);
  if (first.starts_with(json_start)) {  // JSON: the shard line is the first header item
    f.format = io::Format::json;
    f.schema = first.substr(json_start.size(), first.find(',') - json_start.size());
    f.header.push_back(first);
    std::string line;
    if (std::getline(f.in, line)) f.header.push_back(line);
    if (std::getline(f.in, line) && line.starts_with("\"shard ")) {
      if (line.ends_with(',')) line.pop_back();
      f.shard_line = "# " + line.substr(1, line.size() - 2);
    }
  } else {
    f.shard_line = first;
  }
  if (!f.shard_line.starts_with(shard_prefix))
    refuse("'" + f.path + "' is not a shard (its first line is not '# shard K/N ...' or a JSON "
           "document whose first header item is 'shard K/N ...': written by table or average "
           "--cases with --shard K/N)");
  unsigned long long k = 0, n = 0, rows = 0, block = 0;
  if (std::sscanf(f.shard_line.c_str(), "# shard %llu/%llu: blocks of %llu of the %llu rows",
                  &k, &n, &block, &rows) != 4 || k < 1 || k > n || block < 1)
    refuse("'" + f.path + "': its shard line '" + f.shard_line + "' cannot be read");
  f.number = k, f.shards = n, f.rows = rows, f.block = block;
  std::string line;
  if (f.format == io::Format::json) {
    while (std::getline(f.in, line)) {
      f.header.push_back(line);
      if (line == "\"rows\": [") return read_json_end(f);
    }
    refuse("'" + f.path + "' ends before its rows begin");
  }
  f.schema.assign(1, '0');  // none before schema 1
  while (std::getline(f.in, line)) {
    f.header.push_back(line);
    if (line.starts_with("# schema: ")) f.schema = line.substr(10);
    if (!line.starts_with("#")) {  // the column line: CSV's has commas, text's spaces
      f.format = line.find(',') == std::string::npos ? io::Format::text : io::Format::csv;
      return;
    }
  }
  refuse("'" + f.path + "' ends before its column line");
}

/// The next row of `f` (a data line, or a '# failed:' line in place of a row); false at its end.
/// An '# interrupted' line means rows are missing.
bool next_row(ShardFile& f, std::string& line) {
  if (!std::getline(f.in, line)) return false;
  if (f.format == io::Format::json) {  // ,{...} (the first without its comma), up to the ]
    if (line.starts_with(']')) return false;
    if (line.starts_with(',')) line.erase(0, 1);
    if (!line.starts_with('{'))
      refuse("'" + f.path + "' has a line that is not a row: '" + line.substr(0, 80) + "'");
    if (f.in.eof()) refuse("'" + f.path + "' ends in the middle of a row");
    return true;
  }
  if (line.starts_with("# interrupted"))
    refuse("'" + f.path + "' is incomplete (" + line.substr(2) + "): complete it with --resume '" +
           f.path + "' and the same --shard, then merge");
  if (line.starts_with("#") && !line.starts_with("# failed: "))
    refuse("'" + f.path + "' has a line that is not a row: '" + line.substr(0, 80) + "'");
  if (f.in.eof()) refuse("'" + f.path + "' ends in the middle of a row");
  return true;
}

}  // namespace

Shard::Shard(std::size_t number, std::size_t shards, std::size_t rows)
    : number_(number), shards_(shards), rows_(rows),
      block_(std::max<std::size_t>(1, (rows + blocks_per_shard * shards - 1) /
                                          (blocks_per_shard * shards))) {
  for (std::size_t b = number - 1; b * block_ < rows; b += shards)
    count_ += std::min(block_, rows - b * block_);
}

std::string Shard::header_line() const {
  return std::string(shard_prefix) + std::to_string(number_) + "/" + std::to_string(shards_) +
         ": blocks of " + std::to_string(block_) + " of the " + std::to_string(rows_) +
         " rows, those numbered " + std::to_string(number_ - 1) + " mod " +
         std::to_string(shards_) + " (pendavg merge joins the shards)\n";
}

std::optional<Shard> shard_option(const Options& options, std::string_view command,
                                  std::size_t rows) {
  if (!options.has("shard")) return std::nullopt;
  const std::string_view text = options.get("shard", "");
  const auto fraction = parse_fraction(text);
  if (!fraction || fraction->first < 1 || fraction->first > fraction->second)
    throw usage_error(std::string(command) + ": --shard takes K/N with 1 <= K <= N (e.g. 3/8), "
                      "not '" + std::string(text) + "'");
  for (const std::string_view timing : {"timing", "timing-rows"})
    if (options.has(timing))
      throw usage_error(std::string(command) + ": --shard and --" + std::string(timing) +
                        " cannot be combined");
  return Shard(fraction->first, fraction->second, rows);
}

constexpr std::string_view merge_usage =
    "usage: pendavg merge --output FILE SHARD...\n"
    "\n"
    "Joins the files of the shards of one sweep (pendavg table or average with a cases file, run\n"
    "as shard K of N for K = 1..N, e.g. the tasks of a job array: see their help) into FILE,\n"
    "written atomically: the header (without the shard line, with the first shard's date) and\n"
    "every row in the order of the whole sweep, the file one run of the sweep writes. Refuses\n"
    "shards of different sweeps (any other header line differing), a shard given twice, one\n"
    "missing, and a shard that is incomplete (interrupted: resume it as the same shard first)\n"
    "or has extra rows, and shards of different formats (csv, json or text: the merged file\n"
    "has the shards' format). A '# failed:' line (a row that failed; JSON: its entry in\n"
    "\"failed\") is kept in its place; the merge then exits 3.\n";

std::string run_merge(const Options& options) {
  const std::string output(options.required("output"));
  if (output.empty()) refuse("--output needs a file name");
  const std::vector<std::string>& paths = options.operands();
  if (paths.empty()) refuse("no shard files given (pendavg merge --output FILE SHARD...)");
  std::vector<std::unique_ptr<ShardFile>> files;
  for (const std::string& path : paths) {
    refuse_same_file(output, "output", path, "a shard", "merge");
    files.push_back(std::make_unique<ShardFile>());
    files.back()->path = path;
    open_shard(*files.back());
  }
  // One sweep: the same N, rows and blocks, the same header (up to the date), each K once.
  const ShardFile& first = *files.front();
  std::vector<ShardFile*> by_number(first.shards, nullptr);
  for (const auto& f : files) {
    if (f->shards != first.shards || f->rows != first.rows || f->block != first.block)
      refuse("'" + f->path + "' is shard " + std::to_string(f->number) + "/" +
             std::to_string(f->shards) + " of " + std::to_string(f->rows) + " rows, '" +
             first.path + "' of " + std::to_string(first.shards) + " shards of " +
             std::to_string(first.rows) + " rows: not shards of one sweep");
    if (f->format != first.format)
      refuse("'" + f->path + "' is a " + std::string(format_name(f->format)) + " shard, '" +
             first.path + "' a " + std::string(format_name(first.format)) +
             " shard: the shards of one sweep are written in one format");
    if (f->schema != first.schema)
      refuse("'" + f->path + "' has output schema " + f->schema + ", '" + first.path +
             "' schema " + first.schema + ": shards written by different pendavg versions");
    bool same = f->header.size() == first.header.size();
    for (std::size_t k = 0; same && k < first.header.size(); ++k)
      same = same_header_line(first.header[k], f->header[k]);
    if (!same)
      refuse("'" + f->path + "' and '" + first.path + "' are shards of different sweeps (their "
             "headers differ)");
    ShardFile*& slot = by_number[f->number - 1];
    if (slot)
      refuse("'" + slot->path + "' and '" + f->path + "' are both shard " +
             std::to_string(f->number) + "/" + std::to_string(f->shards) + " (overlapping rows)");
    slot = f.get();
  }
  for (std::size_t k = 0; k < by_number.size(); ++k)
    if (!by_number[k])
      refuse("shard " + std::to_string(k + 1) + "/" + std::to_string(first.shards) +
             " is missing (its rows would be missing)");
  std::string text;
  for (const std::string& line : first.header) text += line + "\n";
  AtomicFile file(output, "merge");
  std::string line;
  std::size_t failed = 0;
  const bool json = first.format == io::Format::json;
  std::vector<std::string> failed_entries;  // JSON: after the rows
  bool first_row = true;
  for (std::size_t b = 0; b * first.block < first.rows; ++b) {
    ShardFile& f = *by_number[b % first.shards];
    for (std::size_t r = b * first.block; r < std::min(first.rows, (b + 1) * first.block); ++r) {
      if (json && f.next_failed < f.failed.size() && f.failed[f.next_failed].row == r) {
        failed_entries.push_back(std::move(f.failed[f.next_failed++].entry));
        ++failed;
        continue;
      }
      if (!next_row(f, line))
        refuse("'" + f.path + "' ends before its rows do (row " + std::to_string(r) +
               " of the sweep is missing)");
      failed += line.starts_with("#");
      if (json && !std::exchange(first_row, false)) text += ',';
      (text += line) += '\n';
    }
    if (text.size() >= (1u << 20)) {
      file.append(text);
      text.clear();
    }
  }
  for (const auto& f : files)
    if (next_row(*f, line) || f->next_failed < f->failed.size())
      refuse("'" + f->path + "' has more rows than its shard's blocks");
  if (json) text += json_end(failed_entries, {});
  file.append(text);
  file.commit();
  if (failed > 0)
    throw rows_failed("merge: " + std::to_string(failed) + " of " + std::to_string(first.rows) +
                      " rows failed while they were computed; '" + output + "' has a '# failed:' "
                      "line in place of each; --resume the shards that have them, then merge again");
  return {};
}

constexpr std::array<std::string_view, 1> merge_options{"output"};
const Command merge_command{"merge", merge_usage, merge_options, run_merge, {}, false, true};

}  // namespace pendavg::cli
