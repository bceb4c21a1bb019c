// SPDX-License-Identifier: GPL-3.0-or-later
// tests/bench/bench_double_pendulum.cpp -- the speed targets for the double pendulum.
//
//   BM_double_all_cases          one iteration = reduced_integral_average<double> over all 1000
//                                cases of cases.hpp; counter per_case_us (mean wall time per
//                                case, steady_clock over all iterations).
//   BM_double_case_distribution  every case timed on its own (5 blocks of up to 200 calls, per-case
//                                median of the blocks); counters median_us, p90_us, worst_us and
//                                worst_case (index). The targets: median <= 2 us,
//                                worst <= 10 us per parameter set.
//   BM_mpfr38_distribution       the same over all 1000 cases in mpfr_real at 38 and 77 digits
//   BM_mpfr77_distribution       (5 timings per case, median); median_ms, p90_ms, worst_ms. About
//                                2 s and 5 s. Targets: 38 digits median <= 1 ms, worst <= 3 ms;
//                                77 digits worst <= 5 ms.
//   BM_double_named/<name>       single typical cases.
// Every timed call passes an IntegralWorkspace kept across calls, as pendavg::average and the CLI
// do (the overload without one allocates its node buffers per call: ~15% on 65-node cases).
// Per-case times are thread CPU time (CLOCK_THREAD_CPUTIME_ID, one reading per block), so other
// processes on the cores matter less; repeat the runs and compare medians all the same.
//
// Every distribution benchmark also counts, over its cases, `failures` (exceptions),
// `nonfinite` (a NaN/inf beta<K_i>) and `not_converged` (Averages::converged == false); each
// such case is printed once to stderr with its exact parameters, as is the slowest case.
//
// Extra flag, handled before benchmark::Initialize:
//   bench_double_pendulum --write-cases FILE [--replicate N] [--grouped]
// writes the 1000 cases as CSV (beta,g,m1,m2,l1,l2; %.17g), the list repeated N times (default
// 1; data row r is case r % 1000) or, with --grouped, each case N times in a row (row r is case
// r / N), and exits. tests/bench/cli_cases_bench.sh uses it to time the CLI on the same cases.
//   bench_double_pendulum --profile-cases DIGITS [FIRST COUNT [quadrature|sums]]
// times each case alone (thread CPU time, so other processes on the cores matter less) and
// prints index, time, evaluations (nodes or Graf terms) and parameters, one line per case;
// `sort -k2 -g -r` lists the slowest. DIGITS = 16: double; otherwise MPFR at DIGITS.
// `quadrature` forces the nodes, `sums` the exact Graf sums (IntegralEvaluation), e.g. to
// compare both paths case by case with the cost model's choice.
#include <benchmark/benchmark.h>

#include "cases.hpp"

#include "pendavg/chain.hpp"
#include "engine/double_pendulum/double_pendulum.hpp"
#include "engine/numerics/precision.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <ctime>
#include <exception>
#include <optional>
#include <set>
#include <string>
#include <type_traits>
#include <vector>

namespace {

using pendavg::Chain;
using pendavg::mpfr_real;
using pendavg_bench::Case;
using clock_type = std::chrono::steady_clock;

const std::vector<Case>& all_cases() {
  static const std::vector<Case> cases = pendavg_bench::make_cases();
  return cases;
}

template <class Real>
Chain<Real> make_chain(const Case& c) {
  return Chain<Real>({Real(c.m1), Real(c.m2)}, {Real(c.l1), Real(c.l2)}, Real(c.g));
}

double seconds_since(clock_type::time_point start) {
  return std::chrono::duration<double>(clock_type::now() - start).count();
}

/// Thread CPU time in seconds (a system call, ~0.5 us: read once per block of calls).
double thread_cpu_seconds() {
  timespec ts{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
  return static_cast<double>(ts.tv_sec) + 1e-9 * static_cast<double>(ts.tv_nsec);
}

double median_of(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  const std::size_t n = v.size();
  return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

/// Nearest-rank percentile (p in (0, 1]) of an unsorted sample.
double percentile_of(std::vector<double> v, double p) {
  std::sort(v.begin(), v.end());
  const auto rank = static_cast<std::size_t>(std::ceil(p * static_cast<double>(v.size())));
  return v[std::max<std::size_t>(rank, 1) - 1];
}

/// Prints each (benchmark, case, kind) problem once per process.
void report_problem(const char* bench, std::size_t index, const Case& c, const std::string& what) {
  static std::set<std::string> seen;
  const std::string key = std::string(bench) + "/" + std::to_string(index) + "/" + what;
  if (!seen.insert(key).second) return;
  std::fprintf(stderr, "[%s] case %zu: %s: %s\n", bench, index, pendavg_bench::describe(c).c_str(),
               what.c_str());
}

/// Problems found in one result (and the kinds already counted for this case).
struct Problems {
  long failures = 0, nonfinite = 0, not_converged = 0;
};

template <class Real>
void check_result(const pendavg::Averages<Real>& r, const char* bench, std::size_t index,
                  const Case& c, Problems& problems) {
  using std::isfinite;
  bool finite = r.beta_kinetic.size() == 2;
  for (const pendavg::Estimate<Real>& k : r.beta_kinetic) finite = finite && isfinite(k.value);
  if (!finite) {
    ++problems.nonfinite;
    report_problem(bench, index, c, "non-finite beta<K_i>");
  }
  if (!r.converged) {
    ++problems.not_converged;
    report_problem(bench, index, c, "not converged");
  }
}

void set_problem_counters(benchmark::State& state, const Problems& p) {
  state.counters["failures"] = static_cast<double>(p.failures);
  state.counters["nonfinite"] = static_cast<double>(p.nonfinite);
  state.counters["not_converged"] = static_cast<double>(p.not_converged);
}

// ---------------------------------------------------------------- double, all cases

void BM_double_all_cases(benchmark::State& state) {
  const auto& cases = all_cases();
  std::vector<std::optional<Chain<double>>> chains;
  chains.reserve(cases.size());
  for (const Case& c : cases) {
    try {
      chains.emplace_back(make_chain<double>(c));
    } catch (const std::exception&) {
      chains.emplace_back(std::nullopt);
    }
  }
  long failures = 0;
  pendavg::IntegralWorkspace<double> workspace;
  const auto start = clock_type::now();
  for (auto _ : state) {
    for (std::size_t i = 0; i < cases.size(); ++i) {
      if (!chains[i]) {
        ++failures;
        continue;
      }
      try {
        auto r = pendavg::reduced_integral_average<double>(*chains[i], cases[i].beta, 16, {},
                                                           workspace);
        benchmark::DoNotOptimize(r);
      } catch (const std::exception& e) {
        ++failures;
      }
    }
  }
  const double elapsed = seconds_since(start);  // wall time of all sweeps
  const double n = static_cast<double>(cases.size());
  state.counters["per_case_us"] = elapsed * 1e6 / (static_cast<double>(state.iterations()) * n);
  state.counters["failures"] =
      static_cast<double>(failures) / static_cast<double>(state.iterations());  // per sweep
  state.SetItemsProcessed(state.iterations() * static_cast<std::int64_t>(cases.size()));
}
BENCHMARK(BM_double_all_cases)->Unit(benchmark::kMillisecond)->UseRealTime();

// ---------------------------------------------------------------- per-case distributions

/// Times every case of `cases` alone: `blocks` blocks, each of `reps` calls (chosen per case so
/// one block takes about `block_budget` seconds, at most `max_reps` calls); the per-case time is
/// the median over the blocks of (block thread CPU time / reps). Returns the per-case seconds
/// (NaN for a case that threw).
template <class Real>
std::vector<double> per_case_times(const std::vector<Case>& cases, int digits, int blocks,
                                   int max_reps, double block_budget, const char* bench,
                                   Problems& problems) {
  std::vector<double> times(cases.size(), std::nan(""));
  pendavg::IntegralWorkspace<Real> workspace;  // as pendavg::average and the CLI keep one
  for (std::size_t i = 0; i < cases.size(); ++i) {
    const Case& c = cases[i];
    try {
      const Chain<Real> chain = make_chain<Real>(c);
      const Real beta(c.beta);
      // Warm-up call (workspace, rule levels) and its result check.
      auto t0 = clock_type::now();
      auto first = pendavg::reduced_integral_average<Real>(chain, beta, digits, {}, workspace);
      const double one = seconds_since(t0);
      check_result(first, bench, i, c, problems);
      const int reps = static_cast<int>(
          std::clamp(block_budget / std::max(one, 1e-9), 1.0, static_cast<double>(max_reps)));
      std::vector<double> block_times;
      block_times.reserve(static_cast<std::size_t>(blocks));
      for (int b = 0; b < blocks; ++b) {
        const double start = thread_cpu_seconds();
        for (int k = 0; k < reps; ++k) {
          auto r = pendavg::reduced_integral_average<Real>(chain, beta, digits, {}, workspace);
          benchmark::DoNotOptimize(r);
        }
        block_times.push_back((thread_cpu_seconds() - start) / reps);
      }
      times[i] = median_of(block_times);
    } catch (const std::exception& e) {
      ++problems.failures;
      report_problem(bench, i, c, std::string("exception: ") + e.what());
    }
  }
  return times;
}

/// Sets median/p90/worst counters (in `unit_scale` units, e.g. 1e6 for us) and prints the
/// slowest case once per benchmark name.
void report_distribution(benchmark::State& state, const std::vector<Case>& cases,
                         const std::vector<double>& times, double unit_scale, const char* unit,
                         const char* bench) {
  std::vector<double> ok;
  std::size_t worst = 0;
  for (std::size_t i = 0; i < times.size(); ++i) {
    if (std::isnan(times[i])) continue;
    ok.push_back(times[i]);
    if (std::isnan(times[worst]) || times[i] > times[worst]) worst = i;
  }
  if (ok.empty()) {
    state.SkipWithError("every case failed");
    return;
  }
  const std::string u(unit);
  state.counters["median_" + u] = median_of(ok) * unit_scale;
  state.counters["p90_" + u] = percentile_of(ok, 0.90) * unit_scale;
  state.counters["p99_" + u] = percentile_of(ok, 0.99) * unit_scale;
  state.counters["worst_" + u] = times[worst] * unit_scale;
  state.counters["worst_case"] = static_cast<double>(worst);
  static std::set<std::string> printed;
  if (printed.insert(bench).second) {
    std::fprintf(stderr, "[%s] slowest case %zu (%.4g %s): %s\n", bench, worst,
                 times[worst] * unit_scale, unit, pendavg_bench::describe(cases[worst]).c_str());
  }
}

void BM_double_case_distribution(benchmark::State& state) {
  const auto& cases = all_cases();
  for (auto _ : state) {
    Problems problems;
    const auto times = per_case_times<double>(cases, 16, /*blocks=*/5, /*max_reps=*/200,
                                              /*block_budget=*/1e-3,
                                              "BM_double_case_distribution", problems);
    report_distribution(state, cases, times, 1e6, "us", "BM_double_case_distribution");
    set_problem_counters(state, problems);
  }
}
BENCHMARK(BM_double_case_distribution)->Iterations(1)->Unit(benchmark::kMillisecond)->UseRealTime();

template <int Digits>
void BM_mpfr_distribution(benchmark::State& state, const char* bench) {
  const auto& cases = all_cases();
  // Chains, betas and every temporary are created at the working precision of the computation.
  pendavg::working_precision guard(Digits + pendavg::guard_digits);
  for (auto _ : state) {
    Problems problems;
    const auto times = per_case_times<mpfr_real>(cases, Digits, /*blocks=*/5, /*max_reps=*/1,
                                                 /*block_budget=*/0, bench, problems);
    report_distribution(state, cases, times, 1e3, "ms", bench);
    set_problem_counters(state, problems);
  }
}
void BM_mpfr38_distribution(benchmark::State& state) {
  BM_mpfr_distribution<38>(state, "BM_mpfr38_distribution");
}
void BM_mpfr77_distribution(benchmark::State& state) {
  BM_mpfr_distribution<77>(state, "BM_mpfr77_distribution");
}
BENCHMARK(BM_mpfr38_distribution)->Iterations(1)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_mpfr77_distribution)->Iterations(1)->Unit(benchmark::kMillisecond)->UseRealTime();

// ---------------------------------------------------------------- named single cases

void BM_double_named(benchmark::State& state, Case c) {
  const Chain<double> chain = make_chain<double>(c);
  Problems problems;
  try {
    check_result(pendavg::reduced_integral_average<double>(chain, c.beta, 16), "BM_double_named",
                 0, c, problems);
  } catch (const std::exception& e) {
    report_problem("BM_double_named", 0, c, std::string("exception: ") + e.what());
    state.SkipWithError(e.what());
    return;
  }
  std::size_t evaluations = 0;
  pendavg::IntegralWorkspace<double> workspace;
  for (auto _ : state) {
    auto r = pendavg::reduced_integral_average<double>(chain, c.beta, 16, {}, workspace);
    evaluations = r.evaluations;
    benchmark::DoNotOptimize(r);
  }
  state.counters["evaluations"] = static_cast<double>(evaluations);
  set_problem_counters(state, problems);
}

constexpr double tiny_mu = 1e-12;
// Case = {beta, g, m1, m2, l1, l2}
BENCHMARK_CAPTURE(BM_double_named, paper, Case{1, 1, 0.5, 0.5, 1, 1});
BENCHMARK_CAPTURE(BM_double_named, beta_1e8, Case{1e8, 1, 0.5, 0.5, 1, 1});
BENCHMARK_CAPTURE(BM_double_named, beta_1e-8, Case{1e-8, 1, 0.5, 0.5, 1, 1});
BENCHMARK_CAPTURE(BM_double_named, mu1_1e-12_beta_1, Case{1, 1, tiny_mu, 1 - tiny_mu, 1, 1});
BENCHMARK_CAPTURE(BM_double_named, mu1_1e-12_beta_1e4, Case{1e4, 1, tiny_mu, 1 - tiny_mu, 1, 1});
BENCHMARK_CAPTURE(BM_double_named, l2_1e-4, Case{1, 1, 0.5, 0.5, 1, 1e-4});
BENCHMARK_CAPTURE(BM_double_named, l2_1e4, Case{1, 1, 0.5, 0.5, 1, 1e4});

}  // namespace

/// --profile-cases DIGITS [FIRST COUNT [quadrature|sums]]: times every case alone (thread CPU
/// time, median of 5 blocks) and prints one line per case: index, time, evaluations (nodes or
/// Graf terms), parameters. DIGITS = 16 runs double, otherwise mpfr_real at that many digits.
/// Sort the output to list the slowest cases.
int profile_cases(int digits, std::size_t first, std::size_t count,
                  pendavg::IntegralEvaluation evaluation) {
  pendavg::IntegralOptions options;
  options.evaluation = evaluation;
  const auto& all = all_cases();
  const std::size_t last = std::min(all.size(), first + count);
  for (std::size_t i = first; i < last; ++i) {
    const Case& c = all[i];
    auto run = [&]<class Real>() {
      const Chain<Real> chain = make_chain<Real>(c);
      const Real beta(c.beta);
      pendavg::IntegralWorkspace<Real> workspace;
      auto r = pendavg::reduced_integral_average<Real>(chain, beta, digits, options, workspace);
      std::vector<double> t;
      const int reps = std::is_same_v<Real, double> ? 50 : 1;
      // Thread CPU time: robust against other processes sharing the cores.
      const auto cpu_seconds = thread_cpu_seconds;
      for (int b = 0; b < 5; ++b) {
        const double start = cpu_seconds();
        for (int k = 0; k < reps; ++k) {
          auto x = pendavg::reduced_integral_average<Real>(chain, beta, digits, options, workspace);
          benchmark::DoNotOptimize(x);
        }
        t.push_back((cpu_seconds() - start) / reps);
      }
      std::printf("%4zu %10.3f us evals=%5zu %s\n", i, median_of(t) * 1e6, r.evaluations,
                  pendavg_bench::describe(c).c_str());
    };
    if (digits == 16) {
      run.template operator()<double>();
    } else {
      pendavg::working_precision guard(digits + pendavg::guard_digits);
      run.template operator()<mpfr_real>();
    }
  }
  return 0;
}

int main(int argc, char** argv) {
  for (int i = 1; i < argc; ++i) {
    if (std::strcmp(argv[i], "--profile-cases") != 0) continue;
    if (i + 1 >= argc) {
      std::fprintf(stderr, "--profile-cases needs DIGITS\n");
      return 2;
    }
    const int digits = std::atoi(argv[i + 1]);
    const std::size_t first = i + 2 < argc ? std::strtoull(argv[i + 2], nullptr, 10) : 0;
    const std::size_t count = i + 3 < argc ? std::strtoull(argv[i + 3], nullptr, 10) : 1000;
    auto evaluation = pendavg::IntegralEvaluation::automatic;
    if (i + 4 < argc) {
      if (std::strcmp(argv[i + 4], "quadrature") == 0) {
        evaluation = pendavg::IntegralEvaluation::quadrature;
      } else if (std::strcmp(argv[i + 4], "sums") == 0) {
        evaluation = pendavg::IntegralEvaluation::graf_sums;
      } else {
        std::fprintf(stderr, "--profile-cases: expected quadrature or sums, got %s\n", argv[i + 4]);
        return 2;
      }
    }
    return profile_cases(digits, first, count, evaluation);
  }
  // --write-cases FILE [--replicate N] [--grouped]: write the cases as CSV and exit.
  for (int i = 1; i < argc; ++i) {
    if (std::strcmp(argv[i], "--write-cases") != 0) continue;
    if (i + 1 >= argc) {
      std::fprintf(stderr, "--write-cases needs a file name\n");
      return 2;
    }
    std::size_t replicate = 1;
    for (int j = 1; j + 1 < argc; ++j)
      if (std::strcmp(argv[j], "--replicate") == 0)
        replicate = static_cast<std::size_t>(std::strtoull(argv[j + 1], nullptr, 10));
    if (replicate == 0) {
      std::fprintf(stderr, "--replicate needs a positive count\n");
      return 2;
    }
    bool grouped = false;
    for (int j = 1; j < argc; ++j)
      if (std::strcmp(argv[j], "--grouped") == 0) grouped = true;
    try {
      pendavg_bench::write_cases_csv(argv[i + 1], all_cases(), replicate, grouped);
    } catch (const std::exception& e) {
      std::fprintf(stderr, "%s\n", e.what());
      return 1;
    }
    return 0;
  }
  // The rest is BENCHMARK_MAIN().
  benchmark::Initialize(&argc, argv);
  if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 1;
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  return 0;
}
