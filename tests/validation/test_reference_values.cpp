// SPDX-License-Identifier: GPL-3.0-or-later
// tests/validation/test_reference_values.cpp -- the library against the public reference values in
// tests/data/public_values.csv (published reference values; its comment lines name the source:
// an independent high-precision evaluation of the 1-D reduced integral at 30 and 40 digits, and
// the paper's own quoted limits, eq. aveK1-beta0).
//
// Every N = 2 row is checked at 30 digits to the number of significant digits the file gives,
// minus one, and in double to 2e-15 relative (the product target). Rows with beta = 0 are the
// beta -> 0 limit. Rows of N >= 3 (several values, one per particle) are checked with the any-N
// engine that average() chooses, in double and at 20 digits, to the digits given minus one.
#include <catch2/catch.hpp>

#include "pendavg/chain.hpp"
#include "engine/double_pendulum/double_pendulum.hpp"
#include "engine/numerics/precision.hpp"
#include "pendavg/average.hpp"
#include "pendavg/result.hpp"

#include <cctype>
#include <algorithm>
#include <cmath>
#include <cstddef>
#include <fstream>
#include <iterator>
#include <sstream>
#include <string>
#include <vector>

#ifndef PENDAVG_TEST_DATA_DIR
#error "PENDAVG_TEST_DATA_DIR must name the tests/data directory"
#endif

namespace {

using pendavg::mpfr_real;

/// One data row: N, masses, lengths, g, beta, quantity, value (all kept as the file's text).
struct ReferenceRow {
  int line = 0;
  std::size_t particles = 0;
  std::vector<std::string> masses, lengths;
  std::string g, beta, quantity;
  std::vector<std::string> values;  // one per quantity named (the N = 3 row lists three)
};

std::vector<std::string> split(const std::string& s, char sep) {
  std::vector<std::string> out;
  std::string field;
  std::istringstream is(s);
  while (std::getline(is, field, sep)) out.push_back(field);
  return out;
}

std::vector<std::string> words(const std::string& s) {
  std::vector<std::string> out;
  std::istringstream is(s);
  std::string w;
  while (is >> w) out.push_back(w);
  return out;
}

std::string trim(const std::string& s) {
  std::size_t b = 0, e = s.size();
  while (b < e && std::isspace(static_cast<unsigned char>(s[b]))) ++b;
  while (e > b && std::isspace(static_cast<unsigned char>(s[e - 1]))) --e;
  return s.substr(b, e - b);
}

std::vector<ReferenceRow> read_reference_file(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw std::runtime_error("cannot open " + path);
  std::vector<ReferenceRow> rows;
  std::string line;
  int number = 0;
  while (std::getline(in, line)) {
    ++number;
    const std::string t = trim(line);
    if (t.empty() || t[0] == '#') continue;
    const std::vector<std::string> f = split(t, ',');
    if (f.size() != 7) throw std::runtime_error(path + ":" + std::to_string(number) + ": expected 7 fields");
    ReferenceRow r;
    r.line = number;
    r.particles = static_cast<std::size_t>(std::stoul(trim(f[0])));
    r.masses = words(f[1]);
    r.lengths = words(f[2]);
    r.g = trim(f[3]);
    r.beta = trim(f[4]);
    r.quantity = trim(f[5]);
    r.values = words(f[6]);
    rows.push_back(std::move(r));
  }
  return rows;
}

/// Significant decimal digits written in a decimal string ("0.3431..." -> digits after the
/// leading zeros; an exponent is ignored).
int significant_digits(const std::string& s) {
  int count = 0;
  bool leading = true;
  for (char ch : s) {
    if (ch == 'e' || ch == 'E') break;
    if (!std::isdigit(static_cast<unsigned char>(ch))) continue;
    if (leading && ch == '0') continue;
    leading = false;
    ++count;
  }
  return count;
}

enum class Kind { kinetic, cos_angle };

/// Maps "beta*K1 (beta->0 limit)", "beta*K2", "cos phi1", ... to a quantity and a particle.
bool parse_quantity(const std::string& q, Kind& kind, std::size_t& particle) {
  const std::string& head = q;
  if (head.rfind("beta*K", 0) == 0 && head.size() > 6 && std::isdigit(static_cast<unsigned char>(head[6]))) {
    kind = Kind::kinetic;
    particle = static_cast<std::size_t>(head[6] - '1');
    return true;
  }
  if (head.rfind("cos phi", 0) == 0 && head.size() > 7 && std::isdigit(static_cast<unsigned char>(head[7]))) {
    kind = Kind::cos_angle;
    particle = static_cast<std::size_t>(head[7] - '1');
    return true;
  }
  return false;
}

template <class Real>
const Real& pick(const pendavg::Averages<Real>& a, Kind k, std::size_t i) {
  return k == Kind::kinetic ? a.beta_kinetic.at(i).value : a.cos_angle.at(i).value;
}

std::string reference_path() { return std::string(PENDAVG_TEST_DATA_DIR) + "/public_values.csv"; }

template <class Real>
pendavg::Chain<Real> chain_from(const ReferenceRow& r) {
  std::vector<Real> m, l;
  for (const std::string& s : r.masses) m.push_back(Real(s.c_str()));
  for (const std::string& s : r.lengths) l.push_back(Real(s.c_str()));
  return pendavg::Chain<Real>(std::move(m), std::move(l), Real(r.g.c_str()));
}

template <>
pendavg::Chain<double> chain_from<double>(const ReferenceRow& r) {
  std::vector<double> m, l;
  for (const std::string& s : r.masses) m.push_back(std::stod(s));
  for (const std::string& s : r.lengths) l.push_back(std::stod(s));
  return pendavg::Chain<double>(std::move(m), std::move(l), std::stod(r.g));
}

bool is_zero(const std::string& s) { return std::stod(s) == 0.0; }

}  // namespace

TEST_CASE("public reference values: N = 2 at 30 digits and in double, N = 3 in double and at 20 digits",
          "[reference]") {
  const std::vector<ReferenceRow> rows = read_reference_file(reference_path());
  std::size_t checked = 0;
  for (const ReferenceRow& r : rows) {
    INFO("public_values.csv line " << r.line << ": N = " << r.particles << ", " << r.quantity << " = "
                                   << (r.values.empty() ? std::string("?") : r.values.front()));
    if (r.particles != 2) {
      std::istringstream names(r.quantity);
      const std::vector<std::string> quantities{std::istream_iterator<std::string>(names), {}};
      REQUIRE(quantities.size() == r.values.size());
      const auto in_double = pendavg::average<double>(chain_from<double>(r), std::stod(r.beta));
      const pendavg::working_precision guard(20 + pendavg::guard_digits);
      pendavg::AverageOptions options;
      options.digits = 20;
      const auto in_mpfr = pendavg::average<mpfr_real>(chain_from<mpfr_real>(r),
                                                       mpfr_real(r.beta.c_str()), options);
      for (std::size_t k = 0; k < quantities.size(); ++k) {
        Kind kind{};
        std::size_t particle = 0;
        REQUIRE(parse_quantity(quantities[k], kind, particle));
        REQUIRE(particle < r.particles);
        const int given = significant_digits(r.values[k]);
        REQUIRE(given >= 3);
        const double tol = std::pow(10.0, -(std::min(given, 16) - 1));
        const double expected = std::stod(r.values[k]);
        INFO(quantities[k] << " = " << r.values[k] << ": double " << pick(in_double, kind, particle)
                           << ", 20 digits " << pick(in_mpfr, kind, particle).convert_to<double>());
        CHECK(std::abs(pick(in_double, kind, particle) - expected) <= tol * std::abs(expected));
        CHECK(abs(pick(in_mpfr, kind, particle) - mpfr_real(r.values[k].c_str())) <=
              tol * std::abs(expected));
      }
      ++checked;
      continue;
    }
    REQUIRE(r.masses.size() == 2);
    REQUIRE(r.lengths.size() == 2);
    REQUIRE(r.values.size() == 1);
    Kind kind{};
    std::size_t particle = 0;
    REQUIRE(parse_quantity(r.quantity, kind, particle));
    REQUIRE(particle < 2);
    const bool limit = is_zero(r.beta);
    // A beta = 0 row is the beta -> 0 limit and must say so; a finite-beta row must not.
    CHECK(limit == (r.quantity.find("beta->0") != std::string::npos));
    const int given = significant_digits(r.values.front());
    REQUIRE(given >= 3);

    {  // 30 digits
      const int digits = 30;
      const pendavg::working_precision guard(digits + pendavg::guard_digits);
      const mpfr_real expected(r.values.front().c_str());
      const mpfr_real tol = pow(mpfr_real(10), -(std::min(given, digits) - 1));
      const pendavg::Chain<mpfr_real> chain = chain_from<mpfr_real>(r);
      std::vector<std::pair<std::string, pendavg::Averages<mpfr_real>>> results;
      if (limit) {
        pendavg::AverageOptions options;
        options.digits = digits;
        results.emplace_back("limit", pendavg::high_temperature_limit<mpfr_real>(chain, options));
      } else {
        const mpfr_real beta(r.beta.c_str());
        results.emplace_back("integral", pendavg::reduced_integral_average<mpfr_real>(chain, beta, digits));
        pendavg::AverageOptions options;
        options.digits = digits;
        results.emplace_back("automatic", pendavg::average<mpfr_real>(chain, beta, options));
        if (kind == Kind::kinetic) {
          results.emplace_back("series", pendavg::series_average<mpfr_real>(chain, beta, digits));
        }
      }
      for (const auto& [engine, a] : results) {
        const mpfr_real got = pick(a, kind, particle);
        const mpfr_real rel = abs(got - expected) / abs(expected);
        std::ostringstream os;
        os.precision(digits + 2);
        os << got;
        INFO(engine << ": " << os.str() << " (relative difference " << rel.convert_to<double>() << ", tolerance 1e-"
                    << (std::min(given, digits) - 1) << ")");
        CHECK(rel <= tol);
      }
    }
    {  // double
      const double expected = std::stod(r.values.front());
      const pendavg::Chain<double> chain = chain_from<double>(r);
      std::vector<std::pair<std::string, pendavg::Averages<double>>> results;
      if (limit) {
        results.emplace_back("limit", pendavg::high_temperature_limit<double>(chain));
      } else {
        const double beta = std::stod(r.beta);
        results.emplace_back("integral", pendavg::reduced_integral_average<double>(chain, beta, 16));
        results.emplace_back("automatic", pendavg::average<double>(chain, beta));
        if (kind == Kind::kinetic) results.emplace_back("series", pendavg::series_average<double>(chain, beta, 16));
      }
      for (const auto& [engine, a] : results) {
        const double got = pick(a, kind, particle);
        INFO(engine << ": " << got << " (relative difference " << std::abs(got - expected) / std::abs(expected) << ")");
        CHECK(std::abs(got - expected) <= 2e-15 * std::abs(expected));
      }
    }
    ++checked;
  }
  // The file has five N = 2 rows; an empty or unreadable file must not pass silently.
  CHECK(checked >= 5);
}
