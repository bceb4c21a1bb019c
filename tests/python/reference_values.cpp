// SPDX-License-Identifier: GPL-3.0-or-later
// tests/python/reference_values.cpp -- the C++ library's results, printed exactly, for the Python
// tests' bitwise comparison (tests/python/test_pendavg.py, test_python_bits_equal_the_library).
//
// It calls the library directly (pendavg::average, high_temperature_limit, low_temperature_limit,
// microcanonical_average[_excitation]) with AverageOptions set field by field, not through the
// CLI's or the module's option readers. Each line of stdin is one call:
//
//   average        digits=D beta=B g=G masses=M1,M2,... lengths=L1,L2,... [method=NAME] [tol=T]
//                  [samples=S] [shifts=R] [seed=K]
//   limit          digits=D g=G masses=... lengths=...
//   microcanonical digits=D g=G masses=... lengths=... (energy=E | excitation=X) [method=NAME] ...
//
// Numbers are decimal texts: read by strtod in double (a Python float's repr gives back that
// float) and as mpfr_real(text) at digits + guard_digits in MPFR (correctly rounded, as the CLI
// reads them). Each call prints one JSON line: {"values": {field: [...]}, "decimal": {...},
// "method": ..., ...} where every number is exact -- a double as printf's %a, an MPFR value as
// mpfr's %Ra (its whole binary mantissa) -- and, for MPFR runs, "decimal" holds the CLI's decimal
// strings of the same values (the records of the front-end library, io::append_averages and
// io::append_microcanonical, which the CLI prints). Field names are the Python attributes
// (Averages, MicrocanonicalResult: the schema's names). <K_i> and Var K_i are the library's
// beta<K_i> and beta^2 Var K_i divided by beta and beta^2 here as io divides them (long double
// rounded to double, or MPFR; the error enlarged by the quotient's rounding). Threads:
// io::hardware_threads(), as the module gives one point. A call the library refuses prints
// {"error": message}.
#include "io/record.hpp"
#include "io/requests.hpp"
#include "io/results.hpp"

#include "pendavg/mpfr.hpp"
#include "pendavg/pendavg.hpp"

#include <mpfr.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <exception>
#include <iostream>
#include <map>
#include <optional>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

namespace {

using namespace pendavg;

// ---------------------------------------------------------------- exact text of a number

std::string exact(double x) {
  char text[64];
  std::snprintf(text, sizeof text, "%a", x);
  return text;
}

std::string exact(const mpfr_real& x) {
  char* text = nullptr;
  mpfr_asprintf(&text, "%Ra", x.backend().data());
  std::string out(text);
  mpfr_free_str(text);
  return out;
}

// ---------------------------------------------------------------- a tiny JSON writer

std::string quoted(const std::string& s) {
  std::string out = "\"";
  for (const char c : s) {
    if (c == '"' || c == '\\') out += '\\';
    out += c;
  }
  return out + "\"";
}

std::string list(const std::vector<std::string>& items) {
  std::string out = "[";
  for (std::size_t k = 0; k < items.size(); ++k) out += (k ? ", " : "") + quoted(items[k]);
  return out + "]";
}

/// {name: [exact texts]} in insertion order.
class Fields {
 public:
  template <class Real>
  void add(const std::string& name, const std::vector<Real>& values) {
    std::vector<std::string> texts;
    for (const Real& x : values) texts.push_back(exact(x));
    entries_.emplace_back(name, list(texts));
  }
  template <class Real>
  void add(const std::string& name, const Real& value) {
    add(name, std::vector<Real>{value});
  }
  void add_strings(const std::string& name, const std::vector<std::string>& values) {
    entries_.emplace_back(name, list(values));
  }
  std::string str() const {
    std::string out = "{";
    for (std::size_t k = 0; k < entries_.size(); ++k)
      out += (k ? ", " : "") + quoted(entries_[k].first) + ": " + entries_[k].second;
    return out + "}";
  }

 private:
  std::vector<std::pair<std::string, std::string>> entries_;
};

// ---------------------------------------------------------------- one call's inputs

struct Call {
  std::string kind;
  std::map<std::string, std::string> given;
  const std::string& at(const std::string& key) const {
    const auto found = given.find(key);
    if (found == given.end()) throw std::invalid_argument("reference_values: no " + key + "=");
    return found->second;
  }
  bool has(const std::string& key) const { return given.count(key) != 0; }
};

Call read_call(const std::string& line) {
  std::istringstream in(line);
  Call call;
  in >> call.kind;
  for (std::string token; in >> token;) {
    const std::size_t eq = token.find('=');
    if (eq == std::string::npos) throw std::invalid_argument("reference_values: token " + token);
    call.given[token.substr(0, eq)] = token.substr(eq + 1);
  }
  return call;
}

std::vector<std::string> split(const std::string& text) {
  std::vector<std::string> out;
  std::string item;
  std::istringstream in(text);
  while (std::getline(in, item, ',')) out.push_back(item);
  return out;
}

template <class Real>
Real number(const std::string& text) {
  if constexpr (std::is_same_v<Real, double>) {
    return std::strtod(text.c_str(), nullptr);
  } else {
    return mpfr_real(text);
  }
}

template <class Real>
Chain<Real> chain_of(const Call& call) {
  std::vector<Real> masses, lengths;
  for (const std::string& m : split(call.at("masses"))) masses.push_back(number<Real>(m));
  for (const std::string& l : split(call.at("lengths"))) lengths.push_back(number<Real>(l));
  return Chain<Real>(std::move(masses), std::move(lengths), number<Real>(call.at("g")));
}

AverageOptions options_of(const Call& call) {
  AverageOptions o;
  o.digits = std::stoi(call.at("digits"));
  if (call.has("method")) o.method = parse_average_method(call.at("method").c_str());
  if (call.has("tol")) o.tolerance = std::strtod(call.at("tol").c_str(), nullptr);
  if (call.has("samples")) o.samples = std::stoull(call.at("samples"));
  if (call.has("shifts")) o.shifts = std::stoull(call.at("shifts"));
  if (call.has("seed")) o.seed = std::stoull(call.at("seed"));
  o.threads = io::hardware_threads();
  return o;
}

// ---------------------------------------------------------------- the results

template <class Real>
std::vector<Real> values(const std::vector<Estimate<Real>>& v) {
  std::vector<Real> out;
  for (const auto& e : v) out.push_back(e.value);
  return out;
}

template <class Real>
std::vector<Real> errors(const std::vector<Estimate<Real>>& v) {
  std::vector<Real> out;
  for (const auto& e : v) out.push_back(e.error);
  return out;
}

std::string common(const std::string& method, const char* kind, std::size_t evaluations,
                   bool converged) {
  return ", \"method\": " + quoted(method) + ", \"error_kind\": " + quoted(kind) +
         ", \"evaluations\": " + std::to_string(evaluations) +
         ", \"converged\": " + (converged ? "true" : "false");
}

/// value / divisor and its error as the front end forms them (src/io/results.cpp,
/// put_quotients): a double run divides in long double and rounds to double, the error divided
/// and enlarged by 2^-52 |quotient| (the division and the rounding), rounded up; an MPFR run
/// divides at the working precision, the error enlarged by 2^(1 - p) |quotient| (p its bits).
void quotient(const Estimate<double>& e, long double divisor, double& q, double& error) {
  const long double wide = static_cast<long double>(e.value) / divisor;
  q = static_cast<double>(wide);
  long double enlarged = static_cast<long double>(e.error) / divisor;
  enlarged += std::fabs(static_cast<long double>(q)) * std::ldexp(1.0L, -52);
  error = static_cast<double>(enlarged);
  if (static_cast<long double>(error) < enlarged) error = std::nextafter(error, HUGE_VAL);
}

void quotient(const Estimate<mpfr_real>& e, const mpfr_real& divisor, mpfr_real& q,
              mpfr_real& error) {
  q = e.value / divisor;
  mpfr_real rounding = abs(q);
  mpfr_mul_2si(rounding.backend().data(), rounding.backend().data(),
               1 - static_cast<long>(mpfr_get_prec(q.backend().data())), MPFR_RNDU);
  error = mpfr_real(e.error / divisor + rounding);
}

/// <K_i> = beta<K_i>/beta and Var K_i = beta^2 Var K_i/beta^2 (quotient).
template <class Real>
void add_per_beta(Fields& f, const Averages<Real>& a, const Real& beta) {
  std::vector<Real> k, ke, v, ve;
  using Wide = std::conditional_t<std::is_same_v<Real, double>, long double, Real>;
  const Wide b = static_cast<Wide>(beta), b2 = b * b;
  for (const auto& e : a.beta_kinetic) {
    quotient(e, b, k.emplace_back(), ke.emplace_back());
  }
  for (const auto& e : a.beta2_kinetic_variance) {
    quotient(e, b2, v.emplace_back(), ve.emplace_back());
  }
  f.add("K", k);
  f.add("K_error", ke);
  f.add("var_K", v);
  f.add("var_K_error", ve);
}

/// The CLI's decimal strings of a record: {field: its cells' texts} for every value and error
/// field with a value (the record's own table names them).
void add_decimal(Fields& d, const io::Record& record) {
  for (std::size_t k = 0; k < record.fields().size(); ++k) {
    const io::Field& field = record.fields()[k];
    if (field.kind != io::Kind::real && field.kind != io::Kind::error) continue;
    std::vector<std::string> texts;
    for (const io::Cell& cell : record.cells_of(k)) {
      if (cell.tag == io::Cell::Tag::none) continue;
      std::string text(io::max_cell_length(record, cell), '\0');
      text.resize(static_cast<std::size_t>(io::write_cell(text.data(), record, cell) - text.data()));
      texts.push_back(std::move(text));
    }
    if (!texts.empty()) d.add_strings(std::string(field.name), texts);
  }
}

template <class Real>
std::string averages_json(const Averages<Real>& a, const Real* beta, int digits) {
  Fields f;
  f.add("beta_K", values(a.beta_kinetic));
  f.add("beta_K_error", errors(a.beta_kinetic));
  f.add("cos_phi", values(a.cos_angle));
  f.add("cos_phi_error", errors(a.cos_angle));
  f.add("beta2_var_K", values(a.beta2_kinetic_variance));
  f.add("beta2_var_K_error", errors(a.beta2_kinetic_variance));
  f.add("beta_Kc", values(a.beta_kinetic_canonical));
  f.add("beta_Kc_error", errors(a.beta_kinetic_canonical));
  f.add("diagonal_approx", a.diagonal_approximation);
  if (a.ratio) {
    f.add("ratio", a.ratio->value);
    f.add("ratio_error", a.ratio->error);
  }
  f.add("equipartition_residual", a.equipartition_residual);
  if (beta) add_per_beta(f, a, *beta);
  std::string out = "{\"values\": " + f.str();
  if constexpr (!std::is_same_v<Real, double>) {
    io::Record record(io::averages_fields(), a.beta_kinetic.size());
    io::append_averages(record, a, beta, io::Printing{digits});
    Fields d;
    add_decimal(d, record);
    out += ", \"decimal\": " + d.str();
  }
  return out + common(method_name(a.method), error_kind_name(a.error_kind), a.evaluations,
                      a.converged) +
         "}";
}

template <class Real>
std::string microcanonical_json(const MicrocanonicalAverages<Real>& r, int digits,
                               std::string_view state) {
  Fields f;
  f.add("energy", r.energy);
  f.add("excitation", r.excitation);
  f.add("K", values(r.kinetic));
  f.add("K_error", errors(r.kinetic));
  f.add("Kc", r.kinetic_canonical.value);
  f.add("Kc_error", r.kinetic_canonical.error);
  f.add("K_total", r.kinetic_total.value);
  f.add("K_total_error", r.kinetic_total.error);
  f.add("cos_phi", values(r.cos_angle));
  f.add("cos_phi_error", errors(r.cos_angle));
  f.add("var_K", values(r.kinetic_variance));
  f.add("var_K_error", errors(r.kinetic_variance));
  f.add("density_of_states", r.density_of_states.value);
  f.add("density_of_states_error", r.density_of_states.error);
  if (r.quadrature == Method::qmc) {  // the proposal's beta* and the weights' spread: qmc only
    f.add("proposal_beta", r.proposal_beta);
    f.add("effective_sample_fraction", r.effective_sample_fraction);
  }
  std::string out = "{\"values\": " + f.str();
  if constexpr (!std::is_same_v<Real, double>) {
    // the averages after the state given (the other state first)
    io::Record record(io::microcanonical_fields(state), r.kinetic.size());
    io::append_microcanonical(record, r, io::Printing{digits});
    Fields d;
    add_decimal(d, record);
    out += ", \"decimal\": " + d.str();
  }
  return out + common(method_name(r.quadrature), error_kind_name(r.error_kind), r.evaluations,
                      r.converged) +
         ", \"ensemble\": " + quoted(method_name(r.method)) + "}";
}

template <class Real>
std::string run(const Call& call) {
  const AverageOptions options = options_of(call);
  const Chain<Real> chain = chain_of<Real>(call);
  if (call.kind == "average") {
    const Real beta = number<Real>(call.at("beta"));
    return averages_json(average(chain, beta, options), &beta, options.digits);
  }
  if (call.kind == "limit") {
    return "{\"high_temperature\": " +
           averages_json<Real>(high_temperature_limit(chain, options), nullptr, options.digits) +
           ", \"low_temperature\": " +
           averages_json<Real>(low_temperature_limit(chain, options), nullptr, options.digits) + "}";
  }
  if (call.kind == "microcanonical") {
    const MicrocanonicalOptions micro = microcanonical_options(options, chain.size());
    const MicrocanonicalAverages<Real> r =
        call.has("excitation")
            ? microcanonical_average_excitation(chain, number<Real>(call.at("excitation")), micro)
            : microcanonical_average(chain, number<Real>(call.at("energy")), micro);
    return microcanonical_json(r, options.digits, call.has("excitation") ? "excitation" : "energy");
  }
  throw std::invalid_argument("reference_values: unknown call " + call.kind);
}

std::string run_line(const std::string& line) {
  const Call call = read_call(line);
  const int digits = std::stoi(call.at("digits"));
  if (digits == min_digits) return run<double>(call);
  const working_precision precision(digits + guard_digits);
  return run<mpfr_real>(call);
}

}  // namespace

int main() {
  for (std::string line; std::getline(std::cin, line);) {
    if (line.empty()) continue;
    try {
      std::cout << run_line(line) << std::endl;
    } catch (const std::exception& e) {
      std::cout << "{\"error\": " << quoted(e.what()) << "}" << std::endl;
    }
  }
  return 0;
}
