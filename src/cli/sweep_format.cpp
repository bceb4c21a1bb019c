// SPDX-License-Identifier: GPL-3.0-or-later
// src/cli/sweep_format.cpp -- see sweep_format.hpp.
#include "sweep_format.hpp"

#include "io/record.hpp"

#include <algorithm>
#include <cstdlib>
#include <stdexcept>

#include <sys/types.h>

namespace pendavg::cli {

namespace {

/// A number as the commands write and read them: [+-]digits[.digits][e[+-]digits].
bool is_decimal_number(std::string_view field) {
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

/// A CSV row of an earlier output is kept only when it is whole: it ended with its newline, it
/// has as many fields as the column line, and each is empty, a number or a word. A row cut short
/// (the process killed in the middle of a write, a full disk, a copy that stopped) or otherwise
/// damaged is computed again instead.
bool intact_row(std::string_view row, bool ended, std::size_t columns) {
  if (!ended) return false;
  std::size_t fields = 0;
  for (std::size_t begin = 0;;) {
    const std::size_t comma = std::min(row.find(',', begin), row.size());
    const std::string_view field = row.substr(begin, comma - begin);
    if (!field.empty() && !is_decimal_number(field) && !is_word(field)) return false;
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

constexpr std::string_view json_start = "{\"schema\": ";

}  // namespace

bool read_line(std::FILE* file, std::string& line, bool* ended) {
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

std::string_view format_name(io::Format format) {
  switch (format) {
    case io::Format::json: return "json";
    case io::Format::csv: return "csv";
    case io::Format::text: return "text";
  }
  return "?";
}

std::string sweep_header(const io::RowWriter& rows, std::string_view command, std::string_view csv) {
  if (rows.format() == io::Format::csv) return std::string(csv);
  // The '#' lines (the column line, CSV's last line, is the writer's).
  std::vector<std::string_view> lines;
  for (std::size_t begin = 0; begin < csv.size();) {
    const std::size_t end = std::min(csv.find('\n', begin), csv.size());
    const std::string_view line = csv.substr(begin, end - begin);
    if (line.starts_with('#')) lines.push_back(line);
    begin = end + 1;
  }
  if (rows.format() == io::Format::text) {
    std::string out;
    for (const std::string_view line : lines) (out += line) += '\n';
    return out + rows.text_column_line();
  }
  std::string out(json_start);
  out += std::to_string(io::schema_version) + ", \"command\": ";
  io::append_json_string(out, command);
  out += ",\n\"header\": [\n";
  std::vector<std::string_view> items;
  for (std::string_view line : lines) {
    if (line.starts_with("# schema: ")) continue;  // the "schema" key
    line.remove_prefix(line.starts_with("# ") ? 2 : 1);
    items.push_back(line);
  }
  for (std::size_t k = 0; k < items.size(); ++k) {
    io::append_json_string(out, items[k]);
    out += k + 1 < items.size() ? ",\n" : "\n";
  }
  out += "],\n\"columns\": [";
  for (std::size_t k = 0; k < rows.columns().size(); ++k) {
    if (k) out += ", ";
    io::append_json_string(out, rows.columns()[k]);
  }
  return out + "],\n\"rows\": [\n";
}

io::RowWriter row_writer_of(io::Format format, std::string_view line) {
  std::vector<std::string> names;
  std::vector<std::size_t> widths;
  if (format == io::Format::text) {  // each name ends its column; the columns 2 apart
    for (std::size_t start = 0, end = 0; (end = line.find_first_not_of(' ', end)) != line.npos;
         start = end + 2) {
      const std::size_t name = end;
      end = std::min(line.find(' ', name), line.size());
      names.emplace_back(line.substr(name, end - name));
      widths.push_back(end - start);
    }
    return io::RowWriter(format, std::move(names), std::move(widths));
  }
  const bool json = format == io::Format::json;
  if (json && line.starts_with("\"columns\": [") && line.ends_with("],"))
    line = line.substr(12, line.size() - 14);
  const std::string_view separator = json ? ", " : ",";
  for (std::size_t begin = 0; begin <= line.size();) {
    const std::size_t end = std::min(line.find(separator, begin), line.size());
    std::string_view name = line.substr(begin, end - begin);
    if (json && name.size() >= 2) name = name.substr(1, name.size() - 2);  // its quotes
    names.emplace_back(name);
    begin = end + separator.size();
  }
  return io::RowWriter(format, std::move(names));
}

std::string json_failed_entry(std::size_t row, std::string_view message) {
  std::string out = "{\"row\": " + std::to_string(row) + ", \"message\": ";
  io::append_json_string(out, message);
  return out + "}";
}

std::string json_end(std::span<const std::string> failed, std::string_view interrupted) {
  std::string out = "],\n\"failed\": [";
  for (std::size_t k = 0; k < failed.size(); ++k) (out += k ? ",\n" : "\n") += failed[k];
  out += failed.empty() ? "],\n\"interrupted\": " : "\n],\n\"interrupted\": ";
  if (interrupted.empty()) out += "null";
  else io::append_json_string(out, interrupted);
  return out + "}\n";
}

SweepFileKind sweep_file_kind(std::FILE* file) {
  SweepFileKind kind;
  std::string line;
  bool ended = false;
  while (read_line(file, line, &ended) && ended) {
    if (line.starts_with(json_start)) {
      kind.format = io::Format::json;
      const std::string_view rest = std::string_view(line).substr(json_start.size());
      kind.schema = std::string(rest.substr(0, std::min(rest.find(','), std::size_t(40))));
      break;
    }
    if (line.starts_with('#')) continue;
    // The column line: CSV's has commas, text's only spaces between the names.
    kind.format = line.find(',') == std::string::npos ? io::Format::text : io::Format::csv;
    break;
  }
  std::rewind(file);
  return kind;
}

RowReader::RowReader(const io::RowWriter& rows)
    : format_(rows.format()), columns_(rows.columns()), widths_(rows.widths()),
      line_length_(format_ == io::Format::text ? rows.text_line_length() : 0) {}

bool RowReader::is_row(std::string_view line) const {
  if (format_ == io::Format::json) return line.starts_with('{') || line.starts_with(",{");
  return !line.empty() && line.front() != '#';
}

bool RowReader::read(std::string_view line, bool ended) {
  line_ = line;
  if (!ended) return false;
  if (format_ == io::Format::csv) return intact_row(line, ended, columns_.size());
  values_.clear();
  const auto good = [](std::string_view text) {
    return text.empty() || is_decimal_number(text) || is_word(text);
  };
  if (format_ == io::Format::text) {
    if (line.size() != line_length_) return false;
    std::size_t position = 0;
    for (std::size_t k = 0; k < widths_.size(); ++k) {
      const std::string_view cell = line.substr(position, widths_[k]);
      const std::size_t first = cell.find_first_not_of(' ');
      if (first == std::string_view::npos) return false;
      std::string_view text = cell.substr(first);
      if (text.find(' ') != std::string_view::npos) return false;
      if (text == "-") text = {};
      if (!good(text)) return false;
      values_.push_back({text, false});
      position += widths_[k];
      if (k + 1 < widths_.size()) {
        if (line.substr(position, 2) != "  ") return false;
        position += 2;
      }
    }
    return true;
  }
  // JSON: ,{"name": value, ...} with the columns in their order.
  std::string_view rest = line;
  if (rest.starts_with(',')) rest.remove_prefix(1);
  const auto take = [&](std::string_view expected) {
    if (!rest.starts_with(expected)) return false;
    rest.remove_prefix(expected.size());
    return true;
  };
  if (!take("{")) return false;
  for (std::size_t k = 0; k < columns_.size(); ++k) {
    if ((k > 0 && !take(", ")) || !take("\"") || !take(columns_[k]) || !take("\": ")) return false;
    if (take("\"")) {
      const std::size_t end = rest.find('"');
      if (end == std::string_view::npos) return false;
      const std::string_view text = rest.substr(0, end);
      if (!good(text)) return false;  // no escapes: decimals and names only
      values_.push_back({text, false});
      rest.remove_prefix(end + 1);
    } else if (take("null")) {
      values_.push_back({{}, false});
    } else {
      // A loop, not find_first_of(",}"), which calls memchr once per character.
      std::size_t end = 0;
      while (end < rest.size() && rest[end] != ',' && rest[end] != '}') ++end;
      const std::string_view text = rest.substr(0, end);
      const bool flag = text == "true" || text == "false";
      if (!flag && !is_decimal_number(text)) return false;
      values_.push_back({text, !flag});
      rest.remove_prefix(end);
    }
  }
  return rest == "}";
}

bool RowReader::has_key(std::string_view key, std::size_t count) const {
  if (format_ == io::Format::csv) return leading_fields(line_, count) == key;
  std::size_t begin = 0;
  for (std::size_t k = 0; k < count; ++k) {
    if (k >= values_.size() || begin > key.size()) return false;
    const std::size_t end = std::min(key.find(',', begin), key.size());
    const std::string_view part = key.substr(begin, end - begin);
    begin = end + 1;
    if (values_[k].number) {  // a double run's input as JSON writes it
      scratch_.clear();
      io::append_json_number(scratch_, part);
      if (scratch_ != values_[k].text) return false;
    } else if (part != values_[k].text) {
      return false;
    }
  }
  return begin > key.size();
}

std::string RowReader::leading(std::size_t count) const {
  if (format_ == io::Format::csv) return std::string(leading_fields(line_, count));
  std::string out;
  for (std::size_t k = 0; k < std::min(count, values_.size()); ++k)
    (out += k ? "," : "") += values_[k].text;
  return out;
}

}  // namespace pendavg::cli
