// SPDX-License-Identifier: GPL-3.0-or-later
// src/cli/sweep_file.cpp -- see sweep_file.hpp.
#include "sweep_file.hpp"

#include "args.hpp"
#include "one_line.hpp"
#include "sweep_format.hpp"

#include <algorithm>
#include <cerrno>
#include <cstdlib>
#include <cstring>
#include <exception>
#include <utility>

#include <unistd.h>

namespace pendavg::cli {

namespace {

constexpr std::size_t flush_bytes = 1u << 20;
constexpr std::size_t direct_bytes = 1u << 16;  ///< longer pieces are written unbuffered
constexpr std::string_view generated = ", generated ";

std::string shortened(std::string_view line) {
  return std::string(line.substr(0, 120)) + (line.size() > 120 ? "..." : "");
}

constexpr std::string_view schema_prefix = "# schema: ";
constexpr std::string_view version_prefix = "# pendavg ";

/// A short word as a file's header names a schema or a version by (letters, digits, '.', '-',
/// '+', '_'; at most 40), or empty.
std::string_view header_word(std::string_view text) {
  if (text.empty() || text.size() > 40) return {};
  for (const char c : text)
    if (!((c >= '0' && c <= '9') || (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') ||
          c == '.' || c == '-' || c == '+' || c == '_'))
      return {};
  return text;
}

/// When `file` is an output of pendavg (its '#' lines before the column line hold the
/// "# pendavg VERSION, generated DATE" line) of another output schema than this run's header
/// `expected` names (its "# schema: S" line), the reason a resume cannot use it, e.g. "was
/// written with output schema 0 (pendavg 0.2.0: it has no '# schema:' line); this pendavg writes
/// schema 1"; empty otherwise (the same schema, or a file that is not recognisably pendavg's:
/// the line-by-line comparison speaks for those). Leaves `file` at its start.
std::string other_schema(std::FILE* file, const std::vector<std::string_view>& expected) {
  std::string_view ours;
  for (const std::string_view line : expected)
    if (line.starts_with(schema_prefix)) {
      ours = line.substr(schema_prefix.size());
      break;
    }
  if (ours.empty()) return {};
  std::string line, theirs, version;
  bool has_schema = false, ended = true;
  while (read_line(file, line, &ended) && ended && !line.empty() && line.front() == '#') {
    if (!has_schema && line.starts_with(schema_prefix)) {
      has_schema = true;
      theirs = line.substr(schema_prefix.size());
    } else if (version.empty() && line.starts_with(version_prefix)) {
      const std::size_t cut = line.find(generated);
      if (cut != std::string::npos)
        version = header_word(std::string_view(line).substr(
            version_prefix.size(), cut - version_prefix.size()));
    }
  }
  std::rewind(file);
  if (has_schema ? theirs == ours : version.empty()) return {};
  std::string reason = "was written with output schema ";
  if (has_schema) {
    const std::string_view word = header_word(theirs);
    reason += word.empty() ? "'" + shortened(theirs) + "'" : std::string(word);
    if (!version.empty()) reason += " (pendavg " + version + ")";
  } else {
    reason += "0 (pendavg " + version + ": it has no '# schema:' line)";
  }
  return reason + "; this pendavg writes schema " + std::string(ours);
}

}  // namespace

std::string failed_row_line(std::string_view context, std::string_view reason) {
  return "# failed: " + one_line(std::string(context) + std::string(reason)) + "\n";
}

std::string failed_rows_message(std::string_view command, const SweepOutcome& outcome,
                                std::string_view unit, const std::string& path,
                                std::string_view first_context, io::Format format) {
  std::string message = std::string(command) + ": " + std::to_string(outcome.failed_rows) +
                        " of " + std::to_string(outcome.count) + " " + std::string(unit) +
                        " failed while they were computed; ";
  message += path.empty() ? "the output" : "'" + path + "'";
  message += format == io::Format::json
                 ? " has every other finished row and an entry in \"failed\" for each; the first: "
                 : " has every other finished row and a '# failed:' line in place of each; the "
                   "first: ";
  message += std::string(first_context) + outcome.first_failed_reason;
  if (!path.empty()) message += "; --resume '" + path + "' computes the failed rows again";
  return message;
}

bool same_header_line(std::string_view expected, std::string_view found) {
  const std::size_t cut = expected.find(generated);
  if (cut == std::string_view::npos) return expected == found;
  return found.substr(0, cut + generated.size()) == expected.substr(0, cut + generated.size());
}

std::string fnv1a_hex(std::string_view text) {
  std::uint64_t hash = 0xcbf29ce484222325ull;
  for (const char c : text) {
    hash ^= static_cast<unsigned char>(c);
    hash *= 0x100000001b3ull;
  }
  char buffer[17];
  std::snprintf(buffer, sizeof buffer, "%016llx", static_cast<unsigned long long>(hash));
  return buffer;
}

ResumedRows::ResumedRows(const std::string& path, std::string_view command,
                         const std::string& header, const io::RowWriter& rows, std::size_t count,
                         std::size_t key_fields, const std::function<std::string(std::size_t)>& key)
    : path_(path), command_(command), from_(count, 0), reader_(rows) {
  // The header: every '#' line and the column line, as this run writes them.
  std::vector<std::string_view> expected;
  for (std::size_t begin = 0; begin < header.size();) {
    const std::size_t end = header.find('\n', begin);
    expected.push_back(std::string_view(header).substr(begin, end - begin));
    begin = end == std::string::npos ? header.size() : end + 1;
  }
  std::vector<std::string> paths;
  if (std::FILE* file = std::fopen(path_.c_str(), "rb")) {
    std::fclose(file);
    paths.push_back(path_);
  } else if (errno != ENOENT) {
    throw usage_error(command_ + ": --resume '" + path_ + "': cannot read it: " +
                      std::strerror(errno));
  }
  for (std::string& dead : dead_temporaries(resolved_path(path_, command_)))
    if (paths.size() < 255) paths.push_back(std::move(dead));  // from_ counts 255 sources
  for (std::string& source_path : paths) {
    sources_.emplace_back().path = std::move(source_path);
    if (!read_source(sources_.back(), sources_.size(), expected, key_fields, key))
      sources_.pop_back();
  }
}

bool ResumedRows::read_source(Source& source, std::size_t number,
                              const std::vector<std::string_view>& expected,
                              std::size_t key_fields,
                              const std::function<std::string(std::size_t)>& key) {
  const bool temporary = source.path != path_;
  const std::string where = command_ + ": --resume '" + path_ + "'" +
                            (temporary ? ": '" + source.path + "', left by a killed run," : "");
  source.file.reset(std::fopen(source.path.c_str(), "rb"));
  std::FILE* const file = source.file.get();
  if (!file) {
    if (temporary && errno == ENOENT) return false;  // removed since it was listed
    throw usage_error(where + ": cannot read it: " + std::strerror(errno));
  }
  // A file of another format: named as such (the line-by-line comparison would name a line).
  if (const SweepFileKind kind = sweep_file_kind(file); kind.format) {
    if (*kind.format != reader_.format())
      throw usage_error(where + " holds --format " + std::string(format_name(*kind.format)) +
                        " output; this run writes --format " +
                        std::string(format_name(reader_.format())) + " (give --format " +
                        std::string(format_name(*kind.format)) + " to continue it)");
    if (*kind.format == io::Format::json && kind.schema != std::to_string(io::schema_version))
      throw usage_error(where + " was written with output schema '" + shortened(kind.schema) +
                        "'; this pendavg writes schema " + std::to_string(io::schema_version) +
                        " -- start a new file with --output");
  }
  // A file of another output schema (an older pendavg's: other columns, other number formats)
  // is named as such, not as a line that differs.
  if (const std::string reason = other_schema(file, expected); !reason.empty())
    throw usage_error(where + " " + reason + " -- " +
                      (temporary ? "remove it, or write the file afresh with --output"
                                 : "start a new file with --output, or complete this one with "
                                   "the pendavg that wrote it"));
  std::string line;
  bool ended = true;
  for (const std::string_view want : expected) {
    const bool read = read_line(file, line, &ended);
    // A temporary killed before its header was out has no rows.
    if (temporary && (!read || !ended)) return false;
    if (!read)
      throw usage_error(where + ": not an output of this sweep (it ends before its header does)");
    if (!same_header_line(want, line))
      throw usage_error(where + " is not an output of this sweep: its line '" + shortened(line) +
                        "' differs from '" + shortened(want) + "' (same parameters, method, "
                        "digits, version and columns are needed)" +
                        (temporary ? "; remove it, or write the file afresh with --output" : ""));
  }
  const long rows_at = std::ftell(file);
  // The rows, matched to indices in order; a damaged one is left to be computed again.
  std::size_t index = 0, row_number = 0;
  while (read_line(file, line, &ended)) {
    if (reader_.ends_rows(line)) break;
    if (!reader_.is_row(line)) continue;
    ++row_number;
    if (!reader_.read(line, ended)) continue;
    while (index < from_.size() && !reader_.has_key(key(index), key_fields)) ++index;
    if (index == from_.size())
      throw usage_error(where + ": its data row " + std::to_string(row_number) + " ('" +
                        shortened(reader_.leading(key_fields)) +
                        ",...') is not a row of this sweep, or out of order");
    const bool first = from_[index] == 0;  // rows held by two sources are the same
    source.used.push_back(first);
    if (first) {
      from_[index] = static_cast<std::uint8_t>(number);
      ++kept_count_;
    }
    ++index;
  }
  std::fseek(file, rows_at, SEEK_SET);  // for row()
  return true;
}

const std::string& ResumedRows::row(std::size_t index) {
  Source& source = sources_.at(from_.at(index) - 1u);
  bool ended = false;
  while (source.next < source.used.size() && read_line(source.file.get(), line_, &ended)) {
    if (!reader_.is_row(line_) || !reader_.read(line_, ended)) continue;
    if (source.used[source.next++]) {
      line_ += '\n';
      return line_;
    }
  }
  throw usage_error(command_ + ": --resume '" + source.path + "' changed while it was being read");
}

SweepFile::SweepFile(const std::string& path, std::string_view command, const std::string& header,
                     ResumedRows* resumed, io::Format format)
    : resumed_(resumed), command_(command), header_(header), json_(format == io::Format::json) {
  if (!path.empty()) file_.emplace(path, command);
  buffer_.reserve(flush_bytes + (1u << 16));
  append(header);
}

void SweepFile::write_kept(std::size_t index) {
  std::string_view row = resumed_->row(index);
  if (json_) {  // the earlier file's first row has no comma
    if (row.starts_with(',')) row.remove_prefix(1);
    if (!std::exchange(first_row_, false)) append(",");
  }
  append(row);
}

void SweepFile::write_rows(std::size_t first, std::size_t, std::string_view text,
                           std::span<const double> row_us) {
  if (on_timing && !row_us.empty()) on_timing(first, row_us);
  if (json_) json_rows(first, text);
  else append(text);
}

void SweepFile::json_rows(std::size_t first, std::string_view text) {
  // A row's line holds no '#': rows without a failed one go out as they are.
  if (text.find('#') == std::string_view::npos) {
    if (std::exchange(first_row_, false) && text.starts_with(',')) text.remove_prefix(1);
    append(text);
    return;
  }
  constexpr std::string_view failed = "# failed: ";
  for (std::size_t begin = 0, index = first; begin < text.size(); ++index) {
    const std::size_t end = std::min(text.find('\n', begin), text.size() - 1) + 1;
    std::string_view line = text.substr(begin, end - begin);
    begin = end;
    if (line.starts_with(failed)) {
      line.remove_prefix(failed.size());
      if (line.ends_with('\n')) line.remove_suffix(1);
      failed_.push_back(json_failed_entry(row_number ? row_number(index) : index, line));
      continue;
    }
    if (std::exchange(first_row_, false) && line.starts_with(',')) line.remove_prefix(1);
    append(line);
  }
}

void SweepFile::end_rows(std::string_view interrupted) {
  if (json_) append(json_end(failed_, interrupted));
  else if (!interrupted.empty()) append("# interrupted: " + std::string(interrupted) + "\n");
}

void SweepFile::append(std::string_view text) {
  // A long piece (a chunk of rows) goes to the file as it is: copying it into the buffer first
  // was a third of rank 0's coordinator time in a 2-rank double sweep.
  if (text.size() >= direct_bytes) {
    flush();
    write_out(text);
    return;
  }
  if (buffer_.size() + text.size() > flush_bytes) flush();
  buffer_ += text;
}

void SweepFile::flush() {
  if (buffer_.empty()) return;
  write_out(buffer_);
  buffer_.clear();
}

void SweepFile::write_out(std::string_view text) {
  if (text.empty()) return;
  if (file_) {
    file_->append(text);
    return;
  }
  for (std::size_t written = 0; written < text.size();) {
    const ssize_t n = ::write(STDOUT_FILENO, text.data() + written, text.size() - written);
    if (n < 0) {
      if (errno == EINTR) continue;
      throw usage_error(std::string("cannot write to stdout: ") + std::strerror(errno));
    }
    written += static_cast<std::size_t>(n);
  }
}

void SweepFile::keep_ahead(std::string_view rows) {
  if (!file_ || file_->in_place() || ahead_failed_) return;
  if (rows.empty()) {
    ahead_.reset();
    return;
  }
  // A safeguard, not the output: when the copy cannot be written (a full disk, a directory
  // made read-only) the sweep goes on without it, and the file itself reports its own failure.
  try {
    auto next = std::make_unique<AtomicFile>(file_->path(), command_);
    next->append(header_);
    next->append(rows);
    ahead_ = std::move(next);
  } catch (const std::exception&) {
    ahead_.reset();
    ahead_failed_ = true;
  }
}

void SweepFile::commit() {
  flush();
  ahead_.reset();  // every row is in the file now
  if (file_) file_->commit();
}

void SweepFile::discard() {
  buffer_.clear();
  ahead_.reset();
  file_.reset();
}

}  // namespace pendavg::cli
