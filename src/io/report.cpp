// SPDX-License-Identifier: GPL-3.0-or-later
// src/io/report.cpp -- reports as JSON, CSV and text.
#include "io/report.hpp"

#include <charconv>
#include <stdexcept>

namespace pendavg::io {

Format parse_format(std::string_view name) {
  if (name == "json") return Format::json;
  if (name == "csv") return Format::csv;
  if (name == "text") return Format::text;
  throw std::invalid_argument("'" + std::string(name) + "' is not one of json, csv, text");
}

std::string seconds_text(double seconds) {
  char buffer[32];
  const auto end = std::to_chars(buffer, buffer + sizeof buffer, seconds,
                                 std::chars_format::general, 6).ptr;
  return std::string(buffer, end);
}

std::string schema_line() { return "# schema: " + std::to_string(schema_version) + "\n"; }

namespace {

std::string json(const Report& r) {
  std::string out = "{";
  append_json_member(out, "schema", std::to_string(schema_version));
  append_json_member(out, "command", json_string(r.command));
  for (const Record* record : r.head) append_json_members(out, *record);
  const auto row_members = [](std::string& to, const Report::Row& row) {
    for (const Record* record : row.records) append_json_members(to, *record);
    if (!row.run.empty()) append_json_member(to, "run", row.run);
  };
  if (r.rows.size() == 1) {
    row_members(out, r.rows[0]);
  } else {
    for (const Report::Row& row : r.rows) {
      std::string object = "{";
      row_members(object, row);
      append_json_member(out, row.label, object + "}");
    }
  }
  if (r.seconds) append_json_member(out, "seconds", seconds_text(*r.seconds));
  return out + "}\n";
}

std::string csv(const Report& r) {
  std::string out = schema_line() + "# pendavg " + std::string(r.command) + "\n";
  std::vector<std::string> header;
  const auto add_names = [&](const Record& record) {
    for (std::string& name : column_names(record.fields(), record.particles()))
      header.push_back(std::move(name));
  };
  const bool labelled = r.rows.size() > 1;
  if (labelled) header.emplace_back(r.row_key);
  for (const Record* record : r.head) add_names(*record);
  if (!r.rows.empty())
    for (const Record* record : r.rows[0].records) add_names(*record);
  if (r.seconds) header.emplace_back("seconds");
  for (std::size_t i = 0; i < header.size(); ++i) (out += i ? "," : "") += header[i];
  out += '\n';
  for (const Report::Row& row : r.rows) {
    const std::size_t start = out.size();
    if (labelled) (out += row.label) += ',';
    for (const Record* record : r.head) append_csv_cells(out, *record);
    for (const Record* record : row.records) append_csv_cells(out, *record);
    if (r.seconds) (out += seconds_text(*r.seconds)) += ',';
    if (out.size() > start) out.back() = '\n';
  }
  return out;
}

std::string text(const Report& r) {
  std::string out = "pendavg " + std::string(r.command) + "\n";
  for (const Record* record : r.head) out += text_report(*record);
  for (const Report::Row& row : r.rows) {
    if (r.rows.size() > 1) ((((out += '\n') += r.row_key) += " = ") += row.label) += '\n';
    for (const Record* record : row.records) out += text_report(*record);
  }
  if (r.seconds) out += "seconds = " + seconds_text(*r.seconds) + "\n";
  return out;
}

std::string list_json(const ListReport& r) {
  std::string out = "{";
  append_json_member(out, "schema", std::to_string(schema_version));
  append_json_member(out, "command", json_string(r.command));
  for (const Record* record : r.head) append_json_members(out, *record);
  append_json_member(out, r.list_key, "[");
  Record row;
  for (std::size_t k = 0; k < r.rows; ++k) {
    row.reset(r.row_fields, 0);
    r.fill_row(k, row);
    row.complete();
    out += k ? ", {" : "{";
    append_json_members(out, row);
    out += '}';
  }
  out += ']';
  if (r.seconds) append_json_member(out, "seconds", seconds_text(*r.seconds));
  return out + "}\n";
}

std::string list_csv(const ListReport& r) {
  std::string out = schema_line() + "# pendavg " + std::string(r.command) + "\n";
  std::vector<std::string> header;
  for (const Record* record : r.head)
    for (std::string& name : column_names(record->fields(), record->particles()))
      header.push_back(std::move(name));
  for (std::string& name : column_names(r.row_fields, 0)) header.push_back(std::move(name));
  if (r.seconds) header.emplace_back("seconds");
  for (std::size_t i = 0; i < header.size(); ++i) (out += i ? "," : "") += header[i];
  out += '\n';
  std::string head;
  for (const Record* record : r.head) append_csv_cells(head, *record);
  const std::string seconds = r.seconds ? seconds_text(*r.seconds) + "," : std::string();
  Record row;
  for (std::size_t k = 0; k < r.rows; ++k) {
    row.reset(r.row_fields, 0);
    r.fill_row(k, row);
    row.complete();
    const std::size_t start = out.size();
    out += head;
    append_csv_cells(out, row);
    out += seconds;
    if (out.size() > start) out.back() = '\n';
  }
  return out;
}

std::string list_text(const ListReport& r) {
  std::string out = "pendavg " + std::string(r.command) + "\n";
  for (const Record* record : r.head) out += text_report(*record);
  std::vector<std::vector<std::string>> table(1);
  for (const Field& f : r.row_fields) table[0].emplace_back(f.name);
  Record row;
  for (std::size_t k = 0; k < r.rows; ++k) {
    row.reset(r.row_fields, 0);
    r.fill_row(k, row);
    row.complete();
    table.push_back(text_cells(row));
  }
  out += aligned(table);
  if (r.seconds) out += "seconds = " + seconds_text(*r.seconds) + "\n";
  return out;
}

}  // namespace

std::string format_list_report(const ListReport& report, Format format) {
  for (const Field& f : report.row_fields)
    if (f.shape != Shape::scalar)
      throw std::logic_error("pendavg internal error: a list report's row field " +
                             std::string(f.name) + " is per particle");
  switch (format) {
    case Format::json: return list_json(report);
    case Format::csv: return list_csv(report);
    case Format::text: return list_text(report);
  }
  return {};
}

std::string format_report(const Report& report, Format format) {
  switch (format) {
    case Format::json: return json(report);
    case Format::csv: return csv(report);
    case Format::text: return text(report);
  }
  return {};
}

}  // namespace pendavg::io
