// SPDX-License-Identifier: GPL-3.0-or-later
// tests/bench/bench_series.cpp -- the paper's series (eq. ave-K1-result) in MPFR.
//
//   BM_series/mu1_<m>/digits_<d>   pendavg::series_average<mpfr_real>(chain, beta = 1, d) with
//                                  masses (m, 1 - m), lengths (1, 1), g = 1, the masses parsed
//                                  from exact decimal strings at the working precision
//                                  d + guard_digits. series_average also runs the reduced
//                                  integral (for <cos phi_i> and the variances). Counter `terms`
//                                  = Averages::evaluations (series terms used).
//   BM_series_convergence_only/... pendavg::series_convergence alone (no integral), mu1 = 0.5,
//                                  50 digits: the issue's target "the series to 50 digits at
//                                  mu1 = 0.5: at most 10 ms". Counter `terms` = rows returned.
//
// mu1 = 0.01 at 50 digits takes about a minute per call: registered only when the environment
// variable PENDAVG_BENCH_SLOW=1 is set.
#include <benchmark/benchmark.h>

#include "pendavg/chain.hpp"
#include "engine/double_pendulum/double_pendulum.hpp"
#include "engine/numerics/precision.hpp"

#include <cstdlib>
#include <exception>
#include <string>

namespace {

using pendavg::Chain;
using pendavg::mpfr_real;

struct SeriesCase {
  const char* m1;  ///< exact decimal strings
  const char* m2;
};

/// The chain (m1, m2), (1, 1), g = 1 at the current working precision.
Chain<mpfr_real> make_chain(const SeriesCase& c) {
  return Chain<mpfr_real>({mpfr_real(c.m1), mpfr_real(c.m2)}, {mpfr_real(1), mpfr_real(1)},
                          mpfr_real(1));
}

void BM_series(benchmark::State& state, SeriesCase c, int digits) {
  pendavg::working_precision guard(digits + pendavg::guard_digits);
  const Chain<mpfr_real> chain = make_chain(c);
  const mpfr_real beta(1);
  std::size_t terms = 0;
  bool converged = true;
  long failures = 0;
  for (auto _ : state) {
    try {
      auto r = pendavg::series_average<mpfr_real>(chain, beta, digits);
      terms = r.evaluations;
      converged = converged && r.converged;
      benchmark::DoNotOptimize(r);
    } catch (const std::exception& e) {
      ++failures;
      state.SkipWithError(e.what());
      break;
    }
  }
  state.counters["terms"] = static_cast<double>(terms);
  state.counters["converged"] = converged ? 1 : 0;
  state.counters["failures"] = static_cast<double>(failures);
}

void BM_series_convergence_only(benchmark::State& state, SeriesCase c, int digits) {
  pendavg::working_precision guard(digits + pendavg::guard_digits);
  const Chain<mpfr_real> chain = make_chain(c);
  const mpfr_real beta(1);
  std::size_t terms = 0;
  for (auto _ : state) {
    try {
      auto rows = pendavg::series_convergence<mpfr_real>(chain, beta, digits);
      terms = rows.size();
      benchmark::DoNotOptimize(rows);
    } catch (const std::exception& e) {
      state.SkipWithError(e.what());
      break;
    }
  }
  state.counters["terms"] = static_cast<double>(terms);
}

bool register_all() {
  const char* slow_env = std::getenv("PENDAVG_BENCH_SLOW");
  const bool slow = slow_env && std::string(slow_env) == "1";
  struct Named {
    const char* name;
    SeriesCase c;
  };
  const Named cases[] = {{"mu1_0.5", {"0.5", "0.5"}},
                         {"mu1_0.1", {"0.1", "0.9"}},
                         {"mu1_0.05", {"0.05", "0.95"}},
                         {"mu1_0.01", {"0.01", "0.99"}}};
  for (const int digits : {16, 50}) {
    for (const Named& n : cases) {
      const bool is_slow = std::string(n.name) == "mu1_0.01" && digits == 50;
      if (is_slow && !slow) continue;
      const std::string name =
          std::string("BM_series/") + n.name + "/digits_" + std::to_string(digits);
      auto* b = benchmark::RegisterBenchmark(name.c_str(), BM_series, n.c, digits);
      b->Unit(benchmark::kMillisecond);
      if (is_slow) b->Iterations(1);
    }
  }
  benchmark::RegisterBenchmark("BM_series_convergence_only/mu1_0.5/digits_50",
                               BM_series_convergence_only, SeriesCase{"0.5", "0.5"}, 50)
      ->Unit(benchmark::kMillisecond);
  return true;
}

const bool registered = register_all();

}  // namespace

BENCHMARK_MAIN();
