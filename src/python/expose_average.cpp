// SPDX-License-Identifier: GPL-3.0-or-later
// src/python/expose_average.cpp -- pendavg.average (one point, or a broadcast grid of points on
// all cores) and pendavg.limit, and their result class Averages.
//
// Each point runs as `pendavg average` runs it (src/cli/average.cpp, average_one): the options
// read by the front-end library's reader (io::parse_average_options), the chain and beta parsed
// by its parsers from the same texts (a valid float in double directly: the same double),
// pendavg::average with the same options (all cores for a single point, one thread per point in
// a grid, as `--cases`), and the result filled into the same records the CLI prints
// (io::append_canonical_inputs, io::append_averages). Averages is generated from those records'
// field tables (table_result.hpp): every number is the library's, bit for bit (a double run's
// doubles; an MPFR run's exact values), and every string the CLI's.
#include "bindings.hpp"
#include "inputs.hpp"
#include "parallel.hpp"
#include "table_result.hpp"

#include "io/number_text.hpp"
#include "io/results.hpp"

#include "pendavg/mpfr.hpp"
#include "pendavg/pendavg.hpp"

#include <pybind11/numpy.h>
#include <pybind11/stl.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <cmath>
#include <cstdint>
#include <optional>
#include <stdexcept>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

namespace pendavg::python {

namespace {

using io::Domain;
using namespace pybind11::literals;

// ---------------------------------------------------------------- the result class

/// One point's run diagnostics (io::run_fields: the torus grid, the qmc run or the transfer
/// operator's final resolution; the CLI's `run` object): the table and its cells' numbers, kept
/// small (a grid keeps one per point).
struct RunCells {
  std::span<const io::Field> fields;  ///< empty: none
  std::array<double, 4> numbers{};    ///< per field: a count (exact in a double) or a real
};

template <class Real>
RunCells run_cells_of(const Averages<Real>& a) {
  RunCells out;
  out.fields = io::run_fields(a);
  if (out.fields.empty()) return out;
  if (out.fields.size() > out.numbers.size())
    throw std::logic_error("pendavg internal error: a run table wider than RunCells");
  thread_local io::Record record;  // (reused: a point's call allocates nothing here)
  record.reset(out.fields, 0);
  io::append_run(record, a);
  for (std::size_t k = 0; k < out.fields.size(); ++k) {
    const io::Cell& cell = record.cells_of(k)[0];
    out.numbers[k] = cell.tag == io::Cell::Tag::integer ? static_cast<double>(cell.integer)
                                                        : cell.number;
  }
  return out;
}

/// {field: value} of the run's table (counts int, reals float), or None.
py::object run_object(const RunCells& run) {
  if (run.fields.empty()) return py::none();
  py::dict out;
  for (std::size_t k = 0; k < run.fields.size(); ++k) {
    const io::Field& f = run.fields[k];
    const std::string name(f.name);
    if (f.kind == io::Kind::count) out[name.c_str()] = static_cast<long long>(run.numbers[k]);
    else out[name.c_str()] = run.numbers[k];
  }
  return out;
}

/// The docstring of Averages.run: each run table's fields with their meanings.
std::string run_doc() {
  std::string doc = "How the method ran (the CLI's `run`): a dict of one of these tables, None for "
                    "the other methods (a grid: an object array of them).";
  for (const std::span<const io::Field> table :
       {io::torus_run_fields(), io::qmc_run_fields(), io::transfer_run_fields()}) {
    doc += "\n";
    for (std::size_t k = 0; k < table.size(); ++k)
      doc += std::string(k ? "; " : "\n") + std::string(table[k].name) + ": " +
             std::string(table[k].meaning);
  }
  return doc;
}

/// The Python class Averages: the records of every point (the inputs', then the averages'), and
/// each point's run diagnostics.
struct AveragesResult : TableResult {
  std::vector<RunCells> runs;

  /// Lays out a call of `points` points (shape set before); `beta`: a canonical call (a limit
  /// has no beta).
  void start(bool beta) {
    layout({{beta ? io::canonical_input_fields() : io::chain_input_fields(), true},
            {io::averages_fields(), false}},
           digits > min_digits);
    runs.assign(points(), {});
  }
};

/// The fields of Averages: a canonical call's (a limit has no beta: None).
const std::vector<ClassField>& averages_class_fields() {
  static const std::vector<ClassField> fields =
      class_fields({{io::canonical_input_fields(), true}, {io::averages_fields(), false}});
  return fields;
}

/// The records one point is built into (a worker's, reused from point to point).
struct PointRecords {
  io::Record inputs, values;
};

/// Stores point k of `result`: the library's result `a` of `chain` (at `beta`; null for the
/// limits) filled into the records as the CLI fills them (`texts`: an MPFR run's inputs as
/// written: beta, g, m1..mN, l1..lN, without beta for the limits). Runs without the GIL, an
/// MPFR point under its working precision.
template <class Real>
void keep_point(AveragesResult& result, std::size_t k, const Chain<Real>& chain, const Real* beta,
                const Averages<Real>& a, double seconds, PointRecords& records,
                std::span<const std::string_view> texts = {}) {
  // (a double run's texts are made when .decimal asks for them: TableResult::decimal)
  const io::Printing printing{result.digits, false};
  const bool mpfr = !std::is_same_v<Real, double>;
  records.inputs.keep_exact(mpfr);
  records.values.keep_exact(mpfr);
  if (beta) {
    records.inputs.reset(io::canonical_input_fields(), result.particles);
    io::append_canonical_inputs(records.inputs, chain, *beta, printing, texts);
  } else {
    records.inputs.reset(io::chain_input_fields(), result.particles);
    io::append_chain_inputs(records.inputs, chain, printing, texts);
  }
  records.values.reset(io::averages_fields(), result.particles);
  io::append_averages(records.values, a, beta, printing);
  const std::array<const io::Record*, 2> both{&records.inputs, &records.values};
  result.store(k, both);
  result.set_run(k, seconds, a.interrupted);
  result.runs[k] = run_cells_of(a);
}

/// An empty grid's call-wide fields (N, digits), from a unit chain's inputs.
void keep_call(AveragesResult& result) {
  const std::size_t n = result.particles;
  io::Record inputs(io::canonical_input_fields(), n);
  const Chain<double> unit(std::vector<double>(n, 1.0), std::vector<double>(n, 1.0), 1.0);
  io::append_canonical_inputs(inputs, unit, 1.0, io::Printing{result.digits});
  const std::array<const io::Record*, 2> records{&inputs, nullptr};
  result.store_call(records);
}

// ---------------------------------------------------------------- computing points

/// One point in double; the chain and beta were checked while the GIL was held. `workspace`
/// is the caller's (Pinocchio's Data): a single point makes one for its call, a grid one per
/// worker thread, owned by the grid call; no workspace outlives the call that made it.
void compute_double(AveragesResult& result, std::size_t k, const Chain<double>& chain,
                    double beta, const AverageOptions& options,
                    AverageWorkspace<double>& workspace, PointRecords& records) {
  const Stopwatch watch;
  const Averages<double> a = average(chain, beta, options, workspace);
  keep_point(result, k, chain, &beta, a, watch.seconds(), records);
}

/// One point's inputs as decimal texts (MPFR runs).
struct PointTexts {
  std::vector<std::string> masses, lengths;
  std::string g, beta;
  /// beta (when given), g, m1..mN, l1..lN: how the records print an MPFR run's inputs.
  std::vector<std::string_view> as_written(bool with_beta) const {
    std::vector<std::string_view> out;
    if (with_beta) out.push_back(beta);
    out.push_back(g);
    out.insert(out.end(), masses.begin(), masses.end());
    out.insert(out.end(), lengths.begin(), lengths.end());
    return out;
  }
};

/// The chain of a point's texts, parsed as the CLI parses --masses, --lengths and --g (under
/// the caller's working precision).
template <class Real>
Chain<Real> parse_chain(const PointTexts& in) {
  std::vector<Real> masses, lengths;
  for (const std::string& m : in.masses)
    masses.push_back(io::parse_real<Real>(m, "masses", Domain::positive));
  for (const std::string& l : in.lengths)
    lengths.push_back(io::parse_real<Real>(l, "lengths", Domain::positive));
  Real g = io::parse_real<Real>(in.g, "g", Domain::nonnegative);
  if (masses.size() != lengths.size())
    throw io::bad_input(std::to_string(masses.size()) + " masses but " +
                        std::to_string(lengths.size()) + " lengths");
  return Chain<Real>(std::move(masses), std::move(lengths), std::move(g));
}

/// One MPFR point's chain and beta.
struct MpfrPoint {
  Chain<mpfr_real> chain;
  mpfr_real beta;
};

/// Parses `in` as the CLI does (masses, lengths, g, the chain, then the method's options, then
/// beta). The caller holds the run's working precision.
MpfrPoint parse_mpfr(const PointTexts& in, const AverageOptions& options) {
  Chain<mpfr_real> chain = parse_chain<mpfr_real>(in);
  resolve_average_method(chain.size(), options);
  mpfr_real beta = io::parse_real<mpfr_real>(in.beta, "beta", Domain::positive);
  return {std::move(chain), std::move(beta)};
}

/// Parses and computes point k in MPFR under its working precision. No GIL needed.
void compute_mpfr(AveragesResult& result, std::size_t k, const PointTexts& in,
                  const AverageOptions& options) {
  const working_precision precision(options.digits + guard_digits);
  const MpfrPoint point = parse_mpfr(in, options);
  const Stopwatch watch;
  const Averages<mpfr_real> a = average(point.chain, point.beta, options);
  const double seconds = watch.seconds();
  PointRecords records;
  const std::vector<std::string_view> texts = in.as_written(true);
  keep_point(result, k, point.chain, &point.beta, a, seconds, records, texts);
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

/// Refuses a result with a NaN or an infinity before it reaches Python (ValueError, one line).
void require_finite(const AveragesResult& r, const std::string& command) {
  r.require_finite(command, "the method cannot evaluate this chain");
}

// ---------------------------------------------------------------- pendavg.average

/// The chain of one double point, checked in the CLI's order: masses, lengths, g, counts.
Chain<double> double_chain(const std::vector<py::object>& masses,
                           const std::vector<py::object>& lengths, py::handle g) {
  std::vector<double> m, l;
  for (const py::object& x : masses) m.push_back(number_double(x, "masses", Domain::positive));
  for (const py::object& x : lengths) l.push_back(number_double(x, "lengths", Domain::positive));
  const double gravity = number_double(g, "g", Domain::nonnegative);
  if (m.size() != l.size())
    throw io::bad_input(std::to_string(m.size()) + " masses but " + std::to_string(l.size()) +
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
  AverageOptions run = settings;
  run.threads = hardware_threads();
  Observation observation;
  run.control = observation.control();
  const bool long_run = !progress.is_none() || observable(m.size(), run);
  if (settings.digits == min_digits) {
    const Chain<double> chain = double_chain(m, l, g);
    resolve_average_method(chain.size(), run);  // every option checked before any work
    const double b = number_double(beta, "beta", Domain::positive);
    try {  // what printing needs, after what average() checks (the CLI's order of messages)
      io::check_printed_quotients(b);
    } catch (const invalid_input&) {
      check_average(chain, b, run);
      throw;
    }
    result.start(true);
    AverageWorkspace<double> workspace;  // this call's buffers (a grid: one per worker)
    // A short run's records are this thread's, reused from call to call (no Python code runs
    // meanwhile); a long run's its own (a progress callback may call average again).
    thread_local PointRecords reused;
    PointRecords own;
    PointRecords& records = long_run ? own : reused;
    run_call([&] { compute_double(result, 0, chain, b, run, workspace, records); }, long_run,
             observation, progress);
  } else {
    const PointTexts in{texts(m, "masses"), texts(l, "lengths"), number_text(g, "g"),
                        number_text(beta, "beta")};
    result.start(true);
    run_call([&] { compute_mpfr(result, 0, in, run); }, long_run, observation, progress);
  }
  require_finite(result, "average");
  return py::cast(std::move(result));
}

/// One column of a grid (beta, g, a mass or a length over all points): float64 values, or the
/// Python objects (str, int, Decimal, mpf, ...) of any other dtype.
struct InputColumn {
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

InputColumn column(py::handle x, std::size_t count) {
  py::array a = py::reinterpret_borrow<py::array>(x);
  if (a.ndim() != 1 || static_cast<std::size_t>(a.shape(0)) != count)
    throw std::invalid_argument("average_grid: every column must have one entry per point");
  InputColumn c;
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
  result.start(true);
  if (count == 0) {
    keep_call(result);
    return result;
  }
  std::vector<InputColumn> cols;
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
    // before its work (check_average) and what printing needs (check_printed_quotients); then
    // computed without the GIL.
    std::vector<double> beta(count), g(count), masses(n * count), lengths(n * count);
    bool resolved = false;
    for (std::size_t k = 0; k < count; ++k) {
      try {
        for (std::size_t i = 0; i < n; ++i)
          masses[i * count + k] = cols[2 + i].number(k, "masses", Domain::positive);
        for (std::size_t i = 0; i < n; ++i)
          lengths[i * count + k] = cols[2 + n + i].number(k, "lengths", Domain::positive);
        g[k] = cols[1].number(k, "g", Domain::nonnegative);
        if (!resolved) {
          resolve_average_method(n, run);
          resolved = true;
        }
        beta[k] = cols[0].number(k, "beta", Domain::positive);
        std::vector<double> m, l;
        for (std::size_t i = 0; i < n; ++i) {
          m.push_back(masses[i * count + k]);
          l.push_back(lengths[i * count + k]);
        }
        check_average(Chain<double>(std::move(m), std::move(l), g[k]), beta[k], run);
        io::check_printed_quotients(beta[k]);
      } catch (const invalid_input& bad) {
        throw invalid_input(index_text(k, result.shape) + ": " + bad.what());
      }
    }
    std::vector<AverageWorkspace<double>> workspaces(static_cast<std::size_t>(threads));
    std::vector<PointRecords> records(static_cast<std::size_t>(threads));
    try {
      run_points(count, threads, [&](std::size_t k, int worker) {
        std::vector<double> m(n), l(n);
        for (std::size_t i = 0; i < n; ++i) {
          m[i] = masses[i * count + k];
          l[i] = lengths[i * count + k];
        }
        const Chain<double> chain(std::move(m), std::move(l), g[k]);
        const auto w = static_cast<std::size_t>(worker);
        compute_double(result, k, chain, beta[k], run, workspaces[w], records[w]);
      }, stop, progress);
    } catch (const PointFailure& failure) {
      failed(failure);
    }
  } else {
    std::vector<PointTexts> in(count);
    for (std::size_t k = 0; k < count; ++k) {
      for (std::size_t i = 0; i < n; ++i) in[k].masses.push_back(number_text(cols[2 + i].at(k), "masses"));
      for (std::size_t i = 0; i < n; ++i)
        in[k].lengths.push_back(number_text(cols[2 + n + i].at(k), "lengths"));
      in[k].g = number_text(cols[1].at(k), "g");
      in[k].beta = number_text(cols[0].at(k), "beta");
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
          count, threads, [&](std::size_t k, int) { compute_mpfr(result, k, in[k], run); },
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
void limit_mpfr(AveragesResult& high, AveragesResult& low, const PointTexts& in,
                const AverageOptions& settings) {
  const working_precision precision(settings.digits + guard_digits);
  const Chain<mpfr_real> chain = parse_chain<mpfr_real>(in);
  const Stopwatch high_watch;
  const Averages<mpfr_real> h = high_temperature_limit(chain, settings);
  const double high_seconds = high_watch.seconds();
  const Stopwatch low_watch;
  const Averages<mpfr_real> lo = low_temperature_limit(chain, settings);
  const double low_seconds = low_watch.seconds();
  const mpfr_real* no_beta = nullptr;
  const std::vector<std::string_view> texts = in.as_written(false);
  PointRecords records;
  keep_point(high, 0, chain, no_beta, h, high_seconds, records, texts);
  keep_point(low, 0, chain, no_beta, lo, low_seconds, records, texts);
}

/// beta -> 0 and beta -> infinity, as `pendavg limit` (src/cli/limit.cpp, limit_report).
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
    r->start(false);
  }
  if (d == min_digits) {
    const Chain<double> chain = double_chain(m, l, g);
    run_call(
        [&] {
          const double* no_beta = nullptr;
          PointRecords records;
          const Stopwatch high_watch;
          const Averages<double> h = high_temperature_limit(chain, settings);
          const double high_seconds = high_watch.seconds();
          const Stopwatch low_watch;
          const Averages<double> lo = low_temperature_limit(chain, settings);
          const double low_seconds = low_watch.seconds();
          keep_point(high, 0, chain, no_beta, h, high_seconds, records);
          keep_point(low, 0, chain, no_beta, lo, low_seconds, records);
        },
        long_run, observation, progress);
  } else {
    const PointTexts in{texts(m, "masses"), texts(l, "lengths"), number_text(g, "g"), ""};
    run_call([&] { limit_mpfr(high, low, in, settings); }, long_run, observation, progress);
  }
  require_finite(high, "limit (beta -> 0)");
  require_finite(low, "limit (beta -> infinity)");
  return py::make_tuple(std::move(high), std::move(low));
}

/// The class docstring: what Averages is, then every field with its meaning (the field tables').
std::string averages_doc() {
  std::string doc =
      "Thermal averages of a chain: the result of pendavg.average, pendavg.sweep and "
      "pendavg.limit.\n\n"
      "One point: per-particle fields are arrays of shape (N,), per-point fields are Python\n"
      "scalars. A grid (array arguments): per-particle fields have shape S + (N,), per-point\n"
      "fields shape S, S the broadcast shape of the arguments. Index i is particle i + 1 of the\n"
      "paper. The fields (the CLI's JSON keys, from the output schema's field tables):\n\n";
  for (const ClassField& f : averages_class_fields())
    doc += "  " + std::string(f.field.name) + (f.field.shape == io::Shape::per_particle ? " (per particle)" : "") +
           ": " + std::string(f.field.meaning) + "\n";
  doc += "\nBesides: shape, seconds (the library call's wall time), run\n"
         "(the torus grid, the qmc run or the transfer operator's final resolution; None for the\n"
         "other methods), decimal (the CLI's strings), mpf (exact mpmath values), dims and coords\n"
         "(a grid's axes), to_dict(), to_dataframe(), to_xarray().";
  return doc;
}

}  // namespace

void expose_average(py::module_& m) {
  using namespace pybind11::literals;
  auto c = table_class<AveragesResult>(m, "Averages", averages_doc().c_str(),
                                       averages_class_fields());
  c.def_property_readonly(
      "run",
      [](const AveragesResult& r) -> py::object {
        if (r.single()) return run_object(r.runs.front());
        py::object out = py::module_::import("numpy").attr("empty")(r.runs.size(), "dtype"_a = "object");
        for (std::size_t k = 0; k < r.runs.size(); ++k) out[py::int_(k)] = run_object(r.runs[k]);
        return out.attr("reshape")(py::cast(r.shape));
      },
      [] { static const std::string doc = run_doc(); return doc.c_str(); }());

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
