// SPDX-License-Identifier: GPL-3.0-or-later
// src/python/expose_average.cpp -- pendavg.average (one point, or a broadcast grid of points on
// all cores) and pendavg.limit, and their result class Averages.
//
// Each point runs exactly as `pendavg average` runs it (src/cli/commands.cpp, average_one): the
// options read by the CLI's reader, the chain and beta parsed by the CLI's parsers from the same
// texts (a valid float in double directly: the same double), pendavg::average with the same
// options (all cores for a single point, one thread per point in a grid, as `--cases`), and the
// CLI's decimal strings from cli::averages_text. So every number is the library's, bit for bit.
#include "bindings.hpp"
#include "exact.hpp"
#include "inputs.hpp"
#include "parallel.hpp"

#include "cli/format.hpp"

#include "pendavg/mpfr.hpp"
#include "pendavg/pendavg.hpp"

#include <pybind11/numpy.h>
#include <pybind11/stl.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <cmath>
#include <cstdint>
#include <limits>
#include <optional>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

namespace pendavg::python {

namespace {

using cli::Domain;
using namespace pybind11::literals;

// ---------------------------------------------------------------- one point's result

/// The exact values of an MPFR run, in this order (per particle unless noted).
constexpr std::array<const char*, 15> exact_fields{
    "beta_K", "error", "cos_phi", "cos_phi_error", "var_K_beta2", "var_K_beta2_error",
    "beta_Kc", "diagonal_approx", "K", "K_error", "var_K", "var_K_error",
    "ratio", "ratio_error", "equipartition_residual"};  // the last three: one per point

struct AveragePoint {
  Averages<double> values;  ///< the library's result; an MPFR run's rounded to double
  bool has_beta = true;     ///< false for the limits (no <K_i>, Var K_i)
  double beta = 0;
  /// <K_i> = beta<K_i>/beta and Var K_i = beta^2 Var K_i / beta^2 with their errors, divided
  /// as the CLI divides them (long double, or MPFR) and rounded to double.
  std::vector<double> kinetic, kinetic_error, variance, variance_error;
  double seconds = 0;  ///< wall time of the library call (the CLI's `seconds`)
  /// The CLI's strings: made under the working precision for MPFR, on first use for double.
  mutable std::optional<cli::AveragesText> text;
  std::vector<std::vector<ExactNumber>> exact;  ///< MPFR: exact_fields
};

Estimate<double> rounded(const Estimate<mpfr_real>& e) {
  return {static_cast<double>(e.value), static_cast<double>(e.error), e.kind};
}

std::vector<Estimate<double>> rounded(const std::vector<Estimate<mpfr_real>>& v) {
  std::vector<Estimate<double>> out;
  for (const auto& e : v) out.push_back(rounded(e));
  return out;
}

Averages<double> rounded(const Averages<mpfr_real>& a) {
  Averages<double> d;
  d.beta_kinetic = rounded(a.beta_kinetic);
  d.cos_angle = rounded(a.cos_angle);
  d.beta2_kinetic_variance = rounded(a.beta2_kinetic_variance);
  if (a.ratio) d.ratio = rounded(*a.ratio);
  d.beta_kinetic_canonical = rounded(a.beta_kinetic_canonical);
  for (const mpfr_real& x : a.diagonal_approximation)
    d.diagonal_approximation.push_back(static_cast<double>(x));
  d.equipartition_residual = static_cast<double>(a.equipartition_residual);
  d.method = a.method;
  d.error_kind = a.error_kind;
  d.evaluations = a.evaluations;
  d.work_unit = a.work_unit;
  d.converged = a.converged;
  d.interrupted = a.interrupted;
  if (a.torus) {
    d.torus.emplace();
    d.torus->points_per_dim = a.torus->points_per_dim;
    d.torus->grid_points = a.torus->grid_points;
    d.torus->levels = a.torus->levels;
    d.torus->mean_weight = rounded(a.torus->mean_weight);
  }
  return d;  // qmc runs in double only
}

void scale_by_beta_double(AveragePoint& p) {
  const long double b = p.beta;  // as the CLI: in long double (beta < 1e-154 leaves double)
  for (const Estimate<double>& k : p.values.beta_kinetic) {
    p.kinetic.push_back(static_cast<double>(static_cast<long double>(k.value) / b));
    p.kinetic_error.push_back(static_cast<double>(static_cast<long double>(k.error) / b));
  }
  for (const Estimate<double>& v : p.values.beta2_kinetic_variance) {
    p.variance.push_back(static_cast<double>(static_cast<long double>(v.value) / (b * b)));
    p.variance_error.push_back(static_cast<double>(static_cast<long double>(v.error) / (b * b)));
  }
}

/// Everything of an MPFR result that outlives its working precision: strings, doubles, exact
/// values. Runs under the working precision.
void keep_mpfr(AveragePoint& p, const Averages<mpfr_real>& a, const mpfr_real* beta, int digits) {
  p.text = cli::averages_text(a, digits, beta);
  p.values = rounded(a);
  p.has_beta = beta != nullptr;
  p.exact.resize(exact_fields.size());
  const auto keep = [&](std::size_t field, const mpfr_real& x) {
    p.exact[field].push_back(exact_number(x));
  };
  for (std::size_t i = 0; i < a.beta_kinetic.size(); ++i) {
    keep(0, a.beta_kinetic[i].value);
    keep(1, a.beta_kinetic[i].error);
    keep(2, a.cos_angle[i].value);
    keep(3, a.cos_angle[i].error);
    keep(4, a.beta2_kinetic_variance[i].value);
    keep(5, a.beta2_kinetic_variance[i].error);
    keep(6, a.beta_kinetic_canonical[i].value);
    keep(7, a.diagonal_approximation[i]);
    if (beta) {
      const mpfr_real b2 = *beta * *beta;
      const mpfr_real k = a.beta_kinetic[i].value / *beta, ke = a.beta_kinetic[i].error / *beta;
      const mpfr_real v = a.beta2_kinetic_variance[i].value / b2,
                      ve = a.beta2_kinetic_variance[i].error / b2;
      keep(8, k);
      keep(9, ke);
      keep(10, v);
      keep(11, ve);
      p.kinetic.push_back(static_cast<double>(k));
      p.kinetic_error.push_back(static_cast<double>(ke));
      p.variance.push_back(static_cast<double>(v));
      p.variance_error.push_back(static_cast<double>(ve));
    }
  }
  if (a.ratio) {
    keep(12, a.ratio->value);
    keep(13, a.ratio->error);
  }
  keep(14, a.equipartition_residual);
  if (beta) p.beta = static_cast<double>(*beta);
}

// ---------------------------------------------------------------- computing points

/// One point in double; the chain and beta were checked while the GIL was held. `workspace`
/// is the caller's (Pinocchio's Data): a single point makes one for its call, a grid one per
/// worker thread, owned by the grid call; no workspace outlives the call that made it.
void compute_double(AveragePoint& out, const Chain<double>& chain, double beta,
                    const AverageOptions& options, AverageWorkspace<double>& workspace) {
  const Stopwatch watch;
  out.values = average(chain, beta, options, workspace);
  out.seconds = watch.seconds();
  out.beta = beta;
  scale_by_beta_double(out);
}

/// One point's inputs as the decimal texts the CLI would read (MPFR runs).
struct PointTexts {
  std::vector<std::string> masses, lengths;
  std::string g, beta;
};

/// One MPFR point's chain and beta.
struct MpfrPoint {
  Chain<mpfr_real> chain;
  mpfr_real beta;
};

/// Parses `in` as the CLI does (masses, lengths, g, the chain, then the method's options, then
/// beta). The caller holds the run's working precision.
MpfrPoint parse_mpfr(const PointTexts& in, const AverageOptions& options) {
  std::vector<mpfr_real> masses, lengths;
  for (const std::string& m : in.masses)
    masses.push_back(cli::parse_real<mpfr_real>(m, "--masses", Domain::positive));
  for (const std::string& l : in.lengths)
    lengths.push_back(cli::parse_real<mpfr_real>(l, "--lengths", Domain::positive));
  mpfr_real g = cli::parse_real<mpfr_real>(in.g, "--g", Domain::nonnegative);
  if (masses.size() != lengths.size())
    throw cli::usage_error(std::to_string(masses.size()) + " masses but " +
                           std::to_string(lengths.size()) + " lengths");
  Chain<mpfr_real> chain(std::move(masses), std::move(lengths), std::move(g));
  resolve_average_method(chain.size(), options);
  mpfr_real beta = cli::parse_real<mpfr_real>(in.beta, "--beta", Domain::positive);
  return {std::move(chain), std::move(beta)};
}

/// Parses and computes one MPFR point under its working precision. No GIL needed.
void compute_mpfr(AveragePoint& out, const PointTexts& in, const AverageOptions& options) {
  const working_precision precision(options.digits + guard_digits);
  const MpfrPoint point = parse_mpfr(in, options);
  const Stopwatch watch;
  const Averages<mpfr_real> a = average(point.chain, point.beta, options);
  out.seconds = watch.seconds();
  keep_mpfr(out, a, &point.beta, options.digits);
}

/// Everything average() checks before its work, for one MPFR point (as `--cases` checks every
/// row before computing any).
void check_mpfr(const PointTexts& in, const AverageOptions& options) {
  const working_precision precision(options.digits + guard_digits);
  const MpfrPoint point = parse_mpfr(in, options);
  check_average(point.chain, point.beta, options);
}

/// A library call observed through RunControl: its stop flag (set on Ctrl-C) and the fraction of
/// its current stage done.
struct Observation {
  std::atomic<bool> stop{false};
  std::atomic<double> fraction{0};
  RunControl control() {
    RunControl c;
    c.stop = &stop;
    c.progress = [this](double f) { fraction.store(f); };
    return c;
  }
};

/// Runs `work` without the GIL: directly when it is short, on a helper thread with Ctrl-C and
/// progress (run_interruptible) when it may take long (torus levels, a progress callback).
template <class Work>
void run_call(Work&& work, bool long_run, Observation& observation, const py::object& progress) {
  if (!long_run) {
    py::gil_scoped_release release;
    work();
    return;
  }
  run_interruptible(work, observation.stop, observation.fraction, progress);
}

/// True for the methods that report progress and stop through RunControl (the torus levels).
bool observable(std::size_t particles, const AverageOptions& options) {
  try {
    const AverageMethod m = resolve_average_method(particles, options);
    return m == AverageMethod::torus_trapezoid || m == AverageMethod::torus_gauss;
  } catch (const invalid_input&) {
    return false;  // refused in its turn, with the CLI's message
  }
}

// ---------------------------------------------------------------- the result class

struct AveragesResult {
  std::vector<py::ssize_t> shape;  ///< the broadcast shape; empty for one point
  std::size_t particles = 0;
  int digits = 16;
  bool has_beta = true;  ///< false for the limits (no beta, <K_i>, Var K_i)
  std::vector<AveragePoint> points;  ///< C order over `shape` (none for an empty grid)

  bool single() const { return shape.empty(); }
};

/// A per-particle field as an array of shape shape + (N,).
template <class Field>
py::array_t<double> per_particle(const AveragesResult& r, Field field) {
  std::vector<py::ssize_t> shape = r.shape;
  shape.push_back(static_cast<py::ssize_t>(r.particles));
  py::array_t<double> out(shape);
  double* p = out.mutable_data();
  for (const AveragePoint& point : r.points)
    for (std::size_t i = 0; i < r.particles; ++i) *p++ = field(point, i);
  return out;
}

/// A per-point number: a float for one point, an array of `shape` for a grid.
template <class T, class Field>
py::object per_point(const AveragesResult& r, Field field) {
  if (r.single()) return py::cast(field(r.points.front()));
  py::array_t<T> out(r.shape);
  T* p = out.mutable_data();
  for (const AveragePoint& point : r.points) *p++ = field(point);
  return out;
}

/// A per-point string (method, error kind): a str, or a numpy str array of `shape`.
template <class Field>
py::object per_point_text(const AveragesResult& r, Field field) {
  if (r.single()) return py::str(field(r.points.front()));
  py::list items;
  for (const AveragePoint& point : r.points) items.append(py::str(field(point)));
  return py::module_::import("numpy").attr("array")(items).attr("reshape")(py::cast(r.shape));
}

double nan() { return std::numeric_limits<double>::quiet_NaN(); }

const cli::AveragesText& text_of(const AveragePoint& p, int digits) {
  if (!p.text)  // double: the CLI's strings of the same double values
    p.text = cli::averages_text(p.values, digits, p.has_beta ? &p.beta : nullptr);
  return *p.text;
}

/// The CLI's strings: lists for one point, numpy str arrays for a grid.
py::dict decimal_strings(const AveragesResult& r) {
  using Strings = std::vector<std::string> cli::AveragesText::*;
  using String = std::string cli::AveragesText::*;
  struct PerParticle {
    const char* name;
    Strings field;
    bool needs_beta;  ///< <K_i> and Var K_i: not for the limits
  };
  const std::vector<PerParticle> arrays{
      {"beta_K", &cli::AveragesText::beta_kinetic, false},
      {"error", &cli::AveragesText::error, false},
      {"K", &cli::AveragesText::kinetic, true},
      {"K_error", &cli::AveragesText::kinetic_error, true},
      {"cos_phi", &cli::AveragesText::cos_angle, false},
      {"cos_phi_error", &cli::AveragesText::cos_angle_error, false},
      {"var_K", &cli::AveragesText::variance, true},
      {"var_K_error", &cli::AveragesText::variance_error, true},
      {"var_K_beta2", &cli::AveragesText::beta2_variance, false},
      {"var_K_beta2_error", &cli::AveragesText::beta2_variance_error, false},
      {"diagonal_approx", &cli::AveragesText::diagonal_approximation, false},
      {"beta_Kc", &cli::AveragesText::beta_kinetic_canonical, false}};
  const std::vector<std::pair<const char*, String>> scalars{
      {"ratio", &cli::AveragesText::ratio},
      {"ratio_error", &cli::AveragesText::ratio_error},
      {"equipartition_residual", &cli::AveragesText::equipartition_residual}};
  const bool has_beta = r.has_beta;
  const py::object numpy = py::module_::import("numpy");
  py::dict out;
  for (const auto& [name, field, needs_beta] : arrays) {
    if (needs_beta && !has_beta) continue;
    if (r.single()) {
      out[name] = py::cast(text_of(r.points.front(), r.digits).*field);
      continue;
    }
    py::list items;
    for (const AveragePoint& p : r.points)
      for (const std::string& s : text_of(p, r.digits).*field) items.append(py::str(s));
    std::vector<py::ssize_t> shape = r.shape;
    shape.push_back(static_cast<py::ssize_t>(r.particles));
    out[name] = numpy.attr("array")(items).attr("reshape")(py::cast(shape));
  }
  for (const auto& [name, field] : scalars) {
    const auto value = [&](const AveragePoint& p) -> py::object {
      const std::string& s = text_of(p, r.digits).*field;
      return s.empty() ? py::none() : py::object(py::str(s));  // N = 1: no ratio
    };
    if (r.single()) {
      out[name] = value(r.points.front());
      continue;
    }
    py::list items;
    for (const AveragePoint& p : r.points) items.append(value(p));
    out[name] = numpy.attr("array")(items, "dtype"_a = "object").attr("reshape")(py::cast(r.shape));
  }
  return out;
}

/// MPFR runs: {field: [(mantissa hex, exponent) or float, ...] per point}; None for double runs
/// (their floats are exact already).
py::object exact_values(const AveragesResult& r) {
  if (r.digits == min_digits) return py::none();
  py::dict out;
  for (std::size_t f = 0; f < exact_fields.size(); ++f) {
    py::list per_point;
    for (const AveragePoint& p : r.points) {
      py::list values;
      for (const ExactNumber& x : p.exact[f]) {
        if (x.finite) values.append(py::make_tuple(x.mantissa, x.exponent));
        else values.append(py::float_(x.rounded));
      }
      per_point.append(values);
    }
    out[exact_fields[f]] = per_point;
  }
  return out;
}

py::object run_details(const AveragePoint& p) {
  const Averages<double>& a = p.values;
  if (a.torus) {
    py::dict d;
    d["points_per_dim"] = a.torus->points_per_dim;
    d["levels"] = a.torus->levels;
    d["grid_points"] = a.torus->grid_points;
    return d;
  }
  if (a.qmc) {
    py::dict d;
    d["points"] = a.qmc->points;
    d["shifts"] = a.qmc->shifts;
    d["sigmas"] = a.qmc->sigmas;
    d["effective_sample_fraction"] = a.qmc->effective_sample_fraction;
    return d;
  }
  if (a.transfer) {
    py::dict d;
    d["angle_nodes"] = a.transfer->angle_nodes;
    d["pivot_nodes"] = a.transfer->pivot_nodes;
    d["levels"] = a.transfer->levels;
    return d;
  }
  return py::none();
}

const char* kind_of(const std::vector<Estimate<double>>& estimates, ErrorKind fallback) {
  return error_kind_name(estimates.empty() ? fallback : estimates.front().kind);
}

/// "index (i, j)" of flat index k in `shape` (C order).
std::string index_text(std::size_t k, const std::vector<py::ssize_t>& shape) {
  std::vector<std::size_t> index(shape.size());
  for (std::size_t d = shape.size(); d-- > 0;) {
    index[d] = k % static_cast<std::size_t>(shape[d]);
    k /= static_cast<std::size_t>(shape[d]);
  }
  std::string out = "index (";
  for (std::size_t d = 0; d < index.size(); ++d)
    out += (d ? ", " : "") + std::to_string(index[d]);
  return out + (index.size() == 1 ? ",)" : ")");
}

// ---------------------------------------------------------------- results are finite

/// Refuses a result with a non-finite number before it reaches Python (ValueError, one line): a
/// NaN or an infinity in a value, or in an error (an interrupted run may keep an infinite
/// error: the bound of a level that was never checked). The library's values are checked in
/// double; an MPFR run's exact values too (their doubles may overflow to +-inf when the value
/// lies beyond double's range: K and var_K of beta < 1e-154 or so). <K_i> and Var K_i may
/// overflow double in the same way (finite library values divided by a tiny beta) and are
/// refused only when NaN.
void require_finite(const AveragesResult& r, const char* command) {
  for (std::size_t k = 0; k < r.points.size(); ++k) {
    const AveragePoint& p = r.points[k];
    const Averages<double>& a = p.values;
    const auto refuse = [&](const std::string& name, std::size_t i, double x, bool per_particle) {
      std::string where = r.single() ? "" : " at " + index_text(k, r.shape);
      const std::string field = per_particle ? name + "[" + std::to_string(i) + "]" : name;
      throw invalid_input(std::string(command) + ": the result is not finite (" + field + " = " +
                          (std::isnan(x) ? "nan" : x > 0 ? "inf" : "-inf") + where +
                          "): the method cannot evaluate this chain");
    };
    const auto value = [&](const char* name, std::size_t i, double x, bool per_particle = true) {
      if (!std::isfinite(x)) refuse(name, i, x, per_particle);
    };
    const auto error = [&](const char* name, std::size_t i, double x, bool per_particle = true) {
      const bool unknown_bound = a.interrupted && x == std::numeric_limits<double>::infinity();
      if (!std::isfinite(x) && !unknown_bound) refuse(name, i, x, per_particle);
    };
    const auto estimates = [&](const char* name, const char* error_name,
                               const std::vector<Estimate<double>>& v) {
      for (std::size_t i = 0; i < v.size(); ++i) {
        value(name, i, v[i].value);
        error(error_name, i, v[i].error);
      }
    };
    estimates("beta_K", "beta_K_error", a.beta_kinetic);
    estimates("cos_phi", "cos_phi_error", a.cos_angle);
    estimates("var_K_beta2", "var_K_beta2_error", a.beta2_kinetic_variance);
    estimates("beta_Kc", "beta_Kc_error", a.beta_kinetic_canonical);
    for (std::size_t i = 0; i < a.diagonal_approximation.size(); ++i)
      value("diagonal_approx", i, a.diagonal_approximation[i]);
    if (a.ratio) {
      value("ratio", 0, a.ratio->value, false);
      error("ratio_error", 0, a.ratio->error, false);
    }
    value("equipartition_residual", 0, a.equipartition_residual, false);
    const auto not_nan = [&](const char* name, const std::vector<double>& v) {
      for (std::size_t i = 0; i < v.size(); ++i)
        if (std::isnan(v[i])) refuse(name, i, v[i], true);
    };
    not_nan("K", p.kinetic);
    not_nan("K_error", p.kinetic_error);
    not_nan("var_K", p.variance);
    not_nan("var_K_error", p.variance_error);
    for (std::size_t f = 0; f < p.exact.size(); ++f)
      for (std::size_t i = 0; i < p.exact[f].size(); ++i)
        if (!p.exact[f][i].finite &&
            !(a.interrupted && std::string_view(exact_fields[f]).ends_with("error") &&
              p.exact[f][i].rounded > 0))
          refuse(exact_fields[f], i, p.exact[f][i].rounded, f < 12);
  }
}

// ---------------------------------------------------------------- pendavg.average

/// The chain of one double point, checked in the CLI's order: masses, lengths, g, counts.
Chain<double> double_chain(const std::vector<py::object>& masses,
                           const std::vector<py::object>& lengths, py::handle g) {
  std::vector<double> m, l;
  for (const py::object& x : masses) m.push_back(number_double(x, "--masses", Domain::positive));
  for (const py::object& x : lengths) l.push_back(number_double(x, "--lengths", Domain::positive));
  const double gravity = number_double(g, "--g", Domain::nonnegative);
  if (m.size() != l.size())
    throw cli::usage_error(std::to_string(m.size()) + " masses but " + std::to_string(l.size()) +
                           " lengths");
  return Chain<double>(std::move(m), std::move(l), gravity);
}

std::vector<std::string> texts(const std::vector<py::object>& values, std::string_view what) {
  std::vector<std::string> out;
  for (const py::object& x : values) out.push_back(number_text(x, what));
  return out;
}

/// One point, or None when an argument holds several values (pendavg/__init__.py broadcasts
/// them and calls average_grid).
py::object average_point(py::handle masses, py::handle lengths, py::handle beta, py::handle g,
                         py::handle digits, py::handle method, py::handle tol, py::handle samples,
                         py::handle shifts, py::handle seed, bool certified,
                         const py::object& progress) {
  const std::vector<py::object> m = entries(masses), l = entries(lengths);
  if (is_array_like(beta) || is_array_like(g) ||
      std::any_of(m.begin(), m.end(), [](const py::object& x) { return is_array_like(x); }) ||
      std::any_of(l.begin(), l.end(), [](const py::object& x) { return is_array_like(x); }))
    return py::none();
  AverageOptions settings = average_options(digits, method, tol, samples, shifts, seed);
  settings.certified = certified;
  AveragesResult result;
  result.particles = m.size();
  result.digits = settings.digits;
  result.points.resize(1);
  AverageOptions run = settings;
  run.threads = hardware_threads();
  Observation observation;
  run.control = observation.control();
  const bool long_run = !progress.is_none() || observable(m.size(), run);
  AveragePoint& point = result.points.front();
  if (settings.digits == min_digits) {
    const Chain<double> chain = double_chain(m, l, g);
    resolve_average_method(chain.size(), run);  // every option checked before any work
    const double b = number_double(beta, "--beta", Domain::positive);
    AverageWorkspace<double> workspace;  // this call's buffers (a grid: one per worker)
    run_call([&] { compute_double(point, chain, b, run, workspace); }, long_run, observation,
             progress);
  } else {
    const PointTexts in{texts(m, "--masses"), texts(l, "--lengths"), number_text(g, "--g"),
                        number_text(beta, "--beta")};
    run_call([&] { compute_mpfr(point, in, run); }, long_run, observation, progress);
  }
  require_finite(result, "average");
  return py::cast(std::move(result));
}

/// One column of a grid (beta, g, a mass or a length over all points): float64 values, or the
/// Python objects (str, int, Decimal, mpf, ...) of any other dtype.
struct Column {
  py::array_t<double> values;  ///< float64 columns
  py::list objects;            ///< other dtypes, as Python objects
  bool is_float = false;
  py::object at(std::size_t k) const {
    return is_float ? py::object(py::float_(values.data()[k]))
                    : py::reinterpret_borrow<py::object>(objects[k]);
  }
  /// Entry k in double, checked as number_double checks it (valid floats without a detour).
  double number(std::size_t k, std::string_view what, Domain domain) const {
    if (is_float) {
      const double v = values.data()[k];
      const bool inside = domain == Domain::positive ? v > 0 : domain == Domain::nonnegative ? v >= 0 : true;
      if (std::isfinite(v) && inside) return v;
    }
    return number_double(at(k), what, domain);
  }
};

Column column(py::handle x, std::size_t count) {
  py::array a = py::reinterpret_borrow<py::array>(x);
  if (a.ndim() != 1 || static_cast<std::size_t>(a.shape(0)) != count)
    throw std::invalid_argument("average_grid: every column must have one entry per point");
  Column c;
  if (a.dtype().is(py::dtype::of<double>())) {
    c.is_float = true;
    c.values = py::array_t<double, py::array::c_style | py::array::forcecast>(a);
  } else {
    c.objects = a.attr("tolist")();
  }
  return c;
}

/// A grid of points: columns beta, g, m1..mN, l1..lN, each flat over the broadcast `shape`.
AveragesResult average_grid(std::vector<py::ssize_t> shape, std::size_t n, const py::list& columns,
                            py::handle digits, py::handle method, py::handle tol,
                            py::handle samples, py::handle shifts, py::handle seed,
                            bool certified, const py::object& progress) {
  std::size_t count = 1;
  for (const py::ssize_t s : shape) count *= static_cast<std::size_t>(s);
  if (columns.size() != 2 + 2 * n) throw std::invalid_argument("average_grid: 2 + 2N columns");
  AverageOptions settings = average_options(digits, method, tol, samples, shifts, seed);
  settings.certified = certified;
  AveragesResult result;
  result.shape = std::move(shape);
  result.particles = n;
  result.digits = settings.digits;
  result.points.resize(count);
  if (count == 0) return result;
  std::vector<Column> cols;
  for (const py::handle c : columns) cols.push_back(column(c, count));
  // Points run one thread each (as `--cases` and `table`); a single point gets every core.
  const int threads = static_cast<int>(std::min<std::size_t>(hardware_threads(), count));
  AverageOptions run = settings;
  run.threads = count == 1 ? hardware_threads() : 1;
  std::atomic<bool> stop{false};  // Ctrl-C: no new point starts, torus points end their level
  run.control.stop = &stop;
  const auto failed = [&](const PointFailure& failure) {
    try {
      std::rethrow_exception(failure.error);
    } catch (const invalid_input& bad) {
      throw invalid_input(index_text(failure.index, result.shape) + ": " + bad.what());
    }
  };
  if (settings.digits == min_digits) {
    // Every point checked before any work, as `--cases` checks its rows: the inputs in the CLI's
    // order (the method's options after the first point's chain), then what average() checks
    // before its work (check_average); then computed without the GIL.
    std::vector<double> beta(count), g(count), masses(n * count), lengths(n * count);
    bool resolved = false;
    for (std::size_t k = 0; k < count; ++k) {
      try {
        for (std::size_t i = 0; i < n; ++i)
          masses[i * count + k] = cols[2 + i].number(k, "--masses", Domain::positive);
        for (std::size_t i = 0; i < n; ++i)
          lengths[i * count + k] = cols[2 + n + i].number(k, "--lengths", Domain::positive);
        g[k] = cols[1].number(k, "--g", Domain::nonnegative);
        if (!resolved) {
          resolve_average_method(n, run);
          resolved = true;
        }
        beta[k] = cols[0].number(k, "--beta", Domain::positive);
        std::vector<double> m, l;
        for (std::size_t i = 0; i < n; ++i) {
          m.push_back(masses[i * count + k]);
          l.push_back(lengths[i * count + k]);
        }
        check_average(Chain<double>(std::move(m), std::move(l), g[k]), beta[k], run);
      } catch (const invalid_input& bad) {
        throw invalid_input(index_text(k, result.shape) + ": " + bad.what());
      }
    }
    std::vector<AverageWorkspace<double>> workspaces(static_cast<std::size_t>(threads));
    try {
      run_points(count, threads, [&](std::size_t k, int worker) {
        std::vector<double> m(n), l(n);
        for (std::size_t i = 0; i < n; ++i) {
          m[i] = masses[i * count + k];
          l[i] = lengths[i * count + k];
        }
        const Chain<double> chain(std::move(m), std::move(l), g[k]);
        compute_double(result.points[k], chain, beta[k], run,
                       workspaces[static_cast<std::size_t>(worker)]);
      }, stop, progress);
    } catch (const PointFailure& failure) {
      failed(failure);
    }
  } else {
    std::vector<PointTexts> in(count);
    for (std::size_t k = 0; k < count; ++k) {
      for (std::size_t i = 0; i < n; ++i) in[k].masses.push_back(number_text(cols[2 + i].at(k), "--masses"));
      for (std::size_t i = 0; i < n; ++i)
        in[k].lengths.push_back(number_text(cols[2 + n + i].at(k), "--lengths"));
      in[k].g = number_text(cols[1].at(k), "--g");
      in[k].beta = number_text(cols[0].at(k), "--beta");
    }
    std::optional<std::pair<std::size_t, std::string>> bad_point;
    {
      py::gil_scoped_release release;
      for (std::size_t k = 0; k < count && !bad_point; ++k) {
        try {
          check_mpfr(in[k], run);
        } catch (const invalid_input& bad) {
          bad_point.emplace(k, bad.what());
        }
      }
    }
    if (bad_point)
      throw invalid_input(index_text(bad_point->first, result.shape) + ": " + bad_point->second);
    try {
      run_points(
          count, threads, [&](std::size_t k, int) { compute_mpfr(result.points[k], in[k], run); },
          stop, progress);
    } catch (const PointFailure& failure) {
      failed(failure);
    }
  }
  require_finite(result, "average");
  return result;
}

// ---------------------------------------------------------------- pendavg.limit

/// The limits in MPFR: parsed as the CLI parses them, under the working precision.
void limit_mpfr(AveragePoint& high, AveragePoint& low, const PointTexts& in,
              const AverageOptions& settings) {
  const int d = settings.digits;
  const working_precision precision(d + guard_digits);
  std::vector<mpfr_real> mv, lv;
  for (const std::string& x : in.masses)
    mv.push_back(cli::parse_real<mpfr_real>(x, "--masses", Domain::positive));
  for (const std::string& x : in.lengths)
    lv.push_back(cli::parse_real<mpfr_real>(x, "--lengths", Domain::positive));
  mpfr_real gravity = cli::parse_real<mpfr_real>(in.g, "--g", Domain::nonnegative);
  if (mv.size() != lv.size())
    throw cli::usage_error(std::to_string(mv.size()) + " masses but " +
                           std::to_string(lv.size()) + " lengths");
  const Chain<mpfr_real> chain(std::move(mv), std::move(lv), std::move(gravity));
  const Averages<mpfr_real> h = high_temperature_limit(chain, settings);
  const Averages<mpfr_real> lo = low_temperature_limit(chain, settings);
  keep_mpfr(high, h, nullptr, d);
  keep_mpfr(low, lo, nullptr, d);
}

/// beta -> 0 and beta -> infinity, as `pendavg limit` (src/cli/commands.cpp, limit_report).
py::tuple limit(py::handle masses, py::handle lengths, py::handle g, py::handle digits,
                bool certified, const py::object& progress) {
  const int d = digits_option(digits);
  const std::vector<py::object> m = entries(masses);
  std::vector<py::object> l;
  if (lengths.is_none()) l.assign(m.size(), py::int_(1));
  else l = entries(lengths);
  AverageOptions settings;
  settings.digits = d;
  settings.certified = certified;
  settings.threads = hardware_threads();
  Observation observation;  // the beta -> 0 limit of N >= 3 is a torus run at g = 0
  settings.control = observation.control();
  const bool long_run = !progress.is_none() || m.size() >= 3;
  AveragesResult high, low;
  for (AveragesResult* r : {&high, &low}) {
    r->particles = m.size();
    r->digits = d;
    r->has_beta = false;
    r->points.resize(1);
    r->points.front().has_beta = false;
  }
  if (d == min_digits) {
    const Chain<double> chain = double_chain(m, l, g);
    run_call(
        [&] {
          high.points.front().values = high_temperature_limit(chain, settings);
          low.points.front().values = low_temperature_limit(chain, settings);
        },
        long_run, observation, progress);
  } else {
    const PointTexts in{texts(m, "--masses"), texts(l, "--lengths"), number_text(g, "--g"), ""};
    run_call([&] { limit_mpfr(high.points.front(), low.points.front(), in, settings); }, long_run,
             observation, progress);
  }
  require_finite(high, "limit (beta -> 0)");
  require_finite(low, "limit (beta -> infinity)");
  return py::make_tuple(std::move(high), std::move(low));
}



}  // namespace

void expose_average(py::module_& m) {
  using namespace pybind11::literals;
  py::class_<AveragesResult> c(m, "Averages", py::dynamic_attr(), R"(Thermal averages of a chain: the result of pendavg.average and pendavg.limit.

One point: per-particle fields are arrays of shape (N,), per-point fields are Python
scalars. A grid (array arguments): per-particle fields have shape S + (N,), per-point
fields shape S, S the broadcast shape of the arguments. Index i is particle i + 1 of the
paper. See help(pendavg.average) for every field.)");
  c.def_property_readonly("N", [](const AveragesResult& r) { return r.particles; },
                          "Number of particles (masses).")
      .def_property_readonly("shape", [](const AveragesResult& r) { return py::tuple(py::cast(r.shape)); },
                             "Broadcast shape of the arguments: () for one point.")
      .def_property_readonly("digits", [](const AveragesResult& r) { return r.digits; },
                             "Significant digits requested (16: double; 17..1000: MPFR).")
      .def_property_readonly(
          "beta",
          [](const AveragesResult& r) -> py::object {
            if (!r.has_beta) return py::none();
            return per_point<double>(r, [](const AveragePoint& p) { return p.beta; });
          },
          "Inverse temperature of each point (None for the limits).")
      .def_property_readonly(
          "beta_K",
          [](const AveragesResult& r) {
            return per_particle(r, [](const AveragePoint& p, std::size_t i) {
              return p.values.beta_kinetic[i].value;
            });
          },
          "beta<K_i>: the average kinetic energy of particle i in units of the temperature.")
      .def_property_readonly(
          "beta_K_error",
          [](const AveragesResult& r) {
            return per_particle(r, [](const AveragePoint& p, std::size_t i) {
              return p.values.beta_kinetic[i].error;
            });
          },
          "Absolute error of beta_K (what it promises: error_kind). Same as `error`.")
      .def_property_readonly(
          "K",
          [](const AveragesResult& r) -> py::object {
            if (!r.has_beta) return py::none();
            return per_particle(r, [](const AveragePoint& p, std::size_t i) { return p.kinetic[i]; });
          },
          "<K_i> = beta<K_i> / beta (energy units); None for the limits.")
      .def_property_readonly(
          "K_error",
          [](const AveragesResult& r) -> py::object {
            if (!r.has_beta) return py::none();
            return per_particle(r, [](const AveragePoint& p, std::size_t i) {
              return p.kinetic_error[i];
            });
          },
          "Absolute error of K.")
      .def_property_readonly(
          "ratio",
          [](const AveragesResult& r) -> py::object {
            if (r.particles < 2 && r.single()) return py::none();
            return per_point<double>(r, [](const AveragePoint& p) {
              return p.values.ratio ? p.values.ratio->value : nan();
            });
          },
          "<K_1>/<K_2> (None, or NaN in a grid, for N = 1).")
      .def_property_readonly(
          "ratio_error",
          [](const AveragesResult& r) -> py::object {
            if (r.particles < 2 && r.single()) return py::none();
            return per_point<double>(r, [](const AveragePoint& p) {
              return p.values.ratio ? p.values.ratio->error : nan();
            });
          },
          "Absolute error of ratio (kind: error_kind).")
      .def_property_readonly(
          "cos_phi",
          [](const AveragesResult& r) {
            return per_particle(r, [](const AveragePoint& p, std::size_t i) {
              return p.values.cos_angle[i].value;
            });
          },
          "<cos phi_i>, phi_i the angle of link i from the downward vertical.")
      .def_property_readonly(
          "cos_phi_error",
          [](const AveragesResult& r) {
            return per_particle(r, [](const AveragePoint& p, std::size_t i) {
              return p.values.cos_angle[i].error;
            });
          },
          "Absolute error of cos_phi (kind: error_kinds['cos_phi']).")
      .def_property_readonly(
          "var_K",
          [](const AveragesResult& r) -> py::object {
            if (!r.has_beta) return py::none();
            return per_particle(r, [](const AveragePoint& p, std::size_t i) { return p.variance[i]; });
          },
          "Var K_i = <K_i^2> - <K_i>^2 (energy units squared); None for the limits.")
      .def_property_readonly(
          "var_K_error",
          [](const AveragesResult& r) -> py::object {
            if (!r.has_beta) return py::none();
            return per_particle(r, [](const AveragePoint& p, std::size_t i) {
              return p.variance_error[i];
            });
          },
          "Absolute error of var_K (kind: error_kinds['var_K']).")
      .def_property_readonly(
          "var_K_beta2",
          [](const AveragesResult& r) {
            return per_particle(r, [](const AveragePoint& p, std::size_t i) {
              return p.values.beta2_kinetic_variance[i].value;
            });
          },
          "beta^2 Var K_i (dimensionless; the limits' variance).")
      .def_property_readonly(
          "var_K_beta2_error",
          [](const AveragesResult& r) {
            return per_particle(r, [](const AveragePoint& p, std::size_t i) {
              return p.values.beta2_kinetic_variance[i].error;
            });
          },
          "Absolute error of var_K_beta2.")
      .def_property_readonly(
          "beta_Kc",
          [](const AveragesResult& r) {
            return per_particle(r, [](const AveragePoint& p, std::size_t i) {
              return p.values.beta_kinetic_canonical[i].value;
            });
          },
          "beta<K_i^(c)>, K_i^(c) = p_i phidot_i / 2: 1/2 exactly for every chain (generalized "
          "equipartition), reported as the check it is.")
      .def_property_readonly(
          "diagonal_approx",
          [](const AveragesResult& r) {
            return per_particle(r, [](const AveragePoint& p, std::size_t i) {
              return p.values.diagonal_approximation[i];
            });
          },
          "The paper's diagonal approximation of beta<K_i> (eq. ke-linear-tave-1): an "
          "approximation beside the exact values, without an error.")
      .def_property_readonly(
          "equipartition_residual",
          [](const AveragesResult& r) {
            return per_point<double>(r, [](const AveragePoint& p) {
              return p.values.equipartition_residual;
            });
          },
          "|sum_i beta<K_i> - N/2| after the computation (the trace identity sum_i tr X_i = N).")
      .def_property_readonly(
          "method",
          [](const AveragesResult& r) {
            return per_point_text(r, [](const AveragePoint& p) { return method_name(p.values.method); });
          },
          "The method that ran: integral, series, torus-trapezoid, torus-gauss, qmc, transfer, "
          "low-temperature-extrapolation, limit-beta0, limit-beta-infinity.")
      .def_property_readonly(
          "error_kind",
          [](const AveragesResult& r) {
            return per_point_text(r, [](const AveragePoint& p) {
              return error_kind_name(p.values.error_kind);
            });
          },
          "What the errors of beta_K and ratio promise: 'bound' (rigorous), 'estimate' (from "
          "refinement, checked against independent methods) or 'statistical' (QMC: 99.9% Student-t bars over the shifts).")
      .def_property_readonly(
          "error_kinds",
          [](const AveragesResult& r) {
            py::dict d;
            d["beta_K"] = per_point_text(r, [](const AveragePoint& p) {
              return error_kind_name(p.values.error_kind);
            });
            d["ratio"] = d["beta_K"];
            d["cos_phi"] = per_point_text(r, [](const AveragePoint& p) {
              return kind_of(p.values.cos_angle, p.values.error_kind);
            });
            d["var_K"] = per_point_text(r, [](const AveragePoint& p) {
              return kind_of(p.values.beta2_kinetic_variance, p.values.error_kind);
            });
            return d;
          },
          "The error kind of each observable: {'beta_K', 'ratio', 'cos_phi', 'var_K'}.")
      .def_property_readonly(
          "work_unit",
          [](const AveragesResult& r) {
            return per_point_text(r, [](const AveragePoint& p) {
              return work_unit_name(p.values.work_unit);
            });
          },
          "What evaluations counts: terms, nodes or samples.")
      .def_property_readonly(
          "evaluations",
          [](const AveragesResult& r) {
            return per_point<std::int64_t>(r, [](const AveragePoint& p) {
              return static_cast<std::int64_t>(p.values.evaluations);
            });
          },
          "Work done: series terms, quadrature nodes or QMC samples (work_unit).")
      .def_property_readonly(
          "converged",
          [](const AveragesResult& r) {
            return per_point<bool>(r, [](const AveragePoint& p) { return p.values.converged; });
          },
          "False when the requested accuracy was not reached (the errors still hold).")
      .def_property_readonly(
          "interrupted",
          [](const AveragesResult& r) {
            return per_point<bool>(r, [](const AveragePoint& p) { return p.values.interrupted; });
          },
          "True when Ctrl-C stopped a torus run after a finished level: the values are that "
          "level's (converged = False, the errors still hold).")
      .def_property_readonly(
          "seconds",
          [](const AveragesResult& r) {
            return per_point<double>(r, [](const AveragePoint& p) { return p.seconds; });
          },
          "Wall time of the library call (the CLI's `seconds`); 0 for the limits.")
      .def_property_readonly(
          "run",
          [](const AveragesResult& r) -> py::object {
            if (r.single()) return run_details(r.points.front());
            py::list items;
            for (const AveragePoint& p : r.points) items.append(run_details(p));
            py::object numpy = py::module_::import("numpy");
            py::object out = numpy.attr("empty")(r.points.size(), "dtype"_a = "object");
            for (std::size_t k = 0; k < r.points.size(); ++k) out[py::int_(k)] = items[k];
            return out.attr("reshape")(py::cast(r.shape));
          },
          "The torus grid {points_per_dim, levels, grid_points}, the qmc run {points, shifts, "
          "sigmas, effective_sample_fraction} or the transfer operator's final resolution "
          "{angle_nodes, pivot_nodes, levels}; None for the other methods.")
      .def_property_readonly("decimal", &decimal_strings,
                             "The CLI's decimal strings (`pendavg average --format json`): values "
                             "with `digits` significant digits, errors with 3 that also cover "
                             "the rounding of the printed value.")
      .def("_exact_values", &exact_values);

  m.def("average_point", &average_point, "masses"_a, "lengths"_a, "beta"_a, "g"_a, "digits"_a,
        "method"_a, "tol"_a, "samples"_a, "shifts"_a, "seed"_a, "certified"_a, "progress"_a,
        "One point of pendavg.average, or None when an argument holds several values.");
  m.def("average_grid", &average_grid, "shape"_a, "n"_a, "columns"_a, "digits"_a, "method"_a,
        "tol"_a, "samples"_a, "shifts"_a, "seed"_a, "certified"_a, "progress"_a,
        "pendavg.average over flat columns beta, g, m1..mN, l1..lN of the broadcast shape.");
  m.def("limit", &limit, "masses"_a, "lengths"_a, "g"_a, "digits"_a, "certified"_a, "progress"_a,
        "(beta -> 0, beta -> infinity) limits as two Averages.");
}

}  // namespace pendavg::python
