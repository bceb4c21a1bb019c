// SPDX-License-Identifier: GPL-3.0-or-later
// src/cli/case_columns.hpp -- the output columns of `average --cases` (after the input columns)
// and --columns, which selects and orders them. One list names them for the header and drives
// the row writer, so the two cannot disagree.
#pragma once

#include <cstddef>
#include <string>
#include <string_view>
#include <vector>

namespace pendavg::cli {

/// One quantity of a canonical (beta) cases row; the per-particle ones come once per particle.
enum class CaseField : unsigned char {
  beta_kinetic,            ///< beta_K_i
  beta_kinetic_error,      ///< error_K_i
  ratio,                   ///< <K_1>/<K_2> (empty for N = 1)
  cos_angle,               ///< cos_phi_i
  method,
  evaluations,
  ratio_error,
  cos_angle_error,         ///< cos_phi_error_i
  variance,                ///< var_K_i = Var K_i
  variance_error,          ///< var_K_error_i
  error_kind,              ///< of beta_K and ratio
  converged,
  cos_angle_error_kind,
  variance_error_kind,
  work_unit,
  equipartition_residual,
  kinetic_canonical,        ///< beta_Kc_i
  kinetic_canonical_error,  ///< beta_Kc_error_i
  kinetic_canonical_error_kind,
};

struct CaseColumn {
  CaseField field;
  std::size_t particle;  ///< 0-based, for the per-particle fields (0 for the others)
};

/// Every output column of a canonical cases row of N particles, in the default order, and their
/// header names (same order).
std::vector<CaseColumn> canonical_case_columns(std::size_t particles);
std::vector<std::string> canonical_case_column_names(std::size_t particles);

/// --columns LIST: the positions in `names` (a row's output columns, as in the header) of the
/// columns LIST selects, in LIST's order. LIST is comma separated; an item is a column name
/// (cos_phi2) or a per-particle family's stem (cos_phi: cos_phi1..N). Throws usage_error for an
/// empty list or item, an unknown name, an input column (`inputs`: always printed first) or a
/// column selected twice.
std::vector<std::size_t> select_case_columns(std::string_view list,
                                             const std::vector<std::string>& names,
                                             const std::vector<std::string>& inputs,
                                             std::size_t particles);

}  // namespace pendavg::cli
