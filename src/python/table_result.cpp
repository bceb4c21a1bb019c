// SPDX-License-Identifier: GPL-3.0-or-later
// src/python/table_result.cpp -- see table_result.hpp.
#include "table_result.hpp"

#include "pendavg/chain.hpp"

#include <pybind11/stl.h>

#include <cmath>
#include <limits>
#include <mutex>
#include <utility>
#include <stdexcept>

namespace pendavg::python {

namespace {

constexpr double nan = std::numeric_limits<double>::quiet_NaN();

}  // namespace

const char* kind_name(io::Kind kind) {
  switch (kind) {
    case io::Kind::real: return "real";
    case io::Kind::error: return "error";
    case io::Kind::count: return "count";
    case io::Kind::text: return "text";
    case io::Kind::flag: return "flag";
  }
  return "?";
}

std::vector<ClassField> class_fields(std::initializer_list<Table> tables) {
  std::vector<ClassField> out;
  for (const Table& t : tables)
    for (const io::Field& f : t.fields) {
      if (std::any_of(out.begin(), out.end(),
                      [&](const ClassField& c) { return c.field.name == f.name; }))
        continue;
      out.push_back({f, t.inputs, t.inputs && f.kind == io::Kind::count});
    }
  return out;
}

py::list field_tuples(const std::vector<ClassField>& fields) {
  py::list out;
  for (const ClassField& f : fields)
    out.append(py::make_tuple(std::string(f.field.name), kind_name(f.field.kind),
                              f.field.shape == io::Shape::per_particle,
                              std::string(f.field.meaning), f.input));
  return out;
}

std::string index_text(std::size_t k, const std::vector<py::ssize_t>& shape) {
  std::vector<std::size_t> index(shape.size());
  for (std::size_t d = shape.size(); d-- > 0;) {
    index[d] = k % static_cast<std::size_t>(shape[d]);
    k /= static_cast<std::size_t>(shape[d]);
  }
  std::string out = "index (";
  for (std::size_t d = 0; d < index.size(); ++d) out += (d ? ", " : "") + std::to_string(index[d]);
  return out + (index.size() == 1 ? ",)" : ")");
}

py::object numpy_array(const py::list& items, const std::vector<py::ssize_t>& shape,
                       const char* dtype) {
  const py::object numpy = py::module_::import("numpy");
  const py::object array = dtype ? numpy.attr("array")(items, py::arg("dtype") = dtype)
                                 : numpy.attr("array")(items);
  return array.attr("reshape")(py::cast(shape));
}

// ---------------------------------------------------------------- filling

std::shared_ptr<const TableResult::Layout> TableResult::layout_of(
    std::initializer_list<Table> tables, std::size_t particles) {
  // The layouts made so far, by their tables (static spans: compared by address) and N; this
  // thread's last one first (no lock, no allocation: a call of one point asks for it each time).
  struct Key {
    std::vector<Table> tables;
    std::size_t particles = 0;
    bool is(std::initializer_list<Table> other, std::size_t n) const {
      return n == particles && std::equal(tables.begin(), tables.end(), other.begin(), other.end(),
                                          [](const Table& a, const Table& b) {
                                            return a.fields.data() == b.fields.data() &&
                                                   a.fields.size() == b.fields.size() &&
                                                   a.inputs == b.inputs;
                                          });
    }
  };
  thread_local std::pair<Key, std::shared_ptr<const Layout>> last;
  if (last.second && last.first.is(tables, particles)) return last.second;
  static std::mutex mutex;
  static std::vector<std::pair<Key, std::shared_ptr<const Layout>>> made;
  {
    const std::lock_guard<std::mutex> lock(mutex);
    for (const auto& entry : made)
      if (entry.first.is(tables, particles)) {
        last = entry;
        return entry.second;
      }
  }
  const Key key{std::vector<Table>(tables), particles};
  auto layout = std::make_shared<Layout>();
  for (const Table& table : tables) {
    std::vector<CellPlan>& plan = layout->plans.emplace_back();
    const std::size_t first_column = layout->columns.size();
    for (std::size_t k = 0; k < table.fields.size(); ++k) {
      const io::Field& f = table.fields[k];
      Column c;
      c.field = f;
      c.width = f.shape == io::Shape::per_particle ? particles : 1;
      c.input = table.inputs;
      c.call_wide = table.inputs && f.kind == io::Kind::count;
      c.present = layout->row_present;
      layout->row_present += c.width;
      std::size_t& row = c.numeric()                 ? layout->row_numbers
                         : f.kind == io::Kind::count ? layout->row_integers
                         : f.kind == io::Kind::flag  ? layout->row_flags
                                                     : layout->row_texts;
      c.first = row;
      row += c.width;
      for (std::size_t i = 0; i < c.width; ++i)
        plan.push_back({f.kind, c.call_wide, static_cast<std::uint32_t>(c.first + i),
                        static_cast<std::uint32_t>(c.present + i)});
      if (const std::size_t v = io::value_of_error(table.fields, k); v < table.fields.size())
        c.value = first_column + v;
      layout->columns.push_back(c);
    }
  }
  const std::lock_guard<std::mutex> lock(mutex);
  if (made.size() >= 64) made.erase(made.begin());  // (any N may come: keep the recent ones)
  made.emplace_back(key, layout);
  last = made.back();
  return layout;
}

void TableResult::layout(std::initializer_list<Table> tables, bool mpfr) {
  mpfr_ = mpfr;
  points_ = 1;
  for (const py::ssize_t s : shape) points_ *= static_cast<std::size_t>(s);
  const std::size_t rows = std::max<std::size_t>(points_, 1);  // an empty grid: store_call's
  layout_ = layout_of(tables, particles);
  columns_ = layout_->columns;
  row_present_ = layout_->row_present;
  row_numbers_ = layout_->row_numbers;
  row_integers_ = layout_->row_integers;
  row_flags_ = layout_->row_flags;
  row_texts_ = layout_->row_texts;
  const std::size_t numbers = rows * row_numbers_;
  gaps_at_ = numbers;
  seconds_at_ = gaps_at_ + (mpfr ? 0 : numbers);
  doubles_.assign(seconds_at_ + points_, 0.0);
  std::fill(doubles_.begin(), doubles_.begin() + static_cast<std::ptrdiff_t>(numbers), nan);
  flags_at_ = rows * row_present_;
  finite_at_ = flags_at_ + rows * row_flags_;
  interrupted_at_ = finite_at_ + rows;
  bytes_.assign(interrupted_at_ + points_, 0);
  std::fill(bytes_.begin() + static_cast<std::ptrdiff_t>(finite_at_),
            bytes_.begin() + static_cast<std::ptrdiff_t>(interrupted_at_), std::uint8_t{1});
  decimals_.assign(mpfr ? numbers : 0, {});
  exact_.assign(mpfr ? numbers : 0, {});
  integers_.assign(rows * row_integers_, 0);
  texts_.assign(rows * row_texts_, {});
}

void TableResult::put(std::size_t k, std::span<const io::Record* const> records, bool call_only) {
  std::uint8_t* present = bytes_.data() + k * row_present_;
  double* numbers = doubles_.data() + k * row_numbers_;
  double* gaps = doubles_.data() + gaps_at_ + k * row_numbers_;
  bool finite = true;
  for (std::size_t t = 0; t < layout_->plans.size(); ++t) {
    const std::vector<CellPlan>& plan = layout_->plans[t];
    if (call_only && std::none_of(plan.begin(), plan.end(),
                                  [](const CellPlan& p) { return p.call_wide; }))
      continue;
    const io::Record& record = *records[t];
    const std::span<const io::Cell> cells = record.cells();
    if (cells.size() != plan.size())
      throw std::logic_error("pendavg internal error: a record out of step with its table");
    for (std::size_t j = 0; j < cells.size(); ++j) {
      const CellPlan& p = plan[j];
      const io::Cell& cell = cells[j];
      if (cell.tag == io::Cell::Tag::none || (call_only && !p.call_wide)) continue;
      present[p.present] = 1;
      switch (p.kind) {
        case io::Kind::real:
        case io::Kind::error:
          if (cell.tag == io::Cell::Tag::number || cell.tag == io::Cell::Tag::input) {
            numbers[p.at] = cell.number;  // (an error's: the library's; its text adds a gap)
            if (!mpfr_) gaps[p.at] = cell.gap;
            else if (j < record.exact().size() && record.exact()[j].kept())
              exact_[k * row_numbers_ + p.at] = record.exact()[j];  // (a double of an MPFR run)
            finite = finite && std::isfinite(cell.number);
          } else {  // an MPFR run's decimal text, and the exact value behind it
            const std::span<const io::ExactNumber> exact = record.exact();
            const std::size_t at = k * row_numbers_ + p.at;
            if (!mpfr_ || j >= exact.size() || !exact[j].kept())
              throw std::logic_error("pendavg internal error: a decimal cell without its exact "
                                     "value");
            exact_[at] = exact[j];
            numbers[p.at] = exact[j].rounded;
            decimals_[at] = record.text_of(cell);
            finite = finite && exact[j].finite;
          }
          break;
        case io::Kind::count: integers_[k * row_integers_ + p.at] = cell.integer; break;
        case io::Kind::flag: bytes_[flags_at_ + k * row_flags_ + p.at] = cell.flag ? 1 : 0; break;
        case io::Kind::text: texts_[k * row_texts_ + p.at] = record.text_of(cell); break;
      }
    }
  }
  if (!call_only) bytes_[finite_at_ + k] = finite ? 1 : 0;
}

void TableResult::store(std::size_t k, std::span<const io::Record* const> records) {
  put(k, records, false);
}

void TableResult::store_call(std::span<const io::Record* const> records) {
  put(0, records, true);
}

const Column* TableResult::find(std::string_view name) const {
  for (const Column& c : columns_)
    if (c.field.name == name) return &c;
  return nullptr;
}

// ---------------------------------------------------------------- Python values

py::object TableResult::value(std::string_view name) const {
  const Column* found = find(name);
  if (!found) return py::none();
  const Column& c = *found;
  if (c.call_wide) return py::int_(integers_[c.first]);  // N, digits: the call's
  const auto present = [&, presence = this->present()](std::size_t k, std::size_t i) {
    return presence[k * row_present_ + c.present + i] != 0;
  };
  bool any = false, all = true;
  for (std::size_t k = 0; k < points_; ++k)
    for (std::size_t i = 0; i < c.width; ++i) {
      const bool p = present(k, i);
      any = any || p;
      all = all && p;
    }
  if (points_ > 0 && !any) return py::none();  // no value anywhere: a limit's <K_i>, ...
  const bool per_particle = c.field.shape == io::Shape::per_particle;
  std::vector<py::ssize_t> shape = this->shape;
  if (per_particle) shape.push_back(static_cast<py::ssize_t>(c.width));
  const bool scalar = !per_particle && single();
  // Fills `out` (C order over points, then cells) from the pool of row length `row`.
  const auto gather = [&](auto* out, const auto* pool, std::size_t row, auto convert) {
    for (std::size_t k = 0; k < points_; ++k)
      for (std::size_t i = 0; i < c.width; ++i) *out++ = convert(pool[cell(c, row, k, i)]);
  };
  const auto same = [](auto x) { return x; };
  switch (c.field.kind) {
    case io::Kind::real:
    case io::Kind::error: {
      if (scalar) return present(0, 0) ? py::object(py::float_(numbers()[c.first])) : py::none();
      py::array_t<double> out(shape);
      gather(out.mutable_data(), numbers(), row_numbers_, same);
      return out;
    }
    case io::Kind::count: {
      if (scalar) return present(0, 0) ? py::object(py::int_(integers_[c.first])) : py::none();
      py::array_t<std::int64_t> out(shape);
      gather(out.mutable_data(), integers_.data(), row_integers_, same);
      return out;
    }
    case io::Kind::flag: {
      if (scalar) return present(0, 0) ? py::object(py::bool_(flags()[c.first] != 0)) : py::none();
      py::array_t<bool> out(shape);
      gather(out.mutable_data(), flags(), row_flags_,
             [](std::uint8_t x) { return x != 0; });
      return out;
    }
    case io::Kind::text: {
      if (scalar) return present(0, 0) ? py::object(py::str(texts_[c.first])) : py::none();
      py::list items;
      for (std::size_t k = 0; k < points_; ++k)
        for (std::size_t i = 0; i < c.width; ++i)
          items.append(present(k, i) ? py::object(py::str(texts_[cell(c, row_texts_, k, i)]))
                                     : py::none());
      return numpy_array(items, shape, all ? nullptr : "object");
    }
  }
  return py::none();
}

py::dict TableResult::decimal() const {
  py::dict out;
  for (const Column& c : columns_) {
    if (!c.numeric()) continue;
    const bool per_particle = c.field.shape == io::Shape::per_particle;
    py::list items;
    bool empty = false;
    for (std::size_t k = 0; k < points_; ++k)
      for (std::size_t i = 0; i < c.width; ++i) {
        const std::size_t at = cell(c, row_numbers_, k, i);
        if (!present()[k * row_present_ + c.present + i]) {
          items.append(py::none());
          empty = true;
        } else if (mpfr_ && !decimals_[at].empty()) {
          items.append(py::str(decimals_[at]));
        } else {
          // as the CLI prints it: a value's shortest text, an error covering its value's
          double x = numbers()[at];
          if (c.field.kind == io::Kind::error && !mpfr_) {
            double gap = doubles_[gaps_at_ + at];
            if (gap == io::deferred_gap)
              gap = c.value < columns_.size()
                        ? io::shortest_gap(numbers()[cell(columns_[c.value], row_numbers_, k, i)])
                        : 0;
            x = io::covering(x, gap);
          }
          char text[40];
          items.append(py::str(
              text, static_cast<std::size_t>(io::write_number(text, x, c.field.kind) - text)));
        }
      }
    const std::string name(c.field.name);
    if (single()) {
      out[name.c_str()] = per_particle ? py::object(items) : items[0];
      continue;
    }
    std::vector<py::ssize_t> shape = this->shape;
    if (per_particle) shape.push_back(static_cast<py::ssize_t>(c.width));
    out[name.c_str()] = numpy_array(items, shape, empty || points_ == 0 ? "object" : nullptr);
  }
  return out;
}

py::object TableResult::exact() const {
  if (!mpfr_) return py::none();  // a double run's floats are exact already
  py::dict out;
  for (const Column& c : columns_) {
    if (!c.numeric()) continue;
    py::list items;
    for (std::size_t k = 0; k < points_; ++k)
      for (std::size_t i = 0; i < c.width; ++i) {
        const std::size_t at = cell(c, row_numbers_, k, i);
        if (!present()[k * row_present_ + c.present + i]) {
          items.append(py::none());
          continue;
        }
        const io::ExactNumber& x = exact_[at];
        if (!x.kept()) items.append(py::float_(numbers()[at]));  // a double cell of an MPFR run
        else if (x.finite) items.append(py::make_tuple(x.mantissa, x.exponent));
        else items.append(py::float_(x.rounded));
      }
    out[std::string(c.field.name).c_str()] = items;
  }
  return out;
}

void TableResult::require_finite(const std::string& command, const std::string& reason) const {
  for (std::size_t k = 0; k < points_; ++k) {
    if (bytes_[finite_at_ + k]) continue;
    for (const Column& c : columns_) {
      if (!c.numeric()) continue;
      for (std::size_t i = 0; i < c.width; ++i) {
        if (!present()[k * row_present_ + c.present + i]) continue;
        const std::size_t at = cell(c, row_numbers_, k, i);
        const bool exact = mpfr_ && exact_[at].kept();
        const double x = exact ? exact_[at].rounded : numbers()[at];
        if (exact ? exact_[at].finite : std::isfinite(x)) continue;
        if (c.field.kind == io::Kind::error && bytes_[interrupted_at_ + k] && x > 0)
          continue;  // a bound never checked
        const std::string where = single() ? "" : " at " + index_text(k, shape);
        const std::string field = c.field.shape == io::Shape::per_particle
                                      ? std::string(c.field.name) + "[" + std::to_string(i) + "]"
                                      : std::string(c.field.name);
        throw invalid_input(command + ": the result is not finite (" + field + " = " +
                            (std::isnan(x) ? "nan" : x > 0 ? "inf" : "-inf") + where + "): " +
                            reason);
      }
    }
  }
}

void expose_table_result(py::module_& m) {
  py::class_<TableResult>(m, "_TableResult", py::dynamic_attr(),
                          "The base of the result classes generated from the output schema's "
                          "field tables (Averages, MicrocanonicalResult, SimulationResult).")
      .def_property_readonly(
          "shape", [](const TableResult& r) { return py::tuple(py::cast(r.shape)); },
          "Broadcast shape of the arguments: () for one point.")
      .def_property_readonly(
          "seconds",
          [](const TableResult& r) -> py::object {
            if (r.single()) return py::float_(r.points() ? r.seconds()[0] : 0.0);
            py::array_t<double> out(r.shape);
            std::copy(r.seconds(), r.seconds() + r.points(), out.mutable_data());
            return out;
          },
          "Wall time of the library call (the CLI's `seconds`): a float, an array for a grid.")
      .def_property_readonly("decimal", [](const TableResult& r) { return r.decimal(); },
                             "Every number as the CLI prints it (`--format json`): a double "
                             "run's shortest round-trip text, an MPFR run's `digits` digits; "
                             "errors with 3 significant digits rounded up, covering the printed "
                             "value's rounding. One point: str, or a list per particle; a grid: "
                             "numpy arrays. None: an empty cell.")
      .def("_exact_values", [](const TableResult& r) { return r.exact(); });
}

}  // namespace pendavg::python
