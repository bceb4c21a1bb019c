// SPDX-License-Identifier: GPL-3.0-or-later
// src/cli/case_columns.cpp -- the output columns of `average --cases` and --columns.
#include "case_columns.hpp"

#include "args.hpp"

#include <algorithm>
#include <unordered_map>

namespace pendavg::cli {

namespace {

/// The canonical row's columns in order: a per-particle family (stem given) or one column.
struct ColumnSpec {
  CaseField field;
  std::string_view name;  ///< the stem of a family, or the column's name
  bool per_particle;
};

constexpr ColumnSpec canonical_specs[] = {
    {CaseField::beta_kinetic, "beta_K", true},
    {CaseField::beta_kinetic_error, "error_K", true},
    {CaseField::ratio, "ratio", false},
    {CaseField::cos_angle, "cos_phi", true},
    {CaseField::method, "method", false},
    {CaseField::evaluations, "evaluations", false},
    {CaseField::ratio_error, "ratio_error", false},
    {CaseField::cos_angle_error, "cos_phi_error", true},
    {CaseField::variance, "var_K", true},
    {CaseField::variance_error, "var_K_error", true},
    {CaseField::error_kind, "error_kind", false},
    {CaseField::converged, "converged", false},
    {CaseField::cos_angle_error_kind, "cos_phi_error_kind", false},
    {CaseField::variance_error_kind, "var_K_error_kind", false},
    {CaseField::work_unit, "work_unit", false},
    {CaseField::equipartition_residual, "equipartition_residual", false},
    {CaseField::kinetic_canonical, "beta_Kc", true},
    {CaseField::kinetic_canonical_error, "beta_Kc_error", true},
    {CaseField::kinetic_canonical_error_kind, "beta_Kc_error_kind", false},
};

}  // namespace

std::vector<CaseColumn> canonical_case_columns(std::size_t particles) {
  std::vector<CaseColumn> columns;
  for (const ColumnSpec& spec : canonical_specs) {
    if (!spec.per_particle) columns.push_back({spec.field, 0});
    else
      for (std::size_t i = 0; i < particles; ++i) columns.push_back({spec.field, i});
  }
  return columns;
}

std::vector<std::string> canonical_case_column_names(std::size_t particles) {
  std::vector<std::string> names;
  for (const ColumnSpec& spec : canonical_specs) {
    if (!spec.per_particle) names.emplace_back(spec.name);
    else
      for (std::size_t i = 1; i <= particles; ++i)
        names.push_back(std::string(spec.name) + std::to_string(i));
  }
  return names;
}

std::vector<std::size_t> select_case_columns(std::string_view list,
                                             const std::vector<std::string>& names,
                                             const std::vector<std::string>& inputs,
                                             std::size_t particles) {
  const std::string where = "average: --columns: ";
  std::unordered_map<std::string_view, std::size_t> position;
  for (std::size_t k = 0; k < names.size(); ++k) position.emplace(names[k], k);
  std::vector<std::size_t> selected;
  std::vector<bool> taken(names.size(), false);
  const auto take = [&](std::size_t k, std::string_view item) {
    if (taken[k])
      throw usage_error(where + "column " + in_quotes(names[k]) + " selected twice (by " +
                        in_quotes(item) + ")");
    taken[k] = true;
    selected.push_back(k);
  };
  if (list.empty()) throw usage_error(where + "needs a list of column names");
  for (std::size_t begin = 0; begin <= list.size();) {
    std::size_t end = list.find(',', begin);
    if (end == std::string_view::npos) end = list.size();
    const std::string_view item = list.substr(begin, end - begin);
    begin = end + 1;
    if (item.empty()) throw usage_error(where + "an empty column name in " + in_quotes(list));
    if (const auto found = position.find(item); found != position.end()) {
      take(found->second, item);
      continue;
    }
    // A family's stem: stem1..stemN are all columns.
    if (particles > 0 && position.contains(std::string(item) + "1")) {
      for (std::size_t i = 1; i <= particles; ++i) {
        const auto member = position.find(std::string(item) + std::to_string(i));
        if (member == position.end()) break;
        take(member->second, item);
      }
      continue;
    }
    if (std::find(inputs.begin(), inputs.end(), item) != inputs.end())
      throw usage_error(where + in_quotes(item) + " is an input column: every row starts with "
                        "the input columns; --columns chooses among the output columns");
    std::string known;
    for (std::size_t k = 0; k < names.size() && known.size() < 400; ++k) {
      const std::string& name = names[k];
      // list each family once, by its stem
      const std::size_t digits = name.find_last_not_of("0123456789") + 1;
      if (digits < name.size() && name.substr(digits) != "1") continue;
      (known += known.empty() ? "" : ", ") += name.substr(0, digits);
    }
    throw usage_error(where + "unknown column " + in_quotes(item) + " (one of: " + known +
                      "; a stem such as cos_phi selects cos_phi1..N)");
  }
  return selected;
}

}  // namespace pendavg::cli
