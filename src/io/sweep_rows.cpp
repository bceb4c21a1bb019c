// SPDX-License-Identifier: GPL-3.0-or-later
// src/io/sweep_rows.cpp -- see sweep_rows.hpp.
#include "io/sweep_rows.hpp"

#include "io/number_text.hpp"

#include "pendavg/result.hpp"

#include <mpfr.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <stdexcept>

namespace pendavg::io {

namespace {

bool is_digit(char c) { return c >= '0' && c <= '9'; }

/// The CSV text of a cell (empty for no value).
std::string_view cell_text(const Record& record, const Cell& cell, char* room) {
  return {room, static_cast<std::size_t>(write_cell(room, record, cell) - room)};
}

/// Room for the CSV text of any cell of `record`.
std::size_t cell_room(const Record& record, const Cell& cell) {
  return std::max<std::size_t>(max_cell_length(record, cell), 32);
}

/// Decimal digits of the largest decimal exponent an MPFR number can have (its binary exponent
/// range, which the process may have changed).
std::size_t mpfr_exponent_digits() {
  const double bits = std::max(static_cast<double>(mpfr_get_emax()),
                               -static_cast<double>(mpfr_get_emin()));
  const double largest = std::ceil(bits * 0.30102999566398120) + 1;
  return static_cast<std::size_t>(std::floor(std::log10(largest))) + 1;
}

std::size_t longest(std::initializer_list<const char*> names) {
  std::size_t n = 0;
  for (const char* name : names) n = std::max(n, std::strlen(name));
  return n;
}

std::size_t longest_method_name() {
  std::size_t n = 0;
  for (int k = 0;; ++k) {  // every method the library names, up to its "unknown"
    const char* name = method_name(static_cast<Method>(k));
    if (std::strcmp(name, "unknown") == 0) return n;
    n = std::max(n, std::strlen(name));
  }
}

}  // namespace

RowWriter::RowWriter(Format format, std::vector<std::string> columns, std::vector<std::size_t> widths)
    : format_(format), columns_(std::move(columns)), widths_(std::move(widths)) {
  if (format_ == Format::text && widths_.size() != columns_.size())
    throw std::logic_error("pendavg internal error: a text row needs one width per column");
  for (std::size_t k = 0; k < widths_.size(); ++k)
    widths_[k] = std::max({widths_[k], columns_[k].size(), std::size_t(1)});
  if (format_ == Format::json)
    for (std::size_t k = 0; k < columns_.size(); ++k) {
      std::string key = k == 0 ? ",{" : ", ";
      append_json_string(key, columns_[k]);
      keys_.push_back(key + ": ");
    }
}

void RowWriter::add_json(std::string& out, std::size_t& column) const {
  if (column >= keys_.size())
    throw std::logic_error("pendavg internal error: a row has more cells than columns");
  out += keys_[column++];
}

void RowWriter::add_text(std::string& out, std::size_t& column, std::string_view text) const {
  if (column >= widths_.size())
    throw std::logic_error("pendavg internal error: a row has more cells than columns");
  if (column > 0) out += "  ";
  if (text.empty()) text = "-";
  if (text.size() < widths_[column]) out.append(widths_[column] - text.size(), ' ');
  out += text;
  ++column;
}

void RowWriter::append(std::string& out, std::span<const std::string_view> written, bool numbers,
                       std::span<const RowCells> records) const {
  if (format_ == Format::csv) {
    for (const std::string_view field : written) (out += field) += ',';
    for (const RowCells& r : records) append_csv_cells(out, *r.record, r.selection);
    out.back() = '\n';
    return;
  }
  std::size_t column = 0;
  char room[64];
  std::string long_text;  // a cell longer than `room` (an MPFR value of many digits)
  const auto each_cell = [&](const RowCells& r, auto&& visit) {
    const auto cells = r.record->cells();
    if (r.selection.empty())
      for (std::size_t c = 0; c < cells.size(); ++c) visit(*r.record, cells[c]);
    else
      for (const std::size_t c : r.selection) visit(*r.record, cells[c]);
  };
  const auto text_of = [&](const Record& record, const Cell& cell) -> std::string_view {
    const std::size_t need = cell_room(record, cell);
    if (need <= sizeof room) return cell_text(record, cell, room);
    long_text.resize(need);
    return cell_text(record, cell, long_text.data());
  };
  if (format_ == Format::json) {
    for (const std::string_view field : written) {
      add_json(out, column);
      if (numbers) append_json_number(out, field);
      else append_json_string(out, field);
    }
    for (const RowCells& r : records)
      each_cell(r, [&](const Record& record, const Cell& cell) {
        add_json(out, column);
        switch (cell.tag) {
          case Cell::Tag::none: out += "null"; break;
          case Cell::Tag::decimal:
          case Cell::Tag::text: append_json_string(out, record.text_of(cell)); break;
          case Cell::Tag::input: append_json_number(out, record.text_of(cell)); break;
          default: out += text_of(record, cell);  // numbers, counts, true/false
        }
      });
    if (column != keys_.size())
      throw std::logic_error("pendavg internal error: a row has fewer cells than columns");
    out += "}\n";
    return;
  }
  for (const std::string_view field : written) add_text(out, column, field);
  for (const RowCells& r : records)
    each_cell(r, [&](const Record& record, const Cell& cell) {
      add_text(out, column, cell.tag == Cell::Tag::none ? std::string_view() : text_of(record, cell));
    });
  if (column != widths_.size())
    throw std::logic_error("pendavg internal error: a row has fewer cells than columns");
  out += '\n';
}

std::string RowWriter::text_column_line() const {
  std::string out;
  std::size_t column = 0;
  for (const std::string& name : columns_) add_text(out, column, name);
  return out + '\n';
}

std::size_t RowWriter::text_line_length() const {
  std::size_t n = 0;
  for (const std::size_t w : widths_) n += w;
  return n + (widths_.empty() ? 0 : 2 * (widths_.size() - 1));
}

void append_json_number(std::string& out, std::string_view literal) {
  std::size_t i = 0;
  if (i < literal.size() && (literal[i] == '+' || literal[i] == '-')) {
    if (literal[i] == '-') out += '-';
    ++i;
  }
  std::size_t digits = i;
  while (digits < literal.size() && is_digit(literal[digits])) ++digits;
  // The integer part without leading zeros (one 0 when it is zero or absent).
  std::size_t first = i;
  while (first + 1 < digits && literal[first] == '0') ++first;
  if (first == digits) out += '0';
  else out.append(literal.substr(first, digits - first));
  i = digits;
  if (i < literal.size() && literal[i] == '.') {
    ++i;
    std::size_t end = i;
    while (end < literal.size() && is_digit(literal[end])) ++end;
    out += '.';
    if (end == i) out += '0';
    else out.append(literal.substr(i, end - i));
    i = end;
  }
  out.append(literal.substr(i));  // the exponent, as JSON writes it too
}

std::vector<const Field*> cell_fields(std::span<const Field> fields, std::size_t particles) {
  std::vector<const Field*> out;
  for (const Field& f : fields) out.insert(out.end(), f.shape == Shape::per_particle ? particles : 1, &f);
  return out;
}

std::size_t widest_cell(const Field& field, std::span<const int> digits) {
  // A double row prints values as their shortest text or with 16 digits, quotients formed in
  // long double (4 exponent digits): "-2.2250738585072014e-308", "-1.234567890123456e-4931";
  // errors with error_digits digits, "1.00e-4951". An MPFR row prints D digits and MPFR's
  // exponents.
  constexpr int double_digits = 16;
  std::size_t widest = 1;
  switch (field.kind) {
    case Kind::real:
    case Kind::error:
      for (const int d : digits) {
        const bool value = field.kind == Kind::real;
        const auto mantissa = static_cast<std::size_t>(value ? d : error_digits);
        std::size_t width = 0;
        if (d == double_digits) {
          width = value ? 24 : mantissa + 7;
        } else {
          width = 1 + mantissa + 1 + 2 + mpfr_exponent_digits();  // sign, point, 'e' and sign
          width = std::min(width, decimal_max_length(static_cast<int>(mantissa)) - 1);
        }
        widest = std::max(widest, width);
      }
      return widest;
    case Kind::count: return 19;  // the largest long long
    case Kind::flag: return 5;    // false
    case Kind::text: {
      const std::size_t kinds = longest({error_kind_name(ErrorKind::bound),
                                         error_kind_name(ErrorKind::estimate),
                                         error_kind_name(ErrorKind::statistical)});
      const std::size_t units = longest({work_unit_name(WorkUnit::terms), work_unit_name(WorkUnit::nodes),
                                         work_unit_name(WorkUnit::samples), work_unit_name(WorkUnit::steps)});
      const std::size_t ensembles = longest({"microcanonical", "canonical"});
      const std::size_t methods = longest_method_name();
      if (field.name == "method") return methods;
      if (field.name.ends_with("_error_kind")) return kinds;
      if (field.name == "work_unit") return units;
      if (field.name == "ensemble") return ensembles;
      return std::max({methods, kinds, units, ensembles});
    }
  }
  return widest;
}

}  // namespace pendavg::io
