// SPDX-License-Identifier: GPL-3.0-or-later
// src/io/record.cpp -- records and their JSON, CSV and text writers.
#include "io/record.hpp"

#include "io/migration.hpp"
#include "io/number_text.hpp"

#include <algorithm>
#include <charconv>
#include <cstring>
#include <stdexcept>
#include <unordered_map>

namespace pendavg::io {

std::size_t cell_count(std::span<const Field> fields, std::size_t particles) {
  std::size_t n = 0;
  for (const Field& f : fields) n += f.shape == Shape::per_particle ? particles : 1;
  return n;
}

void Record::reset(std::span<const Field> fields, std::size_t particles) {
  if (fields.data() == fields_.data() && fields.size() == fields_.size() &&
      particles == particles_ && !first_cell_.empty()) {  // the same table: reuse its layout
    cells_.clear();
    text_.clear();
    exact_.clear();
    pending_exact_ = ExactNumber{};
    return;
  }
  fields_ = fields;
  particles_ = particles;
  cells_.clear();
  cells_.reserve(cell_count(fields, particles));
  first_cell_.clear();
  cell_kinds_.clear();
  std::uint32_t k = 0;
  for (const Field& f : fields) {
    first_cell_.push_back(k);
    const std::uint32_t n = static_cast<std::uint32_t>(f.shape == Shape::per_particle ? particles : 1);
    cell_kinds_.insert(cell_kinds_.end(), n, f.kind);
    k += n;
  }
  first_cell_.push_back(k);
  text_.clear();
  exact_.clear();
  pending_exact_ = ExactNumber{};
}

void Record::push_exact() {
  exact_.push_back(std::move(pending_exact_));
  pending_exact_ = ExactNumber{};
}

std::span<const Cell> Record::cells_of(std::size_t field) const {
  return std::span<const Cell>(cells_).subspan(first_cell_[field],
                                               first_cell_[field + 1] - first_cell_[field]);
}

std::size_t Record::find(std::string_view name) const {
  for (std::size_t k = 0; k < fields_.size(); ++k)
    if (fields_[k].name == name) return k;
  return fields_.size();
}

void Record::shortest(double x) {
  Cell& c = add();
  c.tag = Cell::Tag::number;
  c.number = x;
  c.begin = static_cast<std::uint32_t>(text_.size());
  text_.resize(text_.size() + 32);
  char* const first = text_.data() + c.begin;
  char* const end = write_shortest(first, x);
  c.size = static_cast<std::uint32_t>(end - first);
  c.gap = printing_gap(x, std::string_view(first, c.size));
  text_.resize(c.begin + c.size);
}

void Record::decimal(std::string_view text) {
  Cell& c = add();
  c.tag = Cell::Tag::decimal;
  c.begin = static_cast<std::uint32_t>(text_.size());
  c.size = static_cast<std::uint32_t>(text.size());
  text_ += text;
}

char* Record::decimal_room(std::size_t size) {
  pending_ = text_.size();
  text_.resize(pending_ + size);
  return text_.data() + pending_;
}

void Record::commit_decimal(const char* end) {
  const auto size = static_cast<std::uint32_t>(end - (text_.data() + pending_));
  text_.resize(pending_ + size);
  Cell& c = add();
  c.tag = Cell::Tag::decimal;
  c.begin = static_cast<std::uint32_t>(pending_);
  c.size = size;
}

void Record::input(double x, std::string_view written) {
  decimal(written);
  cells_.back().tag = Cell::Tag::input;
  cells_.back().number = x;
}

void Record::text(std::string_view name) {
  decimal(name);
  cells_.back().tag = Cell::Tag::text;
}

void Record::name(const char* static_name) {
  Cell& c = add();
  c.tag = Cell::Tag::text;
  c.literal = static_name;
  c.size = static_cast<std::uint32_t>(std::strlen(static_name));
}

void Record::complete() const {
  if (cells_.size() != first_cell_.back())
    throw std::logic_error("pendavg internal error: a record has " +
                           std::to_string(cells_.size()) + " cells, its table " +
                           std::to_string(first_cell_.back()));
}

std::string column_name(const Field& field, std::size_t i) {
  if (field.shape == Shape::scalar) return std::string(field.name);
  const std::string index = std::to_string(i + 1);
  // the index before "_error", at the end (K_error -> K1_error) or before a qualifier
  // (K_error_blocking -> K1_error_blocking)
  constexpr std::string_view error = "_error";
  for (std::size_t at = field.name.find(error, 1); at != std::string_view::npos;
       at = field.name.find(error, at + 1)) {
    const std::size_t end = at + error.size();
    if (end == field.name.size() || field.name[end] == '_')
      return std::string(field.name.substr(0, at)) + index + std::string(field.name.substr(at));
  }
  return std::string(field.name) + index;
}

std::size_t value_of_error(std::span<const Field> fields, std::size_t k) {
  constexpr std::string_view suffix = "_error";
  const Field& error = fields[k];
  if (error.kind != Kind::error || !error.name.ends_with(suffix)) return fields.size();
  const std::string_view value = error.name.substr(0, error.name.size() - suffix.size());
  for (std::size_t j = 0; j < fields.size(); ++j)
    if (fields[j].name == value && fields[j].shape == error.shape && fields[j].kind == Kind::real)
      return j;
  return fields.size();
}

std::vector<std::string> column_names(std::span<const Field> fields, std::size_t particles) {
  std::vector<std::string> names;
  for (const Field& f : fields) {
    if (f.shape == Shape::scalar) names.emplace_back(f.name);
    else
      for (std::size_t i = 0; i < particles; ++i) names.push_back(column_name(f, i));
  }
  return names;
}

// ---------------------------------------------------------------- cells as text

double shortest_gap(double value) {
  char text[32];
  return printing_gap(value, std::string_view(text, static_cast<std::size_t>(
                                                        write_shortest(text, value) - text)));
}

char* write_number(char* out, double x, Kind kind) {
  if (kind == Kind::error) return write_error(out, x);
  return write_shortest(out, x);
}

std::size_t max_cell_length(const Record& record, const Cell& cell) {
  switch (cell.tag) {
    case Cell::Tag::none: return 0;
    case Cell::Tag::number: return 32;
    case Cell::Tag::decimal:
    case Cell::Tag::input:
    case Cell::Tag::text: return cell.size;
    case Cell::Tag::integer: return 24;
    case Cell::Tag::flag: return 5;
  }
  (void)record;
  return 0;
}

namespace {

char* write_cell_as(char* out, const Record& record, const Cell& cell, Kind kind) {
  switch (cell.tag) {
    case Cell::Tag::none: return out;
    case Cell::Tag::number:
      if (cell.size > 0) {  // a value's text, written once by Record::shortest
        std::memcpy(out, record.text_of(cell).data(), cell.size);
        return out + cell.size;
      }
      return write_number(out, kind == Kind::error ? covering(cell.number, cell.gap) : cell.number,
                          kind);
    case Cell::Tag::decimal:
    case Cell::Tag::input:
    case Cell::Tag::text: {
      const std::string_view t = record.text_of(cell);
      std::memcpy(out, t.data(), t.size());
      return out + t.size();
    }
    case Cell::Tag::integer: return std::to_chars(out, out + 24, cell.integer).ptr;
    case Cell::Tag::flag:
      std::memcpy(out, cell.flag ? "true" : "false", cell.flag ? 4 : 5);
      return out + (cell.flag ? 4 : 5);
  }
  return out;
}

void append_cell(std::string& out, const Record& record, const Cell& cell, Kind kind) {
  const std::size_t start = out.size();
  out.resize(start + max_cell_length(record, cell));
  out.resize(static_cast<std::size_t>(write_cell_as(out.data() + start, record, cell, kind) -
                                      out.data()));
}

void append_json_cell(std::string& out, const Record& record, const Cell& cell, Kind kind) {
  switch (cell.tag) {
    case Cell::Tag::none: out += "null"; return;
    case Cell::Tag::decimal:
    case Cell::Tag::text: out += json_string(record.text_of(cell)); return;
    case Cell::Tag::input: {
      const std::size_t start = out.size();
      out.resize(start + 32);
      out.resize(static_cast<std::size_t>(write_shortest(out.data() + start, cell.number) -
                                          out.data()));
      return;
    }
    default: append_cell(out, record, cell, kind);
  }
}

}  // namespace

char* write_cell(char* out, const Record& record, const Cell& cell) {
  const std::size_t k = static_cast<std::size_t>(&cell - record.cells().data());
  return write_cell_as(out, record, cell, record.kind_of_cell(k));
}

void append_json_string(std::string& out, std::string_view text) {
  out += '"';
  for (const char c : text) {
    if (c == '"' || c == '\\') out += '\\';
    if (static_cast<unsigned char>(c) < 0x20) {
      char code[8];
      std::snprintf(code, sizeof code, "\\u%04x", static_cast<unsigned>(c));
      out += code;
      continue;
    }
    out += c;
  }
  out += '"';
}

std::string json_string(std::string_view text) {
  std::string out;
  append_json_string(out, text);
  return out;
}

void append_json_member(std::string& out, std::string_view key, std::string_view json) {
  if (!out.empty() && out.back() != '{') out += ", ";
  out += json_string(key);
  out += ": ";
  out += json;
}

void append_json_members(std::string& out, const Record& record) {
  for (std::size_t k = 0; k < record.fields().size(); ++k) {
    const Field& f = record.fields()[k];
    if (!out.empty() && out.back() != '{') out += ", ";
    out += json_string(f.name);
    out += ": ";
    const auto cells = record.cells_of(k);
    if (f.shape == Shape::scalar) {
      append_json_cell(out, record, cells[0], f.kind);
      continue;
    }
    out += '[';
    for (std::size_t i = 0; i < cells.size(); ++i) {
      if (i) out += ", ";
      append_json_cell(out, record, cells[i], f.kind);
    }
    out += ']';
  }
}

void append_csv_cells(std::string& out, const Record& record,
                      std::span<const std::size_t> selection) {
  // One resize for the whole row (room for every cell and its comma), then the cells written
  // in place: a resize per cell was a fifth of the printing of an `average --cases` row.
  const auto cells = record.cells();
  const std::size_t count = selection.empty() ? cells.size() : selection.size();
  const auto cell_index = [&](std::size_t j) { return selection.empty() ? j : selection[j]; };
  std::size_t room = count;
  for (std::size_t j = 0; j < count; ++j) room += max_cell_length(record, cells[cell_index(j)]);
  const std::size_t start = out.size();
  out.resize(start + room);
  char* p = out.data() + start;
  for (std::size_t j = 0; j < count; ++j) {
    const std::size_t c = cell_index(j);
    p = write_cell_as(p, record, cells[c], record.kind_of_cell(c));
    *p++ = ',';
  }
  out.resize(static_cast<std::size_t>(p - out.data()));
}

// ---------------------------------------------------------------- text

namespace {

std::string cell_text(const Record& record, const Cell& cell, Kind kind) {
  std::string out;
  append_cell(out, record, cell, kind);
  return cell.tag == Cell::Tag::none ? std::string("-") : out;
}

}  // namespace

std::vector<std::string> text_cells(const Record& record) {
  std::vector<std::string> out;
  out.reserve(record.cells().size());
  for (std::size_t k = 0; k < record.fields().size(); ++k)
    for (const Cell& cell : record.cells_of(k))
      out.push_back(cell_text(record, cell, record.fields()[k].kind));
  return out;
}

std::string aligned(const std::vector<std::vector<std::string>>& rows) {
  std::vector<std::size_t> widths;
  for (const auto& row : rows) {
    widths.resize(std::max(widths.size(), row.size()));
    for (std::size_t i = 0; i < row.size(); ++i) widths[i] = std::max(widths[i], row[i].size());
  }
  std::string out;
  for (const auto& row : rows) {
    for (std::size_t i = 0; i < row.size(); ++i) {
      if (i) out += "  ";
      out.append(widths[i] - row[i].size(), ' ');
      out += row[i];
    }
    out += '\n';
  }
  return out;
}

std::string text_report(const Record& record) {
  const auto fields = record.fields();
  std::vector<std::vector<std::string>> table;
  std::vector<std::size_t> per_particle;
  for (std::size_t k = 0; k < fields.size(); ++k) {
    if (fields[k].shape != Shape::per_particle) continue;
    const auto cells = record.cells_of(k);  // a field with no value at all (a limit's K) is left out
    if (std::any_of(cells.begin(), cells.end(),
                    [](const Cell& c) { return c.tag != Cell::Tag::none; }))
      per_particle.push_back(k);
  }
  if (!per_particle.empty() && record.particles() > 0) {
    table.emplace_back(1, "i");
    for (const std::size_t k : per_particle) table[0].emplace_back(fields[k].name);
    for (std::size_t i = 0; i < record.particles(); ++i) {
      std::vector<std::string> row{std::to_string(i + 1)};
      for (const std::size_t k : per_particle)
        row.push_back(cell_text(record, record.cells_of(k)[i], fields[k].kind));
      table.push_back(std::move(row));
    }
  }
  std::string out = aligned(table);
  // Scalars: a value with its error as `X = v +- e (kind)` on its own line; the kinds of the
  // per-particle fields on one line; every other scalar on one line, comma separated.
  std::vector<bool> done(fields.size(), false);
  std::string kinds, others;
  constexpr std::string_view kind_suffix = "_error_kind";
  for (std::size_t k = 0; k < fields.size(); ++k) {
    if (done[k] || fields[k].shape != Shape::scalar) continue;
    const std::string name(fields[k].name);
    const std::string value = cell_text(record, record.cells_of(k)[0], fields[k].kind);
    const std::size_t e = record.find(name + "_error");
    if (e < fields.size() && fields[e].shape == Shape::scalar) {
      out += name + " = " + value + " +- " +
             cell_text(record, record.cells_of(e)[0], fields[e].kind);
      done[e] = true;
      const std::size_t kind = record.find(name + std::string(kind_suffix));
      if (kind < fields.size()) {
        out += " (" + cell_text(record, record.cells_of(kind)[0], fields[kind].kind) + ")";
        done[kind] = true;
      }
      out += '\n';
    } else if (fields[k].name.ends_with(kind_suffix)) {
      if (record.cells_of(k)[0].tag == Cell::Tag::none) continue;
      (kinds += kinds.empty() ? "" : ", ") +=
          std::string(fields[k].name.substr(0, fields[k].name.size() - kind_suffix.size())) +
          " " + value;
    } else {
      (others += others.empty() ? "" : ", ") += name + " = " + value;
    }
  }
  if (!kinds.empty()) out += "error kinds: " + kinds + "\n";
  if (!others.empty()) out += others + "\n";
  return out;
}

// ---------------------------------------------------------------- --columns

std::vector<std::size_t> select_columns(std::string_view list,
                                        const std::vector<std::string>& columns,
                                        const std::vector<std::string>& inputs,
                                        std::size_t particles, std::vector<std::string>& headers) {
  std::unordered_map<std::string_view, std::size_t> position;
  for (std::size_t k = 0; k < columns.size(); ++k) position.emplace(columns[k], k);
  std::vector<std::size_t> selected;
  headers.clear();
  std::vector<bool> taken(columns.size(), false);
  const auto take = [&](std::size_t k, std::string_view item, std::string header) {
    if (taken[k])
      throw std::invalid_argument("column '" + columns[k] + "' selected twice (by '" +
                                  std::string(item) + "')");
    taken[k] = true;
    selected.push_back(k);
    headers.push_back(std::move(header));
  };
  if (list.empty()) throw std::invalid_argument("needs a list of column names");
  for (std::size_t begin = 0; begin <= list.size();) {
    std::size_t end = list.find(',', begin);
    if (end == std::string_view::npos) end = list.size();
    const std::string_view item = list.substr(begin, end - begin);
    begin = end + 1;
    if (item.empty())
      throw std::invalid_argument("an empty column name in '" + std::string(list) + "'");
    if (const auto found = position.find(item); found != position.end()) {
      take(found->second, item, std::string(item));
      continue;
    }
    // a per-particle stem: its column of every particle
    const Field stem{item, Kind::real, Shape::per_particle, {}};
    if (particles > 0 && position.contains(column_name(stem, 0))) {
      for (std::size_t i = 0; i < particles; ++i) {
        const std::string name = column_name(stem, i);
        const auto member = position.find(name);
        if (member == position.end()) break;
        take(member->second, item, name);
      }
      continue;
    }
    // a name of schema 0: its column (or a stem's columns) under the old header
    if (const auto old = schema0_columns(item, particles); !old.empty()) {
      bool found_all = true;
      for (const auto& [old_name, new_name] : old) found_all = found_all && position.contains(new_name);
      if (found_all) {
        for (const auto& [old_name, new_name] : old)
          take(position.find(new_name)->second, item, old_name);
        continue;
      }
    }
    if (std::find(inputs.begin(), inputs.end(), item) != inputs.end())
      throw std::invalid_argument("'" + std::string(item) +
                                  "' is an input column: every row starts with the input "
                                  "columns; --columns chooses among the output columns");
    std::string known;
    for (std::size_t k = 0; k < columns.size() && known.size() < 400; ++k) {
      const std::string& name = columns[k];
      // list each per-particle family once, by its stem (its particle 1's column)
      const std::size_t e = name.ends_with("_error") ? name.size() - 6 : name.size();
      const std::size_t digits = name.find_last_not_of("0123456789", e - 1) + 1;
      if (digits < e && name.substr(digits, e - digits) != "1") continue;
      const std::string stem = name.substr(0, digits) + name.substr(e);
      (known += known.empty() ? "" : ", ") += stem;
    }
    throw std::invalid_argument("unknown column '" + std::string(item) + "' (one of: " + known +
                                "; a stem such as cos_phi selects cos_phi1..N)");
  }
  return selected;
}

}  // namespace pendavg::io
