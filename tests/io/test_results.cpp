// SPDX-License-Identifier: GPL-3.0-or-later
// tests/io/test_results.cpp -- the output schema's tables of `simulate`, `poincare` and
// `series` (src/io/results.hpp): every name follows the naming rules, and the records the
// builders fill agree with their tables in every format.
#include <catch2/catch.hpp>

#include "io/exact_values.hpp"
#include "io/migration.hpp"
#include "io/number_text.hpp"
#include "io/record.hpp"
#include "io/report.hpp"
#include "io/results.hpp"

#include "pendavg/mpfr.hpp"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdlib>
#include <limits>
#include <set>
#include <span>
#include <string>
#include <string_view>
#include <vector>

namespace {

using namespace pendavg;
using io::Field;
using io::Kind;
using io::Shape;

/// The tables whose fields share one JSON object and one CSV header.
std::vector<Field> joined(std::initializer_list<std::span<const Field>> tables) {
  std::vector<Field> out;
  for (const auto& t : tables) out.insert(out.end(), t.begin(), t.end());
  return out;
}

const Field* find(const std::vector<Field>& fields, std::string_view name) {
  const auto it = std::ranges::find_if(fields, [&](const Field& f) { return f.name == name; });
  return it == fields.end() ? nullptr : &*it;
}

/// The naming rules of schema 1 (README, Output schema), for fields printed together.
void check_naming(const std::vector<Field>& fields) {
  std::set<std::string_view> names;
  for (const Field& f : fields) {
    INFO(f.name);
    CHECK(names.insert(f.name).second);  // one JSON key per name
    CHECK(!f.name.empty());
    CHECK(std::ranges::all_of(f.name, [](char c) {
      return std::isalnum(static_cast<unsigned char>(c)) || c == '_';
    }));
    CHECK(!f.meaning.empty());
    // a value X has X_error (its absolute error, in the same shape) and X_error_kind
    if (f.name.ends_with("_error")) {
      CHECK(f.kind == Kind::error);
      const std::string_view value = f.name.substr(0, f.name.size() - 6);
      const Field* x = find(fields, value);
      REQUIRE(x != nullptr);
      CHECK(x->kind == Kind::real);
      CHECK(x->shape == f.shape);
      const Field* kind = find(fields, std::string(f.name) + "_kind");
      REQUIRE(kind != nullptr);
      CHECK(kind->kind == Kind::text);
      CHECK(kind->shape == Shape::scalar);
    }
    if (f.name.ends_with("_error_kind")) {
      CHECK((f.kind == Kind::text && f.shape == Shape::scalar));
      CHECK(find(fields, f.name.substr(0, f.name.size() - 5)) != nullptr);
    }
    // an error's qualifier (K_error_blocking): an error of a value of the same shape
    if (const std::size_t at = f.name.find("_error_");
        at != std::string_view::npos && !f.name.ends_with("_error_kind") &&
        !f.name.ends_with("_reason")) {
      CHECK(f.kind == Kind::error);
      const Field* x = find(fields, f.name.substr(0, at));
      REQUIRE(x != nullptr);
      CHECK(x->shape == f.shape);
    }
    if (f.name.ends_with("_reason")) CHECK((f.kind == Kind::text && f.shape == Shape::scalar));
    // schema 0's names that schema 1 renamed are gone
    for (const io::Rename& r : io::schema0_renames())
      if (r.old_name != r.new_name) CHECK(f.name != r.old_name);
  }
  // one name per concept
  for (const std::string_view old : {"particles", "error", "error_kind", "error_kinds",
                                     "var_K_beta2", "value", "bound", "i"})
    CHECK(!names.contains(old));
  // the CSV header: unique columns, the particle's index before "_error"
  const std::vector<std::string> columns = io::column_names(fields, 3);
  CHECK(std::set<std::string>(columns.begin(), columns.end()).size() == columns.size());
  for (const std::string& c : columns) {
    INFO(c);
    const std::size_t at = c.find("_error");
    if (at != std::string::npos && at + 6 < c.size())
      CHECK(!std::isdigit(static_cast<unsigned char>(c[at + 6])));
  }
}

/// A record's JSON, CSV and text agree with its table: every field once as a JSON key, one CSV
/// cell per column (no text cell holds a comma), one text line or column per field.
void check_record(const io::Record& record) {
  REQUIRE_NOTHROW(record.complete());
  CHECK(record.cells().size() == io::cell_count(record.fields(), record.particles()));
  std::string json = "{";
  io::append_json_members(json, record);
  json += "}";
  for (const Field& f : record.fields()) {
    const std::string key = io::json_string(f.name) + ": ";
    INFO(key);
    const std::size_t at = json.find(key);
    CHECK(at != std::string::npos);
    CHECK(json.find(key, at + 1) == std::string::npos);
  }
  for (const char* bad : {": nan", ": inf", "[nan", "[inf", ", nan", ", inf", "-nan", "-inf"})
    CHECK(json.find(bad) == std::string::npos);
  std::string csv;
  io::append_csv_cells(csv, record);
  CHECK(static_cast<std::size_t>(std::ranges::count(csv, ',')) ==
        io::column_names(record.fields(), record.particles()).size());
  CHECK(io::text_cells(record).size() == record.cells().size());
}

std::string cell(const io::Record& record, std::string_view name, std::size_t i = 0) {
  const std::size_t k = record.find(name);
  REQUIRE(k < record.fields().size());
  const auto cells = record.cells_of(k);
  REQUIRE(i < cells.size());
  const io::Cell& c = cells[i];
  if (c.tag == io::Cell::Tag::none) return "null";
  std::string out(io::max_cell_length(record, c), '\0');
  out.resize(static_cast<std::size_t>(io::write_cell(out.data(), record, c) - out.data()));
  return out;
}

TimeAverage<double> time_average(double value, double error, double tau) {
  TimeAverage<double> x;
  x.value = value;
  x.error = error;
  x.autocorrelation_time = tau;
  return x;
}

SimulationResult<double> a_run(std::size_t n, double error) {
  SimulationResult<double> r;
  for (std::size_t i = 0; i < n; ++i) {
    r.kinetic.push_back(time_average(0.3 + 0.1 * static_cast<double>(i), error, 0.23));
    r.kinetic_canonical.push_back(time_average(0.7, error, 0.2));
    r.cos_angle.push_back(time_average(0.5, error, 0.1));
  }
  r.kinetic_total = time_average(1.2, error, 0.2);
  r.potential = time_average(-1.2, error, 0.2);
  r.energy_drift = -1.0714610877259084e-13;
  r.energy_error_max = 1.09e-13;
  r.energy_error_rms = 6.2e-14;
  r.energy_trend = -2.7e-14;
  r.constraint_residual = 8.881784197001252e-16;
  r.steps = r.samples = 20000;
  r.newton_solves = 130005;
  r.simulated_time = 20;
  return r;
}

io::ExactValues exact_values(std::size_t n) {
  io::ExactValues e;
  for (std::size_t i = 0; i < n; ++i) {
    e.kinetic.push_back(0.4625006486855847);
    e.kinetic_error.push_back(2.47e-15);
    e.cos_angle.push_back(0.59);
    e.cos_angle_error.push_back(5.3e-15);
    e.variance.push_back(0.25);
    e.variance_error.push_back(7.3e-15);
  }
  e.kinetic_canonical = 0.68;
  e.kinetic_canonical_error = 3.6e-15;
  e.excitation = 3;
  e.method = "microcanonical/integral";
  e.error_kind = e.kinetic_canonical_error_kind = e.cos_angle_error_kind = e.variance_error_kind =
      "estimate";
  return e;
}

}  // namespace

TEST_CASE("io: the tables of simulate, poincare and series follow the naming rules",
          "[io][schema]") {
  SECTION("simulate") {
    check_naming(joined({io::simulation_input_fields(), io::simulation_fields(),
                         io::replica_fields()}));
  }
  SECTION("poincare") {
    check_naming(joined({io::poincare_fields(), io::section_point_fields()}));
  }
  SECTION("series") {
    check_naming(joined({io::canonical_input_fields(), io::series_run_fields(),
                         io::series_row_fields()}));
  }
  SECTION("the naming table lists them") {
    std::set<const Field*> listed;
    for (const io::NamedTable& t : io::all_tables()) listed.insert(t.fields.data());
    for (const auto table : {io::simulation_input_fields(), io::simulation_fields(),
                             io::replica_fields(), io::poincare_fields(),
                             io::section_point_fields(), io::series_run_fields(),
                             io::series_row_fields()})
      CHECK(listed.contains(table.data()));
  }
}

TEST_CASE("io: column names put the particle's index before _error", "[io][schema]") {
  const Field k_error{"K_error", Kind::error, Shape::per_particle, "x"};
  const Field blocking{"K_error_blocking", Kind::error, Shape::per_particle, "x"};
  const Field exact{"exact_cos_phi_error", Kind::error, Shape::per_particle, "x"};
  const Field tau{"K_autocorrelation_time", Kind::real, Shape::per_particle, "x"};
  const Field scalar{"energy_error_max", Kind::error, Shape::scalar, "x"};
  CHECK(io::column_name(k_error, 0) == "K1_error");
  CHECK(io::column_name(blocking, 1) == "K2_error_blocking");
  CHECK(io::column_name(exact, 11) == "exact_cos_phi12_error");
  CHECK(io::column_name(tau, 2) == "K_autocorrelation_time3");
  CHECK(io::column_name(scalar, 2) == "energy_error_max");
}

TEST_CASE("io: simulate's records agree with their tables", "[io][schema]") {
  const Chain<double> chain({1, 2}, {1, 0.5}, 9.81);
  const std::string_view texts[] = {"9.81", "1", "2", "1", "0.5"};
  SimulationOptions run;
  run.time_step = 1e-3;
  run.duration = 20;

  SECTION("NVE with exact values") {
    io::Record inputs(io::simulation_input_fields(), 2);
    io::append_simulation_inputs(inputs, chain, run, "yoshida6", texts);
    check_record(inputs);
    CHECK(cell(inputs, "ensemble") == "microcanonical");
    CHECK(cell(inputs, "g") == "9.81");  // as written
    CHECK(cell(inputs, "l", 1) == "0.5");
    CHECK(cell(inputs, "beta") == "null");
    CHECK(cell(inputs, "friction") == "null");
    io::Record result(io::simulation_fields(), 2);
    const io::ExactValues exact = exact_values(2);
    io::append_simulation(result, a_run(2, 4.187407670e-02), -1.8369701987210297e-16, &exact,
                          false);
    check_record(result);
    // values: the shortest text that reads back as the same double; errors 3 digits, up
    CHECK(cell(result, "energy") == "-1.8369701987210297e-16");
    CHECK(cell(result, "exact_K", 1) == "0.4625006486855847");
    CHECK(cell(result, "K_error", 0) == "4.19e-02");
    CHECK(cell(result, "constraint_residual") == "8.89e-16");
    CHECK(cell(result, "energy_drift") == "-1.0714610877259084e-13");
    CHECK(cell(result, "K_error_kind") == "statistical");
    CHECK(cell(result, "exact_K_error_kind") == "estimate");
    CHECK(cell(result, "exact_excitation") == "3");
    CHECK(cell(result, "error_reason") == "null");
    CHECK(cell(result, "energy_trend_reason") == "null");
    CHECK(cell(result, "exact_var_K_reason") == "null");
    // K_deviation_sigmas = (K - exact_K) / hypot(K_error, exact_K_error)
    const double sigmas = (0.3 - 0.4625006486855847) / std::hypot(4.187407670e-02, 2.47e-15);
    CHECK(std::strtod(cell(result, "K_deviation_sigmas", 0).c_str(), nullptr) == sigmas);
  }
  SECTION("--exact no, unknown error bars, Langevin, replicas") {
    run.thermostat = Thermostat::langevin;
    run.beta = 2;
    io::Record inputs(io::simulation_input_fields(), 3);
    const Chain<double> chain3({1, 1, 1}, {1, 1, 1}, 1);
    io::append_simulation_inputs(inputs, chain3, run, "baoab-rattle");
    check_record(inputs);
    CHECK(cell(inputs, "ensemble") == "canonical");
    CHECK(cell(inputs, "beta") == "2");
    CHECK(cell(inputs, "friction") == "1");
    io::Record result(io::simulation_fields(), 3);
    const double unknown = std::numeric_limits<double>::quiet_NaN();
    io::append_simulation(result, a_run(3, unknown), -6, nullptr, true);
    check_record(result);
    for (std::size_t i = 0; i < 3; ++i) {
      CHECK(cell(result, "K_error", i) == "null");
      CHECK(cell(result, "exact_K", i) == "null");
      CHECK(cell(result, "exact_var_K_error", i) == "null");
      CHECK(cell(result, "K_deviation_sigmas", i) == "null");
    }
    CHECK(cell(result, "error_reason") != "null");
    CHECK(cell(result, "exact_method") == "null");
    CHECK(cell(result, "exact_K_error_kind") == "null");
    CHECK(cell(result, "energy_trend") == "null");
    CHECK(cell(result, "energy_trend_reason") != "null");
    io::ReplicaSpread spread;
    spread.replicas = 1;
    spread.requested = 4;
    // errors exact in binary: printed rounded up, 0.1 (0.1000000000000000055...) would read 1.01e-01
    spread.kinetic_blocking = spread.canonical_blocking = spread.cosine_blocking = {0.125, 0.25, 0.5};
    spread.kinetic_replicas = spread.canonical_replicas = spread.cosine_replicas = {unknown, unknown,
                                                                                   unknown};
    io::Record replicas(io::replica_fields(), 3);
    io::append_replicas(replicas, spread, 10);
    check_record(replicas);
    CHECK(cell(replicas, "K_error_replicas", 2) == "null");
    CHECK(cell(replicas, "K_error_blocking", 2) == "5.00e-01");
    CHECK(cell(replicas, "replicas_error_reason") != "null");
    // the report: one CSV row under its header, every field a JSON key
    const io::Report report{"simulate", {&inputs}, {{"", {&result, &replicas}, ""}}, {}, 1.5};
    const std::string csv = io::format_report(report, io::Format::csv);
    CHECK(csv.starts_with("# schema: 1\n# pendavg simulate\nN,g,m1,m2,m3,"));
    CHECK(std::ranges::count(csv, '\n') == 4);
    const std::string json = io::format_report(report, io::Format::json);
    CHECK(json.starts_with("{\"schema\": 1, \"command\": \"simulate\", \"N\": 3,"));
    CHECK(json.find("\"run\"") == std::string::npos);
    CHECK(json.find("\"K1_error_blocking\"") == std::string::npos);
    CHECK(json.find("\"K_error_blocking\": [1.25e-01, 2.50e-01, 5.00e-01]") != std::string::npos);
  }
}

TEST_CASE("io: poincare's points as a list report", "[io][schema]") {
  const Chain<double> chain({1, 2}, {1, 0.5}, 2);
  PoincareOptions options;
  options.orbits = 2;
  options.points = 2;
  PoincareSection<double> section;
  section.energy = 0;
  section.steps = 1234;
  section.energy_error_max = 1.8e-7;
  for (std::size_t k = 0; k < 4; ++k) {
    SectionPoint<double> p;
    p.orbit = k / 2;
    p.phi2 = 0.1 * static_cast<double>(k) - 0.15;
    p.p2 = 1.0 / 3;
    p.time = 5.5 + static_cast<double>(k);
    section.points.push_back(p);
  }
  const std::string_view texts[] = {"0", "2", "1", "2", "1", "0.5"};
  io::Record head(io::poincare_fields(), 2);
  io::append_poincare(head, chain, options, section, texts);
  check_record(head);
  CHECK(cell(head, "energy") == "0");
  CHECK(cell(head, "points_per_orbit") == "2");
  CHECK(cell(head, "energy_error_max") == "1.80e-07");
  const io::ListReport report{
      "poincare", {&head}, "points", io::section_point_fields(), section.points.size(),
      [&](std::size_t k, io::Record& r) { io::append_section_point(r, section.points[k]); }, {}};
  const std::string csv = io::format_list_report(report, io::Format::csv);
  CHECK(csv.starts_with("# schema: 1\n# pendavg poincare\nN,g,m1,m2,l1,l2,energy,orbits,"
                        "points_per_orbit,dt,steps,energy_error_max,interrupted,orbit,phi2,p2,"
                        "time\n"));
  CHECK(std::ranges::count(csv, '\n') == 3 + 4);
  CHECK(csv.find(",false,1,0.15000000000000005,0.3333333333333333,8.5\n") != std::string::npos);
  const std::string json = io::format_list_report(report, io::Format::json);
  CHECK(json.find("\"points\": [{\"orbit\": 0, \"phi2\": -0.15, \"p2\": 0.3333333333333333, "
                  "\"time\": 5.5}, {") != std::string::npos);
  CHECK(json.ends_with("}]}\n"));
  const std::string text = io::format_list_report(report, io::Format::text);
  CHECK(text.find("orbit  ") != std::string::npos);
}

TEST_CASE("io: series rows as doubles cover the MPFR values, or stay decimals", "[io][schema]") {
  const working_precision guard(16 + guard_digits);
  const Chain<mpfr_real> chain({mpfr_real("0.6"), mpfr_real("0.4")}, {mpfr_real(1), mpfr_real(1)},
                               mpfr_real(1));
  const mpfr_real beta(1);
  std::vector<SeriesRow<mpfr_real>> rows = series_convergence(chain, beta, 16, 6);
  REQUIRE(rows.size() == 6);
  CHECK(io::series_fits_double(rows, chain, beta));
  io::Record row(io::series_row_fields(), 2);
  for (const SeriesRow<mpfr_real>& r : rows) {
    row.reset(io::series_row_fields(), 2);
    io::append_series_row(row, r, io::Printing{16}, true);
    check_record(row);
    // the printed beta_K1 (the double its text reads back as) +- beta_K1_error holds the MPFR
    // value's bound interval
    const double printed = std::strtod(cell(row, "beta_K1").c_str(), nullptr);
    CHECK(printed == mpfr_get_d(r.beta_kinetic1.backend().data(), MPFR_RNDN));
    const mpfr_real error(cell(row, "beta_K1_error").c_str());
    CHECK(abs(mpfr_real(printed) - r.beta_kinetic1) + r.bound <= error);
    CHECK(cell(row, "n") == std::to_string(r.n));
  }
  // no bound yet: null; the decimals of a run that does not fit a double
  SeriesRow<mpfr_real> open = rows.back();
  open.bound = std::numeric_limits<mpfr_real>::infinity();
  row.reset(io::series_row_fields(), 2);
  io::append_series_row(row, open, io::Printing{16}, false);
  check_record(row);
  CHECK(cell(row, "beta_K1_error") == "null");
  CHECK(cell(row, "beta_K1").find('e') != std::string::npos);  // 16 digits, scientific
  std::vector<SeriesRow<mpfr_real>> tiny = rows;
  tiny.back().term = mpfr_real("1e-400");
  CHECK_FALSE(io::series_fits_double(tiny, chain, beta));
  CHECK_FALSE(io::series_fits_double(rows, chain, mpfr_real("1e-320")));
  io::Record run(io::series_run_fields(), 2);
  io::append_series_run(run, rows.size(), false);
  check_record(run);
  CHECK(cell(run, "beta_K1_error_kind") == "bound");
}
