// SPDX-License-Identifier: GPL-3.0-or-later
// src/io/migration.cpp -- schema 0 -> 1 renames.
#include "io/migration.hpp"

#include "io/record.hpp"

namespace pendavg::io {

namespace {

constexpr Rename renames[] = {
    {"error_K", "beta_K_error", true, "average --format csv, average --cases, table"},
    {"error", "beta_K_error", false, "average and limit JSON (an array)", "Averages"},
    {"K_error", "K_error", true, "CSV: K_error1..N became K1_error..N"},
    {"cos_phi_error", "cos_phi_error", true, "CSV: cos_phi_error1..N became cos_phi1_error..N"},
    {"var_K_error", "var_K_error", true, "CSV: var_K_error1..N became var_K1_error..N"},
    {"beta_Kc_error", "beta_Kc_error", true, "CSV: beta_Kc_error1..N became beta_Kc1_error..N"},
    {"beta2_var_K_error", "beta2_var_K_error", true,
     "limit CSV: beta2_var_K_error1..N became beta2_var_K1_error..N"},
    {"var_K_beta2", "beta2_var_K", false, "limit JSON", "Averages"},
    {"var_K_beta2_error", "beta2_var_K_error", false, "limit JSON", "Averages"},
    {"error_kind", "beta_K_error_kind", false,
     "average, limit, table, --cases: the kind of beta_K's and ratio's errors (now also "
     "ratio_error_kind and K_error_kind)",
     "Averages"},
    {"error_kinds", "X_error_kind", false, "average and limit JSON: error_kinds.X became X_error_kind",
     "Averages"},
    {"particles", "N", false, "simulate"},
    {"exact_error_kinds", "exact_X_error_kind", false, "simulate JSON"},
    // simulate (after the averages': --columns takes the first entry of an old name)
    {"error_kind", "K_error_kind", false,
     "simulate: the kind of K_error, Kc_error and cos_phi_error (now K_error_kind, Kc_error_kind, "
     "cos_phi_error_kind, and the new K_total_error_kind and potential_error_kind)",
     "SimulationResult"},
    {"exact_error_kind", "exact_K_error_kind", false, "simulate", "SimulationResult"},
    {"method", "", false,
     "Python simulate: method ('dynamics-nve', 'dynamics-langevin') went away; ensemble says the "
     "same ('microcanonical', 'canonical')"},
    {"final_energy", "", false,
     "Python simulate: final_energy went away; E(T) = energy + energy_drift (sum m) g (sum l)"},
    {"i", "", false,
     "simulate CSV: one row per particle i became one row per run (the '#' lines' values are "
     "columns): a per-particle column X became X1..XN, its error X_error X1_error..XN_error and "
     "K_error_blocking K1_error_blocking..KN_error_blocking"},
    // series
    {"value", "beta_K1", false, "series rows: beta<K1> summed to term n"},
    {"bound", "beta_K1_error", false,
     "series rows: the truncation bound, now 3 digits rounded up (null, not inf, while none "
     "exists)"},
    {"error_kind", "beta_K1_error_kind", false, "series JSON"},
};

}  // namespace

std::span<const Rename> schema0_renames() { return renames; }

std::vector<std::pair<std::string, std::string>> schema0_columns(std::string_view old_name,
                                                                 std::size_t particles) {
  std::vector<std::pair<std::string, std::string>> columns;
  for (const Rename& r : renames) {
    const Field field{r.new_name, Kind::real, r.per_particle ? Shape::per_particle : Shape::scalar,
                      {}};
    if (!r.per_particle) {
      // an old name of several commands: its first entry, the averages' (the CSV --columns reads)
      if (r.old_name == old_name && r.old_name != r.new_name && !r.new_name.empty() &&
          r.new_name != "X_error_kind") {
        columns.emplace_back(std::string(old_name), std::string(r.new_name));
        return columns;
      }
      continue;
    }
    // the old stem, or one old column stem + i
    if (old_name == r.old_name) {
      for (std::size_t i = 0; i < particles; ++i)
        columns.emplace_back(std::string(r.old_name) + std::to_string(i + 1), column_name(field, i));
      if (!columns.empty()) return columns;
    }
    if (old_name.starts_with(r.old_name) && old_name.size() > r.old_name.size()) {
      const std::string_view index = old_name.substr(r.old_name.size());
      if (index.find_first_not_of("0123456789") != std::string_view::npos || index[0] == '0')
        continue;
      const std::size_t i = std::stoul(std::string(index));
      if (i >= 1 && i <= particles) {
        columns.emplace_back(std::string(old_name), column_name(field, i - 1));
        return columns;
      }
    }
  }
  return columns;
}

}  // namespace pendavg::io
