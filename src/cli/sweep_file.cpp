// SPDX-License-Identifier: GPL-3.0-or-later
// src/cli/sweep_file.cpp -- see sweep_file.hpp.
#include "sweep_file.hpp"

#include "args.hpp"
#include "one_line.hpp"

#include <algorithm>
#include <cerrno>
#include <cstdlib>
#include <cstring>
#include <exception>

#include <unistd.h>

namespace pendavg::cli {

namespace {

constexpr std::size_t flush_bytes = 1u << 20;
constexpr std::size_t direct_bytes = 1u << 16;  ///< longer pieces are written unbuffered
constexpr std::string_view generated = ", generated ";

/// Reads one line (without its newline) into `line`; false at the end of the file. `ended`
/// (when given) says whether the line had its newline (the last line of a file cut short has
/// none).
bool read_line(std::FILE* file, std::string& line, bool* ended = nullptr) {
  char* buffer = nullptr;
  std::size_t capacity = 0;
  const ssize_t length = ::getline(&buffer, &capacity, file);
  if (length < 0) {
    std::free(buffer);
    line.clear();
    return false;
  }
  line.assign(buffer, static_cast<std::size_t>(length));
  std::free(buffer);
  const bool newline = !line.empty() && line.back() == '\n';
  if (newline) line.pop_back();
  if (ended) *ended = newline;
  return true;
}

/// A decimal number as the commands write them and read them: [+-]digits[.digits][e[+-]digits]
/// (digits on at least one side of the point).
bool is_number(std::string_view field) {
  std::size_t i = 0;
  const auto digits = [&] {
    const std::size_t start = i;
    while (i < field.size() && field[i] >= '0' && field[i] <= '9') ++i;
    return i - start;
  };
  if (i < field.size() && (field[i] == '+' || field[i] == '-')) ++i;
  std::size_t mantissa = digits();
  if (i < field.size() && field[i] == '.') {
    ++i;
    mantissa += digits();
  }
  if (mantissa == 0) return false;
  if (i < field.size() && (field[i] == 'e' || field[i] == 'E')) {
    ++i;
    if (i < field.size() && (field[i] == '+' || field[i] == '-')) ++i;
    if (digits() == 0) return false;
  }
  return i == field.size();
}

/// A word a row may hold (a method, an error kind, true or false): a letter, then letters,
/// digits, '-', '_' or '.'.
bool is_word(std::string_view field) {
  const auto letter = [](char c) { return (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z'); };
  if (field.empty() || !letter(field.front())) return false;
  for (const char c : field)
    if (!letter(c) && !(c >= '0' && c <= '9') && c != '-' && c != '_' && c != '.') return false;
  return true;
}

/// A row of an earlier output is kept only when it is whole: it ended with its newline, it has
/// as many fields as the column line, and each is empty, a number or a word. A row cut short
/// (the process killed in the middle of a write, a full disk, a copy that stopped) or otherwise
/// damaged is computed again instead.
bool intact_row(std::string_view row, bool ended, std::size_t columns) {
  if (!ended) return false;
  std::size_t fields = 0;
  for (std::size_t begin = 0;;) {
    const std::size_t comma = std::min(row.find(',', begin), row.size());
    const std::string_view field = row.substr(begin, comma - begin);
    if (!field.empty() && !is_number(field) && !is_word(field)) return false;
    ++fields;
    if (comma == row.size()) break;
    begin = comma + 1;
  }
  return fields == columns;
}

/// The first `fields` comma-separated fields of `row` (the whole row when it has fewer).
std::string_view leading_fields(std::string_view row, std::size_t fields) {
  std::size_t position = 0;
  for (std::size_t k = 0; k < fields; ++k) {
    const std::size_t comma = row.find(',', position);
    if (comma == std::string_view::npos) return row;
    position = comma + 1;
  }
  return row.substr(0, position - 1);
}

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
                                std::string_view first_context) {
  std::string message = std::string(command) + ": " + std::to_string(outcome.failed_rows) +
                        " of " + std::to_string(outcome.count) + " " + std::string(unit) +
                        " failed while they were computed; ";
  message += path.empty() ? "the output" : "'" + path + "'";
  message += " has every other finished row and a '# failed:' line in place of each; the "
             "first: " + std::string(first_context) + outcome.first_failed_reason;
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
                         const std::string& header, std::size_t count, std::size_t key_fields,
                         const std::function<std::string(std::size_t)>& key)
    : path_(path), command_(command), from_(count, 0) {
  // The header: every '#' line and the column line, as this run writes them.
  std::vector<std::string_view> expected;
  for (std::size_t begin = 0; begin < header.size();) {
    const std::size_t end = header.find('\n', begin);
    expected.push_back(std::string_view(header).substr(begin, end - begin));
    begin = end == std::string::npos ? header.size() : end + 1;
  }
  columns_ = expected.empty() ? 0 : 1 + static_cast<std::size_t>(std::ranges::count(
                                            expected.back(), ','));
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
    if (line.empty() || line.front() == '#') continue;
    ++row_number;
    if (!intact_row(line, ended, columns_)) continue;
    const std::string_view found = leading_fields(line, key_fields);
    while (index < from_.size() && key(index) != found) ++index;
    if (index == from_.size())
      throw usage_error(where + ": its data row " + std::to_string(row_number) + " ('" +
                        shortened(found) + ",...') is not a row of this sweep, or out of order");
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
    if (line_.empty() || line_.front() == '#' || !intact_row(line_, ended, columns_)) continue;
    if (source.used[source.next++]) {
      line_ += '\n';
      return line_;
    }
  }
  throw usage_error(command_ + ": --resume '" + source.path + "' changed while it was being read");
}

SweepFile::SweepFile(const std::string& path, std::string_view command, const std::string& header,
                     ResumedRows* resumed)
    : resumed_(resumed), command_(command), header_(header) {
  if (!path.empty()) file_.emplace(path, command);
  buffer_.reserve(flush_bytes + (1u << 16));
  append(header);
}

void SweepFile::write_kept(std::size_t index) { append(resumed_->row(index)); }

void SweepFile::write_rows(std::size_t first, std::size_t, std::string_view text,
                           std::span<const double> row_us) {
  if (on_timing && !row_us.empty()) on_timing(first, row_us);
  append(text);
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
      throw std::runtime_error(std::string("cannot write to stdout: ") + std::strerror(errno));
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
